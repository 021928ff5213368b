//! Integer-only numerics: square and cube roots, and `SoftFloat`, the positive software
//! floating-point number (64-bit mantissa, 32-bit exponent) that carries the design's
//! derived constants.
//!
//! * [`icbrt`] / [`icbrt_round`]: bitwise (digit-by-digit) cube root of a `u128`. The
//!   inverse of paper eq. 4, `L = (n·3·E·I·R² / k)^(1/3)`, takes it on `L³` scaled by
//!   2⁹⁶, which yields `L` directly in I32F32 bits (`fixed` has no cube root).
//! * [`isqrt`] / [`isqrt_round`]: bitwise square root of a `u128`, used for the natural
//!   frequency `ω_n = √(k/J)` (ω² scaled by 2⁶⁴ gives ω in I32F32 bits).
//! * `SoftFloat` (crate-internal): a positive number `m·2^e` with a normalised 64-bit `m`.
//!   The design spans ~22 decades (k from 1e-11 to 1e17 N·m/rad over the documented
//!   domain), which no single fixed-point format covers with 1e-4 relative accuracy. Each
//!   `SoftFloat` operation rounds once at 2⁻⁶³ relative, so chains of products and quotients
//!   stay far inside the accuracy budget; the result is rounded once into the public
//!   fixed-point format. Applying a `SoftFloat` to a fixed-point value (`SoftFloat::mul_i64`) is
//!   one 64×64→128-bit multiply and a shift: that is the per-tick path, with every
//!   division by a configuration value replaced by a precomputed reciprocal.
//!
//! Everything here is integer arithmetic: results are bit-identical on x86 and Cortex-M.

use core::cmp::Ordering;

/// Floor square root of `n` and the remainder `n − root²` (bitwise, digit by digit).
#[must_use]
pub const fn isqrt(n: u128) -> (u128, u128) {
    let mut x = n;
    let mut res: u128 = 0;
    let mut bit: u128 = 1 << 126;
    while bit > x {
        bit >>= 2;
    }
    while bit != 0 {
        // res + bit < 2^127: res < 2^64 and bit ≤ 2^126.
        if x >= res + bit {
            x -= res + bit;
            res = (res >> 1) + bit;
        } else {
            res >>= 1;
        }
        bit >>= 2;
    }
    (res, x)
}

/// Square root of `n` rounded to the nearest integer.
#[must_use]
pub const fn isqrt_round(n: u128) -> u128 {
    let (y, rem) = isqrt(n);
    // (y + ½)² = y² + y + ¼, so round up iff rem ≥ y + ¼, i.e. rem > y.
    if rem > y {
        y + 1
    } else {
        y
    }
}

/// Floor cube root of `n` and the remainder `n − root³` (bitwise, three bits per step;
/// Hacker's Delight `icbrt` widened to 128 bits, with the trial value compared before
/// shifting so that nothing overflows).
#[must_use]
pub const fn icbrt(n: u128) -> (u128, u128) {
    let mut x = n;
    let mut y: u128 = 0;
    // y², kept up to date with shifts and adds (no 128-bit multiply per step).
    let mut y2: u128 = 0;
    let mut s: i32 = 126;
    // While y = 0 a step only tests x >> s ≥ 1: skip the steps where that fails.
    while s > 0 && (x >> s) == 0 {
        s -= 3;
    }
    while s >= 0 {
        y <<= 1;
        y2 <<= 2;
        // y < 2^43, so b = 3·y·(y + 1) + 1 < 2^88.
        let b = 3 * (y2 + y) + 1;
        if (x >> s) >= b {
            x -= b << s;
            y2 += 2 * y + 1;
            y += 1;
        }
        s -= 3;
    }
    (y, x)
}

/// Cube root of `n` rounded to the nearest integer.
#[must_use]
pub const fn icbrt_round(n: u128) -> u128 {
    let (y, rem) = icbrt(n);
    // (y + ½)³ = y³ + (12y² + 6y + 1)/8: round up iff 8·rem ≥ 12y² + 6y + 1, i.e.
    // 8·rem > 12y² + 6y. rem ≤ 3y² + 3y < 2^89, y < 2^43: no overflow.
    if 8 * rem > 12 * y * y + 6 * y {
        y + 1
    } else {
        y
    }
}

