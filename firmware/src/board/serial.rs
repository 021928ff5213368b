//! USART2, the host link: the same on every board (the Nucleo's ST-LINK virtual COM port
//! is wired to USART2 on PA2/PA3; the emulated boards' second `-serial` device is
//! USART2), through the board's device crate `super::pac`.

use super::pac;
use heapless::spsc::Producer;

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
    pub fn start(usart: pac::USART2, brr: u16) -> (SerialRx, SerialTx) {
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
        (SerialRx { usart }, SerialTx { usart: tx })
    }
}

/// The receive half of [`Serial`] (the receive interrupt's).
pub struct SerialRx {
    usart: pac::USART2,
}

impl SerialRx {
    /// The next received byte, if any. Reading SR then DR also clears an overrun, so the
    /// interrupt cannot keep firing on a stuck error flag. A byte lost to an overrun, or
    /// taken with a framing or noise error, is not flagged here: the frame it belongs to
    /// fails its COBS or CRC check and is counted and answered by the protocol handler.
    pub fn read(&mut self) -> Option<u8> {
        let sr = self.usart.sr().read();
        let error = sr.ore().bit_is_set() || sr.fe().bit_is_set() || sr.nf().bit_is_set();
        if !(sr.rxne().bit_is_set() || error) {
            return None;
        }
        Some(self.usart.dr().read().dr().bits() as u8)
    }

    /// Moves every byte received into `queue`. A full queue loses the byte: its frame then
    /// fails its CRC, and the protocol handler counts it and answers with an error.
    #[inline]
    pub fn receive_into(&mut self, queue: &mut Producer<'_, u8>) {
        while let Some(byte) = self.read() {
            let _ = queue.enqueue(byte);
        }
    }
}

/// The transmit half of [`Serial`] (the link task's).
pub struct SerialTx {
    usart: pac::USART2,
}

/// The transmitter did not become ready within [`TX_SPIN_LIMIT`] polls.
#[derive(Clone, Copy, Debug, PartialEq, Eq, defmt::Format)]
pub struct TxTimeout;

impl embedded_io::Error for TxTimeout {
    fn kind(&self) -> embedded_io::ErrorKind {
        embedded_io::ErrorKind::TimedOut
    }
}

impl embedded_io::ErrorType for SerialTx {
    type Error = TxTimeout;
}

impl embedded_io::Write for SerialTx {
    /// Sends the bytes TXE takes, waiting for it before each; returns how many went out,
    /// or [`TxTimeout`] if not even the first did within [`TX_SPIN_LIMIT`] polls.
    fn write(&mut self, bytes: &[u8]) -> Result<usize, TxTimeout> {
        for (sent, &b) in bytes.iter().enumerate() {
            let mut polls = 0;
            while self.usart.sr().read().txe().bit_is_clear() {
                polls += 1;
                if polls == TX_SPIN_LIMIT {
                    return if sent == 0 { Err(TxTimeout) } else { Ok(sent) };
                }
            }
            self.usart.dr().write(|w| w.dr().set(u16::from(b)));
        }
        Ok(bytes.len())
    }

    /// Nothing is buffered: each byte is in the data register when `write` returns.
    fn flush(&mut self) -> Result<(), TxTimeout> {
        Ok(())
    }
}
