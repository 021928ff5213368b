//! The command service of the vsa firmware: [`protocol::Device`] over
//! [`model::servo::Servo`], and the telemetry taken from each control tick.
//!
//! Two halves, for two priorities:
//!
//! * [`Actuator`] is what the 1 kHz control task and the command task share: the servo,
//!   the telemetry rate and its drop counter, and the live limits of the last tick. The
//!   control task owns it during a tick ([`Actuator::after_tick`] takes the telemetry
//!   sample); the command task reaches it only through an [`rtic_core::Mutex`] (RTIC's
//!   `lock`), for a few hundred instructions at a time, so every command is applied
//!   *between* two ticks, never in the middle of one.
//! * [`Service`] is the command task's own state: the design and the configuration in
//!   force. A request that changes the configuration (clutch length, stiffness, gains,
//!   limits) is prepared here first — the slow maths: L(k), the gain schedule, the
//!   supervisor's thresholds ([`model::servo::Prepared`]) — outside the lock, at the
//!   command task's priority; only the copy into the servo happens under the lock
//!   ([`model::servo::Servo::install_prepared`]).
//!
//! Unit conversions between the wire (µrad, µm, mN·m/rad, µN·m, mA, ‰, mHz) and the model
//! (I32F32 rad, mm, N·m, A; I64F64 N·m/rad) are exact integer scalings with
//! round-to-nearest where a division is needed (see each function).
#![cfg_attr(not(test), no_std)]
#![forbid(unsafe_code)]
#![deny(missing_docs)]

use model::calibration::pipeline::Pipeline;
use model::control::rest_resistance::RestResistance;
use model::control::supply_window::SupplyWindow;
use model::control::{ClutchSetting, Command, Config, PidGains};
use model::sensors::POT_COUNT_Q32;
use model::servo::{Prepared, Servo, ServoError, ServoState, TickInput, TickOutput};
use model::supervisor::SupervisorConfig;
use model::{Angle, Design, Frequency, Length, Ratio, Stiffness, Torque};
use protocol::{
    Device, ErrorCode, FaultRecord, Gains, LimitFlags, Limits, LoggedFault, State, Status,
    TelemetrySample,
};
use rtic_core::Mutex;

mod bus_settings;
pub mod calibrate;
pub mod clutch_confirmation;
pub mod correction;
pub mod dynamixel;
mod impedance;
pub mod line;
pub mod link;
pub mod sensors;
pub mod store;

use fixed::types::I32F32;

/// Over-current trip above the live current limit, A: the supervisor trips this far above
/// the clamp the controller holds (the defaults: 1.5 A clamp, 1.75 A trip).
pub const TRIP_ABOVE_LIMIT_A: I32F32 = I32F32::lit("0.25");

/// Saturates an i64 into i32.
const fn sat_i32(v: i64) -> i32 {
    if v > i32::MAX as i64 {
        i32::MAX
    } else if v < i32::MIN as i64 {
        i32::MIN
    } else {
        v as i32
    }
}

/// Saturates an i64 into u32 (negative → 0).
const fn sat_u32(v: i64) -> u32 {
    if v > u32::MAX as i64 {
        u32::MAX
    } else if v < 0 {
        0
    } else {
        v as u32
    }
}

/// I32F32 bits × `scale` / 2³², rounded half up, exactly: the integer part and the
/// fraction (< 2³²) are scaled apart, so nothing overflows for `scale` ≤ 10⁶ and no
/// division is needed (this runs per telemetry sample, in the control tick).
const fn q32_scaled(bits: i64, scale: i64) -> i64 {
    let int = bits >> 32; // floor
    let frac = (bits & 0xFFFF_FFFF) as u64; // bits − int·2³², in [0, 2³²)
    int * scale + ((frac * scale as u64 + (1 << 31)) >> 32) as i64
}

/// I32F32 bits (value × 2³² of a unit) → millionths of the unit, rounded, saturated to i32.
/// E.g. rad → µrad, N·m → µN·m. Exact; shifts and multiplies only.
#[must_use]
pub const fn q32_to_micro(bits: i64) -> i32 {
    sat_i32(q32_scaled(bits, 1_000_000))
}

