//! Unit-aware parsing of command-line quantities (`0.5mm`, `200GPa`, `300mNm`, `500Nm/rad`).
//!
//! A value is a decimal number (sign, digits, optional fraction, optional exponent) followed
//! by a unit, with optional spaces between. The number is kept as an exact decimal
//! (significand × 10^exponent) and converted once, with integer arithmetic, to the model's
//! fixed-point format in the model's unit, rounded to the nearest LSB: `7.8mm` gives the same
//! bits as `I32F32::lit("7.8")`. Every unit here is a power of ten of the model's unit.
//!
//! Bare numbers are rejected where a unit is required; the error lists the accepted units.

use std::fmt;

use fixed::types::{I32F32, I64F64};
#[cfg(test)]
use model::{Length, Stress};
use model::{Ratio, Stiffness, Torque};

/// Which physical quantity a value stands for; each has its accepted units.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// A length, model unit mm.
    Length,
    /// A stress or modulus, model unit MPa.
    Pressure,
    /// A torque, model unit N·m.
    Torque,
    /// A joint stiffness, model unit N·m/rad.
    Stiffness,
    /// An angle, unit rad (degrees are not a power of ten of it: see `board::args`).
    Angle,
    /// A duration, unit s.
    Time,
    /// A frequency, unit Hz.
    Frequency,
    /// A current, unit A.
    Current,
    /// A mass, unit g.
    Mass,
    /// A volume, unit mm³.
    Volume,
    /// A moment of inertia, unit kg·mm² (the model's [`model::Inertia`]).
    Inertia,
    /// A rotary damping, unit N·m·s/rad.
    Damping,
}

/// Torque unit spellings and their power of ten relative to N·m.
const TORQUE_UNITS: &[(&str, i32)] = &[
    ("Nm", 0),
    ("N*m", 0),
    ("N·m", 0),
    ("N.m", 0),
    ("mNm", -3),
    ("mN*m", -3),
    ("mN·m", -3),
    ("mN.m", -3),
    ("Nmm", -3),
    ("N*mm", -3),
    ("N·mm", -3),
    ("kNm", 3),
    ("kN*m", 3),
    ("kN·m", 3),
];

impl Kind {
    /// The accepted unit spellings and their power of ten relative to the model's unit.
    fn units(self) -> Vec<(String, i32)> {
        let own = |t: &[(&str, i32)]| t.iter().map(|&(u, e)| (u.to_string(), e)).collect();
        match self {
            Kind::Length => own(&[
                ("mm", 0),
                ("m", 3),
                ("cm", 1),
                ("um", -3),
                ("µm", -3),
                ("μm", -3),
            ]),
            Kind::Pressure => own(&[("Pa", -6), ("kPa", -3), ("MPa", 0), ("GPa", 3)]),
            Kind::Torque => own(TORQUE_UNITS),
            Kind::Stiffness => TORQUE_UNITS
                .iter()
                .map(|&(u, e)| (format!("{u}/rad"), e))
                .collect(),
            Kind::Angle => own(&[
                ("rad", 0),
                ("mrad", -3),
                ("urad", -6),
                ("µrad", -6),
                ("μrad", -6),
            ]),
            Kind::Time => own(&[("s", 0), ("ms", -3), ("us", -6), ("µs", -6)]),
            Kind::Frequency => own(&[("Hz", 0), ("mHz", -3), ("kHz", 3)]),
            Kind::Current => own(&[("A", 0), ("mA", -3)]),
            Kind::Mass => own(&[("g", 0), ("mg", -3), ("kg", 3)]),
            Kind::Volume => own(&[("mm3", 0), ("mm³", 0), ("cm3", 3), ("cm³", 3)]),
            Kind::Inertia => own(&[
                ("kgm2", 6),
                ("kg*m2", 6),
                ("kg·m²", 6),
                ("kg.m2", 6),
                ("gcm2", -1),
                ("g*cm2", -1),
                ("kgmm2", 0),
                ("kg*mm2", 0),
            ]),
            Kind::Damping => own(&[
                ("Nms/rad", 0),
                ("N*m*s/rad", 0),
                ("N·m·s/rad", 0),
                ("N.m.s/rad", 0),
                ("mNms/rad", -3),
                ("mN*m*s/rad", -3),
                ("mN·m·s/rad", -3),
            ]),
        }
    }

