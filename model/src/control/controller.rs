//! The 1 kHz link-position controller (see the [`crate::control`] module docs for the
//! design and the scheduling formulas).

use fixed::types::I32F32;

use super::catch::{CatchHold, Rest};
use super::config::Config;
use super::creep::Creep;
use super::duty_jump::{self, DutyJump};
use super::error::ControlError;
use super::gain::{q16_to_q32, q32_to_q16, sat_i32, scale_q16, Q16_ONE};
use super::hunt::Hunt;
use super::move_drive::MoveDrive;
use super::move_duration;
use super::rest_resistance::UNCALIBRATED_OFFSET_Q16;
use super::schedule::{
    Schedule, CURRENT_GAIN_TOLERANCE_DIV, HELD_DAMPING_DEADBAND_SHIFT, IMPACT_MATCH_SHIFT,
    TICKS_PER_S,
};
use super::sine_feedforward::FeedForward;
use super::speed_scale::SpeedScale;
use super::trajectory::{Command, Reference, Trajectory};
use crate::design::Design;
use crate::sensors::{
    encoder_delta, turn_fraction_bits, ADC_COUNTS_PER_A, ADC_MID, ENCODER_COUNTS,
    ENCODER_HALF_COUNT_Q32, POT_COUNTS, POT_COUNT_Q32,
};
use crate::units::{Angle, Torque};

/// One encoder count per tick (1000 ticks/s) as a velocity, 2π/4096 rad · 1000 /s, Q16
/// (1.534 rad/s).
pub(super) const COUNT_PER_TICK_Q16: i32 =
    turn_fraction_bits(1000, ENCODER_COUNTS as u64, 16) as i32;
/// Ticks in a row the rest hold's conditions must hold before it starts (20 ms).
const REST_TICKS: u8 = 20;
/// ADC counts → A in Q16: 1024 counts/A, so ×64.
const ADC_TO_Q16_SHIFT: u32 = 6;

const _: () = assert!((ADC_COUNTS_PER_A as i32) << ADC_TO_Q16_SHIFT == Q16_ONE);

/// Raw sensor values as the board reads them in this tick.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Measurements {
    /// Link magnetic encoder, counts 0..=4095 per revolution (wraps; higher bits ignored).
    pub link_encoder: u16,
    /// Gear potentiometer, counts 0..=1023 over 300°, if the board has one. `None`: the
    /// torque estimate uses the current only.
    pub gear_pot: Option<u16>,
    /// Motor current ADC, counts 0..=4095, 2048 at 0 A, 1024 counts/A.
    pub current_adc: u16,
    /// The duty (‰) the H-bridge actually applied during the last tick, if it differs from
    /// the controller's previous output (e.g. the supervisor disabled the motor: report 0).
    /// `None`: the controller's previous output. Used by the back-EMF observer.
    pub applied_duty: Option<i16>,
}

/// Live limits active in this tick (clamps, not faults).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Flags {
    /// The coupling torque is being limited to margin·τ_cap(L): the current clamp that
    /// protects the beams is active, or the torque estimate exceeds the limit.
    pub torque_limited: bool,
    /// The motor current (or motor torque) limit clamps the output.
    pub current_limited: bool,
    /// The duty is clamped at ±`max_duty`.
    pub duty_saturated: bool,
}

impl Flags {
    /// Any limit active.
    #[must_use]
    pub const fn any(&self) -> bool {
        self.torque_limited || self.current_limited || self.duty_saturated
    }
}

/// What the controller decided in one tick, and what it estimated.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Output {
    /// Signed PWM duty for the H-bridge, ‰, in ±`max_duty` (≤ ±1000).
    pub duty: i16,
    /// Live limits.
    pub flags: Flags,
    /// Estimated coupling torque on the link, N·m (resolution 1.5e-5 N·m).
    pub torque_estimate: Torque,
    /// The same from the motor side alone, k_t·i − J_g·ω̇_g − b_v·ω_g through the derivative
    /// filter (the pot not used), N·m Q16 (saturated to ±32 768 N·m): what the clutch
    /// monitor regresses the deflection on.
    pub motor_torque_q16: i32,
    /// Link-angle reference r of this tick, rad.
    pub reference: Angle,
    /// Measured link angle (centre of the encoder count), rad, unwrapped.
    pub link_angle: Angle,
    /// Gear velocity from the back-EMF observer, rad/s (I32F32, resolution 1.5e-5).
    pub gear_velocity: I32F32,
    /// Link velocity from the encoder difference through the derivative filter, rad/s.
    pub link_velocity: I32F32,
    /// Motor current, A.
    pub current: I32F32,
}

#[cfg(feature = "defmt")]
impl defmt::Format for Output {
    fn format(&self, f: defmt::Formatter<'_>) {
        // Raw bits, cheap enough for the 1 kHz path.
        defmt::write!(
            f,
            "Output(duty={=i16}, {}, tau={=i64}, r={=i64}, th={=i64})",
            self.duty,
            self.flags,
            self.torque_estimate.to_bits(),
            self.reference.to_bits(),
            self.link_angle.to_bits()
        );
    }
}

/// The link-position controller: trajectory, PID with feed-forward, free-play
/// compensation, torque estimate and limits. No allocation, no floats, no panics.
#[derive(Clone, Debug)]
pub struct Controller {
    design: Design,
    config: Config,
    sched: Schedule,
    traj: Trajectory,
    /// Feed-forward gains of the running reference (the two-mass inverse for a sine).
    ff: FeedForward,
    started: bool,
    commanded: bool,
    enc_prev: u16,
    /// Unwrapped link angle, encoder counts relative to `encoder_zero`.
    n_link: i32,
    /// Filtered link velocity, rad/s Q16.
    w_link: i32,
    /// Filtered gear velocity for the derivative term, rad/s Q16.
    w_fb: i32,
    /// Filtered reference velocity, rad/s Q16.
    w_ref: i32,
    /// Filtered gear velocity of the previous tick (torque estimate), rad/s Q16.
    w_gear_prev: i32,
    /// Motor current through the derivative filter (torque estimate), A Q16.
    i_filtered: i32,
    /// The side the free-play impact limit held the duty on at the last tick (+1 from
    /// above, −1 from below, 0 none): it holds until the closing speed is back under the
    /// impact speed (`Window::new`).
    impact_side: i8,
    /// Integrator, duty ‰ in Q32 (I32F32 bits).
    integ: i64,
    /// Hunting at rest (large duty reversals in quick succession).
    hunt: Hunt,
    /// The creep at rest.
    creep: Creep,
    duty_prev: i16,
    /// Deflection feed-forward of the previous tick, rad Q16, and whether it is valid.
    defl_prev: i32,
    defl_valid: bool,
    /// Its elastic part (the hysteresis band's state), rad Q16.
    elastic_prev: i32,
    /// Gear angle estimate, rad Q32: the observer's gear velocity integrated, pulled
    /// towards θ_l + φ_ref at the rate ω_o (a complementary filter: the gear from the
    /// motor above ω_o, from the link encoder below), and whether it is set.
    theta_g: i64,
    theta_g_valid: bool,
    /// The observer's velocity bias the complementary filter found, rad/s Q32.
    w_bias: i64,
    /// Ticks in a row the rest hold's conditions have held.
    rest_ticks: u8,
    /// τ̂ − τ_ref through a low-pass at `TORQUE_FEEDBACK_CORNER`·ω_c, N·m Q16.
    torque_error_lp: i32,
    /// The side the output was clamped at the duty limit in the last tick (+1, −1, 0).
    limited: i8,
    /// The running move's drive sums and its r̈ feed-forward scale.
    move_drive: MoveDrive,
    /// The running move's velocity feed-forward scale.
    speed_scale: SpeedScale,
    /// The observer's resistance from a raw step's or a probed command's first duty jump.
    duty_jump: DutyJump,
    /// The catch of a floating link at rest.
    catch: CatchHold,
}

impl Controller {
    /// A controller for `design` configured with `config`, holding the link where the
    /// first measurement finds it.
    ///
    /// # Errors
    /// As [`Schedule::new`].
    pub fn new(design: &Design, config: &Config) -> Result<Controller, ControlError> {
        let sched = Schedule::new(design, config)?;
        Ok(Controller {
            design: *design,
            config: *config,
            ff: FeedForward::rigid(&sched),
            sched,
            traj: Trajectory::new(Angle::ZERO),
            started: false,
            commanded: false,
            enc_prev: 0,
            n_link: 0,
            w_link: 0,
            w_fb: 0,
            w_ref: 0,
            w_gear_prev: 0,
            i_filtered: 0,
            impact_side: 0,
            integ: 0,
            hunt: Hunt::NEW,
            creep: Creep::NEW,
            catch: CatchHold::NEW,
            duty_prev: 0,
            defl_prev: 0,
            torque_error_lp: 0,
            limited: 0,
            defl_valid: false,
            elastic_prev: 0,
            theta_g: 0,
            theta_g_valid: false,
            w_bias: 0,
            rest_ticks: 0,
            move_drive: MoveDrive::NEW,
            speed_scale: SpeedScale::NEW,
            duty_jump: DutyJump::NEW,
        })
    }