/// `(⌊a·2⁶⁴/d⌋, a·2⁶⁴ mod d)` for normalised `a`, `d` (top bit set): the quotient of
/// [`SoftFloat::div`], exactly as `((a as u128) << 64) / d` and `% d`.
///
/// A 32-bit core has no 128-bit divide: the generic `u128` division is a library routine
/// of thousands of instructions on a Cortex-M3. This is Knuth's algorithm D (TAOCP 4.3.1;
/// Hacker's Delight `divmnu`) in 16-bit digits, so that every step is one 32/32-bit
/// hardware divide (`UDIV`) and 16×16-bit products: the top quotient bit is `a ≥ d`, then
/// four quotient digits of `(a mod d)·2⁶⁴ / d`. `d` is already normalised (its top digit
/// is ≥ 2¹⁵), so no shift is needed.
pub(crate) const fn div_normalised(a: u64, d: u64) -> (u128, u64) {
    const B: u32 = 1 << 16;
    const M: u32 = B - 1;
    let top = a >= d;
    let a = if top { a - d } else { a }; // now a < d
    let v = [
        (d & 0xFFFF) as u32,
        ((d >> 16) & 0xFFFF) as u32,
        ((d >> 32) & 0xFFFF) as u32,
        (d >> 48) as u32,
    ];
    // Dividend a·2⁶⁴ in 16-bit digits, least significant first, with one digit of headroom.
    let mut u = [
        0,
        0,
        0,
        0,
        (a & 0xFFFF) as u32,
        ((a >> 16) & 0xFFFF) as u32,
        ((a >> 32) & 0xFFFF) as u32,
        (a >> 48) as u32,
        0,
    ];
    let mut q: u64 = 0;
    let mut j: usize = 4;
    while j > 0 {
        j -= 1;
        // Estimate the digit from the top two digits of the remainder and the top digit of
        // d; it is at most 2 too large, and the test against the second digit of d corrects
        // all but (rarely) one of that.
        let num = (u[j + 4] << 16) | u[j + 3];
        let mut qhat = num / v[3];
        let mut rhat = num - qhat * v[3];
        // qhat < 2¹⁶ and rhat < 2¹⁶ when the product test runs: it fits 32 bits.
        while qhat >= B || qhat * v[2] > ((rhat << 16) | u[j + 2]) {
            qhat -= 1;
            rhat += v[3];
            if rhat >= B {
                break;
            }
        }
        // Multiply and subtract: u[j..=j+4] −= qhat·v (16-bit digits, 32-bit arithmetic:
        // products < 2³², the borrow ≤ 2¹⁶ + 1).
        let mut borrow: i32 = 0;
        let mut i = 0;
        while i < 4 {
            let p = qhat * v[i];
            let t = u[i + j] as i32 - borrow - (p & M) as i32;
            u[i + j] = t as u32 & M;
            borrow = (p >> 16) as i32 - (t >> 16);
            i += 1;
        }
        let t = u[j + 4] as i32 - borrow;
        u[j + 4] = t as u32 & M;
        if t < 0 {
            // qhat was one too large: add d back.
            qhat -= 1;
            let mut carry: u32 = 0;
            let mut i = 0;
            while i < 4 {
                let t = u[i + j] + v[i] + carry;
                u[i + j] = t & M;
                carry = t >> 16;
                i += 1;
            }
            u[j + 4] = (u[j + 4] + carry) & M;
        }
        q |= (qhat as u64) << (16 * j);
    }
    let r = u[0] as u64 | (u[1] as u64) << 16 | (u[2] as u64) << 32 | (u[3] as u64) << 48;
    (((top as u128) << 64) | q as u128, r)
}

