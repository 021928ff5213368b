//! The settings store of the vsa firmware: configuration, calibration, bus identity and a
//! fault log in internal flash, power-fail safe.
//!
//! `no_std`, allocation-free, `unsafe`-free. Built on [`sequential_storage`]'s map (CRC-checked
//! items appended to erase pages used in turn: wear levelling, and repair after an
//! interrupted operation) over any `embedded_storage` [`NorFlash`](embedded_storage::nor_flash::NorFlash)
//! of [`PAGES`] pages.
//!
//! # API
//!
//! ```
//! use store::{Clutch, Config, PowerCut, RamFlash, RangeChecks, RecordSet, Store, PAGES};
//!
//! let (mut store, boot) = Store::open(RamFlash::<PAGES>::new(), &RangeChecks)?;
//! for (record, outcome) in boot.report.lines() {
//!     println!("store: {record}: {outcome}"); // "config: nothing stored, defaults"
//! }
//! let config = Config {
//!     clutch: Clutch::LengthUm(3_000),
//!     link_inertia_kg_mm2: 1_000,
//!     gains: None,
//!     limits: protocol::Limits::DEFAULT,
//!     command_timeout_ms: 100,
//! };
//! let set = RecordSet { config: Some(config), ..RecordSet::default() };
//! store.save(&set, &RangeChecks)?;
//! // Power off, power on: the emulated boards keep the bytes in a host file.
//! let bytes = store.flash().as_bytes().to_vec();
//! let (_, boot) = Store::open(RamFlash::<PAGES>::from_bytes(&bytes).unwrap(), &RangeChecks)?;
//! assert_eq!(boot.set.config, Some(config));
//! # Ok::<(), store::StoreError>(())
//! ```
//!
//! * [`Store::open`] loads at once and never fails because of what the flash holds: each
//!   record comes back [`Outcome::Loaded`], [`Outcome::Default`] (nothing stored) or
//!   [`Outcome::Rejected`] with a [`Rejection`] (unknown schema version, undecodable, a check
//!   failed, a flash error); only loaded records are in [`Boot::set`]. One log line per
//!   record: [`Report::lines`].
//! * [`Store::save`] checks, then writes the whole [`RecordSet`]; [`Store::load`] re-reads;
//!   [`Store::factory_reset`] forgets the records and the fault log; [`Store::log_fault`]
//!   appends a latched fault; [`Store::stored`] is the stored set, to tell whether the
//!   running configuration differs from it.
//! * Checks: every record's own [`Record::check`] (the protocol's ranges:
//!   [`protocol::Request::validate`] on the equivalent request, `Limits::is_valid`, ...) and
//!   then the caller's [`Validator`] (what needs the device: the design's clutch range,
//!   L(k), the UART's baud rates). The firmware passes the checks it applies to the same
//!   requests over the wire; [`RangeChecks`] adds nothing.
//! * The map's operations are async (sequential-storage 8); the flash here is blocking, so
//!   every future completes in its first poll and the store runs them with
//!   `embassy_futures::block_on`. The firmware calls the store's blocking methods from its
//!   command task (an RTIC software task below the control task's priority).
//!
//! # Records
//!
//! Every stored record is `[schema version: u8] ++ postcard(fields)`; integers in the
//! protocol's units (`protocol` crate docs, "Units on the wire").
//!
//! | record | version | fields (unit) | largest |
//! |---|---|---|---|
//! | [`Config`] | 2 | clutch: length µm or stiffness mN·m/rad; link inertia kg·mm²; gains (10⁻³ of the controller's units) or automatic; [`protocol::Limits`] (torque margin ‰, current mA, motor torque µN·m, duty ‰, position window µrad, clutch tolerance µm); command timeout ms | [`CONFIG_MAX`] = 75 B |
//! | [`Calibration`] | 2 | motor polarity, encoder and pot directions ±1; current offset ADC counts; pot offset counts; resistance mΩ; back-EMF µV·s/rad; gear friction µN·m; link inertia kg·mm²; stiffness mN·m/rad or unresolved; clutch length µm or unresolved; stiffness uncertainty ‰; encoder counts per turn; pot and current-sense gains ppm; the pot's error table or none | [`CALIBRATION_MAX`] = 107 B |
//! | [`BusSettings`] | 2 | Dynamixel ID; baud bit/s; protocol 1 or 2; return delay × 2 µs; status return level 0–2; CW and CCW angle limits (AX units, 0–1023); the other EEPROM-area registers ([`BusLimits`]: max torque, temperature and voltage limits, alarm LED, shutdown, X velocity and position limits) in their registers' units; ranges and defaults from `dynamixel::table` | [`BUS_MAX`] = 33 B |
//! | [`FaultEntry`] | 1 | number since the last factory reset; [`protocol::FaultRecord`] (code, value, uptime ms) | [`FAULT_MAX`] = 17 B |
//!
//! A record of another version goes through [`Record::migrate`]: an older one the firmware
//! knows is converted (configuration and calibration version 1), any other is rejected
//! (`schema version 3 unknown (this firmware: 2)`) and the defaults are used — never
//! decoded as the current layout. A test pins the config's bytes to its version.
//!
//! # In flash, and power cuts
//!
//! | map key | item |
//! |---|---|
//! | 1 | the record set: `[format 1] ++ postcard(generation, fault floor, config, calibration, bus)`, each record's bytes (empty: not stored), ≤ [`SET_ITEM_MAX`] = 147 B |
//! | 0x10–0x1F | fault-log slot `seq % 16`: one [`FaultEntry`] |
//!
//! * **A save is atomic** because the whole set is one map item: sequential-storage writes
//!   an item's data, then its header with the data's CRC, and skips an item whose CRC does
//!   not match, so a cut save leaves the previous set in force — the old set or the new one,
//!   whole, with its own generation; never a mix (a multi-record save as several items could
//!   leave the config new and the calibration old). The cost: each save rewrites every
//!   record (≤ 147 B).
//! * **A factory reset is a save** of an empty set whose fault floor is above every logged
//!   fault: just as atomic, and it clears the fault log with it (an erase of both pages
//!   could, cut half-way, bring back an older set from the page not yet erased).
//! * **The fault log is a ring** of 16 keys: a fault is one small item; a cut loses at most
//!   that fault.
//! * **Reclaiming a page** (when the active page is full) copies its still-current items
//!   forward, then erases it; sequential-storage resumes an interrupted reclaim at the next
//!   operation.
//! * Whatever the flash holds (random bytes, all zeros), the store opens with nothing
//!   applied, and a factory reset (which erases what it cannot write over) recovers it.
//! * The tests cut the power after every word write and in every erase of a save, of a
//!   reclaiming save, of a factory reset and of a fault write, and
//!   run random sequences of saves, cuts, resets and faults (`tests/power_fail.rs`); the
//!   same histories, cut at any byte (torn words, torn erases), on sequential-storage's own
//!   mock flash, an independent model (`tests/mock_flash.rs`); 1 000 saves wear both pages
//!   evenly (`tests/wear.rs`).
//!
//! # The STM32F4's flash and the 1 kHz loop (docs/design.md §10)
//!
//! Programming or erasing the F4's flash stalls instruction fetch from it: a word program
//! takes ~16 µs, a 16 KiB sector erase 0.25–0.5 s, a 128 KiB one 1–2 s. The loop runs from
//! flash, so:
//!
//! * **Saves, resets and fault-log writes only while the motor is disabled.** `save` and
//!   `factory-reset` while enabled are refused with `not-allowed`; a latched fault disables
//!   the motor first, so the fault-log write that follows it finds it disabled. While the
//!   bridge is off a stalled tick moves nothing. The stall holds the CPU before the control
//!   tick can start, so the SysTick periods it spans coalesce into one late tick (ticks
//!   lost in the once-a-second count) rather than a tick that overruns its own deadline;
//!   that is the expectation on the Nucleo, not yet measured there. The emulated boards'
//!   RAM flash does not stall: there `cargo xtask persistence` shows 0 missed deadlines
//!   over 1 000 saves.
//! * **Small sectors:** the store is [`PAGES`] = 2 pages of [`PAGE_SIZE`] = 16 KiB: on the
//!   F446RE, **sectors 1 and 2** (0x0800_4000–0x0800_BFFF). The 16 KiB sectors erase in
//!   0.25–0.5 s rather than 1–2 s; sector 0 must hold the vector table (the boot address);
//!   sequential-storage needs equal pages, so not sector 4 (64 KiB) with them; two pages
//!   are the map's minimum and hold the live data (one set item + 16 faults ≈ 0.5 KiB)
//!   many times over. A page fills in ≈ 200 saves (a full set: ≈ 80 B with the item
//!   header), so each page is erased once per ≈ 400 saves (1 000 saves: erase counts
//!   `[2, 2]`, `tests/wear.rs`): with the F4's 10 000 erase cycles per sector, ≈ 4 million
//!   saves.
//! * **Word-wide writes:** [`WORD_SIZE`] = 4, the store's write unit on every board.
//!   `stm32f4xx-hal`'s `NorFlash` erases in 128 KiB units (`ERASE_SIZE`), so the Nucleo
//!   has a small `NorFlash` over `UnlockedFlash` (`firmware/src/board/nucleo_flash.rs`)
//!   presenting sectors 1–2 as offsets 0..32 KiB with `ERASE_SIZE` = 16 KiB (erase = the
//!   HAL's `erase(sector)`) and `WRITE_SIZE` = 4 (each word's bytes programmed by the HAL's
//!   `program`, PSIZE x8) — the same geometry as [`RamFlash`], so both boards write the
//!   same format.
//!
//! The one `memory.x` then keeps the image out of sectors 1–2 by starting `.text` after
//! them (cortex-m-rt's `_stext`); sector 0 holds only the vector table:
//!
//! ```text
//! MEMORY
//! {
//!   FLASH : ORIGIN = 0x08000000, LENGTH = 512K
//!   RAM   : ORIGIN = 0x20000000, LENGTH = 128K
//! }
//! /* Sectors 1-2 (0x08004000-0x0800BFFF, 2 x 16 KiB) hold the settings store. */
//! _stext = ORIGIN(FLASH) + 48K;  /* sector 3, 0x0800C000 */
//! ```
//!
//! The emulated boards (QEMU has no flash controller) keep the same 32 KiB in a
//! [`RamFlash`], read from a host file at boot and written back after every store operation
//! over semihosting; [`PowerCut`] makes it lose power after its N-th word write.
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
pub use records::{
    BusLimits, BusSettings, Calibration, Clutch, Config, FaultEntry, Record, Rejection,
};
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
/// Longest path of the emulated boards' flash file (the firmware's `--flash`), bytes.
pub const FLASH_FILE_PATH_MAX: usize = 160;
