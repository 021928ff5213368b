//! The control period run by the 1 kHz tick.
//!
//! This is the one place the tick calls into; the controller of `model` (sensors →
//! estimate → supervisor → controller → PWM) plugs in here.

/// State of the per-tick control work.
pub struct ControlLoop {
    periods: u32,
}

impl ControlLoop {
    /// A control loop that has not run yet.
    pub const fn new() -> Self {
        Self { periods: 0 }
    }

    /// Runs one 1 ms control period. It must return well within the period: the caller
    /// counts an overrun when the next SysTick is already pending on return.
    #[inline(never)]
    pub fn tick(&mut self) {
        self.periods = self.periods.wrapping_add(1);
    }
}
