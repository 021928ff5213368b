//! The real board: ST Nucleo-F446RE (STM32F446RE, Cortex-M4F), flashed and logged with
//! probe-rs over the on-board ST-LINK (`cargo xtask flash`), defmt over RTT.
//!
//! # Pins
//!
//! The one table of what is wired where. The drivers in [`Io`] use exactly these.
//!
//! The bridge is sign-magnitude: one PWM input (magnitude), one phase input (direction),
//! one enable; a DRV8874 in PH/EN mode (PMODE low) takes these three signals as they are.
//! An IN1/IN2 bridge (L298 inputs, DRV8871, TB6612 without an inverter) does not: wired by
//! pin order it drives reverse duties inverted (docs/real-board.md).
//!
//! | function                                 | pin  | peripheral                       | Nucleo header |
//! |------------------------------------------|------|----------------------------------|---------------|
//! | bridge PWM → DRV8874 EN (magnitude)      | PA8  | TIM1_CH1, AF1, 20 kHz            | CN9 D7        |
//! | bridge phase → DRV8874 PH (direction)    | PA9  | GPIO out, push-pull, high = +    | CN5 D8        |
//! | bridge enable → DRV8874 nSLEEP           | PA10 | GPIO out, push-pull, low = off   | CN9 D2        |
//! | link encoder A                           | PA6  | TIM3_CH1, AF2 (QEI), pull-up     | CN5 D12       |
//! | link encoder B                           | PA7  | TIM3_CH2, AF2 (QEI), pull-up     | CN5 D11       |
//! | motor current sense                      | PA0  | ADC1_IN0 (injected, TIM1 CC4)    | CN8 A0        |
//! | gear-side potentiometer                  | PA1  | ADC1_IN1                         | CN8 A1        |
//! | bridge supply sense (1 : 6.2 divider; `supply-sense` builds) | PA4  | ADC1_IN4          | CN8 A2        |
//! | host link TX (USB VCP)                   | PA2  | USART2_TX, AF7                   | ST-LINK VCP   |
//! | host link RX (USB VCP)                   | PA3  | USART2_RX, AF7, DMA1 stream 5    | ST-LINK VCP   |
//! | or (`dynamixel-ttl`) Dynamixel data      | PA2  | USART2 half duplex, AF7, open drain | CN10 35 (SB13/SB14 open, docs/dynamixel.md) |
//! | independent µs clock                     | –    | TIM2 (internal)                  | –             |
//! | current-sense trigger                    | –    | TIM1 CH4 (internal, no pin)      | –             |
//! | watchdog                                 | –    | IWDG (LSI), 80 ms                | –             |
//!
//! From reset until `init` configures them (and again after any reset) the pins are floating
//! inputs: the bridge board must hold its EN (PWM) and nSLEEP inputs low with pull-downs of
//! its own (the DRV8874 has internal pull-downs on both).
//!
//! # Clocks
//!
//! 8 MHz HSE bypass from the ST-LINK's MCO → PLL → 180 MHz SYSCLK (over-drive on), APB1
//! 45 MHz (timers 90 MHz), APB2 90 MHz (timers 180 MHz), ADC 90 MHz / 4 = 22.5 MHz. `init`
//! checks the frozen clocks against these constants, which everything below is derived from.
//! The HSE is given [`HSE_START_TIMEOUT_MS`] to become ready (STM32Cube's
//! `HSE_STARTUP_TIMEOUT`); without it (the ST-LINK's MCO not reaching OSC_IN: UM1724, "OSC
//! clock supply") the PLL runs from the 16 MHz HSI to the same frequencies and a warning is
//! logged: the HSI's ±1 % at 25 °C (datasheet; wider over temperature) then adds to the
//! baud-rate error.
//!
//! # Debugger
//!
//! `init` sets DBGMCU_CR.DBG_SLEEP, so the core's clock keeps running in the idle loop's WFI
//! and probe-rs can attach to the running firmware (otherwise attaching to a sleeping core
//! can fail; `probe-rs … --connect-under-reset` is the other way in).
//!
//! # Peripherals behind the driver traits ([`Io`])
//!
//! - [`MotorPwm`]: TIM1 CH1, edge-aligned PWM mode 1, PSC = 0, ARR = 8999: 180 MHz / 9000 =
//!   20 kHz, duty resolution 1/9000. CCR1 is preloaded (RM0390 requires it in PWM mode), so a
//!   new duty takes effect at the next period; except 0, which forces an update event so
//!   that the output is low at once: [`drivers::HBridge`] relies on "PWM off" having happened
//!   before it flips the direction pin. TIM1 CH4 (no pin) compares at the middle of the
//!   on-time and triggers the current sample ([`CurrentAdc`]).
//! - [`LinkEncoder`]: TIM3 in encoder mode 3 (both edges of both inputs: 1024 lines × 4 =
//!   4096 counts per turn), 16-bit counter wrapping at 65 536 = 16 × 4096, so `CNT mod 4096`
//!   is the angle in either direction through the wrap. Input filter: a level must hold for
//!   8 samples at f_DTS / 16 = 5.625 MHz (1.42 µs) to count, which rejects ringing and
//!   glitches shorter than that and still passes up to ≈ 1.2 M counts/s (each input holds a
//!   level for two counts). Internal pull-ups (≈ 40 kΩ) on A and B: a push-pull output (the
//!   AS5047P's ABI) overrides them, an open-collector one needs them, and an unplugged
//!   encoder reads still rather than counting noise. The ABI output is incremental (no index
//!   wired): counts are relative to the link's position at power-up.
//! - [`GearPot`], [`SupplyAdc`] and [`CurrentAdc`]: ADC1, 12-bit, sample time 56 ADC cycles: (56 + 12) /
//!   22.5 MHz = 3.02 µs per conversion. 56 cycles allow a source impedance up to ≈ 57 kΩ at
//!   12 bits (datasheet R_AIN formula, C_ADC 4 pF, R_ADC 6 kΩ).
//!   The pot and the supply are software-started regular conversions that poll EOC at most
//!   `ADC_POLL_LIMIT` = 1000 times (≥ 7× the polls a conversion needs, ≈ 20–60 µs; an
//!   injected current conversion that interrupts it costs one more conversion time), then
//!   aborts it (ADON off and on, 5 µs to stabilise) and returns [`SensorError::Timeout`]:
//!   never hangs, never panics. It runs in a critical section (≈ 3 µs with interrupts
//!   masked, each). The supply sense's divider (52.3 kΩ over 10 kΩ, 8.4 kΩ source) reads
//!   [`model::sensors::SUPPLY_MV_PER_COUNT`] mV a count (0.4 % low with these values:
//!   the sense's gain error, docs/design.md §11). The HAL's `Adc::convert` spins on STRT
//!   and EOC without bound (and panics if no conversion started), so ADC1 is driven through
//!   the PAC.
//!   The current is an injected conversion triggered by TIM1's CC4 event in every PWM
//!   period, at the middle of the on-time less half the sampling window, so it reads the
//!   average of the current ripple and does not jump with the phase of the tick in the
//!   period or at a reversal. The tick reads the latest result (at most one PWM period,
//!   50 µs, old); no new result since the last tick (1 ms = 20 periods) is
//!   [`SensorError::Timeout`]. Short on-times: [`CURRENT_SAMPLE_LEAD_TICKS`]. The sensor
//!   expected (docs/real-board.md): bidirectional, in series with the motor, 0 A at
//!   mid-scale, [`model::sensors::ADC_COUNTS_PER_A`] counts/A.
//! - [`Watchdog`]: the independent watchdog, LSI / 32 (1 ms per count at the nominal 32 kHz),
//!   reload 79: 80 ms nominal, 54–151 ms over the LSI's 17–47 kHz datasheet range. The
//!   1 kHz tick feeds it ([`TickHooks::before_step`]); a loop that stalls (a tick that never
//!   returns, SysTick no longer firing, interrupts masked, a panic or HardFault after its
//!   report) stops feeding it and the IWDG resets the MCU, which puts every pin back
//!   to a floating input (bridge off through its pull-downs). The next boot logs that the
//!   reset came from the watchdog. It is started last in `init`, so init's own work
//!   is not counted; the first tick follows 1 ms after RTIC's init returns. The same hook
//!   pends the USART2 interrupt when the receive ring holds bytes not yet drained
//!   ([`super::serial::rx_waiting`]).
//! - Host link: USART2 receives by DMA into a 256-byte ring (see [`super::serial`]): the
//!   DMA empties the data register within a few bus cycles of each byte, so no interrupt
//!   latency (the control tick, the link task's locks) can overrun the receiver; the ring
//!   is drained on an idle line and at least every tick.
//! - Panic and HardFault (`crate::fail_safe`): [`force_bridge_off`] first (TIM1's main
//!   output off and EN low by register writes), then the report; a panic then traps into
//!   HardFault (`udf`, where probe-rs stops and prints the backtrace), and the HardFault
//!   handler waits for the watchdog.
//!
//! defmt-rtt runs in non-blocking mode (its `disable-blocking-mode` feature, whatever mode
//! probe-rs asks for): when the host reads too slowly or is detached, log frames are
//! dropped instead of stalling the 1 kHz loop inside defmt's critical section.
//!
//! With a debugger attached and the core halted, TIM1 stops with its output forced low and
//! the watchdog pauses (DBGMCU freeze bits), so a breakpoint neither drives the motor nor
//! resets the board. Without a debugger the freeze bits have no effect.

