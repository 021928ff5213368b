//! The log task's side: what the control tick hands over ([`LogItem`]) and how it is
//! written to defmt ([`Reporter`]), including the scenario results and the final verdict
//! of an emulated run.
//!
//! Results a tool checks are written as one machine-readable line each, besides the lines
//! for people: `RESULT <record> <key>=<value> …`, values without spaces (decimal numbers,
//! `0x` and 16 hex digits for a hash, kebab-case names, `true`/`false`). `xtask`'s
//! `results` module reads them; the records and their keys are listed there.

use crate::board::{self, Event};
use crate::run_config::RunConfig;
use crate::self_check::SelfCheck;
use crate::tick::StepStats;
use crate::timing::{SecondReport, CONTROL_HZ};
use model::supervisor::Fault;

/// Something the control tick wants logged.
#[allow(clippy::large_enum_variant)] // a few items in a static queue
pub enum LogItem {
    /// A fault was latched (the motor is already off).
    Fault(Fault),
    /// One second of ticks on the independent clock.
    Second(SecondReport),
    /// A board event (a scenario's progress on the emulated boards).
    Board(Event),
    /// The emulated run's last board event was logged: the control loop's cost
    /// accounting.
    #[cfg(feature = "qemu")]
    Costs(StepStats),
}

impl LogItem {
    /// What to log after a run's last board event: the control loop's costs on the
    /// emulated boards. The real board's runs do not end; without this variant its log
    /// queue's items stay small.
    pub fn costs(stats: StepStats) -> Option<LogItem> {
        #[cfg(feature = "qemu")]
        return Some(LogItem::Costs(stats));
        #[cfg(not(feature = "qemu"))]
        {
            let _ = stats;
            None
        }
    }
}

/// Writes log items; on the emulated boards, collects the results and ends the run.
pub struct Reporter {
    run: RunConfig,
    self_check: SelfCheck,
    #[cfg(feature = "qemu")]
    results: [Option<(i32, plant::harness::Metrics)>; 5],
    #[cfg(feature = "qemu")]
    summary: Option<plant::scenario::Summary>,
}

impl Reporter {
    /// A reporter for `run`.
    pub fn new(run: RunConfig) -> Self {
        Self {
            run,
            self_check: SelfCheck::new(),
            #[cfg(feature = "qemu")]
            results: [None; 5],
            #[cfg(feature = "qemu")]
            summary: None,
        }
    }

    /// Logs one item.
    pub fn log(&mut self, item: LogItem) {
        match item {
            LogItem::Fault(f) => {
                defmt::error!(
                    "FAULT {=str} (code {=u8}): value {=i32} at tick {=u32}; motor disabled",
                    f.code.name(),
                    f.code as u8,
                    f.value,
                    f.tick
                );
                #[cfg(feature = "qemu")]
                defmt::println!(
                    "RESULT fault name={=str} code={=u8} value={=i32} tick={=u32}",
                    f.code.name(),
                    f.code as u8,
                    f.value,
                    f.tick
                );
            }
            LogItem::Second(report) => {
                self.self_check.record(&report);
                #[cfg(feature = "nucleo-f446re")]
                defmt::info!(
                    "second {=u32}: {=u32} ticks, {=u32} overruns, tick busy max {=u32} sysclk counts, {=u32} log items dropped",
                    report.second,
                    report.ticks,
                    report.overruns,
                    report.busy_max_counts,
                    report.dropped_reports,
                );
                // The emulated boards log a second only when it had an overrun (a long
                // run would otherwise print a line per second). The same line at two defmt
                // levels is two macro calls: `duplicates` pairs them, on purpose.
                #[cfg(feature = "qemu")]
                if report.overruns > 0 {
                    defmt::warn!(
                        "second {=u32}: {=u32} ticks, {=u32} overruns, tick busy max {=u32} sysclk counts, {=u32} log items dropped",
                        report.second,
                        report.ticks,
                        report.overruns,
                        report.busy_max_counts,
                        report.dropped_reports,
                    );
                }
                if self.run.is_last_second(report.second) {
                    defmt::warn!("--seconds {=u32} reached: stopping", report.second);
                    let passed = self.timing_verdict(0);
                    board::exit(passed);
                }
            }
            LogItem::Board(ev) => self.board_event(ev),
            #[cfg(feature = "qemu")]
            LogItem::Costs(stats) => self.finish(stats),
        }
    }

