//! Scripted scenarios that run the same way on the host and on the emulated boards: the
//! paper's step sweep and one fault injection per supervisor check.
//!
//! A [`ScenarioRun`] owns the simulated actuator and the script; the caller owns the
//! [`Servo`] (on the firmware, behind the driver traits) and runs each 1 ms tick as:
//!
//! 1. [`ScenarioRun::begin_tick`] with the H-bridge lines as they are now: the script's
//!    injections for this tick are applied, the plant advances one control period with
//!    those lines, and the sensor readings and the servo actions for this tick come back;
//! 2. the caller applies the actions ([`ScenarioRun::apply`]), reads the sensors, runs
//!    [`Servo::tick`], drives the bridge, and reports an overrun if the tick overran (the
//!    `Overrun` injection asks it to busy-wait past the deadline);
//! 3. [`ScenarioRun::end_tick`] records the metrics, the output hash and the fault
//!    timing, and queues [`ScenarioEvent`]s for the log.
//!
//! The output hash is FNV-1a 64 over, per tick: the controller's duty (i16 LE), the bridge
//! demand (duty, or i16::MIN when off) and the servo state (u8), and per new fault its
//! code (u8) and tick (u32 LE). It covers the controller's output stream and the
//! supervisor's decisions, and not the fault values (an overrun's value is the firmware's
//! measured busy time).
//!
//! For each fault scenario the run records the injection tick, the tick at which the
//! plant's true state first meets the fault condition (for injections that are the
//! condition themselves, the injection tick), the first fault, and how many ticks the
//! bridge was driven after it (must be 0).

use heapless::Deque;
use model::calibration::pipeline::Pipeline;
use model::control::{Command, Config};
use model::servo::{BridgeDemand, Prepared, Servo, ServoError, ServoState, TickOutput};
use model::supervisor::{Fault, FaultCode, Supervisor, SupervisorConfig};
use model::{Angle, Design, Length};

use crate::harness::{self, fnv1a64, Metrics, Recorder, Scenario, FNV_OFFSET};
use crate::overrides::Overrides;
use crate::sensors::{SensorFault, SensorReadings};
use crate::sim::{BridgeCommand, Plant};

const Q32: f64 = 4_294_967_296.0;

fn fx32(bits: i64) -> f64 {
    bits as f64 / Q32
}

/// The scenarios.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ScenarioId {
    /// The paper's experiment: L = 1…5 mm in turn, a 0.5 rad raw step each with a 0.3 N·m
    /// load (0.5 s hold, 2 s run), the `vsa simulate` metrics per setting.
    StepSweep,
    /// The H-bridge's PWM output sticks at full duty (a shorted high side) with the current
    /// limit set to 1.0 A and the trip at 1.2 A.
    OverCurrent,
    /// A collision: a 5 N·m external torque step on the link at L = 5 mm (τ_cap 0.57 N·m).
    BeamOverload,
    /// Pushed away: at L = 1 mm with a 0.3 N·m load, a further 1.5 N·m external torque
    /// (1.8 N·m in all) overpowers the motor (1.5 N·m) and drives the link past a ±0.5 rad
    /// window.
    PositionLimit,
    /// The link encoder reading jumps by 700 counts (a glitch).
    EncoderJump,
    /// The link encoder freezes during a 0.5 rad, 200 ms move at L = 1 mm.
    EncoderStuck,
    /// The current ADC saturates at 4095.
    AdcSaturated,
    /// One control period runs 1.5 periods long (an injected busy-wait).
    Overrun,
    /// The host's heartbeats (every 20 ms) stop; the timeout is 100 ms.
    CommandTimeout,
}

impl ScenarioId {
    /// Every scenario, the step sweep first.
    pub const ALL: [ScenarioId; 9] = [
        ScenarioId::StepSweep,
        ScenarioId::OverCurrent,
        ScenarioId::BeamOverload,
        ScenarioId::PositionLimit,
        ScenarioId::EncoderJump,
        ScenarioId::EncoderStuck,
        ScenarioId::AdcSaturated,
        ScenarioId::Overrun,
        ScenarioId::CommandTimeout,
    ];