    /// The model's unit, as printed.
    pub fn model_unit(self) -> &'static str {
        match self {
            Kind::Length => "mm",
            Kind::Pressure => "MPa",
            Kind::Torque => "N·m",
            Kind::Stiffness => "N·m/rad",
            Kind::Angle => "rad",
            Kind::Time => "s",
            Kind::Frequency => "Hz",
            Kind::Current => "A",
            Kind::Mass => "g",
            Kind::Volume => "mm³",
            Kind::Inertia => "kg·mm²",
            Kind::Damping => "N·m·s/rad",
        }
    }

    /// A short list of accepted units for error messages.
    fn accepted(self) -> &'static str {
        match self {
            Kind::Length => "mm, m, cm, um",
            Kind::Pressure => "Pa, kPa, MPa, GPa",
            Kind::Torque => "Nm (or N*m, N·m), mNm, Nmm, kNm",
            Kind::Stiffness => "Nm/rad (or N*m/rad, N·m/rad), mNm/rad, kNm/rad",
            Kind::Angle => "rad, mrad, urad, deg",
            Kind::Time => "s, ms, us",
            Kind::Frequency => "Hz, mHz, kHz",
            Kind::Current => "A, mA",
            Kind::Mass => "g, mg, kg",
            Kind::Volume => "mm3, cm3",
            Kind::Inertia => "kgm2 (or kg*m2, kg·m²), gcm2, kgmm2",
            Kind::Damping => "Nms/rad (or N*m*s/rad, N·m·s/rad), mNms/rad",
        }
    }
}

/// An exact decimal number, `sign · digits · 10^exp`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Decimal {
    /// `true` for a negative number (never for zero).
    pub negative: bool,
    /// The significand.
    pub digits: u128,
    /// The power of ten.
    pub exp: i32,
}

/// Exponents beyond this are clamped: the value is then far outside every format anyway.
const EXP_LIMIT: i32 = 10_000;
/// Significant digits kept when converting to fixed point (more than any format resolves).
const MAX_SIG: u128 = 1_000_000_000_000_000_000; // 10^18

impl Decimal {
    /// Zero.
    pub const ZERO: Decimal = Decimal {
        negative: false,
        digits: 0,
        exp: 0,
    };

    /// Parses a plain decimal number (`-1.5e-3`, `.5`, `2.`); `None` if it is not one.
    pub fn parse(s: &str) -> Option<Decimal> {
        let (d, rest) = Self::parse_prefix(s)?;
        rest.is_empty().then_some(d)
    }

    /// Parses the longest decimal number at the start of `s`; returns it and the rest.
    fn parse_prefix(s: &str) -> Option<(Decimal, &str)> {
        let b = s.as_bytes();
        let mut i = 0;
        let mut negative = false;
        if i < b.len() && (b[i] == b'+' || b[i] == b'-') {
            negative = b[i] == b'-';
            i += 1;
        }
        let mut digits: u128 = 0;
        let mut exp: i64 = 0;
        let mut any = false;
        let mut point = false;
        while i < b.len() {
            match b[i] {
                c @ b'0'..=b'9' => {
                    any = true;
                    let v = u128::from(c - b'0');
                    match digits.checked_mul(10).and_then(|x| x.checked_add(v)) {
                        Some(x) if x < MAX_SIG * 1_000_000 => {
                            digits = x;
                            if point {
                                exp -= 1;
                            }
                        }
                        // Too many digits: drop the rest (they are far below any resolution).
                        _ => {
                            if !point {
                                exp += 1;
                            }
                        }
                    }
                }
                b'.' if !point => point = true,
                _ => break,
            }
            i += 1;
        }
        if !any {
            return None;
        }
        // Exponent: only if 'e'/'E' is followed by a (signed) digit, so units are not eaten.
        if i < b.len() && (b[i] == b'e' || b[i] == b'E') {
            let mut j = i + 1;
            let mut eneg = false;
            if j < b.len() && (b[j] == b'+' || b[j] == b'-') {
                eneg = b[j] == b'-';
                j += 1;
            }
            if j < b.len() && b[j].is_ascii_digit() {
                let mut e: i64 = 0;
                while j < b.len() && b[j].is_ascii_digit() {
                    e = (e * 10 + i64::from(b[j] - b'0')).min(i64::from(EXP_LIMIT) * 10);
                    j += 1;
                }
                exp += if eneg { -e } else { e };
                i = j;
            }
        }
        let exp = exp.clamp(-i64::from(EXP_LIMIT), i64::from(EXP_LIMIT)) as i32;
        let d = Decimal {
            negative: negative && digits != 0,
            digits,
            exp,
        };
        Some((d.normalized(), &s[i..]))
    }

