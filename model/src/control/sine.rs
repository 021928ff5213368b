//! Integer sine and cosine for the trajectory generator (`fixed` has none).
//!
//! A quarter-wave table of 257 entries of sin(x), x = (π/2)·i/256, i = 0..=256, in Q30
//! (2³⁰ = 1.0), built at compile time by a `const fn` from the Taylor series evaluated in
//! 128-bit integer arithmetic with 64 fractional bits (no floats anywhere), then linear
//! interpolation between entries. The phase is a `u32` turn: 2³² = one full turn (2π), so a
//! phase accumulator wraps naturally. Error of the interpolation ≤ (π/512)²/8 ≈ 4.7e-6
//! (checked against f64 in the tests), i.e. 5 000 LSB of Q30 but far below the 1.5e-5 rad
//! resolution of the Q16 signals that use it.
//!
//! Cost per call: a table read pair, one 32×32→64 multiply and a few shifts/adds.

/// Q30 one (sin(π/2)).
pub const SIN_ONE: i32 = 1 << 30;

const FRAC_BITS: u32 = 64;

/// π/2 in Q64 (rounded), from `fixed`'s 127-fractional-bit constant.
const HALF_PI_Q64: i128 = {
    let b = fixed::consts::FRAC_PI_2.to_bits(); // U1F127
    ((b >> 62) + 1) as i128 >> 1
};

/// sin(x) for x in [0, π/2], x and the result in Q64, by the Taylor series (|term| after
/// n = 13 is below 2⁻⁶⁴).
const fn sin_q64(x: i128) -> i128 {
    // x ≤ 1.58·2⁶⁴ < 2⁶⁵; products of two Q64 values < 2¹³⁰ would overflow, so multiply in
    // Q64 after a 32-bit pre-shift of each factor (keeps 32 fractional bits of each:
    // error ≈ 2⁻³¹ relative per step, far below the Q30 output).
    let x2 = (x >> 32) * (x >> 32); // Q64
    let mut term = x;
    let mut sum = x;
    let mut n: i128 = 1;
    while n < 14 {
        // term_{n} = −term_{n−1}·x²/((2n)(2n+1))
        term = -(((term >> 32) * (x2 >> 32)) / ((2 * n) * (2 * n + 1)));
        sum += term;
        n += 1;
    }
    sum
}

const fn build_table() -> [i32; 257] {
    let mut t = [0i32; 257];
    let mut i = 0;
    while i <= 256 {
        let x = HALF_PI_Q64 * i as i128 / 256;
        let s = sin_q64(x);
        // Q64 → Q30, rounded.
        let v = (s + (1i128 << (FRAC_BITS - 31))) >> (FRAC_BITS - 30);
        t[i] = if v > SIN_ONE as i128 {
            SIN_ONE
        } else {
            v as i32
        };
        i += 1;
    }
    t
}

/// sin over the first quarter wave, Q30.
static QUARTER: [i32; 257] = build_table();

/// sin(2π·phase/2³²) in Q30 (±2³⁰).
#[must_use]
pub fn sin_q30(phase: u32) -> i32 {
    let quadrant = phase >> 30;
    let within = phase & 0x3FFF_FFFF; // 30 bits within the quadrant
                                      // Mirror in the 2nd and 4th quadrants: sin(π − x) = sin(x).
    let idx_phase = if quadrant & 1 == 1 {
        0x4000_0000 - within
    } else {
        within
    };
    let idx = (idx_phase >> 22) as usize; // 0..=256
    let frac = i64::from(idx_phase & 0x3F_FFFF); // 22 bits
    let a = QUARTER.get(idx).copied().unwrap_or(SIN_ONE);
    let b = QUARTER.get(idx + 1).copied().unwrap_or(SIN_ONE);
    let v = i64::from(a) + ((i64::from(b - a) * frac) >> 22);
    let v = v as i32; // |v| ≤ 2³⁰
    if quadrant >= 2 {
        -v
    } else {
        v
    }
}

/// cos(2π·phase/2³²) in Q30.
#[must_use]
pub fn cos_q30(phase: u32) -> i32 {
    sin_q30(phase.wrapping_add(0x4000_0000))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table_endpoints() {
        assert_eq!(QUARTER[0], 0);
        assert_eq!(QUARTER[256], SIN_ONE);
        assert_eq!(sin_q30(0), 0);
        assert_eq!(sin_q30(1 << 30), SIN_ONE);
        assert_eq!(sin_q30(2 << 30), 0);
        assert_eq!(sin_q30(3 << 30), -SIN_ONE);
        assert_eq!(cos_q30(0), SIN_ONE);
    }

    #[test]
    fn matches_f64_everywhere() {
        let mut worst = 0.0f64;
        let mut phase: u32 = 0;
        for _ in 0..200_003 {
            let x = f64::from(phase) / 4_294_967_296.0 * core::f64::consts::TAU;
            let s = f64::from(sin_q30(phase)) / f64::from(SIN_ONE);
            let c = f64::from(cos_q30(phase)) / f64::from(SIN_ONE);
            worst = worst.max((s - x.sin()).abs()).max((c - x.cos()).abs());
            phase = phase.wrapping_add(21_474_943); // ~2⁻⁸ turn·1.28, coprime walk
        }
        assert!(worst < 5e-6, "worst error {worst}");
        // Table entries themselves are exact to Q30 rounding.
        for (i, &t) in QUARTER.iter().enumerate() {
            let want = (core::f64::consts::FRAC_PI_2 * i as f64 / 256.0).sin();
            assert!(
                (f64::from(t) / f64::from(SIN_ONE) - want).abs() < 2e-9,
                "{i}"
            );
        }
    }
}
