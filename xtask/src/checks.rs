//! Checks of a decoded emulated run: what `cargo xtask test` asserts about the firmware.

use crate::qemu::RunOutcome;

/// Everything wrong with a run that panicked on purpose at `tick`: it must end with
/// status 1, with the panic message decoded intact, as the last line, after the run had
/// started its scenario.
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
    if !outcome.lines.iter().any(|l| l.contains(" setting 1: L = ")) {
        failures.push("the scenario did not start before the panic".into());
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
        "  0.001000 INFO  setting 1: L = 1 mm, k = 7167.5 N·m/rad, torque capacity 4.595 N·m (from tick 1)  (firmware/src/report.rs:1)",
    ];

    #[test]
    fn a_panic_run_must_fail_with_its_message_last() {
        let mut lines = GOOD.to_vec();
        lines
            .push("  1.500000 ERROR panic: injected panic at tick 1500 (src/main.rs:97)  (q.rs:1)");
        assert!(panic_test_failures(&outcome(&lines, 1), 1500).is_empty());
        assert!(!panic_test_failures(&outcome(&lines, 0), 1500).is_empty());
        assert!(!panic_test_failures(&outcome(GOOD, 1), 1500).is_empty());
        let no_start = [lines[0], lines[2]];
        assert!(!panic_test_failures(&outcome(&no_start, 1), 1500).is_empty());
    }
}
