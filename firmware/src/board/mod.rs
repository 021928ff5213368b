//! Board support: everything that differs between the boards, behind two traits.
//!
//! - [`Board`]: what a board provides: its name and core clock, how it reads the run's
//!   options, brings up its peripherals ([`Parts`]) and ends a run. [`Selected`] is the
//!   board the cargo features chose; [`pac`] its device crate (RTIC binds to it by path,
//!   which a trait cannot carry).
//! - [`TickHooks`]: what a board does around each control step: before it (the emulated
//!   boards advance the simulated actuator and present its readings; the real one feeds
//!   the watchdog) and after it (a scenario records its results), and the events it has for
//!   the log.
//!
//! Shared by every board: the USART2 host-link driver ([`serial`]), the free-running µs
//! clock on TIM2 ([`IndependentClock`], the tick accounting's independent time base) and
//! the idle wait.

#[cfg(feature = "qemu")]
mod flash_file;
#[cfg(feature = "nucleo-f446re")]
mod nucleo;
#[cfg(feature = "nucleo-f446re")]
mod nucleo_flash;
#[cfg(feature = "qemu")]
mod qemu;
#[cfg(feature = "qemu")]
mod semihosting_exit;
pub mod serial;
#[cfg(feature = "qemu")]
mod sim;

#[cfg(feature = "qemu")]
pub use flash_file::{
    open as open_settings, SettingsFlash, SettingsStore, POWER_CUT_EXIT, SETTINGS_FLASH,
};
#[cfg(feature = "nucleo-f446re")]
pub use nucleo::{force_bridge_off, halt_after_fault, pac, Nucleo as Selected, USART2_CLOCK_HZ};
#[cfg(feature = "nucleo-f446re")]
pub use nucleo_flash::{open as open_settings, SettingsFlash, SettingsStore, SETTINGS_FLASH};
#[cfg(feature = "qemu")]
pub use qemu::{halt_after_fault, pac, Qemu as Selected, USART_BRR};
pub use serial::{Serial, SerialRx, SerialTx};
#[cfg(feature = "qemu")]
pub use sim::force_bridge_off;
#[cfg(feature = "qemu")]
pub use sim::{at_rest, SimulatedIo, Simulation, POT_AT_REST, SERVED_CLUTCH_MM, SUPPLY_AT_REST};

use crate::run_config::{IdleMode, RunConfig};
use model::servo::{Servo, TickOutput};
use model::supervisor::Fault;

/// What a board provides to the firmware (see the module docs).
pub trait Board {
    /// Board name as logged at boot.
    const NAME: &'static str;
    /// Core clock, Hz: SysTick counts it.
    const SYSCLK_HZ: u32;
    /// The actuator's sensors and H-bridge behind the driver traits
    /// (a `drivers::tick_io::TickIo`).
    type Io;
    /// What the board does around each control step.
    type Hooks: TickHooks<Io = Self::Io>;

    /// The run's options: the emulated boards read them from the QEMU command line.
    fn run_config() -> RunConfig;

    /// Brings the board up for `run`.
    fn init(device: pac::Peripherals, run: &RunConfig) -> Parts<Self>;

    /// Ends the run with its verdict: the emulated boards exit QEMU with it, the real
    /// board logs it and halts.
    fn exit(passed: bool) -> !;
}

/// The H-bridge outputs as the fail-safe saw them (`force_bridge_off`, run by the panic
/// and HardFault handlers of `crate::fail_safe`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, defmt::Format)]
pub struct BridgeOutputs {
    /// The bridge's enable line is high (on the real board: EN high and TIM1's main
    /// output on).
    pub enabled: bool,
    /// The PWM duty on the bridge's input, ‰ (0 whenever the PWM output is off).
    pub duty_permille: u16,
}

/// What a board does around each control step, and the events it has for the log.
pub trait TickHooks {
    /// The board's actuator I/O.
    type Io;
    /// Something for the log (a scenario's progress on the emulated boards).
    type Event;

    /// Start of a tick, before the sensors are read.
    fn before_step(&mut self, io: &mut Self::Io, servo: &mut Servo) -> TickPlan;

    /// End of a tick, after the bridge was written: `late` is the missed-deadline fault
    /// if this tick latched one.
    fn after_step(&mut self, servo: &Servo, out: &TickOutput, late: Option<Fault>, io: &Self::Io);

    /// The oldest event not yet logged.
    fn pop_event(&mut self) -> Option<Self::Event>;

    /// Whether `event` is the run's last (the control loop's costs are logged after it).
    fn ends_run(event: &Self::Event) -> bool;
}

/// A board's hooks kept in a static and lent for the run (the emulated boards' simulation
/// is 14 KiB: moved by value through init it took several copies of init's stack).
impl<T: TickHooks> TickHooks for &'static mut T {
    type Io = T::Io;
    type Event = T::Event;

    fn before_step(&mut self, io: &mut Self::Io, servo: &mut Servo) -> TickPlan {
        (**self).before_step(io, servo)
    }

    fn after_step(&mut self, servo: &Servo, out: &TickOutput, late: Option<Fault>, io: &Self::Io) {
        (**self).after_step(servo, out, late, io);
    }

    fn pop_event(&mut self) -> Option<Self::Event> {
        (**self).pop_event()
    }

    fn ends_run(event: &Self::Event) -> bool {
        T::ends_run(event)
    }
}

/// What the start of a tick asks of the control loop.
pub struct TickPlan {
    /// Busy-wait past the deadline in this tick (fault injection; emulated boards only).
    pub overrun: bool,
}

/// The selected board's actuator I/O.
pub type Io = <Selected as Board>::Io;
/// The selected board's tick hooks.
pub type Hooks = <Selected as Board>::Hooks;
/// The selected board's log events.
pub type Event = <Hooks as TickHooks>::Event;
/// The selected board's name as logged at boot.
pub const NAME: &str = <Selected as Board>::NAME;
/// The selected board's core clock, Hz.
pub const SYSCLK_HZ: u32 = <Selected as Board>::SYSCLK_HZ;

/// Ends the run on the selected board (see [`Board::exit`]).
pub fn exit(passed: bool) -> ! {
    Selected::exit(passed)
}

/// Waits for the next interrupt: WFI, or a spin on the emulated boards (see `qemu` for why).
#[inline(always)]
pub fn wait_for_interrupt(mode: IdleMode) {
    match mode {
        IdleMode::Wfi => cortex_m::asm::wfi(),
        IdleMode::Spin => cortex_m::asm::nop(),
    }
}

/// What [`Board::init`] hands over to the application.
pub struct Parts<B: Board + ?Sized> {
    /// Free-running µs clock, independent of SysTick.
    pub clock: IndependentClock,
    /// The actuator's sensors and H-bridge, behind the `drivers` traits.
    pub io: B::Io,
    /// What the board does around each control step.
    pub hooks: B::Hooks,
    /// The servo (controller + supervisor), configured for the board.
    pub servo: Servo,
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
