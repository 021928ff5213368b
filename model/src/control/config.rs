//! Controller configuration, its validation, and the gain schedule computed from it.
//!
//! Everything here runs when the configuration changes (divisions, square roots and
//! 128-bit arithmetic are fine); [`Schedule`] holds the per-tick constants as [`Gain`]s.
//! See the module docs of [`crate::control`] for the design and the derivation of the
//! formulas.

use core::fmt;

use fixed::types::{I32F32, I64F64};

use super::gain::{Gain, Q16_ONE};
use crate::beam::{BeamModel, Setting};
use crate::design::Design;
use crate::dynamics::natural_frequency;
use crate::error::Error;
use crate::units::{Angle, Frequency, Inertia, Length, Ratio, Stiffness, Torque};

/// Why a configuration or a command was rejected. The running configuration (or
/// trajectory) is left untouched.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum ControlError {
    /// The beam model rejected the clutch length or the wanted stiffness.
    Beam(Error),
    /// The clutch length is outside the adjustable range [t_c, l] of the design.
    ClutchOutOfRange,
    /// The stiffness is above [`MAX_STIFFNESS`] (outside the controller's formats).
    StiffnessOutOfRange,
    /// Link inertia outside [[`MIN_INERTIA`], [`MAX_INERTIA`]] kg·mm².
    InertiaOutOfRange,
    /// A motor parameter is outside its documented range (see [`MotorParams`]).
    MotorOutOfRange,
    /// A limit is outside its documented range (see [`Limits`]).
    LimitOutOfRange,
    /// A gain override or the bandwidth is outside its range (see [`GainOverride`]).
    GainOutOfRange,
    /// A sensor calibration value is outside the sensor's range.
    SensorOutOfRange,
    /// A trajectory command is outside its range (see [`super::trajectory`]).
    TrajectoryOutOfRange,
    /// A derived constant does not fit its per-tick format.
    Overflow,
}

impl fmt::Display for ControlError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ControlError::Beam(e) => write!(f, "beam model: {e}"),
            ControlError::ClutchOutOfRange => {
                f.write_str("clutch length outside the adjustable range [t_c, l]")
            }
            ControlError::StiffnessOutOfRange => {
                f.write_str("stiffness above the controller's range (1e6 N·m/rad)")
            }
            ControlError::InertiaOutOfRange => {
                f.write_str("link inertia outside [1, 1e6] kg·mm² (1e-6 … 1 kg·m²)")
            }
            ControlError::MotorOutOfRange => f.write_str("motor parameter out of range"),
            ControlError::LimitOutOfRange => f.write_str("limit out of range"),
            ControlError::GainOutOfRange => f.write_str("gain or bandwidth out of range"),
            ControlError::SensorOutOfRange => f.write_str("sensor calibration out of range"),
            ControlError::TrajectoryOutOfRange => f.write_str("trajectory command out of range"),
            ControlError::Overflow => f.write_str("derived constant out of its fixed-point range"),
        }
    }
}

impl core::error::Error for ControlError {}

impl From<Error> for ControlError {
    fn from(e: Error) -> Self {
        ControlError::Beam(e)
    }
}

/// Stiffest setting the controller accepts, N·m/rad.
pub const MAX_STIFFNESS: i64 = 1_000_000;
/// Smallest link inertia, kg·mm² (1e-6 kg·m²).
pub const MIN_INERTIA: i32 = 1;
/// Largest link inertia, kg·mm² (1 kg·m²).
pub const MAX_INERTIA: i32 = 1_000_000;

/// Encoder counts per revolution (12-bit magnetic encoder).
pub const ENCODER_COUNTS: i32 = 4096;
/// Potentiometer counts over its 300° span.
pub const POT_COUNTS: i32 = 1024;
/// Current ADC zero (mid-scale) and counts per ampere (12 bit, ±2 A).
pub const ADC_MID: i32 = 2048;
/// Current ADC counts per ampere.
pub const ADC_COUNTS_PER_A: i32 = 1024;

