//! Closed-loop harness: the simulated actuator ([`Plant`]) driven by the fixed-point
//! servo of the `model` crate ([`Servo`]: controller and supervisor), with the step-response and tracking
//! metrics computed on the fly (no_std, no allocation: samples are streamed to a
//! caller-supplied closure).
//!
//! The plant's coupling is derived from the beam model at the controller's clutch setting
//! (`docs/design.md` §2): stiffness k(L), free play φ_b, hysteresis coefficient (6/5)·μ·R/L and
//! root stress per N·m; the motor and link from the controller's configuration, so the
//! controller's model and the plant agree (the plant adds Coulomb friction, hysteresis and
//! quantisation the controller does not model) unless the scenario makes the actuator
//! off-nominal ([`Scenario::plant`], [`crate::overrides`]).
//!
//! A run: the board's boot window with the actuator held ([`Scenario::boot_held`]), hold
//! for `settle_ticks` (so that a constant load is taken up by the coupling and the
//! integrator), give the command, run `run_ticks` more. Metrics use the plant's *true*
//! link angle and beam stress.

use model::calibration::correction::SensorCorrection;
use model::calibration::pipeline::Pipeline;
use model::control::rest_resistance::RestResistance;
use model::control::supply_window::SupplyWindow;
use model::control::{Command, Config, ControlError, Flags, ImpedanceCommand, Schedule};
use model::sensors::encoder_delta;
use model::servo::{BridgeDemand, Prepared, Servo, ServoError, TickInput};
use model::supervisor::{Fault, FaultSet, SupervisorConfig};
use model::Design;

use crate::config::{
    CouplingConfig, LinkConfig, LoadConfig, MotorConfig, PlantConfig, ProfileStep, TorqueProfile,
};
use crate::metrics::{Span, StepResponse};
use crate::overrides::Overrides;
use crate::sensors::{SensorReadings, ENCODER_COUNT_RAD};
use crate::sim::{BridgeCommand, Plant};

const Q32: f64 = 4_294_967_296.0;
const Q64: f64 = Q32 * Q32;

/// A load torque step on the link.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Disturbance {
    /// Tick after the command at which the step applies (negative: during the hold).
    pub after_command_ticks: i32,
    /// Added torque on the link, N·m.
    pub torque_nm: f32,
}

/// What to run.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Scenario {
    /// Beam design.
    pub design: Design,
    /// Controller configuration (clutch, inertia, limits, gains).
    pub config: Config,
    /// The command given after the hold.
    pub command: Command,
    /// Constant load torque on the link, N·m (positive pushes the link positive).
    pub load_nm: f32,
    /// Optional load step.
    pub disturbance: Option<Disturbance>,
    /// Ticks (ms) of holding before the command.
    pub settle_ticks: u32,
    /// Ticks (ms) after the command.
    pub run_ticks: u32,
    /// Whether the controller gets the gear potentiometer.
    pub use_pot: bool,
    /// Whether the board has a supply sense (its readings go to the servo's supply window,
    /// docs/design.md §11, "The supply the board measures"); without one the configured
    /// supply stays in force.
    pub use_supply_sense: bool,
    /// Length of the final window for the steadiness metrics, ticks.
    pub steady_window_ticks: u32,
    /// First tick after the command counted in the RMS tracking error.
    pub rms_from_ticks: u32,
    /// Plant integration substeps per tick (0: the plant's default).
    pub substeps: u16,
    /// Start with the coupling already deflected by the constant load (the link hangs on
    /// the beams at rest, the gear holding it) instead of in the middle of the free play,
    /// where applying the load at t = 0 would slam the link into the beams.
    pub preload: bool,
    /// The board's boot window (bridge off: the current offset and the encoder's
    /// alignment, docs/calibration.md) passes before the hold with the actuator held still,
    /// as when the load is hung on once the servo holds (the default). `false`: the board
    /// powers up with the load already hanging, and the coasting gear lets the link fall
    /// during the window.
    pub boot_held: bool,
    /// Changes of the simulated actuator from the nominal one the controller is
    /// configured with (docs/design.md §9); the controller does not see them.
    pub plant: Overrides,
    /// The supervisor's settings (the servo runs the controller under the supervisor; a
    /// latched fault turns the bridge off).
    pub supervision: SupervisorConfig,
    /// An impedance command given instead of `command` after the hold (its target is the
    /// metrics' target).
    pub impedance: Option<ImpedanceCommand>,
    /// Gravity arm m·g·l of the link, N·m (0: none): the link hangs straight down at
    /// 0 rad, gravity pulls it back with −m·g·l·sin θ ([`LoadConfig::gravity_mgd_nm`]).
    pub gravity_nm: f32,
    /// What the servo's correction layer is configured with (the wiring and sensors as
    /// calibration found them; [`SensorCorrection::NOMINAL`] for the nominal build):
    /// raw readings → [`Pipeline`] → servo, as on the boards.
    pub correction: SensorCorrection,
    /// A calibration is in force: before each motion command the armature resistance a
    /// held link under load showed is configured taking the current offset as known
    /// ([`Servo::tracked_configuration`], with the supply the sense measured); without one
    /// (the default) only as far as the offset's tolerance allows, as the boards' service
    /// does.
    pub offset_calibrated: bool,
}