/// I32F32 bits → thousandths of the unit (A → mA, mm → µm), rounded, saturated to i32.
#[must_use]
pub const fn q32_to_milli(bits: i64) -> i32 {
    sat_i32(q32_scaled(bits, 1_000))
}

/// I32F32 bits → thousandths of the unit in a `u16` (the wire's limits), clamped to
/// 0…65535.
const fn q32_to_milli_u16(bits: i64) -> u16 {
    let m = q32_to_milli(bits);
    if m < 0 {
        0
    } else if m > u16::MAX as i32 {
        u16::MAX
    } else {
        m as u16
    }
}

/// `v`/`per` units → I32F32 bits, rounded half away from zero, saturated: the quotient
/// and the remainder are converted apart, so nothing overflows.
const fn to_q32(v: i64, per: i64) -> i64 {
    let q = v / per;
    let r = v % per; // |r| < per ≤ 10⁶: r·2³² fits
    let frac = if r >= 0 {
        ((r << 32) + per / 2) / per
    } else {
        ((r << 32) - per / 2) / per
    };
    match q.checked_mul(1 << 32) {
        Some(int) => int.saturating_add(frac),
        None if q < 0 => i64::MIN,
        None => i64::MAX,
    }
}

/// Millionths of a unit → I32F32 bits, rounded (µrad → rad, µN·m → N·m).
#[must_use]
pub const fn micro_to_q32(v: i64) -> i64 {
    to_q32(v, 1_000_000)
}

/// Thousandths of a unit → I32F32 bits, rounded (mA → A, µm → mm, ‰ → 1); values beyond
/// the I32F32 range saturate.
#[must_use]
pub const fn milli_to_q32(v: i64) -> i64 {
    to_q32(v, 1_000)
}

/// A length on the wire, µm, as a [`Length`] (mm): the clutch length and the clutch
/// tolerance of the requests, and the tolerance a board takes until a calibration
/// confirms the clutch.
#[must_use]
pub const fn length_from_um(um: u32) -> Length {
    Length::from_bits(milli_to_q32(um as i64))
}

/// k in N·m/rad (I64F64) → mN·m/rad, rounded half up, saturated (a multiply and a shift).
#[must_use]
pub fn stiffness_mnm(k: Stiffness) -> u32 {
    let mnm = (k.to_bits().saturating_mul(1_000) + (1 << 63)) >> 64;
    u32::try_from(mnm.max(0)).unwrap_or(u32::MAX)
}

/// The live-limit flags of a controller output on the wire.
#[must_use]
pub const fn wire_limits(flags: &model::control::Flags) -> LimitFlags {
    let mut bits = 0;
    if flags.torque_limited {
        bits |= LimitFlags::TORQUE;
    }
    if flags.current_limited {
        bits |= LimitFlags::CURRENT;
    }
    if flags.duty_saturated {
        bits |= LimitFlags::DUTY;
    }
    LimitFlags(bits)
}

/// Telemetry pacing: a phase accumulator that lets `rate_hz` of every 1000 ticks through,
/// evenly spread (500 Hz: every second tick; 300 Hz: 3 of every 10).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TelemetryGate {
    rate_hz: u16,
    phase: u16,
    taken: u16,
    dropped: u32,
}

impl TelemetryGate {
    /// Samples per second, 0 = off.
    #[must_use]
    pub const fn rate_hz(&self) -> u16 {
        self.rate_hz
    }

    /// Samples dropped because the queue to the link was full, since boot (saturating).
    #[must_use]
    pub const fn dropped(&self) -> u32 {
        self.dropped
    }

    /// Sets the rate (0 = off; the protocol has checked 10..=500 Hz); the phase restarts.
    pub fn set_rate(&mut self, rate_hz: u16) {
        self.rate_hz = rate_hz.min(1000);
        self.phase = 0;
    }

    /// Called once per tick: the sequence number of the sample to take now, if one is due
    /// (a wrapping count of samples taken, dropped ones included).
    pub fn due(&mut self) -> Option<u16> {
        if self.rate_hz == 0 {
            return None;
        }
        self.phase += self.rate_hz;
        if self.phase < 1000 {
            return None;
        }
        self.phase -= 1000;
        self.taken = self.taken.wrapping_add(1);
        Some(self.taken)
    }