/// Positive software floating-point number `m·2^e`; `m = 0` is zero, otherwise `m ∈ [2⁶³, 2⁶⁴)` (normalised).
///
/// Every operation rounds to nearest once (relative error ≤ 2⁻⁶³) and returns `None` when
/// the exponent leaves `i32` (never inside the documented domain) or on a division by
/// zero. Subtraction exists only as a saturating variant (the crate never needs a negative
/// `SoftFloat`; signs are carried beside it).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct SoftFloat {
    m: u64,
    e: i32,
}

impl SoftFloat {
    pub(crate) const ZERO: SoftFloat = SoftFloat { m: 0, e: 0 };
    pub(crate) const ONE: SoftFloat = SoftFloat { m: 1 << 63, e: -63 };

    /// `x·2^e`, rounded (half up) to 64 significant bits.
    pub(crate) const fn from_u128(x: u128, e: i64) -> Option<SoftFloat> {
        if x == 0 {
            return Some(Self::ZERO);
        }
        let lz = x.leading_zeros() as i64;
        let (m, e) = if lz >= 64 {
            let sh = lz - 64;
            ((x << sh) as u64, e - sh)
        } else {
            let sh = 64 - lz; // 1..=64
            let t = x >> (sh - 1); // 65 significant bits
            let t = (t >> 1) + (t & 1);
            if t > u64::MAX as u128 {
                (1u64 << 63, e + sh + 1)
            } else {
                (t as u64, e + sh)
            }
        };
        if e < i32::MIN as i64 || e > i32::MAX as i64 {
            return None;
        }
        Some(SoftFloat { m, e: e as i32 })
    }

    /// An integer, exactly.
    pub(crate) const fn from_u64(v: u64) -> SoftFloat {
        if v == 0 {
            return Self::ZERO;
        }
        let lz = v.leading_zeros();
        SoftFloat {
            m: v << lz,
            e: -(lz as i32),
        }
    }

    /// Magnitude of a signed fixed-point value with `frac` fractional bits, exactly, and
    /// whether it was negative.
    pub(crate) const fn from_bits(bits: i64, frac: u32) -> (SoftFloat, bool) {
        let u = bits.unsigned_abs();
        if u == 0 {
            return (Self::ZERO, false);
        }
        let lz = u.leading_zeros();
        (
            SoftFloat {
                m: u << lz,
                e: -(lz as i32) - frac as i32,
            },
            bits < 0,
        )
    }

    pub(crate) const fn mul(self, o: SoftFloat) -> Option<SoftFloat> {
        if self.m == 0 || o.m == 0 {
            return Some(Self::ZERO);
        }
        let p = self.m as u128 * o.m as u128;
        Self::from_u128(p, self.e as i64 + o.e as i64)
    }

    /// `self / o`; `None` if `o` is zero.
    pub(crate) const fn div(self, o: SoftFloat) -> Option<SoftFloat> {
        if o.m == 0 {
            return None;
        }
        if self.m == 0 {
            return Some(Self::ZERO);
        }
        // q = ⌊m_a·2⁶⁴ / m_b⌋ ∈ (2⁶³, 2⁶⁵) and its remainder, exactly.
        let (q, r) = div_normalised(self.m, o.m);
        // One extra bit that says "remainder ≥ half": from_u128 then rounds to nearest.
        let q2 = (q << 1) | ((r >= o.m - r) as u128);
        Self::from_u128(q2, self.e as i64 - o.e as i64 - 65)
    }

    pub(crate) const fn recip(self) -> Option<SoftFloat> {
        Self::ONE.div(self)
    }

    pub(crate) const fn add(self, o: SoftFloat) -> Option<SoftFloat> {
        if self.m == 0 {
            return Some(o);
        }
        if o.m == 0 {
            return Some(self);
        }
        let (a, b) = if self.e >= o.e { (self, o) } else { (o, self) };
        let d = a.e as i64 - b.e as i64;
        let x = (a.m as u128) << 62; // < 2^126
        let y = if d > 126 {
            0
        } else {
            ((b.m as u128) << 62) >> d
        };
        Self::from_u128(x + y, a.e as i64 - 62)
    }

