//! USART2, the host link: the same on every board (the Nucleo's ST-LINK virtual COM port
//! is wired to USART2 on PA2/PA3; the emulated boards' second `-serial` device is
//! USART2), through the board's device crate `super::pac`. Whatever the board, the receive
//! half moves the received bytes into the link task's queue (`SerialRx::receive_into`,
//! called from the USART2 interrupt).

use super::pac;
use heapless::spsc::Producer;

/// Polls of TXE before one byte is given up (far more than one character takes at the
/// slowest baud rate used: 10 bits at 921 600 Bd is ≈ 2 000 core cycles at 180 MHz).
const TX_SPIN_LIMIT: u32 = 100_000;

/// USART2, the host link, 8N1, transmission by polling TXE. Reception differs by board:
/// the emulated boards take each byte in the receive interrupt (`RXNEIE`; QEMU's USART
/// has no DMA); the real board lets DMA1 stream 5 copy every byte into a ring buffer
/// ([`SerialRx`]) and interrupts only on an idle line.
pub struct Serial;

impl Serial {
    /// Sets `usart` to 8N1 at `brr` (the baud-rate divider, RM0390 §25.4.4: f_PCLK / baud
    /// at 16× oversampling) with the receiver and transmitter on; with `dma_rx`, the
    /// receiver's DMA requests and the idle-line interrupt, else the receive interrupt.
    fn configure(usart: &pac::USART2, brr: u16, dma_rx: bool) {
        usart.cr1().write(|w| w.ue().clear_bit());
        usart.brr().write(|w| {
            w.div_mantissa()
                .set(brr >> 4)
                .div_fraction()
                .set((brr & 0xF) as u8)
        });
        usart.cr2().reset();
        usart.cr3().write(|w| w.dmar().bit(dma_rx));
        // A Dynamixel TTL bus: single-wire half duplex on TX (RM0390 §25.3.11), set while
        // UE is 0. The receiver hears the line, our own bytes included (see `SerialTx`).
        #[cfg(feature = "dynamixel-ttl")]
        usart.cr3().modify(|_, w| w.hdsel().set_bit());
        usart.cr1().write(|w| {
            w.ue()
                .set_bit()
                .te()
                .set_bit()
                .re()
                .set_bit()
                .rxneie()
                .bit(!dma_rx)
                .idleie()
                .bit(dma_rx)
        });
    }

    /// The transmit half: writes DR and reads SR's TXE only, which the receive half never
    /// touches (reading SR has no side effect on its own; RXNE/ORE/IDLE clear on the
    /// SR-then-DR read sequence of the receive half).
    fn tx_half() -> SerialTx {
        // SAFETY: see above: the two halves use disjoint parts of the peripheral.
        SerialTx {
            usart: unsafe { pac::USART2::steal() },
        }
    }

    /// Starts `usart` at `brr` with the receive interrupt on, split into its two halves.
    #[cfg(feature = "qemu")]
    pub fn start(usart: pac::USART2, brr: u16) -> (SerialRx, SerialTx) {
        Self::configure(&usart, brr, false);
        (SerialRx { usart }, Self::tx_half())
    }

    /// Starts `usart` at `brr` receiving by DMA into `ring` through `stream` (DMA1 stream
    /// 5, channel 4: USART2_RX, RM0390 DMA1 request mapping), split into its two halves.
    #[cfg(feature = "nucleo-f446re")]
    pub fn start(
        usart: pac::USART2,
        brr: u16,
        mut stream: RxStream,
        ring: &'static mut [u8; RX_RING],
    ) -> (SerialRx, SerialTx) {
        use stm32f4xx_hal::dma::{
            config::Priority, traits::Stream, DmaChannel, DmaDataSize, DmaDirection,
        };
        Self::configure(&usart, brr, true);
        // SAFETY (both blocks): the stream is disabled (just reset by `StreamsTuple::new`),
        // and the sizes match the byte-wide DR and ring.
        unsafe { stream.disable() };
        stream.set_channel(DmaChannel::Channel4);
        stream.set_direction(DmaDirection::PeripheralToMemory);
        stream.set_peripheral_address(usart.dr().as_ptr() as u32);
        stream.set_memory_address(ring.as_ptr() as u32);
        stream.set_number_of_transfers(RX_RING as u16);
        unsafe {
            stream.set_memory_size(DmaDataSize::Byte);
            stream.set_peripheral_size(DmaDataSize::Byte);
        }
        stream.set_memory_increment(true);
        stream.set_peripheral_increment(false);
        stream.set_circular_mode(true);
        stream.set_priority(Priority::VeryHigh);
        stream.set_fifo_enable(false);
        // SAFETY: fully configured above; the ring is 'static and only read from here on.
        unsafe { stream.enable() };
        let rx = SerialRx {
            usart,
            stream,
            ring: ring.as_ptr(),
            next: 0,
        };
        (rx, Self::tx_half())
    }
}

/// The receive half of [`Serial`] (the receive interrupt's).
#[cfg(feature = "qemu")]
pub struct SerialRx {
    usart: pac::USART2,
}

#[cfg(feature = "qemu")]
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

/// DMA1 stream 5, USART2's receive stream.
#[cfg(feature = "nucleo-f446re")]
pub type RxStream = stm32f4xx_hal::dma::Stream5<pac::DMA1>;

/// Bytes in the real board's receive ring: 2.8 ms of back-to-back bytes at 921 600 Bd
/// (92 160 bytes/s), against a drain at least every control tick (1 ms; see
/// [`rx_waiting`]).
#[cfg(feature = "nucleo-f446re")]
pub const RX_RING: usize = 256;

