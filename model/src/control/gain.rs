//! Per-tick multipliers: a configuration-time constant as a block-floating 32-bit
//! mantissa and a right shift, so that the 1 kHz path multiplies a 32-bit signal by a
//! constant with one 32×32→64-bit multiply (`SMULL` on Cortex-M3) and a shift.
//!
//! Signals on the per-tick path are `i32` in Q16 (16 fractional bits, "I16F16": range
//! ±32 768 of their unit, resolution 1.5e-5). A [`Gain`] carries any change of unit:
//! `out = gain · in`, both Q16.

use fixed::types::I64F64;

/// One Q16 unit (1.0 in I16F16 bits).
pub(crate) const Q16_ONE: i32 = 1 << 16;

/// Saturates an `i64` into `i32`.
#[inline]
pub(crate) const fn sat_i32(v: i64) -> i32 {
    if v > i32::MAX as i64 {
        i32::MAX
    } else if v < i32::MIN as i64 {
        i32::MIN
    } else {
        v as i32
    }
}

/// Q32 (I32F32 bits) → Q16, rounding toward −∞, saturating.
#[inline]
pub(crate) const fn q32_to_q16(v: i64) -> i32 {
    sat_i32(v >> 16)
}

/// Q16 → Q32 (exact).
#[inline]
pub(crate) const fn q16_to_q32(v: i32) -> i64 {
    (v as i64) << 16
}

/// A constant multiplier `m·2^−s` (|m| < 2³¹, s ≤ 62), built at configuration time.
///
/// Relative precision 2⁻³⁰ or better for any value in [2⁻³², 2³¹); smaller values round
/// to zero, larger ones are rejected by [`Gain::new`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Gain {
    m: i32,
    s: u32,
}

impl Gain {
    /// Zero.
    pub const ZERO: Gain = Gain { m: 0, s: 0 };

    /// The nearest `Gain` to `v`, or `None` if |v| ≥ 2³¹ − 1.
    #[must_use]
    pub fn new(v: I64F64) -> Option<Gain> {
        let bits = v.to_bits(); // v·2⁶⁴
        if bits == 0 {
            return Some(Gain::ZERO);
        }
        let mag = bits.unsigned_abs();
        // Largest s ≤ 62 with round(|v|·2^s) < 2³⁰ (keeps a bit of headroom for rounding).
        let mut s: u32 = 62;
        loop {
            // |v|·2^s = mag·2^(s−64), rounded.
            let sh = 64 - s;
            let m = (mag + (1u128 << (sh - 1))) >> sh;
            if m < (1 << 30) {
                let m = m as i32;
                return Some(Gain {
                    m: if bits < 0 { -m } else { m },
                    s,
                });
            }
            if s == 0 {
                return None;
            }
            s -= 1;
        }
    }

    /// `round(v)` of an integer value (convenience for constants).
    #[must_use]
    pub fn from_int(v: i32) -> Option<Gain> {
        Gain::new(I64F64::from_num(v))
    }

    /// The multiplier as I64F64 (exact).
    #[must_use]
    pub fn value(self) -> I64F64 {
        I64F64::from_bits((i128::from(self.m)) << (64 - self.s))
    }

    /// `self · x` in the same fixed-point format as `x` (rounded toward −∞, saturating).
    #[inline]
    #[must_use]
    pub const fn apply(self, x: i32) -> i32 {
        sat_i32((x as i64 * self.m as i64) >> self.s)
    }

    /// `self · x` with 16 more fractional bits out than in (Q16 in, Q32 out), saturating.
    #[inline]
    #[must_use]
    pub const fn apply_wide(self, x: i32) -> i64 {
        let p = x as i64 * self.m as i64; // |p| < 2⁶²
        if self.s >= 16 {
            p >> (self.s - 16)
        } else {
            p.saturating_mul(1 << (16 - self.s))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gain_round_trip_and_apply() {
        for v in [0.0, 1.0, -1.0, 3.2e-3, 161_667.0, 1.0e-9, -7258.5, 1.0e9] {
            let g = Gain::new(I64F64::from_num(v)).unwrap();
            let back = g.value().to_num::<f64>();
            assert!((back - v).abs() <= v.abs() * 2e-9 + 1e-9, "{v}: {back}");
            let x = 12_345 * Q16_ONE / 100; // 123.45
            let want = (v * f64::from(x))
                .floor()
                .clamp(-2f64.powi(31), 2f64.powi(31) - 1.0);
            let got = f64::from(g.apply(x));
            assert!(
                (got - want).abs() <= want.abs() * 1e-8 + 1.0,
                "{v}: {got} vs {want}"
            );
        }
        assert_eq!(Gain::new(I64F64::from_num(3.0e9)), None);
        assert_eq!(Gain::from_int(2).unwrap().apply(i32::MAX), i32::MAX);
        assert_eq!(Gain::from_int(-2).unwrap().apply(i32::MAX), i32::MIN);
        let g = Gain::new(I64F64::from_num(0.001)).unwrap();
        assert!((g.apply_wide(1000 * Q16_ONE) - (1i64 << 32)).abs() <= 8);
    }
}
