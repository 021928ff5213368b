//! The actuator's sensors as the controller, the supervisor, the simulated plant and the
//! tools read them (docs/design.md §3): their resolutions, the count-to-radian constants
//! derived from them, and the wrap of the link encoder.
//!
//! * link encoder: 12-bit magnetic, [`ENCODER_COUNTS`] per turn, wraps;
//! * gear potentiometer: [`POT_COUNTS`] over [`POT_SPAN_DEG`]°;
//! * motor current: 12-bit ADC ([`ADC_COUNTS`]), [`ADC_MID`] at 0 A, [`ADC_COUNTS_PER_A`]
//!   counts per ampere (±2 A full scale);
//! * bridge supply: the same 12-bit ADC behind a divider, [`SUPPLY_MV_PER_COUNT`] mV of
//!   supply per count (0…20.475 V).
//!
//! The fixed-point angles (`*_Q32`, I32F32 bits) are computed here at compile time from
//! the counts and `fixed`'s 2π, each rounded to nearest once.

/// Link encoder counts per turn (12-bit magnetic encoder; readings 0..=4095 wrap).
pub const ENCODER_COUNTS: u16 = 4096;
/// Gear potentiometer counts over its span (readings 0..=1023).
pub const POT_COUNTS: u16 = 1024;
/// Gear potentiometer electrical span, degrees.
pub const POT_SPAN_DEG: u16 = 300;
/// Current ADC full scale: 12 bit (readings 0..=4095).
pub const ADC_COUNTS: u16 = 4096;
/// Current ADC reading at zero current (mid-scale).
pub const ADC_MID: u16 = ADC_COUNTS / 2;
/// Current ADC counts per ampere (±2 A over the full scale).
pub const ADC_COUNTS_PER_A: u16 = 1024;
/// Supply sense, mV of bridge supply per ADC count: a 1 : 6.2 divider into the 3.3 V,
/// 12-bit ADC (docs/design.md §3). 12 V reads 2 400 counts.
pub const SUPPLY_MV_PER_COUNT: u16 = 5;

/// 2π as U67F64 bits (`fixed::consts::TAU`, U3F125, rounded to 64 fractional bits).
const TAU_Q64: u128 = (fixed::consts::TAU.to_bits() + (1 << 60)) >> 61;

/// `num/den` of a turn, in rad, as fixed-point bits with `frac` fractional bits, rounded
/// to nearest. For compile-time constants (`num·2^frac` must stay below 2⁶⁰).
#[must_use]
pub const fn turn_fraction_bits(num: u64, den: u64, frac: u32) -> i64 {
    let x = (TAU_Q64 * num as u128) << frac;
    let d = (den as u128) << 64;
    ((x + d / 2) / d) as i64
}

/// One link-encoder count, 2π/4096 rad, I32F32 bits.
pub const ENCODER_COUNT_Q32: i64 = turn_fraction_bits(1, ENCODER_COUNTS as u64, 32);
/// Half a link-encoder count, π/4096 rad, I32F32 bits (rounded on its own, not
/// `ENCODER_COUNT_Q32 / 2`).
pub const ENCODER_HALF_COUNT_Q32: i64 = turn_fraction_bits(1, 2 * ENCODER_COUNTS as u64, 32);
/// One potentiometer count, 300°/1024 = 5π/(3·1024) rad, I32F32 bits.
pub const POT_COUNT_Q32: i64 = turn_fraction_bits(POT_SPAN_DEG as u64, 360 * POT_COUNTS as u64, 32);

/// Signed change of a link-encoder reading from `prev` to `now`, counts, the shorter way
/// round the turn: in [−2048, 2048). With `prev` the calibrated zero it is the reading
/// relative to that zero.
#[must_use]
pub const fn encoder_delta(now: u16, prev: u16) -> i32 {
    let counts = ENCODER_COUNTS as i32;
    let d = (now as i32 - prev as i32) & (counts - 1);
    if d >= counts / 2 {
        d - counts
    } else {
        d
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn q32(rad: f64) -> i64 {
        (rad * 4_294_967_296.0).round() as i64
    }

    #[test]
    fn angles_match_f64() {
        let tau = core::f64::consts::TAU;
        assert_eq!(ENCODER_COUNT_Q32, q32(tau / 4096.0));
        assert_eq!(ENCODER_HALF_COUNT_Q32, q32(tau / 8192.0));
        assert_eq!(POT_COUNT_Q32, q32(300f64.to_radians() / 1024.0));
        // The values the code carried as literals before they were computed here.
        assert_eq!(
            (ENCODER_COUNT_Q32, ENCODER_HALF_COUNT_Q32, POT_COUNT_Q32),
            (6_588_397, 3_294_199, 21_961_324)
        );
        assert_eq!(
            turn_fraction_bits(1000, 4096, 16),
            (tau * 1000.0 / 4096.0 * 65_536.0).round() as i64
        );
    }

    #[test]
    fn encoder_delta_takes_the_short_way() {
        assert_eq!(encoder_delta(5, 4090), 11);
        assert_eq!(encoder_delta(4090, 5), -11);
        assert_eq!(encoder_delta(2048, 0), -2048);
        assert_eq!(encoder_delta(2047, 0), 2047);
        assert_eq!(encoder_delta(7, 7), 0);
        // Bits above the 12th are ignored.
        assert_eq!(encoder_delta(4096 + 3, 0), 3);
    }
}
