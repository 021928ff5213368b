//! A NOR flash in RAM for the emulated boards (QEMU has no flash controller), with
//! power-cut injection and a byte snapshot the firmware mirrors to a host file.
//!
//! Geometry as the store uses on the STM32F4: [`PAGE_SIZE`] (16 KiB) erase pages,
//! [`WORD_SIZE`] (4 bytes) program words. NOR rules: erase sets every byte to 0xFF; a word
//! is programmed once between erases ([`RamFlashError::ProgramTwice`] otherwise, which the
//! store must never cause); reads are byte-granular.
//!
//! Power cuts ([`PowerCut`]): after the armed number of word writes, or in the middle of the
//! armed erase, the flash loses power: the operation that crossed the line returns
//! [`RamFlashError::PowerLost`] and so does every later one until [`RamFlash::power_on`]. The
//! contents keep exactly the words written before the cut (a torn erase: its first half
//! erased, the rest as it was), which is what the next boot reads.

use embedded_storage::nor_flash::{
    ErrorType, NorFlash, NorFlashError, NorFlashErrorKind, ReadNorFlash,
};

use crate::{PAGE_SIZE, WORD_SIZE};

/// Where the power goes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum PowerCut {
    /// Never (the default).
    #[default]
    Never,
    /// After this many more word writes complete (0: before the next write or erase).
    AfterWrites(u32),
    /// In the middle of the erase after this many more complete (0: the next erase): its
    /// page's first half is erased, the second half keeps its contents.
    InErase(u32),
}

/// Why a flash operation failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum RamFlashError {
    /// The power was cut (see [`PowerCut`]); nothing more is written until power-on.
    PowerLost,
    /// Offset or length not a multiple of the word (write) or page (erase).
    NotAligned,
    /// Beyond the end of the flash.
    OutOfBounds,
    /// A word programmed twice without an erase between (a defect of the caller).
    ProgramTwice,
}

impl NorFlashError for RamFlashError {
    fn kind(&self) -> NorFlashErrorKind {
        match self {
            RamFlashError::NotAligned => NorFlashErrorKind::NotAligned,
            RamFlashError::OutOfBounds => NorFlashErrorKind::OutOfBounds,
            RamFlashError::PowerLost | RamFlashError::ProgramTwice => NorFlashErrorKind::Other,
        }
    }
}

/// The snapshot given to [`RamFlash::restore`] is not [`RamFlash::SIZE`] bytes long.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SnapshotSizeMismatch {
    /// Bytes expected.
    pub expected: usize,
    /// Bytes given.
    pub found: usize,
}

/// `PAGES` erase pages of [`PAGE_SIZE`] bytes in RAM.
///
/// `RamFlash::<2>` is 32 KiB of RAM. [`RamFlash::new`] is `const` but puts 0xFF bytes in
/// `.data` (and the image); a board that wants it in `.bss` can start from
/// [`RamFlash::ZEROED`] and [`RamFlash::erase_all`] or [`RamFlash::restore`] it at boot.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RamFlash<const PAGES: usize> {
    pages: [[u8; PAGE_SIZE]; PAGES],
    erases: [u32; PAGES],
    words_written: u64,
    cut: PowerCut,
    powered: bool,
}

impl<const PAGES: usize> Default for RamFlash<PAGES> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const PAGES: usize> RamFlash<PAGES> {
    /// Bytes of flash.
    pub const SIZE: usize = PAGES * PAGE_SIZE;

    /// All bytes 0 (every word programmed): not a usable store until erased or restored.
    pub const ZEROED: Self = Self::filled(0);

    /// Erased flash (every byte 0xFF), powered, no cut armed.
    #[must_use]
    pub const fn new() -> Self {
        Self::filled(0xFF)
    }

    const fn filled(byte: u8) -> Self {
        Self {
            pages: [[byte; PAGE_SIZE]; PAGES],
            erases: [0; PAGES],
            words_written: 0,
            cut: PowerCut::Never,
            powered: true,
        }
    }

    /// Flash holding `bytes` (a snapshot from [`RamFlash::as_bytes`]).
    ///
    /// # Errors
    /// [`SnapshotSizeMismatch`] if `bytes` is not [`RamFlash::SIZE`] long.
    pub fn from_bytes(bytes: &[u8]) -> Result<Self, SnapshotSizeMismatch> {
        let mut flash = Self::new();
        flash.restore(bytes)?;
        Ok(flash)
    }

    /// The contents, [`RamFlash::SIZE`] bytes: what the emulated boards write to the host
    /// file after every store operation.
    #[must_use]
    pub fn as_bytes(&self) -> &[u8] {
        self.pages.as_flattened()
    }

    /// The contents to fill in place with a snapshot (a board reading its host file at
    /// boot without a second 32 KiB buffer); not a flash operation: nothing is counted.
    pub fn contents_mut(&mut self) -> &mut [u8] {
        self.pages.as_flattened_mut()
    }

