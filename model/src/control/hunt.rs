//! Hunting at rest: large duty reversals in quick succession at a stationary reference
//! (docs/design.md §11, "A loop that hunts at rest"). The controller runs soft while it
//! hunts; the f32 port uses the same detector.

/// A loop hunts at rest when its duty swings by at least this much, ‰ peak to peak, across
/// zero (beyond ±half of it on both sides) again and again: a heavy link juggled through
/// the free play swings it ±600…±900 ‰ at 10–12 Hz, a settling loop does not. Measured on
/// the acceptance grid's six extra seeds with 200 / 300 / 400 ‰: within a few runs of each
/// other.
pub const HUNT_REVERSAL_PERMILLE: i32 = 300;
/// Ticks each such reversal adds to the hunting count (which loses one a tick).
pub const HUNT_KICK_TICKS: i32 = 100;
/// Count above which the loop hunts until the count is back to zero: two reversals within
/// 50 ticks, three within 125. Measured on the six seeds with 100 / 150 / 250: 100 and 150
/// within a run of each other, 250 left 6 more off-nominal runs whose duty swings at rest.
pub const HUNT_LIMIT_TICKS: i32 = 150;
/// Ceiling of the hunting count: a loop that hunted for long is calm again this many ticks
/// after its last reversal at most.
pub const HUNT_CAP_TICKS: i32 = 1000;

/// The hunting count and flag.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Hunt {
    /// Ticks, 0…`HUNT_CAP_TICKS`.
    count: i32,
    hunting: bool,
    /// The side (±1) the duty last went beyond ±`HUNT_REVERSAL_PERMILLE`/2 on, 0 if none yet.
    side: i8,
}

impl Hunt {
    /// Not hunting, the count at zero.
    pub const NEW: Hunt = Hunt {
        count: 0,
        hunting: false,
        side: 0,
    };

    /// Whether the loop hunts (since the count passed `HUNT_LIMIT_TICKS`, until it is back
    /// to zero).
    #[must_use]
    pub const fn hunting(&self) -> bool {
        self.hunting
    }

    /// One tick: the duty, ‰ (within ±1000), and whether the reference is stationary (a
    /// moving one clears the count). A reversal is the duty going beyond half the
    /// reversal on the side opposite to the one it last went beyond (a Schmitt trigger):
    /// a swing of `HUNT_REVERSAL_PERMILLE` peak to peak, in one tick or in many.
    pub fn update(&mut self, stationary: bool, duty: i16) {
        if !stationary {
            *self = Hunt::NEW;
            return;
        }
        let d = i32::from(duty);
        let half = HUNT_REVERSAL_PERMILLE / 2;
        let side: i8 = if d > half {
            1
        } else if d < -half {
            -1
        } else {
            self.side
        };
        self.count = if side != self.side && self.side != 0 {
            (self.count + HUNT_KICK_TICKS).min(HUNT_CAP_TICKS)
        } else {
            (self.count - 1).max(0)
        };
        self.side = side;
        self.hunting = self.count > HUNT_LIMIT_TICKS || (self.hunting && self.count > 0);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(h: &mut Hunt, duties: &[i16]) {
        for &d in duties {
            h.update(true, d);
        }
    }

    /// `n` segments of `len` ticks alternating between `+amp` and `−amp` ‰.
    fn square(amp: i16, len: usize, n: usize) -> Vec<i16> {
        (0..n)
            .flat_map(|k| std::iter::repeat_n(if k % 2 == 0 { amp } else { -amp }, len))
            .collect()
    }

    #[test]
    fn two_large_reversals_in_quick_succession_are_hunting() {
        let mut h = Hunt::default();
        // ±700 ‰ every 20 ticks: the first reversal takes the count to 100, the second to
        // 181 (> 150).
        run(&mut h, &square(700, 20, 2));
        assert!(!h.hunting(), "one reversal");
        run(&mut h, &[700]);
        assert!(h.hunting(), "two");
        // Calm: it stays until the count is back to zero.
        run(&mut h, &[700; 170]);
        assert!(h.hunting());
        run(&mut h, &[700; 20]);
        assert!(!h.hunting());
    }

    #[test]
    fn a_slow_swing_across_zero_counts_as_a_reversal() {
        let mut h = Hunt::default();
        // From −400 to +400 ‰ in steps of 20 ‰ a tick, and back: each crossing of ±150 ‰
        // counts, 40 ticks apart.
        let up: Vec<i16> = (-20..=20).map(|k| k * 20).collect();
        let down: Vec<i16> = up.iter().rev().copied().collect();
        run(&mut h, &up);
        assert!(!h.hunting(), "one reversal");
        run(&mut h, &down);
        assert!(h.hunting(), "two");
    }

    #[test]
    fn small_or_slow_reversals_and_moving_references_are_not() {
        let mut h = Hunt::default();
        // Swings of ±140 ‰ (280 peak to peak), however often.
        run(&mut h, &square(140, 1, 400));
        assert!(!h.hunting());
        // Large reversals 120 ticks apart: the count never passes 150.
        run(&mut h, &square(800, 120, 10));
        assert!(!h.hunting());
        // A moving reference clears it.
        run(&mut h, &square(900, 1, 40));
        assert!(h.hunting());
        h.update(false, 900);
        assert!(!h.hunting());
        assert_eq!(h, Hunt::default());
    }
}
