//! The bring-up mode end to end: `vsa --qemu sensors --nudge …` against the firmware on an
//! emulated board. The raw readings must stream, the nudge must run for its duration and
//! then stop, and the link encoder and the gear pot must move the nudge's way.

use std::path::Path;
use std::process::Command;

use anyhow::{bail, ensure, Context, Result};

use crate::board::Board;
use crate::cmd::{cargo, describe, run_status, target_dir};

/// The nudge asked for, ‰, and how long, ms.
const NUDGE_PERMILLE: i16 = 100;
const NUDGE_MS: u32 = 300;

/// Column header of `vsa sensors`.
const HEADER: &str = "tick\tlink_encoder\tgear_pot\tcurrent_adc\tnudge_permille\tsupply_adc\n";

/// The supply sense's reading of the simulated actuator's supply (12 V: 2 400 counts).
fn simulated_supply_counts() -> u16 {
    let volts = plant::PlantConfig::default().motor.supply_voltage_v;
    (volts * 1000.0 / f32::from(model::sensors::SUPPLY_MV_PER_COUNT)).round() as u16
}

/// One row of `vsa sensors`: tick, link encoder, gear pot, current ADC, nudge duty, supply
/// sense.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Row {
    tick: u32,
    link: u16,
    pot: u16,
    current: u16,
    nudge: i16,
    supply: u16,
}

fn parse_row(line: &str) -> Option<Row> {
    let f: Vec<&str> = line.split('\t').collect();
    let [tick, link, pot, current, nudge, supply] = f.as_slice() else {
        return None;
    };
    Some(Row {
        tick: tick.parse().ok()?,
        link: link.parse().ok()?,
        pot: pot.parse().ok()?,
        current: current.parse().ok()?,
        nudge: nudge.parse().ok()?,
        supply: supply.parse().ok()?,
    })
}

/// Signed change of a 4096-count encoder reading through the wrap.
fn encoder_delta(now: u16, before: u16) -> i32 {
    (i32::from(now) - i32::from(before) + 2048).rem_euclid(4096) - 2048
}

/// Checks the output of `vsa sensors --nudge` (see the module docs); the summary for the
/// log. Every line between the header and the summary must be a full reading: a row
/// skipped here would make the next one look like the first.
fn check_stream(stdout: &str) -> Result<String> {
    let mut lines = stdout.lines();
    ensure!(
        lines.next() == Some(HEADER.trim_end()),
        "no header in {stdout:?}"
    );
    let mut lines: Vec<&str> = lines.collect();
    let summary = lines.pop().unwrap_or_default();
    ensure!(
        summary.contains(" readings; "),
        "no summary line at the end of {stdout:?}"
    );
    let rows = lines
        .iter()
        .enumerate()
        .map(|(i, line)| {
            parse_row(line)
                .with_context(|| format!("reading {} is not a full row: {line:?}", i + 1))
        })
        .collect::<Result<Vec<Row>>>()?;
    ensure!(rows.len() >= 10, "only {} readings: {stdout:?}", rows.len());
    ensure!(
        rows.windows(2).all(|w| w[0].tick < w[1].tick),
        "ticks do not increase: {rows:?}"
    );
    let supply = simulated_supply_counts();
    ensure!(
        rows.iter().all(|r| r.supply == supply),
        "the supply sense does not read the simulated supply ({supply} counts): {rows:?}"
    );
    let (first, last) = (rows[0], rows[rows.len() - 1]);
    ensure!(first.nudge == 0, "nudging before it was asked: {first:?}");
    let nudged: Vec<&Row> = rows.iter().filter(|r| r.nudge != 0).collect();
    let Some(on) = nudged.first() else {
        bail!("no reading shows the nudge: {rows:?}");
    };
    ensure!(
        nudged.iter().all(|r| r.nudge == NUDGE_PERMILLE),
        "nudge duties other than {NUDGE_PERMILLE}: {nudged:?}"
    );
    let span = nudged[nudged.len() - 1].tick - on.tick;
    ensure!(
        span < NUDGE_MS && last.nudge == 0 && last.tick > on.tick + NUDGE_MS,
        "the nudge did not stop after {NUDGE_MS} ms: {rows:?}"
    );
    let link = encoder_delta(last.link, first.link);
    let pot = i32::from(last.pot) - i32::from(first.pot);
    ensure!(
        link > 20 && pot > 5,
        "the link ({link} counts) and the pot ({pot} counts) did not follow a positive nudge"
    );
    Ok(format!(
        "{} readings, nudge {NUDGE_PERMILLE} permille for {NUDGE_MS} ms: link +{link} counts, pot +{pot} counts, current ADC {}..{}; {summary}",
        rows.len(),
        rows.iter().map(|r| r.current).min().unwrap_or(0),
        rows.iter().map(|r| r.current).max().unwrap_or(0),
    ))
}

