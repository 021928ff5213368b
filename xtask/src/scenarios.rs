//! Scenarios on the emulated boards: the firmware's arguments, the host simulation of the
//! same scenario (`plant::scenario::run_on_host`, the same code on x86), and the checks of
//! an emulated run's decoded log against it.

use anyhow::{Context, Result};
use plant::scenario::ScenarioId;
use plant::scenario::{run_on_host, Summary};

use crate::qemu::{RunOutcome, ICOUNT_SHIFT};

/// Firmware arguments that run `id` with instruction counts enabled.
pub fn firmware_args(id: ScenarioId) -> Vec<String> {
    vec![
        "--scenario".to_owned(),
        id.name().to_owned(),
        "--icount-shift".to_owned(),
        ICOUNT_SHIFT.to_string(),
    ]
}

/// The host simulation of `id`.
pub fn host_summary(id: ScenarioId) -> Result<Summary> {
    run_on_host(id, |_| {}).map_err(|e| anyhow::anyhow!("host simulation of {}: {e:?}", id.name()))
}

/// Prints the host simulation's hash of `id` and whether the emulated board's matches.
pub fn print_host_comparison(id: ScenarioId, outcome: &RunOutcome) -> Result<()> {
    let host = host_summary(id)?;
    let board = outcome
        .lines
        .iter()
        .rev()
        .filter(|l| l.contains(" hash 0x"))
        .find_map(|l| parse_summary(l));
    let verdict = match board {
        Some(b) if b.hash == host.hash => "identical to the emulated board's",
        Some(_) => "DIFFERENT from the emulated board's",
        None => "(the emulated board printed none)",
    };
    println!(
        "host simulation of {} (x86, same model and plant code): hash {:#018x}, {verdict}",
        id.name(),
        host.hash
    );
    Ok(())
}

/// What the firmware's final scenario line says.
#[derive(Debug, PartialEq, Eq)]
pub struct FirmwareSummary {
    /// Output hash.
    pub hash: u64,
    /// First fault's name (`none`) and tick.
    pub fault: (String, u32),
    /// Injection tick (0: none).
    pub inject_tick: u32,
    /// Condition tick (0: none).
    pub condition_tick: u32,
    /// Ticks driven after the fault.
    pub driven_after_fault: u32,
    /// Ticks with the bridge enabled after the fault.
    pub lines_on_after_fault: u32,
}

fn number_after<'a>(line: &'a str, key: &str) -> Option<&'a str> {
    let rest = &line[line.find(key)? + key.len()..];
    let end = rest
        .find(|c: char| !(c.is_ascii_alphanumeric() || c == '-' || c == '.'))
        .unwrap_or(rest.len());
    Some(&rest[..end])
}

/// Parses the `scenario NAME: … hash …` line.
pub fn parse_summary(line: &str) -> Option<FirmwareSummary> {
    let hash = number_after(line, "hash 0x")?;
    let fault = number_after(line, "first fault ")?;
    let u = |key: &str| number_after(line, key)?.parse::<u32>().ok();
    Some(FirmwareSummary {
        hash: u64::from_str_radix(hash, 16).ok()?,
        fault: (
            fault.to_owned(),
            u(&format!("first fault {fault} at tick "))?,
        ),
        inject_tick: u("injected at tick ")?,
        condition_tick: u("condition at tick ")?,
        driven_after_fault: u("ticks driven after the fault ")?,
        lines_on_after_fault: u("bridge enabled after the fault ")?,
    })
}

/// Instructions per control step (mean, max) from the firmware's log.
pub fn parse_step_insns(lines: &[String]) -> Option<(u64, u64)> {
    let line = lines.iter().find(|l| l.contains("control step: mean "))?;
    let mean = number_after(line, "control step: mean ")?.parse().ok()?;
    let max = number_after(line, "max ")?.parse().ok()?;
    Some((mean, max))
}

/// Everything wrong with an emulated run of `id`, compared with the host simulation.
pub fn failures(id: ScenarioId, outcome: &RunOutcome, host: &Summary) -> Vec<String> {
    let mut f = Vec::new();
    let prefix = format!("scenario {}: ", id.name());
    let summary = outcome
        .lines
        .iter()
        .find(|l| l.contains(&prefix) && l.contains(" hash 0x"))
        .and_then(|l| parse_summary(l));
    match summary {
        None => f.push(format!("no `{prefix}… hash …` line in the log")),
        Some(s) => {
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
            match id.expected_fault() {
                None => {
                    if s.fault.0 != "none" {
                        f.push(format!("unexpected fault {:?}", s.fault));
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
                    if s.driven_after_fault != 0 || s.lines_on_after_fault != 0 {
                        f.push(format!(
                            "motor not off after the fault: driven {} ticks, bridge enabled {} ticks",
                            s.driven_after_fault, s.lines_on_after_fault
                        ));
                    }
                    // The decoded defmt error for the fault, with its code and tick.
                    let fault_line = format!("FAULT {} (code {})", code.name(), code as u8);
                    let tick = format!("at tick {}; motor disabled", s.fault.1);
                    let n = outcome
                        .lines
                        .iter()
                        .filter(|l| l.contains(" ERROR ") && l.contains(&fault_line))
                        .count();
                    if n != 1
                        || !outcome
                            .lines
                            .iter()
                            .any(|l| l.contains(&fault_line) && l.contains(&tick))
                    {
                        f.push(format!(
                            "expected exactly one ERROR `{fault_line} … {tick}` line, found {n}"
                        ));
                    }
                }
            }
        }
    }
    if !outcome
        .lines
        .iter()
        .any(|l| l.contains(&format!("scenario {} passed", id.name())))
    {
        f.push("the firmware did not report `passed`".to_owned());
    }
    if !outcome.lines.iter().any(|l| {
        l.contains(" timing: ")
            && l.contains(" ticks in every second")
            && l.ends_with(")")
            && l.contains("passed")
    }) {
        f.push("no `timing: … ticks in every second … passed` line".to_owned());
    }
    if parse_step_insns(&outcome.lines).is_none() {
        f.push("no `control step: mean … instructions` line".to_owned());
    }
    if outcome.exit_code != 0 {
        f.push(format!("exit status {}", outcome.exit_code));
    }
    if outcome.malformed_frames != 0 {
        f.push(format!(
            "{} malformed defmt frames",
            outcome.malformed_frames
        ));
    }
    f
}

/// Runs every check of `failures` and turns them into one error.
pub fn check(id: ScenarioId, outcome: &RunOutcome) -> Result<()> {
    let host = host_summary(id).context("host simulation")?;
    let f = failures(id, outcome, &host);
    anyhow::ensure!(f.is_empty(), "{}", f.join("; "));
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_summary_line_parses() {
        let line = "  0.6 INFO  scenario fault-overrun: 1100 ticks, hash 0x61923127aaaa1bdf, first fault deadline-missed at tick 300, injected at tick 300, condition at tick 300, ticks driven after the fault 0, bridge enabled after the fault 0  (firmware/src/report.rs:1)";
        let s = parse_summary(line).unwrap();
        assert_eq!(s.hash, 0x6192_3127_aaaa_1bdf);
        assert_eq!(s.fault, ("deadline-missed".to_owned(), 300));
        assert_eq!((s.inject_tick, s.condition_tick), (300, 300));
        assert_eq!((s.driven_after_fault, s.lines_on_after_fault), (0, 0));
        let lines =
            vec!["x control step: mean 812 instructions, max 1430 instructions (icount".to_owned()];
        assert_eq!(parse_step_insns(&lines), Some((812, 1430)));
    }
}
