//! vsa firmware: the 1 kHz control loop of the variable-stiffness actuator.
//!
//! One RTIC 2 application for three boards, chosen by a cargo feature (see `board`):
//! `qemu-m4` (default), `qemu-m3` and `nucleo-f446re`.
//!
//! Priorities (highest first):
//! 3. `control_tick`: hardware task bound to SysTick at 1 kHz. It runs one control period
//!    (`control::ControlLoop::tick`) and detects a missed deadline: if SysTick fired again
//!    before the task finished, the period overran and is counted.
//! 1. `telemetry`: once per second, logs the tick and overrun counts of that second. On the
//!    emulated boards it also ends the run after the requested number of seconds and
//!    exits QEMU with the self-check's verdict.
//! 0. `idle`: waits for interrupts (`board::wait_for_interrupt`: WFI on the real board;
//!    see `board::qemu` for why the emulated boards spin by default).
#![no_std]
#![no_main]
#![deny(missing_docs)]

#[cfg(not(any(feature = "qemu-m4", feature = "qemu-m3", feature = "nucleo-f446re")))]
compile_error!(
    "no board selected: build with exactly one of the features `qemu-m4` (default), \
     `qemu-m3` or `nucleo-f446re` (e.g. `--no-default-features --features qemu-m3`)"
);

#[cfg(any(
    all(feature = "qemu-m4", feature = "qemu-m3"),
    all(feature = "qemu-m4", feature = "nucleo-f446re"),
    all(feature = "qemu-m3", feature = "nucleo-f446re"),
))]
compile_error!(
    "two boards selected: enable exactly one of `qemu-m4`, `qemu-m3`, `nucleo-f446re` \
     (add `--no-default-features` when choosing a board other than `qemu-m4`)"
);

mod board;
mod control;
mod run;
mod timing;

#[rtic::app(device = crate::board::pac, dispatchers = [CAN1_RX0, CAN1_RX1])]
mod app {
    use crate::board;
    use crate::control::ControlLoop;
    use crate::run::{IdleMode, RunConfig, SelfCheck};
    use crate::timing::{self, SecondReport, TickAccounting};
    use cortex_m::peripheral::{SCB, SYST};

    #[shared]
    struct Shared {}

    #[local]
    struct Local {
        control: ControlLoop,
        accounting: TickAccounting,
        board_clock: board::IndependentClock,
        run: RunConfig,
        self_check: SelfCheck,
        idle_mode: IdleMode,
        panic_at_tick: Option<u32>,
    }

    #[init]
    fn init(cx: init::Context) -> (Shared, Local) {
        let mut core = cx.core;
        let parts = board::init(cx.device);
        let run = board::run_config();
        timing::start_systick(&mut core.SYST, board::SYSCLK_HZ);
        defmt::info!(
            "vsa firmware {=str} on {=str}: sysclk {=u32} Hz, control loop {=u32} Hz, run {=u32} s (0 = forever), idle {}",
            env!("CARGO_PKG_VERSION"),
            board::NAME,
            board::SYSCLK_HZ,
            timing::CONTROL_HZ,
            run.seconds.unwrap_or(0),
            run.idle,
        );
        (
            Shared {},
            Local {
                control: ControlLoop::new(),
                accounting: TickAccounting::new(),
                board_clock: parts.clock,
                idle_mode: run.idle,
                panic_at_tick: run.panic_at_tick,
                run,
                self_check: SelfCheck::new(),
            },
        )
    }

    /// The 1 kHz control period, at the highest priority.
    #[task(binds = SysTick, priority = 3, local = [control, accounting, board_clock, panic_at_tick])]
    fn control_tick(cx: control_tick::Context) {
        let start = SYST::get_current();
        let tick = cx.local.accounting.ticks() + 1;
        if *cx.local.panic_at_tick == Some(tick) {
            panic!("injected panic at tick {}", tick);
        }
        let now_us = cx.local.board_clock.now_us();
        cx.local.control.tick();
        let busy_counts = timing::systick_elapsed(start, SYST::get_current(), board::SYSCLK_HZ);
        // SysTick pending again while we still run it: the next period has already begun.
        let overrun = SCB::is_pendst_pending();
        timing::publish_tick(tick);
        if let Some(report) = cx.local.accounting.on_tick(now_us, overrun, busy_counts) {
            if telemetry::spawn(report).is_err() {
                cx.local.accounting.note_dropped_report();
            }
        }
    }

    /// Once-a-second log line, and the end of an emulated run.
    #[task(priority = 1, local = [run, self_check])]
    async fn telemetry(cx: telemetry::Context, report: SecondReport) {
        defmt::info!(
            "second {=u32}: {=u32} ticks, {=u32} overruns, tick busy max {=u32} sysclk cycles, {=u32} reports dropped",
            report.second,
            report.ticks,
            report.overruns,
            report.busy_max_counts,
            report.dropped_reports,
        );
        cx.local.self_check.record(&report);
        if cx.local.run.is_last_second(report.second) {
            let verdict = cx.local.self_check.verdict();
            if verdict.passed() {
                defmt::info!(
                    "self-check passed: {=u32} s, {=u32} ticks/s in every second, 0 overruns",
                    verdict.seconds,
                    timing::CONTROL_HZ
                );
            } else {
                defmt::error!(
                    "self-check FAILED: {=u32} s, ticks/s min {=u32} max {=u32}, {=u32} overruns",
                    verdict.seconds,
                    verdict.min_ticks,
                    verdict.max_ticks,
                    verdict.overruns
                );
            }
            board::exit(verdict.passed());
        }
    }

    #[idle(local = [idle_mode])]
    fn idle(cx: idle::Context) -> ! {
        loop {
            board::wait_for_interrupt(*cx.local.idle_mode);
        }
    }
}
