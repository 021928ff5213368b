//! Link dynamics on the elastic coupling: natural frequency ω_n = √(k/J) and the
//! energy-optimal stiffness k = J·ω² that puts ω_n at a wanted frequency (the paper's
//! motivation: periodic motion at the natural frequency).
//!
//! Units: k in N·m/rad, J in kg·mm² (10⁻⁶ kg·m²), ω in rad/s, so ω² = 10⁶·k/J. The square
//! root is [`crate::fixmath::isqrt`] on ω²·2⁶⁶, rounded by its last bit to ω in I32F32 bits.
//!
//! [`Design::tune`] turns a wanted ω_n into a clutch length and says when it lies outside
//! the adjustable range [t_c, l] (stiffness range [k(l), k(t_c)]), and which end is
//! nearest.

use crate::beam::{or_overflow, BeamModel};
use crate::design::Design;
use crate::error::{Error, Result};
use crate::fixmath::{isqrt, SoftFloat};
use crate::units::{Frequency, Inertia, Length, Stiffness};

const MEGA: SoftFloat = SoftFloat::from_u64(1_000_000);

/// Natural frequency ω_n = √(k/J) of a link of inertia `inertia` on stiffness `k`.
///
/// Domain: k > 0, J > 0. The result is rounded to the nearest LSB (2.3e-10 rad/s).
///
/// # Errors
/// [`Error::StiffnessNotPositive`], [`Error::InertiaNotPositive`], or [`Error::Overflow`] if
/// ω_n ≥ 2³¹ rad/s.
pub fn natural_frequency(k: Stiffness, inertia: Inertia) -> Result<Frequency> {
    if k.to_bits() <= 0 {
        return Err(Error::StiffnessNotPositive);
    }
    if inertia.to_bits() <= 0 {
        return Err(Error::InertiaNotPositive);
    }
    let j = SoftFloat::from_bits(inertia.to_bits(), 32).0;
    let w2 = or_overflow(or_overflow(k.magnitude().mul(MEGA))?.div(j))?;
    // ω bits = √(ω²·2⁶⁴). Take the root of ω²·2⁶⁶ (one more bit of ω) and round that bit
    // off: rounding ω² to an integer first and then the root would round twice, which at
    // ω of a few LSB lands a whole LSB off. ω < 2³¹ ⟺ ω²·2⁶⁶ < 2¹²⁸ (else `None`).
    let x = or_overflow(w2.to_u128(66))?;
    let (twice_omega_bits, _) = isqrt(x);
    let omega_bits = (twice_omega_bits + 1) >> 1;
    if omega_bits > i64::MAX as u128 {
        return Err(Error::Overflow);
    }
    Ok(Frequency::from_bits(omega_bits as i64))
}

/// The stiffness that puts the natural frequency of `inertia` at `omega`: k = J·ω².
///
/// Domain: J > 0, ω > 0. Rounded to the nearest LSB (tiny products may round to 0).
///
/// # Errors
/// [`Error::InertiaNotPositive`], [`Error::FrequencyNotPositive`], or [`Error::Overflow`] if
/// k ≥ 9.2e18 N·m/rad.
pub fn stiffness_for_frequency(inertia: Inertia, omega: Frequency) -> Result<Stiffness> {
    if inertia.to_bits() <= 0 {
        return Err(Error::InertiaNotPositive);
    }
    if omega.to_bits() <= 0 {
        return Err(Error::FrequencyNotPositive);
    }
    let j = SoftFloat::from_bits(inertia.to_bits(), 32).0;
    let w = SoftFloat::from_bits(omega.to_bits(), 32).0;
    let jw = or_overflow(j.mul(w))?;
    let k = or_overflow(or_overflow(jw.mul(w))?.div(MEGA))?;
    Ok(Stiffness::from_bits(or_overflow(k.to_i128(64, false))?))
}