/// Signed change of a link-encoder reading from `prev` to `now`, counts, the shorter way
/// round the 4096-count turn: in [−2048, 2048).
#[must_use]
pub const fn encoder_delta(now: u16, prev: u16) -> i32 {
    let d = (now as i32 - prev as i32) & (ENCODER_COUNTS - 1);
    if d >= ENCODER_COUNTS / 2 {
        d - ENCODER_COUNTS
    } else {
        d
    }
}

/// Which clutch setting to run at.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ClutchSetting {
    /// Active beam length L, mm, in the adjustable range [t_c, l].
    Length(Length),
    /// Wanted joint stiffness k, N·m/rad: L = L(k) of the beam model.
    Stiffness(Stiffness),
}

/// Motor and gearbox, all referred to the gearbox output (AX-12A class defaults,
/// design.md §3). Units in the field docs; every field is I32F32 unless stated.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MotorParams {
    /// H-bridge supply, V, in [1, 100]. Duty ±1000 ‰ applies ±supply.
    pub supply_v: I32F32,
    /// Armature resistance, Ω, in [0.1, 1000].
    pub resistance_ohm: I32F32,
    /// Torque constant at the output, N·m/A, in [0.01, 100].
    pub torque_constant: I32F32,
    /// Back-EMF constant at the output, V·s/rad, in [0.01, 100].
    pub back_emf: I32F32,
    /// Rotor + gear train inertia at the output, kg·mm², in [1, 10⁶].
    pub rotor_inertia: Inertia,
    /// Viscous friction of the gear train at the output, N·m·s/rad, in [0, 10].
    pub viscous: I32F32,
}

impl MotorParams {
    /// AX-12A class: 12 V, 8 Ω, k_t = 1.0 N·m/A, k_e = 1.94 V·s/rad, J_rotor = 3.2e-3
    /// kg·m² (3200 kg·mm²), viscous 1e-3 N·m·s/rad.
    pub const AX12A: MotorParams = MotorParams {
        supply_v: I32F32::lit("12"),
        resistance_ohm: I32F32::lit("8"),
        torque_constant: I32F32::lit("1"),
        back_emf: I32F32::lit("1.94"),
        rotor_inertia: Inertia::from_int(3200),
        viscous: I32F32::lit("0.001"),
    };
}

/// Live limits (clamps, not faults).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Limits {
    /// Fraction of the beams' stress-limited capacity τ_cap(L) the coupling torque may
    /// use, in (0, 1]. Default 0.85.
    pub torque_margin: Ratio,
    /// Motor current limit, A, in (0, 10]. Default 1.5 A (stall current at 12 V).
    pub max_current_a: I32F32,
    /// Motor torque limit at the output, N·m, > 0. Default 1.5 N·m (stall torque).
    pub max_motor_torque: Torque,
    /// Largest |duty|, ‰, in 1..=1000. Default 1000.
    pub max_duty: i16,
}

impl Limits {
    /// The defaults above.
    pub const DEFAULT: Limits = Limits {
        torque_margin: Ratio::from_fixed(I32F32::lit("0.85")),
        max_current_a: I32F32::lit("1.5"),
        max_motor_torque: Torque::from_fixed(I32F32::lit("1.5")),
        max_duty: 1000,
    };
}

impl Default for Limits {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// PID gains in the controller's units (duty ‰ out, link angle in).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PidGains {
    /// Proportional, ‰/rad, in [0, 10⁶].
    pub kp: I32F32,
    /// Integral, ‰/(rad·s), in [0, 10⁷].
    pub ki: I32F32,
    /// Derivative (on the filtered link velocity), ‰·s/rad, in [0, 10⁴].
    pub kd: I32F32,
}

/// Overrides of the automatic gain schedule.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct GainOverride {
    /// Closed-loop bandwidth ω_c, rad/s, in (0, 500]; `None`: scheduled from k and J.
    pub bandwidth: Option<Frequency>,
    /// Explicit PID gains; `None`: from the pole placement at ω_c.
    pub gains: Option<PidGains>,
}