    /// Name on the command line (`--scenario NAME`).
    #[must_use]
    pub const fn name(self) -> &'static str {
        match self {
            ScenarioId::StepSweep => "step-sweep",
            ScenarioId::OverCurrent => "fault-over-current",
            ScenarioId::BeamOverload => "fault-beam-overload",
            ScenarioId::PositionLimit => "fault-position-limit",
            ScenarioId::EncoderJump => "fault-encoder-jump",
            ScenarioId::EncoderStuck => "fault-encoder-stuck",
            ScenarioId::AdcSaturated => "fault-adc-saturated",
            ScenarioId::Overrun => "fault-overrun",
            ScenarioId::CommandTimeout => "fault-command-timeout",
        }
    }

    /// The scenario called `name`.
    #[must_use]
    pub fn parse(name: &str) -> Option<ScenarioId> {
        Self::ALL.into_iter().find(|s| s.name() == name)
    }

    /// The fault the scenario must raise first (`None` for the step sweep: no fault).
    #[must_use]
    pub const fn expected_fault(self) -> Option<FaultCode> {
        match self {
            ScenarioId::StepSweep => None,
            ScenarioId::OverCurrent => Some(FaultCode::OverCurrent),
            ScenarioId::BeamOverload => Some(FaultCode::BeamOverload),
            ScenarioId::PositionLimit => Some(FaultCode::PositionLimit),
            ScenarioId::EncoderJump => Some(FaultCode::SensorJump),
            ScenarioId::EncoderStuck => Some(FaultCode::SensorStuck),
            ScenarioId::AdcSaturated => Some(FaultCode::AdcOutOfRange),
            ScenarioId::Overrun => Some(FaultCode::DeadlineMissed),
            ScenarioId::CommandTimeout => Some(FaultCode::CommandTimeout),
        }
    }
}

/// What the script breaks.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Injection {
    /// The PWM output sticks at +1000 ‰ while the bridge is enabled.
    PwmStuckHigh,
    /// An external torque on the link, N·m, from this tick on.
    ExternalTorque(f32),
    /// The link encoder reads this many counts off.
    EncoderOffset(i16),
    /// The link encoder repeats its last reading.
    EncoderFrozen,
    /// The current ADC reads this value.
    AdcStuckAt(u16),
    /// The firmware busy-waits in this tick past the deadline (host: reports an overrun).
    Overrun,
    /// The heartbeats stop (the last one was in the previous tick).
    StopHeartbeats,
}

/// What the caller must do to the servo at the start of a tick, before [`Servo::tick`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Action {
    /// [`Servo::restart_prepared`] with segment `n`'s configuration, prepared when the
    /// scenario was built (a new segment on a fresh mechanism: the controller restarts
    /// holding where the link is).
    Restart(u8),
    /// A raw step by this much from the current reference.
    StepBy(Angle),
    /// A minimum-jerk move by this much from the current reference, in this many ms.
    MoveBy(Angle, u32),
    /// A heartbeat from the host.
    Heartbeat,
}

/// Applies `action` to `servo` with the segment configurations `prepared` (the same on
/// the host and on the firmware).
///
/// # Errors
/// The servo rejected it.
fn apply_action(
    servo: &mut Servo,
    action: &Action,
    prepared: &[Option<Prepared>; 5],
) -> Result<(), ServoError> {
    match *action {
        Action::Restart(n) => match prepared.get(usize::from(n)) {
            Some(Some(p)) => servo.restart_prepared(p),
            _ => Err(ServoError::Faulted),
        },
        Action::StepBy(by) => {
            let target = servo.controller().trajectory().target().saturating_add(by);
            servo.command(Command::Step { target })
        }
        Action::MoveBy(by, duration_ms) => {
            let target = servo.controller().trajectory().target().saturating_add(by);
            servo.command(Command::Move {
                target,
                duration_ms,
            })
        }
        Action::Heartbeat => {
            servo.heartbeat();
            Ok(())
        }
    }
}

/// The H-bridge lines as the pins set them (what the simulated bridge sees).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct BridgeLines {
    /// Enable pin high.
    pub enabled: bool,
    /// Direction pin high (positive duty).
    pub forward: bool,
    /// PWM duty, ‰ of the period, 0..=1000.
    pub duty_permille: u16,
}

impl BridgeLines {
    /// What the lines make the bridge do: coast when disabled, else drive with the duty in
    /// the direction line's sense.
    #[must_use]
    pub fn command(self) -> BridgeCommand {
        if !self.enabled {
            return BridgeCommand::Coast;
        }
        let d = self.duty_permille.min(1000) as i16;
        BridgeCommand::Drive(if self.forward { d } else { -d })
    }

