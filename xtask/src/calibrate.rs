//! The calibration of a real build end to end on an emulated board: the served actuator is
//! made off-nominal the way a real build is (`vsa --qemu-plant NAME=VALUE`: wiring signs,
//! sensor offsets and gains, motor parameters, link inertia, the clutch's actual length),
//! and `vsa --qemu calibrate --json` must find it:
//!
//! 1. seeded random healthy builds: `status` "ok", each sign right (relative to the link
//!    encoder, the reference), the current offset within 2 counts, R (as the current sense
//!    sees it, R/gain) and k_e within 5 %; then the nominal actuator with its flash in a
//!    host file, and after a power cycle `vsa calibrate --show --json` gives the same
//!    result back;
//! 2. a broken build (the motor's leads open: 1 kΩ): `status` "motor-open", exit 1, and
//!    the board applies no duty after the end (`motor_duty_permille` 0).
//!
//! One healthy build per board by default (the sequence takes 13–16 s of emulated time);
//! `VSA_CALIBRATION_BUILDS=N` runs N.

use std::path::Path;
use std::process::Command;

use anyhow::{ensure, Context, Result};
use plant::XorShift32;
use serde_json::Value;

use crate::board::Board;
use crate::cmd::{cargo, describe, run_status, target_dir};

/// A build: the overrides and the values the calibration must find.
#[derive(Debug, Clone)]
struct Build {
    overrides: Vec<String>,
    /// Motor polarity and pot direction relative to the encoder's.
    motor: i8,
    pot: i8,
    current_offset: f64,
    /// R / current gain, Ω.
    resistance_seen: f64,
    back_emf: f64,
}

/// A random healthy build from `rng` (the ranges of docs/calibration.md, around the
/// AX-12A: 8 Ω, 1.94 V·s/rad; the board is told 3 mm).
fn build(rng: &mut XorShift32) -> Build {
    let mut u = |lo: f64, hi: f64| lo + (hi - lo) * f64::from(rng.next_unit());
    let sign = |v: f64| if v < 0.5 { -1i8 } else { 1 };
    let (m, e, p) = (sign(u(0.0, 1.0)), sign(u(0.0, 1.0)), sign(u(0.0, 1.0)));
    let offset = u(-300.0, 300.0).round();
    let gain = u(0.9, 1.1);
    let r = 8.0 * u(0.85, 1.15);
    let ke = 1.94 * u(0.85, 1.15);
    let overrides = vec![
        format!("motor-polarity={m}"),
        format!("encoder-direction={e}"),
        format!("pot-direction={p}"),
        format!("current-offset={offset}"),
        format!("current-gain={gain:.4}"),
        format!("pot-offset={:.0}", u(-60.0, 60.0)),
        format!("pot-gain={:.4}", u(0.9, 1.1)),
        format!("resistance={r:.4}ohm"),
        format!("back-emf={ke:.4}Vs/rad"),
        format!("link-inertia={:.6}kgm2", u(0.3e-3, 5e-3)),
        format!("clutch={:.3}mm", u(2.5, 3.5)),
        format!("encoder-zero={:.0}", u(0.0, 4095.0)),
        format!("power-up-angle={:.3}rad", u(-0.8, 0.8)),
        "current-noise=1".to_string(),
        "pot-noise=0.3".to_string(),
    ];
    Build {
        overrides,
        motor: m * e,
        pot: p * e,
        current_offset: offset,
        resistance_seen: r / gain.max(1e-9),
        back_emf: ke,
    }
}

/// `vsa --qemu … calibrate --json [args]` on `board` with the `plant` overrides and the
/// flash file `flash`: exit success and the JSON object.
fn calibrate(
    vsa: &Path,
    board: Board,
    elf: &Path,
    plant: &[String],
    flash: Option<&Path>,
    args: &[&str],
) -> Result<(bool, Value)> {
    let mut cmd = Command::new(vsa);
    cmd.args(["--qemu", "--board", board.feature(), "--elf"])
        .arg(elf);
    for o in plant {
        cmd.args(["--qemu-plant", o]);
    }
    if let Some(f) = flash {
        cmd.arg("--qemu-flash").arg(f);
    }
    cmd.args(["calibrate", "--json"]).args(args);
    let out = cmd
        .output()
        .with_context(|| format!("starting {}", describe(&cmd)))?;
    let stdout = String::from_utf8_lossy(&out.stdout);
    let json: Value = serde_json::from_str(stdout.trim()).with_context(|| {
        format!(
            "{} printed no JSON object: {stdout:?}, stderr {:?}",
            describe(&cmd),
            String::from_utf8_lossy(&out.stderr).trim()
        )
    })?;
    Ok((out.status.success(), json))
}