/// Sensor calibration.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SensorCal {
    /// Gear potentiometer reading at gear angle 0, counts, 0..=1023. Default 512.
    pub pot_center: u16,
    /// Link encoder reading at link angle 0, counts, 0..=4095. Default 0.
    pub encoder_zero: u16,
    /// 1-σ uncertainty of the current-based torque estimate (gear friction, inertia and
    /// gear-efficiency model error), N·m, > 0. Default 0.02 N·m. Sets the blend with the
    /// deflection-based estimate.
    pub current_torque_sigma: Torque,
}

impl SensorCal {
    /// The defaults above.
    pub const DEFAULT: SensorCal = SensorCal {
        pot_center: 512,
        encoder_zero: 0,
        current_torque_sigma: Torque::from_fixed(I32F32::lit("0.02")),
    };
}

impl Default for SensorCal {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// Everything the controller needs to know about the actuator and the task. (Not
/// `defmt::Format`: log the fields you need, as raw bits.)
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Config {
    /// The clutch setting.
    pub clutch: ClutchSetting,
    /// Beam theory for k(L) and L(k).
    pub beam_model: BeamModel,
    /// Link inertia about the output axis, kg·mm² (1e-3 kg·m² = 1000).
    pub link_inertia: Inertia,
    /// Motor and gearbox.
    pub motor: MotorParams,
    /// Live limits.
    pub limits: Limits,
    /// Gain schedule overrides.
    pub gains: GainOverride,
    /// Sensor calibration.
    pub sensors: SensorCal,
}

impl Config {
    /// Paper preset at clutch length `len`: E–B beams, J_link = 1e-3 kg·m², AX-12A motor,
    /// default limits, scheduled gains.
    #[must_use]
    pub const fn paper(len: Length) -> Config {
        Config {
            clutch: ClutchSetting::Length(len),
            beam_model: BeamModel::EulerBernoulli,
            link_inertia: Inertia::from_int(1000),
            motor: MotorParams::AX12A,
            limits: Limits::DEFAULT,
            gains: GainOverride {
                bandwidth: None,
                gains: None,
            },
            sensors: SensorCal::DEFAULT,
        }
    }
}

/// Bandwidth schedule: ω_c = min(`BW_MAX`, ω_a / `BW_RATIO`), ω_a = √(k/J_link).
pub const BW_RATIO: i32 = 5;
/// Upper bound of the scheduled bandwidth, rad/s (encoder quantisation and duty headroom).
pub const BW_MAX: i32 = 60;
/// Derivative filter: time constant τ_f = 1/(`DERIV_FILTER_N`·ω_c).
pub const DERIV_FILTER_N: i32 = 4;
/// Fraction of the current-limited deceleration k_t·i_lim/J the braking governor counts
/// on (the rest covers an assisting load and friction).
pub const BRAKE_FRACTION: I32F32 = I32F32::lit("0.5");
/// Torque width over which the free-play compensation switches sides, N·m (≈ the gear
/// train's dry friction).
pub const FREE_PLAY_SWITCH_NM: I32F32 = I32F32::lit("0.1");

/// The per-tick constants of one configuration (all divisions done).
///
/// Signal formats: Q16 `i32` (see [`super::gain`]); duty in ‰, angles in rad, velocities
/// in rad/s, accelerations in rad/s², currents in A, torques in N·m.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Schedule {
    pub(crate) setting: Setting,
    /// k, N·m/rad (I64F64 for reporting).
    pub(crate) stiffness: Stiffness,
    /// ω_c, rad/s.
    pub(crate) bandwidth: Frequency,
    /// The PID gains in use.
    pub(crate) gains: PidGains,
    pub(crate) kp: Gain,
    /// Ki·dt, ‰/rad per tick (applied wide: Q32 integrator).
    pub(crate) ki_dt: Gain,
    /// 2·a_b, a_b = `BRAKE_FRACTION`·k_t·i_lim/J the deceleration the braking governor
    /// counts on, rad/s² (applied wide).
    pub(crate) two_a_brake: Gain,
    /// Gear speed below which the braking governor stays off, rad/s Q16 (0.5 rad/s).
    pub(crate) brake_min_w_q16: i32,
    /// Integration band: |e| below max_duty/K_p (where the P term alone does not
    /// saturate), rad Q16.
    pub(crate) int_band_q16: i32,
    /// Kp·dt, ‰ per rad/s of gear velocity per tick (gear hold inside the target count).
    pub(crate) kp_dt: Gain,
    /// Dead band of the gear velocity for the gear hold, rad/s Q16 (1.5 ADC counts).
    pub(crate) w_deadband_q16: i32,
    pub(crate) kd: Gain,
    /// Derivative filter coefficient α = dt/(τ_f + dt), Q16.
    pub(crate) alpha: Gain,
    /// Feed-forward ‰ per rad/s of ṙ: (1000/V)·(k_e + R·b_v/k_t).
    pub(crate) ff_vel: Gain,
    /// Feed-forward ‰ per rad/s² of r̈: (1000/V)·R·J/k_t.
    pub(crate) ff_acc: Gain,
    /// Free-play/compliance feed-forward ‰ per rad of deflection change per tick:
    /// (1000/V)·k_e·1000.
    pub(crate) ff_defl: Gain,
    /// J_link, N·m per rad/s² (reference torque on the link).
    pub(crate) j_link: Gain,
    /// 1/k, rad per N·m.
    pub(crate) inv_k: Gain,
    /// k, N·m per rad.
    pub(crate) k: Gain,
    /// φ_b, rad, Q16.
    pub(crate) free_play_q16: i32,
    /// φ_b / τ_switch, rad per N·m (free-play compensation slope).
    pub(crate) fp_slope: Gain,
    /// Load torque held by the integrator, N·m per ‰: (V/1000)·k_t/R.
    pub(crate) torque_per_duty: Gain,
    /// ‰ per A of current: (1000/V)·R.
    pub(crate) duty_per_amp: Gain,
    /// Back-EMF observer: ω_g = duty·w_per_duty − (adc − mid)·w_per_count (rad/s).
    pub(crate) w_per_duty_q32: i64,
    pub(crate) w_per_count_q32: i64,
    /// ‰ per rad/s of gear velocity (back-EMF): (1000/V)·k_e.
    pub(crate) duty_per_w: Gain,
    /// Torque estimate: k_t (N·m/A), J_g·1000 (N·m per rad/s per tick), b_v.
    pub(crate) kt: Gain,
    pub(crate) jg_fs: Gain,
    pub(crate) bv: Gain,
    /// Deflection weight of the torque blend w = σ_i²/(σ_i² + σ_d²), Q16 (0 … 1).
    pub(crate) w_defl: Gain,
    /// Current limit (A, Q16) and whether it comes from the beam capacity.
    pub(crate) i_lim_q16: i32,
    pub(crate) i_lim_from_beams: bool,
    /// Coupling torque limit τ_lim = margin·τ_cap (N·m, Q16).
    pub(crate) tau_lim_q16: i32,
    /// Duty limit, ‰ Q16.
    pub(crate) duty_lim_q16: i32,
    pub(crate) pot_center: i32,
    pub(crate) encoder_zero: i32,
}

