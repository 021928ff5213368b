//! Physical quantities as newtypes over `fixed` numbers, one type per unit.
//!
//! Scaled units keep the paper's values in comfortable ranges: lengths in mm, stresses and
//! moduli in MPa (= N/mm²), torques in N·m, stiffness in N·m/rad, inertia in kg·mm².
//! All but [`Stiffness`] are I32F32: range ±2³¹ (±2.1e9) of the unit, resolution 2⁻³²
//! (2.3e-10). Stiffness spans 1e-11…1e17 N·m/rad over the documented design domain, so it
//! is I64F64: range ±9.2e18 N·m/rad, resolution 2⁻⁶⁴ (5.4e-20).
//!
//! Construct values without floats: [`Length::from_int`], [`Length::from_micro`]
//! (millionths of the unit), [`Length::from_bits`], or
//! `Length::from_fixed(I32F32::lit("0.5"))` in a `const`. Host code may build the inner
//! fixed value with `fixed`'s `from_num` and read it back with `.get().to_num::<f64>()`.

use core::fmt;

use fixed::types::{I32F32, I64F64};

use crate::error::{Error, Result};
use crate::fixmath::{SoftFloat, FRAC_1_TAU, TAU};

macro_rules! unit_i32f32 {
    ($(#[$doc:meta])* $name:ident, $unit:literal) => {
        $(#[$doc])*
        #[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash)]
        #[repr(transparent)]
        pub struct $name(I32F32);

        impl $name {
            /// Zero.
            pub const ZERO: Self = Self(I32F32::ZERO);
            /// Largest representable value (≈ 2.1e9 of the unit).
            pub const MAX: Self = Self(I32F32::MAX);
            /// Most negative representable value (−2³¹ of the unit).
            pub const MIN: Self = Self(I32F32::MIN);
            /// Resolution: one LSB, 2⁻³² of the unit.
            pub const DELTA: Self = Self(I32F32::DELTA);
            /// Unit symbol, as printed by `Display`.
            pub const UNIT: &'static str = $unit;

            /// Wraps an I32F32 value in this unit.
            #[must_use]
            pub const fn from_fixed(v: I32F32) -> Self {
                Self(v)
            }

            /// The inner I32F32 value, in this unit.
            #[must_use]
            pub const fn get(self) -> I32F32 {
                self.0
            }

            /// From raw I32F32 bits (value × 2³²).
            #[must_use]
            pub const fn from_bits(bits: i64) -> Self {
                Self(I32F32::from_bits(bits))
            }

            /// Raw I32F32 bits (value × 2³²); log these from the 1 kHz path.
            #[must_use]
            pub const fn to_bits(self) -> i64 {
                self.0.to_bits()
            }

            /// An integer number of units, exactly.
            #[must_use]
            pub const fn from_int(v: i32) -> Self {
                Self::from_bits((v as i64) << 32)
            }

            /// `v` millionths of the unit, rounded to the nearest LSB.
            ///
            /// # Errors
            /// [`Error::Overflow`] if |v|·10⁻⁶ does not fit (|v| ≥ 2.1e15).
            pub const fn from_micro(v: i64) -> Result<Self> {
                match micro_bits(v as i128, 32) {
                    Some(b) if b >= i64::MIN as i128 && b <= i64::MAX as i128 => {
                        Ok(Self::from_bits(b as i64))
                    }
                    _ => Err(Error::Overflow),
                }
            }

            /// Sum, or `None` on overflow.
            #[must_use]
            pub const fn checked_add(self, o: Self) -> Option<Self> {
                match self.0.checked_add(o.0) {
                    Some(v) => Some(Self(v)),
                    None => None,
                }
            }

            /// Difference, or `None` on overflow.
            #[must_use]
            pub const fn checked_sub(self, o: Self) -> Option<Self> {
                match self.0.checked_sub(o.0) {
                    Some(v) => Some(Self(v)),
                    None => None,
                }
            }

            /// Negation, or `None` for [`Self::MIN`].
            #[must_use]
            pub const fn checked_neg(self) -> Option<Self> {
                match self.0.checked_neg() {
                    Some(v) => Some(Self(v)),
                    None => None,
                }
            }

            /// Sum, saturating at the format's bounds.
            #[must_use]
            pub const fn saturating_add(self, o: Self) -> Self {
                Self(self.0.saturating_add(o.0))
            }

            /// Difference, saturating at the format's bounds.
            #[must_use]
            pub const fn saturating_sub(self, o: Self) -> Self {
                Self(self.0.saturating_sub(o.0))
            }

            /// Absolute value, saturating ([`Self::MIN`] gives [`Self::MAX`]).
            #[must_use]
            pub const fn saturating_abs(self) -> Self {
                Self(self.0.saturating_abs())
            }

            /// `true` if below zero.
            #[must_use]
            pub const fn is_negative(self) -> bool {
                self.0.is_negative()
            }
        }

        impl fmt::Display for $name {
            fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                if $unit.is_empty() {
                    fmt::Display::fmt(&self.0, f)
                } else {
                    write!(f, "{} {}", self.0, $unit)
                }
            }
        }

        #[cfg(feature = "defmt")]
        impl defmt::Format for $name {
            fn format(&self, f: defmt::Formatter<'_>) {
                defmt::write!(f, "{=str}(bits={=i64})", stringify!($name), self.0.to_bits());
            }
        }
    };
}

/// `round(v·10⁻⁶·2^frac)`, ties away from zero.
const fn micro_bits(v: i128, frac: u32) -> Option<i128> {
    // |v| ≤ 2^63 and frac ≤ 64, so |v|·2^frac ≤ 2^127 fits u128.
    let n = v.unsigned_abs() << frac;
    let q = (n + 500_000) / 1_000_000;
    if q > i128::MAX as u128 {
        return None;
    }
    Some(if v < 0 { -(q as i128) } else { q as i128 })
}

unit_i32f32! {
    /// A length in millimetres, I32F32: range ±2.1e9 mm, resolution 2.3e-10 mm.
    ///
    /// Beam radius r, pitch radius R, beam length l, clutch length L, clutch thickness t_c,
    /// tip deflection δ, slot clearance c.
    Length, "mm"
}

unit_i32f32! {
    /// An angle in radians, I32F32: range ±2.1e9 rad, resolution 2.3e-10 rad.
    ///
    /// Joint deflection θ or φ (gear-side minus link-side angle), backlash, free play.
    Angle, "rad"
}

unit_i32f32! {
    /// A torque in newton-metres, I32F32: range ±2.1e9 N·m, resolution 2.3e-10 N·m.
    Torque, "N·m"
}

unit_i32f32! {
    /// A force in newtons, I32F32: range ±2.1e9 N, resolution 2.3e-10 N (per-beam load P).
    Force, "N"
}

unit_i32f32! {
    /// A stress or an elastic modulus in MPa (= N/mm²), I32F32: range ±2.1e9 MPa,
    /// resolution 2.3e-10 MPa. 200 GPa is `Stress::from_int(200_000)` or
    /// `Stress::from_gpa(200)`.
    Stress, "MPa"
}

unit_i32f32! {
    /// A moment of inertia in kg·mm² (1 kg·m² = 10⁶ kg·mm²), I32F32: range ±2.1e9 kg·mm²,
    /// resolution 2.3e-10 kg·mm². The default link, 1e-3 kg·m², is 1000 kg·mm².
    Inertia, "kg·mm²"
}

unit_i32f32! {
    /// An angular frequency in rad/s, I32F32: range ±2.1e9 rad/s, resolution 2.3e-10 rad/s.
    Frequency, "rad/s"
}

unit_i32f32! {
    /// A dimensionless number (friction coefficient μ, Poisson's ratio ν, shear factor κ),
    /// I32F32: range ±2.1e9, resolution 2.3e-10.
    Ratio, ""
}

impl Stress {
    /// `v` GPa (exact).
    ///
    /// # Errors
    /// [`Error::Overflow`] if 1000·|v| MPa does not fit (|v| > 2 147 483).
    pub const fn from_gpa(v: i32) -> Result<Self> {
        match (v as i64).checked_mul(1000) {
            Some(mpa) if mpa >= i32::MIN as i64 && mpa <= i32::MAX as i64 => {
                Ok(Self::from_int(mpa as i32))
            }
            _ => Err(Error::Overflow),
        }
    }
}

impl Frequency {
    /// The angular frequency of `hz` hertz, ω = 2π·f.
    ///
    /// # Errors
    /// [`Error::Overflow`] if ω does not fit (|f| ≥ 3.4e8 Hz).
    pub const fn from_hz(hz: I32F32) -> Result<Self> {
        match TAU.mul_i64(hz.to_bits()) {
            Some(b) => Ok(Self::from_bits(b)),
            None => Err(Error::Overflow),
        }
    }

    /// This angular frequency in hertz, f = ω/(2π), I32F32 (rounded to nearest).
    #[must_use]
    pub const fn to_hz(self) -> I32F32 {
        // |ω/2π| < |ω|: cannot overflow.
        match FRAC_1_TAU.mul_i64(self.to_bits()) {
            Some(b) => I32F32::from_bits(b),
            None => I32F32::ZERO,
        }
    }
}

/// A joint stiffness in N·m/rad, I64F64: range ±9.2e18 N·m/rad, resolution 5.4e-20
/// N·m/rad (relative resolution better than 4e-9 down to 1.5e-11 N·m/rad, the softest
/// setting the documented design domain allows).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash)]
#[repr(transparent)]
pub struct Stiffness(I64F64);

impl Stiffness {
    /// Zero.
    pub const ZERO: Self = Self(I64F64::ZERO);
    /// Largest representable value (≈ 9.2e18 N·m/rad).
    pub const MAX: Self = Self(I64F64::MAX);
    /// Resolution: one LSB, 2⁻⁶⁴ N·m/rad.
    pub const DELTA: Self = Self(I64F64::DELTA);
    /// Unit symbol, as printed by `Display`.
    pub const UNIT: &'static str = "N·m/rad";

    /// Wraps an I64F64 value in N·m/rad.
    #[must_use]
    pub const fn from_fixed(v: I64F64) -> Self {
        Self(v)
    }

    /// The inner I64F64 value in N·m/rad.
    #[must_use]
    pub const fn get(self) -> I64F64 {
        self.0
    }

    /// From raw I64F64 bits (value × 2⁶⁴).
    #[must_use]
    pub const fn from_bits(bits: i128) -> Self {
        Self(I64F64::from_bits(bits))
    }

    /// Raw I64F64 bits (value × 2⁶⁴).
    #[must_use]
    pub const fn to_bits(self) -> i128 {
        self.0.to_bits()
    }

    /// An integer number of N·m/rad, exactly.
    #[must_use]
    pub const fn from_int(v: i64) -> Self {
        Self::from_bits((v as i128) << 64)
    }

    /// `v` millionths of a N·m/rad (µN·m/rad), rounded to the nearest LSB; always fits.
    #[must_use]
    pub const fn from_micro(v: i64) -> Self {
        match micro_bits(v as i128, 64) {
            Some(b) => Self::from_bits(b),
            None => Self::ZERO, // unreachable: |v·2^64/10^6| < 2^108
        }
    }

    /// `true` if below zero.
    #[must_use]
    pub const fn is_negative(self) -> bool {
        self.0.is_negative()
    }

    /// The magnitude as a `SoftFloat` (exact to 2⁻⁶³ relative).
    pub(crate) const fn magnitude(self) -> SoftFloat {
        match SoftFloat::from_u128(self.0.to_bits().unsigned_abs(), -64) {
            Some(s) => s,
            None => SoftFloat::ZERO, // unreachable: the exponent is in [-64, 63]
        }
    }
}

impl fmt::Display for Stiffness {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} N·m/rad", self.0)
    }
}