/// Where the ring's reader stood after the last drain (index into the ring), for
/// [`rx_waiting`].
#[cfg(feature = "nucleo-f446re")]
static DRAINED_TO: core::sync::atomic::AtomicUsize = core::sync::atomic::AtomicUsize::new(0);

/// The ring index DMA writes next, from the stream's remaining count (NDTR counts down from
/// [`RX_RING`] and reloads in circular mode).
#[cfg(feature = "nucleo-f446re")]
fn dma_write_index(remaining: u16) -> usize {
    (RX_RING - usize::from(remaining).min(RX_RING)) % RX_RING
}

/// Whether DMA has written bytes the receive half has not drained yet: the control tick
/// asks every period and pends the USART2 interrupt if so, so a long frame without an idle
/// gap is drained at least every millisecond (92 bytes at the full rate, well inside the
/// 256-byte ring).
#[cfg(feature = "nucleo-f446re")]
pub fn rx_waiting() -> bool {
    // SAFETY: one read of a read-only count register (NDTR); nothing is written.
    let remaining = unsafe { (*pac::DMA1::ptr()).st(5).ndtr().read().ndt().bits() };
    dma_write_index(remaining) != DRAINED_TO.load(core::sync::atomic::Ordering::Relaxed)
}

/// The receive half of [`Serial`] on the real board: DMA1 stream 5 copies each byte out of
/// DR as it arrives (within a few bus cycles, whatever the interrupts are doing: no
/// overrun at 921 600 Bd however long the control tick holds the CPU) into a circular
/// ring; the USART2 interrupt (idle line, or pended by the control tick) drains the ring.
#[cfg(feature = "nucleo-f446re")]
pub struct SerialRx {
    usart: pac::USART2,
    stream: RxStream,
    /// The ring DMA writes (read volatile: DMA changes it behind the compiler's back).
    ring: *const u8,
    /// The next ring index to read.
    next: usize,
}

// SAFETY: the ring pointer is a 'static buffer only this half reads.
#[cfg(feature = "nucleo-f446re")]
unsafe impl Send for SerialRx {}

#[cfg(feature = "nucleo-f446re")]
impl SerialRx {
    /// Moves every byte DMA has written since the last call into `queue`, and clears the
    /// idle-line flag. A full queue loses the byte: its frame then fails its CRC, and the
    /// protocol handler counts it and answers with an error.
    #[inline]
    pub fn receive_into(&mut self, queue: &mut Producer<'_, u8>) {
        use stm32f4xx_hal::dma::traits::Stream;
        // IDLE clears by reading SR then DR. Only while RXNE is clear: DR then holds a
        // byte DMA has already taken, so the read steals nothing (if RXNE is set, DMA takes
        // the byte within a few cycles and the still-set IDLE brings us back at once).
        let sr = self.usart.sr().read();
        if sr.idle().bit_is_set() && sr.rxne().bit_is_clear() {
            let _ = self.usart.dr().read();
        }
        let write = dma_write_index(self.stream.number_of_transfers());
        while self.next != write {
            // SAFETY: `next` < RX_RING, inside the 'static ring; volatile, since DMA writes it.
            let byte = unsafe { self.ring.add(self.next).read_volatile() };
            let _ = queue.enqueue(byte);
            self.next = (self.next + 1) % RX_RING;
        }
        DRAINED_TO.store(write, core::sync::atomic::Ordering::Relaxed);
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

#[cfg(feature = "nucleo-f446re")]
impl SerialTx {
    /// Waits (at most [`TX_SPIN_LIMIT`] polls) until the last byte written has left the
    /// shift register (TC).
    fn wait_transmitted(&self) {
        let mut polls = 0;
        while self.usart.sr().read().tc().bit_is_clear() && polls < TX_SPIN_LIMIT {
            polls += 1;
        }
    }

    /// Changes the line rate to the divider `brr` with 8× oversampling if `over8`
    /// (`drivers::usart_baud::divider`), once what was written has gone out: the status
    /// packet that changed the rate leaves at the old one.
    pub fn set_divider(&self, brr: u16, over8: bool) {
        self.wait_transmitted();
        // OVER8 and BRR are written with the USART disabled (RM0390 §25.6.4).
        self.usart.cr1().modify(|_, w| w.ue().clear_bit());
        self.usart.brr().write(|w| {
            w.div_mantissa()
                .set(brr >> 4)
                .div_fraction()
                .set((brr & 0xF) as u8)
        });
        self.usart
            .cr1()
            .modify(|_, w| w.over8().bit(over8).ue().set_bit());
    }
}

impl embedded_io::Write for SerialTx {
    /// Sends the bytes TXE takes, waiting for it before each; returns how many went out,
    /// or [`TxTimeout`] if not even the first did within [`TX_SPIN_LIMIT`] polls.
    ///
    /// On a Dynamixel TTL bus (single wire) the receiver is off from the first byte until
    /// the last has left the shift register, so the board does not hear its own status
    /// (the other devices' statuses it must hear: a SYNC READ's chain follows them).
    fn write(&mut self, bytes: &[u8]) -> Result<usize, TxTimeout> {
        #[cfg(feature = "dynamixel-ttl")]
        {
            self.usart.cr1().modify(|_, w| w.re().clear_bit());
            let sent = self.send(bytes);
            self.wait_transmitted();
            self.usart.cr1().modify(|_, w| w.re().set_bit());
            sent
        }
        #[cfg(not(feature = "dynamixel-ttl"))]
        self.send(bytes)
    }

    /// Nothing is buffered: each byte is in the data register when `write` returns.
    fn flush(&mut self) -> Result<(), TxTimeout> {
        Ok(())
    }
}

impl SerialTx {
    /// The bytes TXE takes, waiting for it before each (see [`embedded_io::Write::write`]).
    fn send(&mut self, bytes: &[u8]) -> Result<usize, TxTimeout> {
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
}
