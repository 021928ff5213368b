//! Off-nominal actuators on demand: `NAME=VALUE` changes of the simulated actuator's
//! parameters (docs/design.md §9, the real world), applied to a [`PlantConfig`] after it was
//! derived from the controller's (nominal) configuration. The controller keeps its
//! configuration: only the plant changes.
//!
//! One parser for every user of the plant: `vsa simulate --plant NAME=VALUE`, and the
//! emulated boards' arguments later. `no_std`, no allocation (`core`'s `f32` parsing, so
//! the same text gives the same bits on the host and on the boards).
//!
//! VALUE is an absolute value with the parameter's unit (`9.2ohm`, `11.8V`, `2counts`) or
//! a factor of the nominal value, `xF` (`x1.3`); offsets (nominal 0) take counts only.
//!
//! | name | what | unit | nominal |
//! |---|---|---|---|
//! | `resistance` | armature resistance | `ohm` | 8 ohm |
//! | `torque-constant` | torque constant at the output | `Nm/A` | 1.0 |
//! | `back-emf` | back-EMF constant at the output | `Vs/rad` | 1.94 |
//! | `gear-inertia` | rotor + gear train inertia at the output | `kgm2` | 3.2e-3 |
//! | `gear-friction` | gear train Coulomb friction | `Nm`, `mNm` | 0.01 |
//! | `supply` | H-bridge supply | `V` | 12 |
//! | `current-offset` | current-sense offset error | counts | 0 |
//! | `current-gain` | current-sense gain (reading = gain·true) | factor | 1 |
//! | `pot-offset` | gear pot centre error | counts | 0 |
//! | `link-inertia` | link inertia | `kgm2` | the configured one |
//! | `link-friction` | link bearing Coulomb friction | `Nm`, `mNm` | 0 |
//! | `motor-polarity` | motor leads on the bridge (−1: swapped) | ±1 | +1 |
//! | `encoder-direction` | link encoder counting direction | ±1 | +1 |
//! | `encoder-zero` | link encoder reading at power-up | counts | 0 |
//! | `encoder-counts` | link encoder counts per turn | counts | 4096 |
//! | `pot-direction` | pot end terminals (−1: swapped) | ±1 | +1 |
//! | `pot-gain` | pot slope (reading = gain·nominal slope) | factor | 1 |
//! | `pot-nonlinearity` | amplitude of the pot's bow A·sin(2π·c/1024) | counts | 0 |
//! | `pot-noise` | pot noise, standard deviation | counts | 0 |
//! | `current-noise` | current-sense noise, standard deviation | counts | 0 |
//! | `noise-seed` | seed of the sensors' noise | a bare number | 0x2545F491 |
//! | `clutch` | the clutch's actual length (the coupling is derived again) | `mm` | the configured one |
//! | `power-up-angle` | link angle at power-up (the encoder starts at `encoder-zero` there) | `rad`, `deg` | 0 |
//! | `supply-sense-gain` | supply sense gain (reading = gain·true supply) | factor | 1 |
//!
//! Signs (`±1`) take `1` or `-1` only; counts, the seed and the power-up angle take no
//! factor.

use core::fmt;

use crate::config::PlantConfig;

/// A parameter of the simulated actuator that can be overridden.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Param {
    /// Armature resistance, Ω.
    Resistance,
    /// Torque constant at the output, N·m/A.
    TorqueConstant,
    /// Back-EMF constant at the output, V·s/rad.
    BackEmf,
    /// Rotor + gear inertia at the output, kg·m².
    GearInertia,
    /// Gear train Coulomb friction, N·m.
    GearFriction,
    /// H-bridge supply, V.
    Supply,
    /// Current-sense offset, ADC counts.
    CurrentOffset,
    /// Current-sense gain, factor.
    CurrentGain,
    /// Gear pot centre offset, counts.
    PotOffset,
    /// Link inertia, kg·m².
    LinkInertia,
    /// Link bearing Coulomb friction, N·m.
    LinkFriction,
    /// Motor lead polarity, ±1.
    MotorPolarity,
    /// Link encoder direction, ±1.
    EncoderDirection,
    /// Link encoder reading at power-up, counts.
    EncoderZero,
    /// Link encoder counts per turn.
    EncoderCounts,
    /// Pot direction, ±1.
    PotDirection,
    /// Pot gain, factor.
    PotGain,
    /// Pot non-linearity amplitude, counts.
    PotNonlinearity,
    /// Pot noise, counts (1 σ).
    PotNoise,
    /// Current-sense noise, counts (1 σ).
    CurrentNoise,
    /// Seed of the sensor noise.
    NoiseSeed,
    /// Actual clutch length, m.
    Clutch,
    /// Link angle at power-up, rad.
    PowerUpAngle,
    /// Supply-sense gain, factor.
    SupplySenseGain,
}

