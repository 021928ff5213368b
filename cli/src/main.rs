//! `vsa`: the host tool of the vsa actuator.
//!
//! Every number it prints or plots is computed by the `model` crate (fixed point, the same
//! code as the firmware); this crate parses arguments, converts units for display and
//! renders tables, JSON, CSV and figures.
//!
//! Exit codes: 0 success; 2 bad input (one line on stderr naming the argument, nothing on
//! stdout; clap's own usage errors exit 2 too); 1 a failure while working (e.g. a file that
//! cannot be written).
#![forbid(unsafe_code)]

use std::io::Write;
use std::process::ExitCode;

use clap::{Parser, Subcommand};

mod design;
mod error;
mod figures;
mod format;
mod simulate;
mod units;

use error::CliResult;

/// Design calculator, figures, simulation and board access for the vsa actuator.
#[derive(Parser)]
#[command(name = "vsa", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

/// The subcommands. A new one is a variant here and an arm in [`run`] that returns the
/// text for stdout (or writes its own output) and a [`error::CliError`] on failure.
// Parsed once per run: the size difference between variants does not matter.
#[allow(clippy::large_enum_variant)]
#[derive(Subcommand)]
enum Command {
    /// Stiffness, deflection, stress, capacity and backlash of a beam design.
    Design(design::DesignArgs),
    /// Draw the paper's figures (SVG, PNG and the CSV behind each).
    Figures(figures::FiguresArgs),
    /// Run the position controller against the simulated actuator on the host.
    Simulate(simulate::SimulateArgs),
}

fn run(cli: Cli) -> CliResult<()> {
    match cli.command {
        Command::Design(args) => design::run(&args).map(|s| print(&s)),
        Command::Figures(args) => figures::run(&args),
        Command::Simulate(args) => {
            simulate::run(&args).map_err(|reason| error::CliError::usage("simulate", reason))
        }
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
            let _ = writeln!(std::io::stderr(), "error: {e}");
            ExitCode::from(u8::try_from(e.code).unwrap_or(1))
        }
    }
}
