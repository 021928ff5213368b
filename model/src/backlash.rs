//! Backlash of the clutch slots (paper eqs. 5–7) and the coupling's free play.
//!
//! * eq. 5: bending capacity θ_max = δ_max/l, with δ_max = σ_allow·l²/(3·E·r), the largest
//!   elastic tip deflection of the full beam (0.32 mm → 0.04 rad for the paper preset);
//! * eq. 6: slot clearance c = θ_max·t_c and slot radius r_slot = r + c (the paper writes
//!   R for the beam's radius there);
//! * eq. 7: beam-tilt backlash θ_b = θ_max·t_c/x for a clutch position t_c ≤ x ≤ l;
//! * output free play φ_b = c/R: the output rotation before the slot touches the beam. It
//!   is the dead zone of the coupling torque, [`Setting::coupling_torque`]: zero for
//!   |φ| ≤ φ_b, k·(|φ| − φ_b)·sign(φ) beyond.
//!
//! All but θ_b(x) are design constants, computed in [`Design::new`].

use crate::beam::{or_overflow, torque_from, Setting};
use crate::design::Design;
use crate::error::{Error, Result};
use crate::fixmath::SoftFloat;
use crate::units::{Angle, Length, Torque};

impl Design {
    /// Largest elastic tip deflection of the full beam, δ_max = σ_allow·l²/(3·E·r).
    #[must_use]
    pub const fn max_tip_deflection(&self) -> Length {
        self.max_tip_deflection
    }

    /// Beam bending capacity (tilt), θ_max = δ_max/l (paper eq. 5).
    #[must_use]
    pub const fn bending_capacity(&self) -> Angle {
        self.bending_capacity
    }

    /// Slot clearance c = θ_max·t_c (paper eq. 6).
    #[must_use]
    pub const fn slot_clearance(&self) -> Length {
        self.clearance
    }

    /// Slot radius r_slot = r + c (paper eq. 6, with the beam radius r).
    #[must_use]
    pub const fn slot_radius(&self) -> Length {
        self.slot_radius
    }

    /// Output free play φ_b = c/R, the dead zone of the coupling torque.
    #[must_use]
    pub const fn free_play(&self) -> Angle {
        self.free_play
    }

    /// Beam-tilt backlash θ_b = θ_max·t_c/x at clutch position x (paper eq. 7).
    ///
    /// # Errors
    /// [`Error::BacklashPositionOutOfRange`] unless t_c ≤ x ≤ l.
    pub fn tilt_backlash(&self, x: Length) -> Result<Angle> {
        let p = self.params();
        if x < p.clutch_thickness || x > p.beam_length {
            return Err(Error::BacklashPositionOutOfRange);
        }
        let xs = SoftFloat::from_bits(x.to_bits(), 32).0;
        // θ_b ≤ θ_max: cannot overflow.
        Ok(Angle::from_bits(or_overflow(
            or_overflow(self.clearance_s.div(xs))?.to_i64(32, false), // eq. 7: c/x = θ_max·t_c/x
        )?))
    }
}

impl Setting {
    /// Output free play φ_b = c/R of the design (the coupling's dead zone half-width).
    #[must_use]
    pub const fn free_play(&self) -> Angle {
        self.free_play_angle
    }

    /// |φ| − φ_b clamped at 0 (the deflection the beams see), and the sign of φ.
    pub(crate) const fn beyond_free_play(&self, phi: Angle) -> (SoftFloat, bool) {
        let (mag, negative) = SoftFloat::from_bits(phi.to_bits(), 32);
        (mag.saturating_sub(self.free_play), negative)
    }