/// Name, units (spelling, factor to SI) and whether it is an offset (no `xF`), per
/// parameter. An empty unit list takes a bare number.
struct Spec {
    param: Param,
    name: &'static str,
    units: &'static [(&'static str, f64)],
    offset: bool,
}

/// A wiring sign: `1` or `-1`, no factor.
const fn sign(param: Param, name: &'static str) -> Spec {
    Spec {
        param,
        name,
        units: SIGN,
        offset: true,
    }
}

const OHM: &[(&str, f64)] = &[("ohm", 1.0), ("Ω", 1.0), ("mohm", 1e-3)];
const NM_PER_A: &[(&str, f64)] = &[("Nm/A", 1.0), ("N·m/A", 1.0)];
const VS_PER_RAD: &[(&str, f64)] = &[("Vs/rad", 1.0), ("V·s/rad", 1.0)];
const KGM2: &[(&str, f64)] = &[("kgm2", 1.0), ("kg·m²", 1.0), ("kgmm2", 1e-6)];
const NM: &[(&str, f64)] = &[("Nm", 1.0), ("N·m", 1.0), ("mNm", 1e-3)];
const VOLT: &[(&str, f64)] = &[("V", 1.0), ("mV", 1e-3)];
const COUNTS: &[(&str, f64)] = &[("", 1.0), ("counts", 1.0), ("count", 1.0)];
const FACTOR: &[(&str, f64)] = &[("", 1.0)];
const SIGN: &[(&str, f64)] = &[("", 1.0)];
const MM: &[(&str, f64)] = &[("mm", 1e-3), ("m", 1.0)];
const RAD: &[(&str, f64)] = &[
    ("rad", 1.0),
    ("deg", core::f64::consts::PI / 180.0),
    ("°", core::f64::consts::PI / 180.0),
];

const SPECS: [Spec; 24] = [
    Spec {
        param: Param::Resistance,
        name: "resistance",
        units: OHM,
        offset: false,
    },
    Spec {
        param: Param::TorqueConstant,
        name: "torque-constant",
        units: NM_PER_A,
        offset: false,
    },
    Spec {
        param: Param::BackEmf,
        name: "back-emf",
        units: VS_PER_RAD,
        offset: false,
    },
    Spec {
        param: Param::GearInertia,
        name: "gear-inertia",
        units: KGM2,
        offset: false,
    },
    Spec {
        param: Param::GearFriction,
        name: "gear-friction",
        units: NM,
        offset: false,
    },
    Spec {
        param: Param::Supply,
        name: "supply",
        units: VOLT,
        offset: false,
    },
    Spec {
        param: Param::CurrentOffset,
        name: "current-offset",
        units: COUNTS,
        offset: true,
    },
    Spec {
        param: Param::CurrentGain,
        name: "current-gain",
        units: FACTOR,
        offset: false,
    },
    Spec {
        param: Param::PotOffset,
        name: "pot-offset",
        units: COUNTS,
        offset: true,
    },
    Spec {
        param: Param::LinkInertia,
        name: "link-inertia",
        units: KGM2,
        offset: false,
    },
    Spec {
        param: Param::LinkFriction,
        name: "link-friction",
        units: NM,
        offset: false,
    },
    sign(Param::MotorPolarity, "motor-polarity"),
    sign(Param::EncoderDirection, "encoder-direction"),
    Spec {
        param: Param::EncoderZero,
        name: "encoder-zero",
        units: COUNTS,
        offset: true,
    },
    Spec {
        param: Param::EncoderCounts,
        name: "encoder-counts",
        units: COUNTS,
        offset: true,
    },
    sign(Param::PotDirection, "pot-direction"),
    Spec {
        param: Param::PotGain,
        name: "pot-gain",
        units: FACTOR,
        offset: false,
    },
    Spec {
        param: Param::PotNonlinearity,
        name: "pot-nonlinearity",
        units: COUNTS,
        offset: true,
    },
    Spec {
        param: Param::PotNoise,
        name: "pot-noise",
        units: COUNTS,
        offset: true,
    },
    Spec {
        param: Param::CurrentNoise,
        name: "current-noise",
        units: COUNTS,
        offset: true,
    },
    Spec {
        param: Param::NoiseSeed,
        name: "noise-seed",
        units: FACTOR,
        offset: true,
    },
    Spec {
        param: Param::Clutch,
        name: "clutch",
        units: MM,
        offset: false,
    },
    Spec {
        param: Param::PowerUpAngle,
        name: "power-up-angle",
        units: RAD,
        offset: true,
    },
    Spec {
        param: Param::SupplySenseGain,
        name: "supply-sense-gain",
        units: FACTOR,
        offset: false,
    },
];

