//! `vsa-control-only`: the firmware's 1 kHz control loop and host link without the
//! simulated actuator, for the footprint of the control firmware on an emulated board
//! (`cargo xtask bench`).
//!
//! The same parts as `vsa-firmware` minus the plant and the scenario harness: RTIC 2 with
//! the SysTick-bound control task at priority 3 (sensors through the driver traits →
//! `Servo::tick` → H-bridge driver, missed-deadline check, telemetry sample), the host
//! link (USART2 receive interrupt at priority 2, the firmware library's driver; the protocol
//! handler and command service in a priority-1 task, `service::link`), a bounded log queue
//! drained by a priority-1 task into defmt (faults, a once-a-second report), defmt over
//! semihosting.
//! The sensors read what `READINGS` holds (mid-scale: the actuator at rest), so
//! the servo holds still. At boot, `init` queues a few host requests as if they had
//! arrived on USART2, handled from the tenth tick on (`SCRIPT`: stiffness, limits, gains, enable, a move, telemetry at
//! 500 Hz), so that the link task's command path (the configuration maths) and the
//! telemetry run and count in the stack's high-water mark; after two seconds the run ends
//! with exit status 0.
#![no_std]
#![no_main]
#![deny(missing_docs)]

/// Link encoder, gear pot, current ADC and supply sense readings the simulated channels
/// present (read with volatile loads, as from a peripheral, so they are not constants to
/// the compiler).
static READINGS: [u16; 4] = [
    0,
    firmware::board::POT_AT_REST,
    model::sensors::ADC_MID,
    firmware::board::SUPPLY_AT_REST,
];

/// Reading `i` of [`READINGS`].
fn reading(i: usize) -> u16 {
    match READINGS.get(i) {
        // SAFETY: a valid, aligned reference to an immutable static.
        Some(r) => unsafe { core::ptr::read_volatile(r) },
        None => 0,
    }
}

/// The host requests queued at boot, as frames on the wire (see the module docs): the
/// number of requests, then their frames, encoded by `build.rs`.
static SCRIPT: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/script.bin"));

/// The number of requests in [`SCRIPT`].
fn script_requests() -> u32 {
    SCRIPT.first().copied().map_or(0, u32::from)
}

/// Seconds to run.
const RUN_SECONDS: u32 = 2;

/// What the control task hands to the log task.
enum LogItem {
    Fault(model::supervisor::Fault),
    Second { second: u32, overruns: u32 },
}

#[rtic::app(device = firmware::board::pac, dispatchers = [CAN1_RX0])]
mod app {
    use super::{reading, LogItem, RUN_SECONDS};
    use cortex_m::peripheral::{syst::SystClkSource, NVIC, SCB};
    use firmware::board::{self, Io};
    use firmware::timing::CONTROL_HZ;
    use heapless::spsc::{Consumer, Producer, Queue};
    use model::control::{Command, Config};
    use model::servo::{BridgeDemand, Servo};
    use model::supervisor::SupervisorConfig;
    use model::{Design, Length};
    use service::link::{Link, Sample, RX_QUEUE, TELEMETRY_QUEUE};
    use service::{Actuator, Service};

    #[shared]
    struct Shared {
        actuator: Actuator,
    }

    #[local]
    struct Local {
        io: Io,
        link: Link<'static, board::SerialTx>,
        serial_rx: board::SerialRx,
        rx_tx: Producer<'static, u8>,
        telemetry_tx: Producer<'static, Sample>,
        ticks: u32,
        overruns: u32,
        log_tx: Producer<'static, LogItem>,
        log_rx: Consumer<'static, LogItem>,
    }