    /// The control loop's costs per tick, and the stack's high-water mark.
    #[cfg(feature = "qemu")]
    fn log_costs(&self, stats: &StepStats) {
        let n = u64::from(stats.ticks.max(1));
        let step_mean = (stats.step_sum / n) as u32;
        let hooks_mean = (stats.hooks_sum / n) as u32;
        defmt::info!(
            "cost per tick over {=u32} ticks, sysclk counts: control step mean {=u32} max {=u32}; plant mean {=u32} max {=u32}",
            stats.ticks,
            step_mean,
            stats.step_max,
            hooks_mean,
            stats.hooks_max
        );
        if let Some(shift) = self.run.icount_shift {
            // One instruction takes 2^shift ns; SysTick counts at SYSCLK.
            let per = |counts: u64| counts * 1_000_000_000 / (u64::from(board::SYSCLK_HZ) << shift);
            defmt::println!(
                "RESULT control_step insns_mean={=u64} insns_max={=u64} hooks_insns_mean={=u64} icount_shift={=u8}",
                per(u64::from(step_mean)),
                per(u64::from(stats.step_max)),
                per(u64::from(hooks_mean)),
                shift
            );
        }
        crate::stack::log_high_water();
    }

    /// Logs the timing self-check: every complete second had [`CONTROL_HZ`] ticks and
    /// there were exactly `expected_overruns` overruns.
    fn timing_verdict(&mut self, expected_overruns: u32) -> bool {
        let v = self.self_check.verdict();
        let passed = v.seconds > 0
            && v.min_ticks == CONTROL_HZ
            && v.max_ticks == CONTROL_HZ
            && v.overruns == expected_overruns
            && v.dropped_reports == 0;
        defmt::println!(
            "RESULT timing seconds={=u32} min_ticks={=u32} max_ticks={=u32} overruns={=u32} expected_overruns={=u32} dropped={=u32} passed={=bool}",
            v.seconds,
            v.min_ticks,
            v.max_ticks,
            v.overruns,
            expected_overruns,
            v.dropped_reports,
            passed
        );
        if passed {
            defmt::info!(
                "timing: {=u32} s, {=u32} ticks in every second, {=u32} overruns (expected {=u32}), 0 log items dropped: passed",
                v.seconds,
                CONTROL_HZ,
                v.overruns,
                expected_overruns
            );
        } else {
            defmt::error!(
                "timing: {=u32} s, ticks/s min {=u32} max {=u32}, {=u32} overruns (expected {=u32}), {=u32} log items dropped: FAILED",
                v.seconds,
                v.min_ticks,
                v.max_ticks,
                v.overruns,
                expected_overruns,
                v.dropped_reports
            );
        }
        passed
    }
}

/// The real board has no events to report.
#[cfg(feature = "nucleo-f446re")]
impl Reporter {
    fn board_event(&mut self, event: Event) {
        match event {}
    }
}

#[cfg(feature = "qemu")]
mod scenario_log {
    use super::Reporter;
    use crate::board;
    use crate::tick::StepStats;
    use plant::harness::Metrics;
    use plant::scenario::{Injection, ScenarioEvent, ScenarioId};

    /// `v` rounded to `decimals` places, as f32: defmt prints the shortest decimal that
    /// round-trips, so 0.8122263 logs as `0.812`.
    fn r(v: f64, decimals: i32) -> f32 {
        let scale = libm::pow(10.0, f64::from(decimals));
        (libm::round(v * scale) / scale) as f32
    }

    fn opt(v: Option<f64>) -> f64 {
        v.unwrap_or(f64::NAN)
    }