    /// Counts a sample the link could not take.
    pub fn count_dropped(&mut self) {
        self.dropped = self.dropped.saturating_add(1);
    }
}

/// What the control task and the command task share (see the crate docs).
#[derive(Clone, Debug)]
pub struct Actuator {
    /// The servo (controller + supervisor + enable state).
    pub servo: Servo,
    /// The sensor-correction layer in front of it (raw readings in, the bridge's duty out).
    pub pipeline: Pipeline,
    /// Telemetry pacing and drop count.
    pub telemetry: TelemetryGate,
    /// The bring-up mode: the open-loop nudge and the last raw readings.
    pub open_loop: sensors::OpenLoop,
    /// The calibration sequence and the sensor correction it gave.
    pub calibration: calibrate::Calibrator,
    limits: LimitFlags,
    /// Measured link angle at the last tick, I32F32 rad (a sine's centre).
    link_angle: i64,
    /// Link velocity at the last tick, I32F32 rad/s (the Dynamixel Present Speed).
    link_velocity: i64,
    /// Torque estimate at the last tick, I32F32 N·m (the Dynamixel Present Load).
    torque: i64,
    /// The still window of a held link under load (its R·i), kept after each tick.
    rest_resistance: RestResistance,
    /// The supply the board measures, kept after each tick.
    supply: SupplyWindow,
}

impl Actuator {
    /// Wraps `servo`, telemetry off.
    #[must_use]
    pub fn new(servo: Servo) -> Self {
        Self {
            servo,
            pipeline: Pipeline::nominal(),
            telemetry: TelemetryGate::default(),
            open_loop: sensors::OpenLoop::default(),
            calibration: calibrate::Calibrator::default(),
            limits: LimitFlags::NONE,
            link_angle: 0,
            link_velocity: 0,
            torque: 0,
            rest_resistance: RestResistance::NEW,
            supply: SupplyWindow::NEW,
        }
    }

    /// [`Actuator::new`] with the encoder taken as absolute (raw zero at link angle 0) and
    /// no boot window ([`Pipeline::assume_aligned`]): a board whose link encoder is
    /// absolute, or a test that starts from a board already booted at rest.
    #[must_use]
    pub fn aligned(servo: Servo) -> Self {
        let mut a = Self::new(servo);
        a.pipeline.assume_aligned();
        a
    }

    /// One control tick on this tick's raw readings: the correction layer, then the servo
    /// ([`Pipeline::tick`]; the bridge stays off during its boot window). The readings the
    /// servo saw: `self.pipeline.input()`.
    #[inline]
    pub fn tick(&mut self, raw: &TickInput) -> TickOutput {
        self.pipeline.tick(&mut self.servo, raw)
    }

    /// After [`Actuator::tick`]: keeps the live limits for the status and returns the
    /// telemetry sample (with its sequence number) if one is due in this tick.
    /// Cheap: integer scalings only, and only at the telemetry rate.
    pub fn after_tick(
        &mut self,
        input: &TickInput,
        out: &TickOutput,
    ) -> Option<(u16, TelemetrySample)> {
        self.limits = wire_limits(&out.control.flags);
        self.link_angle = out.control.link_angle.to_bits();
        self.link_velocity = out.control.link_velocity.to_bits();
        self.torque = out.control.torque_estimate.to_bits();
        self.rest_resistance.tick(out.bridge.drives(), &out.control);
        self.supply.tick(input.supply_adc);
        self.servo.track_speed(out);
        let seq = self.telemetry.due()?;
        Some((seq, self.sample(input, out)))
    }

    /// The bridge supply the board measured over the last full window, V, if it has a
    /// supply sense ([`SupplyWindow::volts`]).
    #[must_use]
    pub fn measured_supply(&self) -> Option<fixed::types::I32F32> {
        self.supply.volts()
    }

