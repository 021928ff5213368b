//! Release builds of the `vsa-firmware` crate's programs, one ELF per board and program.

use anyhow::{Context, Result};
use std::path::PathBuf;

use crate::board::Board;
use crate::cmd::{cargo, run_status, target_dir};

/// The firmware program.
pub const FIRMWARE: &str = "vsa-firmware";

/// Builds the board's release firmware and returns a copy of its ELF at
/// `target/firmware/<board>.elf`.
pub fn build(board: Board) -> Result<PathBuf> {
    build_program(board, FIRMWARE, format!("{}.elf", board.feature()))
}

/// Builds program `bin` (`src/bin/<bin>.rs`) for `board` in release and returns a copy of
/// its ELF at `target/firmware/<file>`. The copy matters: the boards that share a target
/// triple would otherwise overwrite each other's `target/<triple>/release/<bin>`.
pub fn build_program(board: Board, bin: &str, file: String) -> Result<PathBuf> {
    let mut cmd = cargo();
    cmd.args([
        "build",
        "--release",
        "--package",
        "vsa-firmware",
        "--bin",
        bin,
    ])
    .args(board.cargo_args());
    run_status(&mut cmd).with_context(|| format!("building {bin} for {}", board.feature()))?;
    let built = target_dir().join(board.target()).join("release").join(bin);
    let dir = target_dir().join("firmware");
    std::fs::create_dir_all(&dir)?;
    let elf = dir.join(file);
    std::fs::copy(&built, &elf)
        .with_context(|| format!("copying {} to {}", built.display(), elf.display()))?;
    Ok(elf)
}