    /// `max(self − o, 0)`. Exact when the operands are within a factor of two (where
    /// cancellation happens).
    pub(crate) const fn saturating_sub(self, o: SoftFloat) -> SoftFloat {
        if o.m == 0 {
            return self;
        }
        if !o.lt(self) {
            return Self::ZERO;
        }
        // self > o > 0, both normalised, so self.e ≥ o.e.
        let d = self.e as i64 - o.e as i64;
        let x = (self.m as u128) << 63;
        let y = if d > 126 {
            0
        } else {
            ((o.m as u128) << 63) >> d
        };
        match Self::from_u128(x - y, self.e as i64 - 63) {
            Some(v) => v,
            // The result is smaller than self: its exponent cannot leave i32 upwards, and
            // the subtraction removes at most 127 bits.
            None => Self::ZERO,
        }
    }

    pub(crate) const fn cmp(self, o: SoftFloat) -> Ordering {
        if self.m == 0 || o.m == 0 {
            return if self.m == o.m {
                Ordering::Equal
            } else if self.m == 0 {
                Ordering::Less
            } else {
                Ordering::Greater
            };
        }
        if self.e != o.e {
            return if self.e < o.e {
                Ordering::Less
            } else {
                Ordering::Greater
            };
        }
        if self.m < o.m {
            Ordering::Less
        } else if self.m > o.m {
            Ordering::Greater
        } else {
            Ordering::Equal
        }
    }

    pub(crate) const fn lt(self, o: SoftFloat) -> bool {
        matches!(self.cmp(o), Ordering::Less)
    }

    /// `round(value·2^frac)` as an unsigned integer, `None` if ≥ 2¹²⁸.
    pub(crate) const fn to_u128(self, frac: u32) -> Option<u128> {
        if self.m == 0 {
            return Some(0);
        }
        let s = self.e as i64 + frac as i64;
        if s >= 0 {
            if s > 64 {
                None
            } else {
                Some((self.m as u128) << s)
            }
        } else {
            let k = -s;
            if k > 65 {
                Some(0)
            } else {
                Some((self.m as u128 + (1u128 << (k - 1))) >> k)
            }
        }
    }

    /// `±round(value·2^frac)` as `i64` bits, `None` if out of range.
    pub(crate) const fn to_i64(self, frac: u32, negative: bool) -> Option<i64> {
        match self.to_u128(frac) {
            Some(u) => signed_i64(u, negative),
            None => None,
        }
    }

    /// `±round(value·2^frac)` as `i128` bits, `None` if out of range.
    pub(crate) const fn to_i128(self, frac: u32, negative: bool) -> Option<i128> {
        match self.to_u128(frac) {
            Some(u) => {
                if negative {
                    if u <= 1 << 127 {
                        Some((u as i128).wrapping_neg())
                    } else {
                        None
                    }
                } else if u <= i128::MAX as u128 {
                    Some(u as i128)
                } else {
                    None
                }
            }
            None => None,
        }
    }

    /// `round(x·value)` for fixed-point bits `x` (same format in and out; the scale's unit
    /// carries any change of unit). One 64×64→128 multiply: the per-tick path.
    pub(crate) const fn mul_i64(self, x: i64) -> Option<i64> {
        let p = x.unsigned_abs() as u128 * self.m as u128; // < 2^127
        if p == 0 {
            return Some(0);
        }
        let u = if self.e >= 0 {
            let s = self.e as u32;
            if s >= p.leading_zeros() {
                return None;
            }
            p << s
        } else {
            let k = self.e.unsigned_abs();
            if k > 127 {
                0
            } else {
                // p < 2^127 and 2^(k−1) ≤ 2^126: the sum fits.
                (p + (1u128 << (k - 1))) >> k
            }
        };
        signed_i64(u, x < 0)
    }
}

const fn signed_i64(u: u128, negative: bool) -> Option<i64> {
    if negative {
        if u <= 1 << 63 {
            Some((u as i64).wrapping_neg())
        } else {
            None
        }
    } else if u <= i64::MAX as u128 {
        Some(u as i64)
    } else {
        None
    }
}

