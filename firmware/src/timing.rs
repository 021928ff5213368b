//! Tick timing: SysTick set-up, missed-deadline accounting and the time for the defmt
//! timestamp.
//!
//! The control period is SysTick at [`CONTROL_HZ`]. Each second of the board's
//! *independent* clock (a free-running µs timer, see `board::IndependentClock`) the
//! accounting reports how many control ticks fell into that second and how many of them
//! overran, so a wrong SysTick reload shows up as a tick count other than 1000.

use core::sync::atomic::{AtomicU32, Ordering};
use cortex_m::peripheral::{syst::SystClkSource, SCB, SYST};

/// Control loop rate, Hz.
pub const CONTROL_HZ: u32 = 1000;

/// Length of one accounting window on the independent clock, µs.
const WINDOW_US: u32 = 1_000_000;

/// Control ticks completed since boot, for the log timestamp.
static TICKS: AtomicU32 = AtomicU32::new(0);

/// Starts SysTick on the core clock so that it fires at [`CONTROL_HZ`].
pub fn start_systick(syst: &mut SYST, sysclk_hz: u32) {
    syst.set_clock_source(SystClkSource::Core);
    syst.set_reload(sysclk_hz / CONTROL_HZ - 1);
    syst.clear_current();
    syst.enable_interrupt();
    syst.enable_counter();
}

/// SysTick counts (core clock cycles; under QEMU icount, a fixed multiple of instructions)
/// between two readings of the down-counter taken within one period.
pub fn systick_elapsed(start: u32, end: u32, sysclk_hz: u32) -> u32 {
    if end <= start {
        start - end
    } else {
        // The counter reloaded in between (the task overran its period).
        start + (sysclk_hz / CONTROL_HZ - end)
    }
}

/// Makes `ticks` visible to the log timestamp.
pub fn publish_tick(ticks: u32) {
    TICKS.store(ticks, Ordering::Relaxed);
}

/// Time since SysTick started, µs: whole ticks from the counter plus the part of the
/// current period. Called by defmt inside its critical section (the program's
/// `defmt::timestamp!`), so the tick count cannot advance underneath; a reload that is
/// pending but not yet served counts as one tick.
pub fn uptime_us() -> u64 {
    let ticks = u64::from(TICKS.load(Ordering::Relaxed));
    let reload = SYST::get_reload();
    let current = SYST::get_current();
    let pending = u64::from(SCB::is_pendst_pending());
    let counts_per_us = u64::from(crate::board::SYSCLK_HZ / 1_000_000);
    let in_period = u64::from(reload.saturating_sub(current)) / counts_per_us;
    (ticks + pending) * 1000 + in_period
}

/// What one second of control ticks looked like.
#[derive(Clone, Copy, defmt::Format)]
pub struct SecondReport {
    /// 1-based index of the second on the independent clock.
    pub second: u32,
    /// Control ticks that started within this second.
    pub ticks: u32,
    /// Of those, how many ran past their period.
    pub overruns: u32,
    /// Longest tick body this second, in SysTick counts (core clock cycles).
    pub busy_max_counts: u32,
    /// Reports that could not be handed to the telemetry task since boot.
    pub dropped_reports: u32,
}

/// Counts control ticks into one-second windows of the independent clock.
pub struct TickAccounting {
    ticks: u32,
    window_start_us: Option<u32>,
    second: u32,
    ticks_in_window: u32,
    overruns_in_window: u32,
    busy_max_counts: u32,
    dropped_reports: u32,
}

impl Default for TickAccounting {
    fn default() -> Self {
        Self::new()
    }
}

impl TickAccounting {
    /// No ticks seen yet.
    pub const fn new() -> Self {
        Self {
            ticks: 0,
            window_start_us: None,
            second: 0,
            ticks_in_window: 0,
            overruns_in_window: 0,
            busy_max_counts: 0,
            dropped_reports: 0,
        }
    }

    /// Ticks seen since boot.
    pub fn ticks(&self) -> u32 {
        self.ticks
    }

    /// Records one tick that started at `now_us` on the independent clock. Returns the
    /// report of the previous second when this tick opens a new one.
    ///
    /// Windows start half a period before the first tick, so each window boundary falls
    /// between two ticks and jitter below ±0.5 ms cannot move a tick across it.
    pub fn on_tick(
        &mut self,
        now_us: u32,
        overrun: bool,
        busy_counts: u32,
    ) -> Option<SecondReport> {
        self.ticks = self.ticks.wrapping_add(1);
        let half_period_us = WINDOW_US / CONTROL_HZ / 2;
        let start = *self
            .window_start_us
            .get_or_insert(now_us.wrapping_sub(half_period_us));
        let mut report = None;
        if now_us.wrapping_sub(start) >= WINDOW_US {
            self.second += 1;
            report = Some(SecondReport {
                second: self.second,
                ticks: self.ticks_in_window,
                overruns: self.overruns_in_window,
                busy_max_counts: self.busy_max_counts,
                dropped_reports: self.dropped_reports,
            });
            self.window_start_us = Some(start.wrapping_add(WINDOW_US));
            self.ticks_in_window = 0;
            self.overruns_in_window = 0;
            self.busy_max_counts = 0;
        }
        self.ticks_in_window += 1;
        self.overruns_in_window += u32::from(overrun);
        self.busy_max_counts = self.busy_max_counts.max(busy_counts);
        report
    }

    /// The telemetry task was still busy with the previous report.
    pub fn note_dropped_report(&mut self) {
        self.dropped_reports += 1;
    }
}
