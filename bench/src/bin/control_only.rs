//! `vsa-control-only`: the firmware's 1 kHz control loop without the simulated actuator,
//! for the footprint of the control code on an emulated board (`cargo xtask bench`).
//!
//! The same parts as `vsa-firmware` minus the plant and the scenario harness: RTIC 2 with
//! the SysTick-bound control task at priority 3 (sensors through the driver traits →
//! `Servo::tick` → H-bridge driver, missed-deadline check), a bounded log queue drained by
//! a priority-1 task into defmt (faults, a once-a-second report), defmt over semihosting.
//! The sensors read what `READINGS` holds (mid-scale: the actuator at rest), so
//! the servo holds still; after two seconds the run ends with exit status 0.
#![no_std]
#![no_main]
#![deny(missing_docs)]

/// Link encoder, gear pot and current ADC readings the simulated channels present (read
/// with volatile loads, as from a peripheral, so they are not constants to the compiler).
static READINGS: [u16; 3] = [0, 512, 2048];

/// Reading `i` of [`READINGS`].
fn reading(i: usize) -> u16 {
    match READINGS.get(i) {
        // SAFETY: a valid, aligned reference to an immutable static.
        Some(r) => unsafe { core::ptr::read_volatile(r) },
        None => 0,
    }
}

/// Control loop rate, Hz.
const CONTROL_HZ: u32 = 1000;
/// Seconds to run.
const RUN_SECONDS: u32 = 2;

/// What the control task hands to the log task.
enum LogItem {
    Fault(model::supervisor::Fault),
    Second { second: u32, overruns: u32 },
}

#[rtic::app(device = bench::board::pac, dispatchers = [CAN1_RX0])]
mod app {
    use super::{reading, LogItem, CONTROL_HZ, RUN_SECONDS};
    use bench::board;
    use bench::io::Io;
    use cortex_m::peripheral::{syst::SystClkSource, SCB};
    use heapless::spsc::{Consumer, Producer, Queue};
    use model::control::{Command, Config};
    use model::servo::{BridgeDemand, Servo};
    use model::supervisor::SupervisorConfig;
    use model::{Design, Length};

    #[shared]
    struct Shared {}

    #[local]
    struct Local {
        servo: Servo,
        io: Io,
        ticks: u32,
        overruns: u32,
        log_tx: Producer<'static, LogItem>,
        log_rx: Consumer<'static, LogItem>,
    }

    #[init(local = [queue: Queue<LogItem, 16> = Queue::new()])]
    fn init(cx: init::Context) -> (Shared, Local) {
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
        let Some(io) = Io::new() else {
            defmt::panic!("H-bridge driver refused the lines")
        };
        let (log_tx, log_rx) = cx.local.queue.split();
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
            Shared {},
            Local {
                servo,
                io,
                ticks: 0,
                overruns: 0,
                log_tx,
                log_rx,
            },
        )
    }

    /// The 1 kHz control period.
    #[task(binds = SysTick, priority = 3, local = [servo, io, ticks, overruns, log_tx])]
    fn control_tick(cx: control_tick::Context) {
        let io = cx.local.io;
        io.present(reading(0), reading(1), reading(2));
        let input = io.read_inputs();
        let out = cx.local.servo.tick(&input);
        io.drive(out.bridge);
        let mut fault = out.new_fault;
        if SCB::is_pendst_pending() {
            *cx.local.overruns += 1;
            if let Some(f) = cx.local.servo.deadline_missed(0) {
                io.drive(BridgeDemand::Off);
                fault = fault.or(Some(f));
            }
        }
        *cx.local.ticks += 1;
        let tx = cx.local.log_tx;
        if let Some(f) = fault {
            let _ = tx.enqueue(LogItem::Fault(f));
        }
        if cx.local.ticks.is_multiple_of(CONTROL_HZ) {
            let _ = tx.enqueue(LogItem::Second {
                second: *cx.local.ticks / CONTROL_HZ,
                overruns: *cx.local.overruns,
            });
        }
        if !tx.is_empty() {
            let _ = log::spawn();
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
                        board::exit(overruns == 0);
                    }
                }
            }
        }
    }

    #[idle]
    fn idle(_: idle::Context) -> ! {
        loop {
            cortex_m::asm::nop();
        }
    }
}
