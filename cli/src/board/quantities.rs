//! Command-line quantities of the board commands, converted to the protocol's integer units
//! and checked against the protocol's ranges before anything is sent.

use std::time::Duration;

use client::protocol::{
    CLUTCH_MAX_UM, CLUTCH_MIN_UM, CLUTCH_TOLERANCE_MAX_UM, CURRENT_LIMIT_MAX_MA,
    IMPEDANCE_DAMPING_MAX_UNMS_PER_RAD, IMPEDANCE_STIFFNESS_MIN_MNM_PER_RAD,
    IMPEDANCE_TORQUE_MAX_UNM, MOTOR_TORQUE_LIMIT_MAX_UNM, MOVE_DURATION_MAX_MS,
    MOVE_DURATION_MIN_MS, SINE_AMPLITUDE_MAX_URAD, SINE_FREQUENCY_MAX_MHZ, SINE_FREQUENCY_MIN_MHZ,
    TARGET_MAX_URAD, TELEMETRY_RATE_MAX_HZ, TELEMETRY_RATE_MIN_HZ,
};

use crate::error::{CliError, CliResult};
use crate::format::trim;
use crate::units::{self, Decimal, Kind};

/// `v` in units of 10^-`decimals` as a decimal string: `(500_000, 6)` → `0.5`.
pub fn show(v: i64, decimals: i32) -> String {
    trim(v as f64 / 10f64.powi(decimals))
}

/// Parses `s` as a `kind` quantity and returns round(value · 10^`e`) within `lo..=hi`
/// (integers in 10^-`e` of the kind's unit). Errors name `arg`.
fn scaled(arg: &str, s: &str, kind: Kind, e: i32, lo: i64, hi: i64) -> CliResult<i64> {
    let q = units::parse(s, kind).map_err(|r| CliError::usage(arg, r))?;
    let unit = kind.model_unit();
    let range = || {
        format!(
            "{} {unit} is out of range [{}, {}] {unit}",
            q.value,
            show(lo, e),
            show(hi, e)
        )
    };
    let v = q
        .value
        .round_scaled(e)
        .ok_or_else(|| CliError::usage(arg, range()))?;
    if (lo..=hi).contains(&v) {
        Ok(v)
    } else {
        Err(CliError::usage(arg, range()))
    }
}

fn to_u32(v: i64) -> u32 {
    u32::try_from(v).unwrap_or(u32::MAX)
}

fn to_i32(v: i64) -> i32 {
    i32::try_from(v).unwrap_or(if v < 0 { i32::MIN } else { i32::MAX })
}

/// A link angle in µrad, |·| ≤ 2.54 rad (what the gear pot measures,
/// [`TARGET_MAX_URAD`]). Accepts rad, mrad, urad, and deg (or °).
pub fn angle_urad(arg: &str, s: &str) -> CliResult<i32> {
    angle(arg, s, i64::from(TARGET_MAX_URAD), true)
}

/// A sine amplitude in µrad, 0–1 rad.
pub fn amplitude_urad(arg: &str, s: &str) -> CliResult<u32> {
    angle(arg, s, i64::from(SINE_AMPLITUDE_MAX_URAD), false).map(|v| v.unsigned_abs())
}

fn angle(arg: &str, s: &str, max: i64, signed: bool) -> CliResult<i32> {
    let lo = if signed { -max } else { 0 };
    let t = s.trim();
    let deg = t
        .strip_suffix("deg")
        .or_else(|| t.strip_suffix('°'))
        .map(str::trim);
    let v = match deg {
        Some(num) => {
            let d = Decimal::parse(num).ok_or_else(|| {
                CliError::usage(arg, format!("'{s}' is not a number with a unit"))
            })?;
            let deg: f64 = d.to_string().parse().unwrap_or(f64::NAN);
            let urad = (deg.to_radians() * 1e6).round();
            let max_deg = (max as f64 / 1e6).to_degrees();
            if !(lo as f64..=max as f64).contains(&urad) {
                return Err(CliError::usage(
                    arg,
                    format!(
                        "{d} deg is out of range [{}, {}] deg",
                        trim(if signed { -max_deg } else { 0.0 }),
                        trim(max_deg)
                    ),
                ));
            }
            urad as i64
        }
        None => scaled(arg, s, Kind::Angle, 6, lo, max)?,
    };
    Ok(to_i32(v))
}

/// A move duration in ms, 1 ms – 60 s.
pub fn move_duration_ms(arg: &str, s: &str) -> CliResult<u32> {
    scaled(
        arg,
        s,
        Kind::Time,
        3,
        i64::from(MOVE_DURATION_MIN_MS),
        i64::from(MOVE_DURATION_MAX_MS),
    )
    .map(to_u32)
}

/// A duration of up to `max_s` seconds (at least 1 ms); a bare number is in seconds.
pub fn duration(arg: &str, s: &str, max_s: u32) -> CliResult<Duration> {
    let with_unit = if Decimal::parse(s.trim()).is_some() {
        format!("{}s", s.trim())
    } else {
        s.to_string()
    };
    scaled(arg, &with_unit, Kind::Time, 3, 1, i64::from(max_s) * 1000)
        .map(|ms| Duration::from_millis(ms.unsigned_abs()))
}

