//! The gain schedule: the per-tick constants derived from a validated configuration
//! (docs/design.md §11; the summary is in the [`crate::control`] docs).
//!
//! Everything here runs when the configuration changes (divisions, square roots and
//! 128-bit arithmetic are fine); [`Schedule`] holds the per-tick constants as [`Gain`]s.

use fixed::types::{I32F32, I64F64};

use super::config::{Config, Limits, PidGains};
use super::dash::{self, DashGains};
use super::error::ControlError;
use super::gain::{sat_i32, scale_q16, sqrt_ratio_q16, Gain, Q16_ONE};
use super::move_duration;
use super::shaper::SHAPER_LEN;
use super::validate::validate;
use super::wide::{add, div, mul, sub, to_gain, to_q16, to_q32, wide};
use crate::beam::Setting;
use crate::design::Design;
use crate::dynamics::natural_frequency;
use crate::sensors::{ADC_COUNTS_PER_A, POT_COUNTS, POT_SPAN_DEG};
use crate::units::{Angle, Frequency, Inertia, Length, Stiffness, Torque};

/// Bandwidth schedule: ω_c = min(`BW_MAX`, ω_a / `BW_RATIO`), ω_a = √(k/J_link).
pub const BW_RATIO: i32 = 5;
/// Upper bound of the scheduled bandwidth, rad/s (encoder quantisation and duty headroom).
pub const BW_MAX: i32 = 60;
/// Derivative filter: time constant τ_f = 1/(`DERIV_FILTER_N`·ω_c).
pub const DERIV_FILTER_N: i32 = 4;
/// Fraction of the current-limited deceleration k_t·i_lim/J the braking governor counts
/// on (the rest covers an assisting load and friction).
pub const BRAKE_FRACTION: I32F32 = I32F32::lit("0.5");
/// Torque width over which the free-play compensation switches sides, N·m
/// (docs/design.md §11 step 7: measured against 0.1, 2 and 5 N·m).
pub const FREE_PLAY_SWITCH_NM: I32F32 = I32F32::lit("1");
/// Coupling torque beyond which the beams count as carrying torque on one side, N·m.
pub const CONTACT_TORQUE_NM: I32F32 = I32F32::lit("0.05");
/// Error of the current-based torque estimate k_t·i − J_g·ω̇_g as a fraction of k_t·|i|:
/// k_t ±10 % and J_g ±25 % (docs/design.md §9) while the gear alone takes the current.
/// Measured (docs/design.md §11, "Free-play impacts"): from 0.3 up a real braking contact
/// hides below the bound and a heavy link's raw step loses its braking current.
pub const CONTACT_CURRENT_TOLERANCE: I32F32 = I32F32::lit("0.25");
/// Armature-resistance error the back-EMF observer's dead bands allow for, as a fraction
/// of the configured R: copper from cold to hot (+40 %, docs/design.md §9). With R off by ΔR
/// the observer reads ω_g + ΔR·i/k_e.
pub const RESISTANCE_TOLERANCE: I32F32 = I32F32::lit("0.4");
/// Supply-voltage error the gear hold's dead band allows for, as a fraction of the
/// configured supply: a 12 V supply that sags to 10.5 V (docs/design.md §9). With V_s off by
/// ΔV the back-EMF observer reads ω_g + ΔV·duty/k_e. Not in the braking governor's band:
/// measured, that let a heavy link's hold limit-cycle (docs/design.md §11, "The actuator is
/// not the model").
pub const SUPPLY_TOLERANCE: I32F32 = I32F32::lit("0.125");
/// Lowest armature resistance the current window allows for, as a fraction of the
/// configured R: copper colder than configured (×0.8, docs/design.md §9). The window about
/// the back-EMF is (1000/V_s)·R·i wide in duty, and the current it lets through is that
/// voltage over the true R: with i at most 0.8 of the motor's current rating, a cold motor
/// stays within the rating (and below the supervisor's over-current trip).
pub const RESISTANCE_LOW: I32F32 = I32F32::lit("0.8");
/// Current-sense offset the observer's dead bands allow for, ADC counts (what
/// calibration leaves, docs/design.md §9); plus 1.5 counts of resolution.
pub const CURRENT_OFFSET_TOLERANCE_COUNTS: i32 = 20;
/// Current-sense gain error a plan's load allows for, as the divisor of the reading:
/// 1/20 = ±5 % (docs/design.md §9).
pub const CURRENT_GAIN_TOLERANCE_DIV: i32 = 20;
/// Held in the reference's count, the derivative term is 0 while the filtered gear
/// velocity is below the observer's dead band shifted right by this (an eighth: 11 mrad/s,
/// about 4σ of a 2-count current sense's filtered noise; a quarter left a nominal step's
/// slow end undamped, docs/design.md §11, "Current-sense noise at rest").
pub const HELD_DAMPING_DEADBAND_SHIFT: u32 = 3;
/// Fraction of the elastic impact speed (`impact_speed`) the free-play impact limit lets
/// the gear reach: the observer and the link velocity lag, and the gear is still driven
/// while the beams take up the impact. Measured on the acceptance grid (250 nominal
/// cases): 1.0 leaves 17 runs above σ_allow, 0.6 leaves 6; since, on 97 off-nominal seeds
/// (docs/design.md §11, "Free-play impacts"), 0.6 / 0.55 / 0.5 left 35 / 26 / 16 runs
/// above σ_allow, but at 0.5 a warm motor's hold at 1 mm under load ended buzzing.
pub const IMPACT_SPEED_FRACTION: I32F32 = I32F32::lit("0.55");
/// Beyond the impact speed the duty is held at the back-EMF of a gear speed this far from
/// the gear's own towards the link's, as a right shift of what is left: 2, three quarters
/// of the way (docs/design.md §11, "Free-play impacts"). Measured on 2 × 30 seeds: the
/// gear's own speed (no current, the gear coasts) left 3 nominal and 121 off-nominal runs
/// of 15 000 above σ_allow; half the way 0 and 98, three quarters 0 and 81, all the way
/// 0 and 84, each costing the off-nominal grid more overshoot.
pub const IMPACT_MATCH_SHIFT: u32 = 2;

