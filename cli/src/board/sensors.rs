//! `vsa sensors`: the bring-up mode. Streams the raw readings of the link encoder, the gear
//! pot, the current ADC and the supply sense, and can nudge the motor open-loop at a low, bounded duty
//! (`--nudge`), so that each sensor and the motor's direction can be checked before the
//! loop is closed (docs/real-board.md). The board refuses the nudge unless the motor is
//! disabled; the nudge ends by itself.

use std::fmt::Write as _;
use std::time::{Duration, Instant};

use clap::Args;
use client::protocol::{RawSensors, NUDGE_DURATION_MAX_MS, NUDGE_DUTY_MAX_PERMILLE};
use client::{ErrorCode, Request};

use super::{out, quantities, ConnectArgs, Session};
use crate::error::{CliError, CliResult};

/// Arguments of `vsa sensors`.
#[derive(Args, Debug, Clone)]
pub struct SensorsArgs {
    /// How long to stream (a bare number is in seconds), up to 1 h
    #[arg(long, value_name = "DURATION", default_value = "2s")]
    pub seconds: String,
    /// Readings per second, 1–100
    #[arg(long, value_name = "HZ", default_value = "20")]
    pub rate: String,
    /// Nudge the motor open-loop after the first reading, e.g. 80‰, 5% or -0.08 (|·| ≤
    /// 120 ‰; only while the motor is disabled)
    #[arg(long, value_name = "DUTY", allow_hyphen_values = true)]
    pub nudge: Option<String>,
    /// How long the nudge lasts, 1 ms – 1 s [default: 300ms]
    #[arg(long, value_name = "DURATION")]
    pub nudge_for: Option<String>,
}

/// The checked arguments.
struct Plan {
    span: Duration,
    every: Duration,
    nudge: Option<(i16, u16)>,
}

fn plan(a: &SensorsArgs) -> CliResult<Plan> {
    let span = quantities::duration("sensors --seconds", &a.seconds, 3600)?;
    let rate = match a.rate.trim().parse::<u32>() {
        Ok(r @ 1..=100) => r,
        _ => {
            return Err(CliError::usage(
                "sensors --rate",
                format!("'{}' is not a rate of 1–100 readings per second", a.rate),
            ))
        }
    };
    let nudge = match &a.nudge {
        None if a.nudge_for.is_some() => {
            return Err(CliError::usage(
                "sensors --nudge-for",
                "only applies to --nudge",
            ))
        }
        None => None,
        Some(s) => {
            let (negative, magnitude) = match s.trim().strip_prefix('-') {
                Some(m) => (true, m),
                None => (false, s.trim()),
            };
            let duty = quantities::permille("sensors --nudge", magnitude)?;
            if duty > NUDGE_DUTY_MAX_PERMILLE {
                return Err(CliError::usage(
                    "sensors --nudge",
                    format!("'{s}' is above the nudge's {NUDGE_DUTY_MAX_PERMILLE}‰"),
                ));
            }
            let duty = i16::try_from(duty).unwrap_or(0);
            let span = a.nudge_for.as_deref().unwrap_or("300ms");
            let ms = quantities::duration("sensors --nudge-for", span, 1)?.as_millis();
            let ms = u16::try_from(ms).unwrap_or(NUDGE_DURATION_MAX_MS);
            Some((if negative { -duty } else { duty }, ms))
        }
    };
    Ok(Plan {
        span,
        every: Duration::from_millis(u64::from(1000 / rate)),
        nudge,
    })
}

/// Column header of the stream.
const HEADER: &str = "tick\tlink_encoder\tgear_pot\tcurrent_adc\tnudge_permille\tsupply_adc\n";

/// One reading as a row of the stream.
fn row(r: &RawSensors) -> String {
    let or_dash = |v: Option<u16>| v.map_or_else(|| "-".to_string(), |p| p.to_string());
    format!(
        "{}\t{}\t{}\t{}\t{}\t{}\n",
        r.tick,
        r.link_encoder,
        or_dash(r.gear_pot),
        r.current_adc,
        r.nudge_duty_permille,
        or_dash(r.supply_adc)
    )
}

/// Range of each reading over the stream, for the last lines.
fn summary(rows: &[RawSensors]) -> String {
    let range = |v: &mut dyn Iterator<Item = u16>| {
        let (lo, hi) = v.fold((u16::MAX, 0), |(lo, hi), x| (lo.min(x), hi.max(x)));
        if lo > hi {
            "-".to_string()
        } else {
            format!("{lo}..{hi}")
        }
    };
    let mut s = String::new();
    let _ = writeln!(
        s,
        "{} readings; link encoder {} counts, gear pot {} counts, current ADC {} counts, \
         supply {} counts ({} mV a count)",
        rows.len(),
        range(&mut rows.iter().map(|r| r.link_encoder)),
        range(&mut rows.iter().filter_map(|r| r.gear_pot)),
        range(&mut rows.iter().map(|r| r.current_adc)),
        range(&mut rows.iter().filter_map(|r| r.supply_adc)),
        model::sensors::SUPPLY_MV_PER_COUNT,
    );
    s
}

