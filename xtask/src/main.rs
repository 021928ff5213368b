//! `cargo xtask`: set-up, build, run and test automation for vsa.
//!
//! - `cargo xtask run [--board qemu-m4|qemu-m3] [--seconds N]`: the firmware on an
//!   emulated board, its defmt log decoded.
//! - `cargo xtask test`: formatting, clippy (host and every board), host tests, release
//!   builds of every board, and each emulated board's self-test.
//! - `cargo xtask flash`: the Nucleo-F446RE firmware through probe-rs.

mod board;
mod checks;
mod cmd;
mod defmt_log;
mod firmware;
mod flash;
mod qemu;
mod setup;
mod test;

use anyhow::Result;
use clap::{Parser, Subcommand};
use std::path::PathBuf;
use std::process::ExitCode;

use board::Board;

#[derive(Parser)]
#[command(
    name = "cargo xtask",
    about = "Build, run and test the vsa firmware and tools"
)]
struct Cli {
    #[command(subcommand)]
    command: Task,
}

#[derive(Subcommand)]
enum Task {
    /// Build the firmware and run it on an emulated board, printing its decoded defmt log.
    Run {
        /// Emulated board.
        #[arg(long, value_enum, default_value = "qemu-m4")]
        board: Board,
        /// Seconds of emulated time before the firmware exits by itself.
        #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u32).range(1..=3600))]
        seconds: u32,
        /// How the firmware's idle loop waits on the emulated board (`wfi` shows QEMU's
        /// icount sleep=off defect: 500 ticks per emulated second).
        #[arg(long, value_parser = ["spin", "wfi"], default_value = "spin")]
        idle: String,
    },
    /// Run every check: fmt, clippy, host tests, firmware builds, emulated self-tests.
    Test,
    /// Build the Nucleo-F446RE firmware and run it on the board with probe-rs.
    Flash,
    /// Cargo runner for thumb targets: run an ELF on an emulated board.
    #[command(hide = true)]
    QemuRunner {
        #[arg(long, value_enum)]
        board: Board,
        elf: PathBuf,
        /// Arguments passed to the firmware.
        args: Vec<String>,
    },
}

fn main() -> ExitCode {
    match dispatch(Cli::parse().command) {
        Ok(code) => code,
        Err(e) => {
            eprintln!("xtask: error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

fn dispatch(task: Task) -> Result<ExitCode> {
    match task {
        Task::Run {
            board,
            seconds,
            idle,
        } => {
            anyhow::ensure!(
                board.qemu_machine().is_some(),
                "{} is a real board: use `cargo xtask flash`",
                board.feature()
            );
            setup::ensure_targets()?;
            setup::ensure_qemu()?;
            eprintln!("xtask: building the {} firmware (release)", board.feature());
            let elf = firmware::build(board)?;
            let args = vec![
                "--seconds".to_owned(),
                seconds.to_string(),
                "--idle".to_owned(),
                idle,
            ];
            emulate(board, &elf, &args, test::wall_limit(seconds))
        }
        Task::Test => Ok(if test::run()? {
            ExitCode::SUCCESS
        } else {
            ExitCode::FAILURE
        }),
        Task::Flash => flash::run(),
        Task::QemuRunner { board, elf, args } => {
            setup::ensure_qemu()?;
            emulate(board, &elf, &args, test::wall_limit(3600))
        }
    }
}

/// Runs `elf` on QEMU, prints the decoded log, and exits with the firmware's status.
fn emulate(
    board: Board,
    elf: &std::path::Path,
    args: &[String],
    limit: std::time::Duration,
) -> Result<ExitCode> {
    println!(
        "{} on QEMU {} (-icount shift={}), firmware arguments: {}",
        board.feature(),
        board.qemu_machine().unwrap_or("?"),
        qemu::ICOUNT_SHIFT,
        args.join(" ")
    );
    let outcome = qemu::run(board, elf, args, limit, |line| println!("{line}"))?;
    println!("firmware exit status: {}", outcome.exit_code);
    Ok(ExitCode::from(u8::try_from(outcome.exit_code).unwrap_or(1)))
}
