//! The tick I/O's safety rules against embedded-hal-mock: a failed read keeps the last
//! value and names the sensor; the bridge is off when the servo says so, and after a driver
//! error.

mod common;

use drivers::tick_io::TickIo;
use drivers::{AngleSensor, BridgeState, CurrentSensor, SensorError, SupplySensor};
use embedded_hal_mock::eh1::digital::{Mock as PinMock, State, Transaction as Pin};
use embedded_hal_mock::eh1::pwm::{Mock as PwmMock, Transaction as Pwm};
use embedded_hal_mock::eh1::MockError;
use model::sensors::{ADC_MID, ENCODER_COUNTS};
use model::servo::BridgeDemand;
use model::supervisor::Sensor;
use std::collections::VecDeque;

/// A sensor that returns the scripted results in order (a timeout once they run out).
struct Scripted(VecDeque<Result<u16, SensorError>>);

impl Scripted {
    fn new(results: &[Result<u16, SensorError>]) -> Self {
        Self(results.iter().copied().collect())
    }

    fn next(&mut self) -> Result<u16, SensorError> {
        self.0.pop_front().unwrap_or(Err(SensorError::Timeout))
    }
}

impl AngleSensor for Scripted {
    const FULL_SCALE: u16 = ENCODER_COUNTS;

    fn read_counts(&mut self) -> Result<u16, SensorError> {
        self.next()
    }
}

impl CurrentSensor for Scripted {
    fn read_raw(&mut self) -> Result<u16, SensorError> {
        self.next()
    }
}

impl SupplySensor for Scripted {
    fn read_raw(&mut self) -> Result<u16, SensorError> {
        self.next()
    }
}

type Io = TickIo<Scripted, Scripted, Scripted, Scripted, PwmMock, PinMock, PinMock>;

/// The timer's auto-reload of the mocked PWM.
const MAX: u16 = 1000;

/// Tick I/O whose bridge expects its `new` transactions, then the given ones.
fn io(
    sensors: [&[Result<u16, SensorError>]; 4],
    pwm_after: &[Pwm],
    dir_after: &[Pin],
    en_after: &[Pin],
) -> Io {
    let bridge = common::bridge(pwm_after, dir_after, en_after);
    let [link, pot, current, supply] = sensors;
    TickIo::new(
        Scripted::new(link),
        Scripted::new(pot),
        Scripted::new(current),
        Scripted::new(supply),
        bridge,
    )
}

/// Checks that the bridge's mocks saw every expected transaction, and nothing more.
fn done(io: &Io) {
    common::done(&io.bridge);
}

const LOST: Result<u16, SensorError> = Err(SensorError::Bus);

#[test]
fn a_failed_read_keeps_the_last_value_and_names_the_sensor() {
    let mut io = io(
        [
            &[Ok(100), LOST, Ok(300), Ok(400)],
            &[Ok(500), Ok(510), LOST, Ok(530)],
            &[Ok(2000), Ok(2100), Ok(2200), LOST],
            &[Ok(2400), Ok(2401), Ok(2402), Ok(2403)],
        ],
        &[],
        &[],
        &[],
    );
    let first = io.read_inputs();
    assert_eq!(
        (first.link_encoder, first.gear_pot, first.current_adc),
        (100, Some(500), 2000)
    );
    assert_eq!(first.read_error, None);

    let second = io.read_inputs();
    assert_eq!(
        second.link_encoder, 100,
        "the link keeps its last good value"
    );
    assert_eq!((second.gear_pot, second.current_adc), (Some(510), 2100));
    assert_eq!(second.read_error, Some(Sensor::LinkEncoder));

    let third = io.read_inputs();
    assert_eq!(
        third.gear_pot,
        Some(510),
        "the pot keeps its last good value"
    );
    assert_eq!((third.link_encoder, third.current_adc), (300, 2200));
    assert_eq!(third.read_error, Some(Sensor::GearPot));

    let fourth = io.read_inputs();
    assert_eq!(
        fourth.current_adc, 2200,
        "the current keeps its last good value"
    );
    assert_eq!((fourth.link_encoder, fourth.gear_pot), (400, Some(530)));
    assert_eq!(fourth.read_error, Some(Sensor::CurrentAdc));
    done(&io);
}

