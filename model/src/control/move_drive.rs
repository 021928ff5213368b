//! A minimum-jerk move's acceleration feed-forward for the actuator it meets
//! (docs/design.md §11, "Moves for the actuator they meet").
//!
//! The r̈ feed-forward is the rigid model's: J·r̈ of the configured link, through the
//! configured R/k_t. A link heavier than configured, or a warm motor, needs more duty for
//! the same acceleration; the PID supplies it only once the link has fallen behind, and the
//! lag comes back as overshoot when the reference stops. So while a move's reference
//! accelerates and the link is loaded, the controller hands this tracker the part of its
//! output that went into accelerating (the output less the velocity feed-forward, the
//! deflection's feed-forward and the integrator's held load: what the actuator needed,
//! whether the feed-forward or the PID gave it) and the model's r̈ feed-forward, both summed
//! in the move's direction. Once the model has asked for `MIN_MODEL_DRIVE` ‰·ticks, each
//! such tick sets the scale of the r̈ feed-forward (and of the coupling's J_l·r̈) for the
//! rest of the move:
//!
//! ```text
//! g = clamp(Σ actual / (m·Σ model), 1, MOVE_SCALE_MAX)   where Σ actual > m·Σ model, else 1
//! ```
//!
//! (m = `DRIVE_MARGIN_PERCENT`, the share of the output a nominal actuator's friction,
//! deflection and PID parts take, as for a raw step's braking): the feed-forward then gives
//! all but that margin of what the actuator needs. One 32-bit division a counted tick, out
//! of line. Formats: duty ‰ Q16 per tick, sums ‰·ticks Q8 in `i32` (counting stops at
//! `SUM_STOP` ‰·ticks, an acceleration of seconds at full duty), the scale Q16.

use super::dash::DRIVE_MARGIN_PERCENT;
use super::gain::{sqrt_ratio_q16, Gain, Q16_ONE};

/// The most the acceleration feed-forward is raised: ×2. Measured on the acceptance grid
/// (six seeds, docs/design.md §11, "Moves for the actuator they meet"): ×3 saved one more
/// overshoot but drove two cold motors' heavy links past σ_allow; ×1.5 saved 8 fewer.
pub const MOVE_SCALE_MAX: i32 = 2;

/// The model's drive, ‰·ticks, before the ratio is trusted: the first ticks of a move
/// carry the take-up of the free play and the PID's first reaction (100 and 400 measured
/// within two runs of it on the off-nominal grid, docs/design.md §11).
pub const MIN_MODEL_DRIVE: i32 = 200;

/// The sums' format: ‰ in Q8 (the per-tick duty's Q16 shifted right by 8).
const SUM_SHIFT: u32 = 8;
/// The model's sum at which counting stops, ‰·ticks (2²⁹ in Q8): the scale has long
/// settled, and the sums stay within `i32`.
pub const SUM_STOP: i32 = 1 << 21;

/// A move's drive sums and the feed-forward scale they give.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MoveDrive {
    /// +1 or −1: the move's direction; 0 outside a move (nothing is counted).
    dir: i8,
    /// Σ of the output's acceleration part and of the model's r̈ feed-forward over the
    /// accelerating ticks, in the move's direction, ‰·ticks Q8.
    actual: i32,
    model: i32,
    /// The feed-forward scale, Q16 in [1, `MOVE_SCALE_MAX`].
    scale: i32,
}

impl MoveDrive {
    /// No move: the scale is 1 and nothing is counted.
    pub const NEW: Self = Self {
        dir: 0,
        actual: 0,
        model: 0,
        scale: Q16_ONE,
    };

    /// A move from `from` to `to` (rad, I32F32 bits): counting starts afresh.
    #[must_use]
    pub const fn start(from: i64, to: i64) -> Self {
        Self {
            dir: if to > from {
                1
            } else if to < from {
                -1
            } else {
                0
            },
            ..Self::NEW
        }
    }

    /// `x` (Q16) times the scale; `x` itself while the scale is 1.
    #[inline(always)]
    #[must_use]
    pub fn apply(&self, x: i32) -> i32 {
        super::gain::scale_q16(x, self.scale)
    }