impl Param {
    /// Every parameter, in the table's order.
    pub const ALL: [Param; 24] = [
        Param::Resistance,
        Param::TorqueConstant,
        Param::BackEmf,
        Param::GearInertia,
        Param::GearFriction,
        Param::Supply,
        Param::CurrentOffset,
        Param::CurrentGain,
        Param::PotOffset,
        Param::LinkInertia,
        Param::LinkFriction,
        Param::MotorPolarity,
        Param::EncoderDirection,
        Param::EncoderZero,
        Param::EncoderCounts,
        Param::PotDirection,
        Param::PotGain,
        Param::PotNonlinearity,
        Param::PotNoise,
        Param::CurrentNoise,
        Param::NoiseSeed,
        Param::Clutch,
        Param::PowerUpAngle,
        Param::SupplySenseGain,
    ];

    fn spec(self) -> &'static Spec {
        &SPECS[self as usize] // same order (tested)
    }

    /// The name on the command line (`resistance`, `back-emf`, …).
    #[must_use]
    pub fn name(self) -> &'static str {
        self.spec().name
    }

    /// The parameter called `name`.
    #[must_use]
    pub fn from_name(name: &str) -> Option<Param> {
        SPECS.iter().find(|s| s.name == name).map(|s| s.param)
    }

    /// The first accepted unit spelling (empty for a bare number).
    #[must_use]
    pub fn unit(self) -> &'static str {
        self.spec().units[0].0
    }

    /// The parameter's value in `pc`, SI (offsets and gains as in the table).
    #[must_use]
    pub fn get(self, pc: &PlantConfig) -> f32 {
        match self {
            Param::Resistance => pc.motor.resistance_ohm,
            Param::TorqueConstant => pc.motor.torque_constant_nm_per_a,
            Param::BackEmf => pc.motor.back_emf_v_s_per_rad,
            Param::GearInertia => pc.motor.inertia_kg_m2,
            Param::GearFriction => pc.motor.coulomb_nm,
            Param::Supply => pc.motor.supply_voltage_v,
            Param::CurrentOffset => pc.sensors.current_offset_counts,
            Param::CurrentGain => pc.sensors.current_gain,
            Param::PotOffset => pc.sensors.pot_center_counts - NOMINAL_POT_CENTER,
            Param::LinkInertia => pc.link.inertia_kg_m2,
            Param::LinkFriction => pc.link.coulomb_nm,
            Param::MotorPolarity => pc.motor.polarity,
            Param::EncoderDirection => pc.sensors.encoder_direction,
            Param::EncoderZero => f32::from(pc.sensors.encoder_zero_counts),
            Param::EncoderCounts => f32::from(pc.sensors.encoder_counts_per_turn),
            Param::PotDirection => pc.sensors.pot_direction,
            Param::PotGain => pc.sensors.pot_gain,
            Param::PotNonlinearity => pc.sensors.pot_nonlinearity_counts,
            Param::PotNoise => pc.sensors.pot_noise_counts,
            Param::CurrentNoise => pc.sensors.current_noise_counts,
            // The seed as a number (exact below 2²⁴; the seeds the tools draw are).
            Param::NoiseSeed => pc.sensors.noise_seed as f32,
            Param::Clutch => pc.clutch_length_m,
            Param::PowerUpAngle => pc.power_up_angle_rad,
            Param::SupplySenseGain => pc.sensors.supply_sense_gain,
        }
    }

    fn set(self, pc: &mut PlantConfig, v: f32) {
        match self {
            Param::Resistance => pc.motor.resistance_ohm = v,
            Param::TorqueConstant => pc.motor.torque_constant_nm_per_a = v,
            Param::BackEmf => pc.motor.back_emf_v_s_per_rad = v,
            Param::GearInertia => pc.motor.inertia_kg_m2 = v,
            Param::GearFriction => pc.motor.coulomb_nm = v,
            Param::Supply => pc.motor.supply_voltage_v = v,
            Param::CurrentOffset => pc.sensors.current_offset_counts = v,
            Param::CurrentGain => pc.sensors.current_gain = v,
            Param::PotOffset => pc.sensors.pot_center_counts = NOMINAL_POT_CENTER + v,
            Param::LinkInertia => pc.link.inertia_kg_m2 = v,
            Param::LinkFriction => pc.link.coulomb_nm = v,
            Param::MotorPolarity => pc.motor.polarity = v,
            Param::EncoderDirection => pc.sensors.encoder_direction = v,
            // Ranges checked at parsing: the casts are exact.
            Param::EncoderZero => pc.sensors.encoder_zero_counts = v as u16,
            Param::EncoderCounts => pc.sensors.encoder_counts_per_turn = v as u16,
            Param::PotDirection => pc.sensors.pot_direction = v,
            Param::PotGain => pc.sensors.pot_gain = v,
            Param::PotNonlinearity => pc.sensors.pot_nonlinearity_counts = v,
            Param::PotNoise => pc.sensors.pot_noise_counts = v,
            Param::CurrentNoise => pc.sensors.current_noise_counts = v,
            Param::NoiseSeed => pc.sensors.noise_seed = v as u32,
            Param::Clutch => pc.clutch_length_m = v,
            Param::PowerUpAngle => pc.power_up_angle_rad = v,
            Param::SupplySenseGain => pc.sensors.supply_sense_gain = v,
        }
    }

    /// A wiring sign (takes `1` or `-1` only).
    fn is_sign(self) -> bool {
        matches!(
            self,
            Param::MotorPolarity | Param::EncoderDirection | Param::PotDirection
        )
    }

    /// A count that must be a whole number.
    fn is_integer(self) -> bool {
        matches!(
            self,
            Param::EncoderZero | Param::EncoderCounts | Param::NoiseSeed
        )
    }

    /// The smallest factor `xF` (0 for the frictions, which may vanish).
    fn factor_range(self) -> (f32, f32) {
        match self {
            Param::GearFriction | Param::LinkFriction => (0.0, FACTOR_MAX),
            _ => (FACTOR_MIN, FACTOR_MAX),
        }
    }

    /// The plausible range of an absolute value (SI): physical parameters strictly
    /// positive (frictions may be 0) and within a factor that keeps the simulation
    /// meaningful; offsets within a quarter of the sensor's range.
    fn range(self) -> (f32, f32) {
        match self {
            Param::Resistance => (0.1, 1000.0),
            Param::TorqueConstant | Param::BackEmf => (0.01, 100.0),
            Param::GearInertia | Param::LinkInertia => (1e-6, 1.0),
            Param::GearFriction | Param::LinkFriction => (0.0, 10.0),
            Param::Supply => (1.0, 100.0),
            Param::CurrentOffset => (-1000.0, 1000.0),
            Param::CurrentGain | Param::PotGain | Param::SupplySenseGain => (0.1, 10.0),
            Param::PotOffset => (-250.0, 250.0),
            Param::MotorPolarity | Param::EncoderDirection | Param::PotDirection => (-1.0, 1.0),
            Param::EncoderZero => (0.0, 16383.0),
            Param::EncoderCounts => (16.0, 16384.0),
            Param::PotNonlinearity => (-50.0, 50.0),
            Param::PotNoise | Param::CurrentNoise => (0.0, 100.0),
            Param::NoiseSeed => (0.0, 16_777_215.0),
            Param::Clutch => (0.1e-3, 20.0e-3),
            Param::PowerUpAngle => (-3.2, 3.2),
        }
    }
}

