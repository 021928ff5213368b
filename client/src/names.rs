//! Names of requests, states and faults, for messages and status reports.

use protocol::{FaultCode, FaultRecord, Request, State};

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
}
