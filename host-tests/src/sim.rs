//! Closed-loop scenarios of issue 4 on top of [`plant::harness`]: the paper preset at a
//! clutch length, J_link = 1e-3 kg·m², and the commands and loads of the acceptance tests.

use model::control::{Command, Config};
use model::{Angle, Frequency, Length};
use plant::harness::{self, Metrics, Sample, Scenario};

pub use plant::ENCODER_COUNT_RAD as COUNT_RAD;

/// The step of the acceptance tests, rad.
pub const STEP_RAD: &str = "0.5";
/// Constant load of the acceptance tests, N·m; negative: it opposes the positive step.
pub const LOAD_NM: f32 = -0.3;

/// Controller configuration: paper preset at L = `l_mm` mm.
#[must_use]
pub fn config(l_mm: i32) -> Config {
    Config::paper(Length::from_int(l_mm))
}

/// `v` rad as an [`Angle`] (host only: from a decimal string, rounded to the µrad).
#[must_use]
pub fn rad(v: &str) -> Angle {
    let x: f64 = v.parse().unwrap_or(0.0);
    Angle::from_micro((x * 1e6).round() as i64).unwrap_or(Angle::ZERO)
}

/// Minimum-jerk move to `target` in `ms`.
#[must_use]
pub fn min_jerk(target: &str, ms: u32) -> Command {
    Command::Move {
        target: rad(target),
        duration_ms: ms,
    }
}

/// Raw step to `target`.
#[must_use]
pub fn raw_step(target: &str) -> Command {
    Command::Step {
        target: rad(target),
    }
}

/// Sine of `amp` rad at `hz` hertz.
#[must_use]
pub fn sine(amp: &str, hz: i32) -> Command {
    Command::Sine {
        amplitude: rad(amp),
        frequency: Frequency::from_bits(
            (core::f64::consts::TAU * f64::from(hz) * 4_294_967_296.0).round() as i64,
        ),
    }
}

/// The acceptance scenario: hold 0.5 s with the load, then `command`, run 2 s.
#[must_use]
pub fn scenario(l_mm: i32, command: Command, load_nm: f32) -> Scenario {
    let mut sc = Scenario::new(config(l_mm), command);
    sc.load_nm = load_nm;
    sc
}

/// Runs `sc`, discarding the samples.
///
/// # Panics
/// If the controller rejects the scenario (a test bug).
#[must_use]
pub fn run(sc: &Scenario) -> Metrics {
    harness::run(sc, |_| {}).expect("scenario accepted")
}

/// Runs `sc` and also returns the per-tick samples.
///
/// # Panics
/// If the controller rejects the scenario (a test bug).
#[must_use]
pub fn run_collect(sc: &Scenario) -> (Metrics, Vec<Sample>) {
    let mut v = Vec::new();
    let m = harness::run(sc, |s| v.push(*s)).expect("scenario accepted");
    (m, v)
}

/// One line of figures.
#[must_use]
pub fn describe(label: &str, m: &Metrics) -> String {
    format!(
        "{label}: overshoot {:.2} %, rise {}, settle {}, steady |e| ≤ {:.2} counts \
         (duty span {}, count span {}), peak stress {:.0} MPa = {:.3} σ_allow, \
         peak τ {:.3} N·m, rms {:.2e} rad, max |e| {:.2e} rad, limits T{} I{} D{}, hash {:016x}",
        m.overshoot_pct,
        m.rise_time_s
            .map_or("-".into(), |t| format!("{:.0} ms", t * 1e3)),
        m.settling_time_s
            .map_or("never".into(), |t| format!("{:.0} ms", t * 1e3)),
        m.steady_state_error_counts,
        m.steady_duty_span,
        m.steady_count_span,
        m.peak_stress_pa / 1e6,
        m.peak_stress_ratio,
        m.peak_spring_torque_nm,
        m.rms_error_rad,
        m.max_error_rad,
        u8::from(m.torque_limited),
        u8::from(m.current_limited),
        u8::from(m.duty_saturated),
        m.output_hash,
    )
}