impl Scenario {
    /// The paper-preset defaults for `config` and `command`: 0.5 s hold, 2 s run, no
    /// load, gear pot on, 500 ms steady window, RMS over the whole run.
    #[must_use]
    pub fn new(config: Config, command: Command) -> Scenario {
        Scenario {
            design: Design::paper(),
            config,
            command,
            load_nm: 0.0,
            disturbance: None,
            settle_ticks: 500,
            run_ticks: 2000,
            use_pot: true,
            use_supply_sense: true,
            steady_window_ticks: 500,
            rms_from_ticks: 0,
            substeps: 0,
            preload: true,
            boot_held: true,
            plant: Overrides::NONE,
            supervision: SupervisorConfig::DEFAULT,
            impedance: None,
            gravity_nm: 0.0,
            correction: SensorCorrection::NOMINAL,
            offset_calibrated: false,
        }
    }
}

/// One tick of the run, for plots and CSV.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample {
    /// Ticks since the start of the run (the hold included).
    pub tick: u32,
    /// Time since the command, s (negative during the hold).
    pub t_s: f64,
    /// Controller reference, rad.
    pub reference_rad: f64,
    /// True link angle, rad.
    pub link_angle_rad: f64,
    /// True gear angle, rad.
    pub gear_angle_rad: f64,
    /// Duty applied, ‰.
    pub duty: i16,
    /// True motor current, A.
    pub current_a: f32,
    /// Controller's coupling torque estimate, N·m.
    pub torque_estimate_nm: f64,
    /// True coupling torque, N·m.
    pub spring_torque_nm: f32,
    /// True beam root stress, Pa.
    pub beam_stress_pa: f32,
    /// Controller's live-limit flags.
    pub flags: Flags,
    /// Link encoder reading.
    pub link_encoder: u16,
}

