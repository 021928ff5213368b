//! `vsa bus [--protocol 1|2] [--id N] [--rate B]`: the board's Dynamixel bus settings from
//! our own protocol (`protocol::Request::SetBus`), e.g. to switch a board the SDK left in
//! Protocol 2.0 back to 1.0 without a Dynamixel client. The board applies them after its
//! reply and stores them (once the motor is off); the control table's own registers (ID 3,
//! Baud Rate 4, Protocol Type 63 / 13) change with them. With several boards on one bus,
//! talk to one board only: our protocol has no addresses.

use clap::Args;
use client::protocol::{BusChange, Request};
use client::{ErrorCode, Reply};

use super::{out, Session};
use crate::error::{CliError, CliResult};

/// Arguments of `bus` (at least one).
#[derive(Args, Debug, Clone)]
pub struct BusArgs {
    /// Dynamixel protocol the bus speaks: 1 (AX-12A, Protocol 1.0) or 2 (X series, 2.0)
    #[arg(long, value_name = "1|2")]
    pub protocol: Option<String>,
    /// ID on the bus: 0–253 in Protocol 1.0, 0–252 in 2.0
    #[arg(long, value_name = "ID")]
    pub id: Option<String>,
    /// The bus's line rate, bit/s: one the protocol's Baud Rate register selects (1.0:
    /// 2 000 000 / (n + 1); 2.0: 9600, 57600, 115200, 1000000, 2000000, …). Not --baud,
    /// which is the host port's rate
    #[arg(long, value_name = "BAUD")]
    pub rate: Option<String>,
}

/// Checks the arguments (errors name the argument); the board checks the rest.
pub fn plan(a: &BusArgs) -> CliResult<BusChange> {
    let number = |arg: &str, text: &Option<String>, max: u64| -> CliResult<Option<u64>> {
        text.as_deref()
            .map(|t| {
                t.trim()
                    .parse::<u64>()
                    .ok()
                    .filter(|v| *v <= max)
                    .ok_or_else(|| {
                        CliError::usage(arg, format!("{t:?} is not a whole number 0–{max}"))
                    })
            })
            .transpose()
    };
    let protocol = number("bus --protocol", &a.protocol, 2)?;
    if protocol == Some(0) {
        return Err(CliError::usage("bus --protocol", "0 is not 1 or 2"));
    }
    // The largest ID of either protocol (1.0's; the board checks 2.0's 252).
    let id = number("bus --id", &a.id, u64::from(dynamixel::v1::MAX_ID))?;
    let baud = number("bus --rate", &a.rate, u64::from(u32::MAX))?;
    if baud == Some(0) {
        return Err(CliError::usage("bus --rate", "0 bit/s"));
    }
    let change = BusChange {
        protocol_version: protocol.and_then(|v| u8::try_from(v).ok()),
        id: id.and_then(|v| u8::try_from(v).ok()),
        baud_bps: baud.and_then(|v| u32::try_from(v).ok()),
    };
    if !change.is_valid() {
        return Err(CliError::usage(
            "bus",
            "give at least one of --protocol, --id, --rate",
        ));
    }
    Ok(change)
}

/// Sends the change and says what the board now does.
pub fn run(s: &mut Session, change: &BusChange) -> CliResult<()> {
    match s.client.request(Request::SetBus(*change)) {
        Ok(Reply::Ok) => {
            out(&format!("bus settings changed: {}\n", describe(change)));
            Ok(())
        }
        Ok(reply) => Err(CliError::runtime(format!(
            "the board answered bus with {reply:?}"
        ))),
        Err(client::Error::Refused {
            code: ErrorCode::OutOfRange,
            ..
        }) => Err(CliError::runtime(format!(
            "the board refused bus ({}): the ID is outside the protocol's range, or the \
             protocol's Baud Rate register cannot select the rate or the board's UART \
             cannot make it",
            describe(change)
        ))),
        Err(client::Error::Refused {
            code: ErrorCode::NotAllowed,
            ..
        }) => Err(CliError::runtime(
            "the board refused bus: it does not serve a Dynamixel bus",
        )),
        Err(client::Error::Refused {
            code: ErrorCode::Storage,
            ..
        }) => Err(CliError::runtime(format!(
            "bus settings in force but not stored ({}): the board has no settings store or \
             its flash failed; they last until the next reset",
            describe(change)
        ))),
        Err(e) => Err(s.fail(&e)),
    }
}

fn describe(c: &BusChange) -> String {
    let mut parts = Vec::new();
    if let Some(p) = c.protocol_version {
        parts.push(format!("Protocol {p}.0"));
    }
    if let Some(id) = c.id {
        parts.push(format!("ID {id}"));
    }
    if let Some(b) = c.baud_bps {
        parts.push(format!("{b} bit/s"));
    }
    parts.join(", ")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn args(p: Option<&str>, id: Option<&str>, rate: Option<&str>) -> BusArgs {
        BusArgs {
            protocol: p.map(Into::into),
            id: id.map(Into::into),
            rate: rate.map(Into::into),
        }
    }

    #[test]
    fn arguments_are_checked_before_anything_is_sent() {
        let c = plan(&args(Some("2"), Some("7"), Some("57600"))).unwrap();
        assert_eq!(
            c,
            BusChange {
                protocol_version: Some(2),
                id: Some(7),
                baud_bps: Some(57_600)
            }
        );
        assert_eq!(plan(&args(Some("1"), None, None)).unwrap().id, None);
        for bad in [
            args(None, None, None),
            args(Some("0"), None, None),
            args(Some("3"), None, None),
            args(None, Some("254"), None),
            args(None, Some("-1"), None),
            args(None, None, Some("0")),
            args(None, None, Some("fast")),
        ] {
            assert!(plan(&bad).is_err(), "{bad:?}");
        }
    }
}