    /// The lines a correct driver sets for `demand`.
    #[must_use]
    pub fn for_demand(demand: BridgeDemand) -> BridgeLines {
        match demand {
            BridgeDemand::Off => BridgeLines::default(),
            // Enabled at zero duty: the low sides short the motor (the simulated bridge's
            // 0 V, `BridgeCommand::Drive(0)`).
            BridgeDemand::Brake => BridgeLines {
                enabled: true,
                forward: false,
                duty_permille: 0,
            },
            BridgeDemand::Drive(d) => BridgeLines {
                enabled: true,
                forward: d > 0,
                duty_permille: d.unsigned_abs().min(1000),
            },
        }
    }
}

/// One segment of a scenario: a setting, a hold, a motion, a run.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Segment {
    /// Clutch length, mm.
    pub clutch_mm: i32,
    /// Constant load on the link, N·m (the plant starts preloaded by it).
    pub load_nm: f32,
    /// Ticks of holding before the motion.
    pub hold_ticks: u32,
    /// Ticks after the motion starts.
    pub run_ticks: u32,
    /// The motion given after the hold.
    pub motion: Option<Action>,
}

/// Everything a scenario is made of.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Plan {
    /// Which.
    pub id: ScenarioId,
    /// Its segments (the step sweep has five, the fault scenarios one).
    pub segments: [Option<Segment>; 5],
    /// The injection and its tick (global, 1-based).
    pub injection: Option<(u32, Injection)>,
    /// Motor current limit override, A (`None`: the default 1.5 A).
    pub max_current_a: Option<f32>,
    /// The supervisor's settings.
    pub supervision: SupervisorConfig,
    /// Heartbeat period, ticks (0: no heartbeats).
    pub heartbeat_every: u32,
}

/// The step-sweep settings, mm.
pub const SWEEP_MM: [i32; 5] = [1, 2, 3, 4, 5];
/// Tick at which the fault scenarios inject.
pub const INJECT_TICK: u32 = 300;

impl Plan {
    /// The plan of `id`.
    #[must_use]
    pub fn of(id: ScenarioId) -> Plan {
        let step = Some(Action::StepBy(Angle::from_fixed(
            fixed::types::I32F32::lit("0.5"),
        )));
        let hold = |mm: i32| Segment {
            clutch_mm: mm,
            load_nm: 0.3,
            hold_ticks: 1100,
            run_ticks: 0,
            motion: None,
        };
        let mut plan = Plan {
            id,
            segments: [None; 5],
            injection: None,
            max_current_a: None,
            supervision: SupervisorConfig::DEFAULT,
            heartbeat_every: 0,
        };
        match id {
            ScenarioId::StepSweep => {
                for (slot, mm) in plan.segments.iter_mut().zip(SWEEP_MM) {
                    *slot = Some(Segment {
                        clutch_mm: mm,
                        load_nm: 0.3,
                        hold_ticks: 500,
                        run_ticks: 2000,
                        motion: step,
                    });
                }
            }
            ScenarioId::OverCurrent => {
                plan.segments[0] = Some(hold(3));
                plan.injection = Some((INJECT_TICK, Injection::PwmStuckHigh));
                plan.max_current_a = Some(1.0);
                plan.supervision.trip_current_a = fixed::types::I32F32::lit("1.2");
            }
            ScenarioId::BeamOverload => {
                plan.segments[0] = Some(hold(5));
                plan.injection = Some((INJECT_TICK, Injection::ExternalTorque(5.0)));
            }
            ScenarioId::PositionLimit => {
                // The 0.3 N·m load keeps the coupling in contact on the pushed side, so the
                // push does not slam across the free play: the beams stay below τ_cap.
                plan.segments[0] = Some(hold(1));
                plan.injection = Some((INJECT_TICK, Injection::ExternalTorque(1.5)));
                plan.supervision.position_min =
                    Angle::from_fixed(fixed::types::I32F32::lit("-0.5"));
                plan.supervision.position_max = Angle::from_fixed(fixed::types::I32F32::lit("0.5"));
            }
            ScenarioId::EncoderJump => {
                plan.segments[0] = Some(hold(3));
                plan.injection = Some((INJECT_TICK, Injection::EncoderOffset(700)));
            }
            ScenarioId::EncoderStuck => {
                plan.segments[0] = Some(Segment {
                    clutch_mm: 1,
                    load_nm: 0.3,
                    hold_ticks: 250,
                    run_ticks: 850,
                    motion: Some(Action::MoveBy(
                        Angle::from_fixed(fixed::types::I32F32::lit("0.5")),
                        200,
                    )),
                });
                plan.injection = Some((INJECT_TICK, Injection::EncoderFrozen));
            }
            ScenarioId::AdcSaturated => {
                plan.segments[0] = Some(hold(3));
                plan.injection = Some((INJECT_TICK, Injection::AdcStuckAt(4095)));
            }
            ScenarioId::Overrun => {
                plan.segments[0] = Some(hold(3));
                plan.injection = Some((INJECT_TICK, Injection::Overrun));
            }
            ScenarioId::CommandTimeout => {
                plan.segments[0] = Some(hold(3));
                plan.injection = Some((INJECT_TICK, Injection::StopHeartbeats));
                plan.heartbeat_every = 20;
            }
        }
        plan
    }

