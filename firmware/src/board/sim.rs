//! The emulated boards' peripherals: the simulated actuator behind the same driver traits
//! the real board implements. The H-bridge driver writes simulated PWM and GPIO lines; the
//! sensors return the readings the plant produced at the start of the tick.
//!
//! Each tick the [`World`] advances the plant by one control period with the bridge lines
//! as they are, applies the scenario's injections and actions, and presents the new
//! readings to the sensors (`plant::scenario` has the per-tick protocol).

use core::convert::Infallible;
use drivers::{AngleSensor, CurrentSensor, HBridge, SensorError};
use embedded_hal::digital::{ErrorType as PinErrorType, OutputPin};
use embedded_hal::pwm::{ErrorType as PwmErrorType, SetDutyCycle};
use model::servo::{Servo, TickOutput};
use model::supervisor::Fault;
use plant::scenario::{Action, BridgeLines, ScenarioEvent, ScenarioId, ScenarioRun};

/// Simulated PWM channel: the duty in ‰ of the period (max duty 1000).
#[derive(Default)]
pub struct SimPwm {
    duty: u16,
}

impl PwmErrorType for SimPwm {
    type Error = Infallible;
}

impl SetDutyCycle for SimPwm {
    fn max_duty_cycle(&self) -> u16 {
        1000
    }

    fn set_duty_cycle(&mut self, duty: u16) -> Result<(), Infallible> {
        self.duty = duty.min(1000);
        Ok(())
    }
}

/// Simulated GPIO output.
#[derive(Default)]
pub struct SimPin {
    high: bool,
}

impl PinErrorType for SimPin {
    type Error = Infallible;
}

impl OutputPin for SimPin {
    fn set_low(&mut self) -> Result<(), Infallible> {
        self.high = false;
        Ok(())
    }

    fn set_high(&mut self) -> Result<(), Infallible> {
        self.high = true;
        Ok(())
    }
}

/// A simulated sensor channel: returns the value the plant presented this tick.
pub struct SimChannel<const FULL: u16> {
    value: u16,
}

impl<const FULL: u16> AngleSensor for SimChannel<FULL> {
    const FULL_SCALE: u16 = FULL;

    fn read_counts(&mut self) -> Result<u16, SensorError> {
        Ok(self.value)
    }
}

impl<const FULL: u16> CurrentSensor for SimChannel<FULL> {
    fn read_raw(&mut self) -> Result<u16, SensorError> {
        Ok(self.value)
    }
}

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
            enabled: self.bridge.en().high,
            forward: self.bridge.dir().high,
            duty_permille: self.bridge.pwm().duty,
        }
    }
}

/// What the start of a tick asks of the control loop.
pub struct TickPlan {
    /// Busy-wait past the deadline in this tick (fault injection).
    pub overrun: bool,
}

/// The simulated world: the scenario and its plant.
pub struct World {
    run: ScenarioRun,
    actions: heapless::Vec<Action, 3>,
}

impl World {
    /// Starts `id`; also returns the servo configured for it.
    pub fn new(id: ScenarioId) -> (World, Servo) {
        let run = match ScenarioRun::new(id) {
            Ok(r) => r,
            Err(e) => defmt::panic!("scenario {=str} rejected: {}", id.name(), e),
        };
        let servo = match run.servo() {
            Ok(s) => s,
            Err(e) => defmt::panic!("scenario {=str}: servo rejected: {}", id.name(), e),
        };
        (
            World {
                run,
                actions: heapless::Vec::new(),
            },
            servo,
        )
    }

    /// Start of a tick: the plant advances one period with the bridge lines as they are,
    /// the new readings go to the sensors, the scenario's actions to the servo.
    pub fn begin_tick(&mut self, io: &mut Io, servo: &mut Servo) -> TickPlan {
        let overrun = self.run.begin_tick(io.lines(), &mut self.actions);
        let r = self.run.readings();
        io.link.value = r.link_encoder;
        io.pot.value = r.gear_pot;
        io.current.value = r.current_adc;
        for a in &self.actions {
            if let Err(e) = self.run.apply(servo, a) {
                defmt::warn!("scenario action refused: {}", e);
            }
        }
        TickPlan { overrun }
    }

    /// End of a tick: metrics, hash and fault timing.
    pub fn end_tick(&mut self, servo: &Servo, out: &TickOutput, late: Option<Fault>, io: &Io) {
        self.run.end_tick(servo, out, late, io.lines());
    }

    /// The next event for the log.
    pub fn pop_event(&mut self) -> Option<ScenarioEvent> {
        self.run.pop_event()
    }

    /// Whether the scenario has ended.
    pub fn is_done(&self) -> bool {
        self.run.is_done()
    }
}

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
