//! The H-bridge supply the board measures, for the configuration in force (docs/design.md
//! §11, "The supply the board measures").
//!
//! Every gain that turns volts into duty has the configured supply V̂_s in it (duty ‰ =
//! 1000·V/V̂_s), and so has the back-EMF observer. A battery or bench supply is seldom
//! exactly what was configured: 10.5…12.6 V for a 12 V rating (docs/design.md §9). The
//! board reads the supply through a divider ([`SUPPLY_MV_PER_COUNT`]); the readings are
//! summed over windows of [`WINDOW_TICKS`] ticks (one add per tick, after the control
//! step: [`SupplyWindow::tick`]), and before a command the last full window's mean
//! replaces the configured supply when the two differ by more than
//! [`TOLERANCE_PERMILLE`] (`Servo::tracked_configuration`; the caller prepares the new
//! schedule outside the tick). A board without a supply sense, or whose reads fail, gives
//! no readings, and a mean outside [`PLAUSIBLE_PERCENT`] of the configured supply is taken
//! for a broken sense (an open divider reads 0 or full scale) or an unpowered bridge: the
//! configured supply stays in force.

use fixed::types::I32F32;

use crate::sensors::SUPPLY_MV_PER_COUNT;

/// Readings per window: 2⁸, so that the window's sum is its mean in counts, Q8 (at most
/// 4 095·256 < 2²⁰).
pub const WINDOW_TICKS: u16 = 256;
const WINDOW_SHIFT: u32 = 8;
const _: () = assert!(1 << WINDOW_SHIFT == WINDOW_TICKS as u32);

/// Relative difference from the configured supply, in thousandths, below which the
/// measurement leaves the configuration alone: the sense's own gain error (the divider's
/// resistors, and the ADC's reference, the board's 3.3 V regulator, good to a per cent or
/// two) must not move a correct configuration. Measured on the grids (docs/design.md §11): with the sense 2 %
/// off, 20 leaves the nominal grid unchanged only to the count's rounding, 5 costs it.
pub const TOLERANCE_PERMILLE: i64 = 30;

/// How far from the configured supply, in per cent either way, a measurement is taken as
/// one: 12 V configured, 6…18 V. Beyond it the bridge is unpowered (a board on USB alone)
/// or the sense broken (an open divider reads 0 V or its 20.5 V full scale).
pub const PLAUSIBLE_PERCENT: i64 = 50;

/// The supply windows: the running sum and the last full window's.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SupplyWindow {
    sum: u32,
    n: u16,
    /// The last full window's sum: its mean in counts, Q8.
    last: Option<u32>,
}

impl SupplyWindow {
    /// No readings yet.
    pub const NEW: SupplyWindow = SupplyWindow {
        sum: 0,
        n: 0,
        last: None,
    };

    /// One tick's supply reading, counts (`None`: no sense, or a failed read, left out).
    #[inline]
    pub fn tick(&mut self, counts: Option<u16>) {
        let Some(c) = counts else { return };
        self.sum += u32::from(c);
        self.n += 1;
        if self.n == WINDOW_TICKS {
            self.last = Some(self.sum);
            self.sum = 0;
            self.n = 0;
        }
    }

    /// The last full window's mean supply, V (I32F32, rounded once), if a window has been
    /// completed.
    #[must_use]
    pub fn volts(&self) -> Option<I32F32> {
        // mean counts Q8 · mV per count / 1000 → V, as I32F32 bits (·2³²/2⁸ = ·2²⁴).
        let mv_q8 = i64::from(self.last?) * i64::from(SUPPLY_MV_PER_COUNT);
        Some(I32F32::from_bits(((mv_q8 << 24) + 500) / 1000))
    }