    /// Replaces the configuration (clutch moved, new inertia, limits or gains). The new
    /// schedule is computed first: on error the running configuration is untouched. The
    /// controller state (integrator, filters, trajectory) carries over.
    ///
    /// # Errors
    /// As [`Schedule::new`]; [`ControlError::Overflow`] if a running sine's feed-forward
    /// does not fit its format.
    pub fn configure(&mut self, config: &Config) -> Result<(), ControlError> {
        let sched = Schedule::new(&self.design, config)?;
        self.install(sched, config)
    }

    /// Takes `other`'s configuration (its schedule, feed-forward and parameters, all
    /// derived already) and keeps this controller's state: the integrator, filters and
    /// trajectory go on. The same as [`Controller::configure`] with `other`'s
    /// configuration, without its maths.
    ///
    /// # Errors
    /// As [`Controller::configure`]: a running sine's feed-forward that does not fit.
    pub fn adopt(&mut self, other: &Controller) -> Result<(), ControlError> {
        self.install(other.sched, &other.config)
    }

    /// Puts a derived schedule and its configuration in force, the state kept.
    fn install(&mut self, sched: Schedule, config: &Config) -> Result<(), ControlError> {
        self.ff = self.ff.reconfigure(&sched, config)?;
        self.sched = sched;
        self.config = *config;
        self.defl_valid = false;
        Ok(())
    }

    /// The configuration in use.
    #[must_use]
    pub const fn config(&self) -> &Config {
        &self.config
    }

    /// The gain schedule in use.
    #[must_use]
    pub const fn schedule(&self) -> &Schedule {
        &self.sched
    }

    /// The reference generator.
    #[must_use]
    pub const fn trajectory(&self) -> &Trajectory {
        &self.traj
    }

    /// Starts a trajectory command from the current reference state (before the first
    /// [`Controller::step`], from 0 rad).
    ///
    /// # Errors
    /// [`ControlError::TrajectoryOutOfRange`]; the running trajectory is untouched.
    pub fn command(&mut self, cmd: Command) -> Result<(), ControlError> {
        let ff = FeedForward::for_command(&self.sched, &self.config, &cmd)?;
        let from = self.traj.reference().position.to_bits();
        // The integrator holds a load: the link is not floating.
        let loaded = q32_to_q16(self.integ).saturating_abs() >= self.sched.float_load_q16;
        // A raw step from rest reads the observer's resistance from its duty jump, a move
        // from rest (or a loaded raw step through the shaper, whose first tick carries half
        // the profile's jump) from a probe on its first tick (design §11, "The observer's
        // resistance from a command's first tick").
        let from_rest = self.traj.reference().stationary();
        match duty_jump::probed_target(&cmd, self.sched.shaper_ticks != 0, loaded) {
            Some(target) => self.duty_jump.arm_probe(from_rest, target.to_bits() > from),
            None => self
                .duty_jump
                .arm(from_rest && matches!(cmd, Command::Step { .. })),
        }
        match cmd {
            // A raw step runs the near-time-optimal profile, planned with the load the
            // integrator holds now.
            Command::Step { target } => {
                self.traj.step(target, &self.sched, self.plan_hold())?;
            }
            _ => self.traj.command(self.planned(cmd))?,
        }
        // A move counts its drive afresh (design §11, "Moves for the actuator they meet").
        self.move_drive = match cmd {
            Command::Move { target, .. } => MoveDrive::start(from, target.to_bits()),
            _ => MoveDrive::NEW,
        };
        // ... and its velocity feed-forward's scale, for a loaded link (design §11, "The
        // velocity feed-forward for the actuator a move meets").
        self.speed_scale = match cmd {
            Command::Move { .. } => SpeedScale::start(self.gear_at(self.link_angle()), loaded),
            // ... and a raw step's damping for the motor's back-EMF constant (design §11,
            // "The damping for the motor a raw step meets").
            Command::Step { .. } => SpeedScale::start_raw(self.gear_at(self.link_angle()), loaded),
            _ => SpeedScale::NEW,
        };
        self.ff = ff;
        self.commanded = true;
        self.catch = CatchHold::NEW;
        Ok(())
    }

    /// `cmd` as [`Controller::command`] runs it now: a move no shorter than the limits
    /// allow with the load the integrator holds ([`move_duration`]), anything else as it
    /// is. Out of line: configuration-time work (a 128-bit division, a square root) that
    /// a caller's per-tick code should not carry inlined.
    #[must_use]
    #[inline(never)]
    pub fn planned(&self, cmd: Command) -> Command {
        match cmd {
            Command::Move {
                target,
                duration_ms,
            } => Command::Move {
                target,
                duration_ms: duration_ms.max(move_duration::shortest_ms(
                    &self.sched,
                    self.traj.reference().position.to_bits(),
                    target.to_bits(),
                    self.plan_hold(),
                )),
            },
            other => other,
        }
    }

    /// The load a command is planned with, ‰ Q16: the integrator's hold, but for a still
    /// hold (a standing reference, the link still, no hunt) that takes more than half the
    /// current limit in duty, no more than the duty the measured current needs through the
    /// configured R (plus the sense's gain tolerance and the offset an uncalibrated sense
    /// may have; below half the limit the configured duty's margin stays: heavy links lean
    /// on it). A warm motor or a sagging supply hold a load with R/R̂·V̂/V more duty than the
    /// configured motor would, and a plan on that duty found no headroom: a move stretched
    /// from 295 ms to 4.5 s (design §11, "Runs that ended far off"). A hunting hold's
    /// current swings with its duty and says nothing of the load.
    fn plan_hold(&self) -> i32 {
        let u_i = q32_to_q16(self.integ);
        let starved = u_i.saturating_abs() > self.sched.i_lim_duty_q16 >> 1;
        let still = starved
            && self.traj.reference().stationary()
            && self.w_link.saturating_abs() < self.sched.w_deadband_q16
            && !self.hunt.hunting();
        if !still {
            return u_i;
        }
        let i = self.i_filtered.saturating_abs();
        let i = i
            .saturating_add(i / CURRENT_GAIN_TOLERANCE_DIV)
            .saturating_add(UNCALIBRATED_OFFSET_Q16 as i32);
        let by_current = self.sched.duty_per_amp.apply(i);
        if u_i.saturating_abs() <= by_current {
            u_i
        } else if u_i < 0 {
            -by_current
        } else {
            by_current
        }
    }

    /// Moves the reference to `target` at once, without the raw step's profile: the
    /// impedance command's per-tick reference ([`super::impedance`]).
    ///
    /// # Errors
    /// [`ControlError::TrajectoryOutOfRange`]; the running trajectory is untouched.
    pub fn jump(&mut self, target: Angle) -> Result<(), ControlError> {
        self.traj.command(Command::Step { target })?;
        self.duty_jump.arm(false);
        self.ff = FeedForward::rigid(&self.sched);
        self.move_drive = MoveDrive::NEW;
        self.speed_scale = SpeedScale::NEW;
        self.commanded = true;
        self.catch = CatchHold::NEW;
        Ok(())
    }

    /// Forgets the loop state (integrator, filters, encoder unwrapping); the next step
    /// holds the link where it is.
    pub fn reset(&mut self) {
        self.ff = FeedForward::rigid(&self.sched);
        self.started = false;
        self.commanded = false;
        self.w_link = 0;
        self.w_fb = 0;
        self.w_ref = 0;
        self.w_gear_prev = 0;
        self.i_filtered = 0;
        self.impact_side = 0;
        self.integ = 0;
        self.hunt = Hunt::NEW;
        self.creep = Creep::NEW;
        self.catch = CatchHold::NEW;
        self.duty_prev = 0;
        self.defl_valid = false;
        self.theta_g_valid = false;
        self.w_bias = 0;
        self.rest_ticks = 0;
        self.torque_error_lp = 0;
        self.limited = 0;
        self.move_drive = MoveDrive::NEW;
        self.speed_scale = SpeedScale::NEW;
        // No probe or estimate from a command given before the restart.
        self.duty_jump = DutyJump::NEW;
    }