/// How long a board that has no reading yet (its control tick has not run since it came
/// up: it answers busy) is asked again, 1 ms apart, before `vsa sensors` gives up.
const FIRST_TICK_WAIT: Duration = Duration::from_millis(200);

/// The raw readings of the last control tick; waits out a board whose control tick has
/// not run yet.
fn read(s: &mut Session) -> CliResult<RawSensors> {
    match s
        .client
        .request_while_busy(Request::GetSensors, FIRST_TICK_WAIT)
    {
        Ok(client::Reply::Sensors(r)) => Ok(r),
        Err(client::Error::Refused {
            code: ErrorCode::Busy,
            ..
        }) => Err(CliError::runtime(format!(
            "the board had no reading within {} ms: has its control loop started?",
            FIRST_TICK_WAIT.as_millis()
        ))),
        Ok(other) => Err(CliError::runtime(format!(
            "unexpected reply to get-sensors: {other:?}"
        ))),
        Err(e) => Err(s.fail(&e)),
    }
}

/// Starts the nudge.
fn nudge(s: &mut Session, duty_permille: i16, duration_ms: u16) -> CliResult<()> {
    let req = Request::Nudge {
        duty_permille,
        duration_ms,
    };
    match s.client.request(req) {
        Ok(client::Reply::Ok) => Ok(()),
        Err(client::Error::Refused {
            code: ErrorCode::NotAllowed,
            ..
        }) => Err(CliError::runtime(
            "the board refused the nudge: the motor must be disabled with no fault latched \
             (`vsa disable`, `vsa clear`)",
        )),
        Ok(other) => Err(CliError::runtime(format!(
            "unexpected reply to nudge: {other:?}"
        ))),
        Err(e) => Err(s.fail(&e)),
    }
}

/// Runs `vsa sensors`.
pub fn run(a: &SensorsArgs, conn: &ConnectArgs) -> CliResult<()> {
    let p = plan(a)?;
    let mut s = Session::open(conn)?;
    out(HEADER);
    let start = Instant::now();
    let mut rows = Vec::new();
    let mut next = start;
    while start.elapsed() <= p.span {
        let r = read(&mut s)?;
        out(&row(&r));
        if rows.is_empty() {
            if let Some((duty, ms)) = p.nudge {
                nudge(&mut s, duty, ms)?;
            }
        }
        rows.push(r);
        next += p.every;
        if let Some(wait) = next.checked_duration_since(Instant::now()) {
            s.client.wait(wait).map_err(|e| s.fail(&e))?;
        }
    }
    out(&summary(&rows));
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn args(nudge: Option<&str>, nudge_for: Option<&str>, rate: &str) -> SensorsArgs {
        SensorsArgs {
            seconds: "1".into(),
            rate: rate.into(),
            nudge: nudge.map(str::to_string),
            nudge_for: nudge_for.map(str::to_string),
        }
    }

    #[test]
    fn nudges_are_signed_bounded_and_short() {
        let p = plan(&args(Some("-80‰"), Some("250ms"), "20")).unwrap();
        assert_eq!(p.nudge, Some((-80, 250)));
        assert_eq!(p.every, Duration::from_millis(50));
        let p = plan(&args(Some("12%"), Some("1s"), "1")).unwrap();
        assert_eq!(p.nudge, Some((120, 1000)));
        assert_eq!(
            plan(&args(Some("5%"), None, "1")).unwrap().nudge,
            Some((50, 300))
        );
        for bad in ["13%", "0", "-0.2", "fast"] {
            let e = plan(&args(Some(bad), None, "20")).err().unwrap();
            assert_eq!(e.code, 2, "{bad}");
        }
        assert!(plan(&args(Some("5%"), Some("2s"), "20")).is_err());
        assert!(plan(&args(None, Some("300ms"), "20")).is_err());
        assert!(plan(&args(None, None, "0")).is_err());
        assert!(plan(&args(None, None, "101")).is_err());
    }

    #[test]
    fn rows_and_summary() {
        let r = RawSensors {
            tick: 7,
            link_encoder: 4095,
            gear_pot: None,
            current_adc: 2050,
            supply_adc: Some(2400),
            nudge_duty_permille: -40,
        };
        assert_eq!(row(&r), "7\t4095\t-\t2050\t-40\t2400\n");
        let rows = [
            r,
            RawSensors {
                link_encoder: 3,
                ..r
            },
        ];
        assert_eq!(
            summary(&rows),
            "2 readings; link encoder 3..4095 counts, gear pot - counts, current ADC 2050..2050 \
             counts, supply 2400..2400 counts (5 mV a count)\n"
        );
    }
}
