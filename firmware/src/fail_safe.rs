//! The panic and HardFault handlers of every board: first the H-bridge off, by direct
//! register writes that cannot fail (`board::force_bridge_off`: on the real board TIM1's
//! main output off and EN low; on the emulated boards the simulated bridge's outputs),
//! then the report, then the board's end (`board::halt_after_fault`: the emulated boards
//! exit QEMU with failure; the real board traps into probe-rs, or waits for the watchdog).
//!
//! Without this the motor would stay driven at its last duty until the watchdog resets the
//! MCU, 54–151 ms later.

use crate::board::{self, BridgeOutputs};
use core::sync::atomic::{AtomicBool, Ordering};
use cortex_m_rt::{exception, ExceptionFrame};

/// A failure injected on purpose in a control tick (`--inject-panic-at-tick N`,
/// `--inject-hardfault-at-tick N`), to prove these handlers.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Injection {
    /// The control tick (1-based).
    pub tick: u32,
    /// A HardFault (an undefined instruction) rather than a panic.
    pub hardfault: bool,
}

/// Panics, or faults, if `injection` is for `tick`.
#[inline]
pub fn inject(injection: Option<Injection>, tick: u32) {
    match injection {
        Some(i) if i.tick == tick && i.hardfault => cortex_m::asm::udf(),
        Some(i) if i.tick == tick => panic!("injected panic at tick {}", tick),
        _ => {}
    }
}

/// Set by the first handler to report: a second entry (a panic inside the logger, the
/// HardFault that ends a panic on the real board) skips the report, since logging again
/// could fault again.
static REPORTED: AtomicBool = AtomicBool::new(false);

/// Whether this is the first handler to report.
fn first_report() -> bool {
    !REPORTED.swap(true, Ordering::Relaxed)
}

/// Logs what the fail-safe did to the bridge.
fn report_bridge(before: BridgeOutputs, after: BridgeOutputs) {
    defmt::error!(
        "bridge forced off: enable {=bool}, duty {=u16} permille (before: enable {=bool}, duty {=u16} permille)",
        after.enabled,
        after.duty_permille,
        before.enabled,
        before.duty_permille
    );
}

/// A Rust panic: interrupts masked (the control task cannot start another defmt frame or
/// drive the bridge again), the bridge off, then the message.
#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    cortex_m::interrupt::disable();
    let (before, after) = board::force_bridge_off();
    if first_report() {
        report_bridge(before, after);
        let (file, line) = info.location().map_or(("?", 0), |l| (l.file(), l.line()));
        defmt::error!(
            "panic: {} ({=str}:{=u32})",
            defmt::Display2Format(&info.message()),
            file,
            line
        );
    }
    board::halt_after_fault()
}

/// defmt's own `panic!`/`unwrap!`: their message is already logged (defmt prints it before
/// calling this, a few µs with the non-blocking logger); the bridge goes off now.
#[defmt::panic_handler]
fn defmt_panic() -> ! {
    cortex_m::interrupt::disable();
    let (before, after) = board::force_bridge_off();
    if first_report() {
        report_bridge(before, after);
    }
    board::halt_after_fault()
}

/// A HardFault (a bus fault, an undefined instruction, a fault escalated from another
/// handler): the bridge off, then where it happened.
///
/// # Safety
/// Called by the hardware only (cortex-m-rt's vector table).
#[exception]
unsafe fn HardFault(frame: &ExceptionFrame) -> ! {
    cortex_m::interrupt::disable();
    let (before, after) = board::force_bridge_off();
    if first_report() {
        report_bridge(before, after);
        defmt::error!("HardFault at pc {=u32:#010x}", frame.pc());
    }
    board::halt_after_fault()
}