use super::serial::{self, RX_RING};
use super::{Board, BridgeOutputs, IndependentClock, Parts, Serial, TickHooks, TickPlan};
use crate::run_config::{IdleMode, RunConfig};
use core::cell::RefCell;
use core::convert::Infallible;
use cortex_m::interrupt::{self, Mutex};
use defmt_rtt as _;
use drivers::tick_io::TickIo;
use drivers::{AngleSensor, CurrentSensor, SensorError, SupplySensor};
use model::control::Config as ControlConfig;
use model::sensors::{ENCODER_COUNTS, POT_COUNTS};
use model::servo::{Servo, TickOutput};
use model::supervisor::{Fault, SupervisorConfig};
use model::{Design, Length};
use stm32f4xx_hal::dma::StreamsTuple;
use stm32f4xx_hal::{
    gpio::{
        Alternate, Analog, Output, PinState, PushPull, PA0, PA1, PA10, PA4, PA6, PA7, PA8, PA9,
    },
    prelude::*,
    qei::Qei,
    rcc::{Config, Enable, Reset},
    timer::FTimerUs,
};

pub use stm32f4xx_hal::pac;

/// Core clock, Hz.
const SYSCLK_HZ: u32 = 180_000_000;

/// APB1 clock, Hz (its timers, TIM2 and TIM3, run at twice this).
const PCLK1_HZ: u32 = 45_000_000;

