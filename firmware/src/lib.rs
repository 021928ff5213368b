//! vsa firmware: the library the programs in `src/bin/` are built from.
//!
//! - [`board`]: board support for the three boards, chosen by a cargo feature: `qemu-m4`
//!   (default), `qemu-m3` and `nucleo-f446re`: the [`board::Board`] and
//!   [`board::TickHooks`] traits, the USART2 host-link driver, the emulated boards'
//!   simulated actuator and semihosting exit.
//! - [`tick`]: one period of the 1 kHz control tick, timed.
//! - [`timing`]: SysTick, the once-a-second tick accounting, the log's clock.
//! - [`report`]: what the log task writes, and the verdict of an emulated run
//!   ([`self_check`]); [`run_config`]: the run's options.
//! - [`stack`]: stack painting and the high-water mark.
//! - [`bus`]: the Dynamixel bus on the host-link UART.
//! - [`fail_safe`]: the panic and HardFault handlers: the H-bridge off first, then the
//!   report.
//! - [`settings`]: the settings store at boot (the board's store: `board::open_settings`).
//!
//! The programs: `vsa-firmware` (the firmware, every board), and on the emulated boards
//! `vsa-control-only` (the control loop and host link without the simulated actuator, for
//! the footprint) and `vsa-bench` (instruction counts). `cargo xtask` builds and runs them.
#![no_std]
#![deny(missing_docs)]

#[cfg(not(any(feature = "qemu-m4", feature = "qemu-m3", feature = "nucleo-f446re")))]
compile_error!(
    "no board selected: build with exactly one of the features `qemu-m4` (default), \
     `qemu-m3` or `nucleo-f446re` (e.g. `--no-default-features --features qemu-m3`)"
);

#[cfg(any(
    all(feature = "qemu-m4", feature = "qemu-m3"),
    all(feature = "qemu-m4", feature = "nucleo-f446re"),
    all(feature = "qemu-m3", feature = "nucleo-f446re"),
))]
compile_error!(
    "two boards selected: enable exactly one of `qemu-m4`, `qemu-m3`, `nucleo-f446re` \
     (add `--no-default-features` when choosing a board other than `qemu-m4`)"
);

pub mod board;
pub mod bus;
pub mod fail_safe;
pub mod report;
pub mod run_config;
pub mod self_check;
pub mod settings;
pub mod stack;
pub mod tick;
pub mod timing;