    /// The supply a configuration made now holds, given the `configured` one
    /// ([`SupplyWindow::in_force`], as `Servo::tracked_configuration` takes it).
    #[must_use]
    pub fn supply_in_force(&self, configured: fixed::types::I32F32) -> fixed::types::I32F32 {
        self.supply.in_force(configured)
    }

    /// [`Actuator::after_tick`], and the sample (if one is due) into `queue`, the link's
    /// telemetry queue: never waits; a full queue drops the sample and counts it
    /// ([`TelemetryGate::dropped`], `Status::telemetry_dropped`; its sequence number is
    /// skipped on the wire). Returns whether a sample was queued.
    pub fn publish_tick(
        &mut self,
        input: &TickInput,
        out: &TickOutput,
        queue: &mut heapless::spsc::Producer<'_, link::Sample>,
    ) -> bool {
        match self.after_tick(input, out) {
            Some(sample) => {
                let queued = queue.enqueue(sample).is_ok();
                if !queued {
                    self.telemetry.count_dropped();
                }
                queued
            }
            None => false,
        }
    }

    /// The telemetry sample of a tick, in wire units.
    #[must_use]
    pub fn sample(&self, input: &TickInput, out: &TickOutput) -> TelemetrySample {
        let c = &out.control;
        let gear_angle_urad = match input.gear_pot {
            Some(pot) => {
                let centre = i64::from(self.servo.controller().config().sensors.pot_center);
                q32_to_micro((i64::from(pot) - centre).saturating_mul(POT_COUNT_Q32))
            }
            None => 0,
        };
        TelemetrySample {
            tick: out.tick,
            reference_urad: q32_to_micro(c.reference.to_bits()),
            link_angle_urad: q32_to_micro(c.link_angle.to_bits()),
            gear_angle_urad,
            current_ma: q32_to_milli(c.current.to_bits()).clamp(i16::MIN.into(), i16::MAX.into())
                as i16,
            torque_unm: q32_to_micro(c.torque_estimate.to_bits()),
            duty_permille: out.bridge.duty(),
            faults: self.servo.faults(),
            limits: self.limits,
        }
    }

    /// The status report (`protocol_errors` is the handler's to fill in).
    #[must_use]
    pub fn status(&self) -> Status {
        let servo = &self.servo;
        let sched = servo.controller().schedule();
        Status {
            state: match servo.state() {
                ServoState::Disabled => State::Disabled,
                ServoState::Enabled => State::Enabled,
                ServoState::Faulted => State::Faulted,
            },
            faults: servo.faults(),
            first_fault: servo.supervisor().first_fault().map(|f| FaultRecord {
                code: f.code,
                value: f.value,
                tick: f.tick,
            }),
            limits: self.limits,
            clutch_length_um: sat_u32(i64::from(q32_to_milli(sched.setting().length().to_bits()))),
            stiffness_mnm_per_rad: stiffness_mnm(sched.stiffness()),
            clutch_tolerance_um: q32_to_milli_u16(sched.clutch_tolerance().to_bits()),
            tick: servo.ticks(),
            moving: servo.controller().trajectory().is_moving(),
            telemetry_rate_hz: self.telemetry.rate_hz(),
            telemetry_dropped: self.telemetry.dropped(),
            protocol_errors: 0,
            differs_from_stored: false,
            calibration: self.calibration.progress(),
        }
    }
}

/// [`Request::SetClutchLength`](protocol::Request)'s length, µm, as a clutch setting.
fn clutch_length(length_um: u32) -> ClutchSetting {
    ClutchSetting::Length(length_from_um(length_um))
}

/// [`Request::SetStiffness`](protocol::Request)'s stiffness, mN·m/rad, as a clutch setting.
fn clutch_stiffness(stiffness_mnm_per_rad: u32) -> ClutchSetting {
    // mN·m/rad = 1000 µN·m/rad.
    ClutchSetting::Stiffness(Stiffness::from_micro(
        i64::from(stiffness_mnm_per_rad) * 1_000,
    ))
}

/// Wire gains (10⁻³ of the controller's units) as the controller's.
fn pid_gains(g: Gains) -> PidGains {
    let q = |v: u64| I32F32::from_bits(milli_to_q32(i64::try_from(v).unwrap_or(i64::MAX)));
    PidGains {
        kp: q(g.kp),
        ki: q(g.ki),
        kd: q(g.kd),
    }
}