/// USART2's clock, Hz: PCLK1 (`drivers::usart_baud::divider` makes its rates from it).
pub const USART2_CLOCK_HZ: u32 = PCLK1_HZ;

/// APB2 clock, Hz: ADC1's bus clock.
const PCLK2_HZ: u32 = 90_000_000;

/// TIM1's input clock, Hz: twice PCLK2, since the APB2 prescaler is not 1 (RM0390, RCC
/// clock tree, with TIMPRE = 0).
const TIM1_CLOCK_HZ: u32 = 2 * PCLK2_HZ;

/// H-bridge PWM frequency, Hz.
const PWM_HZ: u32 = 20_000;

/// TIM1 counts per PWM period (PSC = 0): ARR = 8999, duty 0..=9000.
const PWM_PERIOD_TICKS: u16 = (TIM1_CLOCK_HZ / PWM_HZ) as u16;
const _: () = assert!(TIM1_CLOCK_HZ.is_multiple_of(PWM_HZ) && TIM1_CLOCK_HZ / PWM_HZ <= 65_535);

/// ADC clock, Hz: PCLK2 / 4 (ADCPRE = 01); the F446's ADC allows up to 36 MHz at VDDA ≥ 2.4 V.
const ADC_CLOCK_HZ: u32 = PCLK2_HZ / 4;
const _: () = assert!(ADC_CLOCK_HZ <= 36_000_000);

/// ADC1 channel of the motor current sense (PA0).
const CURRENT_CHANNEL: u8 = 0;

/// ADC1 channel of the gear-side potentiometer (PA1).
const POT_CHANNEL: u8 = 1;

/// ADC1 channel of the bridge supply sense (PA4).
const SUPPLY_CHANNEL: u8 = 4;

/// Whether the supply's divider is wired (`supply-sense`): a floating PA4 reads anything,
/// so without it [`SupplyAdc`] reads nothing and the configured supply stays in force.
const SUPPLY_SENSE_FITTED: bool = cfg!(feature = "supply-sense");

/// ADC cycles of one 12-bit conversion: 56 sampling + 12 conversion (RM0390, ADC:
/// conversion time).
const ADC_CONVERSION_CYCLES: u32 = 56 + 12;

/// Core cycles of one conversion (544 at 180 MHz / 22.5 MHz, i.e. 3.02 µs).
const ADC_CONVERSION_CORE_CYCLES: u32 = ADC_CONVERSION_CYCLES * (SYSCLK_HZ / ADC_CLOCK_HZ);

/// EOC polls before a conversion is given up as [`SensorError::Timeout`]. One poll (an APB2
/// load, a test, the loop branch) takes at least 4 core cycles, so a conversion completes
/// within 544 / 4 = 136 polls; the limit leaves a margin of more than 7 and bounds a
/// timeout to ≈ 20–60 µs.
const ADC_POLL_LIMIT: u32 = 1_000;
const _: () = assert!(ADC_POLL_LIMIT >= 7 * ADC_CONVERSION_CORE_CYCLES / 4);

/// Wait after ADON before the first conversion: 5 µs > t_STAB (3 µs max, datasheet).
const ADC_STABILISATION_CORE_CYCLES: u32 = 5 * (SYSCLK_HZ / 1_000_000);

/// How long `init` waits for the HSE (the ST-LINK's 8 MHz MCO) to be ready before it runs
/// from the HSI instead, ms (STM32Cube's `HSE_STARTUP_TIMEOUT`).
const HSE_START_TIMEOUT_MS: u32 = 100;

/// The core's clock from reset until the clock setup: the HSI, Hz.
const HSI_HZ: u32 = 16_000_000;

/// TIM1 counts by which the current sample's trigger leads the middle of the on-time: half
/// the ADC's sampling window (56 ADC cycles × 180 MHz / 22.5 MHz / 2 = 224), so that the
/// window is centred on it. Below twice this (448 counts, 50 ‰ duty) the trigger is at the
/// start of the period and the window reaches into the off-time.
const CURRENT_SAMPLE_LEAD_TICKS: u16 = (56 * (TIM1_CLOCK_HZ / ADC_CLOCK_HZ) / 2) as u16;

/// Link encoder counts per turn (1024 lines × 4 edges).
const LINK_COUNTS_PER_TURN: u16 = ENCODER_COUNTS;
const _: () = assert!(LINK_COUNTS_PER_TURN == 1024 * 4);

/// Host link baud rate, Bd: fast enough for 500 Hz telemetry (≈ 31-byte frames, 15.5 kB/s
/// needs ≥ 155 kBd); the ST-LINK/V2-1 virtual COM port carries it.
pub const LINK_BAUD: u32 = 921_600;

/// USART2's divider at 16× oversampling: PCLK1 / baud = 48.8 → 49 (918 367 Bd, −0.35 %).
const LINK_BRR: u16 = ((PCLK1_HZ + LINK_BAUD / 2) / LINK_BAUD) as u16;

