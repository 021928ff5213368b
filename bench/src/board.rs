//! The emulated boards the bench binaries run on (as `firmware/src/board/qemu.rs`): the
//! device crate RTIC binds to, the fixed core clock, the USART2 driver, and (the firmware's
//! own source files) the exit status and panic handlers.

#[cfg(not(any(feature = "qemu-m4", feature = "qemu-m3")))]
compile_error!("no board selected: build with `qemu-m4` (default) or `qemu-m3`");

#[cfg(all(feature = "qemu-m4", feature = "qemu-m3"))]
compile_error!("two boards selected: add `--no-default-features` when choosing `qemu-m3`");

/// The device crate (STM32F205).
#[cfg(feature = "qemu-m3")]
pub use stm32f2::stm32f215 as pac;
/// The device crate (STM32F405).
#[cfg(feature = "qemu-m4")]
pub use stm32f4::stm32f405 as pac;

/// Board name as logged.
#[cfg(feature = "qemu-m4")]
pub const NAME: &str = "qemu-m4";
/// Board name as logged.
#[cfg(feature = "qemu-m3")]
pub const NAME: &str = "qemu-m3";

/// Core clock of the emulated SoC, Hz (fixed by the QEMU machine; SysTick counts it).
#[cfg(feature = "qemu-m4")]
pub const SYSCLK_HZ: u32 = 168_000_000;
/// Core clock of the emulated SoC, Hz (fixed by the QEMU machine; SysTick counts it).
#[cfg(feature = "qemu-m3")]
pub const SYSCLK_HZ: u32 = 120_000_000;

// The firmware's USART2 driver, the very source file (the control-only image's footprint
// must count the firmware's host link, driver included).
#[path = "../../firmware/src/board/serial.rs"]
mod serial;
pub use serial::{Serial, SerialRx, SerialTx};

/// USART2's baud-rate divider (QEMU ignores it; 115 200 Bd at 42 MHz for the record).
pub const USART_BRR: u16 = 365;

// The emulated firmware's exit and panic handlers, the very source file.
#[path = "../../firmware/src/board/semihosting_exit.rs"]
mod semihosting_exit;
pub use semihosting_exit::exit;
