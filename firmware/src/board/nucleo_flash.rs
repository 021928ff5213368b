//! The Nucleo-F446RE's settings store: flash sectors 1 and 2 (0x0800_4000–0x0800_BFFF,
//! 2 × 16 KiB), which `memory.x` keeps out of the image (`.text` starts at sector 3,
//! `_stext`; sector 0 holds only the vector table, which must sit at the boot address).
//! Why these: the F446's smallest sectors (16 KiB: an erase stalls the bus 0.25–0.5 s
//! rather than 1–2 s for a 128 KiB one), two equal pages as sequential-storage needs, the
//! same geometry as the emulated boards' RAM flash (`store` crate docs).
//!
//! [`SettingsFlash`] is a `NorFlash` over `stm32f4xx-hal`'s flash driver
//! (`UnlockedFlash::erase(sector)`, `program`) presenting the two sectors as offsets
//! 0..32 KiB: erase page = one sector, write word = 4 bytes (the HAL's `NorFlash` erases
//! 128 KiB units, hence this adapter). Reads are plain memory reads.

use embedded_storage::nor_flash::{
    ErrorType, NorFlash, NorFlashError, NorFlashErrorKind, ReadNorFlash,
};
use service::store::Storage;
use stm32f4xx_hal::flash::FlashExt;
use store::{Store, PAGES, PAGE_SIZE, WORD_SIZE};

use super::pac;
use crate::run_config::RunConfig;

/// First sector of the store (sector 1 starts 16 KiB into the flash).
const FIRST_SECTOR: u8 = 1;
/// Offset of sector 1 from the start of the flash, bytes.
const STORE_OFFSET: usize = PAGE_SIZE;

/// Sectors 1–2 of the internal flash.
pub struct SettingsFlash;
/// The flash needs no state before boot.
pub const SETTINGS_FLASH: SettingsFlash = SettingsFlash;
/// The store over sectors 1–2.
pub type SettingsStore = Store<&'static mut SettingsFlash>;

/// What the flash controller reported.
#[derive(Clone, Copy, Debug, defmt::Format)]
pub enum FlashError {
    /// Offset or length not whole words / pages.
    NotAligned,
    /// Beyond the store's 32 KiB.
    OutOfBounds,
    /// The controller's error flags (programming, write protection, ...).
    Controller,
}

impl NorFlashError for FlashError {
    fn kind(&self) -> NorFlashErrorKind {
        match self {
            FlashError::NotAligned => NorFlashErrorKind::NotAligned,
            FlashError::OutOfBounds => NorFlashErrorKind::OutOfBounds,
            FlashError::Controller => NorFlashErrorKind::Other,
        }
    }
}

/// The flash controller. `Nucleo::init` does not use FLASH (the HAL's clock set-up writes
/// the wait states through its own handle), and only the command task reaches this store,
/// so no one else drives the controller at the same time.
fn controller() -> pac::FLASH {
    // SAFETY: see above: this store is the controller's only user after the clock set-up.
    unsafe { pac::Peripherals::steal() }.FLASH
}

fn range(offset: u32, len: usize, unit: usize) -> Result<usize, FlashError> {
    let start = offset as usize;
    if !start.is_multiple_of(unit) || !len.is_multiple_of(unit) {
        return Err(FlashError::NotAligned);
    }
    match start.checked_add(len) {
        Some(end) if end <= PAGES * PAGE_SIZE => Ok(start),
        _ => Err(FlashError::OutOfBounds),
    }
}

impl ErrorType for SettingsFlash {
    type Error = FlashError;
}

impl ReadNorFlash for SettingsFlash {
    const READ_SIZE: usize = 1;

    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), FlashError> {
        let start = STORE_OFFSET + range(offset, bytes.len(), 1)?;
        let flash = controller();
        let src = flash
            .read()
            .get(start..start + bytes.len())
            .ok_or(FlashError::OutOfBounds)?;
        bytes.copy_from_slice(src);
        Ok(())
    }

    fn capacity(&self) -> usize {
        PAGES * PAGE_SIZE
    }
}

impl NorFlash for SettingsFlash {
    const WRITE_SIZE: usize = WORD_SIZE;
    const ERASE_SIZE: usize = PAGE_SIZE;

    fn erase(&mut self, from: u32, to: u32) -> Result<(), FlashError> {
        let len = (to as usize)
            .checked_sub(from as usize)
            .ok_or(FlashError::OutOfBounds)?;
        let start = range(from, len, PAGE_SIZE)?;
        let mut flash = controller();
        let mut unlocked = flash.unlocked();
        for page in start / PAGE_SIZE..(start + len) / PAGE_SIZE {
            let sector = FIRST_SECTOR + page as u8;
            unlocked.erase(sector).map_err(|_| FlashError::Controller)?;
        }
        Ok(())
    }

    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), FlashError> {
        let start = STORE_OFFSET + range(offset, bytes.len(), WORD_SIZE)?;
        let mut flash = controller();
        let written = flash.unlocked().program(start, bytes.iter());
        written.map_err(|_| FlashError::Controller)
    }
}

/// Opens the store on sectors 1–2 (every run: the real board always has its flash).
pub fn open(
    flash: &'static mut SettingsFlash,
    slot: &'static mut Option<SettingsStore>,
    _run: &RunConfig,
) -> Option<&'static mut (dyn Storage + Send)> {
    match Store::open(flash, &store::RangeChecks) {
        Ok((store, _)) => Some(slot.insert(store)),
        Err(e) => {
            defmt::error!("store: {}: running without one", e);
            None
        }
    }
}
