//! How a run on an emulated board ends: the exit status through semihosting (defmt frames
//! leave through `defmt-semihosting`; the panic handlers are `crate::fail_safe`'s). Every
//! program of this crate on an emulated board links it.

use defmt_semihosting as _;

/// Ends the emulation with status 0 (`passed`) or 1.
pub fn exit(passed: bool) -> ! {
    semihosting::process::exit(if passed { 0 } else { 1 })
}
