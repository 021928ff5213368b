//! Driver layer of the vsa firmware, on embedded-hal 1.0.
//!
//! embedded-hal 1.0 has PWM ([`SetDutyCycle`]) and GPIO ([`OutputPin`]) but no trait for an
//! angle sensor or a current sensor, so this crate defines them ([`AngleSensor`],
//! [`CurrentSensor`]), together with the H-bridge motor driver the control loop drives
//! ([`HBridge`]). Each board implements the sensor traits on its peripherals (the Nucleo
//! on its timer encoder interface and ADC, the emulated boards on the simulated actuator)
//! and hands the H-bridge its PWM channel and two pins. [`tick_io`] is the I/O of one
//! control tick over these traits (sensors → servo input, servo demand → H-bridge).
//!
//! Everything is `no_std`, allocation-free and panic-free, and is unit-tested on the host
//! against `embedded-hal-mock` (the exact pin and PWM transactions are checked).
#![no_std]
#![forbid(unsafe_code)]
#![deny(missing_docs)]

pub mod sim;
pub mod tick_io;
pub mod usart_baud;

use embedded_hal::digital::{self, OutputPin};
use embedded_hal::pwm::{self, SetDutyCycle};

/// Largest |duty| the H-bridge accepts, ‰ (1000 = the full supply voltage).
pub const DUTY_FULL_SCALE: i16 = 1000;

/// Why a sensor read failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum SensorError {
    /// No new conversion or frame arrived in time.
    Timeout,
    /// The bus or peripheral reported an error (NACK, overrun, parity).
    Bus,
    /// The sensor reported its own fault (e.g. magnet out of range).
    Device,
}

/// An absolute angle sensor read once per control tick: a magnetic encoder on the link,
/// a potentiometer on the output gear.
pub trait AngleSensor {
    /// Counts of one full scale (4096 for a 12-bit encoder per turn, 1024 for the pot
    /// over 300°).
    const FULL_SCALE: u16;

    /// The latest raw reading, `0..FULL_SCALE`.
    ///
    /// # Errors
    /// [`SensorError`] when no valid reading is available.
    fn read_counts(&mut self) -> Result<u16, SensorError>;
}

/// The motor current sensor: a shunt amplifier into an ADC, read once per control tick.
pub trait CurrentSensor {
    /// The latest raw ADC conversion, `0..=4095` for a 12-bit ADC; the conversion to
    /// ampere (offset, gain) is the controller's calibration.
    ///
    /// # Errors
    /// [`SensorError`] when no conversion is available.
    fn read_raw(&mut self) -> Result<u16, SensorError>;
}

/// The H-bridge supply sense: a divider into an ADC, read once per control tick
/// (`model::sensors::SUPPLY_MV_PER_COUNT`). Advisory: a failed read leaves the tick's
/// reading out, and the configured supply stays in force (`model::control::supply_window`).
pub trait SupplySensor {
    /// The latest raw ADC conversion, `0..=4095` for a 12-bit ADC.
    ///
    /// # Errors
    /// [`SensorError`] when no conversion is available.
    fn read_raw(&mut self) -> Result<u16, SensorError>;
}

/// What the H-bridge is doing.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum BridgeState {
    /// Driving with a signed duty, ‰ (positive: direction pin high).
    Drive(i16),
    /// Bridge enabled, PWM at 0: both low-side switches on, the motor terminals shorted
    /// (dynamic braking).
    Brake,
    /// Bridge outputs off (enable low): the motor free-wheels.
    Coast,
    /// Off like [`BridgeState::Coast`], and latched: [`HBridge::drive`] and
    /// [`HBridge::brake`] are refused until [`HBridge::enable`].
    Disabled,
}

/// Why an H-bridge operation failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum BridgeError {
    /// The PWM channel failed.
    Pwm(pwm::ErrorKind),
    /// The direction or enable pin failed.
    Pin(digital::ErrorKind),
    /// The bridge is disabled; call [`HBridge::enable`] first.
    Disabled,
    /// |duty| > [`DUTY_FULL_SCALE`].
    DutyOutOfRange,
}

fn pwm_err<E: pwm::Error>(e: E) -> BridgeError {
    BridgeError::Pwm(e.kind())
}

fn pin_err<E: digital::Error>(e: E) -> BridgeError {
    BridgeError::Pin(e.kind())
}

/// A sign-magnitude H-bridge (e.g. a DRV8874 in PH/EN mode with nSLEEP as enable, or an
/// L298-style bridge): one PWM channel sets the magnitude, a direction pin the sign, and an
/// enable pin turns the output stage on (high) or off (low, outputs high-impedance).
///
/// Switching order avoids shoot-through and wrong-direction pulses: the PWM goes to 0 before
/// the direction pin changes, and the enable pin goes low before anything else when
/// stopping. The driver starts [`BridgeState::Disabled`] with all outputs low.
pub struct HBridge<Pwm, Dir, En> {
    pwm: Pwm,
    dir: Dir,
    en: En,
    state: BridgeState,
    /// Direction pin level last written (`None`: unknown, write it before driving).
    dir_high: Option<bool>,
}

