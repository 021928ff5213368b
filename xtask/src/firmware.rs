//! Release builds of the firmware, one ELF per board.

use anyhow::{Context, Result};
use std::path::PathBuf;

use crate::board::Board;
use crate::cmd::{cargo, run_status, target_dir};

/// Builds the board's release firmware and returns a copy of its ELF at
/// `target/firmware/<board>.elf`. The copy matters: the boards that share a target triple
/// would otherwise overwrite each other's `target/<triple>/release/vsa-firmware`.
pub fn build(board: Board) -> Result<PathBuf> {
    let mut cmd = cargo();
    cmd.args(["build", "--release", "--package", "vsa-firmware"])
        .args(board.cargo_args());
    run_status(&mut cmd).with_context(|| format!("building the {} firmware", board.feature()))?;
    let built = target_dir()
        .join(board.target())
        .join("release")
        .join("vsa-firmware");
    let dir = target_dir().join("firmware");
    std::fs::create_dir_all(&dir)?;
    let elf = dir.join(format!("{}.elf", board.feature()));
    std::fs::copy(&built, &elf)
        .with_context(|| format!("copying {} to {}", built.display(), elf.display()))?;
    Ok(elf)
}