fn f(v: I32F32) -> I64F64 {
    I64F64::from_num(v)
}

fn mul(a: I64F64, b: I64F64) -> Result<I64F64, ControlError> {
    a.checked_mul(b).ok_or(ControlError::Overflow)
}

fn div(a: I64F64, b: I64F64) -> Result<I64F64, ControlError> {
    a.checked_div(b).ok_or(ControlError::Overflow)
}

fn add(a: I64F64, b: I64F64) -> Result<I64F64, ControlError> {
    a.checked_add(b).ok_or(ControlError::Overflow)
}

fn sub(a: I64F64, b: I64F64) -> Result<I64F64, ControlError> {
    a.checked_sub(b).ok_or(ControlError::Overflow)
}

fn q32(v: I64F64) -> Result<i64, ControlError> {
    i64::try_from(v.to_bits() >> 32).map_err(|_| ControlError::Overflow)
}

fn in_range(v: I32F32, lo: I32F32, hi: I32F32) -> bool {
    v >= lo && v <= hi
}

fn gain(v: I64F64) -> Result<Gain, ControlError> {
    Gain::new(v).ok_or(ControlError::Overflow)
}

fn q16(v: I64F64) -> Result<i32, ControlError> {
    i32::try_from(v.to_bits() >> 48).map_err(|_| ControlError::Overflow)
}

