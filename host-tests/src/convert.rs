//! Glue between the fixed-point `model` (scaled units: mm, MPa, N·m, kg·mm², rad, rad/s,
//! N·m/rad) and the f64 SI [`crate::oracle`], plus the one comparison rule every
//! model-vs-oracle test uses.
//!
//! Fixed-point values are read with `.get().to_num::<f64>()` (exact for I32F32 values below
//! 2²¹ of their unit, otherwise rounded once at 1.1e-16 relative) and built from f64 via
//! their raw bits (`round(x·2^frac)`), since this crate does not depend on `fixed` itself.
//!
//! Comparison rule: a model value `got` matches an oracle value `want` when
//! `|got − want| ≤ max(1e-4·|want|, 2·LSB)`, LSB being the real resolution of the model's
//! output format (2⁻³² of the unit for the I32F32 quantities, 2⁻⁶⁴ N·m/rad for
//! [`Stiffness`]).

use model::{
    Angle, DesignParams, Force, Frequency, Inertia, Length, Ratio, Stiffness, Stress, Torque,
};

use crate::oracle;

/// Metres per millimetre.
pub const MM: f64 = 1e-3;
/// Pascals per MPa.
pub const MPA: f64 = 1e6;
/// kg·m² per kg·mm².
pub const KG_MM2: f64 = 1e-6;
/// Relative tolerance of the model against the oracle.
pub const REL_TOL: f64 = 1e-4;
/// One LSB of an I32F32 quantity (2⁻³² of its unit).
pub const LSB32: f64 = 1.0 / 4_294_967_296.0;
/// One LSB of [`Stiffness`] (I64F64: 2⁻⁶⁴ N·m/rad).
pub const LSB64: f64 = LSB32 * LSB32;
/// Magnitude bound of an I32F32 quantity, 2³¹ of its unit (exclusive for positive values).
pub const MAX32: f64 = 2_147_483_648.0;
/// Magnitude bound of [`Stiffness`], 2⁶³ N·m/rad.
pub const MAX64: f64 = MAX32 * MAX32 * 2.0;

/// The allowed deviation for an expected value `want` in a format of resolution `lsb`:
/// `max(1e-4·|want|, 2·lsb)`.
#[must_use]
pub fn tolerance(want: f64, lsb: f64) -> f64 {
    (REL_TOL * want.abs()).max(2.0 * lsb)
}

/// `|got − want| ≤ max(1e-4·|want|, 2·lsb)`.
#[must_use]
pub fn close(got: f64, want: f64, lsb: f64) -> bool {
    (got - want).abs() <= tolerance(want, lsb)
}

/// Relative error `|got − want| / |want|` (0 when both are 0, ∞ when only `want` is).
#[must_use]
pub fn rel_err(got: f64, want: f64) -> f64 {
    if got == want {
        0.0
    } else {
        (got - want).abs() / want.abs()
    }
}

/// I32F32 bits of `x` units, rounded to nearest; `None` if it does not fit.
#[must_use]
pub fn bits32(x: f64) -> Option<i64> {
    let b = (x * 4_294_967_296.0).round();
    // i64::MAX is not an f64: [−2^63, 2^63) (NaN and ±∞ are outside).
    let lim = 2f64.powi(63);
    (-lim..lim).contains(&b).then_some(b as i64)
}

/// I64F64 bits of `x` N·m/rad, rounded to nearest; `None` if it does not fit.
#[must_use]
pub fn bits64(x: f64) -> Option<i128> {
    let b = (x * 18_446_744_073_709_551_616.0).round();
    let lim = 2f64.powi(127);
    (-lim..lim).contains(&b).then_some(b as i128)
}

/// A length in mm.
#[must_use]
pub fn mm(v: Length) -> f64 {
    v.get().to_num::<f64>()
}

/// An angle in rad.
#[must_use]
pub fn rad(v: Angle) -> f64 {
    v.get().to_num::<f64>()
}

/// A torque in N·m.
#[must_use]
pub fn nm(v: Torque) -> f64 {
    v.get().to_num::<f64>()
}

/// A force in N.
#[must_use]
pub fn newton(v: Force) -> f64 {
    v.get().to_num::<f64>()
}

/// A stress in MPa.
#[must_use]
pub fn mpa(v: Stress) -> f64 {
    v.get().to_num::<f64>()
}

/// A dimensionless ratio.
#[must_use]
pub fn ratio(v: Ratio) -> f64 {
    v.get().to_num::<f64>()
}

/// An inertia in kg·mm².
#[must_use]
pub fn kg_mm2(v: Inertia) -> f64 {
    v.get().to_num::<f64>()
}

/// An angular frequency in rad/s.
#[must_use]
pub fn rad_s(v: Frequency) -> f64 {
    v.get().to_num::<f64>()
}

/// A stiffness in N·m/rad.
#[must_use]
pub fn nm_rad(v: Stiffness) -> f64 {
    v.get().to_num::<f64>()
}

/// The oracle's SI design for the model's parameters (the same values, converted exactly
/// up to f64 rounding of the unit factors).
#[must_use]
pub fn oracle_design(p: &DesignParams) -> oracle::Design {
    oracle::Design {
        n: u32::from(p.beams),
        r: mm(p.beam_radius) * MM,
        pitch_r: mm(p.pitch_radius) * MM,
        e: mpa(p.youngs_modulus) * MPA,
        g: mpa(p.shear_modulus) * MPA,
        sigma_allow: mpa(p.allowable_stress) * MPA,
        l: mm(p.beam_length) * MM,
        t_c: mm(p.clutch_thickness) * MM,
        mu: ratio(p.friction),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn comparison_rule() {
        assert!(close(1.000_09, 1.0, LSB32));
        assert!(!close(1.000_11, 1.0, LSB32));
        // Near resolution the 2-LSB floor applies.
        assert!(close(3.0 * LSB32, LSB32, LSB32));
        assert!(!close(3.5 * LSB32, LSB32, LSB32));
        assert!(close(0.0, 2.0 * LSB64, LSB64));
        assert!(!close(0.0, 2.0 * LSB32, LSB64));
    }

    #[test]
    fn bits_round_trip() {
        assert_eq!(bits32(1.5), Some(3 << 31));
        assert_eq!(bits32(-MAX32), Some(i64::MIN));
        assert_eq!(bits32(MAX32), None);
        assert_eq!(bits64(-1.0), Some(-(1i128 << 64)));
        assert_eq!(bits64(MAX64), None);
        assert!((mm(Length::from_bits(bits32(7.8).unwrap())) - 7.8).abs() <= 0.5 * LSB32);
        let p = oracle_design(&DesignParams::PAPER);
        let o = oracle::Design::paper();
        assert_eq!((p.n, p.e, p.g, p.l, p.t_c), (o.n, o.e, o.g, o.l, o.t_c));
        assert!(rel_err(p.r, o.r) < 1e-15 && rel_err(p.sigma_allow, o.sigma_allow) < 1e-15);
        // R = 7.8 mm and μ = 0.4 are not dyadic: the model holds them to 2⁻³².
        assert!(rel_err(p.pitch_r, o.pitch_r) < 1e-10 && rel_err(p.mu, o.mu) < 1e-9);
    }
}
