//! An f32 port of the per-tick control step and of k(L) / L(k), kept **only** to compare
//! instruction counts with the fixed-point `model` (`cargo xtask bench`). Nothing in the
//! firmware uses it.
//!
//! It mirrors the structure of the fixed-point code statement by statement, with the same
//! per-tick work and the same branches, in SI units and f32 (so `duplicates` pairs it with
//! `model`: on purpose, a comparison is only fair between the same steps):
//!
//! * [`FloatController::step`] is `model::control::Controller::step` (encoder unwrapping,
//!   back-EMF observer, blended torque estimate, reference, feed-forward (the two-mass
//!   inverse for a sine, the gear's Coulomb friction), free-play and hysteresis
//!   compensation, PID, current/duty window, braking governor, anti-windup), all but the
//!   catch of a floating link at rest (`model::control::catch`): it acts only without
//!   load, and the benchmark and the comparison run loaded, where the fixed-point step
//!   only tests whether the rest hold has begun;
//! * [`FloatSupervisor::check`] is `model::supervisor::Supervisor::check` (every check, in
//!   the same order, with the same latch);
//! * [`FloatServo::tick`] is `model::servo::Servo::tick` (controller, supervisor, enable
//!   state, bridge demand);
//! * [`FloatTrajectory`] is `model::control::Trajectory` (hold, raw step, minimum-jerk
//!   quintic, sine with `libm` sin/cos);
//! * [`FloatBeam::stiffness`] is k(L) = n·3·E·I·R²/L³ (paper eq. 4, Euler–Bernoulli) and
//!   [`FloatBeam::clutch_length`] its inverse L(k) = (n·3·E·I·R²/k)^(1/3) (`libm::cbrtf`).
//!
//! The per-tick constants are derived from the fixed-point [`Schedule`] and the [`Config`]
//! when the configuration is set ([`FloatSchedule::new`]; configuration-time maths, not
//! timed). Units: angles rad, velocities rad/s, accelerations rad/s², currents A, torques
//! N·m, duty ‰, lengths mm, stiffness N·m/rad.
//!
//! Agreement with the fixed-point code is tested on the host (`host-tests/tests/
//! float_mirror.rs`): k(L) and L(k) within 1e-5 relative; the same first ticks and the
//! same faults on the same readings; in closed loop with the simulated actuator, the link
//! within one encoder count of the fixed-point run at every tick. The duties are not
//! identical: the fixed-point deflection feed-forward works on a Q16 deflection (1.5e-5
//! rad) through a gain of 1.6e5 ‰/rad, so it moves in steps of 2.5 ‰ where f32 does not. On the Cortex-M3 every f32 operation here is a soft-float library call; on
//! the Cortex-M4F the basic operations are FPU instructions.

use core::f32::consts::PI;

use model::control::creep::{Creep, CREEP_SPEED, PRESS_WIND_SHIFT};
use model::control::hunt::Hunt;
use model::control::schedule::{
    CONTACT_CURRENT_TOLERANCE, CONTACT_TORQUE_NM, COULOMB_RAMP_RAD_S, CURRENT_GAIN_TOLERANCE_DIV,
    CURRENT_OFFSET_TOLERANCE_COUNTS, FLOAT_LOAD_NM, FREE_PLAY_SWITCH_NM,
    HELD_DAMPING_DEADBAND_SHIFT, IMPACT_MATCH_SHIFT, IMPACT_SPEED_FRACTION, MOVE_OBSERVER_RATIO,
    OBSERVER_RATIO, PRESSED_LOAD_NM, RESISTANCE_LOW, RESISTANCE_TOLERANCE, REST_LOAD_NM,
    REST_TORQUE_NM, REST_ZONE_FREE_PLAYS, SUPPLY_TOLERANCE, TORQUE_FEEDBACK_CORNER,
};
use model::control::shaper::SHAPER_LEN;
use model::control::{dash, duty_jump, move_drive, Command, Config, Schedule, BW_MAX, BW_RATIO};
use model::sensors::{self, encoder_delta, POT_SPAN_DEG};
use model::servo::{brakes_on, BridgeDemand, TickInput};
use model::supervisor::{Fault, FaultCode, FaultSet, Supervisor};
use model::{Design, Length, Stiffness};

// The sensors' resolutions (`model::sensors`) in the types the port computes with.
/// Encoder counts per revolution.
const ENCODER_COUNTS: i32 = sensors::ENCODER_COUNTS as i32;
/// Pot counts over its span.
const POT_COUNTS: i32 = sensors::POT_COUNTS as i32;
/// Current ADC zero.
const ADC_MID: i32 = sensors::ADC_MID as i32;
/// Half an encoder count, rad.
const HALF_COUNT: f32 = PI / ENCODER_COUNTS as f32;
/// One encoder count per tick as a velocity, rad/s.
const COUNT_PER_TICK: f32 = 2.0 * PI / ENCODER_COUNTS as f32 * 1000.0;
/// One pot count, rad: the span (300° = 5π/3) over the counts.
const POT_COUNT: f32 = POT_SPAN_DEG as f32 / 60.0 * PI / 3.0 / POT_COUNTS as f32;
/// Current ADC counts per ampere.
const ADC_COUNTS_PER_A: f32 = sensors::ADC_COUNTS_PER_A as f32;
/// Control period, s.
const DT: f32 = 1e-3;

/// f32 of a fixed-point value given as its raw bits and fractional bit count
/// (configuration time only).
fn fx(bits: i128, frac: i32) -> f32 {
    // Via f64: 53 bits are plenty for the conversion, then one rounding to f32.
    libm::ldexp(bits as f64, -frac) as f32
}

fn i32f32(bits: i64) -> f32 {
    fx(i128::from(bits), 32)
}

/// k(L) and L(k) of the Euler–Bernoulli model in f32.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FloatBeam {
    /// C = n·3·E·I·R²/10³, N·m·mm³ (k = C/L³ with L in mm).
    c: f32,
}

impl FloatBeam {
    /// The constant of `design` (computed in f64 from the design parameters, rounded once).
    #[must_use]
    pub fn new(design: &Design) -> FloatBeam {
        let p = design.params();
        let f = |bits: i64| bits as f64 / 4_294_967_296.0;
        let n = f64::from(p.beams);
        let r = f(p.beam_radius.to_bits());
        let pr = f(p.pitch_radius.to_bits());
        let e = f(p.youngs_modulus.to_bits()); // MPa = N/mm²
        let i = core::f64::consts::PI * r * r * r * r / 4.0; // mm⁴
        FloatBeam {
            c: (n * 3.0 * e * i * pr * pr / 1e3) as f32,
        }
    }

    /// Joint stiffness k = C/L³, N·m/rad, for L in mm. No domain check (the caller's
    /// L is in (0, l]).
    #[inline(never)]
    #[must_use]
    pub fn stiffness(&self, len_mm: f32) -> f32 {
        self.c / (len_mm * len_mm * len_mm)
    }

    /// Clutch length L = (C/k)^(1/3), mm, for k in N·m/rad (k > 0).
    #[inline(never)]
    #[must_use]
    pub fn clutch_length(&self, k: f32) -> f32 {
        libm::cbrtf(self.c / k)
    }
}

