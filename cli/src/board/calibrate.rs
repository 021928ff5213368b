//! `vsa calibrate [--json] [--show]`: runs the board's calibration sequence of a real
//! build (docs/calibration.md) with a progress bar, then prints what it found; `--show`
//! prints the calibration in force without running one. A failure prints its name and
//! what to check, and exits 1 (the board has turned the motor off).

use std::fmt::Write as _;
use std::time::{Duration, Instant};

use clap::Args;
use client::protocol::{Calibration, CalibrationProgress, CalibrationReport};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use model::calibration::sequence::Failure;

use super::quantities::show;
use super::{out, Session};
use crate::error::{CliError, CliResult};

/// Arguments of `vsa calibrate`.
#[derive(Args, Debug, Clone, Copy)]
pub struct CalibrateArgs {
    /// Print one JSON object (`status` "ok" or the failure's name, and the values found)
    #[arg(long)]
    pub json: bool,
    /// Print the calibration in force (stored) instead of running the sequence
    #[arg(long)]
    pub show: bool,
}

/// How often the progress is asked for.
const POLL: Duration = Duration::from_millis(100);
/// Longest wait for the board to accept the start (its sensor alignment after boot).
const READY: Duration = Duration::from_secs(2);
/// Longest time without progress before giving up (the sequence moves every few seconds).
const STALL: Duration = Duration::from_secs(30);

/// Names of the phases of `CalibrationProgress::Running`.
fn phase_name(phase: u8) -> &'static str {
    match phase {
        1 => "rest: current and pot offsets and noise",
        2 => "nudge: motor polarity, sensor directions",
        3 => "moves: resistance, back-EMF, friction, inertia, pot",
        4 => "last move: back to the middle",
        _ => "applying and storing the result",
    }
}

/// The status's calibration line.
pub fn progress_text(p: CalibrationProgress) -> String {
    match p {
        CalibrationProgress::Idle => {
            "not run since boot (`vsa calibrate --show`: the one in force)".to_string()
        }
        CalibrationProgress::Running { phase, percent } => {
            format!(
                "running, {percent} % (phase {phase}: {})",
                phase_name(phase)
            )
        }
        CalibrationProgress::Done => "done, result in force".to_string(),
        CalibrationProgress::Failed { failure } => {
            let (name, message) = failure_of(failure);
            format!("failed ({name}): {message}")
        }
    }
}

/// Runs `vsa calibrate`.
///
/// # Errors
/// A refusal or a lost connection, a failed calibration (named, with what to check), or
/// `--show` on a board that has none.
pub fn run(s: &mut Session, a: &CalibrateArgs) -> CliResult<()> {
    let report = if a.show {
        s.client.calibration().map_err(|e| s.fail(&e))?
    } else {
        calibrate(s, a.json)?
    };
    let failure = match report.progress {
        CalibrationProgress::Failed { failure } if !a.show => Some(failure),
        _ => None,
    };
    let cal = if failure.is_some() {
        None
    } else {
        report.calibration
    };
    if a.show && cal.is_none() {
        return Err(CliError::runtime(
            "the board has no calibration: run `vsa calibrate` with the motor disabled",
        ));
    }
    let failure = failure.map(failure_of);
    // The board's word that the sequence's drive has ended: the open-loop duty it
    // applied in its last tick (not asked for with `--show`).
    let duty = if a.show { None } else { Some(applied_duty(s)?) };
    // The resistance in force, mΩ, from the calibration's and the tracked ratio.
    let tracked = cal.as_ref().and_then(|c| {
        report.tracked_resistance_permille.map(|p| {
            u32::try_from(u64::from(c.resistance_mohm) * u64::from(p) / 1000).unwrap_or(u32::MAX)
        })
    });
    out(&if a.json {
        json(cal.as_ref(), tracked, failure, duty)
    } else {
        text(cal.as_ref(), tracked, failure, duty)
    });
    match failure {
        Some((name, message)) => {
            // The supervisor's fault, named (`fault`).
            let first = s.client.status().ok().and_then(|st| st.first_fault);
            let detail = first.map_or_else(String::new, |f| {
                format!(" (first fault: {})", client::describe_fault(&f))
            });
            Err(CliError::runtime(format!(
                "calibration failed ({name}): {message}{detail}"
            )))
        }
        None => Ok(()),
    }
}

