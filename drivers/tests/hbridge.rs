//! The H-bridge driver against embedded-hal-mock: the exact PWM and pin transactions, in
//! order, for each operation. Each test spells its transactions out in full so that it
//! reads alone (`duplicates` pairs lists of the same shape: on purpose).

mod common;

use common::MockBridge;
use drivers::{BridgeError, BridgeState};
use embedded_hal_mock::eh1::digital::{State, Transaction as Pin};
use embedded_hal_mock::eh1::pwm::Transaction as Pwm;
use embedded_hal_mock::eh1::MockError;

/// The timer's auto-reload: 20 kHz from 180 MHz is 9000 counts.
const MAX: u16 = 9000;

struct Rig {
    bridge: MockBridge,
}

/// Builds a bridge whose `new` transactions are followed by the given ones.
fn rig(pwm_after: &[Pwm], dir_after: &[Pin], en_after: &[Pin]) -> Rig {
    Rig {
        bridge: common::bridge(pwm_after, dir_after, en_after),
    }
}

impl Rig {
    fn done(self) {
        let (mut pwm, mut dir, mut en) = match self.bridge.release() {
            Ok(parts) => parts,
            Err(e) => panic!("release failed: {e:?}"),
        };
        pwm.done();
        dir.done();
        en.done();
    }
}

/// Disabling at release: enable low, then PWM off.
fn release_tx() -> (Pwm, Pin) {
    (Pwm::set_duty_cycle(0), Pin::set(State::Low))
}

#[test]
fn starts_disabled_and_refuses_to_drive_until_enabled() {
    let (rp, re) = release_tx();
    let mut r = rig(&[rp], &[], &[re]);
    assert_eq!(r.bridge.state(), BridgeState::Disabled);
    assert_eq!(r.bridge.drive(500), Err(BridgeError::Disabled));
    assert_eq!(r.bridge.brake(), Err(BridgeError::Disabled));
    assert_eq!(r.bridge.state(), BridgeState::Disabled);
    r.done();
}

#[test]
fn forward_drive_scales_the_duty_and_enables_last() {
    // +250 ‰ of 9000 = 2250; the direction pin is already low from `new`, so it is set
    // high once (PWM off first), then the duty, then enable.
    let (rp, re) = release_tx();
    let mut r = rig(
        &[
            Pwm::set_duty_cycle(0),
            Pwm::max_duty_cycle(MAX),
            Pwm::set_duty_cycle(2250),
            Pwm::max_duty_cycle(MAX),
            Pwm::set_duty_cycle(9000),
            rp,
        ],
        &[Pin::set(State::High)],
        &[Pin::set(State::High), re],
    );
    r.bridge.enable();
    assert_eq!(r.bridge.state(), BridgeState::Coast);
    r.bridge.drive(250).unwrap();
    assert_eq!(r.bridge.state(), BridgeState::Drive(250));
    // Same direction: no pin writes, only the new duty.
    r.bridge.drive(1000).unwrap();
    r.done();
}

#[test]
fn reversing_turns_the_pwm_off_before_the_direction_pin_changes() {
    let (rp, re) = release_tx();
    let mut r = rig(
        &[
            Pwm::set_duty_cycle(0),
            Pwm::max_duty_cycle(MAX),
            Pwm::set_duty_cycle(900),
            // reverse: off, flip, new duty
            Pwm::set_duty_cycle(0),
            Pwm::max_duty_cycle(MAX),
            Pwm::set_duty_cycle(4500),
            rp,
        ],
        &[Pin::set(State::High), Pin::set(State::Low)],
        &[Pin::set(State::High), re],
    );
    r.bridge.enable();
    r.bridge.drive(100).unwrap();
    r.bridge.drive(-500).unwrap();
    assert_eq!(r.bridge.state(), BridgeState::Drive(-500));
    r.done();
}

#[test]
fn zero_duty_keeps_the_direction_and_the_bridge_enabled() {
    let (rp, re) = release_tx();
    let mut r = rig(
        &[Pwm::max_duty_cycle(MAX), Pwm::set_duty_cycle(0), rp],
        &[],
        &[Pin::set(State::High), re],
    );
    r.bridge.enable();
    r.bridge.drive(0).unwrap();
    assert_eq!(r.bridge.state(), BridgeState::Drive(0));
    r.done();
}

#[test]
fn out_of_range_duty_is_rejected_without_touching_the_hardware() {
    let (rp, re) = release_tx();
    let mut r = rig(&[rp], &[], &[re]);
    r.bridge.enable();
    assert_eq!(r.bridge.drive(1001), Err(BridgeError::DutyOutOfRange));
    assert_eq!(r.bridge.drive(i16::MIN), Err(BridgeError::DutyOutOfRange));
    assert_eq!(r.bridge.state(), BridgeState::Coast);
    r.done();
}

#[test]
fn brake_shorts_the_terminals_and_coast_opens_them() {
    let (rp, re) = release_tx();
    let mut r = rig(
        &[
            Pwm::set_duty_cycle(0), // brake: PWM off, enable high
            Pwm::set_duty_cycle(0), // coast: enable low, PWM off
            rp,
        ],
        &[],
        &[Pin::set(State::High), Pin::set(State::Low), re],
    );
    r.bridge.enable();
    r.bridge.brake().unwrap();
    assert_eq!(r.bridge.state(), BridgeState::Brake);
    r.bridge.coast().unwrap();
    assert_eq!(r.bridge.state(), BridgeState::Coast);
    r.done();
}

#[test]
fn disable_drops_enable_first_and_latches() {
    let (rp, re) = release_tx();
    let mut r = rig(
        &[
            Pwm::set_duty_cycle(0),
            Pwm::max_duty_cycle(MAX),
            Pwm::set_duty_cycle(6300),
            Pwm::set_duty_cycle(0), // disable
            rp,
        ],
        &[Pin::set(State::High)],
        &[Pin::set(State::High), Pin::set(State::Low), re],
    );
    r.bridge.enable();
    r.bridge.drive(700).unwrap();
    r.bridge.disable().unwrap();
    assert_eq!(r.bridge.state(), BridgeState::Disabled);
    assert_eq!(r.bridge.drive(700), Err(BridgeError::Disabled));
    r.done();
}

#[test]
fn a_failing_enable_pin_still_turns_the_pwm_off_and_reports_the_error() {
    let mut r = rig(
        &[
            Pwm::set_duty_cycle(0),
            Pwm::max_duty_cycle(MAX),
            Pwm::set_duty_cycle(4500),
            Pwm::set_duty_cycle(0), // disable: PWM off although enable failed
        ],
        &[Pin::set(State::High)],
        &[
            Pin::set(State::High),
            Pin::set(State::Low).with_error(MockError::Io(std::io::ErrorKind::Other)),
        ],
    );
    r.bridge.enable();
    r.bridge.drive(500).unwrap();
    assert!(matches!(r.bridge.disable(), Err(BridgeError::Pin(_))));
    assert_eq!(r.bridge.state(), BridgeState::Disabled);
    let mut bridge = r.bridge;
    // Done without `release` (it would disable again): check the mocks consumed everything.
    common::done(&bridge);
    assert_eq!(bridge.drive(1), Err(BridgeError::Disabled));
}