/// The per-tick constants in f32 (the counterpart of the fixed-point `Schedule`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FloatSchedule {
    kp: f32,
    ki_dt: f32,
    kp_dt: f32,
    two_a_brake: f32,
    brake_min_w: f32,
    int_band: f32,
    w_deadband: f32,
    w_bias_per_amp: f32,
    w_bias_per_duty: f32,
    impact_speed: f32,
    contact_torque: f32,
    contact_per_amp: f32,
    obs_beta: f32,
    obs_beta2: f32,
    obs_beta_move: f32,
    torque_lp_beta: f32,
    float_load: f32,
    rest_zone: f32,
    rest_load: f32,
    pressed_load: f32,
    rest_torque: f32,
    kd: f32,
    alpha: f32,
    ff_vel: f32,
    ff_acc: f32,
    /// What a sine of ω takes off `ff_vel` and `ff_acc` per unit of c_ω = J_l·ω²/k
    /// (`model::control::sine_feedforward`): (1000/V)·R·b_v/k_t and (1000/V)·R·J_g/k_t.
    ff_sine_vel: f32,
    ff_sine_acc: f32,
    /// J_l/k, s² (c_ω = ω²·J_l/k).
    jl_over_k: f32,
    /// The raw step's shaper delay π/ω_a, ticks, where the beams set the bandwidth and it
    /// exceeds the motor's time constant J·R/(k_t·k_e); 0 elsewhere
    /// (`model::control::shaper`; the fixed-point one also leaves a profile whose speed
    /// changes by 0.5 rad/s or more in a tick unshaped, which the f32 port need not).
    shaper_ticks: usize,
    ff_defl: f32,
    j_link: f32,
    inv_k: f32,
    /// The hysteresis coefficient c (design §2.1), per rad.
    hyst_c: f32,
    /// The gear's Coulomb friction as a duty, ‰, and its ramp, ‰ per rad/s.
    coulomb: f32,
    coulomb_ramp: f32,
    k: f32,
    free_play: f32,
    fp_slope: f32,
    torque_per_duty: f32,
    duty_per_amp: f32,
    w_per_duty: f32,
    w_per_count: f32,
    duty_per_w: f32,
    kt: f32,
    jg_fs: f32,
    bv: f32,
    w_defl: f32,
    i_lim: f32,
    /// The current window's half-width, A (`Schedule`'s: at most `RESISTANCE_LOW` of the
    /// motor's rating; the fixed-point loop widens it for the resistance the duty jump's
    /// estimate reads, which is not ported: on the nominal motor it stays the configured).
    i_win: f32,
    i_lim_from_beams: bool,
    tau_lim: f32,
    duty_lim: f32,
    pot_center: i32,
    encoder_zero: i32,
}

impl FloatSchedule {
    /// The f32 constants for `config`, whose fixed-point schedule is `sched`: stiffness,
    /// bandwidth, PID gains, limits, blend weight and free play are taken from `sched`,
    /// the motor constants from `config` (the same formulas as `Schedule::new`).
    #[must_use]
    pub fn new(sched: &Schedule, config: &Config) -> FloatSchedule {
        let m = &config.motor;
        let v_s = i32f32(m.supply_v.to_bits());
        let r = i32f32(m.resistance_ohm.to_bits());
        let kt = i32f32(m.torque_constant.to_bits());
        let ke = i32f32(m.back_emf.to_bits());
        let bv = i32f32(m.viscous.to_bits());
        let j_g = i32f32(m.rotor_inertia.to_bits()) * 1e-6; // kg·mm² → kg·m²
        let j_l = i32f32(config.link_inertia.to_bits()) * 1e-6;
        let j = j_g + j_l;
        let dpv = 1000.0 / v_s;
        let c = kt / r;
        let k = fx(sched.stiffness().to_bits(), 64);
        let w_c = fx(i128::from(sched.bandwidth().to_bits()), 32);
        let g = sched.gains();
        let kp = i32f32(g.kp.to_bits());
        let ki = i32f32(g.ki.to_bits());
        let kd = i32f32(g.kd.to_bits());
        let tau_f = 1.0 / (4.0 * w_c);
        let (i_lim, from_beams) = sched.current_limit();
        let i_lim = i32f32(i_lim.to_bits());
        let free_play = i32f32(sched.free_play().to_bits());
        let max_duty = f32::from(config.limits.max_duty);
        let coulomb = (i32f32(m.coulomb.to_bits()) / c * dpv).min(max_duty);
        FloatSchedule {
            kp,
            ki_dt: ki * DT,
            kp_dt: kp * DT,
            two_a_brake: 0.5 * kt * i_lim * 2.0 / j,
            brake_min_w: 0.5,
            int_band: if kp > 0.0 { max_duty / kp } else { f32::MAX },
            w_deadband: r * (3.0 + 2.0 * CURRENT_OFFSET_TOLERANCE_COUNTS as f32)
                / (ke * 2.0 * ADC_COUNTS_PER_A),
            w_bias_per_amp: i32f32(RESISTANCE_TOLERANCE.to_bits()) * r / ke,
            w_bias_per_duty: i32f32(SUPPLY_TOLERANCE.to_bits()) * v_s / 1000.0 / ke,
            impact_speed: i32f32(IMPACT_SPEED_FRACTION.to_bits())
                * i32f32(sched.torque_limit().to_bits())
                / libm::sqrtf(k * j_g * j_l / j),
            contact_torque: i32f32(CONTACT_TORQUE_NM.to_bits()),
            contact_per_amp: i32f32(CONTACT_CURRENT_TOLERANCE.to_bits()) * kt,
            obs_beta: 2.0 * w_c / OBSERVER_RATIO as f32 * DT,
            obs_beta2: (w_c / OBSERVER_RATIO as f32) * (w_c / OBSERVER_RATIO as f32) * DT,
            obs_beta_move: 2.0 * w_c / MOVE_OBSERVER_RATIO as f32 * DT,
            torque_lp_beta: i32f32(TORQUE_FEEDBACK_CORNER.to_bits()) * w_c * DT,
            float_load: i32f32(FLOAT_LOAD_NM.to_bits()) / c * dpv,
            rest_zone: i32f32(REST_ZONE_FREE_PLAYS.to_bits()) * free_play,
            rest_load: i32f32(REST_LOAD_NM.to_bits()) / c * dpv,
            pressed_load: i32f32(PRESSED_LOAD_NM.to_bits()) / c * dpv,
            rest_torque: i32f32(REST_TORQUE_NM.to_bits()),
            kd,
            alpha: DT / (tau_f + DT),
            ff_vel: dpv * (ke + r * bv / kt),
            ff_acc: dpv * r * j / kt,
            ff_sine_vel: dpv * r * bv / kt,
            ff_sine_acc: dpv * r * j_g / kt,
            jl_over_k: j_l / k,
            shaper_ticks: {
                let w_a = libm::sqrtf(k / j_l);
                if w_a >= (BW_RATIO * BW_MAX) as f32 || PI / w_a <= j * r / (kt * ke) {
                    0
                } else {
                    (libm::roundf(PI * 1000.0 / w_a) as usize).clamp(1, SHAPER_LEN - 1)
                }
            },
            ff_defl: dpv * ke * 1000.0,
            j_link: j_l,
            inv_k: 1.0 / k,
            hyst_c: sched
                .setting()
                .hysteresis_coefficient()
                .map_or(0.0, |c| c.to_num::<f32>()),
            coulomb,
            coulomb_ramp: coulomb / i32f32(COULOMB_RAMP_RAD_S.to_bits()),
            k,
            free_play,
            fp_slope: free_play / i32f32(FREE_PLAY_SWITCH_NM.to_bits()),
            torque_per_duty: c / dpv,
            duty_per_amp: dpv * r,
            w_per_duty: v_s / 1000.0 / ke,
            w_per_count: r / ke / ADC_COUNTS_PER_A,
            duty_per_w: dpv * ke,
            kt,
            jg_fs: j_g * 1000.0,
            bv,
            w_defl: i32f32(sched.deflection_weight().to_bits()),
            i_lim,
            i_win: i_lim.min(
                i32f32(config.limits.max_current_a.to_bits()) * i32f32(RESISTANCE_LOW.to_bits()),
            ),
            i_lim_from_beams: from_beams,
            tau_lim: i32f32(sched.torque_limit().to_bits()),
            duty_lim: max_duty,
            pot_center: i32::from(config.sensors.pot_center),
            encoder_zero: i32::from(config.sensors.encoder_zero),
        }
    }
}

