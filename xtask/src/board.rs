//! The boards the firmware builds for, and how each one is built and emulated.

use clap::ValueEnum;

/// A firmware board (a cargo feature of `vsa-firmware`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Board {
    /// QEMU netduinoplus2: STM32F405, Cortex-M4F.
    #[value(name = "qemu-m4")]
    QemuM4,
    /// QEMU netduino2: STM32F205, Cortex-M3 without FPU.
    #[value(name = "qemu-m3")]
    QemuM3,
    /// ST Nucleo-F446RE, the real board (probe-rs).
    #[value(name = "nucleo-f446re")]
    NucleoF446re,
}

impl Board {
    /// Every board, in the order `cargo xtask test` builds them.
    pub const ALL: [Board; 3] = [Board::QemuM4, Board::QemuM3, Board::NucleoF446re];

    /// The cargo feature that selects the board.
    pub fn feature(self) -> &'static str {
        match self {
            Board::QemuM4 => "qemu-m4",
            Board::QemuM3 => "qemu-m3",
            Board::NucleoF446re => "nucleo-f446re",
        }
    }

    /// Rust target triple of the board's core.
    pub fn target(self) -> &'static str {
        match self {
            Board::QemuM4 | Board::NucleoF446re => "thumbv7em-none-eabihf",
            Board::QemuM3 => "thumbv7m-none-eabi",
        }
    }

    /// QEMU machine that emulates the board, if any.
    pub fn qemu_machine(self) -> Option<&'static str> {
        match self {
            Board::QemuM4 => Some("netduinoplus2"),
            Board::QemuM3 => Some("netduino2"),
            Board::NucleoF446re => None,
        }
    }

    /// Cargo arguments that select the board's feature and target.
    pub fn cargo_args(self) -> [&'static str; 5] {
        [
            "--target",
            self.target(),
            "--no-default-features",
            "--features",
            self.feature(),
        ]
    }
}

/// Thumb targets every board needs installed.
pub fn all_targets() -> Vec<&'static str> {
    let mut targets: Vec<_> = Board::ALL.iter().map(|b| b.target()).collect();
    targets.sort_unstable();
    targets.dedup();
    targets
}
