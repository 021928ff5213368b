//! Board support: everything that differs between the boards, behind one small surface.
//!
//! Each board module provides `pac` (the device crate RTIC binds to), `NAME`,
//! `SYSCLK_HZ`, `init`, `run_config`, `exit`, the actuator I/O `Io` (driver traits) and the
//! `World` around the control step, with `drain_world` for its log events. The free-running µs clock on TIM2 is
//! shared code: it is the tick accounting's independent time base.

#[cfg(any(feature = "qemu-m4", feature = "qemu-m3"))]
mod qemu;
#[cfg(any(feature = "qemu-m4", feature = "qemu-m3"))]
pub use qemu::*;
#[cfg(any(feature = "qemu-m4", feature = "qemu-m3"))]
mod sim;
#[cfg(any(feature = "qemu-m4", feature = "qemu-m3"))]
pub use sim::*;

#[cfg(feature = "nucleo-f446re")]
mod nucleo;
#[cfg(feature = "nucleo-f446re")]
pub use nucleo::*;

use crate::run::IdleMode;

/// Waits for the next interrupt: WFI, or a spin on the emulated boards (see `qemu` for why).
#[inline(always)]
pub fn wait_for_interrupt(mode: IdleMode) {
    match mode {
        IdleMode::Wfi => cortex_m::asm::wfi(),
        IdleMode::Spin => cortex_m::asm::nop(),
    }
}

/// What `init` hands over to the application.
pub struct Parts {
    /// Free-running µs clock, independent of SysTick.
    pub clock: IndependentClock,
    /// The actuator's sensors and H-bridge, behind the `drivers` traits.
    pub io: Io,
    /// What surrounds the control step: the simulated actuator and its scenario on the
    /// emulated boards, the watchdog on the real one.
    pub world: World,
    /// The servo (controller + supervisor), configured for the board.
    pub servo: model::servo::Servo,
    /// The command service, with the configuration the servo was built from.
    pub service: service::Service,
    /// The host link's receive half (USART2).
    pub serial_rx: SerialRx,
    /// The host link's transmit half.
    pub serial_tx: SerialTx,
}

/// TIM2 as a free-running 32-bit µs counter (wraps after 71 minutes; readers use
/// wrapping differences). Independent of SysTick, which paces the control loop.
pub struct IndependentClock {
    tim: pac::TIM2,
}

impl IndependentClock {
    /// Starts TIM2 counting µs, given the prescaler that divides its input clock to 1 MHz.
    fn start(tim: pac::TIM2, prescaler: u16) -> Self {
        tim.psc().write(|w| w.psc().set(prescaler));
        tim.arr().write(|w| w.arr().set(u32::MAX));
        // Update event: load the prescaler now rather than at the first overflow.
        tim.egr().write(|w| w.ug().set_bit());
        tim.cr1().modify(|_, w| w.cen().set_bit());
        Self { tim }
    }

    /// µs since the clock started, modulo 2³².
    pub fn now_us(&self) -> u32 {
        self.tim.cnt().read().bits()
    }
}

/// Polls of TXE before one byte is given up (far more than one character takes at the
/// slowest baud rate used: 10 bits at 921 600 Bd is ≈ 2 000 core cycles at 180 MHz).
const TX_SPIN_LIMIT: u32 = 100_000;

/// USART2, the host link, 8N1: the receive interrupt on (`RXNEIE`), transmission by
/// polling TXE. The same on every board: the Nucleo's ST-LINK virtual COM port is wired
/// to USART2 (PA2/PA3), and the emulated boards' second `-serial` device is USART2.
pub struct Serial;

impl Serial {
    /// Sets `usart` to 8N1 at `brr` (the baud-rate divider, RM0390 §25.4.4: f_PCLK / baud
    /// at 16× oversampling) with the receiver, transmitter and receive interrupt on, and
    /// splits it into its two halves.
    fn start(usart: pac::USART2, brr: u16) -> (SerialRx, SerialTx) {
        usart.cr1().write(|w| w.ue().clear_bit());
        usart.brr().write(|w| {
            w.div_mantissa()
                .set(brr >> 4)
                .div_fraction()
                .set((brr & 0xF) as u8)
        });
        usart.cr2().reset();
        usart.cr3().reset();
        usart.cr1().write(|w| {
            w.ue()
                .set_bit()
                .te()
                .set_bit()
                .re()
                .set_bit()
                .rxneie()
                .set_bit()
        });
        // The receive half owns `usart`; the transmit half only writes DR and reads SR's
        // TXE, which the receive half never touches (reading SR has no side effect on its
        // own; RXNE/ORE clear on the SR-then-DR read sequence of the receive half).
        // SAFETY: see above: the two halves use disjoint parts of the peripheral.
        let tx = unsafe { pac::USART2::steal() };
        (
            SerialRx { usart },
            SerialTx {
                usart: tx,
                failed: 0,
            },
        )
    }
}

/// What one receive-register read gave.
pub struct Received {
    /// The byte.
    pub byte: u8,
    /// Bytes were lost before it (overrun: the receive register was not read in time), or
    /// it arrived with a framing or noise error.
    pub error: bool,
}

/// The receive half of [`Serial`] (the receive interrupt's).
pub struct SerialRx {
    usart: pac::USART2,
}

impl SerialRx {
    /// The next received byte, if any. Reading SR then DR also clears an overrun, so the
    /// interrupt cannot keep firing on a stuck error flag.
    pub fn read(&mut self) -> Option<Received> {
        let sr = self.usart.sr().read();
        let error = sr.ore().bit_is_set() || sr.fe().bit_is_set() || sr.nf().bit_is_set();
        if !(sr.rxne().bit_is_set() || error) {
            return None;
        }
        let byte = self.usart.dr().read().dr().bits() as u8;
        Some(Received { byte, error })
    }
}

/// The transmit half of [`Serial`] (the link task's).
pub struct SerialTx {
    usart: pac::USART2,
    failed: u32,
}

impl SerialTx {
    /// Sends `bytes`, waiting for TXE before each; a byte that TXE does not accept within
    /// [`TX_SPIN_LIMIT`] polls abandons the rest (counted in [`SerialTx::failed`]).
    pub fn write_all(&mut self, bytes: &[u8]) {
        for &b in bytes {
            let mut polls = 0;
            while self.usart.sr().read().txe().bit_is_clear() {
                polls += 1;
                if polls == TX_SPIN_LIMIT {
                    self.failed = self.failed.saturating_add(1);
                    return;
                }
            }
            self.usart.dr().write(|w| w.dr().set(u16::from(b)));
        }
    }

    /// Writes abandoned because the transmitter never became ready.
    pub fn failed(&self) -> u32 {
        self.failed
    }
}