/// One tick of reference, f32.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FloatReference {
    /// r, rad.
    pub position: f32,
    /// ṙ, rad/s.
    pub velocity: f32,
    /// r̈, rad/s².
    pub acceleration: f32,
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Mode {
    Hold,
    Quintic {
        p0: f32,
        target: f32,
        c: [f32; 5],
        dv: [f32; 5],
        da: [f32; 4],
        tau: f32,
        dtau: f32,
        left: u32,
    },
    Sine {
        center: f32,
        amp: f32,
        vel_amp: f32,
        acc_amp: f32,
        phase: f32,
        dphase: f32,
    },
    /// The raw step's profile (`model::control::dash`).
    Dash {
        target: f32,
        aim: f32,
        sign: f32,
        speed: f32,
        accel: f32,
        brake: f32,
        top: f32,
        beta: f32,
        braking: f32,
        drive_actual: f32,
        drive_model: f32,
        brake_scaled: f32,
    },
    /// A shaped raw step whose profile has landed: the shaper's last ticks.
    Tail {
        target: f32,
        left: usize,
        sign: f32,
    },
}

/// The raw step's ZV shaper (`model::control::shaper`): the profile's change of speed
/// along the step in each of its last `SHAPER_LEN` ticks (NaN at the landing), replayed
/// `delay` ticks late; the delay is 0 when off.
#[derive(Clone, Copy, Debug, PartialEq)]
struct FloatShaper {
    delay: usize,
    head: usize,
    position: f32,
    speed: f32,
    changes: [f32; SHAPER_LEN],
}

impl FloatShaper {
    const OFF: FloatShaper = FloatShaper {
        delay: 0,
        head: 0,
        position: 0.0,
        speed: 0.0,
        changes: [0.0; SHAPER_LEN],
    };

    /// ½ of this tick's (p, v, a) plus ½ of the profile `delay` ticks ago (direction
    /// `sign`, landing on `target`).
    fn shape(
        &mut self,
        (p, v, a): (f32, f32, f32),
        change: f32,
        landed: bool,
        sign: f32,
        target: f32,
    ) -> (f32, f32, f32) {
        self.head = (self.head + 1) % SHAPER_LEN;
        self.changes[self.head] = if landed { f32::NAN } else { change };
        let old = self.changes[(self.head + SHAPER_LEN - self.delay) % SHAPER_LEN];
        let (ov, oa) = if old.is_nan() {
            self.position = target;
            self.speed = 0.0;
            (0.0, 0.0)
        } else {
            let next = self.speed + old;
            self.position += (self.speed + next) * DT / 2.0 * sign;
            self.speed = next;
            (next * sign, old * 1000.0 * sign)
        };
        (0.5 * (p + self.position), 0.5 * (v + ov), 0.5 * (a + oa))
    }
}

/// The raw step's limits in duty terms (`model::control::dash`): the current and duty
/// limits, ‰, the fractions of their headroom the profile uses, and the feed-forward
/// gains.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FloatDashLimits {
    /// The current limit in duty, ‰.
    pub current_duty: f32,
    /// The duty limit, ‰.
    pub duty_lim: f32,
    /// `CURRENT_FRACTION` and `VOLTAGE_FRACTION`.
    pub current_fraction: f32,
    /// See `current_fraction`.
    pub voltage_fraction: f32,
    /// Rigid feed-forward, ‰ per rad/s.
    pub ff_vel: f32,
    /// Rigid feed-forward, ‰ per rad/s².
    pub ff_acc: f32,
    /// `CONTACT_FRACTION`·(torque per ‰)/J_l, rad/s² per ‰ of held duty.
    pub accel_per_held: f32,
    /// Steps shorter than this are small, rad (`SMALL_STEP_FREE_PLAYS`·φ_b).
    pub small_step: f32,
    /// The least held duty a small step keeps the beams on one wall for, ‰; below it a
    /// small step aims short.
    pub held_min: f32,
    /// How far a floating link's small step aims short, rad (φ_b/2^`FLOATING_SHORT_SHIFT`).
    pub short: f32,
}

/// The reference generator in f32 (hold, raw step, minimum-jerk move, sine).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FloatTrajectory {
    mode: Mode,
    pos: f32,
    vel: f32,
    acc: f32,
    /// A raw step's unshaped profile position, rad, and its shaper.
    raw: f32,
    shaper: FloatShaper,
}

impl FloatTrajectory {
    /// The free-play impact speed's factor for the drive the running raw step met,
    /// √(a_brake'/a_brake) once its braking is fixed; 1 outside its profile.
    fn impact(&self) -> f32 {
        match self.mode {
            Mode::Dash {
                brake,
                brake_scaled,
                ..
            } if brake_scaled > 0.0 => libm::sqrtf((brake_scaled / brake).min(1.0)),
            _ => 1.0,
        }
    }

    /// `true` while a sine runs.
    #[must_use]
    pub const fn is_sine(&self) -> bool {
        matches!(self.mode, Mode::Sine { .. })
    }

    /// `true` while a raw step runs.
    #[must_use]
    pub const fn is_dash(&self) -> bool {
        matches!(self.mode, Mode::Dash { .. } | Mode::Tail { .. })
    }

    /// Holding at `position` (rad).
    #[must_use]
    pub const fn new(position: f32) -> Self {
        Self {
            mode: Mode::Hold,
            pos: position,
            vel: 0.0,
            acc: 0.0,
            raw: position,
            shaper: FloatShaper::OFF,
        }
    }

    /// Starts `cmd` from the current reference state (the checks of the fixed-point
    /// generator are the caller's: the same command is given to both).
    pub fn command(&mut self, cmd: Command) {
        match cmd {
            Command::Hold => {
                self.mode = Mode::Hold;
                self.vel = 0.0;
                self.acc = 0.0;
            }
            Command::Step { target } => {
                self.mode = Mode::Hold;
                self.pos = i32f32(target.to_bits());
                self.vel = 0.0;
                self.acc = 0.0;
            }
            Command::Move {
                target,
                duration_ms,
            } => {
                let t = duration_ms as f32 / 1000.0;
                let target = i32f32(target.to_bits());
                let h = target - self.pos;
                let c1 = self.vel * t;
                let c2 = self.acc * t * t / 2.0;
                let c = [
                    c1,
                    c2,
                    10.0 * h - 6.0 * c1 - 3.0 * c2,
                    -15.0 * h + 8.0 * c1 + 3.0 * c2,
                    6.0 * h - 3.0 * c1 - c2,
                ];
                let mut dv = [0.0; 5];
                let mut da = [0.0; 4];
                for (i, ci) in c.iter().enumerate() {
                    let n = i as f32 + 1.0;
                    dv[i] = ci * n / t;
                    if i >= 1 {
                        da[i - 1] = ci * n * (n - 1.0) / (t * t);
                    }
                }
                self.mode = Mode::Quintic {
                    p0: self.pos,
                    target,
                    c,
                    dv,
                    da,
                    tau: 0.0,
                    dtau: 1.0 / duration_ms as f32,
                    left: duration_ms,
                };
            }
            Command::Sine {
                amplitude,
                frequency,
            } => {
                let a = i32f32(amplitude.to_bits());
                let w = i32f32(frequency.to_bits());
                self.mode = Mode::Sine {
                    center: self.pos,
                    amp: a,
                    vel_amp: a * w,
                    acc_amp: a * w * w,
                    phase: 0.0,
                    dphase: w * DT,
                };
            }
        }
    }