/// Watchdog timeout, ms at the nominal LSI of 32 kHz (LSI / 32 = 1 count per ms).
const WATCHDOG_TIMEOUT_MS: u16 = 80;

/// How long `init` waits for the IWDG to take its prescaler and reload (normally ≈ 0.3 ms;
/// the bound is STM32Cube's: 6 LSI periods at the largest prescaler).
const WATCHDOG_UPDATE_WAIT_MS: u32 = 50;

/// The board's sensors and motor driver, behind the `drivers` traits: the link-side
/// angle (TIM3 quadrature encoder, 4096 counts per turn), the gear-side angle
/// (potentiometer on ADC1, 1024 counts full scale), the motor current (shunt amplifier on
/// ADC1, 12-bit raw), the bridge supply (divider on ADC1, 12-bit raw) and the H-bridge
/// (TIM1 CH1 PWM, direction and enable pins).
pub type Io = TickIo<LinkEncoder, GearPot, CurrentAdc, SupplyAdc, MotorPwm, DirPin, EnPin>;

/// The H-bridge on its PWM channel and pins.
pub type Bridge = drivers::HBridge<MotorPwm, DirPin, EnPin>;

/// H-bridge direction pin (PA9).
pub type DirPin = PA9<Output<PushPull>>;

/// H-bridge enable pin (PA10): low = outputs off.
pub type EnPin = PA10<Output<PushPull>>;

/// The real board.
pub struct Nucleo;

impl Board for Nucleo {
    const NAME: &'static str = "nucleo-f446re (STM32F446RE, Cortex-M4F)";
    const SYSCLK_HZ: u32 = SYSCLK_HZ;
    type Io = Io;
    type Hooks = Watchdog;

    /// The real board runs until it is reset.
    fn run_config() -> RunConfig {
        RunConfig::new(IdleMode::Wfi)
    }

    /// Sets the clocks and brings up the peripherals; the watchdog runs from the end of
    /// `init`.
    ///
    /// # Panics
    /// Only here, at init, with a defmt message: the clocks did not come out as configured,
    /// the H-bridge could not be put in its safe state, or the watchdog did not take its
    /// configuration.
    fn init(device: pac::Peripherals, _run: &RunConfig) -> Parts<Self> {
        init(device)
    }

    /// There is nowhere to exit to: report the verdict and keep running.
    fn exit(passed: bool) -> ! {
        defmt::info!("run finished (passed: {=bool}); halting", passed);
        loop {
            cortex_m::asm::wfi();
        }
    }
}

/// See [`Nucleo::init`].
fn init(device: pac::Peripherals) -> Parts<Nucleo> {
    // Before the clock setup rewrites RCC: was the last reset the watchdog's?
    let watchdog_reset = device.RCC.csr().read().wdgrstf().bit_is_set();
    device.RCC.csr().modify(|_, w| w.rmvf().set_bit());
    if watchdog_reset {
        defmt::warn!(
            "the last reset was the independent watchdog's: the control loop stalled for over {=u16} ms",
            WATCHDOG_TIMEOUT_MS
        );
    }

    let source = if start_hse(&device.RCC) {
        Config::hse(8.MHz()).bypass_hse_oscillator()
    } else {
        defmt::warn!(
            "clock: the HSE (ST-LINK MCO, 8 MHz) was not ready within {=u32} ms; running from the HSI (±1 % at 25 °C, more over temperature)",
            HSE_START_TIMEOUT_MS
        );
        Config::hsi()
    };
    let mut rcc = device.RCC.freeze(
        source
            .sysclk(SYSCLK_HZ.Hz())
            .pclk1(PCLK1_HZ.Hz())
            .pclk2(PCLK2_HZ.Hz()),
    );
    let clocks = rcc.clocks;
    defmt::assert!(
        clocks.sysclk().raw() == SYSCLK_HZ
            && clocks.pclk1().raw() == PCLK1_HZ
            && clocks.pclk2().raw() == PCLK2_HZ
            && clocks.timclk2().raw() == TIM1_CLOCK_HZ,
        "clocks are not as configured: sysclk {=u32} pclk1 {=u32} pclk2 {=u32} timclk2 {=u32} Hz",
        clocks.sysclk().raw(),
        clocks.pclk1().raw(),
        clocks.pclk2().raw(),
        clocks.timclk2().raw()
    );

    // A debugger halting the core stops TIM1 with its output off and pauses the watchdog;
    // the core's clock keeps running in WFI, so a debugger can attach to the idle loop.
    device.DBGMCU.cr().modify(|_, w| w.dbg_sleep().set_bit());
    device
        .DBGMCU
        .apb2_fz()
        .modify(|_, w| w.dbg_tim1_stop().set_bit());
    device
        .DBGMCU
        .apb1_fz()
        .modify(|_, w| w.dbg_iwdg_stop().set_bit());

    // FTimerUs enables TIM2 and computes the 1 MHz prescaler from the frozen clocks;
    // the free-running 32-bit count is then set up like on every board.
    let tim2 = FTimerUs::new(device.TIM2, &mut rcc).release();
    let prescaler = tim2.psc().read().psc().bits();

    let gpioa = device.GPIOA.split(&mut rcc);

    // Bridge pins low (outputs off) before the PWM exists.
    let dir = gpioa.pa9.into_push_pull_output_in_state(PinState::Low);
    let en = gpioa.pa10.into_push_pull_output_in_state(PinState::Low);
    let pwm = MotorPwm::new(device.TIM1, gpioa.pa8, &mut rcc);
    let bridge = match Bridge::new(pwm, dir, en) {
        Ok(bridge) => bridge,
        Err(error) => defmt::panic!(
            "H-bridge: could not put the bridge in its safe state: {}",
            error
        ),
    };

    let link = LinkEncoder::new(device.TIM3, gpioa.pa6, gpioa.pa7, &mut rcc);

    Adc1::new(
        device.ADC1,
        &device.ADC_COMMON,
        gpioa.pa0.into_analog(),
        gpioa.pa1.into_analog(),
        gpioa.pa4.into_analog(),
        &mut rcc,
    )
    .install();

    // The host link: USART2 on the ST-LINK virtual COM port, received by DMA1 stream 5.
    #[cfg(not(feature = "dynamixel-ttl"))]
    let _link = (
        gpioa.pa2.into_alternate::<7>(),
        gpioa.pa3.into_alternate::<7>(),
    );
    // Or on a Dynamixel TTL bus: PA2 alone, open drain (the bus's pull-up holds it high
    // when idle), USART2 in single-wire half-duplex mode (`serial`).
    #[cfg(feature = "dynamixel-ttl")]
    let _link = gpioa.pa2.into_alternate_open_drain::<7>();
    pac::USART2::enable(&mut rcc);
    pac::USART2::reset(&mut rcc);
    let Some(ring) = cortex_m::singleton!(: [u8; RX_RING] = [0; RX_RING]) else {
        defmt::panic!("host link: the receive ring was taken twice");
    };
    let dma1 = StreamsTuple::new(device.DMA1, &mut rcc);
    let (serial_rx, serial_tx) = Serial::start(device.USART2, LINK_BRR, dma1.5, ring);

    let hooks = Watchdog::start(device.IWDG);
    let (servo, service) = default_servo();

    Parts {
        clock: IndependentClock::start(tim2, prescaler),
        io: TickIo::new(
            link,
            GearPot { _adc: () },
            CurrentAdc { _adc: () },
            SupplyAdc { _adc: () },
            bridge,
        ),
        hooks,
        servo,
        service,
        serial_rx,
        serial_tx,
    }
}

