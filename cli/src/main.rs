//! `vsa`: the host tool of the vsa actuator.
use clap::Parser;

/// Design calculator, figures, simulation and board access for the vsa actuator.
#[derive(Parser)]
#[command(name = "vsa", version, about)]
struct Cli {}

fn main() {
    let _cli = Cli::parse();
}
