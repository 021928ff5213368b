//! The armature resistance the loop meets, measured at rest under load (docs/design.md
//! §11, "Tracking a warm motor's resistance").
//!
//! A held link under load does not let the gear turn: the back-EMF is zero and the
//! applied voltage is R·i alone, so over a still window
//!
//! ```text
//! R_eff = (Σ duty / 1000) · V̂_s / Σ i
//! ```
//!
//! with the duty the controller applied (‰), V̂_s the configured supply and i the current
//! it measured (A). R_eff lumps the supply's and the current sense's gain errors with the
//! copper's temperature, which is what the loop's duty-to-current scale needs. The current
//! offset enters whole, so the estimate is only taken with a calibration in force (the
//! offset known to a fraction of a count, docs/calibration.md). Per tick, after the control
//! step: two sums and two compares ([`RestResistance::tick`]); the division when a command
//! is given ([`RestResistance::estimate`]), and the caller prepares the new schedule
//! outside the tick (`Servo::tracked_configuration`, `Servo::adopt_prepared`).

use fixed::types::I32F32;

use super::Output;
use crate::sensors::ENCODER_COUNT_Q32;
use crate::units::Angle;

/// Still ticks (ms) a window needs before it gives an estimate. Measured on calibrated
/// builds warmed ×1.4 (docs/calibration.md): with 300 most of the grid's 500 ms holds,
/// which take up their load first, gave none (343 of 2 000 cases tracked, against 1 027).
pub const WINDOW_TICKS: u32 = 150;
/// Least mean current, A Q16, for an estimate: 0.04 A, 41 ADC counts (a 0.2-count
/// calibrated offset is then 0.5 % of it). Measured on the same builds, loaded runs that
/// overshot, of 1 514: 0.02 A 107 (but settling 297), 0.04 A 125 (292), 0.08 A 179
/// (307), 0.15 A 234 (340); none tracked 302 (483).
pub const MIN_CURRENT_Q16: i64 = 2621;
/// Relative difference from the configured resistance, in thousandths, below which the
/// estimate leaves the configuration alone (a rebuild restarts the clutch monitor).
pub const TOLERANCE_PERMILLE: i64 = 50;
/// The window stops growing here (the sums stay far inside i64).
const MAX_TICKS: u32 = 1 << 20;

/// A window of still ticks of a held, driven link: the sums of the applied duty and the
/// measured current, and what must not change for the window to go on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RestResistance {
    duty_sum: i64,
    current_sum_q16: i64,
    ticks: u32,
    reference: Angle,
    link: Angle,
}

impl RestResistance {
    /// An empty window.
    pub const NEW: RestResistance = RestResistance {
        duty_sum: 0,
        current_sum_q16: 0,
        ticks: 0,
        reference: Angle::ZERO,
        link: Angle::ZERO,
    };

    /// One tick of a driven motor (`out`, the controller's output of this tick): the window
    /// goes on while the reference stays where it was and the link within a count of
    /// where the window began (a held link may toggle between two counts), else it starts
    /// again here.
    fn update(&mut self, out: &Output) {
        // Both angles are below 2⁵⁵ in Q32: the difference cannot overflow.
        let moved = (out.link_angle.to_bits() - self.link.to_bits()).unsigned_abs();
        if out.reference != self.reference || moved > ENCODER_COUNT_Q32.unsigned_abs() {
            *self = RestResistance {
                reference: out.reference,
                link: out.link_angle,
                ..RestResistance::NEW
            };
        } else if self.ticks < MAX_TICKS {
            self.duty_sum += i64::from(out.duty);
            // |current| < 2¹⁵ A, below 2³¹ in Q16: the sum of `MAX_TICKS` stays below 2⁵¹.
            self.current_sum_q16 += out.current.to_bits() >> 16;
            self.ticks += 1;
        }
    }

    /// After each tick, outside the control step (the firmware's publishing step, the
    /// host harness's loop): the window goes on while the motor is driven (`out`, the
    /// controller's output of that tick), else it starts again.
    pub fn tick(&mut self, driving: bool, out: &Output) {
        if driving {
            self.update(out);
        } else {
            *self = RestResistance::NEW;
        }
    }

