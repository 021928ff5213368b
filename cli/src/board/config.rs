//! `vsa config save | load | show | reset` and `vsa faults [--log]`: the board's settings
//! store (flash on the real board, a host file on an emulated one, `--qemu-flash`).

use std::fmt::Write as _;

use clap::{Args, Subcommand};
use client::protocol::LoggedFault;
use client::{describe_fault, Client};

use super::quantities::show;

/// What `vsa config` does.
#[derive(Subcommand, Debug, Clone, Copy, PartialEq, Eq)]
pub enum ConfigCommand {
    /// Store the running configuration (clutch, gains, limits) in the board's flash, for
    /// the next boot; refused while the motor is enabled
    Save,
    /// Re-read the stored configuration and apply it (unsaved changes are lost)
    Load,
    /// The running configuration, and whether it differs from the stored one
    Show,
    /// Factory reset: forget the stored settings and the fault log, back to the defaults;
    /// refused while the motor is enabled
    Reset,
}

/// Arguments of `vsa faults`.
#[derive(Args, Debug, Clone, Copy)]
pub struct FaultsArgs {
    /// The fault log kept in flash (the last 16 latched faults, across power cycles)
    /// instead of the faults latched now
    #[arg(long)]
    pub log: bool,
}

/// The status's line about the stored configuration.
pub fn stored_line(differs: bool) -> &'static str {
    if differs {
        "differs from the running one (`vsa config save` keeps it)"
    } else {
        "same as the running one"
    }
}

/// Carries out `vsa config …`; the text for stdout.
///
/// # Errors
/// The client's (a refusal names the request and the board's error code).
pub fn config(c: &mut Client, cmd: ConfigCommand) -> client::Result<String> {
    match cmd {
        ConfigCommand::Save => c
            .save()
            .map(|()| "configuration saved: the board boots with it\n".to_string()),
        ConfigCommand::Load => c
            .load()
            .map(|()| "stored configuration applied (defaults where none is stored)\n".to_string()),
        ConfigCommand::Reset => c.factory_reset().map(|()| {
            "factory reset: stored settings and fault log erased, defaults in force\n".to_string()
        }),
        ConfigCommand::Show => {
            let st = c.status()?;
            let l = c.limits()?;
            let mut s = String::new();
            let rows = [
                (
                    "clutch length",
                    format!("{} mm", show(st.clutch_length_um.into(), 3)),
                ),
                (
                    "stiffness",
                    format!("{} N·m/rad", show(st.stiffness_mnm_per_rad.into(), 3)),
                ),
                (
                    "limits",
                    format!(
                        "torque margin {}, current {} A, motor torque {} N·m, duty {}, \
                         clutch tolerance {} mm",
                        show(l.torque_margin_permille.into(), 3),
                        show(l.current_ma.into(), 3),
                        show(l.motor_torque_unm.into(), 6),
                        show(l.duty_permille.into(), 3),
                        show(l.clutch_tolerance_um.into(), 3),
                    ),
                ),
                (
                    "position window",
                    format!(
                        "[{}, {}] rad",
                        show(l.position_min_urad.into(), 6),
                        show(l.position_max_urad.into(), 6)
                    ),
                ),
                (
                    "stored config",
                    stored_line(st.differs_from_stored).to_string(),
                ),
            ];
            for (k, v) in rows {
                let _ = writeln!(s, "{k:<16} {v}");
            }
            Ok(s)
        }
    }
}

/// Carries out `vsa faults [--log]`; the text for stdout.
///
/// # Errors
/// The client's.
pub fn faults(c: &mut Client, args: FaultsArgs) -> client::Result<String> {
    if !args.log {
        let st = c.status()?;
        return Ok(match st.first_fault {
            Some(f) => format!("latched: {}\n", describe_fault(&f)),
            None => "no fault latched\n".to_string(),
        });
    }
    Ok(log_text(&c.fault_log()?))
}

/// The fault log, most recent first, one line each.
fn log_text(entries: &[LoggedFault]) -> String {
    if entries.is_empty() {
        return "fault log empty\n".to_string();
    }
    let mut s = format!("{} faults logged, most recent first:\n", entries.len());
    for e in entries {
        let _ = writeln!(s, "#{:<5} {}", e.seq, describe_fault(&e.fault));
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use client::protocol::{FaultCode, FaultRecord};

    #[test]
    fn the_log_lists_the_most_recent_first_as_given() {
        assert_eq!(log_text(&[]), "fault log empty\n");
        let e = |seq, code| LoggedFault {
            seq,
            fault: FaultRecord {
                code,
                value: 5,
                tick: 1200,
            },
        };
        let text = log_text(&[
            e(1, FaultCode::CommandTimeout),
            e(0, FaultCode::OverCurrent),
        ]);
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines.len(), 3);
        assert!(lines[1].starts_with("#1") && lines[1].contains("command-timeout"));
        assert!(lines[2].starts_with("#0") && lines[2].contains("over-current"));
    }
}