/// Starts the sequence and follows it to its end with a progress bar (on stderr, hidden
/// with `--json` or when stderr is not a terminal).
fn calibrate(s: &mut Session, quiet: bool) -> CliResult<CalibrationReport> {
    start(s)?;
    let bar = if quiet {
        ProgressBar::with_draw_target(Some(100), ProgressDrawTarget::hidden())
    } else {
        ProgressBar::new(100)
    };
    bar.set_style(
        ProgressStyle::with_template("calibrating [{bar:40}] {pos:>2} % {msg}")
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    let mut last = (0u8, 0u8);
    let mut since = Instant::now();
    loop {
        let report = s.client.calibration().map_err(|e| {
            bar.abandon();
            s.fail(&e)
        })?;
        let CalibrationProgress::Running { phase, percent } = report.progress else {
            bar.finish_and_clear();
            return Ok(report);
        };
        if (phase, percent) != last {
            last = (phase, percent);
            since = Instant::now();
            bar.set_position(percent.into());
            bar.set_message(phase_name(phase));
        } else if since.elapsed() > STALL {
            bar.abandon();
            // The motor must not be left to a run nobody follows.
            let _ = s.client.calibrate(false);
            return Err(CliError::runtime(format!(
                "the calibration made no progress for {} s (stopped; the motor is off)",
                STALL.as_secs()
            )));
        }
        s.client.wait(POLL).map_err(|e| s.fail(&e))?;
    }
}

/// Starts the sequence. Right after boot (or a new correction) the board aligns its
/// sensors for a few ticks first and refuses: asked again for up to [`READY`].
fn start(s: &mut Session) -> CliResult<()> {
    let since = Instant::now();
    loop {
        match s.client.calibrate(true) {
            Ok(()) => return Ok(()),
            Err(client::Error::Refused {
                code: client::ErrorCode::NotAllowed,
                ..
            }) => {
                let st = s.client.status().map_err(|e| s.fail(&e))?;
                let idle = st.state == client::State::Disabled && st.faults.is_empty();
                if !idle || since.elapsed() > READY {
                    return Err(CliError::runtime(
                        "the board refused to calibrate: the motor must be disabled with no \
                         fault latched (`vsa disable`, `vsa clear`)",
                    ));
                }
                s.client.wait(POLL).map_err(|e| s.fail(&e))?;
            }
            Err(e) => return Err(s.fail(&e)),
        }
    }
}

/// The open-loop duty the board applied in its last tick, ‰.
fn applied_duty(s: &mut Session) -> CliResult<i16> {
    match s.client.request(client::Request::GetSensors) {
        Ok(client::Reply::Sensors(r)) => Ok(r.nudge_duty_permille),
        Ok(reply) => Err(s.fail(&client::Error::UnexpectedReply {
            request: "get-sensors",
            reply,
        })),
        Err(e) => Err(s.fail(&e)),
    }
}

/// The failure's name and message from its wire code.
fn failure_of(code: u8) -> (&'static str, &'static str) {
    Failure::from_code(code).map_or(
        (
            "unknown",
            "the board reported a failure this tool does not know",
        ),
        |f| (f.name(), f.message()),
    )
}

/// Offset in counts or the stiffness's fields, or null.
fn opt(v: Option<f64>) -> serde_json::Value {
    v.map_or(serde_json::Value::Null, serde_json::Value::from)
}

/// The JSON object (one line); `tracked` the resistance in force instead of the
/// calibration's, mΩ.
fn json(
    cal: Option<&Calibration>,
    tracked: Option<u32>,
    failure: Option<(&str, &str)>,
    duty: Option<i16>,
) -> String {
    let f = |g: fn(&Calibration) -> f64| opt(cal.map(g));
    let stiffness = cal.and_then(|c| c.stiffness_mnm_per_rad);
    let v = serde_json::json!({
        "status": failure.map_or("ok", |(name, _)| name),
        "message": failure.map(|(_, m)| m),
        "motor_duty_permille": duty,
        "motor_polarity": f(|c| c.motor_polarity.into()),
        "encoder_direction": f(|c| c.encoder_direction.into()),
        "pot_direction": f(|c| c.pot_direction.into()),
        "current_offset_counts": f(|c| c.current_offset_counts.into()),
        "pot_offset_counts": f(|c| c.pot_offset_counts.into()),
        "resistance_ohm": f(|c| f64::from(c.resistance_mohm) * 1e-3),
        "tracked_resistance_ohm": opt(tracked.map(|r| f64::from(r) * 1e-3)),
        "back_emf_v_s_per_rad": f(|c| f64::from(c.back_emf_uv_s_per_rad) * 1e-6),
        "gear_friction_nm": f(|c| f64::from(c.gear_friction_unm) * 1e-6),
        "link_inertia_kg_m2": f(|c| f64::from(c.link_inertia_kg_mm2) * 1e-6),
        "stiffness_nm_per_rad": opt(stiffness.map(|k| f64::from(k) * 1e-3)),
        "clutch_length_m": opt(cal.and_then(|c| c.clutch_length_um).map(|l| f64::from(l) * 1e-6)),
        "stiffness_uncertainty_pct": opt(stiffness.and(cal.map(|c| f64::from(c.stiffness_uncertainty_permille) * 0.1))),
    });
    format!("{v}\n")
}

fn sign_text(v: i8, plus: &str, minus: &str) -> String {
    format!("{v:+} ({})", if v < 0 { minus } else { plus })
}

/// The result as aligned `name  value` lines; `tracked` the resistance in force instead of
/// the calibration's, mΩ.
fn text(
    cal: Option<&Calibration>,
    tracked: Option<u32>,
    failure: Option<(&str, &str)>,
    duty: Option<i16>,
) -> String {
    let mut s = String::new();
    if let Some((name, message)) = failure {
        let _ = writeln!(s, "calibration failed: {name}\n{message}");
        match duty {
            Some(0) => s.push_str("the motor is off\n"),
            Some(d) => {
                let _ = writeln!(s, "the board still drives the motor at {d} ‰: disable it");
            }
            None => {}
        }
        return s;
    }
    let Some(c) = cal else {
        return s;
    };
    let now = tracked.map_or_else(String::new, |r| {
        format!(
            "; {} Ω in force, as a held link showed it since (not stored)",
            show(r.into(), 3)
        )
    });
    let rows = [
        (
            "motor polarity",
            sign_text(c.motor_polarity, "as wired", "reversed in software"),
        ),
        (
            "encoder direction",
            sign_text(c.encoder_direction, "the reference", "reversed"),
        ),
        (
            "pot direction",
            sign_text(c.pot_direction, "as the encoder", "reversed in software"),
        ),
        (
            "current offset",
            format!("{} ADC counts", c.current_offset_counts),
        ),
        (
            "pot offset",
            format!(
                "{} counts (the pot's electrical centre is the zero)",
                c.pot_offset_counts
            ),
        ),
        (
            "resistance",
            format!(
                "{} Ω (as the current sense sees it){now}",
                show(c.resistance_mohm.into(), 3)
            ),
        ),
        (
            "back-EMF",
            format!("{} V·s/rad", show(c.back_emf_uv_s_per_rad.into(), 6)),
        ),
        (
            "gear friction",
            format!("{} N·m", show(c.gear_friction_unm.into(), 6)),
        ),
        (
            "link inertia",
            format!("{} kg·m²", show(c.link_inertia_kg_mm2.into(), 6)),
        ),
        (
            "stiffness",
            match (c.stiffness_mnm_per_rad, c.clutch_length_um) {
                (Some(k), Some(l)) => format!(
                    "{} N·m/rad ± {} %, clutch {} mm",
                    show(k.into(), 3),
                    show(c.stiffness_uncertainty_permille.into(), 1),
                    show(l.into(), 3)
                ),
                _ => "not resolvable with a free link (the clutch monitor estimates it in use)"
                    .to_string(),
            },
        ),
    ];
    for (name, value) in rows {
        let _ = writeln!(s, "{name:<18} {value}");
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    const CAL: Calibration = Calibration {
        motor_polarity: -1,
        encoder_direction: 1,
        pot_direction: -1,
        current_offset_counts: -250,
        pot_offset_counts: 0,
        resistance_mohm: 7_840,
        back_emf_uv_s_per_rad: 1_943_000,
        gear_friction_unm: 12_000,
        link_inertia_kg_mm2: 1_020,
        stiffness_mnm_per_rad: None,
        clutch_length_um: None,
        stiffness_uncertainty_permille: 1000,
    };

    #[test]
    fn json_has_every_field_in_si_units() {
        let v: serde_json::Value =
            serde_json::from_str(&json(Some(&CAL), None, None, Some(0))).unwrap();
        assert_eq!(v["status"], "ok");
        assert_eq!(v["motor_polarity"], -1.0);
        assert_eq!(v["current_offset_counts"], -250.0);
        assert!((v["resistance_ohm"].as_f64().unwrap() - 7.84).abs() < 1e-12);
        assert!((v["back_emf_v_s_per_rad"].as_f64().unwrap() - 1.943).abs() < 1e-12);
        assert!((v["link_inertia_kg_m2"].as_f64().unwrap() - 1.02e-3).abs() < 1e-12);
        assert!(v["stiffness_nm_per_rad"].is_null());
        assert!(v["clutch_length_m"].is_null());
        assert!(v["stiffness_uncertainty_pct"].is_null());
        assert!(v["tracked_resistance_ohm"].is_null());
    }

    #[test]
    fn a_tracked_resistance_is_shown_beside_the_calibrations() {
        let v: serde_json::Value =
            serde_json::from_str(&json(Some(&CAL), Some(10_192), None, None)).unwrap();
        assert!((v["resistance_ohm"].as_f64().unwrap() - 7.84).abs() < 1e-12);
        assert!((v["tracked_resistance_ohm"].as_f64().unwrap() - 10.192).abs() < 1e-12);
        let t = text(Some(&CAL), Some(10_192), None, None);
        assert!(
            t.contains("7.84 Ω (as the current sense sees it); 10.192 Ω in force"),
            "{t}"
        );
        assert!(!text(Some(&CAL), None, None, None).contains("in force"));
    }

    #[test]
    fn a_failure_is_named_with_its_message() {
        let code = Failure::EncoderDead.code();
        let f = failure_of(code);
        let v: serde_json::Value =
            serde_json::from_str(&json(None, None, Some(f), Some(0))).unwrap();
        assert_eq!(v["status"], "encoder-dead");
        assert!(v["message"].as_str().unwrap().contains("link encoder"));
        assert!(v["resistance_ohm"].is_null());
        assert_eq!(v["motor_duty_permille"], 0);
        assert!(text(None, None, Some(f), Some(0)).contains("the motor is off"));
        assert!(text(None, None, Some(f), Some(80)).contains("still drives"));
        assert_eq!(failure_of(0).0, "unknown");
    }
}
