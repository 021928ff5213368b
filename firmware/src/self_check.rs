//! The self-check that decides an emulated run's exit status: every complete second of
//! the independent clock had exactly the control rate's ticks, and no log item was lost.

use crate::timing::SecondReport;

/// Collects the per-second reports of a run.
pub struct SelfCheck {
    seconds: u32,
    min_ticks: u32,
    max_ticks: u32,
    overruns: u32,
    dropped_reports: u32,
}

/// Outcome of a run.
pub struct Verdict {
    /// Seconds recorded.
    pub seconds: u32,
    /// Fewest ticks in one second.
    pub min_ticks: u32,
    /// Most ticks in one second.
    pub max_ticks: u32,
    /// Overruns over the whole run.
    pub overruns: u32,
    /// Reports lost on the way to the telemetry task.
    pub dropped_reports: u32,
}

impl Default for SelfCheck {
    fn default() -> Self {
        Self::new()
    }
}

impl SelfCheck {
    /// Nothing recorded yet.
    pub const fn new() -> Self {
        Self {
            seconds: 0,
            min_ticks: u32::MAX,
            max_ticks: 0,
            overruns: 0,
            dropped_reports: 0,
        }
    }

    /// Adds one second's report.
    pub fn record(&mut self, report: &SecondReport) {
        self.seconds += 1;
        self.min_ticks = self.min_ticks.min(report.ticks);
        self.max_ticks = self.max_ticks.max(report.ticks);
        self.overruns += report.overruns;
        self.dropped_reports = report.dropped_reports;
    }

    /// The run's outcome so far.
    pub fn verdict(&self) -> Verdict {
        Verdict {
            seconds: self.seconds,
            min_ticks: if self.seconds == 0 { 0 } else { self.min_ticks },
            max_ticks: self.max_ticks,
            overruns: self.overruns,
            dropped_reports: self.dropped_reports,
        }
    }
}