/// Corner of the torque feedback's high-pass, in ω_c: the P term of a loaded link acts on
/// the link error less the beams' torque error above it, (τ̂ − τ_ref)/k (docs/design.md
/// §11, step 8). Measured on the acceptance grid's six extra seeds: ½, ⅔, 1 and 2 within a
/// few runs of each other (2 had the fewest above σ_allow); without the high-pass the moves
/// of heavy links overshot more.
pub const TORQUE_FEEDBACK_CORNER: I32F32 = I32F32::lit("2");

/// Crossover of the gear-angle complementary filter: ω_o = ω_c / `OBSERVER_RATIO`.
pub const OBSERVER_RATIO: i32 = 3;
/// The same crossover while a min-jerk move or a sine runs, ω_c / `MOVE_OBSERVER_RATIO`,
/// with the bias integrator held: there the pull is mostly the observer's scale error
/// (k_e, supply) times the speed, not a bias (docs/design.md §11, "The gear-angle filter
/// during a move").
pub const MOVE_OBSERVER_RATIO: i32 = 1;

/// Half-width of the rest hold without load, in free plays φ_b: within it of a stationary
/// reference an unloaded link's gear is held still (docs/design.md §11, step 8).
pub const REST_ZONE_FREE_PLAYS: I32F32 = I32F32::lit("1.5");
/// Below this load (the torque the integrator holds), N·m, the rest hold may start.
/// Measured on the grid (seed 1, 250 + 250): with `FLOAT_LOAD_NM` (0.05) the hold also
/// caught lightly loaded links off target (steady-state violations 67 → 84 nominal),
/// 0.0125 keeps that to 74 with the same quiet duty; 0.00625 gains little more.
pub const REST_LOAD_NM: I32F32 = I32F32::lit("0.0125");
/// The rest hold also needs |τ̂| below this, N·m: after a raw step the integrator may
/// have unwound although the link is loaded. Above the free-play impacts of an unloaded
/// link (τ̂ up to ≈ 0.15 N·m on the grid).
pub const REST_TORQUE_NM: I32F32 = I32F32::lit("0.2");

/// Above this load (the torque the integrator holds), N·m, a still link off a stationary
/// reference's count is taken to be pressed on a wall and where its count's centre says,
/// not at the count's edge nearest the reference (docs/design.md §11, "A light load one
/// count off"). Twice `REST_LOAD_NM`: measured on the grid (seeds 101…130), at
/// `REST_LOAD_NM` the off-nominal links without load whose integrator holds the
/// observer's bias were taken as pressed (rest duty span violations 257 → 279), at
/// 0.0375 N·m fewer light loads came within a count.
pub const PRESSED_LOAD_NM: I32F32 = I32F32::lit("0.025");

/// Below this load (the torque the integrator holds), N·m, the link is taken to float in
/// the free play and the position loop acts on the gear estimate.
pub const FLOAT_LOAD_NM: I32F32 = I32F32::lit("0.05");