impl Schedule {
    /// Validates `cfg` for `design` and computes the schedule.
    ///
    /// # Errors
    /// See [`ControlError`].
    pub fn new(design: &Design, cfg: &Config) -> Result<Schedule, ControlError> {
        use ControlError as E;
        // --- validation ---
        let m = &cfg.motor;
        let one = I32F32::ONE;
        if !(in_range(m.supply_v, one, I32F32::from_num(100))
            && in_range(
                m.resistance_ohm,
                const { I32F32::lit("0.1") },
                I32F32::from_num(1000),
            )
            && in_range(
                m.torque_constant,
                const { I32F32::lit("0.01") },
                I32F32::from_num(100),
            )
            && in_range(
                m.back_emf,
                const { I32F32::lit("0.01") },
                I32F32::from_num(100),
            )
            && in_range(m.rotor_inertia.get(), one, I32F32::from_num(1_000_000))
            && in_range(m.viscous, I32F32::ZERO, I32F32::from_num(10)))
        {
            return Err(E::MotorOutOfRange);
        }
        let lim = &cfg.limits;
        if !(in_range(lim.torque_margin.get(), I32F32::DELTA, one)
            && in_range(lim.max_current_a, I32F32::DELTA, I32F32::from_num(10))
            && lim.max_motor_torque.to_bits() > 0
            && (1..=1000).contains(&lim.max_duty))
        {
            return Err(E::LimitOutOfRange);
        }
        let ji = cfg.link_inertia.get();
        if !in_range(
            ji,
            I32F32::from_num(MIN_INERTIA),
            I32F32::from_num(MAX_INERTIA),
        ) {
            return Err(E::InertiaOutOfRange);
        }
        let s = &cfg.sensors;
        if i32::from(s.pot_center) >= POT_COUNTS
            || i32::from(s.encoder_zero) >= ENCODER_COUNTS
            || s.current_torque_sigma.to_bits() <= 0
        {
            return Err(E::SensorOutOfRange);
        }
        if let Some(bw) = cfg.gains.bandwidth {
            if bw.to_bits() <= 0 || bw > Frequency::from_int(500) {
                return Err(E::GainOutOfRange);
            }
        }
        if let Some(g) = cfg.gains.gains {
            if !(in_range(g.kp, I32F32::ZERO, I32F32::from_num(1_000_000))
                && in_range(g.ki, I32F32::ZERO, I32F32::from_num(10_000_000))
                && in_range(g.kd, I32F32::ZERO, I32F32::from_num(10_000)))
            {
                return Err(E::GainOutOfRange);
            }
        }
        let len = match cfg.clutch {
            ClutchSetting::Length(l) => l,
            ClutchSetting::Stiffness(k) => cfg.beam_model.clutch_length(design, k)?,
        };
        let (l_min, l_max) = design.adjustable_range();
        if len < l_min || len > l_max {
            return Err(E::ClutchOutOfRange);
        }
        let setting = Setting::new(design, len, cfg.beam_model)?;
        let stiffness = setting.stiffness();
        if stiffness > Stiffness::from_int(MAX_STIFFNESS) {
            return Err(E::StiffnessOutOfRange);
        }

        // --- physical constants (SI, I64F64; every operation checked) ---
        let k = stiffness.get();
        let v_s = f(m.supply_v);
        let r = f(m.resistance_ohm);
        let kt = f(m.torque_constant);
        let ke = f(m.back_emf);
        let bv = f(m.viscous);
        let mega = I64F64::from_num(1_000_000);
        let three = I64F64::from_num(3);
        let j_g = div(f(m.rotor_inertia.get()), mega)?; // kg·m²
        let j_l = div(f(ji), mega)?;
        let j = add(j_g, j_l)?;
        let dpv = div(I64F64::from_num(1000), v_s)?; // ‰ per V
        let c = div(kt, r)?; // N·m per V at stall
        let b_m = add(div(mul(kt, ke)?, r)?, bv)?; // back-EMF + viscous damping, N·m·s/rad

        // --- bandwidth schedule ---
        let w_a = natural_frequency(stiffness, cfg.link_inertia)?; // √(k/J_link)
        let bandwidth = match cfg.gains.bandwidth {
            Some(bw) => bw,
            None => {
                let by_k = Frequency::from_bits(w_a.to_bits() / i64::from(BW_RATIO));
                by_k.min(Frequency::from_int(BW_MAX))
            }
        };
        let w = f(bandwidth.get());

        // --- PID by pole placement: (s + ω)³ on J·s³ + b_m·s² … (module docs) ---
        let gains = match cfg.gains.gains {
            Some(g) => g,
            None => {
                let to = |v: I64F64| I32F32::checked_from_num(v).ok_or(E::GainOutOfRange);
                let j_c = mul(div(j, c)?, dpv)?; // ‰ per (N·m/(kg·m²))
                let kp = mul(mul(mul(three, w)?, w)?, j_c)?;
                let kd_raw = sub(mul(mul(three, w)?, j)?, b_m)?;
                let kd = if kd_raw > I64F64::ZERO {
                    mul(div(kd_raw, c)?, dpv)?
                } else {
                    I64F64::ZERO
                };
                let ki = mul(mul(mul(w, w)?, w)?, j_c)?;
                PidGains {
                    kp: to(kp)?,
                    ki: to(ki)?,
                    kd: to(kd)?,
                }
            }
        };
        let dt = I64F64::ONE / 1000;
        let tau_f = div(I64F64::ONE, mul(I64F64::from_num(DERIV_FILTER_N), w)?)?;
        let alpha = div(dt, add(tau_f, dt)?)?;

        // --- limits ---
        // Coupling torque limit, and the motor torque that keeps the beams below it even
        // with the two-mass overshoot: |τ_s,peak| ≤ max(1, (3J_l − J_g)/(J_g + J_l))·τ_m.
        let tau_lim = mul(
            f(setting.torque_capacity().get()),
            f(lim.torque_margin.get()),
        )?;
        let amp = div(sub(mul(three, j_l)?, j_g)?, j)?.max(I64F64::ONE);
        let i_beams = div(div(tau_lim, amp)?, kt)?;
        let i_motor = f(lim.max_current_a).min(div(f(lim.max_motor_torque.get()), kt)?);
        let (i_lim, i_lim_from_beams) = if i_beams < i_motor {
            (i_beams, true)
        } else {
            (i_motor, false)
        };

        // --- torque-estimate blend by resolution ---
        // Deflection from the pot: one count is q_pot = 300°/1024 of gear angle, so the
        // deflection-based torque has σ_d = k·q_pot/√12; the current-based one σ_i (config).
        let q_pot = I64F64::PI * 5 / 3 / i128::from(POT_COUNTS); // 300° = 5π/3 rad over 1024
        let sd = mul(k, q_pot)?;
        let sd2 = mul(sd, sd)? / 12;
        let si = f(s.current_torque_sigma.get());
        let si2 = mul(si, si)?;
        let w_defl = div(si2, add(si2, sd2)?)?;

        let free_play = f(setting.free_play().get());
        let fs = I64F64::from_num(1000);
        Ok(Schedule {
            setting,
            stiffness,
            bandwidth,
            gains,
            kp: gain(f(gains.kp))?,
            ki_dt: gain(mul(f(gains.ki), dt)?)?,
            kp_dt: gain(mul(f(gains.kp), dt)?)?,
            two_a_brake: gain(div(
                mul(
                    mul(f(BRAKE_FRACTION), kt)?,
                    mul(i_lim, I64F64::from_num(2))?,
                )?,
                j,
            )?)?,
            brake_min_w_q16: Q16_ONE / 2,
            int_band_q16: if gains.kp > I32F32::ZERO {
                q16(div(I64F64::from_num(lim.max_duty), f(gains.kp))?)?
            } else {
                i32::MAX
            },
            w_deadband_q16: q16(div(
                mul(r, I64F64::from_num(3))?,
                mul(ke, I64F64::from_num(2 * ADC_COUNTS_PER_A))?,
            )?)?,
            kd: gain(f(gains.kd))?,
            alpha: gain(alpha)?,
            ff_vel: gain(mul(dpv, add(ke, div(mul(r, bv)?, kt)?)?)?)?,
            ff_acc: gain(div(mul(mul(dpv, r)?, j)?, kt)?)?,
            ff_defl: gain(mul(mul(dpv, ke)?, fs)?)?,
            j_link: gain(j_l)?,
            inv_k: gain(div(I64F64::ONE, k)?)?,
            k: gain(k)?,
            free_play_q16: q16(free_play)?,
            fp_slope: gain(div(free_play, f(FREE_PLAY_SWITCH_NM))?)?,
            torque_per_duty: gain(div(c, dpv)?)?,
            duty_per_amp: gain(mul(dpv, r)?)?,
            w_per_duty_q32: q32(div(div(v_s, fs)?, ke)?)?,
            w_per_count_q32: q32(div(div(r, ke)?, I64F64::from_num(ADC_COUNTS_PER_A))?)?,
            duty_per_w: gain(mul(dpv, ke)?)?,
            kt: gain(kt)?,
            jg_fs: gain(mul(j_g, fs)?)?,
            bv: gain(bv)?,
            w_defl: gain(w_defl)?,
            i_lim_q16: q16(i_lim)?,
            i_lim_from_beams,
            tau_lim_q16: q16(tau_lim)?,
            duty_lim_q16: i32::from(lim.max_duty) * Q16_ONE,
            pot_center: i32::from(s.pot_center),
            encoder_zero: i32::from(s.encoder_zero),
        })
    }