    /// Total ticks of the scenario.
    #[must_use]
    pub fn total_ticks(&self) -> u32 {
        self.segments
            .iter()
            .flatten()
            .map(|s| s.hold_ticks + s.run_ticks)
            .sum()
    }

    /// The controller configuration of `seg`.
    #[must_use]
    pub fn config(&self, seg: &Segment) -> Config {
        let mut cfg = Config::paper(Length::from_int(seg.clutch_mm));
        if let Some(a) = self.max_current_a {
            cfg.limits.max_current_a = fixed::types::I32F32::from_num(a);
        }
        cfg
    }
}

/// Something worth a log line.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ScenarioEvent {
    /// A segment begins at `tick`.
    SegmentStart {
        /// Segment index (0-based).
        index: u8,
        /// Clutch length, mm.
        clutch_mm: i32,
        /// k(L), N·m/rad.
        stiffness_nm_per_rad: f64,
        /// τ_cap(L), N·m.
        torque_capacity_nm: f64,
        /// Tick.
        tick: u32,
    },
    /// The injection was applied at `tick`.
    Injected {
        /// What.
        injection: Injection,
        /// Tick.
        tick: u32,
    },
    /// The plant's true state first met the fault condition at `tick`.
    Condition {
        /// The fault the condition calls for.
        code: FaultCode,
        /// Tick.
        tick: u32,
    },
    /// A segment ended with these metrics.
    SegmentDone {
        /// Segment index.
        index: u8,
        /// Clutch length, mm.
        clutch_mm: i32,
        /// Metrics of the segment (true plant state).
        metrics: Metrics,
    },
    /// The scenario ended.
    Finished(Summary),
}

/// The outcome of a scenario.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Summary {
    /// Which.
    pub id: ScenarioId,
    /// Ticks run.
    pub ticks: u32,
    /// Output hash (module doc).
    pub hash: u64,
    /// First fault: code and tick.
    pub first_fault: Option<(FaultCode, u32)>,
    /// Injection tick.
    pub inject_tick: Option<u32>,
    /// Tick at which the true state met the fault condition.
    pub condition_tick: Option<u32>,
    /// Ticks after the first fault in which the servo demanded drive.
    pub driven_after_fault: u32,
    /// Ticks after the first fault in which the bridge lines drove the motor (enabled
    /// with a duty; a brake, enabled at zero duty, puts no energy in).
    pub lines_driving_after_fault: u32,
}

impl Summary {
    /// Whether the scenario did what it must: the expected first fault, not before the
    /// injection, within 2 ticks of the condition, and the motor off from then on; for the
    /// step sweep, no fault at all.
    #[must_use]
    pub fn passed(&self) -> bool {
        match self.id.expected_fault() {
            None => self.first_fault.is_none(),
            Some(code) => match (self.first_fault, self.inject_tick, self.condition_tick) {
                (Some((c, t)), Some(inj), Some(cond)) => {
                    c == code
                        && t >= inj
                        && t <= cond.saturating_add(2)
                        && self.driven_after_fault == 0
                        && self.lines_driving_after_fault == 0
                }
                _ => false,
            },
        }
    }
}

/// Truth-side thresholds of a segment (f64, for the condition events).
#[derive(Clone, Copy, Debug, PartialEq)]
struct Truth {
    torque_cap_nm: f64,
    envelope_rad: f64,
    position_min: f64,
    position_max: f64,
    trip_current_a: f64,
}

/// A segment's simulated mechanism and figures, built with the scenario (not in a tick).
#[derive(Clone)]
struct SegmentWorld {
    plant: Plant,
    truth: Truth,
    stiffness_nm_per_rad: f64,
}

/// `e`, left in `slot` (a run that failed to build).
fn failed(slot: &mut Option<Result<ScenarioRun, ServoError>>, e: ServoError) -> ServoError {
    *slot = Some(Err(e));
    e
}