/// Smallest factor `xF` of a parameter that must stay positive: the simulation's
/// integrator stays accurate within ×0.1 … ×10 of the nominal actuator.
pub const FACTOR_MIN: f32 = 0.1;
/// Largest factor `xF`.
pub const FACTOR_MAX: f32 = 10.0;

/// The pot count the simulated actuator reads at gear angle 0 when nothing is overridden
/// (the controller's calibration assumes it).
pub const NOMINAL_POT_CENTER: f32 = 512.0;

/// How the value was given.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Value {
    /// Absolute, SI (offsets in counts, the gain as a factor).
    Absolute(f32),
    /// A factor of the nominal value (`xF`).
    Factor(f32),
}

/// One `NAME=VALUE`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Override {
    /// Which parameter.
    pub param: Param,
    /// Its new value.
    pub value: Value,
}

/// Why a `NAME=VALUE` was rejected; [`fmt::Display`] gives the one-line message.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum OverrideError {
    /// Not of the form `NAME=VALUE`.
    Syntax,
    /// No such parameter.
    UnknownName,
    /// The value is not a finite number.
    NotANumber(Param),
    /// The unit is not one of the parameter's.
    Unit(Param),
    /// A factor was given for an offset (nominal 0).
    FactorOfOffset(Param),
    /// The absolute value is outside the parameter's range.
    OutOfRange(Param),
    /// The factor is outside [`FACTOR_MIN`] (0 for frictions) … [`FACTOR_MAX`].
    FactorOutOfRange(Param),
    /// A wiring sign other than `1` or `-1`.
    NotASign(Param),
    /// A count that is not a whole number.
    NotWhole(Param),
}