/// The gear velocity reference, rad/s, at which the gear's Coulomb friction is fed
/// forward in full (in proportion below: no sign flips at standstill).
pub const COULOMB_RAMP_RAD_S: I32F32 = I32F32::lit("0.1");

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
    /// Dead band of the gear velocity for the gear hold at zero current, rad/s Q16: the
    /// observer's resolution (1.5 ADC counts) and its bias from a current-sense offset
    /// (`CURRENT_OFFSET_TOLERANCE_COUNTS`), R·(1.5 + 20)/(1024·k_e).
    pub(crate) w_deadband_q16: i32,
    /// Growth of that dead band with |i|: the observer's bias from a resistance error,
    /// `RESISTANCE_TOLERANCE`·R/k_e, rad/s per A.
    pub(crate) w_bias_per_amp: Gain,
    /// Growth of the gear hold's dead band with |duty|: the observer's bias from a supply
    /// error, `SUPPLY_TOLERANCE`·V_s/(1000·k_e) rad/s per ‰; integer ‰ in, rad/s Q16 out.
    pub(crate) w_bias_per_duty: Gain,
    /// Gear speed relative to the link above which the current may not drive the gear
    /// further across the free play (impact torque τ_lim, see `impact_speed`), rad/s Q16;
    /// a command scales it for the drive it met (`Dash::impact_q16`, `MoveDrive::impact_q16`).
    pub(crate) impact_speed_q16: i32,
    /// The least the impact speed gets for the drive a command met (the factor's floor √⅓,
    /// `gain::sqrt_ratio_q16`), rad/s Q16: the per-tick test's.
    pub(crate) impact_speed_low_q16: i32,
    /// |τ̂| above which the beams are taken to be in contact on the side of τ̂'s sign,
    /// N·m Q16 (`CONTACT_TORQUE_NM`).
    pub(crate) contact_torque_q16: i32,
    /// Growth of that bound with |i|: `CONTACT_CURRENT_TOLERANCE`·k_t, N·m per A.
    pub(crate) contact_per_amp: Gain,
    pub(crate) kd: Gain,
    /// dt = 1 ms (rad/s → rad per tick, applied wide) and the complementary filter's
    /// pull 2·ω_o·dt per tick.
    pub(crate) dt: Gain,
    /// A raw step's shaper delay Δ = π/ω_a, ticks, where the beams set the bandwidth and
    /// Δ exceeds the motor's mechanical time constant; 0 elsewhere ([`super::shaper`]).
    pub(crate) shaper_ticks: u8,
    pub(crate) obs_beta: Gain,
    /// The bias integrator's gain ω_o²·dt (1/s per tick).
    pub(crate) obs_beta2: Gain,
    /// The pull during a min-jerk move or a sine, 2·ω_c·dt / `MOVE_OBSERVER_RATIO` per tick.
    pub(crate) obs_beta_move: Gain,
    /// The torque feedback's low-pass, `TORQUE_FEEDBACK_CORNER`·ω_c·dt per tick.
    pub(crate) torque_lp_beta: Gain,
    /// Half-width of the rest hold, `REST_ZONE_FREE_PLAYS`·φ_b, rad Q16, and the duty of
    /// `REST_LOAD_NM`, ‰ Q16.
    pub(crate) rest_zone_q16: i32,
    pub(crate) rest_load_q16: i32,
    /// `REST_TORQUE_NM`, N·m Q16.
    pub(crate) rest_torque_q16: i32,
    /// Duty of `PRESSED_LOAD_NM`, ‰ Q16.
    pub(crate) pressed_load_q16: i32,
    /// Duty of `FLOAT_LOAD_NM`, ‰ Q16.
    pub(crate) float_load_q16: i32,
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
    /// `COULOMB_RAMP_RAD_S`, rad/s Q16.
    pub(crate) coulomb_ramp_q16: i32,
    /// The duty of the gear's Coulomb friction τ_c, (1000/V_s)·(R/k_t)·τ_c (at most the
    /// duty limit), per rad/s of the gear velocity reference up to the ramp, ‰·s/rad Q16.
    pub(crate) coulomb_per_w_q16: i32,
    /// The configured Coulomb friction's whole duty, ‰ Q16 (`coulomb_per_w_q16` at
    /// `COULOMB_RAMP_RAD_S`).
    pub(crate) coulomb_duty_q16: i32,
    /// The hysteresis coefficient c (§2.1), per rad, Q16: half the band of deflections
    /// that carry one torque τ is c·(τ/k)².
    pub(crate) hyst_c_q16: i32,
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
    /// Back-EMF observer: ω_g = duty·w_per_duty − (adc − mid)·w_per_count (rad/s), Q32;
    /// the validated motor ranges bound them to [0, 2³⁶) and [0, 2³⁹), w_per_count to
    /// [0, 2⁴⁰) once a raw step's estimate is in (the controller's products rely on it).
    pub(crate) w_per_duty_q32: i64,
    pub(crate) w_per_count_q32: i64,
    /// w_per_count as configured (`w_per_count_q32` may follow a raw step's duty jump,
    /// [`super::duty_jump`]), and the gear's speed change in one tick per count of added
    /// current, k_t·dt/(J_g·counts per A), rad/s Q32.
    pub(crate) w_per_count_cfg_q32: i64,
    pub(crate) w_step_per_count_q32: i64,
    /// ‰ per rad/s of gear velocity (back-EMF): (1000/V)·k_e.
    pub(crate) duty_per_w: Gain,
    /// Torque estimate: k_t (N·m/A), J_g/dt (N·m per rad/s of gear velocity change in
    /// one tick), b_v (N·m per rad/s).
    pub(crate) kt: Gain,
    pub(crate) gear_inertia_per_dt: Gain,
    pub(crate) bv: Gain,
    /// Deflection weight of the torque blend w = σ_i²/(σ_i² + σ_d²), Q16 (0 … 1).
    pub(crate) w_defl: Gain,
    /// `w_defl` applied to 1, Q16: 0 when the blend ignores the pot (derived once here,
    /// not per tick).
    pub(crate) w_defl_q16: i32,
    /// Current limit (A, Q16) and whether it comes from the beam capacity.
    pub(crate) i_lim_q16: i32,
    /// The current limit in duty, ‰ Q16: `duty_per_amp` applied to `i_lim_q16` (derived
    /// once here, not per tick).
    pub(crate) i_lim_duty_q16: i32,
    /// Half-width of the current window about the back-EMF in force, ‰ Q16: the
    /// configured one, widened for the warmer motor the observer's resistance estimate
    /// reads within 5/4 of the load the integrator holds (`Controller::track_speed`, design
    /// §11, "Runs that ended far off").
    pub(crate) i_win_duty_q16: i32,
    /// The window as configured, ‰ Q16: the current limit, at most `RESISTANCE_LOW` × the
    /// motor's current rating, in duty.
    pub(crate) i_win_cfg_duty_q16: i32,
    /// The configured window times the estimate's resistance over the configured one
    /// (never below the configured window), ‰ Q16.
    pub(crate) i_win_est_duty_q16: i32,
    pub(crate) i_lim_from_beams: bool,
    /// Coupling torque limit τ_lim = margin·τ_cap(L + ΔL) (N·m, Q16).
    pub(crate) tau_lim_q16: i32,
    /// The clutch tolerance ΔL and the weakest capacity it allows, τ_cap(L)·L/(L + ΔL).
    clutch_tolerance: Length,
    weak_capacity: Torque,
    /// Duty limit, ‰ Q16.
    pub(crate) duty_lim_q16: i32,
    /// Pot reading at gear angle 0 and encoder reading at link angle 0, counts.
    pub(crate) pot_center: i32,
    pub(crate) encoder_zero: u16,
    /// The raw step's profile constants.
    pub(crate) dash: DashGains,
    /// `MOVE_CURRENT_FRACTION`/ff_acc, rad/s² per ‰ of current headroom: a move's peak
    /// acceleration ([`super::move_duration`]).
    pub(crate) move_accel_per_duty: Gain,
}

