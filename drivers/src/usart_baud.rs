//! The STM32 USART's baud-rate divider (RM0390 §25.4.4, "Fractional baud rate generation"),
//! computed once when a rate is chosen, never per byte: which `BRR` (and oversampling)
//! makes a rate from the peripheral clock, and how far off it is.
//!
//! `USARTDIV = f_PCLK / (8 · (2 − OVER8) · baud)`. At 16× oversampling (OVER8 = 0) BRR
//! holds USARTDIV in 12.4 fixed point, i.e. `BRR = f_PCLK / baud`, at least 16; at 8×
//! (OVER8 = 1) the fraction has 3 bits (`BRR[3]` = 0): `D = f_PCLK · 2 / (16 · baud)` in
//! 12.3 fixed point, BRR = (D >> 3) << 4 | (D & 7), at least 8. 8× reaches twice the rate
//! but tolerates less clock error at the receiver (RM0390 §25.4.5: 3.75 % vs 3.43 % with
//! one sample per bit, both sides' errors together), so 16× is preferred on a tie.

/// Largest rate error accepted, ppm (2.5 %): with the other side's error (a USB adapter's
/// is typically < 0.5 %) it stays inside the receiver's 3.43–3.75 % tolerance.
pub const MAX_ERROR_PPM: u32 = 25_000;

/// A divider that makes a rate.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Divider {
    /// The BRR register's value (mantissa << 4 | fraction).
    pub brr: u16,
    /// 8× oversampling (CR1.OVER8).
    pub over8: bool,
    /// The rate it makes, bit/s (rounded down).
    pub actual_bps: u32,
    /// (actual − wanted) / wanted, ppm.
    pub error_ppm: i32,
}

/// Why no divider makes a rate.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum BaudError {
    /// 0 bit/s, or above f_PCLK / 8.
    OutOfRange,
    /// Below f_PCLK / (16 · 4096): the mantissa overflows.
    TooSlow,
    /// The closest divider is further than [`MAX_ERROR_PPM`] off (its error, ppm).
    Inexact(i32),
}