/// The controller's gains on the wire (inverse of [`pid_gains`]).
fn wire_gains(g: &PidGains) -> Gains {
    let milli = |v: I32F32| u64::try_from(q32_to_milli(v.to_bits())).unwrap_or(0);
    Gains {
        kp: milli(g.kp),
        ki: milli(g.ki),
        kd: milli(g.kd),
    }
}

// The wire's bound on the clutch tolerance is the controller's, in µm.
const _: () = assert!(
    protocol::CLUTCH_TOLERANCE_MAX_UM as i32 == model::control::MAX_CLUTCH_TOLERANCE_MM * 1000
);

/// `config` and `supervision` with the wire `limits` (the supervisor trips
/// [`TRIP_ABOVE_LIMIT_A`] above the current limit).
fn with_limits(
    mut config: Config,
    mut supervision: SupervisorConfig,
    limits: &Limits,
) -> Result<(Config, SupervisorConfig), ErrorCode> {
    let current = I32F32::from_bits(milli_to_q32(limits.current_ma.into()));
    config.limits = model::control::Limits {
        torque_margin: Ratio::from_bits(milli_to_q32(limits.torque_margin_permille.into())),
        max_current_a: current,
        max_motor_torque: Torque::from_bits(micro_to_q32(limits.motor_torque_unm.into())),
        max_duty: i16::try_from(limits.duty_permille).map_err(|_| ErrorCode::OutOfRange)?,
        clutch_tolerance: length_from_um(limits.clutch_tolerance_um.into()),
    };
    supervision.trip_current_a = current.saturating_add(TRIP_ABOVE_LIMIT_A);
    supervision.position_min = Angle::from_bits(micro_to_q32(limits.position_min_urad.into()));
    supervision.position_max = Angle::from_bits(micro_to_q32(limits.position_max_urad.into()));
    Ok((config, supervision))
}

/// The limits and position window of `config` and `supervision` on the wire (inverse of
/// [`with_limits`]).
fn limits_of(config: &Config, supervision: &SupervisorConfig) -> Limits {
    let l = &config.limits;
    let s = supervision;
    Limits {
        torque_margin_permille: q32_to_milli_u16(l.torque_margin.to_bits()),
        current_ma: q32_to_milli_u16(l.max_current_a.to_bits()),
        motor_torque_unm: sat_u32(i64::from(q32_to_micro(l.max_motor_torque.to_bits()))),
        duty_permille: l.max_duty.unsigned_abs(),
        position_min_urad: q32_to_micro(s.position_min.to_bits()),
        position_max_urad: q32_to_micro(s.position_max.to_bits()),
        clutch_tolerance_um: q32_to_milli_u16(l.clutch_tolerance.to_bits()),
    }
}

/// Why a configuration could not be prepared or installed.
fn refused(e: ServoError) -> ErrorCode {
    match e {
        ServoError::Faulted => ErrorCode::NotAllowed,
        ServoError::Control(_)
        | ServoError::Supervisor(_)
        | ServoError::Impedance(_)
        | ServoError::Correction(_) => ErrorCode::OutOfRange,
    }
}

/// The command task's state: the design, the configuration in force and the settings
/// store ([`store`]).
#[derive(Debug)]
pub struct Service {
    design: Design,
    /// The configuration in force as configured (the clutch tolerance the controller gets
    /// may be larger: [`clutch_confirmation`]).
    config: Config,
    supervision: SupervisorConfig,
    settings: store::Settings,
    /// The longest clutch, µm, the calibration in force leaves possible (`None`: no
    /// calibration, or one that could not bound it).
    calibrated_longest_um: Option<u32>,
    /// A calibration is in force: its current offset is known to a fraction of a count,
    /// and the resistance tracked between commands ([`Servo::tracked_configuration`]) takes
    /// it as exact; without one it allows for the offset's tolerance.
    offset_calibrated: bool,
    /// The resistance a held link showed, ‰ of the calibration's, in force instead of it
    /// (`None`: the calibration's, or no calibration).
    tracked_resistance_permille: Option<u16>,
}

