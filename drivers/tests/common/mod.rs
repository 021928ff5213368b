//! What the driver tests share: an H-bridge on embedded-hal-mock lines.

use drivers::HBridge;
use embedded_hal_mock::eh1::digital::{Mock as PinMock, State, Transaction as Pin};
use embedded_hal_mock::eh1::pwm::{Mock as PwmMock, Transaction as Pwm};

/// The H-bridge on mocks.
pub type MockBridge = HBridge<PwmMock, PinMock, PinMock>;

/// A bridge whose mocks expect its `new` transactions (enable low, PWM off, direction low),
/// then the given ones.
pub fn bridge(pwm_after: &[Pwm], dir_after: &[Pin], en_after: &[Pin]) -> MockBridge {
    let mut pwm = vec![Pwm::set_duty_cycle(0)];
    pwm.extend_from_slice(pwm_after);
    let mut dir = vec![Pin::set(State::Low)];
    dir.extend_from_slice(dir_after);
    let mut en = vec![Pin::set(State::Low)];
    en.extend_from_slice(en_after);
    HBridge::new(PwmMock::new(&pwm), PinMock::new(&dir), PinMock::new(&en))
        .expect("mock lines do not fail")
}

/// Checks that the bridge's mocks saw every expected transaction, and nothing more.
pub fn done(bridge: &MockBridge) {
    bridge.pwm().clone().done();
    bridge.dir().clone().done();
    bridge.en().clone().done();
}
