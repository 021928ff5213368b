//! Totals of the acceptance grid over many draws: the violations and worst value of every
//! metric of [`Outcome::figures`], the runs that meet every limit but the raw steps' time
//! bound, and how the runs without load end (at rest, within a count, settled in time). The
//! seed sweep of `tests/grid.rs` prints them (docs/design.md §11, "The grid today"); the
//! limits are the grid's own.

use std::fmt::Write as _;

use crate::grid::{
    Outcome, RAW_STEP_BOUND, REST_COUNT_SPAN, REST_DUTY_SPAN, SETTLING, STEADY_STATE,
};

/// Running totals over grid outcomes.
#[derive(Clone, Debug, Default)]
pub struct Tally {
    /// Runs counted.
    pub runs: usize,
    /// Per metric, in [`Outcome::figures`] order: name, violations, worst value.
    metrics: Vec<(&'static str, usize, f64)>,
    /// Runs meeting every limit but the raw steps' time bound.
    pub every_limit_but_raw: usize,
    /// Runs without load (a load of exactly 0: a quarter of the draw).
    pub unloaded: usize,
    /// … of those at rest: count span and duty span within their limits.
    pub unloaded_at_rest: usize,
    /// … at rest and within the steady-state error limit as well.
    pub unloaded_at_rest_within: usize,
    /// … settled within their settling limit.
    pub unloaded_settled: usize,
}

impl Tally {
    /// Counts one outcome.
    pub fn add(&mut self, o: &Outcome) {
        let figures = o.figures();
        if self.metrics.is_empty() {
            self.metrics = figures
                .iter()
                .map(|f| (f.0, 0, f64::NEG_INFINITY))
                .collect();
        }
        let met = |name: &str| figures.iter().any(|f| f.0 == name && f.3);
        for (slot, f) in self.metrics.iter_mut().zip(figures.iter()) {
            if !f.3 {
                slot.1 += 1;
            }
            slot.2 = slot.2.max(f.1);
        }
        self.runs += 1;
        if figures.iter().all(|f| f.3 || f.0 == RAW_STEP_BOUND) {
            self.every_limit_but_raw += 1;
        }
        if o.case.load_nm == 0.0 {
            self.unloaded += 1;
            let at_rest = met(REST_COUNT_SPAN) && met(REST_DUTY_SPAN);
            self.unloaded_at_rest += usize::from(at_rest);
            self.unloaded_at_rest_within += usize::from(at_rest && met(STEADY_STATE));
            self.unloaded_settled += usize::from(met(SETTLING));
        }
    }

    /// Adds another tally's counts (the sweep's threads each keep one).
    pub fn merge(&mut self, other: &Tally) {
        if self.metrics.is_empty() {
            self.metrics.clone_from(&other.metrics);
        } else {
            for (a, b) in self.metrics.iter_mut().zip(&other.metrics) {
                a.1 += b.1;
                a.2 = a.2.max(b.2);
            }
        }
        self.runs += other.runs;
        self.every_limit_but_raw += other.every_limit_but_raw;
        self.unloaded += other.unloaded;
        self.unloaded_at_rest += other.unloaded_at_rest;
        self.unloaded_at_rest_within += other.unloaded_at_rest_within;
        self.unloaded_settled += other.unloaded_settled;
    }

    /// Violations of the metric called `name`, if counted.
    #[must_use]
    pub fn violations(&self, name: &str) -> Option<usize> {
        self.metrics.iter().find(|m| m.0 == name).map(|m| m.1)
    }

    /// The totals as a few lines of text, headed by `label`.
    #[must_use]
    pub fn report(&self, label: &str) -> String {
        let mut out = format!("{label}: {} runs\n", self.runs);
        for (name, bad, worst) in &self.metrics {
            let _ = writeln!(out, "  {name:<32} violations {bad:>6}   worst {worst:.3}");
        }
        let _ = writeln!(
            out,
            "  meeting every limit but the raw steps' bound: {}\n  \
             without load: {} runs, {} at rest, {} of them within a count, {} settled in time",
            self.every_limit_but_raw,
            self.unloaded,
            self.unloaded_at_rest,
            self.unloaded_at_rest_within,
            self.unloaded_settled
        );
        out
    }
}