/// Closed-loop figures of a run (angles from the plant's true state).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Metrics {
    /// Final target of the command (the centre for a sine), rad.
    pub target_rad: f64,
    /// Overshoot beyond the target, % of the commanded change (0 if none).
    pub overshoot_pct: f64,
    /// 10 %→90 % rise time, s (`None` if the link never got there).
    pub rise_time_s: Option<f64>,
    /// Time from the command until the link stays within ±1 count of the target, s
    /// (`None` if it is outside at the end).
    pub settling_time_s: Option<f64>,
    /// Largest |error| to the target over the steady window, encoder counts.
    pub steady_state_error_counts: f64,
    /// Largest |beam stress| over the whole run, Pa.
    pub peak_stress_pa: f64,
    /// `peak_stress_pa / σ_allow`.
    pub peak_stress_ratio: f64,
    /// σ_allow, Pa.
    pub allowable_stress_pa: f64,
    /// RMS of reference − true link angle from `rms_from_ticks` on, rad.
    pub rms_error_rad: f64,
    /// Largest |reference − true link angle| over the same span, rad.
    pub max_error_rad: f64,
    /// A live torque limit was reported after the command.
    pub torque_limited: bool,
    /// The current limit was reported after the command.
    pub current_limited: bool,
    /// The duty saturated after the command.
    pub duty_saturated: bool,
    /// max − min duty over the steady window, ‰.
    pub steady_duty_span: i32,
    /// max − min link encoder count (unwrapped) over the steady window.
    pub steady_count_span: i32,
    /// Largest |coupling torque| (true), N·m.
    pub peak_spring_torque_nm: f64,
    /// FNV-1a 64 of the duty stream (each duty as 2 little-endian bytes, every tick).
    pub output_hash: u64,
    /// Ticks simulated.
    pub ticks: u32,
    /// Faults latched during the run (empty if none).
    pub faults: FaultSet,
    /// The first fault latched, if any.
    pub first_fault: Option<Fault>,
    /// Largest |beam stress| from the tick after the first fault on (the fault
    /// reaction's figure), Pa; 0 without a fault.
    pub peak_stress_after_fault_pa: f64,
    /// Largest |beam stress| up to and including the tick of the first fault (the whole
    /// run without one), Pa: a fault latched with this below σ_allow is a false trip
    /// unless a sensor really failed.
    pub peak_stress_before_fault_pa: f64,
    /// The duration the scenario's move ran for, ms: the commanded one, or the shortest
    /// the limits allow where that is longer (`Controller::planned`); `None` for other
    /// commands.
    pub move_ms: Option<u32>,
}

/// FNV-1a 64 offset basis.
pub const FNV_OFFSET: u64 = 0xCBF2_9CE4_8422_2325;
/// FNV-1a 64 prime.
pub const FNV_PRIME: u64 = 0x0000_0100_0000_01B3;

/// Feeds `bytes` into the FNV-1a 64 hash `h`.
#[must_use]
pub fn fnv1a64(mut h: u64, bytes: &[u8]) -> u64 {
    for &b in bytes {
        h ^= u64::from(b);
        h = h.wrapping_mul(FNV_PRIME);
    }
    h
}

fn fx32(bits: i64) -> f64 {
    bits as f64 / Q32
}

/// The plant configuration matching `config` for `design`: coupling from the beam model at
/// the configured clutch setting, motor and link from the controller's parameters, and a
/// constant load.
///
/// # Errors
/// As [`model::control::Schedule::new`].
pub fn plant_config(
    design: &Design,
    config: &Config,
    load_nm: f32,
) -> Result<PlantConfig, ControlError> {
    let sched = model::control::Schedule::new(design, config)?;
    let m = &config.motor;
    Ok(PlantConfig {
        motor: MotorConfig {
            supply_voltage_v: fx32(m.supply_v.to_bits()) as f32,
            resistance_ohm: fx32(m.resistance_ohm.to_bits()) as f32,
            torque_constant_nm_per_a: fx32(m.torque_constant.to_bits()) as f32,
            back_emf_v_s_per_rad: fx32(m.back_emf.to_bits()) as f32,
            inertia_kg_m2: (fx32(m.rotor_inertia.to_bits()) * 1e-6) as f32,
            viscous_nm_s_per_rad: fx32(m.viscous.to_bits()) as f32,
            ..MotorConfig::default()
        },
        coupling: coupling_config(design, &sched)?,
        link: LinkConfig {
            inertia_kg_m2: (fx32(config.link_inertia.to_bits()) * 1e-6) as f32,
            ..LinkConfig::default()
        },
        load: LoadConfig {
            constant_nm: load_nm,
            ..LoadConfig::default()
        },
        clutch_length_m: (fx32(sched.setting().length().to_bits()) * 1e-3) as f32,
        ..PlantConfig::default()
    })
}

/// The coupling of the beams at an actual clutch length `length_m` (m), whatever the
/// controller was told: the clutch slid by hand to another length.
///
/// # Errors
/// The length is outside the design's range, or its stress does not fit.
pub fn coupling_at(
    design: &Design,
    config: &Config,
    length_m: f32,
) -> Result<CouplingConfig, ControlError> {
    let mut actual = *config;
    let micro = libm::round(f64::from(length_m) * 1e9) as i64; // µm·1000 = mm·1e6
    actual.clutch = model::control::ClutchSetting::Length(
        model::Length::from_micro(micro)
            .map_err(|_| ControlError::Beam(model::Error::ClutchLengthOutOfRange))?,
    );
    coupling_config(design, &model::control::Schedule::new(design, &actual)?)
}