#[cfg(feature = "defmt")]
impl defmt::Format for Stiffness {
    fn format(&self, f: defmt::Formatter<'_>) {
        defmt::write!(f, "Stiffness(bits={=i128})", self.0.to_bits());
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn constructors_without_floats() {
        assert_eq!(Length::from_int(8).get(), I32F32::from_num(8));
        assert_eq!(
            Length::from_micro(500_000).unwrap().get(),
            I32F32::lit("0.5")
        );
        assert_eq!(
            Length::from_micro(-500_000).unwrap().get(),
            I32F32::lit("-0.5")
        );
        assert_eq!(Length::from_micro(i64::MAX), Err(Error::Overflow));
        assert_eq!(Stress::from_gpa(200).unwrap(), Stress::from_int(200_000));
        assert_eq!(Stress::from_gpa(i32::MAX), Err(Error::Overflow));
        assert_eq!(Stiffness::from_micro(1_500_000).get(), I64F64::lit("1.5"));
        assert_eq!(Stiffness::from_int(-3).get(), I64F64::from_num(-3));
        assert_eq!(Torque::from_bits(5).to_bits(), 5);
        let hz = Frequency::from_hz(I32F32::from_num(1)).unwrap();
        assert!((hz.get().to_num::<f64>() - core::f64::consts::TAU).abs() < 1e-9);
        assert!((hz.to_hz().to_num::<f64>() - 1.0).abs() < 1e-9);
        assert_eq!(Frequency::from_hz(I32F32::MAX), Err(Error::Overflow));
        assert_eq!(Torque::MAX.checked_add(Torque::DELTA), None);
        assert_eq!(Angle::MIN.saturating_abs(), Angle::MAX);
        assert_eq!(format!("{}", Length::from_int(2)), "2 mm");
        assert_eq!(format!("{}", Ratio::from_int(2)), "2");
    }
}
