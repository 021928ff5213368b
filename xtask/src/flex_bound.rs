//! `cargo xtask flex-bound`: the shortest raw steps the elastic actuator's linear part
//! allows, against the rigid bound, for the grid's dumped cases
//! (`host-tests/analysis/flex_bound.py`; docs/design.md §10, "The elastic actuator's bound").

use std::path::PathBuf;
use std::process::{Command, ExitCode};

use anyhow::{ensure, Context, Result};

use crate::cmd::{exit_code, workspace_root};
use crate::venv;

/// The analysis with numpy and scipy from target/venv.
fn analysis() -> Result<Command> {
    let python = venv::python_with("numpy, scipy", &["numpy", "scipy"])?;
    let mut cmd = Command::new(python);
    cmd.arg(workspace_root().join("host-tests/analysis/flex_bound.py"));
    Ok(cmd)
}

/// Runs the analysis on `dumps`, every `every`-th loaded raw step, one sequence for the
/// links `links` (factors, comma-separated) times the configured one.
pub fn run(dumps: &[PathBuf], every: u32, links: &str) -> Result<ExitCode> {
    let status = analysis()?
        .args(["--every", &every.to_string(), "--links", links])
        .args(dumps)
        .status()
        .context("running flex_bound.py")?;
    Ok(exit_code(status.success()))
}

/// The program against the rigid bound (`flex_bound.py --check`); its line on success.
pub fn check() -> Result<String> {
    let out = analysis()?
        .arg("--check")
        .output()
        .context("running flex_bound.py --check")?;
    let stdout = String::from_utf8_lossy(&out.stdout).trim().to_owned();
    ensure!(
        out.status.success(),
        "flex_bound.py --check: {stdout} {}",
        String::from_utf8_lossy(&out.stderr).trim()
    );
    Ok(stdout)
}
