//! `vsa-firmware`: the 1 kHz control loop of the variable-stiffness actuator.
//!
//! One RTIC 2 application for three boards, chosen by a cargo feature (see
//! `firmware::board`): `qemu-m4` (default), `qemu-m3` and `nucleo-f446re`.
//!
//! Priorities (highest first):
//! 3. `control_tick`: hardware task bound to SysTick at 1 kHz. It runs one control period
//!    (`tick::ControlLoop::tick`: board hooks → sensors → servo → H-bridge) and detects a
//!    missed deadline: if SysTick fired again before the task finished, the period overran
//!    (the supervisor latches `deadline-missed` and the motor goes off). Everything to log
//!    goes into a bounded queue, never blocking: a full queue drops and counts. The board's
//!    events of the tick (a scenario's progress) are drained into the same queue.
//! 2. `uart_rx`: hardware task bound to USART2's interrupt: moves each received byte of
//!    the host link into a bounded queue (a full queue loses the byte: its frame then fails
//!    its CRC, and the protocol handler counts it and gives an error reply) and pends
//!    `serial`.
//! 1. `serial`: hardware task bound to EXTI1, pended by software (no EXTI line is used):
//!    the host link (`service::link::Link`): decodes the protocol, applies each command to the
//!    shared actuator under a lock — between two ticks — and answers; sends the telemetry
//!    the control tick queued (a full queue drops the sample and counts it, never
//!    blocking the tick). A pended interrupt runs again if pended while running, so no
//!    byte waits for a later wake-up.
//! 1. `log`: drains the queue into defmt: faults, the once-a-second timing report, and on
//!    the emulated boards the scenario's events, results and final verdict (then QEMU
//!    exits with it).
//! 0. `idle`: waits for interrupts (`board::wait_for_interrupt`: WFI on the real board;
//!    see `board::qemu` for why the emulated boards spin by default).
#![no_std]
#![no_main]
#![deny(missing_docs)]

// The log's timestamp: µs since SysTick started.
defmt::timestamp!("{=u64:us}", firmware::timing::uptime_us());

#[rtic::app(device = firmware::board::pac, dispatchers = [CAN1_RX0, CAN1_RX1])]
mod app {
    use cortex_m::peripheral::{NVIC, SYST};
    use firmware::board::{self, Board, Hooks, Selected, TickHooks};
    use firmware::report::{LogItem, Reporter};
    use firmware::run_config::{IdleMode, RunConfig};
    use firmware::tick::ControlLoop;
    use firmware::timing::{self, TickAccounting};
    use heapless::spsc::{Consumer, Producer, Queue};
    use service::link::{DynamixelStats, Link, Sample, RX_QUEUE, TELEMETRY_QUEUE};
    use service::Actuator;

    /// Items waiting for the log task (a tick's worth of events several times over).
    const LOG_QUEUE: usize = 16;

    #[shared]
    struct Shared {
        /// The servo and telemetry state: the control tick's, and the link task's under
        /// a lock.
        actuator: Actuator,
    }

    #[local]
    struct Local {
        control: ControlLoop,
        accounting: TickAccounting,
        board_clock: board::IndependentClock,
        injection: Option<firmware::fail_safe::Injection>,
        log_tx: Producer<'static, LogItem>,
        log_rx: Consumer<'static, LogItem>,
        dropped: u32,
        reporter: Reporter,
        idle_mode: IdleMode,
        link: Link<'static, board::SerialTx>,
        serial_rx: board::SerialRx,
        rx_tx: Producer<'static, u8>,
        telemetry_tx: Producer<'static, Sample>,
    }