    /// R_eff, Ω, of a window of at least [`WINDOW_TICKS`] whose mean current is at least
    /// [`MIN_CURRENT_Q16`] and has the sign of the duty; `None` otherwise or when it does
    /// not fit I32F32.
    #[must_use]
    pub fn estimate(&self, supply_v: I32F32) -> Option<I32F32> {
        if self.ticks < WINDOW_TICKS
            || self.current_sum_q16.unsigned_abs()
                < MIN_CURRENT_Q16.unsigned_abs() * u64::from(self.ticks)
            || (self.duty_sum > 0) != (self.current_sum_q16 > 0)
        {
            return None;
        }
        // R = Σduty·V_s / (1000·Σi): V_s in Q32 and Σi in Q16, so ·2¹⁶ gives Q32 bits.
        // |Σduty| ≤ 1000·2²⁰ < 2³⁰, V_s bits < 2³⁹: the numerator is below 2¹⁰⁰.
        let num = (i128::from(self.duty_sum) * i128::from(supply_v.to_bits())) << 16;
        let den = 1000 * i128::from(self.current_sum_q16);
        i64::try_from(num / den).ok().map(I32F32::from_bits)
    }

    /// The estimate when it differs from `configured` by more than
    /// [`TOLERANCE_PERMILLE`]: the resistance to configure before the next command.
    #[must_use]
    pub fn differs_from(&self, supply_v: I32F32, configured: I32F32) -> Option<I32F32> {
        let r = self.estimate(supply_v)?;
        let diff = (i128::from(r.to_bits()) - i128::from(configured.to_bits())).abs() * 1000;
        (diff > i128::from(TOLERANCE_PERMILLE) * i128::from(configured.to_bits())).then_some(r)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::control::Flags;
    use crate::units::Torque;

    fn out(duty: i16, current_a: f64, link: i64) -> Output {
        Output {
            duty,
            flags: Flags::default(),
            torque_estimate: Torque::ZERO,
            reference: Angle::from_bits(1 << 30),
            link_angle: Angle::from_bits(link),
            gear_velocity: I32F32::ZERO,
            link_velocity: I32F32::ZERO,
            current: I32F32::from_num(current_a),
        }
    }

    #[test]
    fn a_still_loaded_window_gives_the_duty_over_the_current() {
        let v_s = I32F32::from_num(12);
        let mut w = RestResistance::NEW;
        // 0.25 A through 9.6 Ω at 12 V: 200 ‰.
        for _ in 0..WINDOW_TICKS {
            w.tick(true, &out(200, 0.25, 7));
        }
        // The first tick opened the window: one tick short.
        assert_eq!(w.estimate(v_s), None);
        w.tick(true, &out(200, 0.25, 7));
        let r = w.estimate(v_s).unwrap().to_num::<f64>();
        assert!((r - 9.6).abs() < 1e-3, "{r}");
        // Negative load, negative duty: the same.
        let mut n = RestResistance::NEW;
        for _ in 0..=WINDOW_TICKS {
            n.tick(true, &out(-200, -0.25, 7));
        }
        assert!((n.estimate(v_s).unwrap().to_num::<f64>() - 9.6).abs() < 1e-3);
        // 9.6 against 8 Ω configured is 20 % off; against 9.4 Ω, 2 %.
        assert!(w.differs_from(v_s, I32F32::from_num(8)).is_some());
        assert_eq!(w.differs_from(v_s, I32F32::from_num(9.4)), None);
    }

    #[test]
    fn no_estimate_from_a_moving_link_a_small_current_or_opposite_signs() {
        let v_s = I32F32::from_num(12);
        let mut w = RestResistance::NEW;
        for k in 0..2 * WINDOW_TICKS {
            // The link moves a count every 100 ticks: the window never grows long.
            w.tick(
                true,
                &out(200, 0.25, i64::from(k / 100) * ENCODER_COUNT_Q32),
            );
        }
        assert_eq!(w.estimate(v_s), None);
        // A link toggling between two counts is still.
        for k in 0..=WINDOW_TICKS {
            w.tick(true, &out(200, 0.25, i64::from(k % 2) * ENCODER_COUNT_Q32));
        }
        assert!(w.estimate(v_s).is_some());
        w.tick(false, &out(200, 0.25, 0));
        assert_eq!(w.estimate(v_s), None);
        let mut small = RestResistance::NEW;
        for _ in 0..=WINDOW_TICKS {
            small.tick(true, &out(24, 0.03, 0));
        }
        assert_eq!(small.estimate(v_s), None);
        let mut opposite = RestResistance::NEW;
        for _ in 0..=WINDOW_TICKS {
            opposite.tick(true, &out(200, -0.25, 0));
        }
        assert_eq!(opposite.estimate(v_s), None);
        let mut w = RestResistance::NEW;
        for _ in 0..=WINDOW_TICKS {
            w.tick(true, &out(200, 0.25, 0));
        }
        w.tick(false, &out(200, 0.25, 0));
        assert_eq!(w.estimate(v_s), None);
    }
}