    /// A raw step along the profile of `model::control::dash`, planned with `hold` ‰ of
    /// integrator; a jump where the limits leave no acceleration.
    pub fn step(&mut self, target: f32, l: &FloatDashLimits, hold: f32, shaper_ticks: usize) {
        let sign = if target >= self.pos { 1.0 } else { -1.0 };
        let mut accel = l.current_fraction * (l.current_duty - hold * sign) / l.ff_acc;
        let mut brake = l.current_fraction * (l.current_duty + hold * sign) / l.ff_acc;
        let top = l.voltage_fraction * (l.duty_lim - hold * sign) / l.ff_vel;
        let h = libm::fabsf(target - self.pos);
        let floating = libm::fabsf(hold) < l.held_min;
        if accel > 0.0 && brake > 0.0 && top > 0.0 && h < l.small_step && !floating {
            // The beams stay on the wall the held load presses them against.
            let lim =
                (l.accel_per_held * libm::fabsf(hold)).max(h * dash::CONTACT_FLOOR_PER_RAD as f32);
            if hold * sign > 0.0 {
                brake = brake.min(lim);
            } else {
                accel = accel.min(lim);
            }
        }
        if accel <= 0.0 || brake <= 0.0 || top <= 0.0 {
            self.mode = Mode::Hold;
            self.pos = target;
            self.vel = 0.0;
            self.acc = 0.0;
            return;
        }
        // A floating link's small step aims short, at most half the step.
        let short = if h < l.small_step && floating {
            l.short.min(h / 2.0)
        } else {
            0.0
        };
        self.mode = Mode::Dash {
            target,
            aim: target - short * sign,
            sign,
            speed: self.vel * sign,
            accel,
            brake,
            top,
            beta: l.ff_vel / l.ff_acc * DT,
            braking: 0.0,
            drive_actual: 0.0,
            drive_model: 0.0,
            brake_scaled: 0.0,
        };
        self.raw = self.pos;
        self.shaper = FloatShaper::OFF;
        if self.vel == 0.0 && self.acc == 0.0 {
            self.shaper.delay = shaper_ticks;
            self.shaper.position = self.pos;
        }
    }

    /// A raw step's drive in this tick (`model::control::dash`): the output's acceleration
    /// part and the rigid model's r̈ feed-forward, ‰.
    pub fn drive(&mut self, actual: f32, model: f32) {
        if let Mode::Dash {
            sign,
            drive_actual,
            drive_model,
            brake_scaled,
            ..
        } = &mut self.mode
        {
            if *brake_scaled == 0.0 && model * *sign > 0.0 {
                *drive_actual += actual * *sign;
                *drive_model += model * *sign;
            }
        }
    }

    /// Advances one tick and returns the new reference.
    pub fn advance(&mut self) -> FloatReference {
        self.advance_limited(0.0)
    }

    /// `advance`, told the side the drive was at its duty limit on the last tick (+1, −1, 0):
    /// a raw step's profile then gains no speed that way.
    pub fn advance_limited(&mut self, limited: f32) -> FloatReference {
        match &mut self.mode {
            Mode::Hold => {}
            Mode::Dash {
                target,
                aim,
                sign,
                speed,
                accel,
                brake,
                top,
                beta,
                braking,
                drive_actual,
                drive_model,
                brake_scaled,
            } => {
                let s = *speed;
                let left = (*aim - self.raw) * *sign;
                let mut next = if *braking == 0.0 && limited == *sign && s > 0.0 {
                    s
                } else if *braking == 0.0 {
                    s + (*accel * DT).min(*beta * (*top - s))
                } else {
                    s - *braking * DT
                };
                if *braking == 0.0 && next > 0.0 && s > 0.0 {
                    let left_after = left - (s + next) * DT / 2.0;
                    let max = dash::BRAKE_SCALE_MAX as f32;
                    if *brake_scaled == 0.0
                        && next * next >= 2.0 * (*brake / max) * left_after.max(0.0)
                    {
                        let margin = dash::DRIVE_MARGIN_PERCENT as f32 / 100.0;
                        *brake_scaled =
                            if *drive_model > 0.0 && *drive_actual > margin * *drive_model {
                                let ratio = *drive_model / *drive_actual;
                                *brake * (ratio * ratio).max(1.0 / max)
                            } else {
                                *brake
                            };
                    }
                    if *brake_scaled != 0.0
                        && next * next >= 2.0 * *brake_scaled * left_after.max(0.0)
                    {
                        *braking = (s * s / (2.0 * left.max(1.0 / 65536.0))).max(1.0 / 65536.0);
                        next = s - *braking * DT;
                    }
                }
                let travel = (s + next) * DT / 2.0;
                let (p, v, a, done) = if *braking != 0.0 && (next <= 0.0 || left - travel <= 0.0) {
                    (*target, 0.0, 0.0, true)
                } else {
                    *speed = next;
                    (
                        self.raw + travel * *sign,
                        next * *sign,
                        (next - s) * 1000.0 * *sign,
                        false,
                    )
                };
                self.raw = p;
                let shaped = self.shaper.delay > 0;
                (self.pos, self.vel, self.acc) = if shaped {
                    self.shaper.shape((p, v, a), next - s, done, *sign, *target)
                } else {
                    (p, v, a)
                };
                if done {
                    self.mode = if shaped {
                        Mode::Tail {
                            target: p,
                            left: self.shaper.delay,
                            sign: *sign,
                        }
                    } else {
                        Mode::Hold
                    };
                }
            }
            Mode::Tail { target, left, sign } => {
                *left -= 1;
                if *left == 0 {
                    (self.pos, self.vel, self.acc) = (*target, 0.0, 0.0);
                    self.mode = Mode::Hold;
                } else {
                    (self.pos, self.vel, self.acc) =
                        self.shaper
                            .shape((*target, 0.0, 0.0), 0.0, true, *sign, *target);
                }
            }
            Mode::Quintic {
                p0,
                target,
                c,
                dv,
                da,
                tau,
                dtau,
                left,
            } => {
                *left = left.saturating_sub(1);
                if *left == 0 {
                    self.pos = *target;
                    self.vel = 0.0;
                    self.acc = 0.0;
                    self.mode = Mode::Hold;
                } else {
                    *tau += *dtau;
                    let t = *tau;
                    let horner = |k: &[f32]| k.iter().rev().fold(0.0, |acc, &ki| acc * t + ki);
                    self.pos = *p0 + horner(c) * t;
                    self.vel = horner(dv);
                    self.acc = horner(da);
                }
            }
            Mode::Sine {
                center,
                amp,
                vel_amp,
                acc_amp,
                phase,
                dphase,
            } => {
                *phase += *dphase;
                if *phase >= 2.0 * PI {
                    *phase -= 2.0 * PI;
                }
                let s = libm::sinf(*phase);
                let co = libm::cosf(*phase);
                self.pos = *center + *amp * s;
                self.vel = *vel_amp * co;
                self.acc = -*acc_amp * s;
            }
        }
        FloatReference {
            position: self.pos,
            velocity: self.vel,
            acceleration: self.acc,
        }
    }
}

/// Raw sensor values of one tick (as `model::control::Measurements`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FloatMeasurements {
    /// Link encoder, counts.
    pub link_encoder: u16,
    /// Gear pot, counts, if fitted.
    pub gear_pot: Option<u16>,
    /// Current ADC, counts.
    pub current_adc: u16,
    /// Duty the bridge applied last tick if it differs from the controller's output, ‰.
    pub applied_duty: Option<i16>,
}

/// Live limits (as `model::control::Flags`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FloatFlags {
    /// Coupling torque limited.
    pub torque_limited: bool,
    /// Motor current limited.
    pub current_limited: bool,
    /// Duty at ±max.
    pub duty_saturated: bool,
}

/// What the f32 controller decided (as `model::control::Output`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FloatOutput {
    /// Duty, ‰.
    pub duty: i16,
    /// Live limits.
    pub flags: FloatFlags,
    /// Coupling torque estimate, N·m.
    pub torque_estimate: f32,
    /// Reference, rad.
    pub reference: f32,
    /// Link angle, rad.
    pub link_angle: f32,
    /// Gear velocity, rad/s.
    pub gear_velocity: f32,
    /// Filtered link velocity, rad/s.
    pub link_velocity: f32,
    /// Motor current, A.
    pub current: f32,
}