/// A sine frequency in mHz, 0.01–20 Hz.
pub fn frequency_mhz(arg: &str, s: &str) -> CliResult<u32> {
    scaled(
        arg,
        s,
        Kind::Frequency,
        3,
        i64::from(SINE_FREQUENCY_MIN_MHZ),
        i64::from(SINE_FREQUENCY_MAX_MHZ),
    )
    .map(to_u32)
}

/// A clutch length in µm, 1–8 mm.
pub fn length_um(arg: &str, s: &str) -> CliResult<u32> {
    // The model's length unit is mm: 10^3 µm.
    scaled(
        arg,
        s,
        Kind::Length,
        3,
        i64::from(CLUTCH_MIN_UM),
        i64::from(CLUTCH_MAX_UM),
    )
    .map(to_u32)
}

/// A clutch tolerance in µm, 0–5 mm.
pub fn tolerance_um(arg: &str, s: &str) -> CliResult<u16> {
    scaled(
        arg,
        s,
        Kind::Length,
        3,
        0,
        i64::from(CLUTCH_TOLERANCE_MAX_UM),
    )
    .map(|v| u16::try_from(v).unwrap_or(u16::MAX))
}

/// A joint stiffness in mN·m/rad, > 0.
pub fn stiffness_mnm_per_rad(arg: &str, s: &str) -> CliResult<u32> {
    scaled(arg, s, Kind::Stiffness, 3, 1, i64::from(u32::MAX)).map(to_u32)
}

/// A virtual stiffness in mN·m/rad, ≥ 0.1 N·m/rad (the upper bound, the joint's k at the
/// clutch setting, is the board's check).
pub fn virtual_stiffness_mnm_per_rad(arg: &str, s: &str) -> CliResult<u32> {
    let lo = i64::from(IMPEDANCE_STIFFNESS_MIN_MNM_PER_RAD);
    scaled(arg, s, Kind::Stiffness, 3, lo, i64::from(u32::MAX)).map(to_u32)
}

/// A virtual damping in µN·m·s/rad, 0–100 N·m·s/rad.
pub fn damping_unms_per_rad(arg: &str, s: &str) -> CliResult<u32> {
    let hi = i64::from(IMPEDANCE_DAMPING_MAX_UNMS_PER_RAD);
    scaled(arg, s, Kind::Damping, 6, 0, hi).map(to_u32)
}

/// A feed-forward torque in µN·m, |·| ≤ 100 N·m.
pub fn feed_forward_unm(arg: &str, s: &str) -> CliResult<i32> {
    let max = i64::from(IMPEDANCE_TORQUE_MAX_UNM);
    scaled(arg, s, Kind::Torque, 6, -max, max).map(to_i32)
}

/// A current limit in mA, 1 mA – 10 A.
pub fn current_ma(arg: &str, s: &str) -> CliResult<u16> {
    scaled(arg, s, Kind::Current, 3, 1, i64::from(CURRENT_LIMIT_MAX_MA))
        .map(|v| u16::try_from(v).unwrap_or(u16::MAX))
}

/// A motor torque limit in µN·m, 1 µN·m – 100 N·m.
pub fn torque_unm(arg: &str, s: &str) -> CliResult<u32> {
    scaled(
        arg,
        s,
        Kind::Torque,
        6,
        1,
        i64::from(MOTOR_TORQUE_LIMIT_MAX_UNM),
    )
    .map(to_u32)
}

/// Largest |constant load| on the link, mN·m: the emulated board's (`--load-mnm`,
/// |N| ≤ 2000) and `vsa simulate`'s. Beyond what the motor (1.5 N·m stall) can hold.
pub const LOAD_MAX_MNM: i32 = 2_000;

/// The emulated board's link load in mN·m, within ±[`LOAD_MAX_MNM`].
pub fn torque_mnm(arg: &str, s: &str) -> CliResult<i32> {
    let max = i64::from(LOAD_MAX_MNM);
    scaled(arg, s, Kind::Torque, 3, -max, max).map(to_i32)
}

/// A fraction in ‰, (0, 1]: `0.85`, `85%` or `850‰`.
pub fn permille(arg: &str, s: &str) -> CliResult<u16> {
    let t = s.trim();
    let (num, e) = if let Some(n) = t.strip_suffix('%') {
        (n, 1)
    } else if let Some(n) = t.strip_suffix('‰') {
        (n, 0)
    } else {
        (t, 3)
    };
    let d = Decimal::parse(num.trim()).ok_or_else(|| {
        CliError::usage(
            arg,
            format!("'{s}' is not a fraction (e.g. 0.85, 85% or 850‰)"),
        )
    })?;
    match d.round_scaled(e) {
        Some(v @ 1..=1000) => Ok(u16::try_from(v).unwrap_or(1000)),
        _ => Err(CliError::usage(
            arg,
            format!("'{s}' is out of range (0, 1] (at least 0.001)"),
        )),
    }
}