impl fmt::Display for Override {
    /// `NAME=VALUE` as [`Override::parse`] reads it back to the same value: an absolute
    /// value in its SI unit, every value in full precision.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let name = self.param.name();
        match self.value {
            Value::Factor(x) => write!(f, "{name}=x{x}"),
            Value::Absolute(v) => {
                let si = self
                    .param
                    .spec()
                    .units
                    .iter()
                    .find(|&&(_, k)| k == 1.0)
                    .map_or("", |&(u, _)| u);
                write!(f, "{name}={v}{si}")
            }
        }
    }
}

impl fmt::Display for OverrideError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let units = |f: &mut fmt::Formatter<'_>, p: Param| -> fmt::Result {
            let mut first = true;
            for (u, _) in p.spec().units {
                if !first {
                    f.write_str(", ")?;
                }
                first = false;
                if u.is_empty() {
                    f.write_str("a bare number")?;
                } else {
                    f.write_str(u)?;
                }
            }
            Ok(())
        };
        match *self {
            OverrideError::Syntax => f.write_str("expected NAME=VALUE, e.g. resistance=x1.3"),
            OverrideError::UnknownName => {
                f.write_str("unknown parameter (use ")?;
                for (i, s) in SPECS.iter().enumerate() {
                    if i > 0 {
                        f.write_str(", ")?;
                    }
                    f.write_str(s.name)?;
                }
                f.write_str(")")
            }
            OverrideError::NotANumber(p) => {
                write!(f, "{}: not a finite number", p.name())
            }
            OverrideError::Unit(p) => {
                write!(f, "{}: unknown unit (use ", p.name())?;
                units(f, p)?;
                if !p.spec().offset {
                    f.write_str(", or a factor xF")?;
                }
                f.write_str(")")
            }
            OverrideError::FactorOfOffset(p) => {
                write!(
                    f,
                    "{}: an offset (nominal 0) takes counts, not a factor",
                    p.name()
                )
            }
            OverrideError::OutOfRange(p) => {
                let (lo, hi) = p.range();
                write!(f, "{}: outside [{lo}, {hi}]", p.name())?;
                if !p.unit().is_empty() {
                    write!(f, " {}", p.unit())?;
                }
                Ok(())
            }
            OverrideError::FactorOutOfRange(p) => {
                let (lo, hi) = p.factor_range();
                write!(f, "{}: factor outside x{lo} … x{hi}", p.name())
            }
            OverrideError::NotASign(p) => write!(f, "{}: must be 1 or -1", p.name()),
            OverrideError::NotWhole(p) => write!(f, "{}: must be a whole number", p.name()),
        }
    }
}