/// The link-position controller in f32.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FloatController {
    s: FloatSchedule,
    traj: FloatTrajectory,
    /// Feed-forward gains of the running reference (the two-mass inverse for a sine).
    ff_vel: f32,
    ff_acc: f32,
    started: bool,
    commanded: bool,
    enc_prev: u16,
    n_link: i32,
    w_link: f32,
    w_fb: f32,
    w_ref: f32,
    w_gear_prev: f32,
    i_filtered: f32,
    /// The side the impact limit held the duty on at the last tick (+1, −1, 0).
    impact_side: i8,
    integ: f32,
    hunt: Hunt,
    creep: Creep,
    duty_prev: i16,
    defl_prev: f32,
    defl_valid: bool,
    elastic_prev: f32,
    theta_g: f32,
    theta_g_valid: bool,
    rest_ticks: u8,
    w_bias: f32,
    torque_error_lp: f32,
    limited: f32,
    /// The running move's drive sums and its r̈ feed-forward scale.
    move_drive: FloatMoveDrive,
    /// The duty jump's probe of a probed command from rest (as `duty_jump::DutyJump`), ‰,
    /// and the ticks it has left (2: add it, 1: take it away).
    probe: f32,
    probe_ticks: u8,
    /// Ticks the reference has stood still, at most `duty_jump::HELD_TICKS`.
    held: u8,
}

/// A move's drive sums and the r̈ feed-forward scale they give (`model::control::move_drive`).
#[derive(Clone, Copy, Debug, PartialEq)]
struct FloatMoveDrive {
    /// +1 or −1: the move's direction; 0 outside a move.
    dir: f32,
    /// Σ of the output's acceleration part and of the model's r̈ feed-forward, ‰·ticks.
    actual: f32,
    model: f32,
    /// The feed-forward scale.
    scale: f32,
}

impl FloatMoveDrive {
    const NEW: Self = Self {
        dir: 0.0,
        actual: 0.0,
        model: 0.0,
        scale: 1.0,
    };

    fn start(from: f32, to: f32) -> Self {
        let dir = if to > from {
            1.0
        } else if to < from {
            -1.0
        } else {
            0.0
        };
        Self { dir, ..Self::NEW }
    }

    /// One tick of a loaded link's drive: the output's acceleration part and the model's
    /// r̈ feed-forward, ‰.
    fn take(&mut self, actual: f32, model: f32) {
        if self.dir * model <= 0.0 || self.model >= move_drive::SUM_STOP as f32 {
            return;
        }
        self.actual += self.dir * actual;
        self.model += self.dir * model;
        let margin = dash::DRIVE_MARGIN_PERCENT as f32 / 100.0;
        if self.model >= move_drive::MIN_MODEL_DRIVE as f32 {
            self.scale = if self.actual > margin * self.model {
                (self.actual / (margin * self.model)).clamp(1.0, move_drive::MOVE_SCALE_MAX as f32)
            } else {
                1.0
            };
        }
    }
}

impl FloatController {
    /// A controller with the constants `s`, holding the link where the first measurement
    /// finds it.
    #[must_use]
    pub const fn new(s: FloatSchedule) -> Self {
        Self {
            ff_vel: s.ff_vel,
            ff_acc: s.ff_acc,
            s,
            traj: FloatTrajectory::new(0.0),
            started: false,
            commanded: false,
            enc_prev: 0,
            n_link: 0,
            w_link: 0.0,
            w_fb: 0.0,
            w_ref: 0.0,
            w_gear_prev: 0.0,
            i_filtered: 0.0,
            impact_side: 0,
            integ: 0.0,
            hunt: Hunt::NEW,
            creep: Creep::NEW,
            duty_prev: 0,
            defl_prev: 0.0,
            defl_valid: false,
            elastic_prev: 0.0,
            theta_g: 0.0,
            theta_g_valid: false,
            rest_ticks: 0,
            w_bias: 0.0,
            torque_error_lp: 0.0,
            limited: 0.0,
            move_drive: FloatMoveDrive::NEW,
            probe: 0.0,
            probe_ticks: 0,
            held: 0,
        }
    }

    /// Starts a trajectory command. A move runs for the duration it gives: pass the command
    /// `Controller::planned` returns (the fixed-point planning of the move's duration is not
    /// ported).
    pub fn command(&mut self, cmd: Command) {
        let s = &self.s;
        let from = self.traj.pos;
        // A move, or a loaded raw step through the shaper (`duty_jump::probed_target`),
        // probes its first tick for the observer's resistance once the reference has stood
        // `duty_jump::HELD_TICKS` (the estimate itself is not ported: it keeps the
        // configured one on the nominal motor).
        let from_rest =
            self.traj.vel == 0.0 && self.traj.acc == 0.0 && self.held >= duty_jump::HELD_TICKS;
        let loaded = libm::fabsf(self.integ) >= s.float_load;
        (self.probe, self.probe_ticks) =
            match duty_jump::probed_target(&cmd, s.shaper_ticks != 0, loaded) {
                Some(target) if from_rest => {
                    let p = duty_jump::PROBE_PERMILLE as f32;
                    (
                        if i32f32(target.to_bits()) > from {
                            p
                        } else {
                            -p
                        },
                        2,
                    )
                }
                _ => (0.0, 0),
            };
        (self.ff_vel, self.ff_acc) = match cmd {
            Command::Sine { frequency, .. } => {
                let w = i32f32(frequency.to_bits());
                let c = s.jl_over_k * w * w;
                (s.ff_vel - c * s.ff_sine_vel, s.ff_acc - c * s.ff_sine_acc)
            }
            _ => (s.ff_vel, s.ff_acc),
        };
        match cmd {
            Command::Step { target } => {
                let limits = FloatDashLimits {
                    current_duty: s.duty_per_amp * s.i_lim,
                    duty_lim: s.duty_lim,
                    current_fraction: i32f32(dash::CURRENT_FRACTION.to_bits()),
                    voltage_fraction: i32f32(dash::VOLTAGE_FRACTION.to_bits()),
                    ff_vel: s.ff_vel,
                    ff_acc: s.ff_acc,
                    accel_per_held: i32f32(dash::CONTACT_FRACTION.to_bits()) * s.torque_per_duty
                        / s.j_link,
                    small_step: dash::SMALL_STEP_FREE_PLAYS as f32 * s.free_play,
                    held_min: s.float_load / 2.0,
                    short: s.free_play / (1u32 << dash::FLOATING_SHORT_SHIFT) as f32,
                };
                let hold = self.plan_hold();
                self.traj
                    .step(i32f32(target.to_bits()), &limits, hold, s.shaper_ticks);
            }
            _ => self.traj.command(cmd),
        }
        self.move_drive = match cmd {
            Command::Move { target, .. } => FloatMoveDrive::start(from, i32f32(target.to_bits())),
            _ => FloatMoveDrive::NEW,
        };
        self.commanded = true;
    }

    /// The load a raw step is planned with, ‰ (as `Controller::plan_hold`): the
    /// integrator's, but a still hold that takes more than half the current limit no more
    /// than its measured current needs through the configured R.
    fn plan_hold(&self) -> f32 {
        let s = &self.s;
        let still = libm::fabsf(self.integ) > s.duty_per_amp * s.i_lim / 2.0
            && self.traj.vel == 0.0
            && self.traj.acc == 0.0
            && libm::fabsf(self.w_link) < s.w_deadband
            && !self.hunt.hunting();
        if !still {
            return self.integ;
        }
        let i = libm::fabsf(self.i_filtered) * (1.0 + 1.0 / CURRENT_GAIN_TOLERANCE_DIV as f32)
            + CURRENT_OFFSET_TOLERANCE_COUNTS as f32 / ADC_COUNTS_PER_A;
        let by_current = s.duty_per_amp * i;
        if libm::fabsf(self.integ) <= by_current {
            self.integ
        } else {
            libm::copysignf(by_current, self.integ)
        }
    }