    /// Takes one tick of a loaded link's drive: `actual` the output's acceleration part
    /// (‰ Q16), `accel` the reference's r̈ (rad/s² Q16) and `ff_acc` the model's r̈
    /// feed-forward gain. Counted only while the reference accelerates in the move's
    /// direction; the scale follows once the model's sum passes `MIN_MODEL_DRIVE`.
    #[inline(always)]
    pub fn take(&mut self, actual: i32, accel: i32, ff_acc: Gain) {
        if self.dir != 0 {
            self.count(actual, accel, ff_acc);
        }
    }

    /// [`MoveDrive::take`] within a move. Out of line: the control step's other ticks keep
    /// their code (and its instruction count) as without it.
    #[inline(never)]
    fn count(&mut self, actual: i32, accel: i32, ff_acc: Gain) {
        // Sign flips, not products by the direction: this runs inside the control step's
        // instruction budget.
        let (a, r) = if self.dir > 0 {
            (actual, accel)
        } else {
            (actual.saturating_neg(), accel.saturating_neg())
        };
        if r <= 0 || self.model >= SUM_STOP << SUM_SHIFT {
            return;
        }
        self.actual = self.actual.saturating_add(a >> SUM_SHIFT);
        // Below 2²⁹ before, at most 2²³ a tick: no overflow.
        self.model += ff_acc.apply(r) >> SUM_SHIFT;
        if self.model >= MIN_MODEL_DRIVE << SUM_SHIFT {
            self.scale = if self.actual > self.model {
                self.ratio()
            } else {
                Q16_ONE
            };
        }
    }

    /// The free-play impact speed's factor for the drive the move met, 1/√scale (Q16; 1
    /// until the scale is known): an impact's torque is v·√(k·J), so a link that needed
    /// g times the model's drive takes the same torque at 1/√g of the speed. One 32-bit
    /// division: 2³¹/scale is 1/scale in Q15 (scale in [2¹⁶, 2¹⁷]).
    #[must_use]
    pub fn impact_q16(&self) -> i32 {
        if self.scale == Q16_ONE {
            return Q16_ONE;
        }
        sqrt_ratio_q16((((1u32 << 31) / self.scale as u32) as i32) << 1)
    }

