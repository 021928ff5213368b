//! One UART, two protocols: which received byte belongs to our framed protocol and which
//! to a Dynamixel packet.
//!
//! Our frames are COBS-encoded and end with 0x00; a COBS frame's first byte is the
//! distance to its first zero, at most `protocol::MAX_FRAME` (< 255), so a frame of ours
//! never starts with 0xFF. Every Dynamixel packet (1.0 and 2.0, instruction or status)
//! starts with `FF FF`. So at the start of a packet — after our 0x00 delimiter, after a
//! Dynamixel packet was decided, or after an idle line — `FF FF` opens a Dynamixel packet
//! and anything else opens one of our frames:
//!
//! * a Dynamixel packet runs until the bus device has decided it (decoded it, or rejected
//!   it by checksum, length or an idle line), whatever bytes it holds — 0x00 included;
//! * one of our frames runs to its 0x00 delimiter (or an idle line);
//! * a lone 0xFF followed by anything but 0xFF goes to our decoder with that byte (it is
//!   noise there, counted and answered as a bad frame, as before).

use core::mem;

/// Where a received byte goes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Route {
    /// Our framed protocol's decoder.
    Ours(u8),
    /// The Dynamixel bus device.
    Dynamixel(u8),
}

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
enum Mode {
    /// Between packets.
    #[default]
    Start,
    /// Between packets, one 0xFF held: the next byte decides.
    HeldFf,
    /// Inside one of our frames.
    Ours,
    /// Inside a Dynamixel packet.
    Dynamixel,
}

/// Splits the received bytes between the two protocols (see the module docs).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Splitter {
    mode: Mode,
}

impl Splitter {
    /// Between packets.
    #[must_use]
    pub const fn new() -> Self {
        Splitter { mode: Mode::Start }
    }

    /// Routes one received byte: none (a 0xFF held until the next byte), one, or two (the
    /// held 0xFF and this byte).
    pub fn route(&mut self, byte: u8) -> [Option<Route>; 2] {
        match (self.mode, byte) {
            (Mode::Start, 0xFF) => {
                self.mode = Mode::HeldFf;
                [None, None]
            }
            (Mode::Start, b) => {
                self.mode = if b == 0 { Mode::Start } else { Mode::Ours };
                [Some(Route::Ours(b)), None]
            }
            (Mode::HeldFf, 0xFF) => {
                self.mode = Mode::Dynamixel;
                [Some(Route::Dynamixel(0xFF)), Some(Route::Dynamixel(0xFF))]
            }
            (Mode::HeldFf, b) => {
                self.mode = if b == 0 { Mode::Start } else { Mode::Ours };
                [Some(Route::Ours(0xFF)), Some(Route::Ours(b))]
            }
            (Mode::Ours, b) => {
                if b == 0 {
                    self.mode = Mode::Start;
                }
                [Some(Route::Ours(b)), None]
            }
            (Mode::Dynamixel, b) => [Some(Route::Dynamixel(b)), None],
        }
    }

    /// The bus device has decided the packet (it holds no undecided bytes): the next byte
    /// starts a new packet.
    pub fn packet_decided(&mut self) {
        if self.mode == Mode::Dynamixel {
            self.mode = Mode::Start;
        }
    }

    /// The line went idle: whatever comes next starts a new packet (a held 0xFF is dropped).
    pub fn idle(&mut self) {
        let _ = mem::take(&mut self.mode);
    }

    /// Whether a Dynamixel packet is being received.
    #[must_use]
    pub fn in_dynamixel(&self) -> bool {
        matches!(self.mode, Mode::Dynamixel | Mode::HeldFf)
    }

    /// Whether a packet of either protocol is being received (the line is not free).
    #[must_use]
    pub fn in_packet(&self) -> bool {
        self.mode != Mode::Start
    }
}

#[cfg(test)]
mod tests {
    use super::{Route, Splitter};
    use protocol::{encode, Frame, Request};

    fn split(s: &mut Splitter, bytes: &[u8]) -> (Vec<u8>, Vec<u8>) {
        let (mut ours, mut dxl) = (Vec::new(), Vec::new());
        for &b in bytes {
            for r in s.route(b).into_iter().flatten() {
                match r {
                    Route::Ours(b) => ours.push(b),
                    Route::Dynamixel(b) => dxl.push(b),
                }
            }
        }
        (ours, dxl)
    }

    #[test]
    fn frames_of_ours_and_packets_alternate_on_one_line() {
        let mut buf = [0u8; protocol::MAX_FRAME];
        let n = encode(&Frame::new(7, Request::GetStatus), &mut buf).unwrap();
        let frame = &buf[..n];
        assert_ne!(frame[0], 0xFF);
        // A READ with zeros in it (ID 0, address 0).
        let packet = [0xFF, 0xFF, 0x00, 0x04, 0x02, 0x00, 0x02, 0xF7];
        let mut s = Splitter::new();
        let (ours, dxl) = split(&mut s, frame);
        assert_eq!((ours.as_slice(), dxl.len()), (frame, 0));
        let (ours, dxl) = split(&mut s, &packet);
        assert_eq!((ours.len(), dxl.as_slice()), (0, &packet[..]));
        s.packet_decided();
        let (ours, dxl) = split(&mut s, frame);
        assert_eq!((ours.as_slice(), dxl.len()), (frame, 0));
    }

    #[test]
    fn a_lone_ff_is_noise_for_our_decoder_and_an_idle_line_restarts() {
        let mut s = Splitter::new();
        assert_eq!(
            split(&mut s, &[0xFF, 0x05, 0x00]),
            (vec![0xFF, 0x05, 0x00], vec![])
        );
        let (_, dxl) = split(&mut s, &[0xFF, 0xFF, 0x01]);
        assert_eq!(dxl, [0xFF, 0xFF, 0x01]);
        s.idle();
        assert!(!s.in_dynamixel());
        assert_eq!(split(&mut s, &[0x03, 0x00]), (vec![0x03, 0x00], vec![]));
    }
}