    #[init(local = [
        queue: Queue<LogItem, LOG_QUEUE> = Queue::new(),
        rx_queue: Queue<u8, RX_QUEUE> = Queue::new(),
        telemetry_queue: Queue<Sample, TELEMETRY_QUEUE> = Queue::new(),
        settings_flash: board::SettingsFlash = board::SETTINGS_FLASH,
        settings: Option<board::SettingsStore> = None,
    ])]
    fn init(cx: init::Context) -> (Shared, Local) {
        firmware::stack::paint();
        let mut core = cx.core;
        let run: RunConfig = Selected::run_config();
        let dxl_id = run.dxl_id;
        let parts = Selected::init(cx.device, &run);
        let (log_tx, log_rx) = cx.local.queue.split();
        let (rx_tx, rx_rx) = cx.local.rx_queue.split();
        let (telemetry_tx, telemetry_rx) = cx.local.telemetry_queue.split();
        defmt::info!(
            "vsa firmware {=str} on {=str}: sysclk {=u32} Hz, control loop {=u32} Hz, idle {}",
            env!("CARGO_PKG_VERSION"),
            board::NAME,
            board::SYSCLK_HZ,
            timing::CONTROL_HZ,
            run.idle,
        );
        defmt::info!(
            "host link: USART2, protocol version {=u8}",
            protocol::VERSION
        );
        let mut actuator = Actuator::new(parts.servo);
        let mut service = parts.service;
        let storage = board::open_settings(cx.local.settings_flash, cx.local.settings, &run);
        firmware::settings::boot(&mut service, &mut actuator, storage, run.serves());
        // Last: loading and preparing the stored settings takes longer than a period.
        timing::start_systick(&mut core.SYST, board::SYSCLK_HZ);
        (
            Shared { actuator },
            Local {
                control: ControlLoop::new(parts.io, parts.hooks),
                accounting: TickAccounting::new(),
                board_clock: parts.clock,
                injection: run.injection,
                log_tx,
                log_rx,
                dropped: 0,
                idle_mode: run.idle,
                reporter: Reporter::new(run),
                link: firmware::bus::serve(
                    Link::new(service, rx_rx, telemetry_rx, parts.serial_tx),
                    dxl_id,
                ),
                serial_rx: parts.serial_rx,
                rx_tx,
                telemetry_tx,
            },
        )
    }

    /// The 1 kHz control period, at the highest priority.
    #[task(binds = SysTick, priority = 3, shared = [actuator], local = [control, accounting, board_clock, injection, log_tx, dropped, telemetry_tx])]
    fn control_tick(mut cx: control_tick::Context) {
        let entry = SYST::get_current();
        let tick = cx.local.accounting.ticks() + 1;
        firmware::fail_safe::inject(*cx.local.injection, tick);
        let now_us = cx.local.board_clock.now_us();
        let control = &mut *cx.local.control;
        let telemetry_tx = cx.local.telemetry_tx;
        // The highest priority: the lock costs nothing and the link task never holds it
        // across a tick.
        let result = cx
            .shared
            .actuator
            .lock(|actuator| control.tick(entry, actuator, telemetry_tx));
        // Every tick, not only when a telemetry sample was queued or a fault latched: the
        // link task also notices an idle Dynamixel line (`firmware::bus`) and logs faults
        // to the stored fault log.
        NVIC::pend(board::pac::Interrupt::EXTI1);
        timing::publish_tick(tick);

        let tx = cx.local.log_tx;
        let dropped_so_far = *cx.local.dropped;
        let dropped = cx.local.dropped;
        let mut push = |item: LogItem| {
            if tx.enqueue(item).is_err() {
                *dropped = dropped.saturating_add(1);
            }
        };
        // The board's events of this tick (an injection) before the fault they cause; after
        // the run's last one, the cost accounting.
        let control = cx.local.control;
        while let Some(event) = control.hooks_mut().pop_event() {
            let last = Hooks::ends_run(&event);
            push(LogItem::Board(event));
            if let Some(costs) = last.then(|| LogItem::costs(control.stats())).flatten() {
                push(costs);
            }
        }
        if let Some(fault) = result.fault {
            push(LogItem::Fault(fault));
        }
        if let Some(mut report) =
            cx.local
                .accounting
                .on_tick(now_us, result.overran, result.busy_counts)
        {
            report.dropped_reports = dropped_so_far;
            push(LogItem::Second(report));
        }
        if !tx.is_empty() {
            // Already pending or running: it drains everything queued when it runs.
            let _ = log::spawn();
        }
    }

    // The host link's two tasks, declared by each program that serves it (an RTIC app
    // declares its own tasks; their work is the library's): `duplicates` pairs them.

    /// The host link's receive interrupt: queue the bytes, wake the link task.
    #[task(binds = USART2, priority = 2, local = [serial_rx, rx_tx])]
    fn uart_rx(cx: uart_rx::Context) {
        cx.local.serial_rx.receive_into(cx.local.rx_tx);
        NVIC::pend(board::pac::Interrupt::EXTI1);
    }

    /// The host link: commands in, replies and telemetry out (see `link`).
    #[task(binds = EXTI1, priority = 1, shared = [actuator], local = [link, uart_bps: u32 = 0, bus_logged: DynamixelStats = DynamixelStats::NONE])]
    fn serial(mut cx: serial::Context) {
        cx.local.link.poll(&mut cx.shared.actuator);
        firmware::bus::follow_baud(cx.local.link, cx.local.uart_bps);
        firmware::bus::log_losses(cx.local.link, cx.local.bus_logged);
    }

    /// Writes the queued items to defmt (and ends an emulated run).
    #[task(priority = 1, local = [log_rx, reporter])]
    async fn log(cx: log::Context) {
        while let Some(item) = cx.local.log_rx.dequeue() {
            cx.local.reporter.log(item);
        }
    }

    #[idle(local = [idle_mode])]
    fn idle(cx: idle::Context) -> ! {
        firmware::stack::repaint_after_init();
        loop {
            board::wait_for_interrupt(*cx.local.idle_mode);
        }
    }
}