    /// Trailing zeros moved into the exponent; zero as `0e0`.
    fn normalized(mut self) -> Decimal {
        if self.digits == 0 {
            return Decimal::ZERO;
        }
        while self.digits.is_multiple_of(10) {
            self.digits /= 10;
            self.exp += 1;
        }
        self
    }

    /// This number times 10^e.
    #[must_use]
    pub fn scaled(self, e: i32) -> Decimal {
        Decimal {
            exp: self.exp.saturating_add(e).clamp(-EXP_LIMIT, EXP_LIMIT),
            ..self
        }
    }

    /// `round(self · 10^e)` (half away from zero) as an integer, `None` if it does not
    /// fit an i64: `0.5` with `e = 6` is 500 000.
    pub fn round_scaled(self, e: i32) -> Option<i64> {
        let d = self.scaled(e);
        let m: u128 = if d.exp >= 0 {
            d.digits.checked_mul(10u128.checked_pow(d.exp as u32)?)?
        } else {
            match 10u128.checked_pow(d.exp.unsigned_abs()) {
                Some(p) => d.digits / p + u128::from(d.digits % p >= p.div_ceil(2)),
                None => 0, // below 10^-38: rounds to zero
            }
        };
        let m = i64::try_from(m).ok()?;
        Some(if d.negative { -m } else { m })
    }

    /// `true` if zero.
    pub fn is_zero(self) -> bool {
        self.digits == 0
    }

    /// `round(|self| · 2^frac)`, or `None` if it does not fit a u128.
    fn magnitude_bits(self, frac: u32) -> Option<u128> {
        let (mut d, mut e) = (self.digits, self.exp);
        // Keep at most 18 significant digits so that d·2^64 fits (rounding half up).
        while d >= MAX_SIG {
            d = d / 10 + u128::from(d % 10 >= 5);
            e += 1;
        }
        if d == 0 {
            return Some(0);
        }
        if e >= 0 {
            let p = 10u128.checked_pow(e as u32)?;
            let v = d.checked_mul(p)?;
            if v.leading_zeros() <= frac {
                return None;
            }
            Some(v << frac)
        } else {
            let Some(p) = 10u128.checked_pow(e.unsigned_abs()) else {
                return Some(0); // below 10^-20 of the unit: rounds to zero
            };
            Some(((d << frac) + p / 2) / p)
        }
    }

    /// Nearest I32F32, or `None` on overflow.
    pub fn to_i32f32(self) -> Option<I32F32> {
        let m = i64::try_from(self.magnitude_bits(32)?).ok()?;
        Some(I32F32::from_bits(if self.negative { -m } else { m }))
    }

    /// Nearest I32F32, saturating at the format's bounds (for values that are range-checked
    /// afterwards: an overflow is then reported as out of range).
    pub fn to_i32f32_saturating(self) -> I32F32 {
        self.to_i32f32().unwrap_or(if self.negative {
            I32F32::MIN
        } else {
            I32F32::MAX
        })
    }

    /// Nearest I64F64, or `None` on overflow.
    pub fn to_i64f64(self) -> Option<I64F64> {
        let m = i128::try_from(self.magnitude_bits(64)?).ok()?;
        Some(I64F64::from_bits(if self.negative { -m } else { m }))
    }

    /// `self + k·step` exactly, or `None` if the significand overflows.
    pub fn add_times(self, k: u32, step: Decimal) -> Option<Decimal> {
        let e = self.exp.min(step.exp);
        let a = i128::try_from(self.digits)
            .ok()?
            .checked_mul(10i128.checked_pow((self.exp - e) as u32)?)?;
        let b = i128::try_from(step.digits)
            .ok()?
            .checked_mul(10i128.checked_pow((step.exp - e) as u32)?)?
            .checked_mul(i128::from(k))?;
        let a = if self.negative { -a } else { a };
        let b = if step.negative { -b } else { b };
        let s = a.checked_add(b)?;
        Some(
            Decimal {
                negative: s < 0,
                digits: s.unsigned_abs(),
                exp: e,
            }
            .normalized(),
        )
    }