impl core::error::Error for OverrideError {}

/// Splits `s` into its number and unit: the longest prefix that parses as an `f32`.
/// Parsed as f64 and scaled by the unit in f64, then rounded to f32 once (so `30mNm`
/// is the f32 nearest 0.03).
fn number_and_unit(s: &str) -> Option<(f64, &str)> {
    let end = s
        .char_indices()
        .map(|(i, c)| i + c.len_utf8())
        .rev()
        .find(|&i| s[..i].parse::<f64>().is_ok())?;
    let v: f64 = s[..end].parse().ok()?;
    v.is_finite().then_some((v, s[end..].trim()))
}

impl Override {
    /// Parses `NAME=VALUE` (spaces around the parts are ignored).
    ///
    /// # Errors
    /// See [`OverrideError`].
    pub fn parse(s: &str) -> Result<Override, OverrideError> {
        let (name, value) = s.split_once('=').ok_or(OverrideError::Syntax)?;
        let param = Param::from_name(name.trim()).ok_or(OverrideError::UnknownName)?;
        let spec = param.spec();
        let value = value.trim();
        if let Some(factor) = value.strip_prefix(['x', 'X', '×']) {
            if spec.offset {
                return Err(OverrideError::FactorOfOffset(param));
            }
            let f: f32 = factor
                .trim()
                .parse()
                .map_err(|_| OverrideError::NotANumber(param))?;
            if !f.is_finite() {
                return Err(OverrideError::NotANumber(param));
            }
            if !(param.factor_range().0..=FACTOR_MAX).contains(&f) {
                return Err(OverrideError::FactorOutOfRange(param));
            }
            return Ok(Override {
                param,
                value: Value::Factor(f),
            });
        }
        let (v, unit) = number_and_unit(value).ok_or(OverrideError::NotANumber(param))?;
        let scale = spec
            .units
            .iter()
            .find(|(u, _)| u.eq_ignore_ascii_case(unit))
            .map(|&(_, k)| k)
            .ok_or(OverrideError::Unit(param))?;
        let v = (v * scale) as f32;
        if param.is_sign() && v != 1.0 && v != -1.0 {
            return Err(OverrideError::NotASign(param));
        }
        if param.is_integer() && libm::floorf(v) != v {
            return Err(OverrideError::NotWhole(param));
        }
        let (lo, hi) = param.range();
        if !(lo..=hi).contains(&v) {
            return Err(OverrideError::OutOfRange(param));
        }
        Ok(Override {
            param,
            value: Value::Absolute(v),
        })
    }

    /// The value this override gives the parameter in `pc` (a factor applies to `pc`'s).
    #[must_use]
    pub fn resolve(&self, pc: &PlantConfig) -> f32 {
        match self.value {
            Value::Absolute(v) => v,
            Value::Factor(f) => f * self.param.get(pc),
        }
    }
}

/// Most overrides one run takes (one per parameter).
pub const MAX_OVERRIDES: usize = Param::ALL.len();

/// A set of overrides, at most one per parameter (a later one for the same parameter
/// replaces the earlier), applied in one go to a nominal [`PlantConfig`].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Overrides {
    items: [Option<Override>; MAX_OVERRIDES],
}

impl Overrides {
    /// No override: the nominal actuator.
    pub const NONE: Overrides = Overrides {
        items: [None; MAX_OVERRIDES],
    };

    /// Adds `o` (replacing an earlier one of the same parameter).
    pub fn set(&mut self, o: Override) {
        self.items[o.param as usize] = Some(o);
    }