    /// After [`Controller::step`], outside the control step (the service's per-tick work,
    /// as the rest resistance's window): a raw step's or a move's first duty jump for the
    /// observer's resistance (design §11, "The observer's resistance from a command's first
    /// tick"), then a loaded move's observer velocity, current and gear travel for its
    /// velocity feed-forward's scale (design §11, "The velocity feed-forward for the
    /// actuator a move meets"). `out` is that step's output.
    pub fn track_speed(&mut self, out: &Output) {
        let s = &mut self.sched;
        let stationary = self.traj.reference().stationary();
        // The current back in sense counts (1024 per A: Q16 A >> 6, exact).
        let counts = (out.current.to_bits() >> (16 + ADC_TO_Q16_SHIFT)) as i32;
        let quiet = stationary
            && q32_to_q16(out.link_velocity.to_bits()).saturating_abs() < s.w_deadband_q16
            && q32_to_q16(self.integ).saturating_abs() >= s.float_load_q16;
        if let Some(w) = self.duty_jump.take(
            i32::from(out.duty),
            counts,
            stationary,
            quiet,
            s.w_per_count_cfg_q32,
            s.w_per_duty_q32,
            s.w_step_per_count_q32,
        ) {
            s.w_per_count_q32 = w;
            s.i_win_est_duty_q16 = widened_window(s.i_win_cfg_duty_q16, w, s.w_per_count_cfg_q32);
        }
        // The window for the motor the estimate reads, as far as the load held needs it:
        // widened whole it let lightly loaded holds on a warm motor hunt (design §11, "Runs
        // that ended far off").
        let held = q32_to_q16(self.integ).saturating_abs();
        s.i_win_duty_q16 = s
            .i_win_est_duty_q16
            .min(s.i_win_cfg_duty_q16.max(held.saturating_add(held >> 2)));
        if stationary {
            self.speed_scale.stop();
            self.wind_press(quiet);
        }
        // Over a raw step's fit the damping's filtered gear speed settles on ω̂/s, added
        // after the tick so that the control step pays nothing (design §11, "The damping
        // for the motor a raw step meets").
        let w = q32_to_q16(out.gear_velocity.to_bits());
        let c = self.speed_scale.lead(w);
        if c != 0 {
            self.w_fb = self.w_fb.saturating_add(c);
            // Not a change of the gear's speed: the torque estimate's J_g·Δω̂ skips it.
            self.w_gear_prev = self.w_gear_prev.saturating_add(c);
        }
        self.speed_scale.take(
            w,
            q32_to_q16(out.current.to_bits()),
            self.gear_at(out.link_angle.to_bits()),
            self.sched.alpha,
        );
    }

    /// The press of a loaded link that stands more than a count off a stationary
    /// reference, wound into the hold's integrator (`Creep::wind`; docs/design.md §11,
    /// "The press wound into the hold"): the same conditions as the step's `pressed_off`,
    /// read after the tick, so that it costs the control step nothing. `quiet`: the still
    /// link under a held load that the chattering hold's estimate reads too.
    fn wind_press(&mut self, quiet: bool) {
        let s = &self.sched;
        let e_q32 = self
            .traj
            .reference()
            .position
            .to_bits()
            .saturating_sub(self.link_angle());
        let pressed_beyond =
            quiet && !self.hunt.hunting() && e_q32.saturating_abs() > 2 * ENCODER_HALF_COUNT_Q32;
        let w = self
            .creep
            .wind(pressed_beyond, e_q32 > 0, s.coulomb_duty_q16);
        if w != 0 {
            let lim = q16_to_q32(s.duty_lim_q16);
            self.integ = self.integ.saturating_add(w).clamp(-lim, lim);
        }
    }

    /// The link angle at the centre of its measured (unwrapped) count, I32F32 rad.
    #[inline]
    fn link_angle(&self) -> i64 {
        (2 * i64::from(self.n_link) + 1).saturating_mul(ENCODER_HALF_COUNT_Q32)
    }

    /// The gear's place as the feed-forward plans it with the link at `link`: plus the
    /// deflection of the last tick (I32F32 rad).
    fn gear_at(&self, link: i64) -> i64 {
        link.saturating_add(q16_to_q32(self.defl_prev))
    }