    /// Elastic coupling torque with the free-play dead zone: 0 for |φ| ≤ φ_b, and
    /// k·(|φ| − φ_b)·sign(φ) beyond; φ is the deflection (gear-side minus link-side angle).
    /// No friction: see [`crate::hysteresis`] for the hysteretic version.
    ///
    /// # Errors
    /// [`Error::Overflow`] if |τ| ≥ 2³¹ N·m.
    pub fn coupling_torque(&self, phi: Angle) -> Result<Torque> {
        let (d, negative) = self.beyond_free_play(phi);
        torque_from(or_overflow(self.k.mul(d))?, negative)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::beam::BeamModel;
    use fixed::types::I32F32;

    fn to_f64(a: Angle) -> f64 {
        a.get().to_num::<f64>()
    }

    #[test]
    fn paper_backlash() {
        let d = Design::paper();
        assert!((d.max_tip_deflection().get().to_num::<f64>() - 0.32).abs() < 1e-9);
        assert!((to_f64(d.bending_capacity()) - 0.04).abs() < 1e-9);
        assert!((d.slot_clearance().get().to_num::<f64>() - 0.04).abs() < 1e-9);
        assert!((d.slot_radius().get().to_num::<f64>() - 0.54).abs() < 1e-9);
        let r = I32F32::lit("7.8").to_num::<f64>();
        assert!((to_f64(d.free_play()) - 0.04 / r).abs() < 1e-9);
        // θ_b(t_c) = θ_max, θ_b(l) = θ_max·t_c/l.
        assert!((to_f64(d.tilt_backlash(Length::from_int(1)).unwrap()) - 0.04).abs() < 1e-9);
        assert!((to_f64(d.tilt_backlash(Length::from_int(8)).unwrap()) - 0.005).abs() < 1e-9);
        assert!((to_f64(d.tilt_backlash(Length::from_int(5)).unwrap()) - 0.008).abs() < 1e-9);
    }

    #[test]
    fn tilt_backlash_domain() {
        let d = Design::paper();
        let below = Length::from_bits(Length::from_int(1).to_bits() - 1);
        let above = Length::from_bits(Length::from_int(8).to_bits() + 1);
        for x in [below, above, Length::ZERO, Length::from_int(-3)] {
            assert_eq!(d.tilt_backlash(x), Err(Error::BacklashPositionOutOfRange));
        }
        let s = Setting::new(
            &d,
            Length::from_fixed(I32F32::lit("0.5")),
            BeamModel::default(),
        );
        assert_eq!(s.unwrap().tilt_backlash(), None);
        let s = Setting::new(&d, Length::from_int(4), BeamModel::default()).unwrap();
        assert_eq!(s.tilt_backlash(), d.tilt_backlash(Length::from_int(4)).ok());
    }

    #[test]
    fn coupling_dead_zone() {
        let d = Design::paper();
        let s = Setting::new(&d, Length::from_int(5), BeamModel::EulerBernoulli).unwrap();
        let pb = s.free_play();
        assert_eq!(pb, d.free_play());
        assert_eq!(s.coupling_torque(Angle::ZERO), Ok(Torque::ZERO));
        assert_eq!(s.coupling_torque(pb), Ok(Torque::ZERO));
        assert_eq!(
            s.coupling_torque(pb.checked_neg().unwrap()),
            Ok(Torque::ZERO)
        );
        let k = s.stiffness().get().to_num::<f64>();
        for phi in ["0.01", "-0.01", "0.2", "-1.5"] {
            let p = I32F32::lit(phi).to_num::<f64>();
            let t = s
                .coupling_torque(Angle::from_fixed(I32F32::lit(phi)))
                .unwrap();
            let want = k * (p.abs() - 0.04 / I32F32::lit("7.8").to_num::<f64>()) * p.signum();
            assert!(
                ((t.get().to_num::<f64>() - want) / want).abs() < 1e-8,
                "{phi}"
            );
        }
        let stiff = Setting::new(&d, Length::from_int(1), BeamModel::EulerBernoulli).unwrap();
        assert_eq!(stiff.coupling_torque(Angle::MAX), Err(Error::Overflow));
    }
}
