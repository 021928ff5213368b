//! The gear pot's measured error over its track (docs/calibration.md): a bound of
//! |pot − encoder-derived gear angle| per sixteenth of the canonical track, found by
//! calibration (the pot against the link encoder over the steady parts of the moves, the
//! free play taken out, plus a noise margin, [`super::sequence`]) and kept in the
//! calibration record. The supervisor sizes its deflection check from it
//! ([`crate::supervisor::SupervisorConfig::pot_error`]) instead of the fixed
//! `pot_tolerance_counts`: a real pot's non-linearity and noise exceed the fixed tolerance,
//! and a measured bound tells a bent beam from a bent pot track. Bins the calibration's
//! moves did not visit hold the largest visited entry or the fixed tolerance, whichever is
//! larger.

use crate::sensors::POT_COUNTS;

/// Bins of the table over the canonical pot's 1024 counts.
pub const POT_ERROR_BINS: usize = 16;
/// Canonical pot counts per bin (64): the bin of a reading is `pot >> BIN_SHIFT`.
pub const BIN_SHIFT: u32 = (POT_COUNTS as usize / POT_ERROR_BINS).trailing_zeros();
/// Largest bound an entry may hold, pot counts × 100 (50 counts, 0.26 rad): beyond that
/// the pot is broken, not imprecise.
pub const MAX_ERROR_CENTI: u16 = 5000;

/// Bound of the pot's error in each bin of the canonical track, pot counts × 100.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PotErrorTable {
    /// Entry `b` covers canonical pot readings `64·b .. 64·(b + 1)`.
    pub centi: [u16; POT_ERROR_BINS],
}

impl PotErrorTable {
    /// Whether every entry is at most [`MAX_ERROR_CENTI`].
    #[must_use]
    pub fn is_valid(&self) -> bool {
        self.centi.iter().all(|&e| e <= MAX_ERROR_CENTI)
    }

    /// The largest entry, pot counts × 100.
    #[must_use]
    pub fn max_centi(&self) -> u16 {
        self.centi.iter().copied().max().unwrap_or(0)
    }

    /// The bin of canonical pot reading `pot`.
    #[must_use]
    pub const fn bin(pot: u16) -> usize {
        ((pot >> BIN_SHIFT) as usize) & (POT_ERROR_BINS - 1)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bins_cover_the_track_in_sixteenths() {
        assert_eq!(BIN_SHIFT, 6);
        assert_eq!(PotErrorTable::bin(0), 0);
        assert_eq!(PotErrorTable::bin(63), 0);
        assert_eq!(PotErrorTable::bin(64), 1);
        assert_eq!(PotErrorTable::bin(1023), 15);
        let mut t = PotErrorTable::default();
        t.centi[3] = 420;
        assert_eq!(t.max_centi(), 420);
        assert!(t.is_valid());
        t.centi[0] = MAX_ERROR_CENTI + 1;
        assert!(!t.is_valid());
    }
}
