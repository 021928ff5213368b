//! Checks of a decoded emulated run: what `cargo xtask test` asserts about the firmware.

use crate::qemu::RunOutcome;

/// Control ticks expected in each second of the independent clock.
pub const TICKS_PER_SECOND: u32 = 1000;

/// One `second N: T ticks, O overruns, …` telemetry line.
#[derive(Debug, PartialEq, Eq)]
pub struct SecondLine {
    pub second: u32,
    pub ticks: u32,
    pub overruns: u32,
}

/// Parses a decoded telemetry line, if `line` is one.
pub fn parse_second_line(line: &str) -> Option<SecondLine> {
    let rest = &line[line.find(" second ")? + " second ".len()..];
    let (second, rest) = rest.split_once(": ")?;
    let (ticks, rest) = rest.split_once(" ticks, ")?;
    let (overruns, _) = rest.split_once(" overruns")?;
    Some(SecondLine {
        second: second.trim().parse().ok()?,
        ticks: ticks.trim().parse().ok()?,
        overruns: overruns.trim().parse().ok()?,
    })
}

/// Everything wrong with a self-test run of `seconds` seconds (empty: it passed).
pub fn self_test_failures(outcome: &RunOutcome, seconds: u32) -> Vec<String> {
    let mut failures = Vec::new();
    if outcome.exit_code != 0 {
        failures.push(format!("firmware exit status {}", outcome.exit_code));
    }
    if outcome.malformed_frames > 0 {
        failures.push(format!(
            "{} malformed defmt frames",
            outcome.malformed_frames
        ));
    }
    let reports: Vec<_> = outcome
        .lines
        .iter()
        .filter_map(|l| parse_second_line(l))
        .collect();
    if reports.len() != seconds as usize {
        failures.push(format!(
            "{} per-second reports, expected {seconds}",
            reports.len()
        ));
    }
    for (i, r) in reports.iter().enumerate() {
        if r.second != i as u32 + 1 {
            failures.push(format!("report {} is numbered {}", i + 1, r.second));
        }
        if r.ticks != TICKS_PER_SECOND {
            failures.push(format!(
                "second {}: {} ticks, expected {TICKS_PER_SECOND}",
                r.second, r.ticks
            ));
        }
        if r.overruns != 0 {
            failures.push(format!("second {}: {} overruns", r.second, r.overruns));
        }
    }
    if !outcome
        .lines
        .iter()
        .any(|l| l.contains("self-check passed"))
    {
        failures.push("no `self-check passed` line".into());
    }
    for line in &outcome.lines {
        if line.contains(" ERROR ") || line.contains(" WARN ") {
            failures.push(format!("logged: {}", line.trim()));
        }
    }
    failures
}

/// Everything wrong with a run that panicked on purpose at `tick`: it must end with
/// status 1, with the panic message decoded intact after the first second's report.
pub fn panic_test_failures(outcome: &RunOutcome, tick: u32) -> Vec<String> {
    let mut failures = Vec::new();
    if outcome.exit_code != 1 {
        failures.push(format!("exit status {}, expected 1", outcome.exit_code));
    }
    if outcome.malformed_frames > 0 {
        failures.push(format!(
            "{} malformed defmt frames",
            outcome.malformed_frames
        ));
    }
    let expected = format!("ERROR panic: injected panic at tick {tick}");
    match outcome.lines.last() {
        Some(last) if last.contains(&expected) => {}
        other => failures.push(format!("last line {other:?}, expected `{expected}`")),
    }
    if !outcome.lines.iter().any(|l| parse_second_line(l).is_some()) {
        failures.push("no telemetry before the panic".into());
    }
    failures
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
        "  1.001000 INFO  second 1: 1000 ticks, 0 overruns, tick busy max 51 sysclk cycles, 0 reports dropped  (firmware/src/main.rs:1)",
        "  2.001000 INFO  second 2: 1000 ticks, 0 overruns, tick busy max 51 sysclk cycles, 0 reports dropped  (firmware/src/main.rs:1)",
        "  2.001000 INFO  self-check passed: 2 s, 1000 ticks/s in every second, 0 overruns",
    ];

    #[test]
    fn parses_a_telemetry_line() {
        assert_eq!(
            parse_second_line(GOOD[1]),
            Some(SecondLine {
                second: 1,
                ticks: 1000,
                overruns: 0
            })
        );
        assert_eq!(parse_second_line(GOOD[0]), None);
    }

    #[test]
    fn a_good_run_passes() {
        assert_eq!(
            self_test_failures(&outcome(GOOD, 0), 2),
            Vec::<String>::new()
        );
    }

    #[test]
    fn a_panic_run_must_fail_with_its_message_last() {
        let mut lines = GOOD[..2].to_vec();
        lines
            .push("  1.500000 ERROR panic: injected panic at tick 1500 (src/main.rs:97)  (q.rs:1)");
        assert!(panic_test_failures(&outcome(&lines, 1), 1500).is_empty());
        assert!(!panic_test_failures(&outcome(&lines, 0), 1500).is_empty());
        assert!(!panic_test_failures(&outcome(&GOOD[..2], 1), 1500).is_empty());
    }

    #[test]
    fn each_defect_is_caught() {
        assert!(!self_test_failures(&outcome(GOOD, 1), 2).is_empty());
        assert!(!self_test_failures(&outcome(GOOD, 0), 3).is_empty());
        let mut bad = GOOD.to_vec();
        bad[2] = "  2.001000 INFO  second 2: 1001 ticks, 0 overruns, x";
        assert!(!self_test_failures(&outcome(&bad, 0), 2).is_empty());
        bad[2] = "  2.001000 INFO  second 2: 1000 ticks, 1 overruns, x";
        assert!(!self_test_failures(&outcome(&bad, 0), 2).is_empty());
        assert!(!self_test_failures(&outcome(&GOOD[..3], 0), 2).is_empty());
    }
}