/// A telemetry rate in Hz, 10–500 (or 0 = off when `allow_off`); a bare number is in Hz.
pub fn rate_hz(arg: &str, s: &str, allow_off: bool) -> CliResult<u16> {
    let t = s.trim();
    if allow_off && (t == "off" || t == "0" || t == "0Hz") {
        return Ok(0);
    }
    let with_unit = if Decimal::parse(t).is_some() {
        format!("{t}Hz")
    } else {
        t.to_string()
    };
    let v = scaled(arg, &with_unit, Kind::Frequency, 0, 0, i64::from(u16::MAX))?;
    let lo = i64::from(TELEMETRY_RATE_MIN_HZ);
    let hi = i64::from(TELEMETRY_RATE_MAX_HZ);
    if (lo..=hi).contains(&v) {
        Ok(u16::try_from(v).unwrap_or(0))
    } else {
        Err(CliError::usage(
            arg,
            format!(
                "{v} Hz is out of range [{lo}, {hi}] Hz{}",
                if allow_off { " (or off)" } else { "" }
            ),
        ))
    }
}

/// A controller gain in 10⁻³ of its unit (the wire format), from a plain number in the
/// unit, at most `max`.
pub fn gain(arg: &str, s: &str, max: u64) -> CliResult<u64> {
    let d = Decimal::parse(s.trim())
        .ok_or_else(|| CliError::usage(arg, format!("'{s}' is not a number")))?;
    let v = d.round_scaled(3);
    match v.and_then(|v| u64::try_from(v).ok()) {
        Some(v) if v <= max => Ok(v),
        _ => Err(CliError::usage(
            arg,
            format!("{d} is out of range [0, {}]", show(max as i64, 3)),
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn reason(r: CliResult<impl std::fmt::Debug>) -> String {
        r.unwrap_err().to_string()
    }

    #[test]
    fn angles() {
        assert_eq!(angle_urad("x", "0.5rad").unwrap(), 500_000);
        assert_eq!(angle_urad("x", "-0.5 rad").unwrap(), -500_000);
        assert_eq!(angle_urad("x", "90deg").unwrap(), 1_570_796);
        assert_eq!(angle_urad("x", "-30°").unwrap(), -523_599);
        assert_eq!(angle_urad("x", "2.54rad").unwrap(), 2_540_000);
        assert_eq!(
            reason(angle_urad("move", "2.540001rad")),
            "move: 2.540001 rad is out of range [-2.54, 2.54] rad"
        );
        assert!(reason(angle_urad("x", "400deg")).contains("out of range"));
        assert!(reason(angle_urad("x", "0.5")).contains("no unit"));
        assert_eq!(amplitude_urad("x", "0.2rad").unwrap(), 200_000);
        assert!(amplitude_urad("x", "-0.2rad").is_err());
        assert!(amplitude_urad("x", "1.5rad").is_err());
    }

    #[test]
    fn times_rates_and_more() {
        assert_eq!(move_duration_ms("x", "300ms").unwrap(), 300);
        assert_eq!(move_duration_ms("x", "2s").unwrap(), 2000);
        assert!(move_duration_ms("x", "0ms").is_err());
        assert!(move_duration_ms("x", "61s").is_err());
        assert_eq!(duration("x", "2", 3600).unwrap(), Duration::from_secs(2));
        assert_eq!(
            duration("x", "250ms", 3600).unwrap(),
            Duration::from_millis(250)
        );
        assert!(duration("x", "0", 3600).is_err());
        assert_eq!(frequency_mhz("x", "1Hz").unwrap(), 1000);
        assert!(frequency_mhz("x", "25Hz").is_err());
        assert_eq!(length_um("x", "3mm").unwrap(), 3000);
        assert_eq!(
            reason(length_um("clutch", "9mm")),
            "clutch: 9 mm is out of range [1, 8] mm"
        );
        assert_eq!(stiffness_mnm_per_rad("x", "250Nm/rad").unwrap(), 250_000);
        assert!(stiffness_mnm_per_rad("x", "0Nm/rad").is_err());
        assert_eq!(current_ma("x", "1.2A").unwrap(), 1200);
        assert_eq!(torque_unm("x", "1.5Nm").unwrap(), 1_500_000);
        assert_eq!(permille("x", "0.85").unwrap(), 850);
        assert_eq!(permille("x", "85%").unwrap(), 850);
        assert_eq!(permille("x", "850‰").unwrap(), 850);
        assert!(permille("x", "1.5").is_err());
        assert!(permille("x", "0").is_err());
        assert_eq!(rate_hz("x", "500", false).unwrap(), 500);
        assert_eq!(rate_hz("x", "100Hz", true).unwrap(), 100);
        assert_eq!(rate_hz("x", "off", true).unwrap(), 0);
        assert!(rate_hz("x", "0", false).is_err());
        assert!(rate_hz("x", "5", true).is_err());
        assert_eq!(gain("x", "800", 1_000_000_000).unwrap(), 800_000);
        assert!(gain("x", "-1", 1_000_000_000).is_err());
        assert!(gain("x", "2e6", 1_000_000_000).is_err());
    }
}
