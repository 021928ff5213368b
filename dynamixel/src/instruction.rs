//! Instruction codes (the same numbers in both protocols; the 2.0-only ones are marked).
//!
//! Parameter layouts (1.0 addresses and lengths are one byte, 2.0 ones two, little-endian):
//!
//! | instruction | parameters |
//! |---|---|
//! | [`PING`] | none |
//! | [`READ`] | address, length |
//! | [`WRITE`], [`REG_WRITE`] | address, data… |
//! | [`ACTION`] | none |
//! | [`FACTORY_RESET`] | 1.0: none; 2.0: 0xFF all, 0x01 all but ID, 0x02 all but ID and baud |
//! | [`REBOOT`] | none |
//! | [`SYNC_WRITE`] | address, length L, then (ID, L bytes) per device |
//! | [`SYNC_READ`] | address, length, then the IDs in answer order |
//! | [`BULK_READ`] | (ID, address, length) per device, in answer order |
//! | [`BULK_WRITE`] | (ID, address, length L, L bytes) per device |

/// Is the device there? (model number and firmware version in 2.0.)
pub const PING: u8 = 0x01;
/// Read a span of the control table.
pub const READ: u8 = 0x02;
/// Write a span of the control table.
pub const WRITE: u8 = 0x03;
/// Check and hold a write until ACTION (sets Registered).
pub const REG_WRITE: u8 = 0x04;
/// Carry out the held write.
pub const ACTION: u8 = 0x05;
/// Reset the settings to their defaults.
pub const FACTORY_RESET: u8 = 0x06;
/// Restart the device (2.0).
pub const REBOOT: u8 = 0x08;
/// Reset multi-turn information (2.0; not supported here: answered with an instruction
/// error).
pub const CLEAR: u8 = 0x10;
/// Same span from several devices, answered in ID-list order (2.0).
pub const SYNC_READ: u8 = 0x82;
/// Same span to several devices, never answered.
pub const SYNC_WRITE: u8 = 0x83;
/// Different spans from several devices, answered in list order (2.0).
pub const BULK_READ: u8 = 0x92;
/// Different spans to several devices, never answered (2.0).
pub const BULK_WRITE: u8 = 0x93;
