//! The real board: ST Nucleo-F446RE (STM32F446RE, Cortex-M4F), flashed and logged with
//! probe-rs over the on-board ST-LINK (`cargo xtask flash`), defmt over RTT.
//!
//! # Pins
//!
//! The one table of what is wired where. Drivers of the later issues use exactly these.
//!
//! | function                        | pin  | peripheral           | Nucleo header |
//! |---------------------------------|------|----------------------|---------------|
//! | H-bridge PWM (IN1)              | PA8  | TIM1_CH1, AF1, 20 kHz| CN9 D7        |
//! | H-bridge direction (IN2/PHASE)  | PA9  | GPIO out             | CN5 D8        |
//! | H-bridge enable (EN / nSLEEP)   | PA10 | GPIO out, low = off  | CN9 D2        |
//! | link encoder A                  | PA6  | TIM3_CH1, AF2 (QEI)  | CN5 D12       |
//! | link encoder B                  | PA7  | TIM3_CH2, AF2 (QEI)  | CN5 D11       |
//! | motor current sense             | PA0  | ADC1_IN0             | CN8 A0        |
//! | gear-side potentiometer         | PA1  | ADC1_IN1             | CN8 A1        |
//! | host link TX (USB VCP)          | PA2  | USART2_TX, AF7       | ST-LINK VCP   |
//! | host link RX (USB VCP)          | PA3  | USART2_RX, AF7       | ST-LINK VCP   |
//! | independent µs clock            | –    | TIM2 (internal)      | –             |
//! | watchdog                        | –    | IWDG (LSI)           | –             |
//!
//! Clocks: 8 MHz HSE bypass from the ST-LINK's MCO → PLL → 180 MHz SYSCLK, APB1 45 MHz
//! (timers 90 MHz), APB2 90 MHz (timers 180 MHz).

use super::{IndependentClock, Parts};
use crate::run::{IdleMode, RunConfig};
use defmt_rtt as _;
use panic_probe as _;
use stm32f4xx_hal::{prelude::*, rcc::Config, timer::FTimerUs};

pub use stm32f4xx_hal::pac;

/// Board name as logged at boot.
pub const NAME: &str = "nucleo-f446re (STM32F446RE, Cortex-M4F)";

/// Core clock, Hz.
pub const SYSCLK_HZ: u32 = 180_000_000;

/// Sets the clocks and starts the independent µs clock.
pub fn init(device: pac::Peripherals) -> Parts {
    let mut rcc = device.RCC.freeze(
        Config::hse(8.MHz())
            .bypass_hse_oscillator()
            .sysclk(SYSCLK_HZ.Hz())
            .pclk1(45.MHz())
            .pclk2(90.MHz()),
    );
    // FTimerUs enables TIM2 and computes the 1 MHz prescaler from the frozen clocks;
    // the free-running 32-bit count is then set up like on every board.
    let tim2 = FTimerUs::new(device.TIM2, &mut rcc).release();
    let prescaler = tim2.psc().read().psc().bits();
    Parts {
        clock: IndependentClock::start(tim2, prescaler),
    }
}

/// The real board runs until it is reset.
pub fn run_config() -> RunConfig {
    RunConfig {
        seconds: None,
        idle: IdleMode::Wfi,
        panic_at_tick: None,
    }
}

/// There is nowhere to exit to: report the verdict and keep running.
pub fn exit(passed: bool) -> ! {
    defmt::info!("run finished (passed: {=bool}); halting", passed);
    loop {
        cortex_m::asm::wfi();
    }
}

/// panic-probe reports defmt panics too.
#[defmt::panic_handler]
fn defmt_panic() -> ! {
    panic_probe::hard_fault()
}
