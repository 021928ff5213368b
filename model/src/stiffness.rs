//! Joint stiffness at a clutch length L and its inverse (design.md §2 table):
//!
//! * k(L) = n·3·E·I·R²/L³ (paper eq. 4, Euler–Bernoulli) and
//!   k_T(L) = n·R²/(L³/(3EI) + L/(κGA)) (row 4T, Timoshenko);
//! * their inverses L(k): E–B in closed form, L = (n·3·E·I·R²/k)^(1/3), with the integer
//!   cube root of [`crate::fixmath`]; Timoshenko by bisection on the monotone k_T(L).
//!
//! The constants C = n·3·E·I·R² and s are derived once in [`Design::new`].

use crate::beam::{or_overflow, BeamModel};
use crate::design::Design;
use crate::error::{Error, Result};
use crate::fixmath::{icbrt_round, SoftFloat};
use crate::units::{Length, Stiffness};

/// k = C/L³ = (C/L)/L² (two roundings).
pub(crate) const fn k_eb(c_k: SoftFloat, len: SoftFloat) -> Option<SoftFloat> {
    match c_k.div(len) {
        Some(q) => match len.mul(len) {
            Some(l2) => q.div(l2),
            None => None,
        },
        None => None,
    }
}

/// k_T = C/(L³ + s·L) = (C/L)/(L² + s).
pub(crate) const fn k_timo(c_k: SoftFloat, shear: SoftFloat, len: SoftFloat) -> Option<SoftFloat> {
    match c_k.div(len) {
        Some(q) => match len.mul(len) {
            Some(l2) => match l2.add(shear) {
                Some(d) => q.div(d),
                None => None,
            },
            None => None,
        },
        None => None,
    }
}

/// How far above l (in I32F32 bits: 2⁻²⁰ of l, ≈ 1 ppm) an inverse may land and still be
/// clamped to l: k(l) itself is rounded to I64F64, so L(k(l)) can exceed l by a few LSB.
fn clamp_tolerance(l_bits: u128) -> u128 {
    (l_bits >> 20).max(1)
}

impl BeamModel {
    /// k(L) for this model: [`Design::stiffness`] or [`Design::stiffness_timoshenko`].
    ///
    /// # Errors
    /// As the function it dispatches to.
    pub fn stiffness(self, d: &Design, len: Length) -> Result<Stiffness> {
        match self {
            BeamModel::EulerBernoulli => d.stiffness(len),
            BeamModel::Timoshenko => d.stiffness_timoshenko(len),
        }
    }

    /// L(k) for this model: [`Design::clutch_length`] or
    /// [`Design::clutch_length_timoshenko`].
    ///
    /// # Errors
    /// As the function it dispatches to.
    pub fn clutch_length(self, d: &Design, k: Stiffness) -> Result<Length> {
        match self {
            BeamModel::EulerBernoulli => d.clutch_length(k),
            BeamModel::Timoshenko => d.clutch_length_timoshenko(k),
        }
    }
}

impl Design {
    /// L as a `SoftFloat`, checked against (0, l].
    pub(crate) fn clutch(&self, len: Length) -> Result<SoftFloat> {
        let b = len.to_bits();
        if b <= 0 || b > self.params().beam_length.to_bits() {
            return Err(Error::ClutchLengthOutOfRange);
        }
        Ok(SoftFloat::from_bits(b, 32).0)
    }

    pub(crate) fn k_scale(&self, model: BeamModel, len: SoftFloat) -> Result<SoftFloat> {
        or_overflow(match model {
            BeamModel::EulerBernoulli => k_eb(self.c_k, len), // eq. 4
            BeamModel::Timoshenko => k_timo(self.c_k, self.shear, len), // eq. 4T
        })
    }

    /// Joint stiffness k = n·3·E·I·R²/L³ (paper eq. 4), L ∈ (0, l].
    ///
    /// # Errors
    /// [`Error::ClutchLengthOutOfRange`], or [`Error::Overflow`] if k ≥ 9.2e18 N·m/rad.
    pub fn stiffness(&self, len: Length) -> Result<Stiffness> {
        let l = self.clutch(len)?;
        let k = self.k_scale(BeamModel::EulerBernoulli, l)?;
        Ok(Stiffness::from_bits(or_overflow(k.to_i128(64, false))?))
    }

    /// Shear-corrected joint stiffness k_T = n·R²/(L³/(3EI) + L/(κGA)) (Timoshenko, design.md
    /// row 4T), L ∈ (0, l].
    ///
    /// # Errors
    /// [`Error::ClutchLengthOutOfRange`], or [`Error::Overflow`] if k_T ≥ 9.2e18 N·m/rad.
    pub fn stiffness_timoshenko(&self, len: Length) -> Result<Stiffness> {
        let l = self.clutch(len)?;
        let k = self.k_scale(BeamModel::Timoshenko, l)?;
        Ok(Stiffness::from_bits(or_overflow(k.to_i128(64, false))?))
    }