/// Starts the HSE in bypass mode and waits at most [`HSE_START_TIMEOUT_MS`] for it; on a
/// timeout turns it off again. Whether it is ready. (The HAL's `freeze` waits for it
/// without a bound; called after this, it finds it ready at once.)
fn start_hse(rcc: &pac::RCC) -> bool {
    rcc.cr()
        .modify(|_, w| w.hsebyp().bypassed().hseon().set_bit());
    for _ in 0..HSE_START_TIMEOUT_MS {
        if rcc.cr().read().hserdy().bit_is_set() {
            return true;
        }
        // 1 ms on the HSI the core runs from until the clock setup.
        cortex_m::asm::delay(HSI_HZ / 1_000);
    }
    rcc.cr()
        .modify(|_, w| w.hseon().clear_bit().hsebyp().not_bypassed());
    false
}

/// The clutch length the real board starts at, mm, until the host sets another.
pub const START_CLUTCH_MM: i32 = 3;

/// The paper preset at [`START_CLUTCH_MM`], default supervision, disabled: the motor stays
/// off until the host enables it.
fn default_servo() -> (Servo, service::Service) {
    let design = Design::paper();
    let config = ControlConfig::paper(Length::from_int(START_CLUTCH_MM));
    let supervision = SupervisorConfig::DEFAULT;
    match Servo::new(&design, &config, &supervision) {
        Ok(servo) => (servo, service::Service::new(design, config, supervision)),
        Err(e) => defmt::panic!("servo configuration rejected: {}", e),
    }
}

/// The H-bridge PWM: TIM1 CH1 on PA8, 20 kHz, duty `0..=9000`.
///
/// A small driver of its own rather than the HAL's `PwmChannel` (which implements
/// `SetDutyCycle` too), for one reason: with CCR1 preloaded, the HAL's duty 0 reaches the
/// output only at the next update event, up to 50 µs later, so an H-bridge flipping its
/// direction pin right after "PWM off" would drive the new direction with the old duty for
/// up to a period. Here duty 0 also generates the update event (UG): the counter restarts
/// and the output is low before `set_duty_cycle` returns.
pub struct MotorPwm {
    tim: pac::TIM1,
    _pin: PA8<Alternate<1>>,
}