/// The beams' coupling at the clutch setting of `sched` (a controller's schedule for
/// `design`): k, free play, hysteresis c = (6/5)·μ·R/L and root stress per N·m.
///
/// # Errors
/// The stress of the setting does not fit ([`ControlError::Beam`]).
pub fn coupling_config(design: &Design, sched: &Schedule) -> Result<CouplingConfig, ControlError> {
    let setting = sched.setting();
    let p = design.params();
    let k = sched.stiffness().to_bits() as f64 / Q64;
    let len_mm = fx32(setting.length().to_bits());
    let hysteresis = 1.2 * fx32(p.friction.to_bits()) * fx32(p.pitch_radius.to_bits()) / len_mm;
    let stress_mpa = setting
        .root_stress(model::Torque::from_int(1))
        .map_err(ControlError::Beam)?;
    Ok(CouplingConfig {
        stiffness_nm_per_rad: k as f32,
        free_play_rad: fx32(setting.free_play().to_bits()) as f32,
        hysteresis_per_rad: hysteresis as f32,
        stress_per_torque_pa_per_nm: (fx32(stress_mpa.to_bits()) * 1e6) as f32,
        ..CouplingConfig::default()
    })
}

/// Streams the step-response and tracking metrics of a run, one tick at a time (used by
/// [`run`] and by the scenarios that run on the firmware). The step figures are
/// [`crate::metrics`]' (clock from the command, band ±1 count of the true link angle).
#[derive(Clone, Debug)]
pub struct Recorder {
    /// The true frame's offset from the servo's, rad ([`frame_shift`]), set by the command.
    frame_shift: f64,
    settle_ticks: u32,
    total: u32,
    rms_from_ticks: u32,
    m: Metrics,
    step: StepResponse,
    sum_sq: f64,
    n_sq: u32,
    duty_span: Span,
    count_span: Span,
    unwrapped: i32,
    last_enc: u16,
}

/// Seconds from the command to the end of tick `tick` of a run that gives the command
/// before tick `settle_ticks` (negative or 0 during the hold).
fn since_command_s(tick: u32, settle_ticks: u32) -> f64 {
    (i64::from(tick) - i64::from(settle_ticks) + 1) as f64 * 1e-3
}

impl Recorder {
    /// A recorder for a run of `settle_ticks` hold + `run_ticks`, the steadiness metrics
    /// over the last `steady_window_ticks` (at most the run), the RMS error from
    /// `rms_from_ticks` after the command; `sigma_allow_pa` for the stress ratio;
    /// `first_encoder` the link encoder before the first tick.
    #[must_use]
    pub fn new(
        settle_ticks: u32,
        run_ticks: u32,
        steady_window_ticks: u32,
        rms_from_ticks: u32,
        sigma_allow_pa: f64,
        first_encoder: u16,
    ) -> Recorder {
        let total = settle_ticks.saturating_add(run_ticks);
        let window_from = total.saturating_sub(steady_window_ticks.min(run_ticks));
        Recorder {
            settle_ticks,
            total,
            rms_from_ticks,
            m: Metrics {
                allowable_stress_pa: sigma_allow_pa,
                output_hash: FNV_OFFSET,
                ..Metrics::default()
            },
            step: StepResponse::new(
                0.0,
                0.0,
                ENCODER_COUNT_RAD,
                since_command_s(window_from, settle_ticks),
            ),
            sum_sq: 0.0,
            n_sq: 0,
            duty_span: Span::new(),
            count_span: Span::new(),
            unwrapped: 0,
            last_enc: first_encoder,
            frame_shift: 0.0,
        }
    }

    /// Ticks the run lasts (hold + run).
    #[must_use]
    pub const fn total_ticks(&self) -> u32 {
        self.total
    }