/// Control ticks per second (the loop runs at 1 kHz).
pub(crate) const TICKS_PER_S: i32 = 1000;

/// The motor, gear train and link referred to the gearbox output, SI, I64F64.
struct Drive {
    /// H-bridge supply V_s, V.
    supply: I64F64,
    /// Armature resistance R, Ω.
    resistance: I64F64,
    /// Torque constant k_t, N·m/A.
    kt: I64F64,
    /// Back-EMF constant k_e, V·s/rad.
    ke: I64F64,
    /// Gear viscous friction b_v, N·m·s/rad.
    bv: I64F64,
    /// Gear inertia J_g and link inertia J_l, kg·m².
    j_gear: I64F64,
    j_link: I64F64,
    /// J = J_g + J_l, kg·m².
    j: I64F64,
    /// Duty per volt, ‰/V: 1000/V_s.
    duty_per_volt: I64F64,
    /// Stall torque per volt c = k_t/R, N·m/V.
    torque_per_volt: I64F64,
    /// Damping b_m = k_t·k_e/R + b_v (back-EMF and viscous), N·m·s/rad.
    damping: I64F64,
}

impl Drive {
    fn new(cfg: &Config) -> Result<Drive, ControlError> {
        let m = &cfg.motor;
        let mega = I64F64::from_num(1_000_000);
        let resistance = wide(m.resistance_ohm);
        let kt = wide(m.torque_constant);
        let ke = wide(m.back_emf);
        let bv = wide(m.viscous);
        let j_gear = div(wide(m.rotor_inertia.get()), mega)?; // kg·mm² → kg·m²
        let j_link = div(wide(cfg.link_inertia.get()), mega)?;
        let supply = wide(m.supply_v);
        Ok(Drive {
            supply,
            resistance,
            kt,
            ke,
            bv,
            j_gear,
            j_link,
            j: add(j_gear, j_link)?,
            duty_per_volt: div(I64F64::from_num(1000), supply)?,
            torque_per_volt: div(kt, resistance)?,
            damping: add(div(mul(kt, ke)?, resistance)?, bv)?,
        })
    }
}

