//! Beam load and stress at a clutch length L (design.md §2 table): the joint deflection
//! θ = τ/k (paper eqs. 1–3), the load on each beam P = τ/(n·R) (eq. 2), the root stress
//! σ = P·L·r/I, the stress-limited torque τ_cap(L) = n·R·σ_allow·I/(r·L) and deflection
//! θ_cap = τ_cap/k. The coefficients are derived once in [`Design::new`].

use crate::beam::{or_overflow, torque_from};
use crate::design::Design;
use crate::error::Result;
use crate::units::{Angle, Force, Length, Stress, Torque};

impl Design {
    /// Joint deflection θ = τ/k(L) (paper eqs. 1–3, E–B), computed as τ·L³/(n·3·E·I·R²)
    /// (products only). For the Timoshenko model use [`crate::Setting::deflection`].
    ///
    /// # Errors
    /// [`crate::Error::ClutchLengthOutOfRange`], [`crate::Error::Overflow`] if |θ| ≥ 2³¹ rad.
    pub fn deflection(&self, torque: Torque, len: Length) -> Result<Angle> {
        let l = self.clutch(len)?;
        let l2 = or_overflow(l.mul(l))?;
        let l3 = or_overflow(l2.mul(l))?;
        let per_torque = or_overflow(l3.mul(self.inv_c_k))?; // eqs. 1–4: θ = τ·L³/C
        Ok(Angle::from_bits(or_overflow(
            per_torque.mul_i64(torque.to_bits()),
        )?))
    }

    /// Load on each beam, P = τ/(n·R) (τ shared by n beams at radius R), via a
    /// precomputed 1/(n·R).
    ///
    /// # Errors
    /// [`crate::Error::Overflow`] if |P| ≥ 2³¹ N.
    pub fn beam_force(&self, torque: Torque) -> Result<Force> {
        Ok(Force::from_bits(or_overflow(
            self.force_per_torque.mul_i64(torque.to_bits()), // eq. 2
        )?))
    }

    /// Bending stress at the beam root, σ = P·L·r/I with P = τ/(n·R), signed like τ.
    ///
    /// # Errors
    /// [`crate::Error::ClutchLengthOutOfRange`], [`crate::Error::Overflow`] if |σ| ≥ 2³¹ MPa.
    pub fn root_stress(&self, torque: Torque, len: Length) -> Result<Stress> {
        let l = self.clutch(len)?;
        let per_torque = or_overflow(self.stress_coef.mul(l))?;
        Ok(Stress::from_bits(or_overflow(
            per_torque.mul_i64(torque.to_bits()),
        )?))
    }

    /// Stress-limited torque capacity τ_cap(L) = n·R·σ_allow·I/(r·L): the torque at which
    /// the root stress reaches σ_allow.
    ///
    /// # Errors
    /// [`crate::Error::ClutchLengthOutOfRange`], [`crate::Error::Overflow`] if τ_cap ≥ 2³¹ N·m.
    pub fn torque_capacity(&self, len: Length) -> Result<Torque> {
        let l = self.clutch(len)?;
        torque_from(or_overflow(self.cap_coef.div(l))?, false)
    }

    /// Deflection at the stress limit, θ_cap = τ_cap/k = σ_allow·L²/(3·E·r·R) (E–B).
    ///
    /// # Errors
    /// [`crate::Error::ClutchLengthOutOfRange`], [`crate::Error::Overflow`] if θ_cap ≥ 2³¹ rad.
    pub fn deflection_capacity(&self, len: Length) -> Result<Angle> {
        let l = self.clutch(len)?;
        let v = or_overflow(self.theta_cap_coef.mul(or_overflow(l.mul(l))?))?;
        Ok(Angle::from_bits(or_overflow(v.to_i64(32, false))?))
    }

    /// Deflection at the stress limit with the Timoshenko stiffness,
    /// θ_cap = τ_cap/k_T = σ_allow·(L² + s)/(3·E·r·R) (s: see [`crate::design`]).
    ///
    /// # Errors
    /// As [`Design::deflection_capacity`].
    pub fn deflection_capacity_timoshenko(&self, len: Length) -> Result<Angle> {
        let l = self.clutch(len)?;
        let l2_plus_s = or_overflow(or_overflow(l.mul(l))?.add(self.shear))?;
        let v = or_overflow(self.theta_cap_coef.mul(l2_plus_s))?;
        Ok(Angle::from_bits(or_overflow(v.to_i64(32, false))?))
    }
}