    /// The command was given at tick `settle_ticks`: the true link angle then, the
    /// command's final target and the servo's measured link angle then (both in the
    /// servo's frame), rad.
    pub fn on_command(&mut self, start_angle: f64, target: f64, measured: f64) {
        self.frame_shift = frame_shift(measured, start_angle);
        self.step = StepResponse::new(
            start_angle,
            target + self.frame_shift,
            ENCODER_COUNT_RAD,
            self.step.steady_from_s(),
        );
    }

    /// Records tick `tick` (0-based from the start of the hold): the controller's output
    /// and the duty actually applied, the readings and true state at the end of the tick.
    pub fn record(
        &mut self,
        tick: u32,
        out: &model::control::Output,
        duty: i16,
        readings: &crate::SensorReadings,
        st: &crate::TrueState,
    ) -> Sample {
        let m = &mut self.m;
        m.output_hash = fnv1a64(m.output_hash, &duty.to_le_bytes());
        let since = i64::from(tick) - i64::from(self.settle_ticks);
        let t_s = since_command_s(tick, self.settle_ticks);
        let reference = fx32(out.reference.to_bits()) + self.frame_shift;

        m.peak_stress_pa = m.peak_stress_pa.max(f64::from(st.beam_stress_pa).abs());
        m.peak_spring_torque_nm = m
            .peak_spring_torque_nm
            .max(f64::from(st.spring_torque_nm).abs());
        let d = encoder_delta(readings.link_encoder, self.last_enc);
        self.last_enc = readings.link_encoder;
        self.unwrapped = self.unwrapped.saturating_add(d);
        self.step.record(t_s, st.link_angle_rad);
        if since >= 0 {
            m.torque_limited |= out.flags.torque_limited;
            m.current_limited |= out.flags.current_limited;
            m.duty_saturated |= out.flags.duty_saturated;
            if since >= i64::from(self.rms_from_ticks) {
                let e = reference - st.link_angle_rad;
                self.sum_sq += e * e;
                self.n_sq += 1;
                m.max_error_rad = m.max_error_rad.max(e.abs());
            }
        }
        if self.step.in_steady_window(t_s) {
            self.duty_span.add(i32::from(duty));
            self.count_span.add(self.unwrapped);
        }
        Sample {
            tick,
            t_s,
            reference_rad: reference,
            link_angle_rad: st.link_angle_rad,
            gear_angle_rad: st.gear_angle_rad,
            duty,
            current_a: st.motor_current_a,
            torque_estimate_nm: fx32(out.torque_estimate.to_bits()),
            spring_torque_nm: st.spring_torque_nm,
            beam_stress_pa: st.beam_stress_pa,
            flags: out.flags,
            link_encoder: readings.link_encoder,
        }
    }

    /// The metrics of the run.
    #[must_use]
    pub fn finish(&self) -> Metrics {
        let mut m = self.m;
        let step = self.step.figures();
        m.target_rad = self.step.target();
        m.overshoot_pct = step.overshoot_pct;
        m.rise_time_s = step.rise_time_s;
        m.settling_time_s = step.settling_time_s;
        m.steady_state_error_counts = step.steady_state_error / ENCODER_COUNT_RAD;
        m.peak_stress_ratio = m.peak_stress_pa / m.allowable_stress_pa;
        m.rms_error_rad = if self.n_sq > 0 {
            libm::sqrt(self.sum_sq / f64::from(self.n_sq))
        } else {
            0.0
        };
        m.steady_duty_span = self.duty_span.width();
        m.steady_count_span = self.count_span.width();
        m.ticks = self.total;
        m
    }
}

