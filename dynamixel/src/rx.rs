//! The streaming decoder both protocols share: a fixed window of the bytes not yet
//! consumed, the idle mark that says which of them arrived before the line last went
//! quiet, and a [`Framing`] that finds packets in it ([`crate::v1::Framing`],
//! [`crate::v2::Framing`]).

use crate::error::DecodeError;
use core::marker::PhantomData;

/// How one protocol finds its packets at the front of a [`Window`].
pub trait Framing {
    /// A decoded packet, borrowing the window.
    type Packet<'a>;

    /// The next packet or rejected candidate at the front of `rx` (consuming it), `None`
    /// when more bytes are needed.
    fn next<const N: usize>(rx: &mut Window<N>) -> Option<Result<Self::Packet<'_>, DecodeError>>;
}

/// Streaming decoder: feed bytes with [`Decoder::push`], tell it when the line goes idle
/// with [`Decoder::idle`], and take packets and errors from [`Decoder::next`] until it
/// returns `None`. Never allocates; `N` bytes of buffer.
pub struct Decoder<F, const N: usize> {
    rx: Window<N>,
    framing: PhantomData<F>,
}

impl<F: Framing, const N: usize> Default for Decoder<F, N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<F: Framing, const N: usize> Decoder<F, N> {
    /// An empty decoder.
    #[must_use]
    pub const fn new() -> Self {
        Decoder {
            rx: Window::new(),
            framing: PhantomData,
        }
    }

    /// One received byte.
    pub fn push(&mut self, byte: u8) {
        self.rx.push(byte);
    }

    /// The line has been idle (no byte for at least one character time): an incomplete
    /// packet received so far will not complete.
    pub fn idle(&mut self) {
        self.rx.idle();
    }

    /// Whether bytes are held that no packet or error has consumed yet (a packet may be
    /// under way).
    #[must_use]
    pub fn pending(&self) -> bool {
        !self.rx.avail().is_empty()
    }

    /// Forget every byte received.
    pub fn reset(&mut self) {
        self.rx.clear();
    }

    /// The next packet or error in the bytes received, `None` when more bytes are needed.
    #[allow(clippy::should_implement_trait)] // lends from the buffer: not an Iterator
    pub fn next(&mut self) -> Option<Result<F::Packet<'_>, DecodeError>> {
        F::next(&mut self.rx)
    }
}

/// Received bytes `buf[start..end]`, of which `buf[start..idle_end]` came before the last
/// idle gap: a packet never spans an idle gap, so a candidate that starts there and is
/// incomplete is truncated.
pub struct Window<const N: usize> {
    buf: [u8; N],
    start: usize,
    end: usize,
    idle_end: usize,
}

impl<const N: usize> Window<N> {
    pub(crate) const fn new() -> Self {
        Window {
            buf: [0; N],
            start: 0,
            end: 0,
            idle_end: 0,
        }
    }

    /// Append a byte. When the buffer is full of an undecided candidate (the caller did not
    /// drain the decoder), the oldest byte is dropped.
    fn push(&mut self, byte: u8) {
        if self.end == N {
            if self.start == 0 {
                self.start = 1;
            }
            self.buf.copy_within(self.start..self.end, 0);
            self.end -= self.start;
            self.idle_end = self.idle_end.saturating_sub(self.start);
            self.start = 0;
        }
        self.buf[self.end] = byte;
        self.end += 1;
    }

    /// Mark every byte received so far as before an idle gap.
    fn idle(&mut self) {
        self.idle_end = self.end;
    }

    /// Forget everything.
    fn clear(&mut self) {
        self.start = 0;
        self.end = 0;
        self.idle_end = 0;
    }

    /// The unconsumed bytes.
    pub fn avail(&self) -> &[u8] {
        &self.buf[self.start..self.end]
    }

    /// Drop the first `n` unconsumed bytes.
    pub fn consume(&mut self, n: usize) {
        self.start = (self.start + n).min(self.end);
        if self.start == self.end {
            self.start = 0;
            self.end = 0;
            self.idle_end = 0;
        }
    }

    /// Whether the candidate at the front started before the last idle gap (so it can no
    /// longer complete).
    pub fn front_is_stale(&self) -> bool {
        self.start < self.idle_end
    }

    /// Consume the `n`-byte packet at the front and give mutable access to its bytes (they
    /// stay in place until the next byte is pushed).
    pub fn take(&mut self, n: usize) -> &mut [u8] {
        let from = self.start;
        let to = (from + n).min(self.end);
        self.start = to;
        if self.start == self.end {
            // Keep the bytes readable: only the indices reset on the next push.
            self.idle_end = self.idle_end.min(self.start);
        }
        &mut self.buf[from..to]
    }
}

#[cfg(test)]
mod tests {
    use super::Window;

    #[test]
    fn a_full_window_drops_its_oldest_byte() {
        let mut w = Window::<4>::new();
        for b in 0..10 {
            w.push(b);
        }
        assert_eq!(w.avail(), [6, 7, 8, 9]);
        w.consume(1);
        w.push(10);
        assert_eq!(w.avail(), [7, 8, 9, 10]);
    }

    #[test]
    fn the_idle_mark_moves_with_the_bytes() {
        let mut w = Window::<4>::new();
        w.push(1);
        w.push(2);
        w.idle();
        w.consume(1);
        assert!(w.front_is_stale(), "byte 2 came before the gap");
        w.push(3);
        w.push(4);
        w.push(5); // compacts: 2 moves to the front
        assert_eq!(w.avail(), [2, 3, 4, 5]);
        assert!(w.front_is_stale());
        w.consume(1);
        assert!(!w.front_is_stale(), "3 came after the gap");
    }
}
