//! The control step's I/O glue, as in `firmware/src/control.rs`: the three sensors read
//! through the `drivers` traits (a failed read keeps the last value and is reported), the
//! servo's demand put on the `drivers::HBridge`. The channels and lines are simulated, as
//! on the emulated boards (`firmware/src/board/sim.rs`): a sensor returns the value
//! presented to it this tick, the PWM and GPIO lines remember what was written.

pub use drivers::sim::{SimChannel, SimPin, SimPwm};
use drivers::{AngleSensor, BridgeState, CurrentSensor, HBridge};
use model::servo::{BridgeDemand, TickInput};
use model::supervisor::Sensor;

/// The H-bridge on simulated lines.
pub type Bridge = HBridge<SimPwm, SimPin, SimPin>;

/// The actuator I/O of one control step.
pub struct Io {
    /// Link encoder, 4096 counts per turn.
    pub link: SimChannel<4096>,
    /// Gear potentiometer, 1024 counts over 300°.
    pub pot: SimChannel<1024>,
    /// Current ADC, 12 bit.
    pub current: SimChannel<4096>,
    /// H-bridge.
    pub bridge: Bridge,
    last: TickInput,
    /// H-bridge driver errors so far.
    pub bridge_errors: u32,
}

impl Io {
    /// All lines low, sensors at mid-scale. `None` if the bridge driver refused the lines
    /// (it cannot: they are infallible).
    #[must_use]
    pub fn new() -> Option<Io> {
        let bridge = HBridge::new(SimPwm::default(), SimPin::default(), SimPin::default()).ok()?;
        Some(Io {
            link: SimChannel { value: 0 },
            pot: SimChannel { value: 512 },
            current: SimChannel { value: 2048 },
            bridge,
            last: TickInput {
                link_encoder: 0,
                gear_pot: None,
                current_adc: 2048,
                read_error: None,
            },
            bridge_errors: 0,
        })
    }

    /// Presents this tick's readings to the sensors.
    pub fn present(&mut self, link_encoder: u16, gear_pot: u16, current_adc: u16) {
        self.link.value = link_encoder;
        self.pot.value = gear_pot;
        self.current.value = current_adc;
    }

    /// Reads the three sensors; a failed read keeps the last value and is reported.
    pub fn read_inputs(&mut self) -> TickInput {
        let mut input = self.last;
        input.read_error = None;
        match self.link.read_counts() {
            Ok(v) => input.link_encoder = v,
            Err(_) => input.read_error = Some(Sensor::LinkEncoder),
        }
        match self.pot.read_counts() {
            Ok(v) => input.gear_pot = Some(v),
            Err(_) => input.read_error = Some(Sensor::GearPot),
        }
        match self.current.read_raw() {
            Ok(v) => input.current_adc = v,
            Err(_) => input.read_error = Some(Sensor::CurrentAdc),
        }
        self.last = input;
        input
    }

    /// Puts the servo's demand on the H-bridge; a driver error turns the bridge off.
    pub fn drive(&mut self, demand: BridgeDemand) {
        let result = match demand {
            BridgeDemand::Off if self.bridge.state() == BridgeState::Disabled => Ok(()),
            BridgeDemand::Off => self.bridge.disable(),
            BridgeDemand::Drive(duty) => {
                self.bridge.enable();
                self.bridge.drive(duty)
            }
        };
        if result.is_err() {
            self.bridge_errors = self.bridge_errors.saturating_add(1);
            let _ = self.bridge.disable();
        }
    }

    /// The duty the bridge drives, signed ‰ (0 unless driving).
    #[must_use]
    pub fn applied_duty(&self) -> i16 {
        match self.bridge.state() {
            BridgeState::Drive(d) => d,
            _ => 0,
        }
    }
}