/// The plant for `sc`: its configuration with the overrides and the load step, preloaded
/// by a constant load.
///
/// # Errors
/// As [`plant_config`].
pub fn plant_for(sc: &Scenario) -> Result<Plant, ControlError> {
    let nominal = plant_config(&sc.design, &sc.config, sc.load_nm)?;
    let mut pc = sc.plant.apply(&nominal);
    if pc.clutch_length_m != nominal.clutch_length_m {
        pc.coupling = coupling_at(&sc.design, &sc.config, pc.clutch_length_m)?;
    }
    pc.substeps = sc.substeps;
    pc.load.gravity_mgd_nm = sc.gravity_nm;
    pc.load.gravity_down_rad = 0.0;
    if let Some(d) = sc.disturbance {
        let at = i64::from(sc.settle_ticks) + i64::from(d.after_command_ticks);
        let mut profile = TorqueProfile::default();
        profile.steps[0] = ProfileStep {
            from_tick: at.clamp(0, i64::from(u32::MAX)) as u32,
            torque_nm: d.torque_nm,
        };
        profile.len = 1;
        pc.load.profile = profile;
    }
    let mut plant = Plant::new(pc);
    if sc.preload && sc.load_nm != 0.0 && pc.coupling.stiffness_nm_per_rad > 0.0 {
        // Equilibrium: k·φ_e = −load, φ = φ_e − sign(load)·φ_b.
        let phi = -(pc.coupling.free_play_rad
            + sc.load_nm.abs() / pc.coupling.stiffness_nm_per_rad)
            * sc.load_nm.signum();
        let a = f64::from(pc.power_up_angle_rad);
        plant.set_state(a + f64::from(phi), 0.0, a, 0.0);
    }
    Ok(plant)
}

/// σ_allow of `design`, Pa.
#[must_use]
pub fn allowable_stress_pa(design: &Design) -> f64 {
    fx32(design.params().allowable_stress.to_bits()) * 1e6
}

/// What the H-bridge does when the servo turns the motor off (disabled, or faulted
/// without braking).
pub const OFF_BRIDGE: BridgeCommand = BridgeCommand::Coast;

/// The simulated bridge's command for the servo's demand.
#[must_use]
pub const fn bridge_command(demand: BridgeDemand) -> BridgeCommand {
    match demand {
        BridgeDemand::Drive(d) => BridgeCommand::Drive(d),
        BridgeDemand::Off => OFF_BRIDGE,
        BridgeDemand::Brake => BridgeCommand::Brake,
    }
}

/// How far the plant's true frame is from the servo's, rad, from the servo's measured link
/// angle and the true one at the same tick: the sensor-correction layer set the servo's
/// frame at power-up from the pot (within the free play and the pot's error,
/// docs/calibration.md), a whole number of encoder counts away from the true frame. The
/// step and tracking metrics add it to the servo's target and reference, so they measure
/// how well the servo reaches what it was told, not the pot's accuracy.
#[must_use]
pub fn frame_shift(measured: f64, true_angle: f64) -> f64 {
    // Compare the count each angle falls in (the servo reports the centre of its count,
    // so rounding the difference would be a tie between two counts).
    let count = |a: f64| libm::floor(a / ENCODER_COUNT_RAD);
    (count(true_angle) - count(measured)) * ENCODER_COUNT_RAD
}

/// The servo's raw readings from the simulated sensors, as `sc` wires them.
fn tick_input(sc: &Scenario, readings: &SensorReadings) -> TickInput {
    TickInput {
        link_encoder: readings.link_encoder,
        gear_pot: sc.use_pot.then_some(readings.gear_pot),
        current_adc: readings.current_adc,
        supply_adc: sc.use_supply_sense.then_some(readings.supply_adc),
        read_error: None,
    }
}

/// Runs `sc` — the servo (controller under the supervisor, enabled from the first tick)
/// against the simulated actuator — calling `on_sample` once per tick, and returns the
/// metrics. After a fault the bridge is off ([`OFF_BRIDGE`]) and the run goes on.
///
/// # Errors
/// The controller rejected the configuration or the command.
pub fn run<F: FnMut(&Sample)>(sc: &Scenario, on_sample: F) -> Result<Metrics, ServoError> {
    run_script(sc, |_| None, on_sample)
}