impl Service {
    /// The service of a servo built from `design`, `config` and `supervision` (the same
    /// values the servo was built with).
    #[must_use]
    pub const fn new(design: Design, config: Config, supervision: SupervisorConfig) -> Self {
        Self {
            design,
            config,
            supervision,
            settings: store::Settings::new(config, supervision),
            calibrated_longest_um: None,
            offset_calibrated: false,
            tracked_resistance_permille: None,
        }
    }

    /// Whether a calibration was just put in force (`on`) or left; either way the
    /// calibration's (or the configured) resistance is the one reported in force.
    fn set_offset_calibrated(&mut self, on: bool) {
        self.offset_calibrated = on;
        self.tracked_resistance_permille = None;
    }

    /// The controller configuration in force.
    #[must_use]
    pub const fn config(&self) -> &Config {
        &self.config
    }

    /// The supervisor configuration in force.
    #[must_use]
    pub const fn supervision(&self) -> &SupervisorConfig {
        &self.supervision
    }

    /// The [`Device`] the protocol handler drives for one request, over `actuator` (the
    /// RTIC shared resource, or any [`Mutex`]).
    pub fn device<'a, M: Mutex<T = Actuator>>(
        &'a mut self,
        actuator: &'a mut M,
    ) -> ServiceDevice<'a, M> {
        ServiceDevice {
            service: self,
            actuator,
        }
    }
}

/// [`Device`] for one request: [`Service`] plus the locked [`Actuator`].
pub struct ServiceDevice<'a, M> {
    service: &'a mut Service,
    actuator: &'a mut M,
}

impl<M: Mutex<T = Actuator>> ServiceDevice<'_, M> {
    /// Prepares `config`/`supervision` (slow, unlocked) with the clutch tolerance in force
    /// ([`clutch_confirmation`]), installs it (a copy, locked) and keeps it as the
    /// configuration in force. Returns the clutch length L, µm.
    fn reconfigure(
        &mut self,
        config: Config,
        supervision: SupervisorConfig,
    ) -> Result<u32, ErrorCode> {
        let design = &self.service.design;
        let um = |l: Length| u32::try_from(q32_to_milli(l.to_bits())).ok();
        // The length the prepared setting will have (L, or L(k) for a stiffness).
        let clutch = config
            .clutch_length(design)
            .map_err(|_| ErrorCode::OutOfRange)?;
        let length_um = um(clutch).ok_or(ErrorCode::OutOfRange)?;
        let tolerance = clutch_confirmation::tolerance_in_force_um(
            um(config.limits.clutch_tolerance).unwrap_or(0),
            length_um,
            self.service.calibrated_longest_um,
        );
        let mut in_force = config;
        in_force.limits.clutch_tolerance = length_from_um(tolerance);
        let prepared = Prepared::new(design, &in_force, &supervision).map_err(refused)?;
        self.actuator.lock(|a| a.servo.install_prepared(&prepared));
        self.service.config = config;
        self.service.supervision = supervision;
        Ok(length_um)
    }

    /// Configures the supply the board measured and the armature resistance a held link
    /// under load showed when they differ from the ones in force (a supply other than
    /// configured, docs/design.md §11, "The supply the board measures"; a motor warmer or
    /// colder than configured or calibrated, "Tracking a warm motor's resistance"; without a
    /// calibration only as far as the current offset's tolerance allows): prepared unlocked (the
    /// slow maths), adopted locked with the servo's state kept. A refused configuration
    /// keeps the one in force. `plant::harness` does the same before its motion commands.
    fn track_actuator(&mut self) {
        let calibrated = self.service.offset_calibrated;
        let Some((config, supervision)) = self.actuator.lock(|a| {
            a.servo
                .tracked_configuration(&a.supply, &a.rest_resistance, calibrated)
        }) else {
            return;
        };
        let Ok(prepared) = Prepared::new(&self.service.design, &config, &supervision) else {
            return;
        };
        if self
            .actuator
            .lock(|a| a.servo.adopt_prepared(&prepared))
            .is_ok()
        {
            self.service.config.motor.resistance_ohm = config.motor.resistance_ohm;
            self.service.config.motor.supply_v = config.motor.supply_v;
            let tracked = i64::from(q32_to_milli(config.motor.resistance_ohm.to_bits()));
            self.service.tracked_resistance_permille = self.service.calibration().map(|c| {
                let calibrated = i64::from(c.wire.resistance_mohm).max(1);
                u16::try_from(tracked.saturating_mul(1000) / calibrated).unwrap_or(u16::MAX)
            });
        }
    }

    /// Whether `lo..=hi` (I32F32 rad) lies inside the position window in force.
    fn within_window(&self, lo: i64, hi: i64) -> bool {
        let s = &self.service.supervision;
        s.position_min.to_bits() <= lo && hi <= s.position_max.to_bits()
    }

    /// A motion target (µrad) inside the position window: the supervisor would latch
    /// `position-limit` out there, and the sensors measure only so far
    /// ([`protocol::TARGET_MAX_URAD`]), so such a target is refused, not attempted.
    fn target(&self, target_urad: i32) -> Result<Angle, ErrorCode> {
        let bits = micro_to_q32(target_urad.into());
        if self.within_window(bits, bits) {
            Ok(Angle::from_bits(bits))
        } else {
            Err(ErrorCode::OutOfRange)
        }
    }

    /// Gives the servo a motion command; only while enabled. First the resistance a held
    /// link under load showed and the supply the board measured ([`Self::track_actuator`]).
    fn motion(&mut self, cmd: Command) -> Result<(), ErrorCode> {
        self.track_actuator();
        self.actuator.lock(|a| {
            if a.servo.state() != ServoState::Enabled {
                return Err(ErrorCode::NotAllowed);
            }
            a.servo.command(cmd).map_err(refused)
        })
    }
}

