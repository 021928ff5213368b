//! `cargo xtask`: set-up, build, run and test automation for vsa.
//!
//! - `cargo xtask run [--board qemu-m4|qemu-m3] [--scenario NAME] [--flash FILE]`: the firmware on an
//!   emulated board running a scenario (default: the step sweep), its defmt log decoded,
//!   and the host simulation's hash of the same scenario for comparison.
//! - `cargo xtask test`: formatting, clippy (host and every board), host tests, release
//!   builds of every board, and each emulated board's self-test.
//! - `cargo xtask flash`: the Nucleo-F446RE firmware through probe-rs.
//! - `cargo xtask bench`: instruction counts (fixed point vs f32), footprint and stack.

mod bench;
mod board;
mod calibrate;
mod checks;
mod ci_script;
mod cmd;
mod defmt_log;
mod dynamixel;
mod e2e;
mod fail_safe;
mod firmware;
mod flash;
mod flex_bound;
mod persistence;
mod power_up;
mod qemu;
mod results;
mod scenarios;
mod sensors;
mod setup;
mod test;
mod venv;

use anyhow::Result;
use clap::{Parser, Subcommand};
use std::path::PathBuf;
use std::process::ExitCode;

use board::Board;
use plant::scenario::ScenarioId;

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
        /// Scenario the emulated board runs: `step-sweep` (the paper's experiment) or one
        /// of the fault injections (`cargo xtask run --scenario list` lists them).
        #[arg(long, default_value = "step-sweep")]
        scenario: String,
        /// Stop after this many seconds of emulated time even if the scenario has not ended.
        #[arg(long, value_parser = clap::value_parser!(u32).range(1..=3600))]
        seconds: Option<u32>,
        /// How the firmware's idle loop waits on the emulated board (`wfi` shows QEMU's
        /// icount sleep=off defect: 500 ticks per emulated second).
        #[arg(long, value_parser = ["spin", "wfi"], default_value = "spin")]
        idle: String,
        /// Host file holding the emulated board's flash (its settings store: the boot log
        /// shows what is stored; latched faults go to its fault log); created if absent.
        /// Two runs with one file are a power cycle.
        #[arg(long, value_name = "FILE")]
        flash: Option<std::path::PathBuf>,
        /// Makes the simulated actuator off-nominal (repeatable; the names of `vsa simulate
        /// --plant`), e.g. power-up-angle=0.8: the host simulation gets the same.
        #[arg(long, value_name = "NAME=VALUE", allow_hyphen_values = true)]
        plant: Vec<String>,
    },
    /// Run every check: fmt, clippy, host tests, firmware builds, emulated self-tests.
    Test,
    /// Only the host-link end-to-end test (`cargo xtask test` runs it too): an emulated
    /// board serving the protocol, driven through the client library.
    E2e {
        /// Emulated board.
        #[arg(long, value_enum, default_value = "qemu-m4")]
        board: Board,
    },
    /// Only the Dynamixel check (`cargo xtask test` runs it too): three emulated boards on
    /// the bus of `vsa serve-qemu --bus`, checked with ROBOTIS' dynamixel-sdk.
    Dynamixel {
        /// Emulated board.
        #[arg(long, value_enum, default_value = "qemu-m4")]
        board: Board,
    },
    /// Build the Nucleo-F446RE firmware and run it on the board with probe-rs.
    Flash {
        /// The board's optional features, comma-separated: `supply-sense` (the bridge
        /// supply's divider wired to PA4), `dynamixel-ttl` (a Dynamixel TTL bus on PA2).
        #[arg(long, value_delimiter = ',', value_parser = ["supply-sense", "dynamixel-ttl"])]
        features: Vec<String>,
    },
    /// Decode a raw defmt log (e.g. QEMU's stdout saved by `vsa --qemu --qemu-log FILE`)
    /// with the ELF that wrote it.
    DecodeLog {
        /// The firmware ELF that produced the log.
        elf: PathBuf,
        /// The raw defmt bytes.
        log: PathBuf,
    },
    /// The settings store on an emulated board: save and power cycle, power cuts in every
    /// word write of a save and of a factory reset, 1 000 saves (`VSA_PERSISTENCE_CUTS=N`
    /// sweeps every N-th cut, `VSA_PERSISTENCE_SAVES=N` makes N saves).
    Persistence {
        /// Emulated board.
        #[arg(long, value_enum, default_value = "qemu-m4")]
        board: Board,
    },
    /// `vsa --qemu calibrate` on seeded off-nominal builds, a power cycle and a broken
    /// build (`VSA_CALIBRATION_BUILDS=N` calibrates N builds).
    Calibration {
        /// Emulated board.
        #[arg(long, value_enum, default_value = "qemu-m4")]
        board: Board,
    },
    /// Instruction counts per call (fixed point vs f32), footprint and stack of each board.
    Bench {
        /// Only the benchmarks on qemu-m3, mean and max per row (about 30 s; no footprint,
        /// stack or report): for trying a change to the control step.
        #[arg(long)]
        quick: bool,
    },
    /// The shortest raw steps the elastic actuator's linear part allows (a linear program
    /// per step, numpy and scipy in target/venv) for the loaded raw steps of the grid's
    /// dumps (`VSA_GRID_DUMP=/tmp/g.nom cargo test --release -p host-tests --test grid --
    /// --exact nominal_actuator_grid`).
    FlexBound {
        /// The grid's dump files, e.g. /tmp/g.nom.1.tsv.
        #[arg(required_unless_present = "check")]
        dumps: Vec<PathBuf>,
        /// Take every N-th loaded raw step.
        #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..))]
        every: u32,
        /// Factors of the configured link inertia one voltage sequence must serve at once,
        /// e.g. 0.5,1,2,3 (an open-loop plan for a link known only within that range).
        #[arg(long, default_value = "1")]
        links: String,
        /// Only check the program against the rigid bound (`cargo xtask test` does).
        #[arg(long)]
        check: bool,
    },
    /// Cargo runner for thumb targets: run an ELF on an emulated board.
    #[command(hide = true)]
    QemuRunner {
        #[arg(long, value_enum)]
        board: Board,
        elf: PathBuf,
        /// Arguments passed to the firmware.
        #[arg(trailing_var_arg = true, allow_hyphen_values = true)]
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

/// One emulated-board check on its own (`cargo xtask e2e | persistence | dynamixel`): set-up,
/// the firmware build, the check, its summary line.
fn board_check<T: std::fmt::Display>(
    board: Board,
    check: fn(Board, &std::path::Path) -> Result<T>,
) -> Result<ExitCode> {
    setup::ensure_targets()?;
    setup::ensure_qemu()?;
    let elf = firmware::build(board)?;
    let r = check(board, &elf)?;
    println!("{}: {r}", board.feature());
    Ok(ExitCode::SUCCESS)
}

fn dispatch(task: Task) -> Result<ExitCode> {
    match task {
        Task::Run {
            board,
            scenario,
            seconds,
            idle,
            flash,
            plant,
        } => {
            anyhow::ensure!(
                board.qemu_machine().is_some(),
                "{} is a real board: use `cargo xtask flash`",
                board.feature()
            );
            if scenario == "list" {
                for id in ScenarioId::ALL {
                    println!("{}", id.name());
                }
                return Ok(ExitCode::SUCCESS);
            }
            let Some(id) = ScenarioId::parse(&scenario) else {
                let names: Vec<_> = ScenarioId::ALL.iter().map(|s| s.name()).collect();
                anyhow::bail!(
                    "unknown scenario `{scenario}`; the scenarios are: {}",
                    names.join(", ")
                );
            };
            setup::ensure_targets()?;
            setup::ensure_qemu()?;
            eprintln!("xtask: building the {} firmware (release)", board.feature());
            let elf = firmware::build(board)?;
            let mut args = scenarios::firmware_args(id);
            args.extend(["--idle".to_owned(), idle]);
            if let Some(s) = seconds {
                args.extend(["--seconds".to_owned(), s.to_string()]);
            }
            if let Some(f) = &flash {
                let f =
                    client::qemu::flash_file_arg(f).map_err(|e| anyhow::anyhow!("--flash {e}"))?;
                args.extend(["--flash".to_owned(), f]);
            }
            // The one parser of the overrides; the firmware parses the same text again.
            let overrides =
                plant::overrides::Overrides::parse_all(plant.iter().map(String::as_str))
                    .map_err(|e| anyhow::anyhow!("--plant: {e}"))?;
            for o in &plant {
                args.extend(["--plant".to_owned(), o.clone()]);
            }
            let (code, outcome) = emulate(board, &elf, &args, test::wall_limit(60))?;
            scenarios::print_host_comparison(id, &overrides, &outcome)?;
            Ok(code)
        }
        Task::Test => Ok(cmd::exit_code(test::run()?)),
        Task::Flash { features } => flash::run(&features),
        Task::E2e { board } => board_check(board, e2e::run),
        Task::Persistence { board } => board_check(board, persistence::run),
        Task::Calibration { board } => board_check(board, calibrate::check),
        Task::Dynamixel { board } => board_check(board, dynamixel::run),
        Task::DecodeLog { elf, log } => {
            let format = defmt_log::LogFormat::from_elf(&elf)?;
            let bytes = std::fs::read(&log)
                .map_err(|e| anyhow::anyhow!("reading {}: {e}", log.display()))?;
            let mut decoder = format.decoder();
            for line in decoder.feed(&bytes) {
                println!("{line}");
            }
            if decoder.malformed() > 0 {
                eprintln!("xtask: {} malformed defmt frames", decoder.malformed());
            }
            Ok(ExitCode::SUCCESS)
        }
        Task::Bench { quick: false } => bench::run().map(|()| ExitCode::SUCCESS),
        Task::Bench { quick: true } => bench::quick().map(|()| ExitCode::SUCCESS),
        Task::FlexBound {
            dumps,
            every,
            links,
            check: false,
        } => flex_bound::run(&dumps, every, &links),
        Task::FlexBound { check: true, .. } => flex_bound::check().map(|line| {
            println!("{line}");
            ExitCode::SUCCESS
        }),
        Task::QemuRunner { board, elf, args } => {
            setup::ensure_qemu()?;
            Ok(emulate(board, &elf, &args, test::wall_limit(3600))?.0)
        }
    }
}

/// Runs `elf` on QEMU, prints the decoded log, and exits with the firmware's status.
fn emulate(
    board: Board,
    elf: &std::path::Path,
    args: &[String],
    limit: std::time::Duration,
) -> Result<(ExitCode, qemu::RunOutcome)> {
    println!(
        "{} on QEMU {} (-icount shift={}), firmware arguments: {}",
        board.feature(),
        board.qemu_machine().unwrap_or("?"),
        qemu::ICOUNT_SHIFT,
        args.join(" ")
    );
    let outcome = qemu::run(board, elf, args, limit, |line| println!("{line}"))?;
    println!("firmware exit status: {}", outcome.exit_code);
    let code = ExitCode::from(u8::try_from(outcome.exit_code).unwrap_or(1));
    Ok((code, outcome))
}
