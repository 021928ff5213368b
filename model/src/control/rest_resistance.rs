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
//! offset enters whole: with a calibration in force it is known to a fraction of a count
//! (docs/calibration.md) and the estimate is taken as it is; without one it may be
//! [`UNCALIBRATED_OFFSET_Q16`] either way, and the window allows any R between
//! Σduty·V̂_s/(1000·(Σi ± n·δ)): the resistance configured is the one of that band nearest
//! the one in force ([`RestResistance::differs_from`]). Per tick, after the control step:
//! two sums and two compares ([`RestResistance::tick`]); the divisions when a command is
//! given, and the caller prepares the new schedule outside the tick
//! (`Servo::tracked_configuration`, `Servo::adopt_prepared`).

use fixed::types::I32F32;

use super::schedule::CURRENT_OFFSET_TOLERANCE_COUNTS;
use super::Output;
use crate::sensors::{ADC_COUNTS_PER_A, ENCODER_COUNT_Q32};
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
/// Current-sense offset, A Q16, a window allows for without a calibration in force: the
/// observer's tolerance of `CURRENT_OFFSET_TOLERANCE_COUNTS` (20 ADC counts, 0.0195 A;
/// docs/design.md §9). With a calibration in force the offset is known to 0.2 counts, 0.5 %
/// of [`MIN_CURRENT_Q16`], and taken as exact (0).
pub const UNCALIBRATED_OFFSET_Q16: i64 =
    CURRENT_OFFSET_TOLERANCE_COUNTS as i64 * 65_536 / ADC_COUNTS_PER_A as i64;

