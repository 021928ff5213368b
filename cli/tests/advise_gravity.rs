//! `vsa advise --gravity M·G·L`: a link hanging at the task's centre, pulled back by
//! −m·g·l·sin θ. Checked against an independent statement of the lossless two-mass model
//! with the pendulum's stiffness G = m·g·l on the link: the undamped system
//! [J_g, 0; 0, J_l]·θ̈ + [k, −k; −k, k + G]·θ = 0 has a mode at ω when
//! det([k − J_g·ω², −k; −k, k + G − J_l·ω²]) = 0, found here by bisection (the tool solves
//! the quadratic in closed form). The coupling mode is the upper root; the stiffness a task
//! at ω needs is the k that puts a mode there. The closed-loop energies must see gravity.

use serde_json::Value;

mod common;
use common::num;

/// Gear-side inertia at the output, docs/design.md §3.
const J_GEAR: f64 = 3.2e-3;
const J_LINK: f64 = 1e-3;

fn json(args: &[&str]) -> Value {
    common::json("advise", args)
}

fn det(k: f64, g: f64, w: f64) -> f64 {
    let w2 = w * w;
    (k - J_GEAR * w2) * (k + g - J_LINK * w2) - k * k
}

/// A root of `f` in [lo, hi] (a sign change there), by bisection.
fn bisect(f: impl Fn(f64) -> f64, mut lo: f64, mut hi: f64) -> f64 {
    assert!(f(lo) * f(hi) <= 0.0, "no sign change in [{lo}, {hi}]");
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if f(lo) * f(mid) <= 0.0 {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    0.5 * (lo + hi)
}

fn rel(got: f64, want: f64) -> f64 {
    ((got - want) / want).abs()
}

#[test]
fn without_gravity_nothing_changes() {
    let a = json(&["--lengths", "2mm,6mm"]);
    let mut b = json(&["--lengths", "2mm,6mm", "--gravity", "0Nm"]);
    assert_eq!(b["task"]["gravity_nm"], 0.0);
    b["task"]
        .as_object_mut()
        .unwrap()
        .insert("gravity_nm".into(), a["task"]["gravity_nm"].clone());
    assert_eq!(a, b);
}

#[test]
fn the_coupling_mode_and_the_stiffness_needed_include_the_pendulum() {
    let v = json(&["--lengths", "2mm,6mm", "--gravity", "0.2Nm"]);
    let v0 = json(&["--lengths", "2mm,6mm"]);
    // 0.2 N·m rounded to the I32F32 LSB, as the tool takes it.
    let g = num(&v["task"], "gravity_nm");
    assert!((g - 0.2).abs() < 1e-9, "{g}");
    for (r, r0) in v["rows"]
        .as_array()
        .unwrap()
        .iter()
        .zip(v0["rows"].as_array().unwrap())
    {
        let k = num(r, "stiffness_nm_per_rad");
        // Above the pendulum mode, below ∞: the upper root.
        let w0 = num(r0, "natural_frequency_hz") * std::f64::consts::TAU;
        let w = bisect(|w| det(k, g, w), 0.9 * w0, 2.0 * w0);
        let got = num(r, "natural_frequency_hz") * std::f64::consts::TAU;
        assert!(rel(got, w) < 1e-9, "{r}: {got} vs {w}");
        // Gravity moves the energies (the plant carries it).
        assert_ne!(r["energy_per_cycle_j"], r0["energy_per_cycle_j"], "{r}");
    }
    // 1 Hz: G = 0.2 > (J_g + J_l)·ω² = 0.166 N·m, so a positive k puts a mode there.
    let w = std::f64::consts::TAU;
    let k = bisect(|k| det(k, g, w), 1e-6, 1e3);
    let got = num(&v, "stiffness_needed_nm_per_rad");
    assert!(rel(got, k) < 1e-6, "{got} vs {k}");
    assert_eq!(
        v["resonance_reachable"], false,
        "{got} N·m/rad is below the softest"
    );
}

#[test]
fn no_stiffness_tunes_a_task_between_the_two_inertial_torques() {
    // 1 Hz: J_l·ω² = 0.039, (J_g + J_l)·ω² = 0.166 N·m; G = 0.1 lies between: det(k) has
    // no positive root (it is −J_g·ω²·(G − J_l·ω²) + k·(G − J·ω²) < 0 for all k > 0).
    let w = std::f64::consts::TAU;
    assert!((1..=1000).all(|k| det(f64::from(k) * 0.1, 0.1, w) < 0.0));
    let v = json(&["--lengths", "4mm", "--gravity", "0.1Nm"]);
    assert_eq!(v["resonance_reachable"], false);
    assert_eq!(v["stiffness_needed_nm_per_rad"], Value::Null);
    let out = common::vsa("advise", &["--lengths", "4mm", "--gravity", "0.1Nm"]);
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(text.contains("is out of reach at any stiffness"), "{text}");
    assert!(text.contains("gravity m·g·l = 0.1000 N·m"), "{text}");
}

#[test]
fn bad_gravity_is_one_line_and_exit_2() {
    for (arg, want) in [
        (
            "-0.1Nm",
            "error: --gravity: -0.1 N·m is out of range [0, 100] N·m",
        ),
        ("0.2", "error: --gravity: '0.2' has no unit"),
        ("1e9Nm", "error: --gravity: "),
    ] {
        let out = common::vsa("advise", &["--gravity", arg]);
        assert_eq!(out.status.code(), Some(2), "{arg}");
        assert!(out.stdout.is_empty(), "{arg}");
        let err = String::from_utf8(out.stderr).unwrap();
        assert_eq!(err.lines().count(), 1, "{err}");
        assert!(err.starts_with(want), "{err}");
    }
}