/// A scenario in progress (see the module doc for the per-tick protocol).
pub struct ScenarioRun {
    plan: Plan,
    design: Design,
    worlds: [Option<SegmentWorld>; 5],
    prepared: [Option<Prepared>; 5],
    plant: Plant,
    seg_index: usize,
    seg_tick: u32,
    tick: u32,
    recorder: Option<Recorder>,
    truth: Truth,
    readings: SensorReadings,
    hash: u64,
    pwm_stuck: bool,
    frozen_angle: Option<f64>,
    heartbeats: bool,
    last_heartbeat: Option<u32>,
    first_fault: Option<(FaultCode, u32)>,
    inject_tick: Option<u32>,
    condition_tick: Option<u32>,
    driven_after_fault: u32,
    lines_driving_after_fault: u32,
    results: [Option<Metrics>; 5],
    events: Deque<ScenarioEvent, 8>,
    done: bool,
}

impl ScenarioRun {
    /// Starts scenario `id` (paper design).
    ///
    /// # Errors
    /// The plan's configuration was rejected (a bug in the plan).
    pub fn new(id: ScenarioId) -> Result<ScenarioRun, ServoError> {
        Self::with_plant(id, &Overrides::NONE)
    }

    /// Starts scenario `id` on a simulated actuator changed by `plant` (e.g. the link
    /// powered up elsewhere, `power-up-angle`); the servo is configured as for the nominal
    /// one and sees the changes only through its sensors.
    ///
    /// # Errors
    /// As [`ScenarioRun::new`].
    pub fn with_plant(id: ScenarioId, plant: &Overrides) -> Result<ScenarioRun, ServoError> {
        let mut slot = None;
        Self::build_in(&mut slot, id, plant)?;
        slot.unwrap_or(Err(ServoError::Faulted))
    }

