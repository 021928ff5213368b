//! The emulated boards' peripherals: the simulated actuator behind the same driver traits
//! the real board implements. The H-bridge driver writes simulated PWM and GPIO lines; the
//! sensors return the readings the plant produced at the start of the tick.
//!
//! Each tick the [`World`] advances the plant by one control period with the bridge lines
//! as they are, applies the scenario's injections and actions, and presents the new
//! readings to the sensors (`plant::scenario` has the per-tick protocol).

use drivers::sim::{SimChannel, SimPin, SimPwm};
use drivers::HBridge;
use model::control::Config;
use model::servo::{Servo, TickOutput};
use model::supervisor::{Fault, SupervisorConfig};
use model::{Design, Length};
use plant::scenario::{Action, BridgeLines, ScenarioEvent, ScenarioId, ScenarioRun};
use plant::served::ServedActuator;
use service::Service;

/// Link magnetic encoder, 4096 counts per turn.
pub type LinkEncoder = SimChannel<4096>;
/// Gear potentiometer, 1024 counts over 300°.
pub type GearPot = SimChannel<1024>;
/// Current ADC, 12 bit.
pub type CurrentAdc = SimChannel<4096>;
/// The H-bridge on the simulated lines.
pub type Bridge = HBridge<SimPwm, SimPin, SimPin>;

/// The board's actuator I/O.
pub struct Io {
    /// Link encoder.
    pub link: LinkEncoder,
    /// Gear potentiometer.
    pub pot: GearPot,
    /// Motor current ADC.
    pub current: CurrentAdc,
    /// H-bridge.
    pub bridge: Bridge,
}

impl Io {
    /// All lines low, sensors at mid-scale until the first tick.
    pub fn new() -> Io {
        let bridge = match HBridge::new(SimPwm::default(), SimPin::default(), SimPin::default()) {
            Ok(b) => b,
            // The simulated lines cannot fail (`Infallible`).
            Err(_) => defmt::panic!("simulated H-bridge failed"),
        };
        Io {
            link: SimChannel { value: 0 },
            pot: SimChannel { value: 512 },
            current: SimChannel { value: 2048 },
            bridge,
        }
    }

    /// The bridge lines as the driver set them.
    pub fn lines(&self) -> BridgeLines {
        BridgeLines {
            enabled: self.bridge.en().is_high(),
            forward: self.bridge.dir().is_high(),
            duty_permille: self.bridge.pwm().duty(),
        }
    }
}

/// What the start of a tick asks of the control loop.
pub struct TickPlan {
    /// Busy-wait past the deadline in this tick (fault injection).
    pub overrun: bool,
}

/// The simulated world: a scripted scenario and its plant, or (serving the host protocol)
/// the plant alone, commanded from the host.
pub struct World {
    kind: WorldKind,
}

// One world per run, in a static: the size difference does not matter.
#[allow(clippy::large_enum_variant)]
enum WorldKind {
    Scenario {
        run: ScenarioRun,
        actions: heapless::Vec<Action, 3>,
    },
    Served(ServedActuator),
}

impl World {
    /// Starts scenario `id`; also returns the servo configured for it and its service.
    pub fn new(id: ScenarioId) -> (World, Servo, Service) {
        let run = match ScenarioRun::new(id) {
            Ok(r) => r,
            Err(e) => defmt::panic!("scenario {=str} rejected: {}", id.name(), e),
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
        let kind = WorldKind::Scenario {
            run,
            actions: heapless::Vec::new(),
        };
        (World { kind }, servo, service)
    }

    /// The world of a board serving the host protocol: the paper design at
    /// [`SERVED_CLUTCH_MM`], `load_mnm` mN·m hung on the link once the motor drives
    /// (see `plant::served`), the servo disabled.
    pub fn serve(load_mnm: i32) -> (World, Servo, Service) {
        let design = Design::paper();
        let config = Config::paper(Length::from_int(SERVED_CLUTCH_MM));
        let supervision = SupervisorConfig::DEFAULT;
        let servo = match Servo::new(&design, &config, &supervision) {
            Ok(s) => s,
            Err(e) => defmt::panic!("served servo rejected: {}", e),
        };
        let plant = match ServedActuator::new(design, &config, load_mnm as f32 / 1000.0) {
            Ok(p) => p,
            Err(e) => defmt::panic!("served plant rejected: {}", e),
        };
        let kind = WorldKind::Served(plant);
        (
            World { kind },
            servo,
            Service::new(design, config, supervision),
        )
    }

    /// Start of a tick: the plant advances one period with the bridge lines as they are,
    /// the new readings go to the sensors, a scenario's actions to the servo.
    pub fn begin_tick(&mut self, io: &mut Io, servo: &mut Servo) -> TickPlan {
        let (r, overrun) = match &mut self.kind {
            WorldKind::Scenario { run, actions } => {
                let overrun = run.begin_tick(io.lines(), actions);
                for a in actions.iter() {
                    if let Err(e) = run.apply(servo, a) {
                        defmt::warn!("scenario action refused: {}", e);
                    }
                }
                (run.readings(), overrun)
            }
            WorldKind::Served(plant) => {
                (plant.tick(io.lines(), servo.controller().schedule()), false)
            }
        };
        io.link.value = r.link_encoder;
        io.pot.value = r.gear_pot;
        io.current.value = r.current_adc;
        TickPlan { overrun }
    }

    /// End of a tick: a scenario's metrics, hash and fault timing.
    pub fn end_tick(&mut self, servo: &Servo, out: &TickOutput, late: Option<Fault>, io: &Io) {
        if let WorldKind::Scenario { run, .. } = &mut self.kind {
            run.end_tick(servo, out, late, io.lines());
        }
    }

    /// The next event for the log.
    pub fn pop_event(&mut self) -> Option<ScenarioEvent> {
        match &mut self.kind {
            WorldKind::Scenario { run, .. } => run.pop_event(),
            WorldKind::Served(_) => None,
        }
    }
}

/// Clutch length a serving board starts at, mm.
pub const SERVED_CLUTCH_MM: i32 = 3;

/// Moves the world's events into the log queue; after the last one, the cost accounting.
pub fn drain_world(
    control: &mut crate::control::ControlLoop,
    push: &mut impl FnMut(crate::report::LogItem),
) {
    use crate::report::LogItem;
    let world = control.world_mut();
    let mut finished = false;
    while let Some(ev) = world.pop_event() {
        finished |= matches!(ev, ScenarioEvent::Finished(_));
        push(LogItem::Scenario(ev));
    }
    if finished {
        push(LogItem::Costs(control.stats()));
    }
}
