//! The one checker of an emulated run: what `cargo xtask test` and `cargo xtask bench`
//! assert about every program on an emulated board, read from its `RESULT` records
//! (`results`).

use anyhow::Result;
use plant::scenario::{ScenarioId, Summary};

use crate::qemu::RunOutcome;
use crate::results;
use crate::scenarios::{self, BoardSummary};

/// What a run must show.
pub enum Expected<'a> {
    /// `vsa-firmware` running scenario `id`, compared with the host simulation `host`.
    Scenario {
        /// The scenario.
        id: ScenarioId,
        /// The host simulation of it.
        host: &'a Summary,
    },
    /// `vsa-firmware` told to panic at this control tick: it must fail with the panic
    /// message decoded intact as the last line, after its scenario had started.
    PanicAt(u32),
    /// A program that ends by itself with status 0, having written these records.
    Records(&'a [&'a str]),
}

/// Everything wrong with `outcome` against `expected` (empty: the run passed).
pub fn failures(outcome: &RunOutcome, expected: &Expected<'_>) -> Vec<String> {
    let mut f = Vec::new();
    let status = match expected {
        Expected::PanicAt(_) => 1,
        _ => 0,
    };
    if outcome.exit_code != status {
        f.push(format!(
            "exit status {}, expected {status}",
            outcome.exit_code
        ));
    }
    if outcome.malformed_frames != 0 {
        f.push(format!(
            "{} malformed defmt frames",
            outcome.malformed_frames
        ));
    }
    match expected {
        Expected::Scenario { id, host } => scenario_failures(*id, outcome, host, &mut f),
        Expected::PanicAt(tick) => panic_failures(outcome, *tick, &mut f),
        Expected::Records(kinds) => {
            for kind in *kinds {
                if results::all(&outcome.lines, kind).next().is_none() {
                    f.push(format!("no `RESULT {kind} …` line"));
                }
            }
        }
    }
    f
}

/// [`failures`] as one error.
pub fn check(outcome: &RunOutcome, expected: &Expected<'_>) -> Result<()> {
    let f = failures(outcome, expected);
    anyhow::ensure!(f.is_empty(), "{}", f.join("; "));
    Ok(())
}

fn scenario_failures(id: ScenarioId, outcome: &RunOutcome, host: &Summary, f: &mut Vec<String>) {
    let lines = &outcome.lines;
    let summary = results::last(lines, "scenario").and_then(|r| BoardSummary::from_record(&r));
    match summary {
        Err(e) => f.push(format!("{e:#}")),
        Ok(s) => {
            if s.name != id.name() {
                f.push(format!("the board ran {}, not {}", s.name, id.name()));
            }
            if !s.passed {
                f.push("the firmware's scenario check did not pass".to_owned());
            }
            if s.hash != host.hash {
                f.push(format!(
                    "hash {:#018x} on the board, {:#018x} on the host",
                    s.hash, host.hash
                ));
            }
            let want = host
                .first_fault
                .map_or(("none".to_owned(), 0), |(c, t)| (c.name().to_owned(), t));
            if s.fault != want {
                f.push(format!("first fault {:?}, host {:?}", s.fault, want));
            }
            let faults: Vec<_> = results::all(lines, "fault").collect();
            match id.expected_fault() {
                None => {
                    if s.fault.0 != "none" || !faults.is_empty() {
                        f.push(format!(
                            "unexpected fault {:?} ({} fault records)",
                            s.fault,
                            faults.len()
                        ));
                    }
                }
                Some(code) => {
                    if s.fault.0 != code.name() {
                        f.push(format!("expected fault {}, got {:?}", code.name(), s.fault));
                    }
                    if s.fault.1 < s.inject_tick || s.inject_tick == 0 {
                        f.push(format!(
                            "fault at tick {} before the injection at {}",
                            s.fault.1, s.inject_tick
                        ));
                    }
                    if s.condition_tick == 0 || s.fault.1 > s.condition_tick + 2 {
                        f.push(format!(
                            "fault at tick {}, more than 2 ticks after the condition at {}",
                            s.fault.1, s.condition_tick
                        ));
                    }
                    if s.driven_after_fault != 0 || s.bridge_driving_after_fault != 0 {
                        f.push(format!(
                            "motor driven after the fault: demanded {} ticks, bridge driving {} ticks",
                            s.driven_after_fault, s.bridge_driving_after_fault
                        ));
                    }
                    // The expected fault as the log task reported it: once, with its code
                    // and tick (later faults of other kinds may follow).
                    let expected: Vec<_> = faults
                        .iter()
                        .filter(|r| r.text("name").ok() == Some(code.name()))
                        .collect();
                    let reported =
                        |r: &results::Record| -> Result<bool> {
                            Ok(r.get::<u8>("code")? == code as u8
                                && r.get::<u32>("tick")? == s.fault.1)
                        };
                    let n = expected.len();
                    if n != 1 || !expected.iter().all(|r| reported(r).unwrap_or(false)) {
                        f.push(format!(
                            "expected exactly one `RESULT fault name={} code={} tick={}`, found {n}",
                            code.name(),
                            code as u8,
                            s.fault.1
                        ));
                    }
                }
            }
        }
    }
    match results::last(lines, "timing") {
        Ok(t) => {
            let expected_overruns = u32::from(id == ScenarioId::Overrun);
            if t.get::<bool>("passed").ok() != Some(true)
                || t.get::<u32>("expected_overruns").ok() != Some(expected_overruns)
            {
                f.push(format!("timing self-check failed: {t:?}"));
            }
        }
        Err(e) => f.push(format!("{e:#}")),
    }
    if let Err(e) = scenarios::step_insns(lines) {
        f.push(format!("{e:#}"));
    }
}

fn panic_failures(outcome: &RunOutcome, tick: u32, f: &mut Vec<String>) {
    // The panic handler's message is text by nature: it must arrive whole, last.
    let expected = format!("ERROR panic: injected panic at tick {tick}");
    match outcome.lines.last() {
        Some(last) if last.contains(&expected) => {}
        other => f.push(format!("last line {other:?}, expected `{expected}`")),
    }
    if results::all(&outcome.lines, "setting").next().is_none() {
        f.push("the scenario did not start before the panic".into());
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn outcome(lines: &[&str], exit_code: i32) -> RunOutcome {
        RunOutcome {
            lines: lines.iter().map(|s| s.to_string()).collect(),
            exit_code,
            malformed_frames: 0,
        }
    }

    const GOOD: &[&str] = &[
        "  0.000000 INFO  vsa firmware 0.1.0 on qemu-m4",
        "  0.001000 PRINT RESULT setting index=1 clutch_mm=1 stiffness_nm_per_rad=7167.5 torque_capacity_nm=4.595 from_tick=1  (firmware/src/report.rs:1)",
    ];

    #[test]
    fn a_panic_run_must_fail_with_its_message_last() {
        let mut lines = GOOD.to_vec();
        lines
            .push("  1.500000 ERROR panic: injected panic at tick 1500 (src/main.rs:97)  (q.rs:1)");
        let panic = Expected::PanicAt(1500);
        assert!(failures(&outcome(&lines, 1), &panic).is_empty());
        assert!(!failures(&outcome(&lines, 0), &panic).is_empty());
        assert!(!failures(&outcome(GOOD, 1), &panic).is_empty());
        let no_start = [lines[0], lines[2]];
        assert!(!failures(&outcome(&no_start, 1), &panic).is_empty());
        let records = Expected::Records(&["setting"]);
        assert!(failures(&outcome(GOOD, 0), &records).is_empty());
        assert!(!failures(&outcome(&no_start, 0), &records).is_empty());
    }
}