    /// Parses and adds `NAME=VALUE`.
    ///
    /// # Errors
    /// As [`Override::parse`].
    pub fn push_str(&mut self, s: &str) -> Result<(), OverrideError> {
        self.set(Override::parse(s)?);
        Ok(())
    }

    /// Parses every item of `items`.
    ///
    /// # Errors
    /// The first rejected item's error.
    pub fn parse_all<'a, I: IntoIterator<Item = &'a str>>(
        items: I,
    ) -> Result<Overrides, OverrideError> {
        let mut o = Overrides::NONE;
        for s in items {
            o.push_str(s)?;
        }
        Ok(o)
    }

    /// Whether nothing is overridden.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.items.iter().all(Option::is_none)
    }

    /// The overrides, in the table's order.
    pub fn iter(&self) -> impl Iterator<Item = &Override> {
        self.items.iter().flatten()
    }

    /// `nominal` with the overrides applied (factors of `nominal`'s values).
    #[must_use]
    pub fn apply(&self, nominal: &PlantConfig) -> PlantConfig {
        let mut pc = *nominal;
        for o in self.iter() {
            o.param.set(&mut pc, o.resolve(nominal));
        }
        pc
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_absolute_values_and_factors() {
        let o = Override::parse("resistance=9.2ohm").unwrap();
        assert_eq!(o.param, Param::Resistance);
        assert_eq!(o.value, Value::Absolute(9.2));
        let o = Override::parse(" supply = 11.8V ").unwrap();
        assert_eq!(o.value, Value::Absolute(11.8));
        assert_eq!(
            Override::parse("gear-friction=30mNm").unwrap().value,
            Value::Absolute(30.0e-3)
        );
        assert_eq!(
            Override::parse("back-emf=x0.9").unwrap().value,
            Value::Factor(0.9)
        );
        assert_eq!(
            Override::parse("current-offset=-20").unwrap().value,
            Value::Absolute(-20.0)
        );
        assert_eq!(
            Override::parse("pot-offset=3counts").unwrap().value,
            Value::Absolute(3.0)
        );
        assert_eq!(
            Override::parse("link-inertia=2e-3kgm2").unwrap().value,
            Value::Absolute(2.0e-3)
        );
        assert_eq!(
            Override::parse("current-gain=1.05").unwrap().value,
            Value::Absolute(1.05)
        );
    }

    /// What `Display` writes, `parse` reads back to the same value, bit for bit: the
    /// acceptance grid prints its cases as `vsa simulate` arguments that rerun them.
    #[test]
    fn display_parses_back_to_the_same_value() {
        let mut n = 0;
        for p in Param::ALL {
            let (lo, hi) = p.range();
            let mut values: Vec<f32> = (0..=400)
                .map(|k| lo + (hi - lo) * (k as f32 / 400.0).powi(3))
                .chain([lo, hi, lo + (hi - lo) * 0.123_456_79])
                .filter(|v| (lo..=hi).contains(v))
                .collect();
            if p.is_sign() {
                values = vec![-1.0, 1.0];
            } else if p.is_integer() {
                values = values.iter().map(|v| v.floor().max(lo)).collect();
            }
            let mut all: Vec<Value> = values.into_iter().map(Value::Absolute).collect();
            if !p.spec().offset {
                let (flo, fhi) = p.factor_range();
                all.extend((0..=200).map(|k| Value::Factor(flo + (fhi - flo) * k as f32 / 200.0)));
                all.push(Value::Factor(1.154_444_3));
            }
            for value in all {
                let o = Override { param: p, value };
                let text = o.to_string();
                assert_eq!(Override::parse(&text), Ok(o), "{text}");
                n += 1;
            }
        }
        assert!(n > 5000, "{n} values");
    }

    #[test]
    fn rejects_bad_input_with_one_line_messages() {
        use OverrideError as E;
        let cases = [
            ("resistance", E::Syntax),
            ("resistor=8ohm", E::UnknownName),
            ("resistance=abc", E::NotANumber(Param::Resistance)),
            ("resistance=8", E::Unit(Param::Resistance)),
            ("resistance=8V", E::Unit(Param::Resistance)),
            ("resistance=xabc", E::NotANumber(Param::Resistance)),
            ("resistance=x-1", E::FactorOutOfRange(Param::Resistance)),
            ("resistance=x0", E::FactorOutOfRange(Param::Resistance)),
            ("supply=x100", E::FactorOutOfRange(Param::Supply)),
            ("resistance=-8ohm", E::OutOfRange(Param::Resistance)),
            ("pot-offset=x2", E::FactorOfOffset(Param::PotOffset)),
            ("supply=infV", E::NotANumber(Param::Supply)),
            ("supply=NaNV", E::NotANumber(Param::Supply)),
            ("motor-polarity=0", E::NotASign(Param::MotorPolarity)),
            ("pot-direction=x1", E::FactorOfOffset(Param::PotDirection)),
            ("encoder-counts=1000.5", E::NotWhole(Param::EncoderCounts)),
            ("encoder-counts=8", E::OutOfRange(Param::EncoderCounts)),
            ("clutch=3", E::Unit(Param::Clutch)),
            ("clutch=30mm", E::OutOfRange(Param::Clutch)),
        ];
        for (s, want) in cases {
            let got = Override::parse(s).unwrap_err();
            assert_eq!(got, want, "{s}");
            let msg = std::format!("{got}");
            assert!(!msg.is_empty() && !msg.contains('\n'), "{s}: {msg}");
        }
        let msg = std::format!("{}", E::UnknownName);
        for p in Param::ALL {
            assert!(msg.contains(p.name()), "{msg}");
        }
    }

    #[test]
    fn applies_factors_of_the_nominal_values() {
        let nominal = PlantConfig::default();
        let o = Overrides::parse_all([
            "resistance=x1.4",
            "pot-offset=-3",
            "current-gain=x0.95",
            "link-inertia=x3",
            "supply=10.5V",
            "supply-sense-gain=x1.02",
        ])
        .unwrap();
        let pc = o.apply(&nominal);
        assert_eq!(pc.sensors.supply_sense_gain, 1.02);
        assert_eq!(pc.motor.resistance_ohm, 1.4 * 8.0);
        assert_eq!(pc.sensors.pot_center_counts, 509.0);
        assert_eq!(pc.sensors.current_gain, 0.95);
        assert_eq!(pc.link.inertia_kg_m2, 3.0 * 1.0e-3);
        assert_eq!(pc.motor.supply_voltage_v, 10.5);
        let real = Overrides::parse_all([
            "motor-polarity=-1",
            "encoder-direction=-1",
            "encoder-zero=100",
            "pot-direction=-1",
            "pot-gain=x1.1",
            "clutch=3.5mm",
            "power-up-angle=-30deg",
            "noise-seed=99",
        ])
        .unwrap()
        .apply(&nominal);
        assert_eq!(real.motor.polarity, -1.0);
        assert_eq!(real.sensors.encoder_direction, -1.0);
        assert_eq!(real.sensors.encoder_zero_counts, 100);
        assert_eq!(real.sensors.pot_direction, -1.0);
        assert_eq!(real.sensors.pot_gain, 1.1);
        assert_eq!(real.clutch_length_m, 3.5e-3);
        assert_eq!(real.power_up_angle_rad, (-30f64).to_radians() as f32);
        assert_eq!(real.sensors.noise_seed, 99);
        // Untouched parameters stay nominal.
        assert_eq!(
            pc.motor.back_emf_v_s_per_rad,
            nominal.motor.back_emf_v_s_per_rad
        );
        for p in Param::ALL {
            assert_eq!(Param::from_name(p.name()), Some(p));
            assert_eq!(p.spec().param, p);
        }
        assert_eq!(
            Override::parse("gear-friction=x0")
                .unwrap()
                .resolve(&nominal),
            0.0
        );
        // The later of two overrides of one parameter wins.
        let o = Overrides::parse_all(["supply=11V", "supply=12.6V"]).unwrap();
        assert_eq!(o.apply(&nominal).motor.supply_voltage_v, 12.6);
        assert!(Overrides::NONE.is_empty() && !o.is_empty());
    }
}
