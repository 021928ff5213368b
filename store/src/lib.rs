//! Settings store (docs below are filled in).
#![cfg_attr(not(test), no_std)]
#![forbid(unsafe_code)]
#![deny(missing_docs)]

mod blocking;
pub mod fault_log;
pub mod ram_flash;
pub mod records;
mod store;

pub use fault_log::{FaultLog, FAULT_LOG_LEN};
pub use ram_flash::{PowerCut, RamFlash, RamFlashError};
pub use records::{BusSettings, Calibration, Clutch, Config, FaultEntry, Record, Rejection};
pub use store::{
    Boot, FlashFault, Outcome, RangeChecks, RecordSet, Report, Store, StoreError, Validator,
    BUS_MAX, CALIBRATION_MAX, CONFIG_MAX, FAULT_MAX, SET_ITEM_MAX,
};

/// Erase page of the store, bytes: the STM32F4's small sectors (16 KiB).
pub const PAGE_SIZE: usize = 16 * 1024;
/// Program word of the store, bytes (32-bit programming, PSIZE x32).
pub const WORD_SIZE: usize = 4;
/// Erase pages of the store on every board.
pub const PAGES: usize = 2;