/// How far the current sense's zero may be off, A Q16: 0 with a calibration in force
/// (`offset_calibrated`), [`UNCALIBRATED_OFFSET_Q16`] without.
#[must_use]
pub const fn offset_tolerance_q16(offset_calibrated: bool) -> i64 {
    if offset_calibrated {
        0
    } else {
        UNCALIBRATED_OFFSET_Q16
    }
}
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

    /// Whether the window gives an estimate: at least [`WINDOW_TICKS`] long, its mean
    /// current at least [`MIN_CURRENT_Q16`] and of the duty's sign.
    fn usable(&self) -> bool {
        self.ticks >= WINDOW_TICKS
            && self.current_sum_q16.unsigned_abs()
                >= MIN_CURRENT_Q16.unsigned_abs() * u64::from(self.ticks)
            && (self.duty_sum > 0) == (self.current_sum_q16 > 0)
    }

    /// |Σduty|·V_s / (1000·`current_q16`), the window's duty over a positive current sum
    /// (Q16), as I32F32 bits: V_s in Q32 and the current in Q16, so ·2¹⁶ gives Q32 bits.
    /// |Σduty| ≤ 1000·2²⁰ < 2³⁰, V_s bits < 2³⁹: the numerator is below 2¹⁰⁰.
    fn ohms(&self, supply_v: I32F32, current_q16: i128) -> i128 {
        ((i128::from(self.duty_sum).abs() * i128::from(supply_v.to_bits())) << 16)
            / (1000 * current_q16)
    }

    /// R_eff, Ω, of a window of at least [`WINDOW_TICKS`] whose mean current is at least
    /// [`MIN_CURRENT_Q16`] and has the sign of the duty; `None` otherwise or when it does
    /// not fit I32F32.
    #[must_use]
    pub fn estimate(&self, supply_v: I32F32) -> Option<I32F32> {
        if !self.usable() {
            return None;
        }
        let r = self.ohms(supply_v, i128::from(self.current_sum_q16).abs());
        i64::try_from(r).ok().map(I32F32::from_bits)
    }

    /// The resistance to configure before the next command, when the window shows one
    /// that differs from `configured` by more than [`TOLERANCE_PERMILLE`]. With the current
    /// offset unknown within ±`offset_q16` (A Q16, [`UNCALIBRATED_OFFSET_Q16`] without a
    /// calibration, 0 with one: the band is then R_eff alone) the window allows R_eff
    /// between Σduty·V̂_s/(1000·(|Σi| + n·δ)) and Σduty·V̂_s/(1000·(|Σi| − n·δ))
    /// (unbounded above when n·δ ≥ |Σi|): `None` while `configured` lies in that band, else
    /// its bound nearest `configured`, the smallest correction the measurement asks for.
    #[must_use]
    pub fn differs_from(
        &self,
        supply_v: I32F32,
        configured: I32F32,
        offset_q16: i64,
    ) -> Option<I32F32> {
        if !self.usable() {
            return None;
        }
        let c = i128::from(configured.to_bits());
        // Both sums have the duty's sign (`usable`); |Σi| ≤ 2⁵¹, n·δ ≤ 2⁵⁰.
        let si = i128::from(self.current_sum_q16).abs();
        let n_off = i128::from(offset_q16) * i128::from(self.ticks);
        let low = self.ohms(supply_v, si + n_off);
        let r = if c < low {
            low
        } else {
            match (si > n_off).then(|| self.ohms(supply_v, si - n_off)) {
                Some(high) if c > high => high,
                _ => return None,
            }
        };
        let diff = (r - c).abs() * 1000;
        let r = I32F32::from_bits(i64::try_from(r).ok()?);
        (diff > i128::from(TOLERANCE_PERMILLE) * c).then_some(r)
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
            motor_torque_q16: 0,
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
        assert!(w.differs_from(v_s, I32F32::from_num(8), 0).is_some());
        assert_eq!(w.differs_from(v_s, I32F32::from_num(9.4), 0), None);
    }

    #[test]
    fn an_unknown_offset_moves_the_resistance_only_to_the_nearest_it_allows() {
        let v_s = I32F32::from_num(12);
        let ohm = |r: Option<I32F32>| r.map(|r| r.to_num::<f64>());
        let near = |r: Option<f64>, want: f64| r.is_some_and(|r| (r - want).abs() < 1e-3);
        let mut w = RestResistance::NEW;
        for _ in 0..=WINDOW_TICKS {
            w.tick(true, &out(200, 0.25, 7));
        }
        // 2.4 V over 0.25 A ∓ 20/1024 A: 8.9043 … 10.4136 Ω.
        assert_eq!(UNCALIBRATED_OFFSET_Q16, 1280);
        let d = UNCALIBRATED_OFFSET_Q16;
        let r = |configured: f64| ohm(w.differs_from(v_s, I32F32::from_num(configured), d));
        assert!(near(r(8.0), 2.4 / (0.25 + 20.0 / 1024.0)), "{:?}", r(8.0));
        assert!(near(r(12.0), 2.4 / (0.25 - 20.0 / 1024.0)), "{:?}", r(12.0));
        assert_eq!(r(9.6), None);
        assert_eq!(r(8.904), None);
        // The bound is 3.5 % above 8.6 Ω: within the tolerance.
        assert_eq!(r(8.6), None);
        // An offset as large as the current leaves no upper bound.
        let mut small = RestResistance::NEW;
        for _ in 0..=WINDOW_TICKS {
            small.tick(true, &out(-24, -0.0625, 7));
        }
        let big = 65_536 / 10;
        let r = |configured: f64| ohm(small.differs_from(v_s, I32F32::from_num(configured), big));
        assert_eq!(r(100.0), None);
        assert!(near(r(1.0), 0.288 / (0.0625 + 0.1)), "{:?}", r(1.0));
    }

    /// Whatever the offset within its tolerance, the resistance configured lies between
    /// the one in force and the true one (the window's duty over the true current): the
    /// tracking never goes past the motor it measures.
    #[test]
    fn an_offset_within_its_tolerance_never_moves_the_resistance_past_the_true_one() {
        let v_s = I32F32::from_num(12);
        let configured = 8.0;
        let (mut moved, mut cases) = (0, 0);
        for r_true in [6.4, 7.2, 8.0, 8.8, 9.6, 10.4, 11.2] {
            for i_true in [0.05, 0.08, 0.12, 0.2, 0.3] {
                for offset_counts in [-20.0, -12.5, -5.0, 0.0, 5.0, 12.5, 20.0] {
                    let duty = (r_true * i_true * 1000.0 / 12.0_f64).round();
                    let measured = i_true + offset_counts / 1024.0;
                    let mut w = RestResistance::NEW;
                    for _ in 0..=WINDOW_TICKS {
                        w.tick(true, &out(duty as i16, measured, 7));
                    }
                    let truth = duty * 12.0 / (1000.0 * i_true);
                    let got =
                        w.differs_from(v_s, I32F32::from_num(configured), UNCALIBRATED_OFFSET_Q16);
                    cases += 1;
                    if let Some(r) = got {
                        let r = r.to_num::<f64>();
                        moved += 1;
                        let (lo, hi) = if truth < configured {
                            (truth, configured)
                        } else {
                            (configured, truth)
                        };
                        // The Q16 current's rounding: 2⁻¹⁶ A of 0.03 A and more.
                        let eps = 1e-3 * hi;
                        assert!(
                            lo - eps <= r && r <= hi + eps,
                            "R {r_true}, {i_true} A, offset {offset_counts}: {r} outside {lo}…{hi}"
                        );
                    }
                }
            }
        }
        // The rule does correct: more than a quarter of these windows moved it.
        assert!(moved * 4 > cases, "{moved} of {cases}");
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