/// Builds `vsa` and runs `vsa --qemu sensors --nudge …` on `board` with `elf`.
pub fn check(board: Board, elf: &Path) -> Result<String> {
    run_status(cargo().args(["build", "--quiet", "-p", "vsa-cli", "--bin", "vsa"]))?;
    let vsa = target_dir().join("debug").join("vsa");
    let mut cmd = Command::new(&vsa);
    cmd.args(["--qemu", "--board", board.feature(), "--elf"])
        .arg(elf)
        .args(["sensors", "--seconds", "1", "--rate", "20"])
        .args(["--nudge", &format!("{NUDGE_PERMILLE}‰")])
        .args(["--nudge-for", &format!("{NUDGE_MS}ms")]);
    let out = cmd
        .output()
        .with_context(|| format!("starting {}", describe(&cmd)))?;
    let stdout = String::from_utf8_lossy(&out.stdout);
    ensure!(
        out.status.success(),
        "{} exited with {}: {}",
        describe(&cmd),
        out.status,
        String::from_utf8_lossy(&out.stderr).trim()
    );
    check_stream(&stdout)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn stream(rows: &[(u32, u16, u16, i16)]) -> String {
        let mut s = HEADER.to_string();
        for (tick, link, pot, nudge) in rows {
            s.push_str(&format!("{tick}\t{link}\t{pot}\t2048\t{nudge}\t2400\n"));
        }
        s.push_str("n readings; …\n");
        s
    }

    fn good() -> Vec<(u32, u16, u16, i16)> {
        let mut rows = vec![(30, 0, 512, 0)];
        rows.extend((0..5).map(|i| (180 + 50 * i, 20 * i as u16, 517 + i as u16, 100)));
        rows.extend((0..8).map(|i| (430 + 50 * i, 110 + i as u16, 550, 0)));
        rows
    }

    #[test]
    fn the_stream_must_show_a_bounded_nudge_moving_the_sensors() {
        assert!(check_stream(&stream(&good())).is_ok());
        // Through the encoder's wrap: 4090 → 100 is +106.
        let mut wrapped = good();
        wrapped[0].1 = 4090;
        assert!(check_stream(&stream(&wrapped)).is_ok());
        let mut endless = good();
        for r in endless.iter_mut().skip(1) {
            r.3 = 100;
        }
        assert!(check_stream(&stream(&endless)).is_err());
        let mut still = good();
        for r in still.iter_mut() {
            r.1 = 0;
        }
        assert!(check_stream(&stream(&still)).is_err());
        let mut backwards = good();
        let last = backwards.len() - 1;
        backwards[last].2 = 500;
        assert!(check_stream(&stream(&backwards)).is_err());
        assert!(check_stream(&stream(&good()[..5])).is_err());
        assert!(check_stream("").is_err());
    }

    /// A line that is not a full reading is an error of its own, never skipped: a board
    /// asked before its first control tick once answered zeros with no gear pot
    /// (`0 0 - 0 0`), the check skipped that row, and the next one, already nudged, passed
    /// for the first reading.
    #[test]
    fn every_line_must_be_a_full_reading() {
        let mut nudged_first = good();
        nudged_first.remove(0);
        let pre_tick =
            stream(&nudged_first).replacen(HEADER, &format!("{HEADER}0\t0\t-\t0\t0\n"), 1);
        let e = format!("{:#}", check_stream(&pre_tick).unwrap_err());
        assert!(e.contains("reading 1 is not a full row"), "{e}");
        let mut cut = stream(&good());
        cut.truncate(cut.rfind("n readings").unwrap());
        let e = format!("{:#}", check_stream(&cut).unwrap_err());
        assert!(e.contains("no summary line"), "{e}");
    }
}