/// The divider of the USART clocked at `pclk_hz` that makes `baud` with the smallest
/// error: `D = f_PCLK / baud` rounded to nearest is USARTDIV in 1/16 steps at 16× and in
/// 1/8 steps at 8×, so both make the same rate `f_PCLK / D`; 16× is used whenever D ≥ 16,
/// 8× for 8 ≤ D < 16.
///
/// # Errors
/// [`BaudError`] when no divider makes it within [`MAX_ERROR_PPM`].
pub fn divider(pclk_hz: u32, baud: u32) -> Result<Divider, BaudError> {
    if baud == 0 {
        return Err(BaudError::OutOfRange);
    }
    let d = (u64::from(pclk_hz) + u64::from(baud) / 2) / u64::from(baud);
    let (brr, over8) = match d {
        0..=7 => return Err(BaudError::OutOfRange),
        8..=15 => (d >> 3 << 4 | (d & 7), true),
        _ => (d, false),
    };
    let brr = u16::try_from(brr).map_err(|_| BaudError::TooSlow)?;
    let actual = u64::from(pclk_hz) / d;
    // (f_PCLK/D − baud)/baud = (f_PCLK − baud·D)/(baud·D), exactly.
    let bd = i128::from(baud) * i128::from(d);
    let err = (i128::from(pclk_hz) - bd) * 1_000_000 / bd;
    let error_ppm = i32::try_from(err).unwrap_or(i32::MAX);
    if error_ppm.unsigned_abs() > MAX_ERROR_PPM {
        return Err(BaudError::Inexact(error_ppm));
    }
    Ok(Divider {
        brr,
        over8,
        actual_bps: u32::try_from(actual).unwrap_or(u32::MAX),
        error_ppm,
    })
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use std::println;

    /// The Nucleo's USART2 clock (PCLK1), Hz.
    const PCLK1_HZ: u32 = 45_000_000;

    /// f64 statement of the same rule: the closest whole D, at least 8.
    fn oracle(pclk: f64, baud: f64) -> (f64, f64) {
        let d = (pclk / baud).round().max(8.0);
        let actual = pclk / d;
        (d, (actual - baud) / baud * 1e6)
    }

    #[test]
    fn dividers_match_the_reference_manual_rule() {
        // Exact: 1 Mbit/s is D = 45, BRR 45 (mantissa 2, fraction 13) at 16×.
        let d = divider(PCLK1_HZ, 1_000_000).unwrap();
        assert_eq!(
            (d.brr, d.over8, d.actual_bps, d.error_ppm),
            (45, false, 1_000_000, 0)
        );
        // 4.5 Mbit/s: D = 10, 8× oversampling: mantissa 1, fraction 2.
        let d = divider(PCLK1_HZ, 4_500_000).unwrap();
        assert_eq!((d.brr, d.over8, d.error_ppm), (0x12, true, 0));
        assert_eq!(divider(PCLK1_HZ, 0), Err(BaudError::OutOfRange));
        assert_eq!(divider(PCLK1_HZ, 7_000_000), Err(BaudError::OutOfRange));
        assert_eq!(
            divider(PCLK1_HZ, 6_000_000),
            Err(BaudError::Inexact(-62_500))
        );
        assert_eq!(divider(PCLK1_HZ, 600), Err(BaudError::TooSlow));
        for baud in (1_000..6_000_000).step_by(997) {
            let (d, err) = oracle(f64::from(PCLK1_HZ), f64::from(baud));
            match divider(PCLK1_HZ, baud) {
                Ok(div) => {
                    assert!((f64::from(div.error_ppm) - err).abs() <= 1.5, "{baud}");
                    let mantissa = f64::from(div.brr >> 4);
                    let fraction = f64::from(div.brr & 0xF);
                    let usartdiv = if div.over8 {
                        assert_eq!(div.brr & 0x8, 0, "BRR[3] must be 0 at 8×");
                        mantissa + fraction / 8.0
                    } else {
                        mantissa + fraction / 16.0
                    };
                    let oversampling = if div.over8 { 8.0 } else { 16.0 };
                    assert_eq!(usartdiv * oversampling, d, "{baud}");
                }
                Err(BaudError::Inexact(e)) => {
                    assert!(err.abs() > f64::from(MAX_ERROR_PPM) - 1.0, "{baud}: {e}");
                }
                Err(e) => assert!(
                    d > 65_535.0 || f64::from(PCLK1_HZ) / f64::from(baud) < 7.5,
                    "{baud}: {e:?}"
                ),
            }
        }
    }

    /// The Dynamixel rates on the Nucleo (`cargo test -p vsa-drivers usart -- --nocapture`
    /// prints the table docs/dynamixel.md quotes).
    #[test]
    fn dynamixel_rates_on_the_nucleo() {
        let ax = (1..=254u32).map(|v| 2_000_000 / (v + 1));
        let x = [
            9_600, 57_600, 115_200, 1_000_000, 2_000_000, 3_000_000, 4_000_000, 4_500_000,
        ];
        let mut refused = 0;
        // The AX rates below 400 000 bit/s: the largest |error| and the smallest BRR.
        let (mut worst_ppm, mut least_brr) = (0, u16::MAX);
        println!("baud, BRR, OVER8, error ppm (PCLK1 = {PCLK1_HZ} Hz)");
        for baud in ax.chain(x) {
            match divider(PCLK1_HZ, baud) {
                Ok(d) if baud < 400_000 && !x.contains(&baud) => {
                    worst_ppm = worst_ppm.max(d.error_ppm.unsigned_abs());
                    least_brr = least_brr.min(d.brr);
                }
                Ok(d) => println!("{baud}, {}, {}, {}", d.brr, d.over8, d.error_ppm),
                Err(e) => {
                    refused += 1;
                    println!("{baud}: {e:?}");
                }
            }
        }
        println!("AX rates below 400 000: |error| ≤ {worst_ppm} ppm, BRR ≥ {least_brr}");
        // Every AX-12A rate and every X-series rate is made within 2.5 %.
        assert_eq!(refused, 0);
        assert_eq!(divider(PCLK1_HZ, 2_000_000).unwrap().error_ppm, -21_739);
        assert_eq!(divider(PCLK1_HZ, 4_000_000).unwrap().error_ppm, 22_727);
    }
}
