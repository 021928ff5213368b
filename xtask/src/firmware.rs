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

/// [`build`] with the board's optional `features` as well (e.g. the Nucleo's
/// `supply-sense`), its ELF at `target/firmware/<board>[+feature…].elf`.
pub fn build_with(board: Board, features: &[String]) -> Result<PathBuf> {
    let file = std::iter::once(board.feature())
        .chain(features.iter().map(String::as_str))
        .collect::<Vec<_>>()
        .join("+");
    build_program_with(board, FIRMWARE, format!("{file}.elf"), features)
}

/// Builds program `bin` (`src/bin/<bin>.rs`) for `board` in release and returns a copy of
/// its ELF at `target/firmware/<file>`. The copy matters: the boards that share a target
/// triple would otherwise overwrite each other's `target/<triple>/release/<bin>`.
pub fn build_program(board: Board, bin: &str, file: String) -> Result<PathBuf> {
    build_program_with(board, bin, file, &[])
}

/// [`build_program`] with the board's optional `features` as well.
fn build_program_with(
    board: Board,
    bin: &str,
    file: String,
    features: &[String],
) -> Result<PathBuf> {
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
    if !features.is_empty() {
        cmd.args(["--features", &features.join(",")]);
    }
    run_status(&mut cmd).with_context(|| format!("building {bin} for {}", board.feature()))?;
    let built = target_dir().join(board.target()).join("release").join(bin);
    let dir = target_dir().join("firmware");
    std::fs::create_dir_all(&dir)?;
    let elf = dir.join(file);
    std::fs::copy(&built, &elf)
        .with_context(|| format!("copying {} to {}", built.display(), elf.display()))?;
    Ok(elf)
}