/// π as a `SoftFloat` (from `fixed::consts::PI`, U2F126).
pub(crate) const PI: SoftFloat = match SoftFloat::from_u128(fixed::consts::PI.to_bits(), -126) {
    Some(v) => v,
    None => SoftFloat::ZERO,
};
/// π/4 as a `SoftFloat` (from `fixed::consts::FRAC_PI_4`, U0F128).
pub(crate) const FRAC_PI_4: SoftFloat =
    match SoftFloat::from_u128(fixed::consts::FRAC_PI_4.to_bits(), -128) {
        Some(v) => v,
        None => SoftFloat::ZERO,
    };
/// 2π as a `SoftFloat` (from `fixed::consts::TAU`, U3F125).
pub(crate) const TAU: SoftFloat = match SoftFloat::from_u128(fixed::consts::TAU.to_bits(), -125) {
    Some(v) => v,
    None => SoftFloat::ZERO,
};
/// 1/(2π) as a `SoftFloat` (from `fixed::consts::FRAC_1_TAU`, U0F128).
pub(crate) const FRAC_1_TAU: SoftFloat =
    match SoftFloat::from_u128(fixed::consts::FRAC_1_TAU.to_bits(), -128) {
        Some(v) => v,
        None => SoftFloat::ZERO,
    };

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn div_normalised_is_the_u128_division() {
        let top = 1u64 << 63;
        let mut cases = vec![
            (top, top),
            (u64::MAX, top),
            (top, u64::MAX),
            (u64::MAX, u64::MAX),
            (u64::MAX - 1, u64::MAX),
            (top + 1, top),
            (top, top + 1),
            (0xFFFF_0000_0000_0000, 0x8000_0000_0000_FFFF),
            (0x8000_FFFF_FFFF_FFFF, 0xFFFF_FFFF_0000_0001),
        ];
        let mut next = crate::test_rng::xorshift(0x2545_F491_4F6C_DD1D);
        for _ in 0..1_000_000 {
            let (a, d) = (next() | top, next() | top);
            cases.push((a, d));
            // Digit patterns that exercise the estimate's corrections and the add-back.
            let mask = next();
            cases.push((a | mask & 0xFFFF_0000_FFFF_0000, d | 0x0000_FFFF_0000_0000));
            cases.push((a, (d & 0xFFFF_FFFF_FFFF_0000) | 0xFFFF));
            cases.push((
                a & 0xFFFF_FFFF_0000_0000 | top,
                d & 0xFFFF_0000_0000_0000 | top,
            ));
        }
        for (a, d) in cases {
            let n = u128::from(a) << 64;
            let want = (n / u128::from(d), (n % u128::from(d)) as u64);
            assert_eq!(div_normalised(a, d), want, "{a:#x} / {d:#x}");
        }
    }

    fn to_f64(s: SoftFloat) -> f64 {
        s.m as f64 * 2f64.powi(s.e)
    }

    fn soft(bits: i64) -> SoftFloat {
        SoftFloat::from_bits(bits, 32).0
    }

    #[test]
    fn isqrt_exhaustive_small_and_large() {
        for n in 0u128..20_000 {
            let (y, r) = isqrt(n);
            assert!(y * y <= n && (y + 1) * (y + 1) > n && r == n - y * y, "{n}");
            let yr = isqrt_round(n);
            let fr = (n as f64).sqrt().round() as u128;
            assert_eq!(yr, fr, "{n}");
        }
        for &n in &[
            u128::MAX,
            u128::MAX - 1,
            1 << 126,
            (1 << 126) - 1,
            12_345_678_901_234_567_890_123,
        ] {
            let (y, r) = isqrt(n);
            assert!(y * y <= n && r == n - y * y);
            assert!((y + 1).checked_mul(y + 1).is_none_or(|s| s > n));
        }
    }

    /// The plain digit-by-digit cube root (a 128-bit multiply per step), as `icbrt` was.
    fn icbrt_reference(n: u128) -> (u128, u128) {
        let mut x = n;
        let mut y: u128 = 0;
        let mut s: i32 = 126;
        while s >= 0 {
            y <<= 1;
            let b = 3 * y * (y + 1) + 1;
            if (x >> s) >= b {
                x -= b << s;
                y += 1;
            }
            s -= 3;
        }
        (y, x)
    }

    #[test]
    fn icbrt_is_the_reference_everywhere() {
        let mut next = crate::test_rng::xorshift(0x853C_49E6_748F_EA9B);
        for i in 0..300_000u32 {
            let n = (u128::from(next()) << 64 | u128::from(next())) >> (i % 128);
            for n in [n, n.saturating_add(1), n.saturating_sub(1)] {
                assert_eq!(icbrt(n), icbrt_reference(n), "{n}");
            }
        }
    }

    #[test]
    fn icbrt_exhaustive_small_and_large() {
        for n in 0u128..50_000 {
            let (y, r) = icbrt(n);
            assert!(
                y * y * y <= n && (y + 1).pow(3) > n && r == n - y * y * y,
                "{n}"
            );
            let yr = icbrt_round(n);
            let fr = (n as f64).cbrt().round() as u128;
            assert_eq!(yr, fr, "{n}");
        }
        for &n in &[
            u128::MAX,
            1 << 117,
            (1 << 117) - 1,
            8_000_000_000_000_000_000_000_000_000u128,
        ] {
            let (y, r) = icbrt(n);
            assert!(y.pow(3) <= n && r == n - y.pow(3));
            assert!((y + 1).checked_pow(3).is_none_or(|c| c > n));
        }
        // Perfect cubes and their neighbours.
        for y in [1u128, 2, 1000, 1 << 20, (1 << 42) + 12345] {
            assert_eq!(icbrt(y.pow(3)).0, y);
            assert_eq!(icbrt(y.pow(3) - 1).0, y - 1);
        }
    }

    #[test]
    fn soft_float_arithmetic_matches_f64() {
        let a = soft(3 << 32); // 3
        let b = soft(7 << 31); // 3.5
        assert!((to_f64(a.mul(b).unwrap()) - 10.5).abs() < 1e-15);
        assert!((to_f64(a.div(b).unwrap()) - 3.0 / 3.5).abs() < 1e-15);
        assert!((to_f64(a.add(b).unwrap()) - 6.5).abs() < 1e-15);
        assert!((to_f64(b.saturating_sub(a)) - 0.5).abs() < 1e-15);
        assert_eq!(a.saturating_sub(b), SoftFloat::ZERO);
        assert!((to_f64(PI) - core::f64::consts::PI).abs() < 1e-15);
        assert!((to_f64(FRAC_PI_4) - core::f64::consts::FRAC_PI_4).abs() < 1e-15);
        assert!((to_f64(TAU) - core::f64::consts::TAU).abs() < 1e-15);
        assert_eq!(a.to_i64(32, false), Some(3 << 32));
        assert_eq!(a.to_i64(32, true), Some(-(3 << 32)));
        assert_eq!(soft(1).to_i64(0, false), Some(0));
        assert_eq!(soft(1 << 31).to_i64(0, false), Some(1)); // ½ rounds up
        assert_eq!(SoftFloat::from_u64(1 << 40).to_i64(30, false), None);
        assert_eq!(a.recip().unwrap().mul_i64(3 << 32), Some(1 << 32));
        assert_eq!(a.mul_i64(-5), Some(-15));
        assert_eq!(SoftFloat::ONE.mul_i64(i64::MIN), Some(i64::MIN));
        assert_eq!(a.mul_i64(i64::MAX), None);
        assert_eq!(SoftFloat::ZERO.div(a), Some(SoftFloat::ZERO));
        assert_eq!(a.div(SoftFloat::ZERO), None);
        assert!(SoftFloat::ZERO.lt(a) && !a.lt(a) && a.lt(b));
        // Rounding carry: all-ones rounds up to the next power of two.
        let c = SoftFloat::from_u128(u128::MAX, 0).unwrap();
        assert!((to_f64(c) - 2f64.powi(128)).abs() < 1.0);
    }
}