    /// [`ScenarioRun::with_plant`] built in `slot` (left `Some(Err(…))` on an error): the
    /// run is written there once and its segments filled in place, so that a board that
    /// keeps it in a static does not hold it on its stack as well (the firmware's boot
    /// stack, docs/performance.md).
    ///
    /// # Errors
    /// As [`ScenarioRun::new`].
    pub fn build_in<'a>(
        slot: &'a mut Option<Result<ScenarioRun, ServoError>>,
        id: ScenarioId,
        plant: &Overrides,
    ) -> Result<&'a mut ScenarioRun, ServoError> {
        let plan = Plan::of(id);
        let design = Design::paper();
        let first = plan.segments[0]
            .ok_or(ServoError::Faulted)
            .and_then(|seg| Self::segment_world(&plan, &design, &seg, plant));
        let first = match first {
            Ok(w) => w,
            Err(e) => return Err(failed(slot, e)),
        };
        let (mechanism, truth) = (first.plant.clone(), first.truth);
        let readings = mechanism.readings();
        let built = slot.insert(Ok(ScenarioRun {
            plan,
            design,
            worlds: [Some(first), None, None, None, None],
            prepared: Default::default(),
            plant: mechanism,
            seg_index: 0,
            seg_tick: 0,
            tick: 0,
            recorder: None,
            truth,
            readings,
            hash: FNV_OFFSET,
            pwm_stuck: false,
            frozen_angle: None,
            heartbeats: plan.heartbeat_every > 0,
            last_heartbeat: None,
            first_fault: None,
            inject_tick: None,
            condition_tick: None,
            driven_after_fault: 0,
            lines_driving_after_fault: 0,
            results: [None; 5],
            events: Deque::new(),
            done: false,
        }));
        let Ok(run) = built else {
            return Err(ServoError::Faulted);
        };
        if let Err(e) = run.fill_segments(plant) {
            return Err(failed(slot, e));
        }
        match slot {
            Some(Ok(run)) => Ok(run),
            _ => Err(ServoError::Faulted),
        }
    }

    /// Every segment's world (the first is in) and prepared configuration, in place.
    fn fill_segments(&mut self, plant: &Overrides) -> Result<(), ServoError> {
        for k in 0..self.plan.segments.len() {
            let Some(seg) = self.plan.segments[k] else {
                continue;
            };
            if k > 0 {
                self.worlds[k] = Some(Self::segment_world(&self.plan, &self.design, &seg, plant)?);
            }
            self.prepared[k] = Some(Prepared::new(
                &self.design,
                &self.plan.config(&seg),
                &self.plan.supervision,
            )?);
        }
        Ok(())
    }

    /// A servo set up for this scenario's first segment (disabled; the first tick's
    /// `Restart` action enables it).
    ///
    /// # Errors
    /// The plan's configuration was rejected.
    pub fn servo(&self) -> Result<Servo, ServoError> {
        let first = self.plan.segments[0].ok_or(ServoError::Faulted)?;
        Servo::new(
            &self.design,
            &self.plan.config(&first),
            &self.plan.supervision,
        )
    }

    /// Applies `action` to `servo` (the same on the host and on the firmware).
    ///
    /// # Errors
    /// The servo rejected it.
    pub fn apply(&self, servo: &mut Servo, action: &Action) -> Result<(), ServoError> {
        apply_action(servo, action, &self.prepared)
    }

    fn segment_world(
        plan: &Plan,
        design: &Design,
        seg: &Segment,
        overrides: &Overrides,
    ) -> Result<SegmentWorld, ServoError> {
        let cfg = plan.config(seg);
        let sc = Scenario {
            plant: *overrides,
            load_nm: seg.load_nm,
            settle_ticks: seg.hold_ticks,
            run_ticks: seg.run_ticks,
            ..Scenario::new(cfg, Command::Hold)
        };
        let plant = harness::plant_for(&sc).map_err(ServoError::Control)?;
        let sched = model::control::Schedule::new(design, &cfg).map_err(ServoError::Control)?;
        let sup = Supervisor::new(&plan.supervision, &sched).map_err(ServoError::Supervisor)?;
        let truth = Truth {
            torque_cap_nm: fx32(sup.torque_capacity().to_bits()),
            envelope_rad: fx32(sup.deflection_envelope().to_bits()),
            position_min: fx32(plan.supervision.position_min.to_bits()),
            position_max: fx32(plan.supervision.position_max.to_bits()),
            trip_current_a: fx32(plan.supervision.trip_current_a.to_bits()),
        };
        Ok(SegmentWorld {
            plant,
            truth,
            stiffness_nm_per_rad: sched.stiffness().to_bits() as f64 / (Q32 * Q32),
        })
    }

    /// The plan.
    #[must_use]
    pub const fn plan(&self) -> &Plan {
        &self.plan
    }

    /// Whether the scenario has ended.
    #[must_use]
    pub const fn is_done(&self) -> bool {
        self.done
    }

    /// The sensor readings of this tick.
    #[must_use]
    pub const fn readings(&self) -> SensorReadings {
        self.readings
    }

    /// Metrics of the segments finished so far.
    #[must_use]
    pub const fn results(&self) -> &[Option<Metrics>; 5] {
        &self.results
    }

    /// The next queued event.
    pub fn pop_event(&mut self) -> Option<ScenarioEvent> {
        self.events.pop_front()
    }

    fn push(&mut self, ev: ScenarioEvent) {
        // The queue holds a tick's worth of events; the caller drains it every tick.
        let _ = self.events.push_back(ev);
    }

    fn segment(&self) -> Option<Segment> {
        self.plan.segments.get(self.seg_index).copied().flatten()
    }

    /// Step 1 of a tick: injections, one control period of the plant with `lines`, the
    /// readings. Returns whether this tick must overrun, and fills `actions` (at most 3).
    pub fn begin_tick(
        &mut self,
        lines: BridgeLines,
        actions: &mut heapless::Vec<Action, 3>,
    ) -> bool {
        actions.clear();
        self.tick = self.tick.wrapping_add(1);
        let t = self.tick;
        let Some(seg) = self.segment() else {
            return false;
        };
        let mut overrun = false;
        if let Some((at, inj)) = self.plan.injection {
            if at == t {
                self.inject_tick = Some(t);
                self.push(ScenarioEvent::Injected {
                    injection: inj,
                    tick: t,
                });
                match inj {
                    Injection::PwmStuckHigh => self.pwm_stuck = true,
                    Injection::ExternalTorque(nm) => self.plant.set_external_torque(nm),
                    Injection::EncoderOffset(c) => {
                        self.plant.faults_mut().link_encoder = SensorFault::Offset(c);
                        self.condition_tick = Some(t);
                    }
                    Injection::EncoderFrozen => {
                        self.plant.faults_mut().link_encoder = SensorFault::Frozen;
                        let raw = self.readings.link_encoder;
                        let v = model::sensors::encoder_delta(raw, 0);
                        self.frozen_angle = Some((f64::from(v) + 0.5) * crate::ENCODER_COUNT_RAD);
                    }
                    Injection::AdcStuckAt(v) => {
                        self.plant.faults_mut().current_adc = SensorFault::StuckAt(v);
                        self.condition_tick = Some(t);
                    }
                    Injection::Overrun => {
                        overrun = true;
                        self.condition_tick = Some(t);
                    }
                    Injection::StopHeartbeats => self.heartbeats = false,
                }
            }
        }
        if self.seg_tick == 0 {
            // A new segment: a fresh (preloaded) plant, the servo restarted on it.
            let Some(world) = self.worlds.get(self.seg_index).cloned().flatten() else {
                self.done = true;
                return false;
            };
            self.plant = world.plant;
            self.truth = world.truth;
            let _ = actions.push(Action::Restart(self.seg_index as u8));
            self.push(ScenarioEvent::SegmentStart {
                index: self.seg_index as u8,
                clutch_mm: seg.clutch_mm,
                stiffness_nm_per_rad: world.stiffness_nm_per_rad,
                torque_capacity_nm: world.truth.torque_cap_nm,
                tick: t,
            });
            self.readings = self.plant.readings();
            self.recorder = Some(Recorder::new(
                seg.hold_ticks,
                seg.run_ticks,
                500.min(seg.run_ticks),
                0,
                harness::allowable_stress_pa(&self.design),
                self.readings.link_encoder,
            ));
        } else {
            let cmd = if self.pwm_stuck && lines.enabled {
                BridgeCommand::Drive(1000)
            } else {
                lines.command()
            };
            self.readings = self.plant.step_tick_cmd(cmd);
        }
        if self.seg_tick == seg.hold_ticks {
            if let Some(m) = seg.motion {
                let _ = actions.push(m);
            }
        }
        if self.heartbeats && self.plan.heartbeat_every > 0 && t % self.plan.heartbeat_every == 1 {
            let _ = actions.push(Action::Heartbeat);
            self.last_heartbeat = Some(t);
        }
        self.watch_condition(t);
        overrun
    }

    /// Records the first tick at which the true state meets the scenario's condition.
    fn watch_condition(&mut self, t: u32) {
        if self.condition_tick.is_some() || self.inject_tick.is_none() {
            return;
        }
        let st = self.plant.state();
        let tr = self.truth;
        let code = self.plan.id.expected_fault();
        let met = match code {
            Some(FaultCode::OverCurrent) => f64::from(st.motor_current_a).abs() > tr.trip_current_a,
            Some(FaultCode::BeamOverload) => {
                f64::from(st.spring_torque_nm).abs() > tr.torque_cap_nm
            }
            Some(FaultCode::PositionLimit) => {
                st.link_angle_rad < tr.position_min || st.link_angle_rad > tr.position_max
            }
            Some(FaultCode::SensorStuck) => self
                .frozen_angle
                .is_some_and(|frozen| (st.gear_angle_rad - frozen).abs() > tr.envelope_rad),
            Some(FaultCode::CommandTimeout) => self
                .last_heartbeat
                .is_some_and(|last| t > last + self.plan.supervision.command_timeout_ms),
            _ => false,
        };
        if met {
            self.condition_tick = Some(t);
            if let Some(code) = code {
                self.push(ScenarioEvent::Condition { code, tick: t });
            }
        }
    }

    /// Step 3 of a tick: the servo's output (and the overrun fault, if the caller found
    /// one after the tick), the bridge lines the driver set, metrics and hash.
    pub fn end_tick(
        &mut self,
        servo: &Servo,
        out: &TickOutput,
        late: Option<Fault>,
        lines: BridgeLines,
    ) {
        let Some(seg) = self.segment() else {
            return;
        };
        let mut h = fnv1a64(self.hash, &out.control.duty.to_le_bytes());
        let demand = match out.bridge {
            BridgeDemand::Drive(d) => d,
            BridgeDemand::Off => i16::MIN,
            BridgeDemand::Brake => i16::MIN + 1,
        };
        h = fnv1a64(h, &demand.to_le_bytes());
        let state = match servo.state() {
            ServoState::Disabled => 0u8,
            ServoState::Enabled => 1,
            ServoState::Faulted => 2,
        };
        h = fnv1a64(h, &[state]);
        for f in [out.new_fault, late].into_iter().flatten() {
            h = fnv1a64(h, &[f.code as u8]);
            h = fnv1a64(h, &f.tick.to_le_bytes());
            if self.first_fault.is_none() {
                self.first_fault = Some((f.code, f.tick));
            }
        }
        self.hash = h;
        if let Some((_, fault_tick)) = self.first_fault {
            if out.tick >= fault_tick {
                // An overrun is found after the tick's output was applied: that tick's
                // demand stands, but the lines must be off by the end of the tick.
                let found_late = out.tick == fault_tick && out.new_fault.is_none();
                if !found_late && matches!(out.bridge, BridgeDemand::Drive(_)) {
                    self.driven_after_fault += 1;
                }
                if lines.enabled && lines.duty_permille != 0 {
                    self.lines_driving_after_fault += 1;
                }
            }
        }

        let applied = out.bridge.duty();
        if self.seg_tick == seg.hold_ticks {
            if let Some(rec) = self.recorder.as_mut() {
                let true_angle = self.plant.state().link_angle_rad;
                rec.on_command(
                    true_angle,
                    fx32(servo.controller().trajectory().target().to_bits()),
                    fx32(out.control.link_angle.to_bits()),
                );
            }
        }
        let st = self.plant.state();
        let readings = self.readings;
        if let Some(rec) = self.recorder.as_mut() {
            rec.record(self.seg_tick, &out.control, applied, &readings, &st);
        }
        self.seg_tick += 1;
        if self.seg_tick >= seg.hold_ticks + seg.run_ticks {
            if let Some(rec) = self.recorder.take() {
                let metrics = rec.finish();
                if let Some(slot) = self.results.get_mut(self.seg_index) {
                    *slot = Some(metrics);
                }
                self.push(ScenarioEvent::SegmentDone {
                    index: self.seg_index as u8,
                    clutch_mm: seg.clutch_mm,
                    metrics,
                });
            }
            self.seg_index += 1;
            self.seg_tick = 0;
            if self.segment().is_none() {
                self.done = true;
                let s = self.summary();
                self.push(ScenarioEvent::Finished(s));
            }
        }
    }

    /// The outcome so far.
    #[must_use]
    pub fn summary(&self) -> Summary {
        Summary {
            id: self.plan.id,
            ticks: self.tick,
            hash: self.hash,
            first_fault: self.first_fault,
            inject_tick: self.inject_tick,
            condition_tick: self.condition_tick,
            driven_after_fault: self.driven_after_fault,
            lines_driving_after_fault: self.lines_driving_after_fault,
        }
    }
}

