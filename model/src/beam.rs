//! The beam model (Euler–Bernoulli or Timoshenko) and [`Setting`]: everything
//! [`crate::stiffness`] and [`crate::stress`] compute at a clutch length, precomputed for
//! one L and one model, for the 1 kHz loop (docs/design.md §2 table).
//!
//! Domain of L: (0, l]; anything else is [`Error::ClutchLengthOutOfRange`]. Results that
//! do not fit their format are [`Error::Overflow`] (e.g. k(L) for L → 0).

use crate::design::Design;
use crate::error::{Error, Result};
use crate::fixmath::SoftFloat;
use crate::units::{Angle, Force, Frequency, Inertia, Length, Stiffness, Stress, Torque};

/// Which beam theory gives the stiffness.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum BeamModel {
    /// Euler–Bernoulli cantilever, paper eq. 4 (the paper's model and the default).
    #[default]
    EulerBernoulli,
    /// Timoshenko cantilever (shear-corrected, docs/design.md row 4T); softer at short L.
    Timoshenko,
}

/// `v`, or [`Error::Overflow`] if the result left its format.
pub(crate) fn or_overflow<T>(v: Option<T>) -> Result<T> {
    v.ok_or(Error::Overflow)
}

pub(crate) fn torque_from(s: SoftFloat, negative: bool) -> Result<Torque> {
    Ok(Torque::from_bits(or_overflow(s.to_i64(32, negative))?))
}

/// One clutch setting: a design at a clutch length L with a beam model, with every
/// constant the control loop needs precomputed (the divisions happen in [`Setting::new`]).
///
/// The per-tick functions ([`Setting::deflection`], [`Setting::elastic_torque`],
/// [`Setting::root_stress`], [`Setting::coupling_torque`], the hysteresis branches …) are a
/// few integer multiplies and shifts each, with no division.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Setting {
    pub(crate) length: Length,
    pub(crate) model: BeamModel,
    pub(crate) stiffness: Stiffness,
    /// k (N·m/rad).
    pub(crate) k: SoftFloat,
    /// 1/k (rad per N·m).
    pub(crate) inv_k: SoftFloat,
    /// 10³/(n·R) (N per N·m).
    pub(crate) force_per_torque: SoftFloat,
    /// 10³·L·r/(n·R·I) (MPa per N·m).
    pub(crate) stress_per_torque: SoftFloat,
    pub(crate) torque_capacity: Torque,
    pub(crate) deflection_capacity: Angle,
    /// φ_b (rad).
    pub(crate) free_play: SoftFloat,
    pub(crate) free_play_angle: Angle,
    /// a = (6/5)·μ·R/L (1/rad).
    pub(crate) friction: SoftFloat,
    pub(crate) tilt_backlash: Option<Angle>,
}

impl Setting {
    /// Precomputes the setting at clutch length `len` ∈ (0, l] with `model`.
    ///
    /// # Errors
    /// [`Error::ClutchLengthOutOfRange`]; [`Error::Overflow`] if k, τ_cap or θ_cap does
    /// not fit its format (only far below t_c).
    pub fn new(design: &Design, len: Length, model: BeamModel) -> Result<Setting> {
        let l = design.clutch(len)?;
        let k = design.k_scale(model, l)?;
        let stiffness = Stiffness::from_bits(or_overflow(k.to_i128(64, false))?);
        let deflection_capacity = match model {
            BeamModel::EulerBernoulli => design.deflection_capacity(len)?,
            BeamModel::Timoshenko => design.deflection_capacity_timoshenko(len)?,
        };
        Ok(Setting {
            length: len,
            model,
            stiffness,
            k,
            inv_k: or_overflow(k.recip())?,
            force_per_torque: design.force_per_torque,
            stress_per_torque: or_overflow(design.stress_coef.mul(l))?,
            torque_capacity: design.torque_capacity(len)?,
            deflection_capacity,
            free_play: design.free_play_s,
            free_play_angle: design.free_play(),
            friction: or_overflow(design.friction_coef.div(l))?,
            tilt_backlash: design.tilt_backlash(len).ok(),
        })
    }

