//! In-memory implementations of the lines and sensors: what the emulated boards hand the
//! drivers (the simulated actuator reads the lines and presents the sensor values), and
//! what host code can use without mocks.
//!
//! Nothing here can fail ([`Infallible`]).

use core::convert::Infallible;
use embedded_hal::digital::{ErrorType as PinErrorType, OutputPin};
use embedded_hal::pwm::{ErrorType as PwmErrorType, SetDutyCycle};

use crate::tick_io::TickIo;
use crate::{
    AngleSensor, BridgeError, CurrentSensor, HBridge, SensorError, SupplySensor, DUTY_FULL_SCALE,
};

/// A PWM channel that remembers its duty, in ‰ of the period (max duty
/// [`DUTY_FULL_SCALE`] = 1000).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SimPwm {
    duty: u16,
}

impl SimPwm {
    /// The duty last set, ‰.
    #[must_use]
    pub const fn duty(&self) -> u16 {
        self.duty
    }
}

impl PwmErrorType for SimPwm {
    type Error = Infallible;
}

impl SetDutyCycle for SimPwm {
    fn max_duty_cycle(&self) -> u16 {
        DUTY_FULL_SCALE as u16
    }

    fn set_duty_cycle(&mut self, duty: u16) -> Result<(), Infallible> {
        self.duty = duty.min(DUTY_FULL_SCALE as u16);
        Ok(())
    }
}

/// A GPIO output that remembers its level (low at first).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SimPin {
    high: bool,
}

impl SimPin {
    /// Whether the line is high.
    #[must_use]
    pub const fn is_high(&self) -> bool {
        self.high
    }
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

/// A sensor channel of `FULL` counts that returns the value presented to it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SimChannel<const FULL: u16> {
    /// The reading the next read returns, counts.
    pub value: u16,
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

impl<const FULL: u16> SupplySensor for SimChannel<FULL> {
    fn read_raw(&mut self) -> Result<u16, SensorError> {
        Ok(self.value)
    }
}

/// The H-bridge on simulated lines.
pub type SimBridge = HBridge<SimPwm, SimPin, SimPin>;

/// A tick's I/O on simulated channels of `LINK`, `POT` and `ADC` counts full scale (the
/// current and the supply sense share the ADC) and a simulated H-bridge: what the emulated
/// boards and the benchmark run the control step on.
pub type SimTickIo<const LINK: u16, const POT: u16, const ADC: u16> = TickIo<
    SimChannel<LINK>,
    SimChannel<POT>,
    SimChannel<ADC>,
    SimChannel<ADC>,
    SimPwm,
    SimPin,
    SimPin,
>;

impl<const LINK: u16, const POT: u16, const ADC: u16> SimTickIo<LINK, POT, ADC> {
    /// All lines low, the sensors presenting `link`, `pot`, `current` and `supply` counts.
    ///
    /// # Errors
    /// Only if the bridge driver refused the lines, which cannot happen: they are
    /// infallible.
    pub fn simulated(link: u16, pot: u16, current: u16, supply: u16) -> Result<Self, BridgeError> {
        let bridge = HBridge::new(SimPwm::default(), SimPin::default(), SimPin::default())?;
        Ok(TickIo::new(
            SimChannel { value: link },
            SimChannel { value: pot },
            SimChannel { value: current },
            SimChannel { value: supply },
            bridge,
        ))
    }

    /// Presents this tick's readings to the sensors.
    pub fn present(&mut self, link: u16, pot: u16, current: u16, supply: u16) {
        self.link.value = link;
        self.pot.value = pot;
        self.current.value = current;
        self.supply.value = supply;
    }
}