/// As [`run`], and `n` ticks after `sc.command` (n ≥ 1) the command `script(n)`, if any,
/// replaces it: a trajectory given as a sequence of moves (`vsa advise --trajectory`).
///
/// # Errors
/// The servo rejected the configuration or a command.
pub fn run_script<S, F>(
    sc: &Scenario,
    mut script: S,
    mut on_sample: F,
) -> Result<Metrics, ServoError>
where
    S: FnMut(u32) -> Option<Command>,
    F: FnMut(&Sample),
{
    let mut plant = plant_for(sc).map_err(ServoError::Control)?;
    let mut servo = Servo::new(&sc.design, &sc.config, &sc.supervision)?;
    let mut pipeline = Pipeline::new(&sc.correction).map_err(ServoError::Correction)?;
    servo.enable()?;
    let mut readings = plant.readings();
    // A coasting gear could not hold the load the coupling starts deflected by: the boot
    // window passes first, the actuator held still (as the emulated board hangs its load
    // on once the bridge drives, `served`), unless the board boots under the load.
    while sc.boot_held && !pipeline.aligned() {
        let _ = pipeline.tick(&mut servo, &tick_input(sc, &readings));
        readings = plant.resample();
    }
    let mut rec = Recorder::new(
        sc.settle_ticks,
        sc.run_ticks,
        sc.steady_window_ticks,
        sc.rms_from_ticks,
        allowable_stress_pa(&sc.design),
        readings.link_encoder,
    );
    let (mut after_fault, mut before_fault) = (0.0f64, 0.0f64);
    let mut move_ms = None;
    // The still window of a held link (R·i), kept after each tick as the boards' service does.
    let mut window = RestResistance::NEW;
    let mut supply = SupplyWindow::NEW;
    for tick in 0..rec.total_ticks() {
        // The scenario's command at `settle_ticks`, then the script's (if any).
        let command = if tick == sc.settle_ticks {
            Some(sc.command)
        } else {
            tick.checked_sub(sc.settle_ticks)
                .filter(|&n| n > 0)
                .and_then(&mut script)
        };
        if let Some(command) = command {
            // The service tracks before a move, a step or a sine (not a hold, not an
            // impedance command); a configuration that does not take keeps the one in force.
            let impedance = tick == sc.settle_ticks && sc.impedance.is_some();
            if !impedance && !matches!(command, Command::Hold) {
                if let Some((config, supervision)) =
                    servo.tracked_configuration(&supply, &window, sc.offset_calibrated)
                {
                    if let Ok(p) = Prepared::new(&sc.design, &config, &supervision) {
                        let _ = servo.adopt_prepared(&p);
                    }
                }
            }
            if tick == sc.settle_ticks {
                if let Command::Move { duration_ms, .. } = servo.controller().planned(command) {
                    move_ms = Some(duration_ms);
                }
            }
            // A fault latched earlier refuses the command; the run goes on (its metrics
            // show the fault).
            let given = match sc.impedance {
                Some(imp) if tick == sc.settle_ticks => servo.impedance(&imp),
                _ => servo.command(command),
            };
            match given {
                Ok(()) | Err(ServoError::Faulted) => {}
                Err(e) => return Err(e),
            }
        }
        let input = tick_input(sc, &readings);
        let out = pipeline.tick(&mut servo, &input);
        if tick == sc.settle_ticks {
            let target = servo
                .impedance_command()
                .map_or(servo.controller().trajectory().target(), |c| c.target);
            let true_angle = plant.state().link_angle_rad;
            let measured = fx32(out.control.link_angle.to_bits());
            rec.on_command(true_angle, fx32(target.to_bits()), measured);
        }
        window.tick(out.bridge.drives(), &out.control);
        supply.tick(input.supply_adc);
        servo.track_speed(&out);
        let (cmd, duty) = (bridge_command(out.bridge), out.bridge.duty());
        readings = plant.step_tick_cmd(cmd);
        let st = plant.state();
        let stress = f64::from(st.beam_stress_pa).abs();
        if out.new_fault.is_none() && !servo.faults().is_empty() {
            after_fault = after_fault.max(stress);
        } else if servo.faults().is_empty() || out.new_fault.is_some() {
            before_fault = before_fault.max(stress);
        }
        let sample = rec.record(tick, &out.control, duty, &readings, &st);
        on_sample(&sample);
    }
    let mut m = rec.finish();
    m.peak_stress_after_fault_pa = after_fault;
    m.peak_stress_before_fault_pa = before_fault;
    m.faults = servo.faults();
    m.first_fault = servo.supervisor().first_fault();
    m.move_ms = move_ms;
    Ok(m)
}