    /// The clutch length L.
    #[must_use]
    pub const fn length(&self) -> Length {
        self.length
    }

    /// The beam model.
    #[must_use]
    pub const fn model(&self) -> BeamModel {
        self.model
    }

    /// The joint stiffness k(L) (or k_T(L)).
    #[must_use]
    pub const fn stiffness(&self) -> Stiffness {
        self.stiffness
    }

    /// The hysteresis coefficient c = (6/5)·μ·R/L of §2.1 (τ = k·φ·(1 ± c·|φ|)), per rad.
    #[must_use]
    pub const fn hysteresis_coefficient(&self) -> Option<fixed::types::I64F64> {
        match self.friction.to_i128(64, false) {
            Some(b) => Some(fixed::types::I64F64::from_bits(b)),
            None => None,
        }
    }

    /// The stress-limited torque capacity τ_cap(L).
    #[must_use]
    pub const fn torque_capacity(&self) -> Torque {
        self.torque_capacity
    }

    /// The deflection at the stress limit, τ_cap/k for this model.
    #[must_use]
    pub const fn deflection_capacity(&self) -> Angle {
        self.deflection_capacity
    }

    /// `true` if |τ| ≤ τ_cap: the beams stay below σ_allow.
    #[must_use]
    pub const fn within_capacity(&self, torque: Torque) -> bool {
        torque.to_bits().unsigned_abs() <= self.torque_capacity.to_bits().unsigned_abs()
    }

    /// Deflection θ = τ/k, as τ times the precomputed 1/k.
    ///
    /// # Errors
    /// [`Error::Overflow`] if |θ| ≥ 2³¹ rad.
    pub const fn deflection(&self, torque: Torque) -> Result<Angle> {
        match self.inv_k.mul_i64(torque.to_bits()) {
            Some(b) => Ok(Angle::from_bits(b)),
            None => Err(Error::Overflow),
        }
    }

    /// Elastic torque τ = k·θ of the beams alone (no free play, no friction).
    ///
    /// # Errors
    /// [`Error::Overflow`] if |τ| ≥ 2³¹ N·m.
    pub const fn elastic_torque(&self, deflection: Angle) -> Result<Torque> {
        match self.k.mul_i64(deflection.to_bits()) {
            Some(b) => Ok(Torque::from_bits(b)),
            None => Err(Error::Overflow),
        }
    }

    /// Per-beam load P = τ/(n·R).
    ///
    /// # Errors
    /// [`Error::Overflow`] if |P| ≥ 2³¹ N.
    pub const fn beam_force(&self, torque: Torque) -> Result<Force> {
        match self.force_per_torque.mul_i64(torque.to_bits()) {
            Some(b) => Ok(Force::from_bits(b)),
            None => Err(Error::Overflow),
        }
    }

    /// Root bending stress σ = P·L·r/I, signed like τ.
    ///
    /// # Errors
    /// [`Error::Overflow`] if |σ| ≥ 2³¹ MPa.
    pub const fn root_stress(&self, torque: Torque) -> Result<Stress> {
        match self.stress_per_torque.mul_i64(torque.to_bits()) {
            Some(b) => Ok(Stress::from_bits(b)),
            None => Err(Error::Overflow),
        }
    }

    /// Beam-tilt backlash θ_b at this clutch position (paper eq. 7), `None` if L < t_c.
    #[must_use]
    pub const fn tilt_backlash(&self) -> Option<Angle> {
        self.tilt_backlash
    }

