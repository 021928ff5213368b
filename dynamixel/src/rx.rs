//! The receive window both decoders scan: a fixed buffer of the bytes not yet consumed,
//! and the idle mark that says which of them arrived before the line last went quiet.

/// Received bytes `buf[start..end]`, of which `buf[start..idle_end]` came before the last
/// idle gap: a packet never spans an idle gap, so a candidate that starts there and is
/// incomplete is truncated.
pub(crate) struct Window<const N: usize> {
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
    pub(crate) fn push(&mut self, byte: u8) {
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
    pub(crate) fn idle(&mut self) {
        self.idle_end = self.end;
    }

    /// Forget everything.
    pub(crate) fn clear(&mut self) {
        self.start = 0;
        self.end = 0;
        self.idle_end = 0;
    }

    /// The unconsumed bytes.
    pub(crate) fn avail(&self) -> &[u8] {
        &self.buf[self.start..self.end]
    }

    /// Drop the first `n` unconsumed bytes.
    pub(crate) fn consume(&mut self, n: usize) {
        self.start = (self.start + n).min(self.end);
        if self.start == self.end {
            self.start = 0;
            self.end = 0;
            self.idle_end = 0;
        }
    }

    /// Whether the candidate at the front started before the last idle gap (so it can no
    /// longer complete).
    pub(crate) fn front_is_stale(&self) -> bool {
        self.start < self.idle_end
    }

    /// Consume the `n`-byte packet at the front and give mutable access to its bytes (they
    /// stay in place until the next [`Window::push`]).
    pub(crate) fn take(&mut self, n: usize) -> &mut [u8] {
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
