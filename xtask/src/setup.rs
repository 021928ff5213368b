//! Provides what a fresh machine lacks: thumb targets (rustup) and QEMU (apt-get).

use anyhow::{bail, Context, Result};
use std::process::Command;

use crate::board;
use crate::cmd::{run_status, workspace_root};

/// Installs the thumb targets that `rustup` reports missing for the workspace toolchain.
pub fn ensure_targets() -> Result<()> {
    let output = Command::new("rustup")
        .args(["target", "list", "--installed"])
        .current_dir(workspace_root())
        .output()
        .context("running `rustup target list --installed` (is rustup installed?)")?;
    let installed = String::from_utf8_lossy(&output.stdout);
    let missing: Vec<_> = board::all_targets()
        .into_iter()
        .filter(|t| !installed.lines().any(|l| l.trim() == *t))
        .collect();
    if missing.is_empty() {
        return Ok(());
    }
    eprintln!("xtask: installing Rust targets {}", missing.join(", "));
    let mut cmd = Command::new("rustup");
    cmd.args(["target", "add"]).args(&missing);
    run_status(&mut cmd).context("`rustup target add` failed")
}

/// Makes sure `qemu-system-arm` is on PATH, installing it with apt-get when running as
/// root on Debian/Ubuntu; otherwise stops with the exact command to run.
pub fn ensure_qemu() -> Result<()> {
    if qemu_version().is_some() {
        return Ok(());
    }
    let install = "apt-get update && apt-get install -y --no-install-recommends qemu-system-arm";
    let is_root = Command::new("id")
        .arg("-u")
        .output()
        .map(|o| String::from_utf8_lossy(&o.stdout).trim() == "0")
        .unwrap_or(false);
    let has_apt = Command::new("apt-get").arg("--version").output().is_ok();
    if !(is_root && has_apt) {
        bail!(
            "qemu-system-arm is not installed. Install it with:\n    sudo sh -c '{install}'\n\
             (or your distribution's QEMU ARM system emulator package), then run this again"
        );
    }
    eprintln!("xtask: qemu-system-arm is missing; installing it with apt-get");
    run_status(Command::new("apt-get").arg("update")).context("`apt-get update` failed")?;
    run_status(
        Command::new("apt-get")
            .args([
                "install",
                "-y",
                "--no-install-recommends",
                "qemu-system-arm",
            ])
            .env("DEBIAN_FRONTEND", "noninteractive"),
    )
    .context("`apt-get install qemu-system-arm` failed")?;
    match qemu_version() {
        Some(v) => {
            eprintln!("xtask: installed {v}");
            Ok(())
        }
        None => bail!("qemu-system-arm still not found after installing it"),
    }
}

/// First line of `qemu-system-arm --version`, if it runs.
pub fn qemu_version() -> Option<String> {
    let out = Command::new("qemu-system-arm")
        .arg("--version")
        .output()
        .ok()?;
    if !out.status.success() {
        return None;
    }
    String::from_utf8_lossy(&out.stdout)
        .lines()
        .next()
        .map(str::to_owned)
}
