//! Names of requests, states and faults, for messages and status reports.

use protocol::{FaultCode, FaultRecord, Limits, Request, State, TARGET_MAX_URAD};

/// Short name of a request, for messages (`move`, `set-clutch-length`, …).
#[must_use]
pub const fn request_name(req: &Request) -> &'static str {
    match req {
        Request::Ping => "ping",
        Request::GetStatus => "status",
        Request::Enable => "enable",
        Request::Disable => "disable",
        Request::ClearFault => "clear-fault",
        Request::SetClutchLength { .. } => "set-clutch-length",
        Request::SetStiffness { .. } => "set-stiffness",
        Request::Move { .. } => "move",
        Request::Step { .. } => "step",
        Request::Sine { .. } => "sine",
        Request::Hold => "hold",
        Request::SetGains(_) => "set-gains",
        Request::AutoGains => "auto-gains",
        Request::SetLimits(_) => "set-limits",
        Request::StreamTelemetry { .. } => "stream-telemetry",
        Request::Heartbeat => "heartbeat",
        Request::DisarmHeartbeat => "disarm-heartbeat",
        Request::GetLimits => "get-limits",
        Request::GetSensors => "get-sensors",
        Request::Nudge { .. } => "nudge",
        Request::Save => "save",
        Request::Load => "load",
        Request::FactoryReset => "factory-reset",
        Request::FaultsLog { .. } => "faults-log",
        Request::Impedance { .. } => "impedance",
        Request::SetBus(_) => "bus",
    }
}

/// The state as printed: `disabled`, `enabled`, `faulted`.
#[must_use]
pub const fn state_name(s: State) -> &'static str {
    match s {
        State::Disabled => "disabled",
        State::Enabled => "enabled",
        State::Faulted => "faulted",
    }
}

/// The fault's name as the firmware logs it (`over-current`, `command-timeout`, …).
#[must_use]
pub const fn fault_name(code: FaultCode) -> &'static str {
    code.name()
}

/// Unit of a [`FaultRecord::value`] for this fault (see [`FaultCode`]).
#[must_use]
pub const fn fault_value_unit(code: FaultCode) -> &'static str {
    match code {
        FaultCode::SensorRead => "sensor (1 link encoder, 2 gear pot, 3 current ADC)",
        FaultCode::AdcOutOfRange => "ADC counts",
        FaultCode::OverCurrent => "mA",
        FaultCode::SensorJump => "counts",
        FaultCode::SensorStuck => "µrad",
        FaultCode::BeamOverload => "µN·m or µrad",
        FaultCode::PositionLimit => "µrad",
        FaultCode::DeadlineMissed => "sysclk counts",
        FaultCode::CommandTimeout => "ms",
        FaultCode::ClutchMismatch => "‰ of the configured compliance",
    }
}

/// One line for a fault record: `over-current (code 3): 1834 mA at tick 1234`.
#[must_use]
pub fn describe_fault(r: &FaultRecord) -> String {
    let value = match r.code {
        FaultCode::SensorRead => format!(
            "sensor {} ({})",
            r.value,
            match r.value {
                1 => "link encoder",
                2 => "gear pot",
                3 => "current ADC",
                _ => "unknown",
            }
        ),
        c => format!("{} {}", r.value, fault_value_unit(c)),
    };
    format!(
        "{} (code {}): {value} at tick {}",
        fault_name(r.code),
        r.code.code(),
        r.tick
    )
}

/// µrad as a number of rad, exact, for messages: `2640000` → `2.64`.
fn rad_number(urad: i64) -> String {
    let s = format!(
        "{}{}.{:06}",
        if urad < 0 { "-" } else { "" },
        urad.unsigned_abs() / 1_000_000,
        urad.unsigned_abs() % 1_000_000
    );
    s.trim_end_matches('0').trim_end_matches('.').to_string()
}

/// µrad as rad, for messages: `2640000` → `2.64 rad`.
#[must_use]
pub fn urad_text(urad: i64) -> String {
    format!("{} rad", rad_number(urad))
}

/// Which condition of a fault still holds, its value now, and the way out short of a
/// reset, in one line (the message of a refused clear). `limits`: the limits in force, to
/// name the position window.
#[must_use]
pub fn persisting_advice(r: &FaultRecord, limits: Option<&Limits>) -> String {
    let window = limits.map_or_else(
        || "the position window".to_string(),
        |l| {
            format!(
                "the position window [{}, {}] rad",
                rad_number(l.position_min_urad.into()),
                rad_number(l.position_max_urad.into())
            )
        },
    );
    let most = urad_text(TARGET_MAX_URAD.into());
    let v = i64::from(r.value);
    let what = match r.code {
        FaultCode::PositionLimit => format!(
            "link at {}, outside {window}: move it back by hand, or widen the window \
             (`limits --position-min/--position-max`, up to ±{most}), then clear",
            urad_text(v)
        ),
        FaultCode::BeamOverload => format!(
            "the beams still carry {} µN·m or µrad of deflection, beyond their capacity: \
             take the load off the link, or move the link back by hand if it is beyond what \
             the gear pot measures (±{most} commanded at most), then clear",
            r.value
        ),
        FaultCode::OverCurrent => format!(
            "{} mA flow with the motor off: check the H-bridge and the current sensor",
            r.value
        ),
        FaultCode::AdcOutOfRange => format!(
            "the current ADC reads {} counts (a rail): check the current sensor's wiring",
            r.value
        ),
        FaultCode::SensorRead => {
            format!("sensor {} still fails to read: check its wiring", r.value)
        }
        FaultCode::SensorStuck => "the link encoder still reads frozen while the gear moves: \
             check the encoder"
            .to_string(),
        FaultCode::SensorJump => "a sensor still jumps: check its wiring".to_string(),
        FaultCode::DeadlineMissed => "the control period still overruns".to_string(),
        FaultCode::CommandTimeout => "heartbeats are still armed and late: send one, or \
             disarm them"
            .to_string(),
        FaultCode::ClutchMismatch => format!(
            "the beams are {}‰ as compliant as configured: measure the clutch length and \
             configure it (`clutch`), or slide the clutch to the configured length",
            r.value
        ),
    };
    format!(
        "{} (code {}) persists at tick {}: {what}",
        fault_name(r.code),
        r.code.code(),
        r.tick
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names() {
        for c in FaultCode::ALL {
            assert!(!fault_name(c).is_empty());
        }
        let r = FaultRecord {
            code: FaultCode::OverCurrent,
            value: 1834,
            tick: 1234,
        };
        assert_eq!(
            describe_fault(&r),
            "over-current (code 3): 1834 mA at tick 1234"
        );
        assert_eq!(request_name(&Request::Hold), "hold");
    }

    #[test]
    fn advice_names_the_value_the_window_and_the_way_out() {
        let r = FaultRecord {
            code: FaultCode::PositionLimit,
            value: 2_640_000,
            tick: 77,
        };
        let s = persisting_advice(&r, Some(&Limits::DEFAULT));
        assert!(
            s.starts_with(
                "position-limit (code 7) persists at tick 77: link at 2.64 rad, outside the \
                 position window [-2.5, 2.5] rad: move it back by hand, or widen the window"
            ),
            "{s}"
        );
        assert_eq!(urad_text(-500), "-0.0005 rad");
    }
}