/// The clutch setting for a wanted natural frequency, or why there is none.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Tuning {
    /// Reachable: the stiffness J·ω² and the clutch length that gives it.
    InRange {
        /// The wanted stiffness k = J·ω².
        stiffness: Stiffness,
        /// The clutch length L(k), in [t_c, l].
        length: Length,
    },
    /// Softer than the softest setting (k < k(l)); the nearest end is L = l.
    TooSoft {
        /// The wanted stiffness k = J·ω².
        stiffness: Stiffness,
        /// The nearest setting, l.
        nearest: Length,
    },
    /// Stiffer than the stiffest setting (k > k(t_c)); the nearest end is L = t_c.
    TooStiff {
        /// The wanted stiffness k = J·ω².
        stiffness: Stiffness,
        /// The nearest setting, t_c.
        nearest: Length,
    },
}

impl Tuning {
    /// The clutch length to use: the exact one when in range, else the nearest end.
    #[must_use]
    pub const fn length(&self) -> Length {
        match *self {
            Tuning::InRange { length, .. } => length,
            Tuning::TooSoft { nearest, .. } | Tuning::TooStiff { nearest, .. } => nearest,
        }
    }

    /// The wanted stiffness k = J·ω².
    #[must_use]
    pub const fn stiffness(&self) -> Stiffness {
        match *self {
            Tuning::InRange { stiffness, .. }
            | Tuning::TooSoft { stiffness, .. }
            | Tuning::TooStiff { stiffness, .. } => stiffness,
        }
    }
}