    fn log_metrics(index: u8, mm: i32, m: &Metrics) {
        defmt::println!(
            "RESULT segment index={=u8} clutch_mm={=i32} overshoot_pct={=f32} rise_s={=f32} settling_s={=f32} steady_state_error_counts={=f32} peak_stress_mpa={=f32} peak_stress_ratio={=f32} rms_error_rad={=f32} torque_limited={=bool} hash={=u64:#018x}",
            index + 1,
            mm,
            r(m.overshoot_pct, 2),
            r(opt(m.rise_time_s), 3),
            r(opt(m.settling_time_s), 3),
            r(m.steady_state_error_counts, 2),
            r(m.peak_stress_pa * 1e-6, 1),
            r(m.peak_stress_ratio, 3),
            r(m.rms_error_rad, 4),
            m.torque_limited,
            m.output_hash
        );
    }

    impl Reporter {
        pub(super) fn board_event(&mut self, ev: ScenarioEvent) {
            match ev {
                ScenarioEvent::SegmentStart {
                    index,
                    clutch_mm,
                    stiffness_nm_per_rad,
                    torque_capacity_nm,
                    tick,
                } => defmt::println!(
                    "RESULT setting index={=u8} clutch_mm={=i32} stiffness_nm_per_rad={=f32} torque_capacity_nm={=f32} from_tick={=u32}",
                    index + 1,
                    clutch_mm,
                    r(stiffness_nm_per_rad, 1),
                    r(torque_capacity_nm, 3),
                    tick
                ),
                ScenarioEvent::Injected { injection, tick } => match injection {
                    Injection::ExternalTorque(nm) => defmt::warn!(
                        "inject at tick {=u32}: external torque {=f32} N·m on the link",
                        tick,
                        nm
                    ),
                    other => defmt::warn!("inject at tick {=u32}: {}", tick, other),
                },
                ScenarioEvent::Condition { code, tick } => defmt::info!(
                    "condition for {=str} met at tick {=u32} (plant's true state)",
                    code.name(),
                    tick
                ),
                ScenarioEvent::SegmentDone {
                    index,
                    clutch_mm,
                    metrics,
                } => {
                    log_metrics(index, clutch_mm, &metrics);
                    if let Some(slot) = self.results.get_mut(usize::from(index)) {
                        *slot = Some((clutch_mm, metrics));
                    }
                }
                ScenarioEvent::Finished(s) => self.summary = Some(s),
            }
        }

        pub(super) fn finish(&mut self, stats: StepStats) -> ! {
            let Some(s) = self.summary else {
                defmt::error!("scenario ended without a summary");
                board::exit(false)
            };
            if s.id == ScenarioId::StepSweep {
                defmt::info!("step sweep (0.5 rad raw step, 0.3 N·m load, J_link = 1e-3 kg·m²):");
                defmt::info!("| L mm | overshoot % | settling s | ss error counts | peak stress / allowable | torque-limited |");
                for (mm, m) in self.results.iter().flatten() {
                    defmt::info!(
                        "| {=i32} | {=f32} | {=f32} | {=f32} | {=f32} | {=bool} |",
                        mm,
                        r(m.overshoot_pct, 2),
                        r(opt(m.settling_time_s), 3),
                        r(m.steady_state_error_counts, 2),
                        r(m.peak_stress_ratio, 3),
                        m.torque_limited
                    );
                }
            }
            self.log_costs(&stats);
            let fault = s.first_fault.map_or("none", |(c, _)| c.name());
            let fault_tick = s.first_fault.map_or(0, |(_, t)| t);
            let passed_scenario = s.passed();
            defmt::println!(
                "RESULT scenario name={=str} ticks={=u32} hash={=u64:#018x} first_fault={=str} fault_tick={=u32} inject_tick={=u32} condition_tick={=u32} driven_after_fault={=u32} bridge_driving_after_fault={=u32} passed={=bool}",
                s.id.name(),
                s.ticks,
                s.hash,
                fault,
                fault_tick,
                s.inject_tick.unwrap_or(0),
                s.condition_tick.unwrap_or(0),
                s.driven_after_fault,
                s.lines_driving_after_fault,
                passed_scenario
            );
            let expected_overruns = u32::from(s.id == ScenarioId::Overrun);
            let timing = self.timing_verdict(expected_overruns);
            if passed_scenario && timing {
                defmt::info!("scenario {=str} passed", s.id.name());
            } else {
                defmt::error!("scenario {=str} FAILED", s.id.name());
            }
            board::exit(passed_scenario && timing)
        }
    }
}