    /// Forgets the loop state (as `Controller::reset`).
    pub fn reset(&mut self) {
        self.ff_vel = self.s.ff_vel;
        self.ff_acc = self.s.ff_acc;
        self.started = false;
        self.commanded = false;
        self.w_link = 0.0;
        self.w_fb = 0.0;
        self.w_ref = 0.0;
        self.w_gear_prev = 0.0;
        self.i_filtered = 0.0;
        self.impact_side = 0;
        self.integ = 0.0;
        self.hunt = Hunt::NEW;
        self.creep = Creep::NEW;
        self.duty_prev = 0;
        self.defl_valid = false;
        self.theta_g_valid = false;
        self.rest_ticks = 0;
        self.w_bias = 0.0;
        self.torque_error_lp = 0.0;
        self.limited = 0.0;
        self.move_drive = FloatMoveDrive::NEW;
        self.probe_ticks = 0;
        self.held = 0;
    }

    fn centred_counts(&self, raw: u16) -> i32 {
        let v = (i32::from(raw) - self.s.encoder_zero) & (ENCODER_COUNTS - 1);
        if v >= ENCODER_COUNTS / 2 {
            v - ENCODER_COUNTS
        } else {
            v
        }
    }

    /// One 1 kHz control step (the f32 port of `Controller::step`).
    pub fn step(&mut self, m: &FloatMeasurements) -> FloatOutput {
        let s = self.s;

        // --- link angle ---
        let delta = if self.started {
            encoder_delta(m.link_encoder, self.enc_prev)
        } else {
            self.n_link = self.centred_counts(m.link_encoder);
            0
        };
        self.enc_prev = m.link_encoder;
        self.n_link = self.n_link.saturating_add(delta);
        let theta_l = (2 * self.n_link + 1) as f32 * HALF_COUNT;
        if !self.started {
            self.started = true;
            if !self.commanded {
                self.traj = FloatTrajectory::new(theta_l);
            }
        }
        let v_raw = delta as f32 * COUNT_PER_TICK;
        self.w_link += s.alpha * (v_raw - self.w_link);

        // --- current and the back-EMF observer ---
        let adc = i32::from(m.current_adc) - ADC_MID;
        let current = adc as f32 / ADC_COUNTS_PER_A;
        let applied = m.applied_duty.unwrap_or(self.duty_prev);
        let w_gear = f32::from(applied) * s.w_per_duty - adc as f32 * s.w_per_count;
        self.w_fb += s.alpha * (w_gear - self.w_fb);

        // --- coupling torque estimate ---
        self.i_filtered += s.alpha * (current - self.i_filtered);
        let dw = self.w_fb - self.w_gear_prev;
        self.w_gear_prev = self.w_fb;
        let gear_inertial = s.jg_fs * dw;
        let tau_i = s.kt * self.i_filtered - gear_inertial - s.bv * w_gear;
        let tau = match m.gear_pot {
            Some(pot) if s.w_defl != 0.0 => {
                let pot = i32::from(pot) & (POT_COUNTS - 1);
                let theta_g = (pot - s.pot_center) as f32 * POT_COUNT;
                let phi = theta_g - theta_l;
                let mag = (libm::fabsf(phi) - s.free_play).max(0.0);
                let phi_e = if phi < 0.0 { -mag } else { mag };
                let tau_d = s.k * phi_e;
                tau_i + s.w_defl * (tau_d - tau_i)
            }
            _ => tau_i,
        };

        // --- reference and error ---
        let r = self.traj.advance_limited(self.limited);
        let e_raw = r.position - theta_l;
        let in_count = (-HALF_COUNT..HALF_COUNT).contains(&e_raw);
        let e = if in_count { 0.0 } else { e_raw };
        let stationary = r.velocity == 0.0 && r.acceleration == 0.0;
        self.held = duty_jump::held_after(self.held, stationary);
        // Gear angle: complementary filter (observer above ω_o, link encoder below); a
        // link held on a wall at a stationary reference at its count's centre.
        let pressed = stationary
            && libm::fabsf(self.integ) >= s.pressed_load
            && libm::fabsf(self.w_link) < s.w_deadband
            && !self.hunt.hunting();
        let nearest = if in_count || !pressed {
            e_raw.clamp(-HALF_COUNT, HALF_COUNT)
        } else {
            0.0
        };
        let anchor = theta_l + nearest + self.defl_prev;
        let floating = libm::fabsf(self.integ) < s.float_load;
        if self.theta_g_valid && floating {
            self.theta_g += (w_gear - self.w_bias) * DT;
            let pull = anchor - self.theta_g;
            if stationary || self.traj.is_dash() {
                self.theta_g += s.obs_beta * pull;
                self.w_bias -= s.obs_beta2 * pull;
            } else {
                self.theta_g += s.obs_beta_move * pull;
            }
        } else {
            self.theta_g = anchor;
            self.theta_g_valid = true;
        }
        let e_g = r.position + self.defl_prev - self.theta_g;
        // Rest without load: the gear stays where it is.
        let e_abs = libm::fabsf(e_raw);
        let near = e_abs <= s.rest_zone;
        // Twice the zone after a creep push.
        let calm = libm::fabsf(self.integ) < s.rest_load
            && libm::fabsf(tau) < s.rest_torque
            && stationary
            && (near || (self.creep.pushed() && e_abs <= 2.0 * s.rest_zone));
        self.rest_ticks = if calm {
            self.rest_ticks.saturating_add(1)
        } else {
            0
        };
        let resting = self.rest_ticks >= 20;
        // The creep at rest: the same rule, its push in f32.
        let (creep_w, u_creep) = if stationary {
            let beyond = e_abs > 2.0 * HALF_COUNT;
            let dir = self
                .creep
                .update(delta, resting, in_count, e_raw > 0.0, beyond);
            if dir == 0 {
                let press = self.creep.press(!in_count && pressed, e_raw > 0.0);
                (0.0, f32::from(press) * s.coulomb)
            } else {
                let w = f32::from(dir) * i32f32(CREEP_SPEED.to_bits());
                let f = s.coulomb + self.creep.boost_q16() as f32 / 65_536.0;
                (w, self.ff_vel * w + f32::from(dir) * f)
            }
        } else {
            self.creep = Creep::NEW;
            (0.0, 0.0)
        };
        self.w_ref += s.alpha * (r.velocity - self.w_ref);

        // --- feed-forward ---
        let (u_vel, u_acc_model) = (self.ff_vel * r.velocity, self.ff_acc * r.acceleration);
        let scale = self.move_drive.scale;
        let u_acc = scale * u_acc_model;
        let u_ff = u_vel + u_acc;
        let u_i = self.integ;
        let tau_ref = scale * s.j_link * r.acceleration + s.torque_per_duty * u_i;
        let side = (s.fp_slope * tau_ref).clamp(-s.free_play, s.free_play);
        // Hysteresis band φ₀ ± c·φ₀² (a play operator).
        let phi0 = s.inv_k * tau_ref;
        let elastic = if self.defl_valid {
            let h = s.hyst_c * phi0 * phi0;
            self.elastic_prev.clamp(phi0 - h, phi0 + h)
        } else {
            phi0
        };
        self.elastic_prev = elastic;
        let defl = elastic + side;
        let d_defl = if self.defl_valid {
            defl - self.defl_prev
        } else {
            0.0
        };
        let u_defl = s.ff_defl * d_defl;
        let u_coulomb = if floating || stationary {
            0.0
        } else {
            (s.coulomb_ramp * (r.velocity + d_defl * 1000.0)).clamp(-s.coulomb, s.coulomb)
        };
        self.defl_prev = defl;
        self.defl_valid = true;

        // --- PID ---
        // The floating gear loop at ω_c/2 near the target or while the reference moves,
        // and any loop that hunts at rest.
        let (soft_p, soft_d, soft_i) = if (floating && (near || !stationary)) || self.hunt.hunting()
        {
            (0.25, 0.5, 0.125)
        } else {
            (1.0, 1.0, 1.0)
        };
        // A loaded link: the beams' torque error above the corner puts the gear in the loop.
        // Held in the count with a still link: no J_g·Δω_g/dt (noise) in the torque error.
        let held = in_count && stationary;
        let tau_p = if held && libm::fabsf(self.w_link) < s.w_deadband {
            tau + gear_inertial
        } else {
            tau
        };
        let torque_error_hp = tau_p - tau_ref - self.torque_error_lp;
        self.torque_error_lp += s.torque_lp_beta * torque_error_hp;
        let e_p = if floating {
            e_g
        } else if self.traj.is_sine() {
            e
        } else {
            e - s.inv_k * torque_error_hp
        };
        let u_p = if resting { 0.0 } else { s.kp * soft_p * e_p };
        let u = u_ff
            + u_creep
            + u_defl
            + u_coulomb
            + u_p
            + u_i
            // Held, a gear velocity below an eighth of the dead band is noise: no damping.
            + if held
                && libm::fabsf(self.w_fb)
                    < s.w_deadband / (1u32 << HELD_DAMPING_DEADBAND_SHIFT) as f32
            {
                0.0
            } else {
                s.kd * soft_d * (self.w_ref - self.w_fb)
            };

        // --- limits ---
        let emf = s.duty_per_w * w_gear;
        let di = s.duty_per_amp * s.i_win;
        let dl = s.duty_lim;
        let (hi_i, lo_i) = (emf + di, emf - di);
        let (mut hi, mut lo) = (hi_i.min(dl), lo_i.max(-dl));
        if lo > hi {
            let v = emf.clamp(-dl, dl);
            hi = v;
            lo = v;
        }
        let contact_bound = s.contact_torque + s.contact_per_amp * libm::fabsf(current);
        let closing = w_gear - self.w_link;
        // The impact speed for the drive the command met.
        let impact_speed = s.impact_speed
            * self
                .traj
                .impact()
                .min(1.0 / libm::sqrtf(self.move_drive.scale));
        // The back-EMF of a speed most of the way from the gear's to the link's.
        let emf_link = s.duty_per_w * self.w_link;
        let matched =
            (emf_link - (emf_link - emf) / (1u32 << IMPACT_MATCH_SHIFT) as f32).clamp(lo, hi);
        // Held on a side, the limit stays there while the gear closes that fast.
        let held = self.impact_side;
        self.impact_side = 0;
        if (tau <= contact_bound || held > 0) && closing > impact_speed {
            hi = hi.min(matched);
            self.impact_side = 1;
        }
        if (tau >= -contact_bound || held < 0) && closing < -impact_speed {
            lo = lo.max(matched);
            self.impact_side = -1;
        }
        let probe = match self.probe_ticks {
            2 => self.probe,
            1 => -self.probe,
            _ => 0.0,
        };
        self.probe_ticks = self.probe_ticks.saturating_sub(1);
        let mut u = u + probe;
        if r.velocity == 0.0
            && r.acceleration == 0.0
            && libm::fabsf(w_gear) > s.brake_min_w
            && (w_gear > 0.0) == (e > 0.0)
            && e != 0.0
            && w_gear * w_gear > s.two_a_brake * libm::fabsf(e)
        {
            u = if w_gear > 0.0 { f32::MIN } else { f32::MAX };
        }
        let sat_hi = u > hi;
        let sat_lo = u < lo;
        let uc = u.clamp(lo, hi);
        let (duty_hi, duty_lo) = (sat_hi && hi == dl, sat_lo && lo == -dl);
        self.limited = f32::from(i8::from(duty_hi) - i8::from(duty_lo));
        let at_current = (sat_hi && hi == hi_i) || (sat_lo && lo == lo_i);
        let flags = FloatFlags {
            torque_limited: (at_current && s.i_lim_from_beams) || libm::fabsf(tau) > s.tau_lim,
            current_limited: at_current && !s.i_lim_from_beams,
            duty_saturated: duty_hi || duty_lo,
        };

        // --- integrator ---
        let inc = if in_count || resting {
            let slip = w_gear - r.velocity - creep_w;
            let band = s.w_deadband
                + s.w_bias_per_amp * libm::fabsf(current)
                + s.w_bias_per_duty * libm::fabsf(f32::from(applied));
            if libm::fabsf(slip) <= band || !stationary {
                0.0
            } else {
                -s.kp_dt * slip
            }
        } else if libm::fabsf(e_p) < s.int_band
            || (stationary && libm::fabsf(self.w_link) < s.w_deadband)
        {
            // The press wound in beyond a count, for a loaded link (`creep::wind`).
            let wind = if !floating && e_abs > 2.0 * HALF_COUNT {
                u_creep / (1u32 << PRESS_WIND_SHIFT) as f32
            } else {
                0.0
            };
            s.ki_dt * soft_i * e_p + wind
        } else {
            0.0
        };
        if inc != 0.0 && !((sat_hi && inc > 0.0) || (sat_lo && inc < 0.0)) {
            self.integ = (self.integ + inc).clamp(-dl, dl);
        }

        self.traj.drive(uc - u_vel - u_i - probe, u_acc);
        // A loaded move's drive against the model's: the r̈ feed-forward's scale.
        if !floating {
            self.move_drive
                .take(uc - u_vel - u_i - probe - u_defl, u_acc_model);
        }
        let duty = libm::floorf(uc + 0.5).clamp(-1000.0, 1000.0) as i16;
        self.hunt.update(stationary, duty);
        self.duty_prev = duty;
        FloatOutput {
            duty,
            flags,
            torque_estimate: tau,
            reference: r.position,
            link_angle: theta_l,
            gear_velocity: w_gear,
            link_velocity: self.w_link,
            current,
        }
    }
}