impl MotorPwm {
    /// Configures TIM1 (RM0390, advanced-control timers: PWM mode) with the output low,
    /// then hands PA8 to it.
    fn new(tim: pac::TIM1, pin: PA8, rcc: &mut pac::RCC) -> Self {
        pac::TIM1::enable(rcc);
        pac::TIM1::reset(rcc);
        tim.psc().write(|w| w.psc().set(0));
        tim.arr().write(|w| w.arr().set(PWM_PERIOD_TICKS - 1));
        tim.ccr1().write(|w| w.ccr().set(0));
        // CH1 output, PWM mode 1 (high while CNT < CCR1), CCR1 preloaded.
        tim.ccmr1_output()
            .write(|w| w.oc1m().pwm_mode1().oc1pe().set_bit());
        // CH4: no pin (PA11 stays a GPIO); its compare event triggers the current sample,
        // CCR4 preloaded so that it changes with CCR1.
        tim.ccr4().write(|w| w.ccr().set(current_trigger(0)));
        tim.ccmr2_output()
            .write(|w| w.oc4m().pwm_mode1().oc4pe().set_bit());
        // CH1 active high; no complementary output; CH4 on for its compare event.
        tim.ccer().write(|w| w.cc1e().set_bit().cc4e().set_bit());
        // Main output on. OSSI: whenever MOE is off (debug halt), drive the idle level (OIS1
        // = 0, low) rather than leave the pin floating. No break input, no dead time.
        tim.bdtr().write(|w| w.ossi().set_bit().moe().set_bit());
        // Edge-aligned, up-counting, ARR preloaded; load PSC, ARR and CCR1, then count.
        tim.cr1().write(|w| w.arpe().set_bit());
        tim.egr().write(|w| w.ug().set_bit());
        tim.cr1().modify(|_, w| w.cen().set_bit());
        Self {
            tim,
            _pin: pin.into_alternate::<1>(),
        }
    }
}

/// CCR4 for a duty of `duty` TIM1 counts: the middle of the on-time less
/// [`CURRENT_SAMPLE_LEAD_TICKS`], at least 1 (a compare at 0 coincides with the update);
/// mid-period with the output off (any time reads the same).
const fn current_trigger(duty: u16) -> u16 {
    let centre = if duty == 0 {
        PWM_PERIOD_TICKS / 2
    } else {
        duty / 2
    };
    if centre > CURRENT_SAMPLE_LEAD_TICKS {
        centre - CURRENT_SAMPLE_LEAD_TICKS
    } else {
        1
    }
}

impl embedded_hal::pwm::ErrorType for MotorPwm {
    type Error = Infallible;
}

impl embedded_hal::pwm::SetDutyCycle for MotorPwm {
    fn max_duty_cycle(&self) -> u16 {
        PWM_PERIOD_TICKS
    }

    /// Sets CCR1 (duties above 9000 are clamped to 9000, always on). A non-zero duty
    /// starts with the next period; 0 applies at once.
    fn set_duty_cycle(&mut self, duty: u16) -> Result<(), Infallible> {
        let duty = duty.min(PWM_PERIOD_TICKS);
        self.tim.ccr1().write(|w| w.ccr().set(duty));
        self.tim
            .ccr4()
            .write(|w| w.ccr().set(current_trigger(duty)));
        if duty == 0 {
            // Update event: CCR1 = 0 is loaded now and the output goes low.
            self.tim.egr().write(|w| w.ug().set_bit());
        }
        Ok(())
    }
}

/// The link's angle: TIM3 quadrature decoder on PA6/PA7 (an AS5047-style ABI output).
pub struct LinkEncoder {
    tim: pac::TIM3,
}

impl LinkEncoder {
    fn new(tim: pac::TIM3, a: PA6, b: PA7, rcc: &mut pac::RCC) -> Self {
        // The HAL sets up encoder mode 3 (both edges of TI1 and TI2), ARR = 0xFFFF, and
        // the pins as AF2; the pins stay in that mode when their handles are dropped.
        // Pull-ups first: the change to AF2 leaves PUPDR as it is.
        let (a, b) = (a.internal_pull_up(true), b.internal_pull_up(true));
        let (tim, _pins) = Qei::new(tim, (a, b), rcc).release();
        // Input filter (8 samples at f_DTS / 16 = 5.625 MHz: 1.42 µs), start from 0.
        tim.cr1().modify(|_, w| w.cen().clear_bit());
        tim.ccmr1_input()
            .modify(|_, w| w.ic1f().fdts_div16_n8().ic2f().fdts_div16_n8());
        tim.cnt().write(|w| w.cnt().set(0));
        tim.cr1().modify(|_, w| w.cen().set_bit());
        Self { tim }
    }
}

impl AngleSensor for LinkEncoder {
    const FULL_SCALE: u16 = LINK_COUNTS_PER_TURN;

    /// The counter modulo 4096. Never fails: a quadrature decoder has no error to report.
    fn read_counts(&mut self) -> Result<u16, SensorError> {
        Ok(self.tim.cnt().read().cnt().bits() % LINK_COUNTS_PER_TURN)
    }
}

/// The gear-side potentiometer: ADC1 channel 1 (PA1), 12-bit conversion >> 2.
pub struct GearPot {
    _adc: (),
}

impl AngleSensor for GearPot {
    const FULL_SCALE: u16 = POT_COUNTS;

    fn read_counts(&mut self) -> Result<u16, SensorError> {
        Adc1::convert_shared(POT_CHANNEL).map(|raw| raw >> 2)
    }
}

/// The bridge supply sense: ADC1 channel 4 (PA4) behind a 1 : 6.2 divider, 12-bit raw;
/// only in a build with `supply-sense` ([`SUPPLY_SENSE_FITTED`]).
pub struct SupplyAdc {
    _adc: (),
}

impl SupplySensor for SupplyAdc {
    fn read_raw(&mut self) -> Result<u16, SensorError> {
        if !SUPPLY_SENSE_FITTED {
            return Err(SensorError::Device);
        }
        Adc1::convert_shared(SUPPLY_CHANNEL)
    }
}

