//! The Python virtual environment `target/venv` for the third-party Python the checks
//! and analyses use (made with `python3 -m venv`; when the `venv` module is missing and we
//! are root with apt-get, `python3-venv` is installed the way `setup` installs QEMU:
//! never removing a package).

use std::path::PathBuf;
use std::process::{Command, Stdio};

use anyhow::{bail, Context, Result};

use crate::cmd::{is_root, run_status, target_dir};

/// The venv's python with `modules` importable: makes the venv and `pip install`s
/// `packages` (their PyPI names) when an import fails.
pub fn python_with(modules: &str, packages: &[&str]) -> Result<PathBuf> {
    let venv = target_dir().join("venv");
    let python = venv.join("bin").join("python");
    if !python.exists() {
        let made = Command::new("python3")
            .args(["-m", "venv"])
            .arg(&venv)
            .status()
            .context("running python3 (is Python 3 installed?)")?;
        if !made.success() {
            install_venv_package()?;
            run_status(Command::new("python3").args(["-m", "venv"]).arg(&venv))
                .context("python3 -m venv target/venv")?;
        }
    }
    let importable = Command::new(&python)
        .args(["-c", &format!("import {modules}")])
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    if !importable {
        let names = packages.join(" ");
        eprintln!("xtask: installing {names} into target/venv");
        run_status(
            Command::new(venv.join("bin").join("pip"))
                .args(["install", "--quiet"])
                .args(packages),
        )
        .with_context(|| format!("pip install {names}"))?;
    }
    Ok(python)
}

/// `python3-venv` with apt-get, as root, never removing a package (see `setup`).
fn install_venv_package() -> Result<()> {
    let install = "apt-get install -y --no-install-recommends --no-remove python3-venv";
    if !is_root() {
        bail!("python3 -m venv failed; install the venv module with:\n    sudo {install}");
    }
    eprintln!("xtask: python3's venv module is missing; {install}");
    run_status(Command::new("apt-get").arg("update")).context("apt-get update")?;
    run_status(Command::new("sh").args(["-c", install])).context(install)
}