/// ω_c: the override, or min(`BW_MAX`, ω_a/`BW_RATIO`), ω_a = √(k/J_link).
fn bandwidth(cfg: &Config, stiffness: Stiffness) -> Result<Frequency, ControlError> {
    let w_a = natural_frequency(stiffness, cfg.link_inertia)?;
    Ok(match cfg.gains.bandwidth {
        Some(bw) => bw,
        None => {
            let by_k = Frequency::from_bits(w_a.to_bits() / i64::from(BW_RATIO));
            by_k.min(Frequency::from_int(BW_MAX))
        }
    })
}

/// The raw step's shaper delay ([`super::shaper`]): round(π/ω_a) in ticks where the
/// beams set the bandwidth (ω_a < `BW_RATIO`·`BW_MAX`: the loop cannot damp the ringing)
/// and half a ringing period is longer than the motor's mechanical time constant
/// τ_m = J·R/(k_t·k_e) (a faster ringing the motor's own lag already smooths out of the
/// profile's torque steps), at most `SHAPER_LEN` − 1; 0 (no shaper) elsewhere.
fn shaper_ticks(cfg: &Config, p: &Drive, stiffness: Stiffness) -> Result<u8, ControlError> {
    let w_a = natural_frequency(stiffness, cfg.link_inertia)?;
    if w_a >= Frequency::from_int(BW_RATIO * BW_MAX) {
        return Ok(0);
    }
    let half_period = div(I64F64::PI, wide(w_a.get()))?;
    let tau_m = div(mul(p.j, p.resistance)?, mul(p.kt, p.ke)?)?;
    if half_period <= tau_m {
        return Ok(0);
    }
    let ticks = mul(half_period, I64F64::from_num(TICKS_PER_S))?;
    let max = (SHAPER_LEN - 1) as i64;
    Ok(ticks.round().to_num::<i64>().clamp(1, max) as u8)
}

/// PID gains by pole placement: (s + ω_c)³ on J·s³ + (b_m + c·K_d)·s² + c·K_p·s + c·K_i
/// (K_p = 3ω²J/c, K_i = ω³J/c, K_d = max(0, 3ωJ − b_m)/c, times 1000/V_s for ‰).
fn pole_placement(p: &Drive, w: I64F64) -> Result<PidGains, ControlError> {
    let three = I64F64::from_num(3);
    let to = |v: I64F64| I32F32::checked_from_num(v).ok_or(ControlError::GainOutOfRange);
    let j_c = mul(div(p.j, p.torque_per_volt)?, p.duty_per_volt)?; // ‰ per (N·m/(kg·m²))
    let kp = mul(mul(mul(three, w)?, w)?, j_c)?;
    let kd_raw = sub(mul(mul(three, w)?, p.j)?, p.damping)?;
    let kd = if kd_raw > I64F64::ZERO {
        mul(div(kd_raw, p.torque_per_volt)?, p.duty_per_volt)?
    } else {
        I64F64::ZERO
    };
    let ki = mul(mul(mul(w, w)?, w)?, j_c)?;
    Ok(PidGains {
        kp: to(kp)?,
        ki: to(ki)?,
        kd: to(kd)?,
    })
}

/// The weakest capacity the clutch tolerance allows, τ_cap(L)·L/(L + ΔL), N·m: the beams
/// of a clutch up to ΔL longer than configured (τ_cap ∝ 1/L, eq. 2; docs/calibration.md,
/// "The clutch monitor").
fn weak_capacity(setting: &Setting, lim: &Limits) -> Result<I64F64, ControlError> {
    let len = wide(setting.length().get());
    let longer = add(len, wide(lim.clutch_tolerance.get()))?;
    mul(wide(setting.torque_capacity().get()), div(len, longer)?)
}