    /// Compares two decimals.
    pub fn cmp_value(self, o: Decimal) -> std::cmp::Ordering {
        let sign = |d: Decimal| {
            if d.digits == 0 {
                0
            } else if d.negative {
                -1
            } else {
                1
            }
        };
        let (sa, sb) = (sign(self), sign(o));
        if sa != sb || sa == 0 {
            return sa.cmp(&sb);
        }
        // Same sign, both non-zero: compare magnitudes via digit count + exponent.
        let mag = |d: Decimal| {
            let n = d.digits.to_string();
            (n.len() as i64 + i64::from(d.exp), n)
        };
        let ((ma, na), (mb, nb)) = (mag(self), mag(o));
        let ord = ma.cmp(&mb).then_with(|| {
            // Same order of magnitude: compare digit strings padded with zeros.
            let w = na.len().max(nb.len());
            format!("{na:0<w$}").cmp(&format!("{nb:0<w$}"))
        });
        if sa < 0 {
            ord.reverse()
        } else {
            ord
        }
    }
}

impl fmt::Display for Decimal {
    /// Plain decimal notation (`0.0005`, `80000`), scientific for extreme exponents.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.digits == 0 {
            return f.write_str("0");
        }
        let sign = if self.negative { "-" } else { "" };
        let digits = self.digits.to_string();
        let n = digits.len() as i32;
        // Position of the decimal point relative to the first digit.
        let point = n + self.exp;
        if self.exp >= 0 && point <= 15 {
            write!(f, "{sign}{digits}{}", "0".repeat(self.exp as usize))
        } else if self.exp < 0 && point > 0 {
            let (a, b) = digits.split_at(point as usize);
            write!(f, "{sign}{a}.{b}")
        } else if self.exp < 0 && point > -6 {
            write!(f, "{sign}0.{}{digits}", "0".repeat((-point) as usize))
        } else {
            let (a, b) = digits.split_at(1);
            let e = point - 1;
            if b.is_empty() {
                write!(f, "{sign}{a}e{e}")
            } else {
                write!(f, "{sign}{a}.{b}e{e}")
            }
        }
    }
}

/// A parsed quantity: its decimal value in the model's unit, and its kind.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Quantity {
    /// The value in the model's unit (mm, MPa, N·m, N·m/rad), exact.
    pub value: Decimal,
    /// What it measures.
    pub kind: Kind,
}

impl Quantity {
    /// The value in units of 10^`unit_exp` model units (`value_in(3)` of a pressure is in
    /// GPa, the model using MPa), for messages.
    pub fn value_in(self, unit_exp: i32) -> Decimal {
        self.value.scaled(-unit_exp)
    }

    /// As a model length (mm), `None` if not a length or on overflow.
    #[cfg(test)]
    pub fn length(self) -> Option<Length> {
        (self.kind == Kind::Length)
            .then(|| self.value.to_i32f32().map(Length::from_fixed))
            .flatten()
    }

    /// As a model stress (MPa), `None` if not a pressure or on overflow.
    #[cfg(test)]
    pub fn stress(self) -> Option<Stress> {
        (self.kind == Kind::Pressure)
            .then(|| self.value.to_i32f32().map(Stress::from_fixed))
            .flatten()
    }

    /// As a model torque (N·m), `None` if not a torque or on overflow.
    pub fn torque(self) -> Option<Torque> {
        (self.kind == Kind::Torque)
            .then(|| self.value.to_i32f32().map(Torque::from_fixed))
            .flatten()
    }

    /// As a model stiffness (N·m/rad), `None` if not a stiffness or on overflow.
    pub fn stiffness(self) -> Option<Stiffness> {
        (self.kind == Kind::Stiffness)
            .then(|| self.value.to_i64f64().map(Stiffness::from_fixed))
            .flatten()
    }
}

impl fmt::Display for Quantity {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} {}", self.value, self.kind.model_unit())
    }
}

/// Parses `s` as a quantity of `kind`; the error says why (for `--arg: <reason>`).
pub fn parse(s: &str, kind: Kind) -> Result<Quantity, String> {
    let t = s.trim();
    let Some((number, rest)) = Decimal::parse_prefix(t) else {
        return Err(format!(
            "'{s}' is not a number with a unit (accepted units: {})",
            kind.accepted()
        ));
    };
    let unit = rest.trim();
    if unit.is_empty() {
        return Err(format!(
            "'{s}' has no unit (accepted units: {})",
            kind.accepted()
        ));
    }
    let Some((_, e)) = kind.units().into_iter().find(|(u, _)| u == unit) else {
        return Err(format!(
            "unknown unit '{unit}' in '{s}' (accepted units: {})",
            kind.accepted()
        ));
    };
    Ok(Quantity {
        value: number.scaled(e),
        kind,
    })
}