    /// Σ actual / (m·Σ model), Q16, in [1, `MOVE_SCALE_MAX`], for Σ actual > Σ model ≥
    /// `MIN_MODEL_DRIVE`; 1 where the actual sum is within the margin m. One 32-bit
    /// division (one `UDIV` on Cortex-M3/M4): the quotient in Q8 (m·Σ model/2⁸ ≥ 250, so
    /// its resolution is 0.4 % or better), then Q16.
    fn ratio(&self) -> i32 {
        let den = ((self.model >> 8) as u32 * DRIVE_MARGIN_PERCENT as u32) / 100; // < 2²⁸
        let q8 = (self.actual as u32 / den.max(1)).min((MOVE_SCALE_MAX as u32) << 8);
        ((q8 as i32) << 8).max(Q16_ONE)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const ONE: i32 = 1 << 16;

    fn unit() -> Gain {
        Gain::from_int(1).expect("1")
    }

    fn scale(d: &MoveDrive) -> f64 {
        f64::from(d.scale) / 65536.0
    }

    /// The scale is Σactual/(1.25·Σmodel) clamped to [1, 2] (computed here in f64 from the
    /// ticks handed in), once the model has asked for 200 ‰·ticks; 1 before; the impact
    /// speed's factor 1/√scale.
    #[test]
    fn the_scale_is_the_drive_ratio_over_the_margin() {
        for factor in [0.5, 1.0, 1.2, 1.25, 1.3, 1.6, 2.0, 2.5, 2.6, 4.0, 1.0e3] {
            for dir in [1, -1] {
                let mut d = MoveDrive::start(0, i64::from(dir) << 32);
                let (mut sa, mut sm) = (0.0f64, 0.0f64);
                for tick in 0..60 {
                    let model = dir * (ONE / 4 + tick * 977); // ‰ Q16, growing
                    let actual = (f64::from(model) * factor) as i32;
                    d.take(actual, model, unit());
                    sa += f64::from(actual) * f64::from(dir) / 65536.0;
                    sm += f64::from(model) * f64::from(dir) / 65536.0;
                    let want = if sm < 200.0 || sa <= 1.25 * sm {
                        1.0
                    } else {
                        (sa / (1.25 * sm)).clamp(1.0, 2.0)
                    };
                    let got = scale(&d);
                    assert!(
                        (got - want).abs() <= 0.01 * want,
                        "×{factor}, dir {dir}, tick {tick}: {got} vs {want}"
                    );
                    // The impact speed's factor, 1/√scale.
                    let impact = f64::from(d.impact_q16()) / 65536.0;
                    assert!(
                        (impact * want.sqrt() - 1.0).abs() <= 0.01,
                        "×{factor}, dir {dir}, tick {tick}: impact {impact}"
                    );
                }
            }
        }
    }

    /// The model's drive is the feed-forward gain times r̈: a gain of 2 halves the ratio.
    #[test]
    fn the_model_is_the_gain_times_the_acceleration() {
        let two = Gain::from_int(2).expect("2");
        let mut d = MoveDrive::start(0, 1 << 32);
        for _ in 0..400 {
            d.take(5 * ONE, ONE, two); // actual 5, model 2·1: ratio 2.5, scale 2
        }
        assert!((scale(&d) - 2.0).abs() < 0.01, "{}", scale(&d));
        let mut d = MoveDrive::start(0, 1 << 32);
        for _ in 0..400 {
            d.take(3 * ONE, ONE, two); // ratio 1.5, scale 1.2
        }
        assert!((scale(&d) - 1.2).abs() < 0.01, "{}", scale(&d));
    }

    /// Ticks that decelerate the move (r̈ against its direction), and any tick outside a
    /// move, leave the sums and the scale alone; counting stops once the model's sum is
    /// large, so the sums cannot overflow.
    #[test]
    fn only_the_moves_acceleration_counts() {
        let mut d = MoveDrive::start(0, 1 << 32);
        for _ in 0..1000 {
            d.take(3 * ONE, ONE, unit()); // accelerating: ×3 of the model
        }
        assert_eq!(d.scale, 2 * ONE, "capped at MOVE_SCALE_MAX");
        let before = d;
        d.take(-100 * ONE, -ONE, unit()); // decelerating
        d.take(5 * ONE, 0, unit());
        assert_eq!(d, before);
        let mut none = MoveDrive::NEW;
        for _ in 0..1000 {
            none.take(3 * ONE, ONE, unit());
        }
        assert_eq!(none, MoveDrive::NEW);
        assert_eq!(MoveDrive::start(5, 5), MoveDrive::NEW);
        let mut long = MoveDrive::start(0, 1 << 32);
        for _ in 0..10_000 {
            long.take(2000 * ONE, 1000 * ONE, unit()); // full duty, twice the model
        }
        assert!(long.actual > 0 && long.model >= SUM_STOP << SUM_SHIFT);
        assert!((scale(&long) - 1.6).abs() < 0.01, "{}", scale(&long));
    }

    /// `apply` multiplies by the scale (Q16), and passes values through at 1.
    #[test]
    fn apply_multiplies_by_the_scale() {
        let mut d = MoveDrive::start(0, -(1 << 32));
        assert_eq!(d.apply(12_345), 12_345);
        for _ in 0..400 {
            d.take(-2 * ONE, -ONE, unit()); // ×2 of the model: scale 1.6
        }
        assert!((scale(&d) - 1.6).abs() < 0.01, "{}", scale(&d));
        let x = 1000 * ONE;
        let want = (f64::from(x) * scale(&d)) as i64;
        assert!((i64::from(d.apply(x)) - want).abs() <= 1);
        assert_eq!(d.apply(i32::MAX), i32::MAX, "saturates");
    }
}