/// The supervisor's thresholds in f32 and its latch (the port of `Supervisor`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FloatSupervisor {
    trip_adc: i32,
    adc_min: u16,
    adc_max: u16,
    max_jump_counts: i32,
    max_pot_jump: i32,
    stuck_ticks: u16,
    torque_cap: f32,
    envelope: f32,
    pot_center: i32,
    position_min: f32,
    position_max: f32,
    timeout_ticks: u32,
    overload_ticks: u16,
    over_ticks: u16,
    latched: FaultSet,
    prev_encoder: Option<u16>,
    prev_pot: Option<u16>,
    unchanged_ticks: u16,
    last_heartbeat: Option<u32>,
}

/// Engineering value → millionths, saturated (µrad, µN·m).
fn to_micro(v: f32) -> i32 {
    // `as` saturates at the i32 range.
    (v * 1e6) as i32
}

impl FloatSupervisor {
    /// The thresholds of the fixed-point supervisor `sup` in f32 (`pot_center` from the
    /// controller's sensor calibration).
    #[must_use]
    pub fn new(sup: &Supervisor, pot_center: u16) -> Self {
        let cfg = sup.config();
        FloatSupervisor {
            trip_adc: ((cfg.trip_current_a.to_bits() * i64::from(sensors::ADC_COUNTS_PER_A)) >> 32)
                as i32,
            adc_min: cfg.adc_min,
            adc_max: cfg.adc_max,
            max_jump_counts: sup.max_jump_counts(),
            max_pot_jump: i32::from(cfg.max_pot_jump),
            stuck_ticks: cfg.stuck_ticks,
            // The capacity the overload check uses (the clutch tolerance's weak one; the
            // port has no clutch monitor).
            torque_cap: i32f32(sup.checked_capacity().to_bits()),
            envelope: i32f32(sup.deflection_envelope().to_bits()),
            pot_center: i32::from(pot_center),
            position_min: i32f32(cfg.position_min.to_bits()),
            position_max: i32f32(cfg.position_max.to_bits()),
            timeout_ticks: cfg.command_timeout_ms,
            overload_ticks: cfg.overload_ticks,
            over_ticks: 0,
            latched: FaultSet(0),
            prev_encoder: None,
            prev_pot: None,
            unchanged_ticks: 0,
            last_heartbeat: None,
        }
    }

