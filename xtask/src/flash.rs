//! `cargo xtask flash`: the real board through probe-rs and its defmt-rtt log.

use anyhow::{bail, Context, Result};
use std::process::{Command, ExitCode};

use crate::board::Board;
use crate::firmware;

/// probe-rs's name for the Nucleo-F446RE's MCU.
pub const CHIP: &str = "STM32F446RETx";

/// Builds the Nucleo firmware (with its optional `features`) and runs it with `probe-rs
/// run` (flash, reset, print the decoded defmt-rtt log until Ctrl-C).
pub fn run(features: &[String]) -> Result<ExitCode> {
    let elf = firmware::build_with(Board::NucleoF446re, features)?;
    if Command::new("probe-rs").arg("--version").output().is_err() {
        bail!(
            "probe-rs is not installed. Install it with\n    cargo install probe-rs-tools --locked\n\
             (on Linux also install its udev rules: https://probe.rs/docs/getting-started/probe-setup/),\n\
             then run `cargo xtask flash` again. The firmware is built at {}",
            elf.display()
        );
    }
    let probes = Command::new("probe-rs")
        .arg("list")
        .output()
        .context("running `probe-rs list`")?;
    let listing = String::from_utf8_lossy(&probes.stdout);
    if !probes.status.success() || listing.contains("No debug probes") || listing.trim().is_empty()
    {
        bail!(
            "no debug probe found. Connect the Nucleo-F446RE's ST-LINK USB port (CN1) to this \
             machine, check that `probe-rs list` shows it (and, on Linux, that the udev rules \
             allow access), then run `cargo xtask flash` again"
        );
    }
    let status = Command::new("probe-rs")
        .args(["run", "--chip", CHIP])
        .arg(&elf)
        .status()
        .context("running probe-rs")?;
    Ok(crate::cmd::exit_code(status.success()))
}