/// The motor current sense: ADC1 channel 0 (PA0), 12-bit raw, sampled by TIM1 in every PWM
/// period (see the module docs). The raw reading with the bridge off is the sensor's
/// offset: boot-time calibration measures it through [`CurrentSensor::read_raw`] before the
/// first enable.
pub struct CurrentAdc {
    _adc: (),
}

impl CurrentSensor for CurrentAdc {
    /// The latest PWM-synchronous sample; [`SensorError::Timeout`] if none completed since
    /// the last read (TIM1 or the trigger stopped).
    fn read_raw(&mut self) -> Result<u16, SensorError> {
        interrupt::free(|cs| {
            let Ok(adc) = ADC1.borrow(cs).try_borrow() else {
                return Err(SensorError::Bus);
            };
            adc.as_ref()
                .map_or(Err(SensorError::Device), Adc1::latest_current)
        })
    }
}

/// ADC1, shared by [`GearPot`], [`SupplyAdc`] and [`CurrentAdc`] (installed once by `init`).
static ADC1: Mutex<RefCell<Option<Adc1>>> = Mutex::new(RefCell::new(None));

/// ADC1 with its three analog pins.
struct Adc1 {
    adc: pac::ADC1,
    _current: PA0<Analog>,
    _pot: PA1<Analog>,
    _supply: PA4<Analog>,
}

impl Adc1 {
    /// Powers ADC1 up (RM0390, ADC): 12-bit, right-aligned, no scan, no DMA, no interrupt;
    /// single software-started regular conversions (the pot, the supply), and one injected conversion
    /// of the current on each rising TIM1 CC4 event.
    fn new(
        adc: pac::ADC1,
        common: &pac::ADC_COMMON,
        current: PA0<Analog>,
        pot: PA1<Analog>,
        supply: PA4<Analog>,
        rcc: &mut pac::RCC,
    ) -> Self {
        pac::ADC1::enable(rcc);
        pac::ADC1::reset(rcc);
        common.ccr().modify(|_, w| w.adcpre().div4());
        adc.cr1().write(|w| w.res().twelve_bit());
        adc.smpr2().write(|w| {
            w.smp(CURRENT_CHANNEL).cycles56();
            w.smp(POT_CHANNEL).cycles56();
            w.smp(SUPPLY_CHANNEL).cycles56()
        });
        adc.sqr1().write(|w| w.l().set(0));
        // One injected conversion (JL = 0 converts JSQ4 alone).
        // SAFETY: JSQ4 takes a channel number 0..=18; CURRENT_CHANNEL is 0.
        adc.jsqr()
            .write(|w| unsafe { w.jl().bits(0).jsq4().bits(CURRENT_CHANNEL) });
        adc.cr2().write(|w| {
            w.adon()
                .set_bit()
                .jextsel()
                .tim1cc4()
                .jexten()
                .rising_edge()
        });
        cortex_m::asm::delay(ADC_STABILISATION_CORE_CYCLES);
        Self {
            adc,
            _current: current,
            _pot: pot,
            _supply: supply,
        }
    }

    /// The latest injected (current) result, if one completed since the last call.
    fn latest_current(&self) -> Result<u16, SensorError> {
        let adc = &self.adc;
        if adc.sr().read().jeoc().bit_is_clear() {
            return Err(SensorError::Timeout);
        }
        adc.sr().write(|w| w.jeoc().clear().jstrt().clear());
        Ok(adc.jdr1().read().jdata().bits() & 0x0FFF)
    }

    fn install(self) {
        interrupt::free(|cs| {
            ADC1.borrow(cs).replace(Some(self));
        });
    }

    /// One conversion of `channel` on the shared ADC1, in a critical section.
    fn convert_shared(channel: u8) -> Result<u16, SensorError> {
        interrupt::free(|cs| {
            let Ok(mut adc) = ADC1.borrow(cs).try_borrow_mut() else {
                return Err(SensorError::Bus);
            };
            adc.as_mut()
                .map_or(Err(SensorError::Device), |adc| adc.convert(channel))
        })
    }

    /// Starts one conversion of `channel` and polls for its end at most
    /// `ADC_POLL_LIMIT` times.
    fn convert(&mut self, channel: u8) -> Result<u16, SensorError> {
        let adc = &self.adc;
        // SAFETY: SQ1 takes a channel number 0..=18; `channel` is 1 or 4.
        adc.sqr3().write(|w| unsafe { w.sq1().bits(channel) });
        // Clear stale flags (rc_w0), then start; SWSTART is ignored while ADON = 0, which
        // ends in the timeout below rather than a hang.
        adc.sr()
            .write(|w| w.eoc().clear().strt().clear().ovr().clear());
        adc.cr2().modify(|_, w| w.swstart().set_bit());
        for _ in 0..ADC_POLL_LIMIT {
            if adc.sr().read().eoc().bit_is_set() {
                // Reading DR clears EOC.
                return Ok(adc.dr().read().data().bits() & 0x0FFF);
            }
        }
        // Abort whatever the ADC is doing (ADON = 0 stops a conversion and powers it down),
        // so that a late end of conversion cannot be taken for the next channel's; then
        // power it up again and let it stabilise. Only on this failure path.
        adc.cr2().modify(|_, w| w.adon().clear_bit());
        adc.cr2().modify(|_, w| w.adon().set_bit());
        cortex_m::asm::delay(ADC_STABILISATION_CORE_CYCLES);
        Err(SensorError::Timeout)
    }
}