#[test]
fn a_failed_supply_read_gives_no_reading_and_no_fault() {
    let mut io = io(
        [
            &[Ok(100), Ok(101), Ok(102)],
            &[Ok(500), Ok(501), Ok(502)],
            &[Ok(2000), Ok(2001), Ok(2002)],
            &[Ok(2400), LOST, Ok(2100)],
        ],
        &[],
        &[],
        &[],
    );
    let first = io.read_inputs();
    assert_eq!((first.supply_adc, first.read_error), (Some(2400), None));
    let second = io.read_inputs();
    assert_eq!(
        (second.supply_adc, second.read_error),
        (None, None),
        "a lost supply reading is left out, not kept and not a fault"
    );
    assert_eq!(second.current_adc, 2001);
    let third = io.read_inputs();
    assert_eq!((third.supply_adc, third.read_error), (Some(2100), None));
    done(&io);
}

#[test]
fn before_any_good_read_the_servo_sees_the_actuator_at_rest() {
    let mut io = io([&[LOST], &[LOST], &[LOST], &[LOST]], &[], &[], &[]);
    let input = io.read_inputs();
    assert_eq!(
        (
            input.link_encoder,
            input.gear_pot,
            input.current_adc,
            input.supply_adc
        ),
        (0, None, ADC_MID, None)
    );
    // All three failed; the last one read is the one named.
    assert_eq!(input.read_error, Some(Sensor::CurrentAdc));
    done(&io);
}

#[test]
fn the_bridge_is_off_when_the_servo_says_so_and_brakes_only_while_on() {
    let mut io = io(
        [&[], &[], &[], &[]],
        &[
            // Drive(+450): PWM off before the direction flips, then the duty.
            Pwm::set_duty_cycle(0),
            Pwm::max_duty_cycle(MAX),
            Pwm::set_duty_cycle(450),
            // Brake: the PWM to 0, the enable stays high (the low sides short the motor).
            Pwm::set_duty_cycle(0),
            // Off: enable low first, then the PWM off.
            Pwm::set_duty_cycle(0),
        ],
        &[Pin::set(State::High)],
        &[Pin::set(State::High), Pin::set(State::Low)],
    );
    io.drive(BridgeDemand::Drive(450));
    assert_eq!(io.bridge.state(), BridgeState::Drive(450));
    assert_eq!(io.applied_duty(), 450);
    io.drive(BridgeDemand::Brake);
    assert_eq!(io.bridge.state(), BridgeState::Brake);
    assert_eq!(io.applied_duty(), 0);
    io.drive(BridgeDemand::Off);
    assert_eq!(io.bridge.state(), BridgeState::Disabled);
    assert_eq!(io.applied_duty(), 0);
    // Already off: nothing more is written, and a brake does not turn the bridge on.
    io.drive(BridgeDemand::Off);
    io.drive(BridgeDemand::Brake);
    assert_eq!(io.bridge.state(), BridgeState::Disabled);
    assert_eq!(io.bridge_errors(), 0);
    done(&io);
}

#[test]
fn a_bridge_error_turns_the_bridge_off_and_is_counted() {
    let failure = MockError::Io(std::io::ErrorKind::Other);
    let mut io = io(
        [&[], &[], &[], &[]],
        &[
            Pwm::set_duty_cycle(0),
            Pwm::max_duty_cycle(MAX),
            Pwm::set_duty_cycle(300).with_error(failure),
            // The error: disabled (enable low, PWM off).
            Pwm::set_duty_cycle(0),
        ],
        &[Pin::set(State::High)],
        &[Pin::set(State::Low)],
    );
    io.drive(BridgeDemand::Drive(300));
    assert_eq!(io.bridge.state(), BridgeState::Disabled);
    assert_eq!(io.bridge_errors(), 1);
    assert_eq!(io.applied_duty(), 0);
    done(&io);
}
