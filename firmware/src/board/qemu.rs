//! The emulated boards: QEMU `netduinoplus2` (STM32F405, Cortex-M4F, `qemu-m4`) and
//! `netduino2` (STM32F205, Cortex-M3, `qemu-m3`).
//!
//! QEMU does not emulate RCC, GPIO or the flash controller of these SoCs, so nothing
//! here waits on a clock-ready bit: the core runs at the machine's fixed SYSCLK and
//! QEMU clocks the general-purpose timers TIM2–5 from a fixed 1 GHz input whatever
//! RCC says. defmt frames leave through semihosting (`defmt-semihosting`); the run's
//! arguments arrive through semihosting too, and so does the exit status.
//!
//! The host link is USART2, QEMU's *second* `-serial` device (`-serial null -serial
//! tcp:…`): the receive interrupt works (`RXNEIE`), and transmission is immediate.
//!
//! # Serving the host protocol (`--serve`)
//!
//! A board that talks to a host must keep time with it (heartbeats every ≤ 100 ms of the
//! board's time are sent in real time). It runs under `-icount shift=3,sleep=on,align=on`
//! and keeps spinning when idle: virtual time is still the instruction count (8 ns each),
//! and QEMU sleeps whenever the guest runs ahead of real time. With WFI and `sleep=on`,
//! virtual time instead jumps to real time after every idle period, and a jump past a
//! SysTick period looks like a missed deadline to the control tick (measured: a
//! `deadline-missed` fault within 220 ticks).
//!
//! # Idle: spin, not WFI
//!
//! Under QEMU 7.2 with `-icount shift=3,sleep=off`, a core sleeping in WFI is woken by
//! SysTick only every *second* period: measured against TIM2 (an independent virtual-time
//! clock), the 1 kHz loop then runs 500 ticks per emulated second, at every icount shift
//! tried (0–7); with `sleep=on` it runs 1000 but is no longer deterministic. The emulated
//! boards therefore idle in a spin loop by default, which keeps both the rate and the
//! determinism. Reproduce with `cargo xtask run --idle wfi` (the self-check fails).

use super::semihosting_exit::exit;
use super::sim::{SimulatedIo, Simulation};
use super::{Board, IndependentClock, Parts, Serial};
use crate::run_config::{IdleMode, RunConfig};

#[cfg(feature = "qemu-m4")]
pub use stm32f4::stm32f405 as pac;

#[cfg(feature = "qemu-m3")]
pub use stm32f2::stm32f215 as pac;

/// USART2's baud-rate divider. QEMU's STM32F2xx USART model ignores it (bytes move at the
/// speed of its character device, here a TCP socket); the value is 115 200 Bd at the
/// F405's 42 MHz APB1 for the record.
pub const USART_BRR: u16 = 365;

/// Input clock of QEMU's STM32F2xx/F4xx TIM2–5 model, Hz.
const QEMU_TIMER_INPUT_HZ: u32 = 1_000_000_000;

/// The emulated board the features selected.
pub struct Qemu;

impl Board for Qemu {
    #[cfg(feature = "qemu-m4")]
    const NAME: &'static str = "qemu-m4 (QEMU netduinoplus2, STM32F405, Cortex-M4F)";
    #[cfg(feature = "qemu-m3")]
    const NAME: &'static str = "qemu-m3 (QEMU netduino2, STM32F205, Cortex-M3)";

    /// Fixed by the QEMU machine.
    #[cfg(feature = "qemu-m4")]
    const SYSCLK_HZ: u32 = 168_000_000;
    /// Fixed by the QEMU machine.
    #[cfg(feature = "qemu-m3")]
    const SYSCLK_HZ: u32 = 120_000_000;

    type Io = SimulatedIo;
    type Hooks = &'static mut Simulation;

    /// Reads the run's options from the semihosting command line (`-semihosting-config
    /// arg=…`); the first argument is the program name.
    fn run_config() -> RunConfig {
        let Ok(args) = semihosting::experimental::env::args::<256>() else {
            defmt::warn!("no semihosting command line; running the default time");
            return RunConfig::new(IdleMode::Spin);
        };
        let words = (&args).skip(1).map_while(Result::ok);
        match RunConfig::parse(words, IdleMode::Spin) {
            Ok(config) => config,
            Err(error) => {
                defmt::error!("bad run arguments: {}", error);
                exit(false)
            }
        }
    }

    /// Brings up what the emulated board has, and the simulated actuator running `run`'s
    /// scenario (or serving the host).
    fn init(device: pac::Peripherals, run: &RunConfig) -> Parts<Self> {
        let prescaler = (QEMU_TIMER_INPUT_HZ / 1_000_000 - 1) as u16;
        let (hooks, servo, service) = if run.serve {
            Simulation::serve(run.serve_load_mnm)
        } else {
            Simulation::new(run.scenario)
        };
        let (serial_rx, serial_tx) = Serial::start(device.USART2, USART_BRR);
        Parts {
            clock: IndependentClock::start(device.TIM2, prescaler),
            io: super::sim::at_rest(),
            hooks,
            servo,
            service,
            serial_rx,
            serial_tx,
        }
    }

    fn exit(passed: bool) -> ! {
        exit(passed)
    }
}

/// How a panic or HardFault ends on the emulated boards, once the bridge is off and the
/// report is out: QEMU exits with failure.
pub fn halt_after_fault() -> ! {
    exit(false)
}