/// The coupling torque limit τ_lim = margin·τ_cap(L + ΔL), N·m (the weak capacity), the
/// current limit, A, and whether the beams (not the motor) set it: the motor torque that
/// keeps the beams below τ_lim even with the two-mass overshoot,
/// |τ_s,peak| ≤ max(1, (3J_l − J_g)/(J_g + J_l))·τ_m.
fn current_limit(
    p: &Drive,
    cap_weak: I64F64,
    lim: &Limits,
) -> Result<(I64F64, I64F64, bool), ControlError> {
    let tau_lim = mul(cap_weak, wide(lim.torque_margin.get()))?;
    let overshoot = div(sub(mul(I64F64::from_num(3), p.j_link)?, p.j_gear)?, p.j)?.max(I64F64::ONE);
    let i_beams = div(div(tau_lim, overshoot)?, p.kt)?;
    let i_motor = wide(lim.max_current_a).min(div(wide(lim.max_motor_torque.get()), p.kt)?);
    Ok(if i_beams < i_motor {
        (tau_lim, i_beams, true)
    } else {
        (tau_lim, i_motor, false)
    })
}

/// The gear-angle filter's pull per tick, 2·ω_o·dt with ω_o = ω_c / `ratio`.
fn observer_pull(w: I64F64, ratio: i32, dt: I64F64) -> Result<Gain, ControlError> {
    to_gain(mul(div(w, I64F64::from_num(ratio))?, dt)?.saturating_mul(I64F64::from_num(2)))
}

/// The gear's speed relative to the link at which crossing the free play and hitting the
/// link gives an impact torque of τ_lim: two masses closing at v on a spring k meet with
/// a peak torque v·√(k·J_eff), J_eff = J_g·J_l/(J_g + J_l), so v = τ_lim/(J_eff·ω_eff),
/// ω_eff = √(k/J_eff), rad/s.
fn impact_speed(p: &Drive, k: Stiffness, tau_lim: I64F64) -> Result<I64F64, ControlError> {
    let j_eff = div(mul(p.j_gear, p.j_link)?, p.j)?; // kg·m²
    let j_eff_mm2 = mul(j_eff, I64F64::from_num(1_000_000))?;
    let j_eff_inertia = Inertia::from_bits(
        i64::try_from(j_eff_mm2.to_bits() >> 32).map_err(|_| ControlError::Overflow)?,
    );
    let w_eff = wide(natural_frequency(k, j_eff_inertia)?.get());
    div(tau_lim, mul(j_eff, w_eff)?)
}

/// Weight of the deflection-based torque estimate, w = σ_i²/(σ_i² + σ_d²): one pot count
/// q_pot = 300°/1024 of gear angle gives σ_d = k·q_pot/√12; σ_i is configured.
fn deflection_weight(k: I64F64, current_sigma: Torque) -> Result<I64F64, ControlError> {
    let q_pot = I64F64::PI * i128::from(POT_SPAN_DEG) / 180 / i128::from(POT_COUNTS);
    let sd = mul(k, q_pot)?;
    let sd2 = mul(sd, sd)? / 12;
    let si = wide(current_sigma.get());
    let si2 = mul(si, si)?;
    div(si2, add(si2, sd2)?)
}

