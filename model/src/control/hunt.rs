//! Hunting at rest: large duty reversals in quick succession at a stationary reference
//! (docs/design.md §11, "A loop that hunts at rest"). The controller runs soft while it
//! hunts; the f32 port uses the same detector.

/// A loop hunts at rest when the duty reverses by at least this much, ‰, in quick
/// succession: a heavy link juggled through the free play swings it ±600…±900 ‰ at
/// 10–12 Hz, a settling loop does not.
pub const HUNT_REVERSAL_PERMILLE: i32 = 300;
/// Ticks each such reversal adds to the hunting count (which loses one a tick).
pub const HUNT_KICK_TICKS: i32 = 100;
/// Count above which the loop hunts until the count is back to zero: three reversals
/// within about 50 ms, four within 150 ms. Measured on the acceptance grid's six extra
/// seeds with 200 / 300 ‰ and 150 / 250 / 350 ticks: within a few runs of each other.
pub const HUNT_LIMIT_TICKS: i32 = 250;
/// Ceiling of the hunting count: a loop that hunted for long is calm again this many ticks
/// after its last reversal at most.
pub const HUNT_CAP_TICKS: i32 = 1000;

/// The hunting count and flag.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Hunt {
    /// Ticks, 0…`HUNT_CAP_TICKS`.
    count: i32,
    hunting: bool,
}

impl Hunt {
    /// Not hunting, the count at zero.
    pub const NEW: Hunt = Hunt {
        count: 0,
        hunting: false,
    };

    /// Whether the loop hunts (since the count passed `HUNT_LIMIT_TICKS`, until it is back
    /// to zero).
    #[must_use]
    pub const fn hunting(&self) -> bool {
        self.hunting
    }

    /// One tick: the duty of this tick and of the last, ‰ (within ±1000), and whether the
    /// reference is stationary (a moving one clears the count).
    pub fn update(&mut self, stationary: bool, duty: i16, prev: i16) {
        if !stationary {
            *self = Hunt::NEW;
            return;
        }
        let (d, p) = (i32::from(duty), i32::from(prev));
        // A reversal: opposite signs, and |d − p| = |d| + |p| ≤ 2000.
        self.count = if (d ^ p) < 0 && (d - p).abs() >= HUNT_REVERSAL_PERMILLE {
            (self.count + HUNT_KICK_TICKS).min(HUNT_CAP_TICKS)
        } else {
            (self.count - 1).max(0)
        };
        self.hunting = self.count > HUNT_LIMIT_TICKS || (self.hunting && self.count > 0);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(h: &mut Hunt, duties: &[i16]) {
        for w in duties.windows(2) {
            h.update(true, w[1], w[0]);
        }
    }

    #[test]
    fn three_large_reversals_in_quick_succession_are_hunting() {
        let mut h = Hunt::default();
        // ±700 ‰ every 20 ticks: the third reversal takes the count to 262 (> 250).
        let mut d = Vec::new();
        for k in 0..3 {
            d.extend(std::iter::repeat_n(if k % 2 == 0 { 700 } else { -700 }, 20));
        }
        run(&mut h, &d);
        assert!(!h.hunting(), "two reversals");
        run(&mut h, &[-700, 700]);
        assert!(h.hunting(), "three");
        // Calm: it stays until the count is back to zero (at most the cap).
        run(&mut h, &[700; 200]);
        assert!(h.hunting());
        run(&mut h, &[700; 200]);
        assert!(!h.hunting());
    }

    #[test]
    fn small_or_slow_reversals_and_moving_references_are_not() {
        let mut h = Hunt::default();
        // Reversals of 200 ‰ (below 300), however often.
        let d: Vec<i16> = (0..400)
            .map(|k| if k % 2 == 0 { 100 } else { -100 })
            .collect();
        run(&mut h, &d);
        assert!(!h.hunting());
        // Large reversals 120 ticks apart: the count never passes 250.
        let mut d = Vec::new();
        for k in 0..10 {
            d.extend(std::iter::repeat_n(
                if k % 2 == 0 { 800 } else { -800 },
                120,
            ));
        }
        run(&mut h, &d);
        assert!(!h.hunting());
        // A moving reference clears it.
        let d: Vec<i16> = (0..40)
            .map(|k| if k % 2 == 0 { 900 } else { -900 })
            .collect();
        run(&mut h, &d);
        assert!(h.hunting());
        h.update(false, 900, -900);
        assert!(!h.hunting());
        assert_eq!(h, Hunt::default());
    }
}
