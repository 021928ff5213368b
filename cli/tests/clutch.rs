//! A clutch slid by hand 1 mm longer than configured (`--plant clutch=…`): the beams are
//! softer and weaker than the controller believes. `vsa simulate --clutch-tolerance`
//! keeps the true beam stress within σ_allow where, without it, a 3 Hz sine against a load
//! bends them beyond it with no fault (docs/calibration.md, "The clutch monitor").

use std::process::Command;

/// `vsa simulate --json` at 4 mm configured, 5 mm actual, the sine `sine` against the load
/// `load`, with `extra` arguments: (peak stress / σ_allow, the latched faults).
fn wrong_clutch(sine: &str, load: &str, extra: &[&str]) -> (f64, Vec<String>) {
    let out = Command::new(env!("CARGO_BIN_EXE_vsa"))
        .args([
            "simulate",
            "--clutch-length",
            "4mm",
            "--plant",
            "clutch=5mm",
            "--sine",
            sine,
            &format!("--load={load}"),
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

/// Fast sines against and along 0.3 N·m: which of them peaks highest depends on where the
/// free play's impacts fall, so the hazard is shown over the set, not by one case.
const SINES: [&str; 4] = ["0.3rad:3Hz", "0.25rad:3.5Hz", "0.25rad:4Hz", "0.15rad:5Hz"];
const LOADS: [&str; 2] = ["-0.3Nm", "0.3Nm"];

#[test]
fn a_clutch_tolerance_keeps_a_longer_clutch_within_its_stress() {
    // Without a tolerance the controller plans with τ_cap(4 mm), the beams carry
    // τ_cap(5 mm) = 0.8·τ_cap(4 mm): some of the sines bend them beyond σ_allow, and
    // nothing notices. With 0.6 mm (a clutch slid by hand) and 1 mm none does, and no
    // fault latches.
    let mut worst = [0.0f64; 3];
    for sine in SINES {
        for load in LOADS {
            for (i, extra) in [
                &[][..],
                &["--clutch-tolerance", "0.6mm"],
                &["--clutch-tolerance", "1mm"],
            ]
            .into_iter()
            .enumerate()
            {
                let (ratio, faults) = wrong_clutch(sine, load, extra);
                println!("{sine} against {load}, {extra:?}: {ratio:.3} σ_allow, faults {faults:?}");
                assert!(faults.is_empty(), "{sine} {load} {extra:?}: {faults:?}");
                worst[i] = worst[i].max(ratio);
            }
        }
    }
    assert!(worst[0] > 1.0, "without a tolerance: worst {}", worst[0]);
    assert!(worst[1] < 1.0, "0.6 mm: worst {}", worst[1]);
    assert!(worst[2] < 1.0, "1 mm: worst {}", worst[2]);
}