    /// The clutch setting in use.
    #[must_use]
    pub const fn setting(&self) -> &Setting {
        &self.setting
    }

    /// The joint stiffness k.
    #[must_use]
    pub const fn stiffness(&self) -> Stiffness {
        self.stiffness
    }

    /// The closed-loop bandwidth ω_c.
    #[must_use]
    pub const fn bandwidth(&self) -> Frequency {
        self.bandwidth
    }

    /// The PID gains in use (scheduled or overridden).
    #[must_use]
    pub const fn gains(&self) -> PidGains {
        self.gains
    }

    /// The coupling torque limit τ_lim = margin·τ_cap(L).
    #[must_use]
    pub fn torque_limit(&self) -> Torque {
        Torque::from_bits(i64::from(self.tau_lim_q16) << 16)
    }

    /// The motor current limit, A, and whether the beams (not the motor) set it.
    #[must_use]
    pub fn current_limit(&self) -> (I32F32, bool) {
        (
            I32F32::from_bits(i64::from(self.i_lim_q16) << 16),
            self.i_lim_from_beams,
        )
    }

    /// Weight of the deflection-based torque estimate in the blend (0 … 1).
    #[must_use]
    pub fn deflection_weight(&self) -> I32F32 {
        I32F32::from_bits(i64::from(self.w_defl.apply(Q16_ONE)) << 16)
    }

    /// The output free play φ_b the compensation uses.
    #[must_use]
    pub const fn free_play(&self) -> Angle {
        self.setting.free_play()
    }
}
