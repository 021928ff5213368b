//! Scenarios on the emulated boards: the firmware's arguments, the host simulation of the
//! same scenario (`plant::scenario::run_on_host`, the same code on x86), and what the
//! emulated board reported of it (its `RESULT scenario` record).

use anyhow::Result;
use plant::overrides::Overrides;
use plant::scenario::ScenarioId;
use plant::scenario::{run_on_host, run_on_host_with_plant, Summary};

use crate::qemu::{RunOutcome, ICOUNT_SHIFT};
use crate::results::{self, Record};

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

/// Prints the host simulation's hash of `id` (on the actuator changed by `plant`, as the
/// board's) and whether the emulated board's matches.
pub fn print_host_comparison(
    id: ScenarioId,
    plant: &Overrides,
    outcome: &RunOutcome,
) -> Result<()> {
    let host = run_on_host_with_plant(id, plant, |_| {})
        .map_err(|e| anyhow::anyhow!("host simulation of {}: {e:?}", id.name()))?;
    let board =
        results::last(&outcome.lines, "scenario").and_then(|r| BoardSummary::from_record(&r));
    let verdict = match board {
        Ok(b) if b.hash == host.hash => "identical to the emulated board's",
        Ok(_) => "DIFFERENT from the emulated board's",
        Err(_) => "(the emulated board printed none)",
    };
    println!(
        "host simulation of {} (x86, same model and plant code): hash {:#018x}, {verdict}",
        id.name(),
        host.hash
    );
    Ok(())
}

/// What the emulated board reported of a scenario (its `RESULT scenario` record).
#[derive(Debug, PartialEq, Eq)]
pub struct BoardSummary {
    /// Scenario name.
    pub name: String,
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
    /// Ticks after the fault in which the bridge drove the motor (enabled with a duty; a
    /// brake, enabled at zero duty, does not count).
    pub bridge_driving_after_fault: u32,
    /// The firmware's own verdict on the scenario.
    pub passed: bool,
}

impl BoardSummary {
    /// Reads a `RESULT scenario` record.
    pub fn from_record(r: &Record) -> Result<Self> {
        Ok(Self {
            name: r.text("name")?.to_owned(),
            hash: r.hex("hash")?,
            fault: (r.text("first_fault")?.to_owned(), r.get("fault_tick")?),
            inject_tick: r.get("inject_tick")?,
            condition_tick: r.get("condition_tick")?,
            driven_after_fault: r.get("driven_after_fault")?,
            bridge_driving_after_fault: r.get("bridge_driving_after_fault")?,
            passed: r.get("passed")?,
        })
    }
}

/// Instructions per control step (mean, max) from the firmware's `RESULT control_step`.
pub fn step_insns(lines: &[String]) -> Result<(u64, u64)> {
    let r = results::last(lines, "control_step")?;
    Ok((r.get("insns_mean")?, r.get("insns_max")?))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_scenario_record_reads() {
        let line = "  0.6 PRINT RESULT scenario name=fault-overrun ticks=1100 hash=0x61923127aaaa1bdf first_fault=deadline-missed fault_tick=300 inject_tick=300 condition_tick=300 driven_after_fault=0 bridge_driving_after_fault=0 passed=true  (firmware/src/report.rs:1)";
        let s = BoardSummary::from_record(&Record::parse(line).unwrap()).unwrap();
        assert_eq!(s.name, "fault-overrun");
        assert_eq!(s.hash, 0x6192_3127_aaaa_1bdf);
        assert_eq!(s.fault, ("deadline-missed".to_owned(), 300));
        assert_eq!((s.inject_tick, s.condition_tick), (300, 300));
        assert_eq!((s.driven_after_fault, s.bridge_driving_after_fault), (0, 0));
        assert!(s.passed);
        let lines = vec![
            "x PRINT RESULT control_step insns_mean=812 insns_max=1430 hooks_insns_mean=9000 icount_shift=3".to_owned(),
        ];
        assert_eq!(step_insns(&lines).unwrap(), (812, 1430));
    }
}