    /// `q = C/k` (= L³ for E–B, L³ + s·L for Timoshenko) in mm³.
    fn cube_for(&self, k: Stiffness) -> Result<SoftFloat> {
        if k.to_bits() <= 0 {
            return Err(Error::StiffnessNotPositive);
        }
        // An exponent overflow here means q is astronomically large: L far beyond l.
        self.c_k.div(k.magnitude()).ok_or(Error::StiffnessTooLow)
    }

    /// Final checks of a clutch length in I32F32 bits: 0 → too stiff, within 1 ppm above l →
    /// l, beyond → too soft.
    fn finish_length(&self, bits: u128) -> Result<Length> {
        let lb = self.params().beam_length.to_bits() as u128;
        if bits == 0 {
            return Err(Error::StiffnessTooHigh);
        }
        if bits > lb {
            if bits - lb <= clamp_tolerance(lb) {
                return Ok(self.params().beam_length);
            }
            return Err(Error::StiffnessTooLow);
        }
        Ok(Length::from_bits(bits as i64))
    }

    /// Clutch length for a wanted stiffness, E–B: L = (n·3·E·I·R²/k)^(1/3) (inverse of
    /// eq. 4), rounded to the nearest LSB with an integer cube root.
    ///
    /// Domain: k > 0 with L(k) ∈ (0, l], i.e. k ≥ k(l). This is not limited to the
    /// adjustable range [t_c, l]: see [`Design::tune`] for that.
    ///
    /// # Errors
    /// [`Error::StiffnessNotPositive`] for k ≤ 0; [`Error::StiffnessTooLow`] if L > l
    /// (more than 1 ppm: closer is clamped to l); [`Error::StiffnessTooHigh`] if L rounds
    /// to 0 (for E–B only beyond [`Stiffness::MAX`]: every representable k has L ≥ 1.2e-8 mm
    /// in the design domain; for Timoshenko, k_T ∝ 1/L at short L, from about 1e14 N·m/rad).
    pub fn clutch_length(&self, k: Stiffness) -> Result<Length> {
        let q = self.cube_for(k)?;
        // L bits = (L³·2⁹⁶)^(1/3); L³ ≥ 2³² mm³ means L > 1625 mm > l.
        let x = q.to_u128(96).ok_or(Error::StiffnessTooLow)?;
        self.finish_length(icbrt_round(x)) // eq. 4, inverted
    }

    /// Clutch length for a wanted stiffness, Timoshenko: the L ∈ (0, l] with k_T(L) = k,
    /// found by bisection on L³ + s·L = n·3·E·I·R²/k (monotone in L) to the nearest LSB.
    ///
    /// # Errors
    /// As [`Design::clutch_length`].
    pub fn clutch_length_timoshenko(&self, k: Stiffness) -> Result<Length> {
        let q = self.cube_for(k)?;
        let lb = self.params().beam_length.to_bits() as u128;
        // g(L) = L·(L² + s), L = bits·2^-frac.
        let g = |bits: u128, frac: i64| -> Result<SoftFloat> {
            let len = or_overflow(SoftFloat::from_u128(bits, -frac))?;
            let len2 = or_overflow(len.mul(len))?;
            or_overflow(or_overflow(len2.add(self.shear))?.mul(len))
        };
        let mut lo: u128 = 0;
        let mut hi = lb + clamp_tolerance(lb);
        if g(hi, 32)?.lt(q) {
            return Err(Error::StiffnessTooLow);
        }
        // Invariant: g(lo) ≤ q ≤ g(hi).
        while hi - lo > 1 {
            let mid = lo + (hi - lo) / 2;
            if q.lt(g(mid, 32)?) {
                hi = mid;
            } else {
                lo = mid;
            }
        }
        // Nearest of lo, hi: compare q with g at the half-LSB point.
        let best = if q.lt(g(2 * lo + 1, 33)?) { lo } else { hi };
        self.finish_length(best)
    }

    /// Stiffness at both ends of the adjustable range, `(k(l), k(t_c))`: the softest and
    /// the stiffest setting (precomputed).
    #[must_use]
    pub const fn stiffness_range(&self, model: BeamModel) -> (Stiffness, Stiffness) {
        match model {
            BeamModel::EulerBernoulli => self.range_eb,
            BeamModel::Timoshenko => self.range_t,
        }
    }
}
