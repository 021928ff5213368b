//! The fail-safe's checks: the firmware's panic and HardFault handlers must force the
//! H-bridge off before they report, so the log of an injected panic or HardFault must show
//! the bridge's outputs after the handler (enable low, duty 0) and before it (driving, or
//! the test would prove nothing), ahead of the handler's report.

use std::path::Path;

use anyhow::{bail, ensure, Context, Result};

use crate::board::Board;
use crate::qemu::{self, RunOutcome};
use crate::test::wall_limit;

/// What the panic handler reports after the fail-safe line.
pub const PANIC_REPORT: &str = "panic: ";

/// What the HardFault handler reports after the fail-safe line.
const HARDFAULT_REPORT: &str = "HardFault at pc ";

/// What the firmware's fail-safe logs (`firmware/src/fail_safe.rs`), before the values.
const MARKER: &str = "bridge forced off: ";

/// The bridge outputs as one half of the fail-safe's line gives them.
#[derive(Debug, PartialEq, Eq)]
struct Outputs {
    enabled: bool,
    duty_permille: u16,
}

/// Parses `enable <bool>, duty <n> permille` at the start of `s`.
fn outputs(s: &str) -> Option<Outputs> {
    let rest = s.strip_prefix("enable ")?;
    let (enabled, rest) = rest.split_once(", duty ")?;
    let (duty, _) = rest.split_once(" permille")?;
    Some(Outputs {
        enabled: enabled.parse().ok()?,
        duty_permille: duty.parse().ok()?,
    })
}

/// Runs `elf` on `board` with a HardFault injected at control tick `tick`: the run must
/// fail, with the fail-safe's line and then the HardFault's report last.
pub fn hardfault_test(board: Board, elf: &Path, tick: u32) -> Result<()> {
    let args = vec!["--inject-hardfault-at-tick".to_owned(), tick.to_string()];
    let outcome = qemu::run(board, elf, &args, wall_limit(3), |line| {
        println!("[{} HardFault test] {line}", board.feature())
    })?;
    ensure!(
        outcome.exit_code != 0,
        "the run passed despite the HardFault"
    );
    ensure!(
        outcome
            .lines
            .last()
            .is_some_and(|l| l.contains(HARDFAULT_REPORT)),
        "the last line is not the HardFault's report: {:?}",
        outcome.lines.last()
    );
    check_bridge_off(&outcome, HARDFAULT_REPORT)
}

/// Checks the fail-safe line of an injected failure's log, followed by `report`.
pub fn check_bridge_off(outcome: &RunOutcome, report: &str) -> Result<()> {
    let lines = &outcome.lines;
    let at = lines
        .iter()
        .position(|l| l.contains(MARKER))
        .context("no `bridge forced off` line: the panic handler did not force the bridge off")?;
    let line = &lines[at];
    let text = &line[line.find(MARKER).unwrap_or(0) + MARKER.len()..];
    let after = outputs(text).with_context(|| format!("unreadable fail-safe line `{line}`"))?;
    let before = text
        .split_once("(before: ")
        .and_then(|(_, b)| outputs(b))
        .with_context(|| format!("unreadable fail-safe line `{line}`"))?;
    if after.enabled || after.duty_permille != 0 {
        bail!("the bridge is still driven after the panic: {after:?} (`{line}`)");
    }
    if !before.enabled || before.duty_permille == 0 {
        bail!(
            "the bridge was not driving when the panic came ({before:?}): the test proves nothing"
        );
    }
    if !lines[at..].iter().skip(1).any(|l| l.contains(report)) {
        bail!("the handler's report (`{report}`) does not follow the fail-safe line");
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn outcome(lines: &[&str]) -> RunOutcome {
        RunOutcome {
            lines: lines.iter().map(|s| s.to_string()).collect(),
            exit_code: 1,
            malformed_frames: 0,
        }
    }

    const OFF: &str = " 1.499001 ERROR bridge forced off: enable false, duty 0 permille (before: enable true, duty 197 permille)  (f.rs:26)";
    const PANIC: &str = " 1.499006 ERROR panic: injected panic at tick 1500 (m.rs:1)  (f.rs:44)";

    #[test]
    fn the_bridge_must_go_from_driving_to_off_before_the_report() {
        let check = |lines: &[&str]| check_bridge_off(&outcome(lines), PANIC_REPORT);
        assert!(check(&[OFF, PANIC]).is_ok());
        assert!(check(&[PANIC]).is_err());
        assert!(check(&[PANIC, OFF]).is_err());
        assert!(check_bridge_off(&outcome(&[OFF, PANIC]), HARDFAULT_REPORT).is_err());
        let still_on = OFF.replace("enable false, duty 0", "enable true, duty 197");
        assert!(check(&[&still_on, PANIC]).is_err());
        let pwm_on = OFF.replace("enable false, duty 0", "enable false, duty 5");
        assert!(check(&[&pwm_on, PANIC]).is_err());
        let idle = OFF.replace(
            "before: enable true, duty 197",
            "before: enable false, duty 0",
        );
        assert!(check(&[&idle, PANIC]).is_err());
    }
}