impl Design {
    /// The clutch setting that puts the natural frequency of a link of inertia `inertia`
    /// at `omega` with `model`: k = J·ω², then L(k), checked against the adjustable range
    /// [t_c, l] (see [`Design::adjustable_range`]).
    ///
    /// # Errors
    /// As [`stiffness_for_frequency`]; an unreachable stiffness is not an error but a
    /// [`Tuning::TooSoft`] / [`Tuning::TooStiff`].
    pub fn tune(&self, inertia: Inertia, omega: Frequency, model: BeamModel) -> Result<Tuning> {
        let stiffness = stiffness_for_frequency(inertia, omega)?;
        let (soft, stiff) = self.stiffness_range(model);
        let (l_min, l_max) = self.adjustable_range();
        if stiffness < soft {
            return Ok(Tuning::TooSoft {
                stiffness,
                nearest: l_max,
            });
        }
        if stiffness > stiff {
            return Ok(Tuning::TooStiff {
                stiffness,
                nearest: l_min,
            });
        }
        // In range: L(k) ∈ [t_c, l] up to rounding of the last LSB, which the clamp absorbs.
        let length = model.clutch_length(self, stiffness)?.max(l_min).min(l_max);
        Ok(Tuning::InRange { stiffness, length })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn hz(f: Frequency) -> f64 {
        f.get().to_num::<f64>() / core::f64::consts::TAU
    }

    #[test]
    fn anti_resonance_of_the_default_link() {
        // design.md §3: J_link = 1e-3 kg·m² → 426 Hz at L = 1 mm, 38 Hz at L = 5 mm.
        let d = Design::paper();
        let j = Inertia::from_int(1000);
        let w1 = natural_frequency(d.stiffness(Length::from_int(1)).unwrap(), j).unwrap();
        assert!((hz(w1) - 426.0).abs() < 0.5, "{}", hz(w1));
        let w5 = natural_frequency(d.stiffness(Length::from_int(5)).unwrap(), j).unwrap();
        assert!((hz(w5) - 38.1).abs() < 0.1, "{}", hz(w5));
        let k = 7167.5f64;
        let want = (k * 1e6 / 1000.0).sqrt();
        let got = natural_frequency(Stiffness::from_micro(7_167_500_000), j).unwrap();
        assert!((got.get().to_num::<f64>() - want).abs() < 2e-9 * want);
    }

    #[test]
    fn frequency_round_trip_and_errors() {
        let j = Inertia::from_int(1000);
        let w = Frequency::from_int(500);
        let k = stiffness_for_frequency(j, w).unwrap();
        assert_eq!(k, Stiffness::from_int(250)); // 1e-3 · 500²
        assert_eq!(natural_frequency(k, j), Ok(w));
        // ω of a few LSB rounds to the nearest LSB: √(5·2⁻⁶⁴ / 2.01) = 1.577·2⁻³² → 2 LSB,
        // √(7·2⁻⁶⁴ / 2.9) = 1.554·2⁻³² → 2 LSB (both once came out as 1 LSB).
        let tiny = |bits, j_mg_mm2| {
            natural_frequency(Stiffness::from_bits(bits), Inertia::from_int(j_mg_mm2))
                .map(|w| w.to_bits())
        };
        assert_eq!(tiny(5, 2_010_000), Ok(2));
        assert_eq!(tiny(7, 2_900_000), Ok(2));
        assert_eq!(tiny(4, 1_000_000), Ok(2));
        assert_eq!(
            natural_frequency(Stiffness::ZERO, j),
            Err(Error::StiffnessNotPositive)
        );
        assert_eq!(
            natural_frequency(k, Inertia::ZERO),
            Err(Error::InertiaNotPositive)
        );
        assert_eq!(
            natural_frequency(Stiffness::MAX, Inertia::DELTA),
            Err(Error::Overflow)
        );
        assert_eq!(
            stiffness_for_frequency(Inertia::from_int(-1), w),
            Err(Error::InertiaNotPositive)
        );
        assert_eq!(
            stiffness_for_frequency(j, Frequency::ZERO),
            Err(Error::FrequencyNotPositive)
        );
        assert_eq!(
            stiffness_for_frequency(Inertia::MAX, Frequency::MAX),
            Err(Error::Overflow)
        );
        let d = Design::paper();
        assert_eq!(
            d.tune(j, Frequency::from_int(-3), BeamModel::default()),
            Err(Error::FrequencyNotPositive)
        );
    }

    #[test]
    fn tuning_in_and_out_of_range() {
        let d = Design::paper();
        let j = Inertia::from_int(1000);
        for model in [BeamModel::EulerBernoulli, BeamModel::Timoshenko] {
            // ω_n at L = 3 mm.
            let len = Length::from_int(3);
            let k3 = model.stiffness(&d, len).unwrap();
            let w = natural_frequency(k3, j).unwrap();
            match d.tune(j, w, model).unwrap() {
                Tuning::InRange { stiffness, length } => {
                    let rel = (stiffness.get().to_num::<f64>() / k3.get().to_num::<f64>()) - 1.0;
                    assert!(rel.abs() < 1e-8);
                    assert!(
                        (length.get().to_num::<f64>() - 3.0).abs() < 1e-8,
                        "{length}"
                    );
                }
                other => panic!("{other:?}"),
            }
            let slow = d.tune(j, Frequency::from_int(1), model).unwrap();
            assert!(matches!(slow, Tuning::TooSoft { .. }));
            assert_eq!(slow.length(), Length::from_int(8));
            let fast = d.tune(j, Frequency::from_int(100_000), model).unwrap();
            assert!(matches!(fast, Tuning::TooStiff { .. }));
            assert_eq!(fast.length(), Length::from_int(1));
            assert_eq!(
                fast.stiffness(),
                stiffness_for_frequency(j, Frequency::from_int(100_000)).unwrap()
            );
            // The ends themselves are in range.
            let (soft, stiff) = d.stiffness_range(model);
            for (k, l) in [(soft, 8), (stiff, 1)] {
                let w = natural_frequency(k, j).unwrap();
                let t = d.tune(j, w, model).unwrap();
                let lf = t.length().get().to_num::<f64>();
                // ω is rounded to 2.3e-10 rad/s; k within ~1e-12 relative.
                assert!((lf - f64::from(l)).abs() < 1e-6, "{t:?}");
            }
        }
    }
}
