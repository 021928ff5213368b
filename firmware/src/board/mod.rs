//! Board support: everything that differs between the boards, behind one small surface.
//!
//! Each board module provides `pac` (the device crate RTIC binds to), `NAME`,
//! `SYSCLK_HZ`, `init`, `run_config`, `exit`, the actuator I/O `Io` (driver traits) and the
//! `World` around the control step, with `drain_world` for its log events. The free-running µs clock on TIM2 is
//! shared code: it is the tick accounting's independent time base.

#[cfg(any(feature = "qemu-m4", feature = "qemu-m3"))]
mod qemu;
#[cfg(any(feature = "qemu-m4", feature = "qemu-m3"))]
pub use qemu::*;
#[cfg(any(feature = "qemu-m4", feature = "qemu-m3"))]
mod semihosting_exit;
#[cfg(any(feature = "qemu-m4", feature = "qemu-m3"))]
mod sim;
#[cfg(any(feature = "qemu-m4", feature = "qemu-m3"))]
pub use semihosting_exit::exit;
#[cfg(any(feature = "qemu-m4", feature = "qemu-m3"))]
pub use sim::*;

#[cfg(feature = "nucleo-f446re")]
mod nucleo;
#[cfg(feature = "nucleo-f446re")]
pub use nucleo::*;

use crate::run::IdleMode;

/// Waits for the next interrupt: WFI, or a spin on the emulated boards (see `qemu` for why).
#[inline(always)]
pub fn wait_for_interrupt(mode: IdleMode) {
    match mode {
        IdleMode::Wfi => cortex_m::asm::wfi(),
        IdleMode::Spin => cortex_m::asm::nop(),
    }
}

/// What `init` hands over to the application.
pub struct Parts {
    /// Free-running µs clock, independent of SysTick.
    pub clock: IndependentClock,
    /// The actuator's sensors and H-bridge, behind the `drivers` traits.
    pub io: Io,
    /// What surrounds the control step: the simulated actuator and its scenario on the
    /// emulated boards, the watchdog on the real one.
    pub world: World,
    /// The servo (controller + supervisor), configured for the board.
    pub servo: model::servo::Servo,
    /// The command service, with the configuration the servo was built from.
    pub service: service::Service,
    /// The host link's receive half (USART2).
    pub serial_rx: SerialRx,
    /// The host link's transmit half.
    pub serial_tx: SerialTx,
}

/// TIM2 as a free-running 32-bit µs counter (wraps after 71 minutes; readers use
/// wrapping differences). Independent of SysTick, which paces the control loop.
pub struct IndependentClock {
    tim: pac::TIM2,
}

impl IndependentClock {
    /// Starts TIM2 counting µs, given the prescaler that divides its input clock to 1 MHz.
    fn start(tim: pac::TIM2, prescaler: u16) -> Self {
        tim.psc().write(|w| w.psc().set(prescaler));
        tim.arr().write(|w| w.arr().set(u32::MAX));
        // Update event: load the prescaler now rather than at the first overflow.
        tim.egr().write(|w| w.ug().set_bit());
        tim.cr1().modify(|_, w| w.cen().set_bit());
        Self { tim }
    }

    /// µs since the clock started, modulo 2³².
    pub fn now_us(&self) -> u32 {
        self.tim.cnt().read().bits()
    }
}

mod serial;
pub use serial::{Serial, SerialRx, SerialTx};