    /// One 1 kHz control step. Total: no panics, saturating arithmetic throughout.
    pub fn step(&mut self, m: &Measurements) -> Output {
        // A reference, not a copy: a copy made the whole schedule a stack frame loaded
        // up front on every tick (most fields are read once, on one branch).
        let s = &self.sched;

        // --- link angle: unwrap, centre of the count, filtered velocity ---
        let delta = if self.started {
            encoder_delta(m.link_encoder, self.enc_prev)
        } else {
            // Counts in [−2048, 2048) relative to the calibrated zero.
            self.n_link = encoder_delta(m.link_encoder, s.encoder_zero);
            0
        };
        self.enc_prev = m.link_encoder;
        self.n_link = self.n_link.saturating_add(delta);
        let theta_l = self.link_angle();
        if !self.started {
            self.started = true;
            if !self.commanded {
                self.traj = Trajectory::new(Angle::from_bits(theta_l));
            }
        }
        let v_raw = delta.saturating_mul(COUNT_PER_TICK_Q16);
        self.w_link = self
            .w_link
            .saturating_add(s.alpha.apply(v_raw.saturating_sub(self.w_link)));

        // --- current and the back-EMF observer of the gear velocity ---
        let adc = i32::from(m.current_adc) - i32::from(ADC_MID);
        let current = adc << ADC_TO_Q16_SHIFT; // A, Q16 (|adc| < 2¹⁶: no overflow)
        let applied = m.applied_duty.unwrap_or(self.duty_prev);
        // Plain i64 products: validation bounds V_s ≤ 100 V, R ≤ 1000 Ω, k_e ≥ 0.01 V·s/rad,
        // so 0 ≤ w_per_duty_q32 < 10·2³² < 2³⁶ and 0 ≤ w_per_count_q32 < 1.6·98·2³² < 2⁴⁰
        // (a raw step's estimate is at most 1.6 times the configured one, `duty_jump`);
        // with |applied| ≤ 2¹⁵ and |adc| < 2¹⁶ the terms are below 2⁵¹ and 2⁵⁶ and their
        // difference below 2⁵⁷: nothing to saturate (the saturating forms cost ~30
        // instructions a tick on Cortex-M3).
        let w_gear =
            q32_to_q16(i64::from(applied) * s.w_per_duty_q32 - i64::from(adc) * s.w_per_count_q32);
        self.w_fb = self
            .w_fb
            .saturating_add(s.alpha.apply(w_gear.saturating_sub(self.w_fb)));

        // --- coupling torque estimate ---
        // Current-based: motor torque minus the gear's inertial and viscous torque, both
        // through the derivative filter F: an imperfect R or k_e makes the observer jump
        // with every duty step, and J_g·Δω_g/dt of that jump is a torque no beam sees.
        self.i_filtered = self
            .i_filtered
            .saturating_add(s.alpha.apply(current.saturating_sub(self.i_filtered)));
        let dw = self.w_fb.saturating_sub(self.w_gear_prev);
        self.w_gear_prev = self.w_fb;
        let gear_inertial = s.gear_inertia_per_dt.apply(dw);
        let tau_i =
            s.kt.apply(self.i_filtered)
                .saturating_sub(gear_inertial)
                .saturating_sub(s.bv.apply(w_gear));
        let tau = match m.gear_pot {
            Some(pot) if s.w_defl_q16 != 0 => {
                let pot = i32::from(pot) & (i32::from(POT_COUNTS) - 1);
                let theta_g = i64::from(pot - s.pot_center).saturating_mul(POT_COUNT_Q32);
                let phi = q32_to_q16(theta_g.saturating_sub(theta_l));
                let mag = phi.saturating_abs().saturating_sub(s.free_play_q16).max(0);
                let phi_e = if phi < 0 { -mag } else { mag };
                let tau_d = s.k.apply(phi_e);
                tau_i.saturating_add(s.w_defl.apply(tau_d.saturating_sub(tau_i)))
            }
            _ => tau_i,
        };

        // --- reference and error (zero inside the reference's encoder count) ---
        let r: Reference = self.traj.advance_limited(i32::from(self.limited));
        // r (a target within `MAX_ANGLE_RAD`, or a link angle the hold started from) and θ_l
        // (an i32 count of 2π/4096 rad, 2²²·⁷ in Q32) are below 2⁵⁵: the plain difference
        // cannot overflow (the M3 has no 64-bit saturating subtract).
        let e_q32 = r.position.to_bits() - theta_l;
        // −½ count ≤ e < ½ count as one unsigned compare.
        let in_count =
            (e_q32.wrapping_add(ENCODER_HALF_COUNT_Q32) as u64) < 2 * ENCODER_HALF_COUNT_Q32 as u64;

        // The integrator's duty (‰ Q16): it is updated at the end of the tick (and read
        // again below when the catch gives back the hold it set aside).
        let mut u_i = q32_to_q16(self.integ);
        let load_abs = u_i.saturating_abs();
        let stationary = r.stationary();

        // --- gear angle: complementary filter of the observer and the link encoder ---
        // The link at the point of its measured count nearest the reference (the encoder
        // cannot tell better), plus the deflection the coupling needs. A still link that a
        // load holds on a wall (the integrator holds more than `PRESSED_LOAD_NM`) at a
        // stationary reference: its count's centre, so that the loop is not content with
        // the neighbouring count (design §11, "A light load one count off").
        let pressed_off = !in_count
            && stationary
            && load_abs >= s.pressed_load_q16
            && self.w_link.saturating_abs() < s.w_deadband_q16
            && !self.hunt.hunting();
        let nearest = if in_count {
            e_q32
        } else if pressed_off {
            0
        } else if e_q32 < 0 {
            -ENCODER_HALF_COUNT_Q32
        } else {
            ENCODER_HALF_COUNT_Q32
        };
        let link = theta_l + nearest;
        // |θ_l| < 2⁵⁵ and the deflection an i32 in Q16 (below 2⁴⁷ in Q32): a plain add
        // (the saturating i64 forms cost ~8 instructions each on the M3).
        let anchor = link + q16_to_q32(self.defl_prev);
        // Under load the beams stay in contact on one side and the link error is the
        // better signal (an observer scale error adds up over a move); the gear loop is for
        // a link that floats in the free play.
        let floating = load_abs < s.float_load_q16;
        if self.theta_g_valid && floating {
            let w = w_gear.saturating_sub(q32_to_q16(self.w_bias));
            self.theta_g = self.theta_g.saturating_add(s.dt.apply_wide(w));
            let pull = q32_to_q16(anchor.saturating_sub(self.theta_g));
            if stationary || self.traj.is_dash() {
                self.theta_g = self.theta_g.saturating_add(s.obs_beta.apply_wide(pull));
                // The observer's bias (current offset, resistance error) integrated out.
                self.w_bias = self.w_bias.saturating_sub(s.obs_beta2.apply_wide(pull));
            } else {
                // A min-jerk move or a sine: the pull is the observer's scale error times
                // the speed; followed at ω_c, the bias held (design §11, "The gear-angle
                // filter during a move").
                self.theta_g = self
                    .theta_g
                    .saturating_add(s.obs_beta_move.apply_wide(pull));
            }
        } else {
            self.theta_g = anchor;
            self.theta_g_valid = true;
        }

        let e = if in_count { 0 } else { q32_to_q16(e_q32) };
        // Rest without load (the integrator holds < `REST_LOAD_NM` and the torque estimate
        // is below `REST_TORQUE_NM`, which a raw step's unwound integrator can hide): while the link is
        // within 1.5·φ_b of a stationary reference the gear stays where it is (no position
        // action; the integrator only holds the gear, as inside the reference's count): a
        // gear that chases the link in the free play throws it from wall to wall, a still
        // one only takes energy out of it at each contact. A load that turns up makes the
        // gear creep, the hold integrates it and the integrator leaves the band.
        let e_abs = q32_to_q16(e_q32).saturating_abs();
        let near = e_abs <= s.rest_zone_q16;
        // After a creep push (below) the zone is twice as wide: a link without friction
        // leaves the push at its speed and drifts between the still gear's walls.
        let calm = load_abs < s.rest_load_q16
            && tau.saturating_abs() < s.rest_torque_q16
            && stationary
            && (near || (self.creep.pushed() && e_abs <= 2 * s.rest_zone_q16));
        // The conditions must hold for `REST_TICKS` in a row: a loaded link passes through
        // them for a few ticks at the end of a raw step (the integrator unwinds).
        self.rest_ticks = if calm {
            self.rest_ticks.saturating_add(1)
        } else {
            0
        };
        let resting = self.rest_ticks >= REST_TICKS;
        // The creep: a still link more than a count off, pushed there at a crawl by a
        // gear reference of ±`CREEP_SPEED`, its velocity feed-forward and the configured
        // Coulomb friction plus a drive that grows while the link does not move
        // (design §11, "The creep at rest"). A pressed link still off its count gets the
        // configured Coulomb friction towards the target (design §11, "A light load one
        // count off").
        let (creep_w, u_creep) = if stationary {
            self.creep.step(
                delta,
                resting,
                in_count,
                pressed_off,
                e_q32,
                self.ff.vel,
                s.coulomb_duty_q16,
            )
        } else {
            self.creep = Creep::NEW;
            (0, 0)
        };
        // The catch of a floating link at rest (docs/design.md §11, "Catching the floating
        // link"): while it has the output the loop's terms, its governor and its integrator
        // rest, and so do their filters.
        if stationary {
            let rest = Rest {
                load_abs,
                e_abs,
                e_q32,
                tau,
                delta,
                w_gear,
                hunting: self.hunt.hunting(),
                still: self.creep.still(),
            };
            let was_caught = self.catch.active();
            if let Some(u) = self
                .catch
                .output(s, &mut self.integ, self.ff.vel, resting, rest)
            {
                return self.caught(u, w_gear, current, tau, tau_i, r.position, theta_l);
            }
            if was_caught {
                // Given back with the integrator it set aside: the deflection's feed-forward
                // starts afresh from this tick's hold (its state rested under the catch, and
                // the restored hold moves the free play's side at once: a one-tick kick of
                // up to 150 ‰ in the rest, design §11, "Catching the floating link").
                u_i = q32_to_q16(self.integ);
                self.defl_valid = false;
            }
        }
        // The position loop acts on the gear: where the gear should be (the reference plus
        // the deflection the coupling needs) minus the gear estimate. The link enters it
        // below ω_o only, so the link's rattle in the free play does not drive the motor.
        // r below 2⁵⁵ (above) plus the deflection below 2⁴⁷: a plain add, as the anchor's.
        let e_g = q32_to_q16(
            (r.position.to_bits() + q16_to_q32(self.defl_prev)).saturating_sub(self.theta_g),
        );

        // Derivative on the measured (gear) velocity; the reference velocity goes through
        // the same filter so that the filter lag does not show up as a tracking error.
        self.w_ref = self
            .w_ref
            .saturating_add(s.alpha.apply(r.velocity_q16.saturating_sub(self.w_ref)));

        // --- feed-forward: trajectory, then free play and compliance ---
        // ṙ's feed-forward as the move's actuator needs it: scaled for its back-EMF and supply.
        let u_vel = self.speed_scale.apply(self.ff.vel.apply(r.velocity_q16));
        // r̈ as the move's actuator needs it: scaled for the drive its acceleration took.
        let accel = self.move_drive.apply(r.acceleration_q16);
        let u_acc = self.ff.acc.apply(accel);
        let u_ff = u_vel.saturating_add(u_acc);
        let tau_ref = s
            .j_link
            .apply(accel)
            .saturating_add(s.torque_per_duty.apply(u_i));
        let side = s
            .fp_slope
            .apply(tau_ref)
            .clamp(-s.free_play_q16, s.free_play_q16);
        let phi0 = s.inv_k.apply(tau_ref);
        let elastic = if self.defl_valid {
            hysteresis_band(self.elastic_prev, phi0, s.hyst_c_q16)
        } else {
            phi0
        };
        self.elastic_prev = elastic;
        let defl = elastic.saturating_add(side);
        let d_defl = if self.defl_valid {
            defl.saturating_sub(self.defl_prev)
        } else {
            0
        };
        let u_defl = s.ff_defl.apply(d_defl);
        // The gear's Coulomb friction ahead of the gear velocity the reference asks for,
        // ṙ + Δφ_ref/dt, ramped in near standstill. Only for a moving reference and a
        // loaded link: at rest the integrator holds the friction, and a floating link's
        // gear loop settled fewer runs with it (design §11, step 7).
        let u_coulomb = if floating || stationary {
            0
        } else {
            let w_gear_ref = r
                .velocity_q16
                .saturating_add(d_defl.saturating_mul(TICKS_PER_S))
                .clamp(-s.coulomb_ramp_q16, s.coulomb_ramp_q16);
            // |w| ≤ 2¹⁶·0.1 and the gain ≤ 2³¹: the product fits, the result ≤ the duty.
            ((i64::from(w_gear_ref) * i64::from(s.coulomb_per_w_q16)) >> 16) as i32
        };
        self.defl_prev = defl;
        self.defl_valid = true;

        // A floating link near its target or following a moving reference: the gear loop at
        // ω_c/2 (K_p/4, K_i/8, K_d/2), so that the gear meets the link's bounces in the
        // free play softly instead of throwing it back (design §11, step 8). The same for
        // a loop that hunts at rest: a heavy link juggled through the free play.
        let soft = u32::from((floating && (near || !stationary)) || self.hunt.hunting());
        // A link in contact: the P term sees the gear, not the link, above the corner. The
        // link plus the deflection the beams show, θ_l + (τ̂ − τ_ref)/k, is the gear's
        // place (collocated with the motor); the link alone, non-collocated, let a link
        // heavier than configured limit-cycle at its anti-resonance (design §11, step 8).
        // Not for a sine: its two-mass feed-forward places the gear, and near the coupling
        // resonance the term cost tracking.
        // Held in the reference's count with a still link (its filtered encoder velocity
        // below the observer's dead band), the gear does not accelerate: τ̂'s J_g·Δω_g/dt
        // is then the difference of two noisy observer samples × J_g/dt (3.2 N·m per
        // rad/s), so it is left out of this error (design §11, "Current-sense noise at rest").
        let held = in_count && stationary;
        let tau_p = if held && self.w_link.saturating_abs() < s.w_deadband_q16 {
            tau.saturating_add(gear_inertial)
        } else {
            tau
        };
        let torque_error_hp = tau_p
            .saturating_sub(tau_ref)
            .saturating_sub(self.torque_error_lp);
        self.torque_error_lp = self
            .torque_error_lp
            .saturating_add(s.torque_lp_beta.apply(torque_error_hp));
        // --- PID (derivative on the filtered link velocity) ---
        let u = u_ff
            .saturating_add(u_creep)
            .saturating_add(u_defl)
            .saturating_add(u_coulomb)
            .saturating_add(if resting {
                0
            } else {
                s.kp.apply(if floating {
                    e_g >> (2 * soft)
                } else if self.traj.is_sine() {
                    e
                } else {
                    e.saturating_sub(s.inv_k.apply(torque_error_hp)) >> (2 * soft)
                })
            })
            .saturating_add(u_i)
            // Held in the count, a filtered gear velocity below an eighth of the dead band
            // (`HELD_DAMPING_DEADBAND_SHIFT`) is noise: damping it made duty noise and, under
            // a load, a creep that walked the link to its count's edge.
            .saturating_add(
                if held
                    && self.w_fb.saturating_abs() < s.w_deadband_q16 >> HELD_DAMPING_DEADBAND_SHIFT
                {
                    0
                } else {
                    s.kd.apply(self.w_ref.saturating_sub(self.w_fb) >> soft)
                },
            );

        // --- limits: current window about the back-EMF, duty limit ---
        let win = Window::new(
            s,
            w_gear,
            self.w_link,
            current,
            tau,
            self.impact_side,
            Some((&self.move_drive, &self.traj)),
        );
        self.impact_side = win.side;
        // Braking governor (raw steps and other jumps of a stationary reference): when
        // the gear approaches the target faster than the available deceleration a_b can
        // stop it, ω_g² > 2·a_b·|e|, brake at the limit now instead of when the linear
        // zone is reached. Products only (no square root).
        // Only beyond the observer's bias bound (current offset, and R error × |i|): with
        // a warm motor its phantom speed follows the duty, and a governor that braked on
        // it chattered at rest under load (duty swinging 1 500 ‰ tick to tick, design §11).
        let dead_band = s
            .w_deadband_q16
            .saturating_add(s.w_bias_per_amp.apply(current.saturating_abs()));
        let probe = self.duty_jump.probe_step();
        let mut u = u.saturating_add(probe);
        if r.velocity_q16 == 0
            && r.acceleration_q16 == 0
            && w_gear.saturating_abs() > s.brake_min_w_q16.saturating_add(dead_band)
            && (w_gear > 0) == (e > 0)
            && e != 0
        {
            let w2 = i64::from(w_gear) * i64::from(w_gear); // Q32
            if w2 > s.two_a_brake.apply_wide(e.saturating_abs()) {
                u = if w_gear > 0 { i32::MIN } else { i32::MAX };
            }
        }
        let c = win.clamp(s, u, tau);
        let (uc, sat_hi, sat_lo) = (c.uc, c.sat_hi, c.sat_lo);

        // --- integrator: not further into a clamp ---
        // Outside the reference's count it integrates K_i·e. Inside, the link error is
        // unmeasurable, but a creeping gear is not: it integrates −K_p·(ω_g − ṙ), i.e. holds
        // the gear where it is with the stiffness K_p, so an imperfect integrator value
        // cannot let the link creep out of the count. Its dead band is the observer's
        // resolution and bias bound (current offset, R error × |i|, supply error × |duty|):
        // a hold that chased the bias of a warm motor, or of a sagging supply, under load
        // hunted (design §11, "The actuator is not the model").
        // Integral separation only while the link moves: a link that stands still far
        // from a stationary reference, the P term (soft, or under a hunt's wound-up
        // integrator) balancing the integrator, stays there unless it integrates (design
        // §11, "Runs that ended far off"). Tested only beyond the band.
        let inc = if in_count || resting {
            let slip = w_gear
                .saturating_sub(r.velocity_q16)
                .saturating_sub(creep_w);
            // Only for a stationary reference: a moving one asks the gear for ṙ plus the
            // deflection's rate (−ṙ at a sine's coupling resonance), and the slip
            // integrated whenever the link crossed the reference's count kicked the hold
            // off by several mrad (design §11, step 8).
            let band = dead_band.saturating_add(s.w_bias_per_duty.apply(i32::from(applied).abs()));
            if slip.saturating_abs() <= band || !stationary {
                0
            } else {
                -s.kp_dt.apply_wide(slip)
            }
        } else if !floating {
            if e.saturating_abs() < s.int_band_q16
                || (stationary && self.w_link.saturating_abs() < s.w_deadband_q16)
            {
                s.ki_dt.apply_wide(e >> (3 * soft))
            } else {
                0
            }
        } else if e_g.saturating_abs() < s.int_band_q16
            || (stationary && self.w_link.saturating_abs() < s.w_deadband_q16)
        {
            s.ki_dt.apply_wide(e_g >> (3 * soft))
        } else {
            0 // integral separation: far from the target the P term saturates anyway
        };
        if inc != 0 && !((sat_hi && inc > 0) || (sat_lo && inc < 0)) {
            let lim = q16_to_q32(s.duty_lim_q16);
            self.integ = self.integ.saturating_add(inc).clamp(-lim, lim);
        }

        // What this output spent on accelerating against what the rigid model asked: a
        // raw step brakes for the actuator it met (design §11, "Braking for the actuator
        // the step met").
        let drive = uc
            .saturating_sub(u_vel)
            .saturating_sub(u_i)
            .saturating_sub(probe);
        self.traj.drive(drive, u_acc);
        // The same for a loaded move, less the deflection's feed-forward: a heavier link or
        // a warm motor scales the r̈ feed-forward of the rest of the move (design §11,
        // "Moves for the actuator they meet"). A floating link's drive is the gear loop's,
        // not the link's acceleration.
        if !floating {
            self.move_drive.take(
                drive.saturating_sub(u_defl),
                r.acceleration_q16,
                self.ff.acc,
            );
        }
        self.finish(
            &c, stationary, tau, tau_i, r.position, theta_l, w_gear, current,
        )
    }