impl Schedule {
    /// Validates `cfg` for `design` and computes the schedule.
    ///
    /// # Errors
    /// See [`ControlError`].
    pub fn new(design: &Design, cfg: &Config) -> Result<Schedule, ControlError> {
        let setting = validate(design, cfg)?;
        let stiffness = setting.stiffness();
        let p = Drive::new(cfg)?;
        let k = stiffness.get();
        let (r, kt, ke, bv) = (p.resistance, p.kt, p.ke, p.bv);
        let duty_per_volt = p.duty_per_volt;

        let bandwidth = bandwidth(cfg, stiffness)?;
        let w = wide(bandwidth.get());
        let gains = match cfg.gains.gains {
            Some(g) => g,
            None => pole_placement(&p, w)?,
        };
        let ticks_per_s = I64F64::from_num(TICKS_PER_S);
        let w_per_count = to_q32(div(div(r, ke)?, I64F64::from_num(ADC_COUNTS_PER_A))?)?;
        let dt = I64F64::ONE / i128::from(TICKS_PER_S);
        let tau_f = div(I64F64::ONE, mul(I64F64::from_num(DERIV_FILTER_N), w)?)?;
        let alpha = div(dt, add(tau_f, dt)?)?;

        let lim = &cfg.limits;
        let cap_weak = weak_capacity(&setting, lim)?;
        let (tau_lim, i_lim, i_lim_from_beams) = current_limit(&p, cap_weak, lim)?;
        let w_defl = deflection_weight(k, cfg.sensors.current_torque_sigma)?;
        let free_play = wide(setting.free_play().get());
        let w_defl = to_gain(w_defl)?;
        let i_lim_q16 = to_q16(i_lim)?;
        // ‰ of duty per ampere through R (the current limit, the window, R·J/k_t).
        let duty_per_amp_wide = mul(duty_per_volt, r)?;
        let duty_per_amp = to_gain(duty_per_amp_wide)?;
        let i_win = to_q16(mul(
            duty_per_amp_wide,
            i_lim.min(mul(wide(lim.max_current_a), wide(RESISTANCE_LOW))?),
        )?)?;
        let ff_vel = mul(duty_per_volt, add(ke, div(mul(r, bv)?, kt)?)?)?;
        let ff_acc = div(mul(duty_per_amp_wide, p.j)?, kt)?;
        // τ_c → duty as for the loads below: ÷ (k_t/R), × 1000/V_s.
        let coulomb_duty = mul(
            div(wide(cfg.motor.coulomb), p.torque_per_volt)?,
            duty_per_volt,
        )?
        .min(I64F64::from_num(lim.max_duty));
        let coulomb_ramp_q16 = to_q16(wide(COULOMB_RAMP_RAD_S))?;
        let coulomb_per_w_q16 = to_q16(div(coulomb_duty, wide(COULOMB_RAMP_RAD_S))?)?;
        let dash = DashGains {
            accel_per_duty: to_gain(div(wide(dash::CURRENT_FRACTION), ff_acc)?)?,
            top_per_duty: to_gain(div(wide(dash::VOLTAGE_FRACTION), ff_vel)?)?,
            beta: to_gain(mul(div(ff_vel, ff_acc)?, dt)?)?,
            accel_per_held: to_gain(div(
                mul(
                    wide(dash::CONTACT_FRACTION),
                    div(p.torque_per_volt, duty_per_volt)?,
                )?,
                p.j_link,
            )?)?,
        };
        let move_accel_per_duty =
            to_gain(div(wide(move_duration::MOVE_CURRENT_FRACTION), ff_acc)?)?;
        let impact_speed_q16 = to_q16(mul(
            impact_speed(&p, stiffness, tau_lim)?,
            wide(IMPACT_SPEED_FRACTION),
        )?)?;
        Ok(Schedule {
            setting,
            stiffness,
            bandwidth,
            gains,
            kp: to_gain(wide(gains.kp))?,
            ki_dt: to_gain(mul(wide(gains.ki), dt)?)?,
            kp_dt: to_gain(mul(wide(gains.kp), dt)?)?,
            two_a_brake: to_gain(div(
                mul(
                    mul(wide(BRAKE_FRACTION), kt)?,
                    mul(i_lim, I64F64::from_num(2))?,
                )?,
                p.j,
            )?)?,
            brake_min_w_q16: Q16_ONE / 2,
            int_band_q16: if gains.kp > I32F32::ZERO {
                to_q16(div(I64F64::from_num(lim.max_duty), wide(gains.kp))?)?
            } else {
                i32::MAX
            },
            w_deadband_q16: to_q16(div(
                mul(r, I64F64::from_num(3 + 2 * CURRENT_OFFSET_TOLERANCE_COUNTS))?,
                mul(ke, I64F64::from_num(2 * i32::from(ADC_COUNTS_PER_A)))?,
            )?)?,
            w_bias_per_amp: to_gain(div(mul(wide(RESISTANCE_TOLERANCE), r)?, ke)?)?,
            w_bias_per_duty: to_gain(mul(
                div(
                    mul(wide(SUPPLY_TOLERANCE), p.supply)?,
                    mul(ke, I64F64::from_num(1000))?,
                )?,
                I64F64::from_num(Q16_ONE),
            )?)?,
            impact_speed_q16,
            impact_speed_low_q16: scale_q16(impact_speed_q16, sqrt_ratio_q16(0)),
            contact_torque_q16: to_q16(wide(CONTACT_TORQUE_NM))?,
            contact_per_amp: to_gain(mul(wide(CONTACT_CURRENT_TOLERANCE), kt)?)?,
            kd: to_gain(wide(gains.kd))?,
            dt: to_gain(dt)?,
            shaper_ticks: shaper_ticks(cfg, &p, stiffness)?,
            obs_beta: observer_pull(w, OBSERVER_RATIO, dt)?,
            obs_beta_move: observer_pull(w, MOVE_OBSERVER_RATIO, dt)?,
            rest_zone_q16: to_q16(mul(free_play, wide(REST_ZONE_FREE_PLAYS))?)?,
            rest_torque_q16: to_q16(wide(REST_TORQUE_NM))?,
            rest_load_q16: to_q16(mul(
                div(wide(REST_LOAD_NM), p.torque_per_volt)?,
                duty_per_volt,
            )?)?,
            pressed_load_q16: to_q16(mul(
                div(wide(PRESSED_LOAD_NM), p.torque_per_volt)?,
                duty_per_volt,
            )?)?,
            float_load_q16: to_q16(mul(
                div(wide(FLOAT_LOAD_NM), p.torque_per_volt)?,
                duty_per_volt,
            )?)?,
            torque_lp_beta: to_gain(mul(mul(w, wide(TORQUE_FEEDBACK_CORNER))?, dt)?)?,
            obs_beta2: to_gain(mul(
                mul(
                    div(w, I64F64::from_num(OBSERVER_RATIO))?,
                    div(w, I64F64::from_num(OBSERVER_RATIO))?,
                )?,
                dt,
            )?)?,
            alpha: to_gain(alpha)?,
            ff_vel: to_gain(ff_vel)?,
            ff_acc: to_gain(ff_acc)?,
            ff_defl: to_gain(mul(mul(duty_per_volt, ke)?, ticks_per_s)?)?,
            j_link: to_gain(p.j_link)?,
            inv_k: to_gain(div(I64F64::ONE, k)?)?,
            coulomb_ramp_q16,
            coulomb_per_w_q16,
            // The ramp's end as the per-tick feed-forward computes it (bit for bit).
            coulomb_duty_q16: sat_i32(
                (i64::from(coulomb_ramp_q16) * i64::from(coulomb_per_w_q16)) >> 16,
            ),
            hyst_c_q16: to_q16(
                setting
                    .hysteresis_coefficient()
                    .ok_or(ControlError::Overflow)?,
            )?,
            k: to_gain(k)?,
            free_play_q16: to_q16(free_play)?,
            fp_slope: to_gain(div(free_play, wide(FREE_PLAY_SWITCH_NM))?)?,
            torque_per_duty: to_gain(div(p.torque_per_volt, duty_per_volt)?)?,
            duty_per_amp,
            w_per_duty_q32: to_q32(div(div(p.supply, ticks_per_s)?, ke)?)?,
            w_per_count_q32: w_per_count,
            w_per_count_cfg_q32: w_per_count,
            w_step_per_count_q32: to_q32(div(
                div(kt, mul(p.j_gear, ticks_per_s)?)?,
                I64F64::from_num(ADC_COUNTS_PER_A),
            )?)?,
            duty_per_w: to_gain(mul(duty_per_volt, ke)?)?,
            kt: to_gain(kt)?,
            gear_inertia_per_dt: to_gain(mul(p.j_gear, ticks_per_s)?)?,
            bv: to_gain(bv)?,
            w_defl,
            w_defl_q16: w_defl.apply(Q16_ONE),
            i_lim_q16,
            i_lim_duty_q16: duty_per_amp.apply(i_lim_q16),
            i_win_duty_q16: i_win,
            i_win_cfg_duty_q16: i_win,
            i_win_est_duty_q16: i_win,
            i_lim_from_beams,
            tau_lim_q16: to_q16(tau_lim)?,
            clutch_tolerance: lim.clutch_tolerance,
            weak_capacity: Torque::from_bits(
                i64::try_from(cap_weak.to_bits() >> 32).map_err(|_| ControlError::Overflow)?,
            ),
            duty_lim_q16: i32::from(lim.max_duty) * Q16_ONE,
            pot_center: i32::from(cfg.sensors.pot_center),
            encoder_zero: cfg.sensors.encoder_zero,
            dash,
            move_accel_per_duty,
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

    /// How much longer than configured the clutch may be.
    #[must_use]
    pub const fn clutch_tolerance(&self) -> Length {
        self.clutch_tolerance
    }

    /// The weakest capacity the clutch tolerance allows, τ_cap(L)·L/(L + ΔL).
    #[must_use]
    pub const fn weak_capacity(&self) -> Torque {
        self.weak_capacity
    }

    /// The coupling torque limit τ_lim = margin·τ_cap(L + ΔL).
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
        I32F32::from_bits(i64::from(self.w_defl_q16) << 16)
    }

    /// The output free play φ_b the compensation uses.
    #[must_use]
    pub const fn free_play(&self) -> Angle {
        self.setting.free_play()
    }
}