/// Parses a list `1mm,2mm,3mm` or a range `START..END:STEP` (end included) of quantities
/// of `kind`, at most `max` of them (`noun` names them in messages).
pub fn parse_list(s: &str, kind: Kind, max: u32, noun: &str) -> Result<Vec<Decimal>, String> {
    let unit = kind.model_unit();
    let q = |t: &str| parse(t, kind);
    let decimals: Vec<Decimal> = if let Some((start, rest)) = s.split_once("..") {
        let Some((end, step)) = rest.split_once(':') else {
            return Err(format!(
                "'{s}' is not a range START..END:STEP (e.g. 1mm..5mm:1mm)"
            ));
        };
        let (a, b, st) = (q(start)?.value, q(end)?.value, q(step)?.value);
        if st.negative || st.is_zero() {
            return Err(format!("step {st} {unit} must be positive"));
        }
        if b.cmp_value(a).is_lt() {
            return Err(format!(
                "range end {b} {unit} is below its start {a} {unit}"
            ));
        }
        let mut v = Vec::new();
        for i in 0.. {
            let x = a
                .add_times(i, st)
                .ok_or_else(|| format!("'{s}' cannot be enumerated exactly"))?;
            if x.cmp_value(b).is_gt() {
                break;
            }
            if i >= max {
                return Err(format!("'{s}' gives more than {max} {noun}"));
            }
            v.push(x);
        }
        v
    } else {
        s.split(',')
            .map(|t| q(t).map(|q| q.value))
            .collect::<Result<_, _>>()?
    };
    if decimals.len() > max as usize {
        return Err(format!("more than {max} {noun}"));
    }
    Ok(decimals)
}