impl<M: Mutex<T = Actuator>> Device for ServiceDevice<'_, M> {
    fn enable(&mut self) -> Result<(), ErrorCode> {
        self.actuator.lock(|a| {
            if a.calibration.running() {
                return Err(ErrorCode::Busy);
            }
            // Not before the encoder is aligned to the pot: a command would start from 0.
            // Busy, not refused: the window ends by itself within 32 ms.
            if !a.pipeline.aligned() {
                return Err(ErrorCode::Busy);
            }
            a.servo.enable().map_err(refused)
        })
    }

    fn disable(&mut self) -> Result<(), ErrorCode> {
        self.actuator.lock(|a| {
            a.open_loop.stop();
            a.calibration.abort();
            a.servo.disable();
        });
        Ok(())
    }

    fn clear_fault(&mut self) -> Result<(), ErrorCode> {
        self.actuator.lock(|a| a.servo.clear_fault());
        Ok(())
    }

    fn persisting_fault(&mut self) -> Option<FaultRecord> {
        self.actuator.lock(|a| {
            let servo = &a.servo;
            if servo.faults().is_empty() {
                return None;
            }
            servo.supervisor().condition().map(|f| FaultRecord {
                code: f.code,
                value: f.value,
                tick: f.tick,
            })
        })
    }

    fn set_clutch_length(&mut self, length_um: u32) -> Result<(), ErrorCode> {
        let mut config = self.service.config;
        config.clutch = clutch_length(length_um);
        self.reconfigure(config, self.service.supervision)
            .map(|_| ())
    }

    fn set_stiffness(&mut self, stiffness_mnm_per_rad: u32) -> Result<u32, ErrorCode> {
        let mut config = self.service.config;
        config.clutch = clutch_stiffness(stiffness_mnm_per_rad);
        self.reconfigure(config, self.service.supervision)
    }

    fn command_move(&mut self, target_urad: i32, duration_ms: u32) -> Result<(), ErrorCode> {
        let target = self.target(target_urad)?;
        self.motion(Command::Move {
            target,
            duration_ms,
        })
    }

    fn command_step(&mut self, target_urad: i32) -> Result<(), ErrorCode> {
        let target = self.target(target_urad)?;
        self.motion(Command::Step { target })
    }

    fn command_sine(&mut self, amplitude_urad: u32, frequency_mhz: u32) -> Result<(), ErrorCode> {
        let hz = I32F32::from_bits(milli_to_q32(frequency_mhz.into()));
        let frequency = Frequency::from_hz(hz).map_err(|_| ErrorCode::OutOfRange)?;
        // About the link angle now: both extremes inside the window.
        let centre = self.actuator.lock(|a| a.link_angle);
        let amplitude = micro_to_q32(amplitude_urad.into());
        if !self.within_window(
            centre.saturating_sub(amplitude),
            centre.saturating_add(amplitude),
        ) {
            return Err(ErrorCode::OutOfRange);
        }
        self.motion(Command::Sine {
            amplitude: Angle::from_bits(micro_to_q32(amplitude_urad.into())),
            frequency,
        })
    }

    fn impedance(&mut self, target: i32, k: u32, d: u32, torque: i32) -> Result<(), ErrorCode> {
        impedance::apply(self, target, k, d, torque)
    }

    fn set_bus(&mut self, change: &protocol::BusChange) -> Result<(), ErrorCode> {
        bus_settings::set(self, change)
    }

    fn hold(&mut self) -> Result<(), ErrorCode> {
        self.actuator.lock(|a| {
            if a.servo.state() == ServoState::Faulted {
                return Err(ErrorCode::NotAllowed);
            }
            a.servo.command(Command::Hold).map_err(refused)
        })
    }

    fn set_gains(&mut self, gains: Option<Gains>) -> Result<(), ErrorCode> {
        let mut config = self.service.config;
        config.gains.gains = gains.map(pid_gains);
        self.reconfigure(config, self.service.supervision)
            .map(|_| ())
    }

    fn set_limits(&mut self, limits: &Limits) -> Result<(), ErrorCode> {
        let (config, supervision) =
            with_limits(self.service.config, self.service.supervision, limits)?;
        self.reconfigure(config, supervision).map(|_| ())
    }

    fn set_telemetry_rate(&mut self, rate_hz: u16) -> Result<(), ErrorCode> {
        self.actuator.lock(|a| a.telemetry.set_rate(rate_hz));
        Ok(())
    }

    fn heartbeat(&mut self) {
        self.actuator.lock(|a| a.servo.heartbeat());
    }

    fn disarm_heartbeat(&mut self) {
        self.actuator.lock(|a| a.servo.disarm_heartbeat());
    }

    fn link_activity(&mut self) {
        self.actuator.lock(|a| {
            if a.servo.supervisor().heartbeat_armed() {
                a.servo.heartbeat();
            }
        });
    }

    fn limits(&mut self) -> Limits {
        limits_of(&self.service.config, &self.service.supervision)
    }

    fn status(&mut self) -> Status {
        let differs = self.differs_from_stored();
        let mut status = self.actuator.lock(|a| a.status());
        status.differs_from_stored = differs;
        status
    }

    fn save(&mut self) -> Result<(), ErrorCode> {
        self.save_settings()
    }

    fn load(&mut self) -> Result<(), ErrorCode> {
        self.load_settings().map(|_| ())
    }

    fn factory_reset(&mut self) -> Result<(), ErrorCode> {
        self.reset_settings()
    }

    fn faults_log(&mut self, index: u8) -> Result<(u8, Option<LoggedFault>), ErrorCode> {
        self.logged_fault(index)
    }

    fn raw_sensors(&mut self) -> Result<protocol::RawSensors, ErrorCode> {
        self.actuator.lock(|a| a.open_loop.last())
    }

    fn nudge(&mut self, duty_permille: i16, duration_ms: u16) -> Result<(), ErrorCode> {
        self.actuator.lock(|a| {
            if a.calibration.running() {
                return Err(ErrorCode::Busy);
            }
            let state = a.servo.state();
            a.open_loop.start(state, duty_permille, duration_ms)
        })
    }

    fn calibrate(&mut self, start: bool) -> Result<(), ErrorCode> {
        ServiceDevice::calibrate(self, start)
    }

    fn calibration(&mut self) -> Result<protocol::CalibrationReport, ErrorCode> {
        Ok(self.calibration_report())
    }
}
