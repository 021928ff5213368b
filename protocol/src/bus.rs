//! The Dynamixel bus settings from our own protocol ([`Request::SetBus`], `vsa bus`): the
//! protocol the bus speaks, the board's ID on it and the line's rate, so that a board can
//! be switched between Protocol 1.0 and 2.0 (or given a new ID) without a Dynamixel
//! client. The same settings are the control table's EEPROM registers on the bus itself.

use serde::{Deserialize, Serialize};

use crate::msg::{ErrorCode, Reply, Request};

/// A change of the Dynamixel bus settings ([`Request::SetBus`]): each field `None` keeps
/// what is in force.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct BusChange {
    /// Dynamixel protocol version, 1 or 2.
    pub protocol_version: Option<u8>,
    /// ID on the bus (the device checks its table's range: 0–253 in Protocol 1.0, 0–252
    /// in 2.0; 0xFE is the broadcast ID).
    pub id: Option<u8>,
    /// The line's rate, bit/s (the device checks that the protocol's Baud Rate register
    /// selects it and that its UART makes it).
    pub baud_bps: Option<u32>,
}

impl BusChange {
    /// Whether at least one field is given, the protocol is 1 or 2 and the rate above 0
    /// (the ID's range is the device's control table's).
    #[must_use]
    pub const fn is_valid(&self) -> bool {
        let protocol_ok = match self.protocol_version {
            Some(v) => v == 1 || v == 2,
            None => true,
        };
        let baud_ok = match self.baud_bps {
            Some(b) => b > 0,
            None => true,
        };
        let any = self.protocol_version.is_some() || self.id.is_some() || self.baud_bps.is_some();
        any && protocol_ok && baud_ok
    }
}

/// What the handler asks of the device for [`Request::SetBus`] (part of [`crate::Device`];
/// refused with [`ErrorCode::NotAllowed`] by a device without a bus).
pub(crate) fn dispatch<D: crate::Device + ?Sized>(
    req: Request,
    dev: &mut D,
) -> Result<Reply, ErrorCode> {
    match req {
        Request::SetBus(change) => dev.set_bus(&change).map(|()| Reply::Ok),
        _ => Err(ErrorCode::UnknownMessage),
    }
}