    /// The step's end while the catch has the output `u` (‰ Q16): the same limits, flags
    /// and output as the loop's. Out of line: the loop's ticks keep their code.
    #[inline(never)]
    #[allow(clippy::too_many_arguments)]
    fn caught(
        &mut self,
        u: i32,
        w_gear: i32,
        current: i32,
        tau: i32,
        tau_i: i32,
        reference: Angle,
        theta_l: i64,
    ) -> Output {
        // The catch's output has its own window; the loop's limit starts afresh after it.
        let win = Window::new(&self.sched, w_gear, self.w_link, current, tau, 0, None);
        self.impact_side = 0;
        let c = win.clamp(&self.sched, u, tau);
        self.finish(&c, true, tau, tau_i, reference, theta_l, w_gear, current)
    }

    /// The clamped output's duty, the side it met the duty limit on (the raw step's speed
    /// hold reads it next tick), the hunt's record of the duty, and the step's output.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn finish(
        &mut self,
        c: &Clamped,
        stationary: bool,
        tau: i32,
        tau_i: i32,
        reference: Angle,
        theta_l: i64,
        w_gear: i32,
        current: i32,
    ) -> Output {
        self.limited = c.limited;
        // Rounded to whole ‰ in 32 bits: the window bounds |uc| by the duty limit (below
        // 2²⁷ in Q16), so the add cannot saturate and no 64-bit step is needed.
        let duty = (c.uc.saturating_add(0x8000) >> 16).clamp(-1000, 1000) as i16;
        self.hunt.update(stationary, duty);
        self.duty_prev = duty;
        Output {
            duty,
            flags: c.flags,
            torque_estimate: Torque::from_bits(q16_to_q32(tau)),
            motor_torque_q16: tau_i,
            reference,
            link_angle: Angle::from_bits(theta_l),
            gear_velocity: I32F32::from_bits(q16_to_q32(w_gear)),
            link_velocity: I32F32::from_bits(q16_to_q32(self.w_link)),
            current: I32F32::from_bits(q16_to_q32(current)),
        }
    }
}

