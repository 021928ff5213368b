//! The emulated boards' settings store: QEMU has no flash controller, so the store runs on
//! a [`RamFlash`] (the same 2 × 16 KiB pages as the Nucleo's sectors 1–2) whose contents
//! are read at boot from a host file and written back to it after every store operation,
//! through semihosting (`--flash PATH`): "power off, power on" is two runs with one file.
//!
//! `--flash-cut-after N` makes the RAM flash lose power after its N-th word write since
//! boot: the operation in progress fails, the file gets exactly the words written so far,
//! and the firmware exits at once with status [`POWER_CUT_EXIT`] — what a brown-out in the
//! middle of a save leaves behind, for the next boot to load.

use core::ffi::CStr;

use semihosting::io::{Read, Write};
use service::store::{Checks, Storage};
use store::{FaultLog, PowerCut, RamFlash, RecordSet, Store, StoreError, PAGES};

use crate::run_config::{RunConfig, FLASH_PATH_MAX};

/// The RAM flash (32 KiB; in `.data`).
pub type SettingsFlash = RamFlash<PAGES>;
/// Its value before boot fills it (from the file, or erased).
pub const SETTINGS_FLASH: SettingsFlash = RamFlash::ZEROED;

/// QEMU's exit status when an injected power cut ended the run.
pub const POWER_CUT_EXIT: i32 = 3;

/// The store over the RAM flash, mirrored to the host file.
pub struct SettingsStore {
    store: Store<&'static mut SettingsFlash>,
    /// `--flash` as a C string (NUL-terminated), if given.
    path: Option<heapless::Vec<u8, { FLASH_PATH_MAX + 1 }>>,
    /// Erase counts when the store opened (the boot's own erase of the RAM is not wear).
    erases_at_open: [u32; PAGES],
}

/// Opens the store on `flash` for `run`: reads the `--flash` file into it (an absent or
/// empty file is an erased flash; one of another size is ignored with a warning), arms
/// the power cut. `None` (no store) in a scenario run without `--flash`.
pub fn open(
    flash: &'static mut SettingsFlash,
    slot: &'static mut Option<SettingsStore>,
    run: &RunConfig,
) -> Option<&'static mut (dyn Storage + Send)> {
    if run.flash_file.is_none() && !run.serve {
        return None;
    }
    flash.erase_all();
    let path = run.flash_file.as_ref().and_then(|p| {
        let mut c: heapless::Vec<u8, { FLASH_PATH_MAX + 1 }> = heapless::Vec::new();
        c.extend_from_slice(p.as_bytes()).ok()?;
        c.push(0).ok()?;
        Some(c)
    });
    if let Some(p) = path
        .as_ref()
        .and_then(|p| CStr::from_bytes_with_nul(p).ok())
    {
        read_file(p, flash);
    } else {
        defmt::info!("store: emulated flash in RAM only (no --flash file): lost at exit");
    }
    if let Some(n) = run.flash_cut_after {
        defmt::info!("store: the flash loses power after word write {=u32}", n);
        flash.arm(PowerCut::AfterWrites(n));
    }
    let erases_at_open = *flash.erase_counts();
    let store = match Store::open(flash, &store::RangeChecks) {
        Ok((store, _)) => store,
        Err(e) => defmt::panic!("store: {}", e),
    };
    let opened = slot.insert(SettingsStore {
        store,
        path,
        erases_at_open,
    });
    Some(opened)
}

/// Fills `flash` from the file at `path`, if it holds a whole flash image.
fn read_file(path: &CStr, flash: &mut SettingsFlash) {
    let Ok(mut file) = semihosting::fs::File::open(path) else {
        defmt::info!("store: flash file absent: an erased flash");
        return;
    };
    let len = file.metadata().map(|m| m.len()).unwrap_or(0);
    if len == 0 {
        defmt::info!("store: flash file empty: an erased flash");
        return;
    }
    if len != SettingsFlash::SIZE as u64 {
        defmt::warn!(
            "store: flash file holds {=u64} bytes, not {=usize}: ignored, an erased flash",
            len,
            SettingsFlash::SIZE
        );
        return;
    }
    if file.read_exact(flash.contents_mut()).is_err() {
        defmt::warn!("store: flash file unreadable: an erased flash");
        flash.erase_all();
    }
}

impl SettingsStore {
    /// After every operation: the file gets the flash's contents; a power cut ends the run.
    fn after(&mut self, op: &str, words_before: u64) {
        let flash = self.store.flash();
        let words = flash.words_written() - words_before;
        let now: [u32; PAGES] = *flash.erase_counts();
        let erased = |page: usize| now[page] - self.erases_at_open[page];
        if let Some(path) = self
            .path
            .as_ref()
            .and_then(|p| CStr::from_bytes_with_nul(p).ok())
        {
            let written =
                semihosting::fs::File::create(path).and_then(|mut f| f.write_all(flash.as_bytes()));
            if written.is_err() {
                defmt::error!("store: could not write the flash file");
            }
        }
        defmt::info!(
            "store: {=str}: {=u64} word writes (since boot {=u64}), page erases since boot [{=u32}, {=u32}]",
            op,
            words,
            flash.words_written(),
            erased(0),
            erased(1)
        );
        if flash.power_lost() {
            defmt::warn!(
                "store: power cut after word write {=u64}: exiting",
                flash.words_written()
            );
            semihosting::process::exit(POWER_CUT_EXIT);
        }
    }

    fn words(&mut self) -> u64 {
        self.store.flash().words_written()
    }
}

impl Storage for SettingsStore {
    fn load(&mut self, checks: &Checks<'_>) -> store::Boot {
        let before = self.words();
        let boot = self.store.load(checks);
        self.after("load", before);
        boot
    }

    fn save(&mut self, set: &RecordSet, checks: &Checks<'_>) -> Result<u32, StoreError> {
        let before = self.words();
        let r = self.store.save(set, checks);
        self.after("save", before);
        r
    }

    fn factory_reset(&mut self) -> Result<(), StoreError> {
        let before = self.words();
        let r = self.store.factory_reset();
        self.after("factory-reset", before);
        r
    }

    fn log_fault(&mut self, fault: protocol::FaultRecord) -> Result<u32, StoreError> {
        let before = self.words();
        let r = self.store.log_fault(fault);
        self.after("fault logged", before);
        r
    }

    fn fault_log(&mut self) -> FaultLog {
        self.store.fault_log()
    }
}