    /// The measured supply, when it differs from `configured` (V) by more than
    /// [`TOLERANCE_PERMILLE`] but not beyond [`PLAUSIBLE_PERCENT`]; `None` otherwise (no
    /// window yet, within the tolerance, or no plausible reading). Called before a command.
    #[must_use]
    pub fn differs_from(&self, configured: I32F32) -> Option<I32F32> {
        let v = self.volts()?;
        let (m, c) = (i128::from(v.to_bits()), i128::from(configured.to_bits()));
        let off = (m - c).abs();
        // tol·c < |v − c| ≤ plausible·c, in integers (c > 0: the configuration's 1…100 V).
        (off * 1000 > i128::from(TOLERANCE_PERMILLE) * c
            && off * 100 <= i128::from(PLAUSIBLE_PERCENT) * c)
            .then_some(v)
    }

    /// The supply a configuration made now holds, given the `configured` one (V): the
    /// measured one where [`SupplyWindow::differs_from`] gives it, else `configured`.
    #[must_use]
    pub fn in_force(&self, configured: I32F32) -> I32F32 {
        self.differs_from(configured).unwrap_or(configured)
    }
}

impl Default for SupplyWindow {
    fn default() -> Self {
        Self::NEW
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn filled(counts: u16, ticks: u16) -> SupplyWindow {
        let mut w = SupplyWindow::NEW;
        for _ in 0..ticks {
            w.tick(Some(counts));
        }
        w
    }

    #[test]
    fn a_full_window_reads_its_mean_in_volts() {
        // 5 mV a count: 2 400 counts are 12 V, 2 100 are 10.5 V, 2 521 are 12.605 V.
        assert_eq!(filled(2400, 256).volts(), Some(I32F32::from_num(12)));
        assert_eq!(filled(2100, 256).volts(), Some(I32F32::from_num(10.5)));
        let v = filled(2521, 256).volts().unwrap().to_num::<f64>();
        assert!((v - 12.605).abs() < 1e-9, "{v}");
        // Alternating readings: the mean, 12.0025 V.
        let mut w = SupplyWindow::NEW;
        for i in 0..256 {
            w.tick(Some(if i % 2 == 0 { 2400 } else { 2401 }));
        }
        let v = w.volts().unwrap().to_num::<f64>();
        assert!((v - 12.0025).abs() < 1e-9, "{v}");
    }

    #[test]
    fn no_estimate_before_a_full_window_and_failed_reads_are_left_out() {
        assert_eq!(filled(2400, 255).volts(), None);
        let mut w = filled(2400, 255);
        w.tick(None);
        assert_eq!(w.volts(), None);
        w.tick(Some(2400));
        assert_eq!(w.volts(), Some(I32F32::from_num(12)));
        // The next window replaces the last only when it is full.
        for _ in 0..255 {
            w.tick(Some(2200));
        }
        assert_eq!(w.volts(), Some(I32F32::from_num(12)));
        w.tick(Some(2200));
        assert_eq!(w.volts(), Some(I32F32::from_num(11)));
    }

    #[test]
    fn only_a_difference_beyond_the_tolerance_changes_the_configuration() {
        let twelve = I32F32::from_num(12);
        // 3 % of 12 V is 0.36 V, 72 counts: 2 471 and 2 329 are within, 2 473 beyond.
        assert_eq!(TOLERANCE_PERMILLE, 30);
        assert_eq!(filled(2471, 256).differs_from(twelve), None);
        assert_eq!(filled(2329, 256).differs_from(twelve), None);
        let v = filled(2473, 256)
            .differs_from(twelve)
            .unwrap()
            .to_num::<f64>();
        assert!((v - 12.365).abs() < 1e-9, "{v}");
        assert_eq!(
            filled(2100, 256).differs_from(twelve),
            Some(I32F32::from_num(10.5))
        );
        // 6 and 18 V are the plausible bounds; an unpowered bridge (a board on USB alone)
        // or an open divider (0 or 20.475 V) keeps the configured supply.
        assert_eq!(
            filled(1200, 256).differs_from(twelve),
            Some(I32F32::from_num(6))
        );
        assert_eq!(
            filled(3600, 256).differs_from(twelve),
            Some(I32F32::from_num(18))
        );
        for broken in [0, 100, 1199, 3601, 4095] {
            assert_eq!(filled(broken, 256).differs_from(twelve), None, "{broken}");
        }
        assert_eq!(SupplyWindow::NEW.differs_from(twelve), None);
    }
}