    #[init(local = [
        queue: Queue<LogItem, 16> = Queue::new(),
        rx_queue: Queue<u8, RX_QUEUE> = Queue::new(),
        telemetry_queue: Queue<Sample, TELEMETRY_QUEUE> = Queue::new(),
    ])]
    fn init(cx: init::Context) -> (Shared, Local) {
        firmware::stack::paint();
        let mut syst = cx.core.SYST;
        let design = Design::paper();
        let config = Config::paper(Length::from_int(3));
        let mut servo = match Servo::new(&design, &config, &SupervisorConfig::DEFAULT) {
            Ok(s) => s,
            Err(e) => defmt::panic!("servo rejected: {}", e),
        };
        if servo.enable().is_err() || servo.command(Command::Hold).is_err() {
            defmt::panic!("servo refused to enable");
        }
        let io = board::at_rest();
        let (log_tx, log_rx) = cx.local.queue.split();
        let (rx_tx, rx_rx) = cx.local.rx_queue.split();
        let (telemetry_tx, telemetry_rx) = cx.local.telemetry_queue.split();
        let (serial_rx, serial_tx) = board::Serial::start(cx.device.USART2, board::USART_BRR);
        let service = Service::new(design, config, SupervisorConfig::DEFAULT);
        let mut rx_tx = rx_tx;
        for &b in crate::SCRIPT.get(1..).unwrap_or(&[]) {
            let _ = rx_tx.enqueue(b);
        }
        // The link task takes them once running: `control_tick` pends it at tick 1.

        syst.set_clock_source(SystClkSource::Core);
        syst.set_reload(board::SYSCLK_HZ / CONTROL_HZ - 1);
        syst.clear_current();
        syst.enable_interrupt();
        syst.enable_counter();
        defmt::info!(
            "vsa control-only on {=str}: sysclk {=u32} Hz",
            board::NAME,
            board::SYSCLK_HZ
        );
        (
            Shared {
                actuator: Actuator::new(servo),
            },
            Local {
                io,
                link: Link::new(service, rx_rx, telemetry_rx, serial_tx),
                serial_rx,
                rx_tx,
                telemetry_tx,
                ticks: 0,
                overruns: 0,
                log_tx,
                log_rx,
            },
        )
    }

    /// The 1 kHz control period.
    #[task(binds = SysTick, priority = 3, shared = [actuator], local = [io, ticks, overruns, log_tx, telemetry_tx])]
    fn control_tick(mut cx: control_tick::Context) {
        let io = cx.local.io;
        let overruns = cx.local.overruns;
        let telemetry_tx = cx.local.telemetry_tx;
        io.present(reading(0), reading(1), reading(2), reading(3));
        let (fault, sampled) = cx.shared.actuator.lock(|a| {
            let raw = io.read_inputs();
            let out = a.tick(&raw);
            let input = *a.pipeline.input();
            io.drive(out.bridge);
            let mut fault = out.new_fault;
            if SCB::is_pendst_pending() {
                *overruns += 1;
                if let Some(f) = a.servo.deadline_missed(0) {
                    io.drive(BridgeDemand::Off);
                    fault = fault.or(Some(f));
                }
            }
            let sampled = a.publish_tick(&input, &out, telemetry_tx);
            (fault, sampled)
        });
        // Tick 10: the requests queued at boot reach the link task (well after `idle`
        // started, so their stack counts as running, not boot: `init` can take longer than
        // a period, and the first tick then comes before `idle`).
        if sampled || *cx.local.ticks == 9 {
            NVIC::pend(board::pac::Interrupt::EXTI1);
        }
        *cx.local.ticks += 1;
        let tx = cx.local.log_tx;
        if let Some(f) = fault {
            let _ = tx.enqueue(LogItem::Fault(f));
        }
        if cx.local.ticks.is_multiple_of(CONTROL_HZ) {
            let _ = tx.enqueue(LogItem::Second {
                second: *cx.local.ticks / CONTROL_HZ,
                overruns: *overruns,
            });
        }
        if !tx.is_empty() {
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

    /// The host link: commands in, replies and telemetry out.
    #[task(binds = EXTI1, priority = 1, shared = [actuator], local = [link])]
    fn serial(mut cx: serial::Context) {
        let link = cx.local.link;
        let before = link.requests();
        link.poll(&mut cx.shared.actuator);
        let script = crate::script_requests();
        if before < script && link.requests() >= script {
            let refused = link.errors().total();

            defmt::info!(
                "host link: the {=u32} queued requests handled, {=u32} refused",
                link.requests(),
                refused
            );
        }
    }

    /// Writes the queued items to defmt; ends the run after `RUN_SECONDS`.
    #[task(priority = 1, local = [log_rx])]
    async fn log(cx: log::Context) {
        while let Some(item) = cx.local.log_rx.dequeue() {
            match item {
                LogItem::Fault(f) => defmt::error!(
                    "FAULT {=str} (code {=u8}): value {=i32} at tick {=u32}; motor disabled",
                    f.code.name(),
                    f.code as u8,
                    f.value,
                    f.tick
                ),
                LogItem::Second { second, overruns } => {
                    defmt::info!("second {=u32}: {=u32} overruns", second, overruns);
                    if second >= RUN_SECONDS {
                        firmware::stack::log_high_water();
                        board::exit(overruns == 0);
                    }
                }
            }
        }
    }

    #[idle]
    fn idle(_: idle::Context) -> ! {
        firmware::stack::repaint_after_init();
        loop {
            cortex_m::asm::nop();
        }
    }
}