/// What surrounds the real board's control step: the independent watchdog, fed every
/// tick.
pub struct Watchdog {
    iwdg: pac::IWDG,
}

impl Watchdog {
    /// Starts the IWDG with an 80 ms timeout (RM0390, IWDG; STM32Cube's sequence: start,
    /// which also starts the LSI, then configure, wait for the update, reload).
    fn start(iwdg: pac::IWDG) -> Self {
        iwdg.kr().write(|w| w.key().start());
        iwdg.kr().write(|w| w.key().unlock());
        iwdg.pr().write(|w| w.pr().divide_by32());
        iwdg.rlr().write(|w| w.rl().set(WATCHDOG_TIMEOUT_MS - 1));
        // PVU/RVU clear once the LSI domain has taken the values (≤ 5 LSI periods).
        let mut waited_ms = 0;
        while {
            let sr = iwdg.sr().read();
            sr.pvu().bit_is_set() || sr.rvu().bit_is_set()
        } {
            if waited_ms == WATCHDOG_UPDATE_WAIT_MS {
                defmt::panic!(
                    "watchdog: the IWDG did not take its prescaler and reload within {=u32} ms (LSI not running?)",
                    WATCHDOG_UPDATE_WAIT_MS
                );
            }
            cortex_m::asm::delay(SYSCLK_HZ / 1_000);
            waited_ms += 1;
        }
        // The counter started at 0xFFF; from this reload on it counts down from 79.
        iwdg.kr().write(|w| w.key().feed());
        Self { iwdg }
    }
}

impl TickHooks for Watchdog {
    type Io = Io;
    /// The real world has no events to log.
    type Event = core::convert::Infallible;

    /// Feeds the watchdog; pends the USART2 interrupt if the receive ring holds bytes.
    fn before_step(&mut self, _io: &mut Io, _servo: &mut Servo) -> TickPlan {
        self.iwdg.kr().write(|w| w.key().feed());
        if serial::rx_waiting() {
            cortex_m::peripheral::NVIC::pend(pac::Interrupt::USART2);
        }
        TickPlan { overrun: false }
    }

    /// Nothing to record on the real board.
    fn after_step(&mut self, _servo: &Servo, _out: &TickOutput, _late: Option<Fault>, _io: &Io) {}

    fn pop_event(&mut self) -> Option<core::convert::Infallible> {
        None
    }

    fn ends_run(event: &core::convert::Infallible) -> bool {
        match *event {}
    }
}

/// The fail-safe of the real board (see `crate::fail_safe`): TIM1's main output off (the
/// PWM pin to its idle level, low: OSSI) and EN low, by register writes that cannot fail
/// (with TIM1 or GPIOA not yet clocked they are ignored, and the pins still float as from
/// reset). Returns the outputs before and after.
pub fn force_bridge_off() -> (BridgeOutputs, BridgeOutputs) {
    // SAFETY: the register blocks of TIM1 and GPIOA, touched here only by single reads and
    // writes: BDTR without MOE, CCR1 = 0, and BSRR (atomic) for PA10. The callers have
    // interrupts masked, so no task can write them in between.
    let (tim1, gpioa) = unsafe { (&*pac::TIM1::ptr(), &*pac::GPIOA::ptr()) };
    let before = bridge_outputs(tim1, gpioa);
    tim1.bdtr().write(|w| w.ossi().set_bit());
    gpioa.bsrr().write(|w| w.br(EN_PIN).set_bit());
    tim1.ccr1().write(|w| w.ccr().set(0));
    (before, bridge_outputs(tim1, gpioa))
}

/// PA10, the bridge's enable.
const EN_PIN: u8 = 10;

/// The bridge outputs as the registers say: EN's output level; the duty of CCR1 while the
/// main output is on, else 0.
fn bridge_outputs(
    tim1: &pac::tim1::RegisterBlock,
    gpioa: &pac::gpioa::RegisterBlock,
) -> BridgeOutputs {
    let duty = if tim1.bdtr().read().moe().bit_is_set() {
        u32::from(tim1.ccr1().read().ccr().bits()) * 1000 / u32::from(PWM_PERIOD_TICKS)
    } else {
        0
    };
    BridgeOutputs {
        enabled: gpioa.odr().read().odr(EN_PIN).bit_is_set(),
        duty_permille: duty.min(1000) as u16,
    }
}

/// How a panic or HardFault ends on the real board, once the bridge is off and the report
/// is out: a panic traps into HardFault (`udf`: probe-rs stops there and prints the
/// backtrace, as with panic-probe); in the HardFault handler, wait for the watchdog.
pub fn halt_after_fault() -> ! {
    use cortex_m::peripheral::scb::{Exception, VectActive};
    if cortex_m::peripheral::SCB::vect_active() != VectActive::Exception(Exception::HardFault) {
        // UsageFault off, so that `udf` raises HardFault rather than UsageFault.
        // SAFETY: one read-modify-write of SHCSR with interrupts masked.
        unsafe {
            (*cortex_m::peripheral::SCB::PTR)
                .shcsr
                .modify(|v| v & !(1 << 18));
        }
        cortex_m::asm::udf();
    }
    loop {
        cortex_m::asm::nop();
    }
}
