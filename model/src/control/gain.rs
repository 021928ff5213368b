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
    // It fits iff the high half is the low half's sign: one compare of the halves on a
    // 32-bit core instead of two 64-bit compares.
    let lo = v as i32;
    if (v >> 32) as i32 == lo >> 31 {
        lo
    } else {
        ((v >> 63) as i32) ^ i32::MAX
    }
}

/// `x` (Q16) times a Q16 `scale` (|scale| < 2³¹, so the product fits i64), saturated; `x`
/// itself at a scale of 1 (the feed-forward scales of a move: `move_drive`, `speed_scale`).
#[inline(always)]
#[must_use]
pub(crate) fn scale_q16(x: i32, scale: i32) -> i32 {
    if scale == Q16_ONE {
        x
    } else {
        sat_i32((i64::from(x) * i64::from(scale)) >> 16)
    }
}

/// √r for a ratio r in [1/3, 1] (Q16, clamped to it), Q16: the quadratic
/// 1 + 0.4713·(r − 1) − 0.2358·(r − 1)² fitted to √r on that range, within 0.7 % of it and
/// exact at 1, in 32-bit products (the impact limit's factor for the drive a command met,
/// docs/design.md §11, "Free-play impacts").
#[inline]
#[must_use]
pub(crate) fn sqrt_ratio_q16(r: i32) -> i32 {
    const B: i32 = 30_888;
    const C: i32 = -15_456;
    // −43 691 ≤ d ≤ 0: d² < 1.91e9, B·d > −1.35e9, C·(d²/2¹⁶) > −4.5e8, all within i32.
    let d = r.clamp(Q16_ONE / 3, Q16_ONE) - Q16_ONE;
    Q16_ONE + ((B * d) >> 16) + ((C * ((d * d) >> 16)) >> 16)
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
        let p = x as i64 * self.m as i64;
        if self.s >= 32 {
            // ⌊p/2^s⌋ = ⌊⌊p/2³²⌋/2^(s−32)⌋: the product's high word alone, one shift
            // (a 64-bit shift by a variable amount is a dozen instructions on the M3), and
            // it cannot overflow (|m| < 2³⁰).
            ((p >> 32) as i32) >> (self.s - 32)
        } else {
            // p >> s for s < 32 in 32-bit halves (LLVM's i64 shift also handles s ≥ 32,
            // ten instructions more), then saturated.
            let (hi, lo) = ((p >> 32) as i32, p as u32);
            let s = self.s & 31;
            // (hi << 1) << (31 − s): hi << (32 − s) without a shift by 32 at s = 0.
            let r = (lo >> s) | (((hi as u32) << 1) << (31 - s));
            sat_i32(((hi >> s) as i64) << 32 | r as i64)
        }
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
    use crate::test_rng::xorshift;

    /// Against f64's square root: within 0.7 % on [1/3, 1], exact at 1, clamped outside.
    #[test]
    fn sqrt_ratio_is_within_its_fit() {
        for k in 0..=1000 {
            let r = 1.0 / 3.0 + f64::from(k) * (2.0 / 3.0) / 1000.0;
            let got = f64::from(sqrt_ratio_q16((r * 65536.0).round() as i32)) / 65536.0;
            let want = r.sqrt();
            assert!((got / want - 1.0).abs() < 0.007, "√{r}: {got} vs {want}");
        }
        assert_eq!(sqrt_ratio_q16(Q16_ONE), Q16_ONE);
        assert_eq!(sqrt_ratio_q16(2 * Q16_ONE), Q16_ONE);
        assert_eq!(sqrt_ratio_q16(0), sqrt_ratio_q16(Q16_ONE / 3));
    }

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

    #[test]
    fn sat_i32_is_the_clamp() {
        let edges = [
            0,
            1,
            -1,
            i64::from(i32::MAX),
            i64::from(i32::MIN),
            i64::MAX,
            i64::MIN,
        ];
        let near = edges
            .iter()
            .flat_map(|&e| [e, e.wrapping_add(1), e.wrapping_sub(1)]);
        let mut next = xorshift(0x2545_F491_4F6C_DD1D);
        let random = core::iter::repeat_with(move || {
            let r = next();
            (r as i64) >> (r % 64)
        });
        for v in near.chain(random.take(100_000)) {
            let want = v.clamp(i64::from(i32::MIN), i64::from(i32::MAX));
            assert_eq!(i64::from(sat_i32(v)), want, "{v}");
        }
    }

    /// `apply` is exactly ⌊v·x⌋ saturated, v the gain's exact value: checked in i128 on
    /// gains across the whole range of shifts (both of `apply`'s paths, s ≥ 32 and
    /// s < 32) and inputs including the extremes.
    #[test]
    fn apply_is_the_exact_floor_saturated() {
        let mut next = xorshift(0x9E37_79B9_7F4A_7C15);
        let mut shifts = [0u32; 63];
        for case in 0..200_000 {
            // |v| from 2⁻³² to 2³¹: a random mantissa at a random binary exponent.
            let e = (next() % 63) as i32 - 32;
            let mantissa = (next() as i64 >> 32) as i128; // ±2³¹, both signs
            let bits = mantissa << (e + 33);
            let Some(g) = Gain::new(I64F64::from_bits(bits)) else {
                continue;
            };
            shifts[g.s as usize] += 1;
            let x = match case % 5 {
                0 => i32::MAX,
                1 => i32::MIN,
                _ => next() as i32 >> (next() % 32),
            };
            let want = ((g.value().to_bits() * i128::from(x)) >> 64)
                .clamp(i128::from(i32::MIN), i128::from(i32::MAX));
            assert_eq!(i128::from(g.apply(x)), want, "{g:?} · {x}");
        }
        assert!(
            shifts.iter().all(|&n| n > 0),
            "every shift 0..=62 drawn: {shifts:?}"
        );
    }
}