/// Parses a dimensionless number (friction coefficient).
pub fn parse_ratio(s: &str) -> Result<(Decimal, Ratio), String> {
    let d = Decimal::parse(s.trim()).ok_or_else(|| format!("'{s}' is not a number"))?;
    let r = d.to_i32f32().ok_or_else(|| format!("{d} is too large"))?;
    Ok((d, Ratio::from_fixed(r)))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn len(s: &str) -> Length {
        parse(s, Kind::Length).unwrap().length().unwrap()
    }

    #[test]
    fn lengths_in_every_unit() {
        let half = Length::from_fixed(I32F32::lit("0.5"));
        assert_eq!(len("0.5mm"), half);
        assert_eq!(len("500um"), half);
        assert_eq!(len("500 µm"), half);
        assert_eq!(len("5e-4m"), half);
        assert_eq!(len("0.05cm"), half);
        assert_eq!(len("8e-3m"), Length::from_int(8));
        assert_eq!(len("7.8mm"), Length::from_fixed(I32F32::lit("7.8")));
        assert_eq!(len(".5mm"), half);
        assert_eq!(len("+0.5 mm"), half);
    }

    #[test]
    fn pressures_torques_stiffness() {
        let p = |s: &str| parse(s, Kind::Pressure).unwrap().stress().unwrap();
        assert_eq!(p("200GPa"), Stress::from_int(200_000));
        assert_eq!(p("80e9Pa"), Stress::from_int(80_000));
        assert_eq!(p("1500MPa"), Stress::from_int(1_500));
        assert_eq!(p("1.5 GPa"), Stress::from_int(1_500));
        let t = |s: &str| parse(s, Kind::Torque).unwrap().torque().unwrap();
        assert_eq!(t("2Nm"), Torque::from_int(2));
        assert_eq!(t("2N*m"), Torque::from_int(2));
        assert_eq!(t("2N·m"), Torque::from_int(2));
        assert_eq!(t("2000mNm"), Torque::from_int(2));
        assert_eq!(t("300mNm"), Torque::from_fixed(I32F32::lit("0.3")));
        let k = |s: &str| parse(s, Kind::Stiffness).unwrap().stiffness().unwrap();
        assert_eq!(k("500Nm/rad"), Stiffness::from_int(500));
        assert_eq!(k("0.5kNm/rad"), Stiffness::from_int(500));
        assert_eq!(k("500 N·m/rad"), Stiffness::from_int(500));
        assert_eq!(k("1.5Nm/rad"), Stiffness::from_micro(1_500_000));
    }

    #[test]
    fn rejects_bare_numbers_and_unknown_units() {
        let e = parse("0.5", Kind::Length).unwrap_err();
        assert!(e.contains("no unit") && e.contains("mm, m"), "{e}");
        let e = parse("0.5in", Kind::Length).unwrap_err();
        assert!(e.contains("unknown unit 'in'"), "{e}");
        assert!(parse("200gpa", Kind::Pressure).is_err());
        assert!(parse("Nm", Kind::Torque).is_err());
        assert!(parse("2Nm", Kind::Length).is_err());
        assert!(parse("500Nm", Kind::Stiffness).is_err());
        assert!(parse("", Kind::Length).is_err());
        assert!(parse("1..2mm", Kind::Length).is_err());
    }

    #[test]
    fn overflow_and_tiny_values() {
        let q = parse("1e30mm", Kind::Length).unwrap();
        assert_eq!(q.length(), None);
        assert_eq!(q.to_string(), "1e30 mm");
        let q = parse("1e99999999999999mm", Kind::Length).unwrap();
        assert_eq!(q.length(), None);
        let q = parse("1e-30mm", Kind::Length).unwrap();
        assert_eq!(q.length(), Some(Length::ZERO));
        let q = parse("123456789012345678901234567890123456789012mm", Kind::Length).unwrap();
        assert_eq!(q.length(), None);
        assert_eq!(
            parse("-2Nm", Kind::Torque).unwrap().torque(),
            Some(Torque::from_int(-2))
        );
    }

    #[test]
    fn decimal_display_and_arithmetic() {
        let d = |s: &str| Decimal::parse(s).unwrap();
        assert_eq!(d("0.50").to_string(), "0.5");
        assert_eq!(d("8e-3").scaled(3).to_string(), "8");
        assert_eq!(d("80e9").scaled(-6).to_string(), "80000");
        assert_eq!(d("0").to_string(), "0");
        assert_eq!(d("-0").to_string(), "0");
        assert_eq!(d("0.0005").to_string(), "0.0005");
        assert_eq!(d("0").scaled(-6).to_string(), "0");
        assert_eq!(d("1e20").to_string(), "1e20");
        assert_eq!(d("1.5e-9").to_string(), "1.5e-9");
        assert_eq!(d("-12.5").to_string(), "-12.5");
        assert_eq!(d("123000").to_string(), "123000");
        assert_eq!(d("1").add_times(3, d("0.1")), Some(d("1.3")));
        use std::cmp::Ordering::*;
        assert_eq!(d("5").cmp_value(d("5.0")), Equal);
        assert_eq!(d("4.9").cmp_value(d("5")), Less);
        assert_eq!(d("-1").cmp_value(d("0")), Less);
        assert_eq!(d("-2").cmp_value(d("-1")), Less);
        assert_eq!(d("1e3").cmp_value(d("999")), Greater);
        assert!(Decimal::parse("abc").is_none());
        assert!(Decimal::parse("1e").is_none());
    }

    #[test]
    fn board_quantities_to_wire_integers() {
        let w = |s: &str, k: Kind, e: i32| parse(s, k).unwrap().value.round_scaled(e);
        assert_eq!(w("0.5rad", Kind::Angle, 6), Some(500_000));
        assert_eq!(w("-500mrad", Kind::Angle, 6), Some(-500_000));
        assert_eq!(w("12urad", Kind::Angle, 6), Some(12));
        assert_eq!(w("300ms", Kind::Time, 3), Some(300));
        assert_eq!(w("1.5s", Kind::Time, 3), Some(1_500));
        assert_eq!(w("1Hz", Kind::Frequency, 3), Some(1_000));
        assert_eq!(w("250mHz", Kind::Frequency, 3), Some(250));
        assert_eq!(w("1.2A", Kind::Current, 3), Some(1_200));
        assert_eq!(w("3mm", Kind::Length, 3), Some(3_000));
        assert_eq!(w("250Nm/rad", Kind::Stiffness, 3), Some(250_000));
        // Rounding half away from zero, tiny and huge values.
        assert_eq!(w("0.0000005rad", Kind::Angle, 6), Some(1));
        assert_eq!(w("-0.0000005rad", Kind::Angle, 6), Some(-1));
        assert_eq!(w("0.0000004rad", Kind::Angle, 6), Some(0));
        assert_eq!(w("1e-90rad", Kind::Angle, 6), Some(0));
        assert_eq!(w("1e30rad", Kind::Angle, 6), None);
        assert!(parse("1deg", Kind::Angle).is_err());
    }

    #[test]
    fn ratios() {
        assert_eq!(
            parse_ratio("0.4").unwrap().1,
            Ratio::from_fixed(I32F32::lit("0.4"))
        );
        assert!(parse_ratio("0.4mm").is_err());
        assert!(parse_ratio("x").is_err());
    }
}
