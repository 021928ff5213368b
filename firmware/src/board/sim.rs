//! The emulated boards' peripherals and what surrounds their control step: the simulated
//! actuator behind the same driver traits the real board implements. The H-bridge driver
//! writes simulated PWM and GPIO lines; the sensors return the readings the plant produced
//! at the start of the tick.
//!
//! Each tick the [`Simulation`] advances the plant by one control period with the bridge
//! lines as they are, applies the scenario's injections and actions, and presents the new
//! readings to the sensors (`plant::scenario` has the per-tick protocol).

use super::{BridgeOutputs, TickHooks, TickPlan};
use core::sync::atomic::{AtomicU32, Ordering};
use drivers::sim::SimTickIo;
use model::control::{Config, MotorParams};
use model::sensors::{ADC_COUNTS, ADC_MID, ENCODER_COUNTS, POT_COUNTS, SUPPLY_MV_PER_COUNT};
use model::servo::{Servo, TickOutput};
use model::supervisor::{Fault, SupervisorConfig};
use model::{Design, Length};
use plant::overrides::Overrides;
use plant::scenario::{Action, BridgeLines, ScenarioEvent, ScenarioId, ScenarioRun};
use plant::served::ServedActuator;
use service::Service;

/// The emulated boards' actuator I/O: the link encoder, gear pot, current ADC and supply
/// sense of `model::sensors`, and the H-bridge, all on simulated lines.
pub type SimulatedIo = SimTickIo<ENCODER_COUNTS, POT_COUNTS, ADC_COUNTS>;

/// Gear pot counts at mid-travel, where the actuator rests before the first tick.
pub const POT_AT_REST: u16 = POT_COUNTS / 2;

/// Supply sense counts of the AX-12A's supply (12 V: 2 400), before the first tick.
pub const SUPPLY_AT_REST: u16 =
    ((MotorParams::AX12A.supply_v.to_bits() * 1000) >> 32) as u16 / SUPPLY_MV_PER_COUNT;

/// All lines low, the sensors presenting the actuator at rest until the first tick.
pub fn at_rest() -> SimulatedIo {
    match SimulatedIo::simulated(0, POT_AT_REST, ADC_MID, SUPPLY_AT_REST) {
        Ok(io) => io,
        // The simulated lines cannot fail (`Infallible`).
        Err(_) => defmt::panic!("simulated H-bridge failed"),
    }
}

/// The bridge lines as the driver set them.
fn lines(io: &SimulatedIo) -> BridgeLines {
    BridgeLines {
        enabled: io.bridge.en().is_high(),
        forward: io.bridge.dir().is_high(),
        duty_permille: io.bridge.pwm().duty(),
    }
}

/// The emulated board's bridge outputs, what the simulated actuator is driven by: the
/// driver's lines as latched at the end of each tick ([`TickHooks::after_step`]), packed
/// as enable (bit 31), direction (bit 30) and duty ‰ (bits 0–15). A static, like a
/// peripheral's output register, so that the panic and HardFault handlers can force them
/// off with one store that cannot fail ([`force_bridge_off`]). All low at reset.
static OUTPUTS: AtomicU32 = AtomicU32::new(0);

const OUTPUT_ENABLE: u32 = 1 << 31;
const OUTPUT_FORWARD: u32 = 1 << 30;

/// Latches `l` onto the outputs.
fn latch(l: BridgeLines) {
    let mut bits = u32::from(l.duty_permille);
    if l.enabled {
        bits |= OUTPUT_ENABLE;
    }
    if l.forward {
        bits |= OUTPUT_FORWARD;
    }
    OUTPUTS.store(bits, Ordering::Relaxed);
}

/// The outputs as the simulated actuator sees them.
fn outputs() -> BridgeLines {
    let bits = OUTPUTS.load(Ordering::Relaxed);
    BridgeLines {
        enabled: bits & OUTPUT_ENABLE != 0,
        forward: bits & OUTPUT_FORWARD != 0,
        duty_permille: (bits & 0xFFFF) as u16,
    }
}

/// The fail-safe of the emulated boards (see `crate::fail_safe`): enable low and duty 0 by
/// one store; returns the outputs before and after.
pub fn force_bridge_off() -> (BridgeOutputs, BridgeOutputs) {
    let seen = |l: BridgeLines| BridgeOutputs {
        enabled: l.enabled,
        duty_permille: l.duty_permille,
    };
    let before = seen(outputs());
    OUTPUTS.store(0, Ordering::Relaxed);
    (before, seen(outputs()))
}

/// The simulated actuator around the control step: a scripted scenario and its plant, or
/// (serving the host protocol) the plant alone, commanded from the host.
pub struct Simulation {
    kind: SimulationKind,
}

// One simulation per run, in a static: the size difference does not matter.
#[allow(clippy::large_enum_variant)]
enum SimulationKind {
    Scenario {
        run: &'static mut ScenarioRun,
        actions: heapless::Vec<Action, 3>,
    },
    Served(ServedActuator),
}