/// Runs scenario `id` on the host with the bridge lines a correct driver would set,
/// calling `on_event` for every event.
///
/// # Errors
/// The plan's configuration was rejected.
pub fn run_on_host<F: FnMut(&ScenarioEvent)>(
    id: ScenarioId,
    on_event: F,
) -> Result<Summary, ServoError> {
    run_on_host_with_plant(id, &Overrides::NONE, on_event)
}

/// [`run_on_host`] on a simulated actuator changed by `plant` ([`ScenarioRun::with_plant`]):
/// the same run as an emulated board given the same overrides. The raw readings go
/// through the sensor-correction layer ([`Pipeline`], nominal correction) as on the boards.
///
/// # Errors
/// The plan's configuration was rejected.
pub fn run_on_host_with_plant<F: FnMut(&ScenarioEvent)>(
    id: ScenarioId,
    plant: &Overrides,
    mut on_event: F,
) -> Result<Summary, ServoError> {
    let mut run = ScenarioRun::with_plant(id, plant)?;
    let mut servo = run.servo()?;
    let mut pipeline = Pipeline::nominal();
    let mut lines = BridgeLines::default();
    let mut actions = heapless::Vec::new();
    while !run.is_done() {
        let overrun = run.begin_tick(lines, &mut actions);
        for a in &actions {
            // A refused action (e.g. a command while faulted) is part of the scenario's
            // behaviour, not an error of the run.
            let _ = run.apply(&mut servo, a);
        }
        let r = run.readings();
        let out = pipeline.tick(
            &mut servo,
            &model::servo::TickInput {
                link_encoder: r.link_encoder,
                gear_pot: Some(r.gear_pot),
                current_adc: r.current_adc,
                supply_adc: Some(r.supply_adc),
                read_error: None,
            },
        );
        // The board's service takes the tick after it (`Actuator::after_tick`).
        servo.track_speed(&out);
        let late = if overrun {
            servo.deadline_missed(0)
        } else {
            None
        };
        lines = if late.is_some() {
            BridgeLines::default()
        } else {
            BridgeLines::for_demand(out.bridge)
        };
        run.end_tick(&servo, &out, late, lines);
        while let Some(ev) = run.pop_event() {
            on_event(&ev);
        }
    }
    Ok(run.summary())
}