    /// Natural frequency of a link of inertia `inertia` on this stiffness, ω_n = √(k/J).
    ///
    /// # Errors
    /// As [`crate::dynamics::natural_frequency`].
    pub fn natural_frequency(&self, inertia: Inertia) -> Result<Frequency> {
        crate::dynamics::natural_frequency(self.stiffness, inertia)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::design::DesignParams;
    use fixed::types::I32F32;

    fn mm(v: &str) -> Length {
        Length::from_fixed(I32F32::lit(v))
    }

    fn kf(k: Stiffness) -> f64 {
        k.get().to_num::<f64>()
    }

    fn close(a: f64, b: f64, rel: f64) -> bool {
        ((a - b) / b).abs() <= rel
    }

    #[test]
    fn paper_stiffness_table() {
        let d = Design::paper();
        // docs/design.md §2.2 (rounded in the table).
        let table = [
            (1, 7167.5, 4680.8, 4.59),
            (2, 895.9, 790.9, 2.30),
            (3, 265.5, 250.7, 1.53),
            (4, 112.0, 108.4, 1.15),
            (5, 57.3, 56.1, 0.92),
        ];
        for (l, k, kt, cap) in table {
            let len = Length::from_int(l);
            // The table is rounded to its last digit.
            let got = kf(d.stiffness(len).unwrap());
            assert!((got - k).abs() <= 0.05, "k({l}) = {got}");
            let got = kf(d.stiffness_timoshenko(len).unwrap());
            assert!((got - kt).abs() <= 0.05, "k_T({l}) = {got}");
            let c = d.torque_capacity(len).unwrap().get().to_num::<f64>();
            assert!((c - cap).abs() <= 0.005, "τ_cap({l}) = {c}");
        }
    }

    #[test]
    fn stiffness_matches_formula_exactly() {
        let d = Design::paper();
        let i = core::f64::consts::PI * 0.5f64.powi(4) / 4.0;
        let r = I32F32::lit("7.8").to_num::<f64>();
        let c = 4.0 * 3.0 * 200_000.0 * i * r * r / 1000.0;
        let s = i / (core::f64::consts::PI * 0.25) * (1.0 + 3.0 * 2.5);
        for l in ["0.001", "0.37", "1", "2.5", "7.999", "8"] {
            let lf = I32F32::lit(l).to_num::<f64>();
            let k = kf(d.stiffness(mm(l)).unwrap());
            assert!(close(k, c / lf.powi(3), 1e-12), "{l}: {k}");
            let kt = kf(d.stiffness_timoshenko(mm(l)).unwrap());
            assert!(close(kt, c / (lf.powi(3) + s * lf), 1e-12), "{l}: {kt}");
        }
    }

    #[test]
    fn deflection_stress_force() {
        let d = Design::paper();
        let two = Torque::from_int(2);
        let theta = d
            .deflection(two, Length::from_int(5))
            .unwrap()
            .get()
            .to_num::<f64>();
        assert!(
            (theta.to_degrees() - 2.00).abs() < 0.005,
            "{}",
            theta.to_degrees()
        );
        let theta1 = d
            .deflection(two, Length::from_int(1))
            .unwrap()
            .get()
            .to_num::<f64>();
        assert!((theta1.to_degrees() - 0.0160).abs() < 5e-5);
        let sigma = d
            .root_stress(two, Length::from_int(1))
            .unwrap()
            .get()
            .to_num::<f64>();
        assert!((sigma - 653.0).abs() < 0.5, "{sigma}");
        let sigma5 = d
            .root_stress(two, Length::from_int(5))
            .unwrap()
            .get()
            .to_num::<f64>();
        assert!((sigma5 - 3265.0).abs() < 1.0, "{sigma5}");
        let p = d.beam_force(two).unwrap().get().to_num::<f64>();
        let r = I32F32::lit("7.8").to_num::<f64>();
        assert!(close(p, 2000.0 / (4.0 * r), 1e-9));
        let neg = d
            .root_stress(Torque::from_int(-2), Length::from_int(1))
            .unwrap();
        assert_eq!(
            neg.checked_neg(),
            Some(d.root_stress(two, Length::from_int(1)).unwrap())
        );
        // θ_cap = τ_cap/k.
        for l in 1..=8 {
            let len = Length::from_int(l);
            let cap = d.torque_capacity(len).unwrap();
            let tc = d.deflection_capacity(len).unwrap().get().to_num::<f64>();
            let via = d.deflection(cap, len).unwrap().get().to_num::<f64>();
            assert!(close(tc, via, 1e-8), "{tc} {via}");
            let s = Setting::new(&d, len, BeamModel::Timoshenko).unwrap();
            let via_t = s.deflection(cap).unwrap().get().to_num::<f64>();
            let tct = s.deflection_capacity().get().to_num::<f64>();
            assert!(close(tct, via_t, 1e-8), "{tct} {via_t}");
        }
    }

    #[test]
    fn fig6_deflection_vs_beam_radius() {
        for (r, deg) in [("0.5", 2.00), ("1", 0.125), ("1.5", 0.0247)] {
            let d = Design::new(DesignParams {
                beam_radius: mm(r),
                ..DesignParams::PAPER
            })
            .unwrap();
            let th = d
                .deflection(Torque::from_int(2), Length::from_int(5))
                .unwrap();
            let got = th.get().to_num::<f64>().to_degrees();
            assert!(close(got, deg, 3e-3), "r = {r}: {got}°");
        }
    }

    #[test]
    fn inverse_round_trips() {
        let d = Design::paper();
        for l in [
            "0.001", "0.01", "0.5", "1", "1.234567", "3", "5", "7.9", "8",
        ] {
            let len = mm(l);
            let k = d.stiffness(len).unwrap();
            let back = d.clutch_length(k).unwrap();
            assert!((back.to_bits() - len.to_bits()).abs() <= 1, "{l}: {back}");
            let kt = d.stiffness_timoshenko(len).unwrap();
            let back_t = d.clutch_length_timoshenko(kt).unwrap();
            assert!(
                (back_t.to_bits() - len.to_bits()).abs() <= 1,
                "{l}: {back_t}"
            );
            for m in [BeamModel::EulerBernoulli, BeamModel::Timoshenko] {
                let k = m.stiffness(&d, len).unwrap();
                assert!((m.clutch_length(&d, k).unwrap().to_bits() - len.to_bits()).abs() <= 1);
            }
        }
        // A wanted stiffness between table values.
        let l = d
            .clutch_length(Stiffness::from_int(1000))
            .unwrap()
            .get()
            .to_num::<f64>();
        let want = (kf(d.stiffness(Length::from_int(1)).unwrap()) / 1000.0).cbrt();
        assert!(close(l, want, 1e-9));
    }

    #[test]
    fn inverse_errors() {
        let d = Design::paper();
        assert_eq!(
            d.clutch_length(Stiffness::ZERO),
            Err(Error::StiffnessNotPositive)
        );
        assert_eq!(
            d.clutch_length(Stiffness::from_int(-5)),
            Err(Error::StiffnessNotPositive)
        );
        assert_eq!(
            d.clutch_length_timoshenko(Stiffness::ZERO),
            Err(Error::StiffnessNotPositive)
        );
        // Softer than k(8 mm) = 14 N·m/rad.
        assert_eq!(
            d.clutch_length(Stiffness::from_int(13)),
            Err(Error::StiffnessTooLow)
        );
        assert_eq!(
            d.clutch_length(Stiffness::DELTA),
            Err(Error::StiffnessTooLow)
        );
        assert_eq!(
            d.clutch_length_timoshenko(Stiffness::from_int(13)),
            Err(Error::StiffnessTooLow)
        );
        // The stiffest representable k still has a clutch length (9.2e-6 mm here).
        let l = d
            .clutch_length(Stiffness::MAX)
            .unwrap()
            .get()
            .to_num::<f64>();
        let want = (kf(d.stiffness(Length::from_int(1)).unwrap()) / kf(Stiffness::MAX)).cbrt();
        assert!(close(l, want, 1e-4), "{l}");
        // Timoshenko: k_T ≈ C/(s·L) at short L, so L(9.2e18) ≈ 1.5e-15 mm rounds to 0.
        assert_eq!(
            d.clutch_length_timoshenko(Stiffness::MAX),
            Err(Error::StiffnessTooHigh)
        );
        let lt = d
            .clutch_length_timoshenko(Stiffness::from_int(1_000_000_000))
            .unwrap();
        assert!(close(kf(d.stiffness_timoshenko(lt).unwrap()), 1e9, 1e-4));
        // k(l) itself, and a hair below it, still map to l.
        let (soft, _) = d.stiffness_range(BeamModel::EulerBernoulli);
        assert_eq!(d.clutch_length(soft), Ok(Length::from_int(8)));
        let below = Stiffness::from_bits(soft.to_bits() - (soft.to_bits() >> 24));
        assert_eq!(d.clutch_length(below), Ok(Length::from_int(8)));
        let (soft_t, _) = d.stiffness_range(BeamModel::Timoshenko);
        assert_eq!(d.clutch_length_timoshenko(soft_t), Ok(Length::from_int(8)));
    }

    #[test]
    fn length_domain_and_overflow_errors() {
        let d = Design::paper();
        for len in [
            Length::ZERO,
            Length::from_int(-1),
            Length::from_fixed(I32F32::lit("8.0001")),
        ] {
            assert_eq!(d.stiffness(len), Err(Error::ClutchLengthOutOfRange));
            assert_eq!(
                d.stiffness_timoshenko(len),
                Err(Error::ClutchLengthOutOfRange)
            );
            assert_eq!(
                d.deflection(Torque::ZERO, len),
                Err(Error::ClutchLengthOutOfRange)
            );
            assert_eq!(
                d.root_stress(Torque::ZERO, len),
                Err(Error::ClutchLengthOutOfRange)
            );
            assert_eq!(d.torque_capacity(len), Err(Error::ClutchLengthOutOfRange));
            assert_eq!(
                d.deflection_capacity(len),
                Err(Error::ClutchLengthOutOfRange)
            );
            assert_eq!(
                Setting::new(&d, len, BeamModel::EulerBernoulli),
                Err(Error::ClutchLengthOutOfRange)
            );
        }
        // k(1 LSB) ≈ 7e31 N·m/rad does not fit I64F64.
        assert_eq!(d.stiffness(Length::DELTA), Err(Error::Overflow));
        assert_eq!(d.torque_capacity(Length::DELTA), Err(Error::Overflow));
        assert_eq!(
            Setting::new(&d, Length::DELTA, BeamModel::EulerBernoulli),
            Err(Error::Overflow)
        );
        // θ = 2.1e9 N·m / 0.022 N·m/rad with r = 0.1 mm.
        let thin = Design::new(DesignParams {
            beam_radius: mm("0.1"),
            ..DesignParams::PAPER
        })
        .unwrap();
        assert_eq!(
            thin.deflection(Torque::MAX, Length::from_int(8)),
            Err(Error::Overflow)
        );
        assert_eq!(
            d.root_stress(Torque::MAX, Length::from_int(8)),
            Err(Error::Overflow)
        );
        assert_eq!(d.beam_force(Torque::MAX), Err(Error::Overflow));
    }

    #[test]
    fn setting_matches_design_functions() {
        let d = Design::paper();
        let len = mm("2.5");
        let s = Setting::new(&d, len, BeamModel::EulerBernoulli).unwrap();
        let tau = Torque::from_fixed(I32F32::lit("1.234"));
        assert_eq!(s.stiffness(), d.stiffness(len).unwrap());
        assert_eq!(s.deflection(tau), d.deflection(tau, len));
        assert_eq!(s.root_stress(tau), d.root_stress(tau, len));
        assert_eq!(s.beam_force(tau), d.beam_force(tau));
        assert_eq!(s.torque_capacity(), d.torque_capacity(len).unwrap());
        assert!(s.within_capacity(tau) && !s.within_capacity(Torque::from_int(-5)));
        let th = s.deflection(tau).unwrap();
        let back = s.elastic_torque(th).unwrap().get().to_num::<f64>();
        assert!(close(back, tau.get().to_num::<f64>(), 1e-7));
        assert_eq!(s.elastic_torque(Angle::MAX), Err(Error::Overflow));
        let soft = Setting::new(&d, Length::from_int(8), BeamModel::Timoshenko).unwrap();
        assert_eq!(soft.root_stress(Torque::MAX), Err(Error::Overflow));
        assert_eq!(soft.beam_force(Torque::MAX), Err(Error::Overflow));
        assert_eq!(soft.model(), BeamModel::Timoshenko);
        assert_eq!(soft.length(), Length::from_int(8));
    }
}