    /// Replaces the contents with a snapshot (power and counters unchanged).
    ///
    /// # Errors
    /// [`SnapshotSizeMismatch`] if `bytes` is not [`RamFlash::SIZE`] long (nothing changed).
    pub fn restore(&mut self, bytes: &[u8]) -> Result<(), SnapshotSizeMismatch> {
        let flat = self.pages.as_flattened_mut();
        if bytes.len() != flat.len() {
            return Err(SnapshotSizeMismatch {
                expected: flat.len(),
                found: bytes.len(),
            });
        }
        flat.copy_from_slice(bytes);
        Ok(())
    }

    /// Erases every page (counted in the erase counts), whatever the power.
    pub fn erase_all(&mut self) {
        for (page, n) in self.pages.iter_mut().zip(self.erases.iter_mut()) {
            page.fill(0xFF);
            *n = n.saturating_add(1);
        }
    }

    /// Arms a power cut, counted from now; replaces any armed one.
    /// [`PowerCut::AfterWrites`]`(0)` cuts the power at once.
    pub fn arm(&mut self, cut: PowerCut) {
        self.cut = cut;
        if cut == PowerCut::AfterWrites(0) {
            self.powered = false;
        }
    }

    /// Power back on (the next boot): operations work again, no cut armed.
    pub fn power_on(&mut self) {
        self.powered = true;
        self.cut = PowerCut::Never;
    }

    /// Whether an armed cut has happened.
    #[must_use]
    pub const fn power_lost(&self) -> bool {
        !self.powered
    }

    /// Erases of each page since this value was made (wear).
    #[must_use]
    pub const fn erase_counts(&self) -> &[u32; PAGES] {
        &self.erases
    }

    /// Words programmed since this value was made.
    #[must_use]
    pub const fn words_written(&self) -> u64 {
        self.words_written
    }

    fn check_range(offset: u32, len: usize, unit: usize) -> Result<usize, RamFlashError> {
        let start = offset as usize;
        if !start.is_multiple_of(unit) || !len.is_multiple_of(unit) {
            return Err(RamFlashError::NotAligned);
        }
        match start.checked_add(len) {
            Some(end) if end <= Self::SIZE => Ok(start),
            _ => Err(RamFlashError::OutOfBounds),
        }
    }

    /// Programs one word, or loses the power instead if the armed cut says so.
    fn program_word(&mut self, at: usize, word: &[u8]) -> Result<(), RamFlashError> {
        if !self.powered {
            return Err(RamFlashError::PowerLost);
        }
        let flat = self.pages.as_flattened_mut();
        let Some(cell) = flat.get_mut(at..at + WORD_SIZE) else {
            return Err(RamFlashError::OutOfBounds);
        };
        if cell.iter().any(|b| *b != 0xFF) {
            return Err(RamFlashError::ProgramTwice);
        }
        cell.copy_from_slice(word);
        self.words_written += 1;
        if let PowerCut::AfterWrites(n) = self.cut {
            let left = n.saturating_sub(1);
            self.cut = PowerCut::AfterWrites(left);
            if left == 0 {
                self.powered = false; // this word is kept; nothing after it
            }
        }
        Ok(())
    }

    fn erase_page(&mut self, index: usize) -> Result<(), RamFlashError> {
        if !self.powered {
            return Err(RamFlashError::PowerLost);
        }
        let (Some(page), Some(count)) = (self.pages.get_mut(index), self.erases.get_mut(index))
        else {
            return Err(RamFlashError::OutOfBounds);
        };
        *count = count.saturating_add(1);
        match self.cut {
            PowerCut::InErase(0) => {
                if let Some(half) = page.get_mut(..PAGE_SIZE / 2) {
                    half.fill(0xFF);
                }
                self.powered = false;
                Err(RamFlashError::PowerLost)
            }
            PowerCut::InErase(n) => {
                self.cut = PowerCut::InErase(n - 1);
                page.fill(0xFF);
                Ok(())
            }
            _ => {
                page.fill(0xFF);
                Ok(())
            }
        }
    }
}

impl<const PAGES: usize> ErrorType for RamFlash<PAGES> {
    type Error = RamFlashError;
}

impl<const PAGES: usize> ReadNorFlash for RamFlash<PAGES> {
    const READ_SIZE: usize = 1;

    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
        if !self.powered {
            return Err(RamFlashError::PowerLost);
        }
        let start = Self::check_range(offset, bytes.len(), 1)?;
        let src = self
            .as_bytes()
            .get(start..start + bytes.len())
            .ok_or(RamFlashError::OutOfBounds)?;
        bytes.copy_from_slice(src);
        Ok(())
    }

    fn capacity(&self) -> usize {
        Self::SIZE
    }
}

impl<const PAGES: usize> NorFlash for RamFlash<PAGES> {
    const WRITE_SIZE: usize = WORD_SIZE;
    const ERASE_SIZE: usize = PAGE_SIZE;

    fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        if to < from {
            return Err(RamFlashError::OutOfBounds);
        }
        let start = Self::check_range(from, (to - from) as usize, PAGE_SIZE)?;
        for index in start / PAGE_SIZE..to as usize / PAGE_SIZE {
            self.erase_page(index)?;
        }
        Ok(())
    }

    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
        let start = Self::check_range(offset, bytes.len(), WORD_SIZE)?;
        for (i, word) in bytes.chunks_exact(WORD_SIZE).enumerate() {
            self.program_word(start + i * WORD_SIZE, word)?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    type Flash = RamFlash<2>;

    #[test]
    fn a_cut_after_n_writes_keeps_exactly_n_words() {
        let mut f = Flash::new();
        f.arm(PowerCut::AfterWrites(3));
        assert_eq!(
            f.write(0, &[0x11; 5 * WORD_SIZE]),
            Err(RamFlashError::PowerLost)
        );
        assert!(f.power_lost());
        assert_eq!(&f.as_bytes()[..3 * WORD_SIZE], &[0x11; 3 * WORD_SIZE]);
        assert!(f.as_bytes()[3 * WORD_SIZE..].iter().all(|b| *b == 0xFF));
        assert_eq!(f.words_written(), 3);
        // Nothing works until power-on, erases included.
        assert_eq!(f.erase(0, PAGE_SIZE as u32), Err(RamFlashError::PowerLost));
        let mut b = [0; 4];
        assert_eq!(f.read(0, &mut b), Err(RamFlashError::PowerLost));
        f.power_on();
        f.read(0, &mut b).unwrap();
        assert_eq!(b, [0x11; 4]);
    }

    #[test]
    fn the_nth_write_completing_a_call_still_cuts_what_follows() {
        let mut f = Flash::new();
        f.arm(PowerCut::AfterWrites(2));
        f.write(0, &[0; 2 * WORD_SIZE]).unwrap();
        assert!(f.power_lost());
        assert_eq!(f.write(8, &[0; WORD_SIZE]), Err(RamFlashError::PowerLost));
        assert!(f.as_bytes()[8..].iter().all(|b| *b == 0xFF));
    }

    #[test]
    fn a_torn_erase_leaves_the_second_half() {
        let mut f = Flash::new();
        f.write(0, &[0; WORD_SIZE]).unwrap();
        f.write(PAGE_SIZE as u32 - 4, &[0; WORD_SIZE]).unwrap();
        f.write(PAGE_SIZE as u32, &[0; WORD_SIZE]).unwrap();
        f.arm(PowerCut::InErase(1));
        // The first erase completes, the second is torn.
        assert_eq!(
            f.erase(0, 2 * PAGE_SIZE as u32),
            Err(RamFlashError::PowerLost)
        );
        assert!(f.as_bytes()[..PAGE_SIZE].iter().all(|b| *b == 0xFF));
        assert_eq!(&f.as_bytes()[PAGE_SIZE..PAGE_SIZE + 4], &[0xFF; 4]);
        assert_eq!(f.erase_counts(), &[1, 1]);
        let mut g = Flash::new();
        g.write(PAGE_SIZE as u32 + PAGE_SIZE as u32 / 2, &[0; 4])
            .unwrap();
        g.arm(PowerCut::InErase(0));
        assert_eq!(
            g.erase(PAGE_SIZE as u32, 2 * PAGE_SIZE as u32),
            Err(RamFlashError::PowerLost)
        );
        assert_eq!(&g.as_bytes()[PAGE_SIZE + PAGE_SIZE / 2..][..4], &[0; 4]);
    }

    #[test]
    fn nor_rules_are_enforced() {
        let mut f = Flash::new();
        assert_eq!(f.write(2, &[0; 4]), Err(RamFlashError::NotAligned));
        assert_eq!(f.write(0, &[0; 3]), Err(RamFlashError::NotAligned));
        assert_eq!(
            f.write(Flash::SIZE as u32, &[0; 4]),
            Err(RamFlashError::OutOfBounds)
        );
        assert_eq!(f.erase(1, PAGE_SIZE as u32), Err(RamFlashError::NotAligned));
        f.write(0, &[0xF0; 4]).unwrap();
        assert_eq!(f.write(0, &[0x00; 4]), Err(RamFlashError::ProgramTwice));
        f.erase(0, PAGE_SIZE as u32).unwrap();
        f.write(0, &[0x00; 4]).unwrap();
        assert_eq!(f.erase_counts(), &[1, 0]);
    }

    #[test]
    fn a_snapshot_round_trips() {
        let mut f = Flash::new();
        f.write(40, &[1, 2, 3, 4]).unwrap();
        let g = Flash::from_bytes(f.as_bytes()).unwrap();
        assert_eq!(g.as_bytes(), f.as_bytes());
        assert_eq!(
            Flash::from_bytes(&[0; 10]),
            Err(SnapshotSizeMismatch {
                expected: 2 * PAGE_SIZE,
                found: 10
            })
        );
        let mut z = Flash::ZEROED;
        assert!(z.as_bytes().iter().all(|b| *b == 0));
        z.erase_all();
        assert_eq!(z.as_bytes(), Flash::new().as_bytes());
    }
}
