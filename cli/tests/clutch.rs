//! A clutch slid by hand 1 mm longer than configured (`--plant clutch=…`): the beams are
//! softer and weaker than the controller believes. `vsa simulate --clutch-tolerance`
//! keeps the true beam stress within σ_allow where, without it, a 3 Hz sine against a load
//! bends them beyond it with no fault (docs/calibration.md, "The clutch monitor").

use std::process::Command;

/// `vsa simulate --json` at 4 mm configured, 5 mm actual, a 0.3 rad 3 Hz sine against
/// −0.3 N·m, with `extra` arguments: (peak stress / σ_allow, the latched faults).
fn wrong_clutch(extra: &[&str]) -> (f64, Vec<String>) {
    let out = Command::new(env!("CARGO_BIN_EXE_vsa"))
        .args([
            "simulate",
            "--clutch-length",
            "4mm",
            "--plant",
            "clutch=5mm",
            "--sine",
            "0.3rad:3Hz",
            "--load=-0.3Nm",
            "--json",
        ])
        .args(extra)
        .output()
        .expect("run vsa");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
    let faults = v["faults"]
        .as_array()
        .expect("faults")
        .iter()
        .map(|f| f.as_str().unwrap_or("").to_string())
        .collect();
    (v["peak_stress_ratio"].as_f64().expect("ratio"), faults)
}

#[test]
fn a_clutch_tolerance_keeps_a_longer_clutch_within_its_stress() {
    // Without a tolerance the controller plans with τ_cap(4 mm), the beams carry
    // τ_cap(5 mm) = 0.8·τ_cap(4 mm): beyond σ_allow, and nothing notices.
    let (none, faults) = wrong_clutch(&[]);
    assert!(none > 1.0, "{none}");
    assert!(faults.is_empty(), "{faults:?}");
    // 0.6 mm (a clutch slid by hand) and 1 mm: within σ_allow, no fault.
    for tol in ["0.6mm", "1mm"] {
        let (ratio, faults) = wrong_clutch(&["--clutch-tolerance", tol]);
        assert!(ratio < 1.0, "{tol}: {ratio}");
        assert!(faults.is_empty(), "{tol}: {faults:?}");
    }
}