impl Simulation {
    /// Starts scenario `id` on the simulated actuator changed by `plant`, in the run's
    /// static simulation (init calls this or [`serve`] once); also returns the servo configured for it and its service.
    ///
    /// [`serve`]: Simulation::serve
    #[inline(never)] // its frame ends with it (the 14 KiB scenario is built in its static)
    pub fn new(id: ScenarioId, plant: &Overrides) -> (&'static mut Simulation, Servo, Service) {
        let run = match place_run(id, plant) {
            Ok(r) => r,
            Err(e) => defmt::panic!("scenario {=str} rejected: {}", id.name(), e),
        };
        let sim = place(Simulation {
            kind: SimulationKind::Scenario {
                run,
                actions: heapless::Vec::new(),
            },
        });
        let SimulationKind::Scenario { run, .. } = &sim.kind else {
            defmt::unreachable!()
        };
        let servo = match run.servo() {
            Ok(s) => s,
            Err(e) => defmt::panic!("scenario {=str}: servo rejected: {}", id.name(), e),
        };
        let plan = run.plan();
        let config = match plan.segments[0] {
            Some(seg) => plan.config(&seg),
            None => defmt::panic!("scenario {=str} has no segment", id.name()),
        };
        let service = Service::new(*servo.design(), config, plan.supervision);
        (sim, servo, service)
    }

    /// The simulation of a board serving the host protocol: the paper design at
    /// [`SERVED_CLUTCH_MM`], `load_mnm` mN·m hung on the link once the motor drives
    /// (see `plant::served`), the actuator changed by `plant`, the servo disabled.
    #[inline(never)] // its frame ends with it, as [`Simulation::new`]'s
    pub fn serve(load_mnm: i32, plant: &Overrides) -> (&'static mut Simulation, Servo, Service) {
        let design = Design::paper();
        let config = Config::paper(Length::from_int(SERVED_CLUTCH_MM));
        let supervision = SupervisorConfig::DEFAULT;
        let servo = match Servo::new(&design, &config, &supervision) {
            Ok(s) => s,
            Err(e) => defmt::panic!("served servo rejected: {}", e),
        };
        let load_nm = load_mnm as f32 / 1000.0;
        let plant = match ServedActuator::with_plant(design, &config, load_nm, plant) {
            Ok(p) => p,
            Err(e) => defmt::panic!("served plant rejected: {}", e),
        };
        (
            place(Simulation {
                kind: SimulationKind::Served(plant),
            }),
            servo,
            Service::new(design, config, supervision),
        )
    }
}

/// Moves the run's simulation into its static and lends it out. Only init calls this
/// (through [`Simulation::new`] or [`Simulation::serve`]), once.
fn place(simulation: Simulation) -> &'static mut Simulation {
    static mut SLOT: Option<Simulation> = None;
    // SAFETY: called once, from init, before any task runs: no other reference exists.
    unsafe { (*core::ptr::addr_of_mut!(SLOT)).insert(simulation) }
}

/// Builds the run's scenario straight into its static (returned by value it took two
/// copies of its 14 KiB on init's stack). Only init calls this, once.
#[inline(never)]
fn place_run(
    id: ScenarioId,
    plant: &Overrides,
) -> Result<&'static mut ScenarioRun, model::servo::ServoError> {
    static mut RUN: Option<Result<ScenarioRun, model::servo::ServoError>> = None;
    // SAFETY: called once, from init, before any task runs: no other reference exists.
    let slot = unsafe { &mut *core::ptr::addr_of_mut!(RUN) };
    ScenarioRun::build_in(slot, id, plant)
}

/// Clutch length a serving board starts at, mm.
pub const SERVED_CLUTCH_MM: i32 = 3;

impl TickHooks for Simulation {
    type Io = SimulatedIo;
    type Event = ScenarioEvent;

    /// Start of a tick: the plant advances one period with the bridge outputs as they are,
    /// the new readings go to the sensors, a scenario's actions to the servo.
    fn before_step(&mut self, io: &mut SimulatedIo, servo: &mut Servo) -> TickPlan {
        let (r, overrun) = match &mut self.kind {
            SimulationKind::Scenario { run, actions } => {
                let overrun = run.begin_tick(outputs(), actions);
                for a in actions.iter() {
                    if let Err(e) = run.apply(servo, a) {
                        defmt::warn!("scenario action refused: {}", e);
                    }
                }
                (run.readings(), overrun)
            }
            SimulationKind::Served(plant) => {
                (plant.tick(outputs(), servo.controller().schedule()), false)
            }
        };
        io.present(r.link_encoder, r.gear_pot, r.current_adc, r.supply_adc);
        TickPlan { overrun }
    }

    /// End of a tick: the bridge lines onto the outputs; a scenario's metrics, hash and
    /// fault timing.
    fn after_step(
        &mut self,
        servo: &Servo,
        out: &TickOutput,
        late: Option<Fault>,
        io: &SimulatedIo,
    ) {
        latch(lines(io));
        if let SimulationKind::Scenario { run, .. } = &mut self.kind {
            run.end_tick(servo, out, late, lines(io));
        }
    }

    /// The next event for the log.
    fn pop_event(&mut self) -> Option<ScenarioEvent> {
        match &mut self.kind {
            SimulationKind::Scenario { run, .. } => run.pop_event(),
            SimulationKind::Served(_) => None,
        }
    }

    fn ends_run(event: &ScenarioEvent) -> bool {
        matches!(event, ScenarioEvent::Finished(_))
    }
}