fn num(v: &Value, key: &str) -> Result<f64> {
    v[key]
        .as_f64()
        .with_context(|| format!("no number {key} in {v}"))
}

/// Checks a healthy build's result (module docs); the largest relative error of R and k_e.
fn check_healthy(b: &Build, v: &Value) -> Result<f64> {
    ensure!(
        v["status"] == "ok",
        "status {} for {:?}",
        v["status"],
        b.overrides
    );
    let signs = (
        num(v, "motor_polarity")?,
        num(v, "encoder_direction")?,
        num(v, "pot_direction")?,
    );
    ensure!(
        signs == (f64::from(b.motor), 1.0, f64::from(b.pot)),
        "signs {signs:?}, want ({}, 1, {}): {:?}",
        b.motor,
        b.pot,
        b.overrides
    );
    let off = num(v, "current_offset_counts")?;
    ensure!(
        (off - b.current_offset).abs() <= 2.0,
        "current offset {off}, want {}: {:?}",
        b.current_offset,
        b.overrides
    );
    let r = num(v, "resistance_ohm")? / b.resistance_seen - 1.0;
    let ke = num(v, "back_emf_v_s_per_rad")? / b.back_emf - 1.0;
    ensure!(
        r.abs() <= 0.05 && ke.abs() <= 0.05,
        "R off by {:.1} %, k_e by {:.1} %: {v} for {:?}",
        r * 100.0,
        ke * 100.0,
        b.overrides
    );
    ensure!(v["stiffness_nm_per_rad"].is_null() && v["clutch_length_m"].is_null());
    Ok(r.abs().max(ke.abs()))
}

/// Runs the check on `board` with `elf` (module docs); the summary for the log.
pub fn check(board: Board, elf: &Path) -> Result<String> {
    run_status(cargo().args(["build", "--quiet", "-p", "vsa-cli", "--bin", "vsa"]))?;
    let vsa = target_dir().join("debug").join("vsa");
    let builds: u32 = std::env::var("VSA_CALIBRATION_BUILDS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(1);
    let flash = target_dir().join(format!("calibration-{}.flash", board.feature()));
    let _ = std::fs::remove_file(&flash);
    // The same seeded builds on both boards.
    let mut rng = XorShift32::new(0x5EED_0000);
    let mut worst = 0.0f64;
    for _ in 0..builds {
        let b = build(&mut rng);
        let (ok, v) = calibrate(&vsa, board, elf, &b.overrides, None, &[])?;
        ensure!(
            ok,
            "vsa calibrate failed on a healthy build: {v} ({:?})",
            b.overrides
        );
        worst = worst.max(check_healthy(&b, &v)?);
    }
    // Power cycle, on the nominal actuator (a build's overrides together with a flash file
    // latch adc-out-of-range at the emulated board's first tick: not yet understood): a
    // new board with the same flash file shows the stored result.
    let stored = Some(flash.as_path());
    let (ok, v) = calibrate(&vsa, board, elf, &[], stored, &[])?;
    ensure!(
        ok && v["status"] == "ok",
        "vsa calibrate with a flash file: {v}"
    );
    let (ok, shown) = calibrate(&vsa, board, elf, &[], stored, &["--show"])?;
    ensure!(
        ok,
        "vsa calibrate --show failed after a power cycle: {shown}"
    );
    for key in ["motor_polarity", "pot_direction", "current_offset_counts"] {
        ensure!(
            shown[key] == v[key],
            "after the power cycle {key}: {shown} vs {v}"
        );
    }
    for key in [
        "resistance_ohm",
        "back_emf_v_s_per_rad",
        "link_inertia_kg_m2",
    ] {
        ensure!(
            (num(&shown, key)? - num(&v, key)?).abs() <= 1e-6 * num(&v, key)?.abs(),
            "after the power cycle {key}: {shown} vs {v}"
        );
    }
    let _ = std::fs::remove_file(&flash);
    let open = vec!["resistance=1000ohm".to_string()];
    let (ok, v) = calibrate(&vsa, board, elf, &open, None, &[])?;
    ensure!(
        !ok,
        "vsa calibrate succeeded with the motor's leads open: {v}"
    );
    ensure!(
        v["status"] == "motor-open" && num(&v, "motor_duty_permille")? == 0.0,
        "open motor leads: {v}"
    );
    Ok(format!(
        "{builds} healthy build(s) calibrated (worst R/k_e error {:.2} %), the stored result back after a power cycle; open motor leads: motor-open, motor off",
        worst * 100.0
    ))
}
