//! `vsa`: the host tool of the vsa actuator.
//!
//! Every number it prints or plots is computed by the `model` crate (fixed point, the same
//! code as the firmware); this crate parses arguments, converts units for display and
//! renders tables, JSON, CSV and figures. The board commands (`status`, `enable`, `move`,
//! `record`, `script`, …) talk to a board through the `client` crate: a real board on a
//! serial port (`--port`), a board or relay on TCP (`--tcp`), or an emulated board started
//! for the invocation (`--qemu`).
//!
//! Exit codes: 0 success; 2 bad input (one line on stderr naming the argument, nothing on
//! stdout; clap's own usage errors exit 2 too); 1 a failure while working (e.g. a file that
//! cannot be written, a board that refuses a command or does not answer).
#![forbid(unsafe_code)]

use std::io::Write;
use std::process::ExitCode;

use clap::{Parser, Subcommand};

mod advise;
mod board;
mod design;
mod error;
mod explore;
mod figures;
mod format;
mod output;
mod plot;
mod simulate;
mod units;

use error::CliResult;

/// Design calculator, figures, simulation and board access for the vsa actuator.
#[derive(Parser)]
#[command(name = "vsa", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
    #[command(flatten)]
    conn: board::ConnectArgs,
}

/// The subcommands. A new one is a variant here and an arm in [`run`] that returns the
/// text for stdout (or writes its own output) and a [`error::CliError`] on failure.
// Parsed once per run: the size difference between variants does not matter.
#[allow(clippy::large_enum_variant)]
#[derive(Subcommand)]
enum Command {
    /// Stiffness, deflection, stress, capacity and backlash of a beam design.
    Design(design::DesignArgs),
    /// The clutch setting that saves energy for a periodic task (closed-loop simulation).
    Advise(advise::AdviseArgs),
    /// Search beam designs against capacity, deflection, mass and volume goals.
    Explore(explore::ExploreArgs),
    /// Draw the paper's figures (SVG, PNG and the CSV behind each).
    Figures(figures::FiguresArgs),
    /// Run the position controller against the simulated actuator on the host.
    Simulate(simulate::SimulateArgs),
    /// Plot a recorded run from its CSV (angles, current and torque against time).
    Plot(plot::PlotArgs),
    #[command(flatten)]
    Board(board::BoardCommand),
    /// Run several board commands in one session (the way to use one --qemu board).
    Script(board::ScriptArgs),
    /// Keep an emulated board running and relay a TCP port to it for `--tcp` clients.
    ServeQemu(board::serve::ServeArgs),
    /// Stream the raw sensor readings, optionally nudging the motor open-loop (bring-up).
    Sensors(board::sensors::SensorsArgs),
}

fn run(cli: Cli) -> CliResult<()> {
    let offline = |conn: &board::ConnectArgs| match conn.first_given() {
        Some(arg) => Err(error::CliError::usage(
            arg,
            "connection options only apply to board commands",
        )),
        None => Ok(()),
    };
    match cli.command {
        Command::Design(args) => {
            offline(&cli.conn).and_then(|()| design::run(&args).map(|s| print(&s)))
        }
        Command::Advise(args) => {
            offline(&cli.conn).and_then(|()| advise::run(&args).map(|s| print(&s)))
        }
        Command::Explore(args) => {
            offline(&cli.conn).and_then(|()| explore::run(&args).map(|s| print(&s)))
        }
        Command::Figures(args) => offline(&cli.conn).and_then(|()| figures::run(&args)),
        Command::Simulate(args) => offline(&cli.conn).and_then(|()| {
            simulate::run(&args).map_err(|reason| error::CliError::usage("simulate", reason))
        }),
        Command::Plot(args) => offline(&cli.conn).and_then(|()| plot::run(&args)),
        Command::Board(cmd) => board::run(&cmd, &cli.conn),
        Command::Script(args) => board::script(&args, &cli.conn),
        Command::ServeQemu(args) => board::serve::run(&args, &cli.conn),
        Command::Sensors(args) => board::sensors::run(&args, &cli.conn),
    }
}

/// Writes `s` to stdout; a closed pipe (`vsa design | head`) is not an error.
fn print(s: &str) {
    let mut out = std::io::stdout().lock();
    let _ = out.write_all(s.as_bytes()).and_then(|()| out.flush());
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            // Stopped by a signal: the handler kills the emulated board and exits with
            // 130; the lost connection that woke this thread is not the error to report.
            board::park_if_interrupted();
            let _ = writeln!(std::io::stderr(), "error: {e}");
            ExitCode::from(u8::try_from(e.code).unwrap_or(1))
        }
    }
}