impl<Pwm, Dir, En> HBridge<Pwm, Dir, En>
where
    Pwm: SetDutyCycle,
    Dir: OutputPin,
    En: OutputPin,
{
    /// Takes the PWM channel and the pins, and puts the bridge in the safe state: enable
    /// low, PWM 0, direction low.
    ///
    /// # Errors
    /// A pin or the PWM failed; the parts are dropped (the caller's board init fails).
    pub fn new(pwm: Pwm, dir: Dir, en: En) -> Result<Self, BridgeError> {
        let mut bridge = Self {
            pwm,
            dir,
            en,
            state: BridgeState::Disabled,
            dir_high: None,
        };
        bridge.en.set_low().map_err(pin_err)?;
        bridge.pwm.set_duty_cycle_fully_off().map_err(pwm_err)?;
        bridge.dir.set_low().map_err(pin_err)?;
        bridge.dir_high = Some(false);
        Ok(bridge)
    }

    /// The current state.
    pub fn state(&self) -> BridgeState {
        self.state
    }

    /// Drives with a signed duty in ‰ (`-1000..=1000`).
    ///
    /// # Errors
    /// [`BridgeError::Disabled`] while disabled (nothing is written),
    /// [`BridgeError::DutyOutOfRange`], or a pin/PWM error.
    pub fn drive(&mut self, duty_permille: i16) -> Result<(), BridgeError> {
        if self.state == BridgeState::Disabled {
            return Err(BridgeError::Disabled);
        }
        if duty_permille.unsigned_abs() > DUTY_FULL_SCALE.unsigned_abs() {
            return Err(BridgeError::DutyOutOfRange);
        }
        let want_high = duty_permille > 0;
        let magnitude = duty_permille.unsigned_abs();
        if magnitude != 0 && self.dir_high != Some(want_high) {
            // Never drive the new direction with the old duty: PWM off, then flip.
            self.pwm.set_duty_cycle_fully_off().map_err(pwm_err)?;
            if want_high {
                self.dir.set_high().map_err(pin_err)?;
            } else {
                self.dir.set_low().map_err(pin_err)?;
            }
            self.dir_high = Some(want_high);
        }
        self.pwm
            .set_duty_cycle_fraction(magnitude, DUTY_FULL_SCALE.unsigned_abs())
            .map_err(pwm_err)?;
        if !matches!(self.state, BridgeState::Drive(_) | BridgeState::Brake) {
            self.en.set_high().map_err(pin_err)?;
        }
        self.state = BridgeState::Drive(duty_permille);
        Ok(())
    }

    /// Shorts the motor terminals (enable high, PWM 0).
    ///
    /// # Errors
    /// [`BridgeError::Disabled`] while disabled, or a pin/PWM error.
    pub fn brake(&mut self) -> Result<(), BridgeError> {
        if self.state == BridgeState::Disabled {
            return Err(BridgeError::Disabled);
        }
        self.pwm.set_duty_cycle_fully_off().map_err(pwm_err)?;
        if !matches!(self.state, BridgeState::Drive(_) | BridgeState::Brake) {
            self.en.set_high().map_err(pin_err)?;
        }
        self.state = BridgeState::Brake;
        Ok(())
    }

    /// Lets the motor free-wheel (enable low, PWM 0). Allowed while disabled (stays
    /// disabled).
    ///
    /// # Errors
    /// A pin/PWM error.
    pub fn coast(&mut self) -> Result<(), BridgeError> {
        self.off()?;
        if self.state != BridgeState::Disabled {
            self.state = BridgeState::Coast;
        }
        Ok(())
    }

    /// Turns the output stage off and latches it off: the supervisor's safe state. Enable
    /// goes low first (the bridge is off after the first write), then the PWM to 0.
    ///
    /// # Errors
    /// A pin/PWM error. The state is [`BridgeState::Disabled`] even then, so no further
    /// drive is attempted.
    pub fn disable(&mut self) -> Result<(), BridgeError> {
        self.state = BridgeState::Disabled;
        self.off()
    }

    /// Leaves [`BridgeState::Disabled`] for [`BridgeState::Coast`]; the next
    /// [`HBridge::drive`] turns the output stage on.
    pub fn enable(&mut self) {
        if self.state == BridgeState::Disabled {
            self.state = BridgeState::Coast;
        }
    }

    fn off(&mut self) -> Result<(), BridgeError> {
        // Try both writes even if the first fails: each one alone stops the motor.
        let en = self.en.set_low().map_err(pin_err);
        let pwm = self.pwm.set_duty_cycle_fully_off().map_err(pwm_err);
        en.and(pwm)
    }

    /// The PWM channel (e.g. for a simulated bridge to read the duty written).
    pub fn pwm(&self) -> &Pwm {
        &self.pwm
    }

    /// The direction pin.
    pub fn dir(&self) -> &Dir {
        &self.dir
    }

    /// The enable pin.
    pub fn en(&self) -> &En {
        &self.en
    }

    /// Gives the parts back, after disabling the bridge.
    ///
    /// # Errors
    /// A pin/PWM error while disabling; the parts are returned only when the bridge is off.
    pub fn release(mut self) -> Result<(Pwm, Dir, En), BridgeError> {
        self.disable()?;
        Ok((self.pwm, self.dir, self.en))
    }
}