    /// The latched faults.
    #[must_use]
    pub const fn latched(&self) -> FaultSet {
        self.latched
    }

    fn latch(&mut self, code: FaultCode, value: i32, tick: u32) -> Option<Fault> {
        if self.latched.contains(code) {
            return None;
        }
        self.latched.0 |= code.bit();
        Some(Fault { code, value, tick })
    }

    /// The per-tick checks (the port of `Supervisor::check`): returns the first fault
    /// newly latched in this tick.
    pub fn check(&mut self, tick: u32, r: &TickInput, out: &FloatOutput) -> Option<Fault> {
        let mut new: Option<Fault> = None;
        let mut note = |s: &mut Self, code: FaultCode, value: i32| {
            if let Some(f) = s.latch(code, value, tick) {
                if new.is_none() {
                    new = Some(f);
                }
            }
        };
        if let Some(sensor) = r.read_error {
            note(self, FaultCode::SensorRead, sensor as i32);
        }
        if r.current_adc < self.adc_min || r.current_adc > self.adc_max {
            note(self, FaultCode::AdcOutOfRange, i32::from(r.current_adc));
        } else {
            let adc = i32::from(r.current_adc) - ADC_MID;
            if adc.abs() > self.trip_adc {
                note(
                    self,
                    FaultCode::OverCurrent,
                    adc * 1000 / i32::from(sensors::ADC_COUNTS_PER_A),
                );
            }
        }
        let mut link_moved = true;
        if let Some(prev) = self.prev_encoder {
            let d = encoder_delta(r.link_encoder, prev);
            if d.abs() > self.max_jump_counts {
                note(self, FaultCode::SensorJump, d);
            }
            link_moved = d != 0;
        }
        self.prev_encoder = Some(r.link_encoder);
        self.unchanged_ticks = if link_moved {
            0
        } else {
            self.unchanged_ticks.saturating_add(1)
        };
        if let Some(pot) = r.gear_pot {
            if let Some(prev) = self.prev_pot {
                let d = i32::from(pot) - i32::from(prev);
                if d.abs() > self.max_pot_jump {
                    note(self, FaultCode::SensorJump, d);
                }
            }
            self.prev_pot = Some(pot);
            let theta_g = (i32::from(pot) - self.pot_center) as f32 * POT_COUNT;
            let phi = theta_g - out.link_angle;
            if libm::fabsf(phi) > self.envelope {
                let tau = libm::fabsf(out.torque_estimate);
                if self.unchanged_ticks >= self.stuck_ticks && tau < self.torque_cap / 2.0 {
                    note(self, FaultCode::SensorStuck, to_micro(phi));
                } else {
                    note(self, FaultCode::BeamOverload, to_micro(phi));
                }
            }
        } else {
            self.prev_pot = None;
        }
        let tau = out.torque_estimate;
        if libm::fabsf(tau) > self.torque_cap {
            self.over_ticks = self.over_ticks.saturating_add(1);
            if self.over_ticks >= self.overload_ticks {
                note(self, FaultCode::BeamOverload, to_micro(tau));
            }
        } else {
            self.over_ticks = 0;
        }
        let theta = out.link_angle;
        if theta < self.position_min || theta > self.position_max {
            note(self, FaultCode::PositionLimit, to_micro(theta));
        }
        if let Some(last) = self.last_heartbeat {
            let since = tick.wrapping_sub(last);
            if since > self.timeout_ticks {
                note(
                    self,
                    FaultCode::CommandTimeout,
                    i32::try_from(since).unwrap_or(i32::MAX),
                );
            }
        }
        new
    }
}

/// Enable state of the f32 servo.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FloatServoState {
    /// Motor off.
    Disabled,
    /// Driving.
    Enabled,
    /// A fault is latched.
    Faulted,
}

/// One tick's decision of the f32 servo (as `model::servo::TickOutput`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FloatTickOutput {
    /// Tick number.
    pub tick: u32,
    /// What the H-bridge must do.
    pub bridge: BridgeDemand,
    /// The controller's output.
    pub control: FloatOutput,
    /// A fault latched in this tick.
    pub new_fault: Option<Fault>,
    /// State after the tick.
    pub state: FloatServoState,
}

/// The f32 controller under the f32 supervisor, with the enable state (the port of
/// `model::servo::Servo`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FloatServo {
    controller: FloatController,
    supervisor: FloatSupervisor,
    state: FloatServoState,
    tick: u32,
    was_off: bool,
}

impl FloatServo {
    /// A disabled servo mirroring the fixed-point `servo` as configured with `config`.
    #[must_use]
    pub fn new(servo: &model::servo::Servo, config: &Config) -> Self {
        let sched = FloatSchedule::new(servo.controller().schedule(), config);
        FloatServo {
            controller: FloatController::new(sched),
            supervisor: FloatSupervisor::new(servo.supervisor(), config.sensors.pot_center),
            state: FloatServoState::Disabled,
            tick: 0,
            was_off: true,
        }
    }

    /// The state.
    #[must_use]
    pub const fn state(&self) -> FloatServoState {
        self.state
    }

    /// The latched faults.
    #[must_use]
    pub const fn faults(&self) -> FaultSet {
        self.supervisor.latched()
    }

    /// Turns the motor on from `Disabled` (controller reset); refused while faulted.
    pub fn enable(&mut self) -> bool {
        match self.state {
            FloatServoState::Faulted => false,
            FloatServoState::Enabled => true,
            FloatServoState::Disabled => {
                self.controller.reset();
                self.state = FloatServoState::Enabled;
                true
            }
        }
    }

    /// Gives the controller a command (refused while faulted).
    pub fn command(&mut self, cmd: Command) -> bool {
        if self.state == FloatServoState::Faulted {
            return false;
        }
        self.controller.command(cmd);
        true
    }

    /// One 1 kHz tick (the port of `Servo::tick`).
    pub fn tick(&mut self, input: &TickInput) -> FloatTickOutput {
        self.tick = self.tick.wrapping_add(1);
        let m = FloatMeasurements {
            link_encoder: input.link_encoder,
            gear_pot: input.gear_pot,
            current_adc: input.current_adc,
            applied_duty: if self.was_off { Some(0) } else { None },
        };
        let control = self.controller.step(&m);
        let new_fault = self.supervisor.check(self.tick, input, &control);
        if new_fault.is_some() {
            self.state = FloatServoState::Faulted;
            self.was_off = true;
        }
        let bridge = if self.state == FloatServoState::Enabled {
            BridgeDemand::Drive(control.duty)
        } else if self.state == FloatServoState::Faulted && brakes_on(self.supervisor.latched()) {
            BridgeDemand::Brake
        } else {
            BridgeDemand::Off
        };
        self.was_off = !matches!(bridge, BridgeDemand::Drive(_));
        FloatTickOutput {
            tick: self.tick,
            bridge,
            control,
            new_fault,
            state: self.state,
        }
    }
}

/// L in mm as f32 (configuration time).
#[must_use]
pub fn length_mm(len: Length) -> f32 {
    i32f32(len.to_bits())
}

/// k in N·m/rad as f32 (configuration time).
#[must_use]
pub fn stiffness_nm_per_rad(k: Stiffness) -> f32 {
    fx(k.to_bits(), 64)
}