/// The output's window, ‰ Q16: the current window about the back-EMF (`hi_i`, `lo_i`)
/// within the duty limit, narrowed against free-play impacts (`hi`, `lo`).
struct Window {
    hi: i32,
    lo: i32,
    hi_i: i32,
    lo_i: i32,
    /// The side the impact limit holds the duty on (+1 from above, −1 from below, 0 none).
    side: i8,
}

impl Window {
    /// The window for the gear speed `w_gear`, the link speed `w_link` (rad/s Q16), the
    /// current (A Q16), the torque estimate `tau` (N·m Q16) and the side the impact limit
    /// held at the last tick (`held`, as `Window::side`), and the running command's drive
    /// (`drive`: the move's and the raw step's, for the impact speed's factor; none under
    /// the catch).
    #[inline(always)]
    fn new(
        s: &Schedule,
        w_gear: i32,
        w_link: i32,
        current: i32,
        tau: i32,
        held: i8,
        drive: Option<(&MoveDrive, &Trajectory)>,
    ) -> Window {
        let emf = s.duty_per_w.apply(w_gear);
        let di = s.i_win_duty_q16;
        let dl = s.duty_lim_q16;
        let (hi_i, lo_i) = (emf.saturating_add(di), emf.saturating_sub(di));
        let (mut hi, mut lo) = (hi_i.min(dl), lo_i.max(-dl));
        if lo > hi {
            // Back-EMF beyond the supply: the least current the bridge can give.
            let v = emf.clamp(-dl, dl);
            hi = v;
            lo = v;
        }
        // Free-play impacts: current that drives the gear across the free play beyond the
        // impact speed would hit the link with more than τ_lim; above that relative speed
        // the duty goes no further that way than the back-EMF of a speed three quarters of
        // the way from the gear's to the link's (the observer lags a duty step: at the
        // gear's own the gear kept braking into a link thrown ahead). Only where the
        // beams carry torque now, on the side of τ̂, may the gear close on the link: a
        // bouncing link leaves the wall it was pushed by, and the gear's next push would hit
        // it. The bound carries the current-based estimate's error, which grows with |i|.
        // Once it holds a side, the limit stays there while the gear closes that fast,
        // whatever τ̂ says: the held duty's own current moves τ̂, and letting it decide
        // each tick made the duty alternate between the limit's and the loop's (design
        // §11, "Free-play impacts", "The limit holds its side").
        let closing = w_gear.saturating_sub(w_link);
        let mut side = 0;
        // Tested per tick against the least impact speed a command's factor gives; the
        // command's own is tested out of line.
        if closing.saturating_abs() > s.impact_speed_low_q16 {
            (hi, lo, side) =
                impact_limit(s, emf, w_link, current, tau, held, closing, hi, lo, drive);
        }
        Window {
            hi,
            lo,
            hi_i,
            lo_i,
            side,
        }
    }

    /// `u` (‰ Q16) clamped to the window, with the flags.
    #[inline(always)]
    fn clamp(&self, s: &Schedule, u: i32, tau: i32) -> Clamped {
        let (hi, lo) = (self.hi, self.lo);
        let sat_hi = u > hi;
        let sat_lo = u < lo;
        // Clamped at the duty limit, by side: the flag, and the raw step's speed hold.
        let dl = s.duty_lim_q16;
        let (duty_hi, duty_lo) = (sat_hi && hi == dl, sat_lo && lo == -dl);
        let at_current = (sat_hi && hi == self.hi_i) || (sat_lo && lo == self.lo_i);
        Clamped {
            uc: u.clamp(lo, hi),
            sat_hi,
            sat_lo,
            limited: i8::from(duty_hi) - i8::from(duty_lo),
            flags: Flags {
                torque_limited: (at_current && s.i_lim_from_beams)
                    || tau.saturating_abs() > s.tau_lim_q16,
                current_limited: at_current && !s.i_lim_from_beams,
                duty_saturated: duty_hi || duty_lo,
            },
        }
    }
}

/// The free-play impact limit past the impact speed (`Window::new`): the window (`hi`,
/// `lo`) narrowed to the back-EMF of a speed three quarters of the way to the link's on
/// the side the gear closes from, and that side (0 where the beams carry the gear's push).
/// Out of line: the loop's ticks mostly do not reach it.
#[inline(never)]
#[allow(clippy::too_many_arguments)]
fn impact_limit(
    s: &Schedule,
    emf: i32,
    w_link: i32,
    current: i32,
    tau: i32,
    held: i8,
    closing: i32,
    hi: i32,
    lo: i32,
    drive: Option<(&MoveDrive, &Trajectory)>,
) -> (i32, i32, i8) {
    // The impact speed for the drive the command met (a heavier link than configured,
    // design §11, "Free-play impacts").
    let factor = drive.map_or(Q16_ONE, |(m, t)| m.impact_q16().min(t.impact_q16()));
    if closing.saturating_abs() <= scale_q16(s.impact_speed_q16, factor) {
        return (hi, lo, 0);
    }
    let contact_bound = s
        .contact_torque_q16
        .saturating_add(s.contact_per_amp.apply(current.saturating_abs()));
    let emf_link = s.duty_per_w.apply(w_link);
    let matched = emf_link
        .saturating_sub(emf_link.saturating_sub(emf) >> IMPACT_MATCH_SHIFT)
        .clamp(lo, hi);
    if closing > 0 && (held > 0 || tau <= contact_bound) {
        (hi.min(matched), lo, 1)
    } else if closing < 0 && (held < 0 || tau >= -contact_bound) {
        (hi, lo.max(matched), -1)
    } else {
        (hi, lo, 0)
    }
}

/// The current window `cfg` (‰ Q16, R̂·i_lim in duty) for the resistance an observer
/// estimate `w` (Q32 rad/s per count) reads against the configured `w_cfg`: R/R̂ = w/w_cfg,
/// the back-EMF constant being the configured one in both. Never narrower than `cfg`
/// (narrowed for a colder motor, an unloaded step on a motor ×0.8 ended 1.8 counts off).
fn widened_window(cfg: i32, w: i64, w_cfg: i64) -> i32 {
    if w <= w_cfg || w_cfg <= 0 {
        return cfg;
    }
    // w < 2⁴⁰ (the schedule's bound): w·2¹⁶ < 2⁵⁶; the ratio is below 1.6 (`duty_jump`'s
    // range) and cfg below 2³¹, so the product fits an i64.
    let ratio = (w << 16) / w_cfg;
    sat_i32((i64::from(cfg) * ratio) >> 16)
}

/// An output clamped to its [`Window`].
struct Clamped {
    /// The output, ‰ Q16.
    uc: i32,
    /// Clamped from above, from below.
    sat_hi: bool,
    sat_lo: bool,
    /// The side it was clamped at the duty limit (+1, −1, 0).
    limited: i8,
    flags: Flags,
}

/// The elastic deflection that carries the torque k·φ₀ through the beams' friction
/// hysteresis (design §2.1, τ = k·φ·(1 ± c·|φ|)), rad Q16: to first order in c·|φ₀| the
/// loading branch needs φ₀ − c·φ₀·|φ₀| and the unloading one φ₀ + c·φ₀·|φ₀|, so the
/// deflections that carry it form the band φ₀ ± c·φ₀². The beams stick inside it
/// (`prev` stays) and move only when an edge pushes them (a play operator). `c_q16` is c
/// in Q16 (per rad), below 2³¹.
fn hysteresis_band(prev: i32, phi0: i32, c_q16: i32) -> i32 {
    // |φ₀| ≤ 1 rad (2¹⁶; the beams break far below): c·|φ₀| < 2³¹ and h < 2³¹ in Q16,
    // two multiplies with constant shifts.
    let a = phi0.unsigned_abs().min(1 << 16) as i32;
    let c_phi = ((i64::from(c_q16) * i64::from(a)) >> 16) as i32;
    let h = ((i64::from(c_phi) * i64::from(a) + (1 << 15)) >> 16) as i32;
    // max/min rather than clamp: h ≥ 0 orders the bounds, and clamp's check costs a branch.
    prev.max(phi0.saturating_sub(h)).min(phi0.saturating_add(h))
}

