//! The actuator I/O of one control tick, the same on every board and in the benchmark:
//! the sensors read through the driver traits into the servo's input
//! ([`TickIo::read_inputs`]) and the servo's demand put on the H-bridge
//! ([`TickIo::drive`]).
//!
//! Its two safety rules (tested on the host, `tests/tick_io.rs`):
//! - a failed read keeps the sensor's last good value and names the sensor in
//!   `TickInput::read_error`, so the supervisor sees the failure and the controller never a
//!   made-up reading; the supply sense is advisory: a failed read gives no reading
//!   (`TickInput::supply_adc` is `None`) and no fault;
//! - the bridge is off whenever the servo says so ([`BridgeDemand::Off`]), and after any
//!   driver error (counted in [`TickIo::bridge_errors`]); a brake
//!   ([`BridgeDemand::Brake`], the fault reaction) never turns on a bridge that is off.

use embedded_hal::digital::OutputPin;
use embedded_hal::pwm::SetDutyCycle;
use model::sensors::ADC_MID;
use model::servo::{BridgeDemand, TickInput};
use model::supervisor::Sensor;

use crate::{AngleSensor, BridgeState, CurrentSensor, HBridge, SupplySensor};

/// The sensors and the H-bridge of one actuator, with what the last tick read.
pub struct TickIo<Link, Pot, Current, Supply, Pwm, Dir, En> {
    /// Link-side angle sensor (magnetic encoder).
    pub link: Link,
    /// Gear-side angle sensor (potentiometer).
    pub pot: Pot,
    /// Motor current sensor.
    pub current: Current,
    /// H-bridge supply sense.
    pub supply: Supply,
    /// The H-bridge.
    pub bridge: HBridge<Pwm, Dir, En>,
    last: TickInput,
    bridge_errors: u32,
}

impl<Link, Pot, Current, Supply, Pwm, Dir, En> TickIo<Link, Pot, Current, Supply, Pwm, Dir, En>
where
    Link: AngleSensor,
    Pot: AngleSensor,
    Current: CurrentSensor,
    Supply: SupplySensor,
    Pwm: SetDutyCycle,
    Dir: OutputPin,
    En: OutputPin,
{
    /// The actuator's I/O; until the first good read the servo sees the link at 0, no
    /// gear pot, zero current (`ADC_MID`) and no supply reading.
    pub fn new(
        link: Link,
        pot: Pot,
        current: Current,
        supply: Supply,
        bridge: HBridge<Pwm, Dir, En>,
    ) -> Self {
        Self {
            link,
            pot,
            current,
            supply,
            bridge,
            last: TickInput {
                link_encoder: 0,
                gear_pot: None,
                current_adc: ADC_MID,
                supply_adc: None,
                read_error: None,
            },
            bridge_errors: 0,
        }
    }

    /// Reads the sensors; a failed read keeps the last value and is reported (the supply
    /// sense's gives no reading).
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
        input.supply_adc = self.supply.read_raw().ok();
        self.last = input;
        input
    }

    /// Puts the servo's demand on the H-bridge; a driver error turns the bridge off.
    pub fn drive(&mut self, demand: BridgeDemand) {
        let result = match demand {
            // Already off, nothing to write; and braking never turns on a bridge that is
            // off (disabled, or after a driver error).
            BridgeDemand::Off | BridgeDemand::Brake
                if self.bridge.state() == BridgeState::Disabled =>
            {
                Ok(())
            }
            BridgeDemand::Off => self.bridge.disable(),
            BridgeDemand::Brake => self.bridge.brake(),
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

    /// H-bridge driver errors so far.
    pub fn bridge_errors(&self) -> u32 {
        self.bridge_errors
    }

    /// The duty the bridge drives, signed ‰ (0 unless driving).
    pub fn applied_duty(&self) -> i16 {
        match self.bridge.state() {
            BridgeState::Drive(d) => d,
            _ => 0,
        }
    }
}
