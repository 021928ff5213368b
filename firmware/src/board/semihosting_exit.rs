//! How a run on an emulated board ends: the exit status through semihosting, and the panic
//! handlers (defmt frames leave through `defmt-semihosting`). Every program of this crate
//! on an emulated board links them.

use core::sync::atomic::{AtomicBool, Ordering};
use defmt_semihosting as _;

/// Ends the emulation with status 0 (`passed`) or 1.
pub fn exit(passed: bool) -> ! {
    semihosting::process::exit(if passed { 0 } else { 1 })
}

/// Logs the panic once, then makes QEMU exit with failure.
///
/// Interrupts are masked first so the control task cannot start another defmt frame.
/// If the panic came from inside the logger itself (a frame half written), logging
/// again would panic again: the second entry skips straight to the exit, and the
/// decoder on the host drops the half frame.
#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    static PANICKING: AtomicBool = AtomicBool::new(false);
    cortex_m::interrupt::disable();
    if !PANICKING.swap(true, Ordering::Relaxed) {
        let (file, line) = info.location().map_or(("?", 0), |l| (l.file(), l.line()));
        defmt::error!(
            "panic: {} ({=str}:{=u32})",
            defmt::Display2Format(&info.message()),
            file,
            line
        );
    }
    exit(false)
}

/// defmt's own `panic!`/`unwrap!` end up here.
#[defmt::panic_handler]
fn defmt_panic() -> ! {
    exit(false)
}