#[cfg(test)]
mod tests {
    use super::super::config::{ClutchSetting, GainOverride, PidGains};
    use super::*;
    use crate::units::{Frequency, Inertia, Length, Ratio, Stiffness};

    fn ctl(l: i32) -> Controller {
        Controller::new(&Design::paper(), &Config::paper(Length::from_int(l))).unwrap()
    }

    fn meas(enc: u16, adc: u16) -> Measurements {
        Measurements {
            link_encoder: enc,
            gear_pot: Some(512),
            current_adc: adc,
            applied_duty: None,
        }
    }

    #[test]
    fn the_window_widens_by_the_resistance_the_estimate_reads_and_never_narrows() {
        // Oracle: cfg·w/w_cfg in f64 for a warmer motor, cfg itself otherwise.
        let w_cfg: i64 = 37 << 32; // rad/s per count, Q32 (the order of the paper motor's)
        let cfg: i32 = 350 << 16; // ‰ Q16
        for ratio in [1.0, 1.06, 1.2, 1.34, 1.6] {
            let w = (w_cfg as f64 * ratio) as i64;
            let got = f64::from(widened_window(cfg, w, w_cfg)) / 65536.0;
            let due = 350.0 * ratio;
            assert!((got - due).abs() < 0.01, "×{ratio}: {got} ‰ against {due}");
        }
        for ratio in [0.7, 0.95] {
            let w = (w_cfg as f64 * ratio) as i64;
            assert_eq!(widened_window(cfg, w, w_cfg), cfg, "×{ratio}");
        }
    }

    #[test]
    fn schedule_matches_the_formulas() {
        let d = Design::paper();
        for l in 1..=5 {
            let s = Schedule::new(&d, &Config::paper(Length::from_int(l))).unwrap();
            let k = s.stiffness().get().to_num::<f64>();
            let wa = (k / 1e-3).sqrt();
            let wc = (wa / 5.0).min(60.0);
            let got = s.bandwidth().get().to_num::<f64>();
            assert!((got - wc).abs() < 1e-6, "L = {l}: ω_c {got} vs {wc}");
            let j = 4.2e-3;
            let c = 1.0 / 8.0;
            let dpv = 1000.0 / 12.0;
            let g = s.gains();
            let kp = 3.0 * wc * wc * j / c * dpv;
            let ki = wc.powi(3) * j / c * dpv;
            let kd = (3.0 * wc * j - (1.94 / 8.0 + 1e-3)).max(0.0) / c * dpv;
            assert!((g.kp.to_num::<f64>() - kp).abs() < 1e-3 * kp);
            assert!((g.ki.to_num::<f64>() - ki).abs() < 1e-3 * ki);
            assert!((g.kd.to_num::<f64>() - kd).abs() < 1e-3 * kd.max(1.0));
            let cap = s.setting().torque_capacity().get().to_num::<f64>();
            // Without a clutch tolerance (the default), τ_cap(L) itself.
            assert_eq!(s.weak_capacity(), s.setting().torque_capacity());
            let (i_lim, beams) = s.current_limit();
            let want = (0.85 * cap).min(1.5);
            assert!((i_lim.to_num::<f64>() - want).abs() < 1e-4, "L = {l}");
            assert_eq!(beams, 0.85 * cap < 1.5);
            // A clutch up to 0.6 mm long: the weak capacity of a clutch that long
            // (τ_cap ∝ 1/L) sets the limit.
            let mut cfg = Config::paper(Length::from_int(l));
            cfg.limits.clutch_tolerance = Length::from_micro(600_000).unwrap();
            let t = Schedule::new(&d, &cfg).unwrap();
            let weak = cap * f64::from(l) / (f64::from(l) + 0.6);
            assert!((t.weak_capacity().get().to_num::<f64>() - weak).abs() < 1e-6);
            let (i_lim, beams) = t.current_limit();
            let want = (0.85 * weak).min(1.5);
            assert!((i_lim.to_num::<f64>() - want).abs() < 1e-4, "L = {l}");
            assert_eq!(beams, 0.85 * weak < 1.5);
            // Blend weight: σ_i² / (σ_i² + (k·q_pot)²/12).
            let sd = k * (300f64.to_radians() / 1024.0);
            let w = 4e-4 / (4e-4 + sd * sd / 12.0);
            let got = s.deflection_weight().to_num::<f64>();
            assert!((got - w).abs() < 1e-4, "L = {l}: w {got} vs {w}");
            // The gear-angle filter's pulls: 2·ω_o·dt, ω_o = ω_c/3 at rest and in a raw
            // step, ω_c in a min-jerk move or a sine; its bias gain (ω_c/3)²·dt.
            let pull = |g: super::super::gain::Gain| g.value().to_num::<f64>();
            assert!(
                (pull(s.obs_beta) - 2.0 * wc / 3.0 * 1e-3).abs() < 1e-6,
                "L = {l}"
            );
            assert!(
                (pull(s.obs_beta_move) - 2.0 * wc * 1e-3).abs() < 1e-6,
                "L = {l}"
            );
            assert!(
                (pull(s.obs_beta2) - (wc / 3.0).powi(2) * 1e-3).abs() < 1e-6,
                "L = {l}"
            );
        }
    }

    /// Oracle: ω_a = √(k/J_l) and τ_m = (J_g + J_l)·R/(k_t·k_e) in f64 from the
    /// configuration's own figures; shaped where ω_a < 300 rad/s and π/ω_a > τ_m.
    #[test]
    fn raw_step_shaper_delay_is_half_the_link_ringing_period_where_the_motor_lags_less() {
        use super::super::shaper::SHAPER_LEN;
        let d = Design::paper();
        // (L mm, J_l kg·mm², the branch expected: 0 stiff, 1 motor lag, 2 shaped, 3 clamped)
        for (l, j, branch) in [
            (1, 1000, 0),
            (3, 1000, 0),
            (5, 1000, 1),
            (7, 1000, 2),
            (8, 5000, 2),
            (8, 6000, 3),
        ] {
            let mut cfg = Config::paper(Length::from_int(l));
            cfg.link_inertia = Inertia::from_int(j);
            let s = Schedule::new(&d, &cfg).unwrap();
            let k = s.stiffness().get().to_num::<f64>();
            let j_l = f64::from(j) * 1e-6;
            let wa = (k / j_l).sqrt();
            let m = cfg.motor;
            let tau_m = (m.rotor_inertia.get().to_num::<f64>() * 1e-6 + j_l)
                * m.resistance_ohm.to_num::<f64>()
                / (m.torque_constant.to_num::<f64>() * m.back_emf.to_num::<f64>());
            let half = core::f64::consts::PI / wa;
            let longest = SHAPER_LEN as f64 - 1.0;
            let want = match branch {
                0 => {
                    assert!(wa >= 300.0, "L = {l}: ω_a {wa}");
                    0
                }
                1 => {
                    assert!(
                        wa < 300.0 && half <= tau_m,
                        "L = {l}: {half} s, τ_m {tau_m} s"
                    );
                    0
                }
                2 => {
                    assert!(half > tau_m && half * 1e3 < longest, "L = {l}: {half} s");
                    (half * 1e3).round() as u8
                }
                _ => {
                    assert!(half * 1e3 > longest, "L = {l}: {half} s");
                    longest as u8
                }
            };
            assert_eq!(s.shaper_ticks, want, "L = {l} mm, J_l {j} kg·mm²");
        }
    }

    #[test]
    fn clutch_by_stiffness() {
        let d = Design::paper();
        let mut cfg = Config::paper(Length::from_int(3));
        cfg.clutch = ClutchSetting::Stiffness(Stiffness::from_int(250));
        let s = Schedule::new(&d, &cfg).unwrap();
        assert!((s.stiffness().get().to_num::<f64>() - 250.0).abs() < 1e-6);
        cfg.clutch = ClutchSetting::Stiffness(Stiffness::from_int(5));
        assert_eq!(
            Schedule::new(&d, &cfg).unwrap_err(),
            ControlError::Beam(crate::Error::StiffnessTooLow)
        );
    }

    #[test]
    fn rejected_configuration_leaves_the_running_one_untouched() {
        let mut a = ctl(3);
        let mut b = ctl(3);
        let good = *a.config();
        let mut bads = [good; 9];
        bads[0].link_inertia = Inertia::ZERO;
        bads[1].clutch = ClutchSetting::Length(Length::from_int(9));
        bads[2].clutch =
            ClutchSetting::Length(Length::from_fixed(fixed::types::I32F32::lit("0.5")));
        bads[3].limits.torque_margin = Ratio::from_int(2);
        bads[4].limits.max_duty = 0;
        bads[5].motor.resistance_ohm = I32F32::ZERO;
        bads[6].gains = GainOverride {
            bandwidth: Some(Frequency::from_int(-1)),
            gains: None,
        };
        bads[7].gains = GainOverride {
            bandwidth: None,
            gains: Some(PidGains {
                kp: I32F32::from_num(-1),
                ki: I32F32::ZERO,
                kd: I32F32::ZERO,
            }),
        };
        bads[8].motor.coulomb = I32F32::from_num(2);
        let want = [
            ControlError::InertiaOutOfRange,
            ControlError::ClutchOutOfRange,
            ControlError::ClutchOutOfRange,
            ControlError::LimitOutOfRange,
            ControlError::LimitOutOfRange,
            ControlError::MotorOutOfRange,
            ControlError::GainOutOfRange,
            ControlError::GainOutOfRange,
            ControlError::MotorOutOfRange,
        ];
        a.command(Command::Move {
            target: Angle::from_int(1),
            duration_ms: 300,
        })
        .unwrap();
        b.command(Command::Move {
            target: Angle::from_int(1),
            duration_ms: 300,
        })
        .unwrap();
        for tick in 0..400u16 {
            let m = meas(tick / 2, 2048 + tick % 7);
            if tick % 50 == 10 {
                let i = usize::from(tick / 50) % bads.len();
                assert_eq!(a.configure(&bads[i]), Err(want[i]));
                assert_eq!(a.config(), &good);
                assert_eq!(a.schedule(), b.schedule());
            }
            assert_eq!(a.step(&m), b.step(&m), "tick {tick}");
        }
        // A valid reconfiguration does take effect.
        a.configure(&Config::paper(Length::from_int(5))).unwrap();
        assert_ne!(a.schedule(), b.schedule());
    }

    #[test]
    fn errors_display() {
        for e in [
            ControlError::Beam(crate::Error::Overflow),
            ControlError::ClutchOutOfRange,
            ControlError::StiffnessOutOfRange,
            ControlError::InertiaOutOfRange,
            ControlError::MotorOutOfRange,
            ControlError::LimitOutOfRange,
            ControlError::GainOutOfRange,
            ControlError::SensorOutOfRange,
            ControlError::TrajectoryOutOfRange,
            ControlError::Overflow,
        ] {
            assert!(!format!("{e}").is_empty());
        }
        assert_eq!(
            format!("{}", ControlError::Beam(crate::Error::Overflow)),
            "beam model: result out of range of its fixed-point format"
        );
    }

    #[test]
    fn step_is_total_and_bounded() {
        // Arbitrary and hostile measurement streams: no panic, duty within the limit.
        let mut c = ctl(5);
        c.command(Command::Step {
            target: Angle::from_int(9_000),
        })
        .unwrap();
        let mut x: u32 = 0x1234_5678;
        for _ in 0..20_000 {
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            let m = Measurements {
                link_encoder: (x & 0xFFFF) as u16,
                gear_pot: if x & 0x1_0000 == 0 {
                    None
                } else {
                    Some((x >> 20) as u16)
                },
                current_adc: (x >> 8) as u16,
                applied_duty: if x & 0x2_0000 == 0 {
                    None
                } else {
                    Some((x >> 3) as i16)
                },
            };
            let o = c.step(&m);
            assert!(o.duty.unsigned_abs() <= 1000);
        }
    }

    #[test]
    fn limits_are_reported() {
        // Link stuck at 0, gear free: a 1 rad jump of the reference drives the current
        // window at once (a raw step's profile starts gently).
        let mut c = ctl(5);
        c.step(&meas(0, 2048));
        c.jump(Angle::from_int(1)).unwrap();
        let o = c.step(&meas(0, 2048));
        // At rest the window is ±R·i_lim·1000/V, i_lim = 0.85·τ_cap(L)/k_t (beam-limited):
        // 0.78 A, 521 ‰.
        let cap = c
            .schedule()
            .setting()
            .torque_capacity()
            .get()
            .to_num::<f64>();
        let window = 8.0 * 0.85 * cap * 1000.0 / 12.0;
        assert!(o.flags.torque_limited && !o.flags.current_limited, "{o:?}");
        assert!(
            (f64::from(o.duty) - window).abs() < 10.0,
            "{} vs {window}",
            o.duty
        );
        let mut c = ctl(1);
        c.step(&meas(0, 2048));
        c.jump(Angle::from_int(1)).unwrap();
        let o = c.step(&meas(0, 2048));
        // L = 1 mm: the motor's rating binds, and the window is sized for copper at 0.8 R:
        // 0.8·1.5 A·8 Ω·1000/12 V = 800 ‰ (a cold motor then draws the full 1.5 A).
        assert!(o.flags.current_limited && !o.flags.duty_saturated && !o.flags.torque_limited);
        assert_eq!(o.duty, 800);
    }

    #[test]
    fn holds_still_at_rest() {
        // At rest in the target count the output is constant (no hunting on quantisation).
        let mut c = ctl(3);
        let mut last = None;
        for _ in 0..1000 {
            let o = c.step(&meas(100, 2048));
            if let Some(l) = last {
                assert_eq!(o.duty, l);
            }
            last = Some(o.duty);
        }
        assert_eq!(last, Some(0));
    }

    /// The band against the §2.1 branches solved exactly in f64: the loading branch
    /// k·φ·(1 + c·|φ|) = τ and the unloading one k·φ·(1 − c·|φ|) = τ have the roots
    /// φ = (√(1 ± 4·c·|φ₀|) ∓ 1)/(2c)·sign(φ₀) (φ₀ = τ/k), which the band's edges match to
    /// second order; a deflection inside the band stays, one outside moves to the edge.
    #[test]
    fn hysteresis_band_holds_the_branches_roots() {
        let q16 = |x: f64| (x * 65_536.0).round() as i32;
        let f = |x: i32| f64::from(x) / 65_536.0;
        for c in [0.25, 1.248, 3.0] {
            let gain = q16(c);
            // c·|φ₀| ≤ 0.05 covers every setting within its capacity (c·φ_cap ≤ 0.02 for the paper preset).
            for phi0 in [-0.1, -0.05, -0.004, 0.0, 0.003, 0.04, 0.12] {
                let a: f64 = phi0;
                if c * a.abs() > 0.05 {
                    continue;
                }
                let loading = a.signum() * ((1.0 + 4.0 * c * a.abs()).sqrt() - 1.0) / (2.0 * c);
                let unloading = a.signum() * (1.0 - (1.0 - 4.0 * c * a.abs()).sqrt()) / (2.0 * c);
                let (lo, hi) = (loading.min(unloading), loading.max(unloading));
                // Second-order agreement: the neglected terms are 2·c²·|φ₀|³ + 5·c³·φ₀⁴ + ….
                let tol = 3.0 * c * c * a.abs().powi(3) + 4.0 / 65_536.0;
                let below = f(hysteresis_band(q16(-1.0), q16(a), gain));
                let above = f(hysteresis_band(q16(1.0), q16(a), gain));
                assert!((below - lo).abs() <= tol, "c {c} φ₀ {a}: {below} vs {lo}");
                assert!((above - hi).abs() <= tol, "c {c} φ₀ {a}: {above} vs {hi}");
                let mid = q16((lo + hi) / 2.0);
                assert_eq!(hysteresis_band(mid, q16(a), gain), mid);
            }
        }
    }

    /// The Coulomb duty against (1000/V_s)·(R/k_t)·τ_c in f64, and none without friction.
    #[test]
    fn coulomb_feed_forward_is_the_friction_duty() {
        let d = Design::paper();
        let mut cfg = Config::paper(Length::from_int(3));
        let s = Schedule::new(&d, &cfg).unwrap();
        let want = 1000.0 / 12.0 * 8.0 / 1.0 * 0.01;
        let full = f64::from(s.coulomb_ramp_q16) * f64::from(s.coulomb_per_w_q16) / 2f64.powi(32);
        assert!((full - want).abs() < 1e-3, "{full} ‰");
        assert!((f64::from(s.coulomb_ramp_q16) / 65_536.0 - 0.1).abs() < 2e-5);
        cfg.motor.coulomb = I32F32::ZERO;
        let s = Schedule::new(&d, &cfg).unwrap();
        assert_eq!(s.coulomb_per_w_q16, 0);
    }
}
