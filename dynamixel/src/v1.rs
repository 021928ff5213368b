//! Protocol 1.0 packets (AX series): `FF FF ID LEN CODE P1..Pn CHK`.
//!
//! `LEN = n + 2`; `CHK = ~(ID + LEN + CODE + ΣP) & 0xFF`. An instruction packet carries the
//! instruction in `CODE`, a status packet its error bits ([`error`]). The framing is the
//! same, so one [`Packet`] type and one [`Decoder`] serve both directions.

use crate::error::{DecodeError, EncodeError};
use crate::rx::{self, Window};

/// The two header bytes.
pub const HEADER: [u8; 2] = [0xFF, 0xFF];
/// The broadcast ID: every device executes, none answers.
pub const BROADCAST_ID: u8 = 0xFE;
/// The largest device ID.
pub const MAX_ID: u8 = 253;
/// Most parameters in one packet (`LEN` is one byte: 255 − 2).
pub const MAX_PARAMS: usize = 253;
/// Longest packet on the wire: header, ID, LEN and `LEN` = 255 bytes.
pub const MAX_PACKET: usize = 4 + 255;

/// Status packet error bits (AX-12A e-Manual, "Alarm LED / Shutdown"). Bit 7 is always 0.
pub mod error {
    /// Input voltage outside the voltage limits.
    pub const INPUT_VOLTAGE: u8 = 1 << 0;
    /// Goal position outside the CW/CCW angle limits.
    pub const ANGLE_LIMIT: u8 = 1 << 1;
    /// Internal temperature above the temperature limit.
    pub const OVERHEATING: u8 = 1 << 2;
    /// A value or address out of range.
    pub const RANGE: u8 = 1 << 3;
    /// The instruction packet's checksum did not match.
    pub const CHECKSUM: u8 = 1 << 4;
    /// The load cannot be held with the torque limit.
    pub const OVERLOAD: u8 = 1 << 5;
    /// Unknown instruction, or ACTION without a registered write.
    pub const INSTRUCTION: u8 = 1 << 6;
    /// The bits that report the actuator's state rather than the instruction's fate.
    pub const HARDWARE: u8 = INPUT_VOLTAGE | OVERHEATING | OVERLOAD;
}

/// One decoded packet: instruction (host → device) or status (device → host).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Packet<'a> {
    /// Device ID (or [`BROADCAST_ID`]).
    pub id: u8,
    /// Instruction, or the error bits of a status packet.
    pub code: u8,
    /// Parameters.
    pub params: &'a [u8],
}

/// `~(ID + LEN + CODE + ΣP) & 0xFF` (Protocol 1.0 checksum).
#[must_use]
pub fn checksum(id: u8, len: u8, code: u8, params: &[u8]) -> u8 {
    let sum = params
        .iter()
        .fold(id.wrapping_add(len).wrapping_add(code), |s, &p| {
            s.wrapping_add(p)
        });
    !sum
}

/// Encode a packet into `out`; returns its length.
///
/// # Errors
/// [`EncodeError::BadId`] for ID 0xFF, [`EncodeError::TooLong`] beyond [`MAX_PARAMS`],
/// [`EncodeError::BufferTooSmall`].
pub fn encode(id: u8, code: u8, params: &[u8], out: &mut [u8]) -> Result<usize, EncodeError> {
    if id > MAX_ID && id != BROADCAST_ID {
        return Err(EncodeError::BadId);
    }
    if params.len() > MAX_PARAMS {
        return Err(EncodeError::TooLong);
    }
    let total = params.len() + 6;
    let out = out.get_mut(..total).ok_or(EncodeError::BufferTooSmall)?;
    // MAX_PARAMS + 2 fits in a byte.
    let len = (params.len() + 2) as u8;
    out[..2].copy_from_slice(&HEADER);
    out[2] = id;
    out[3] = len;
    out[4] = code;
    out[5..5 + params.len()].copy_from_slice(params);
    out[total - 1] = checksum(id, len, code, params);
    Ok(total)
}

/// Streaming Protocol 1.0 decoder: feed bytes with [`Decoder::push`], tell it when the line
/// goes idle with [`Decoder::idle`], and take packets and errors from [`Decoder::next`]
/// until it returns `None`.
///
/// Bytes before a header are skipped silently. A candidate with a bad length or checksum,
/// or one that the idle line cut short, is reported once and scanning resumes at the byte
/// after its first header byte, so a packet hidden inside a damaged one is still found.
/// Never allocates; each byte costs O(1) except the checksum at a candidate's last byte.
pub type Decoder = rx::Decoder<Framing, { MAX_PACKET + 1 }>;

/// Protocol 1.0 packet framing, for [`Decoder`].
pub struct Framing;

impl rx::Framing for Framing {
    type Packet<'a> = Packet<'a>;

    fn next<const N: usize>(rx: &mut Window<N>) -> Option<Result<Packet<'_>, DecodeError>> {
        let total = loop {
            let a = rx.avail();
            match header(a) {
                Scan::Skip => rx.consume(1),
                Scan::Empty => return None,
                Scan::Need => {
                    if rx.front_is_stale() {
                        rx.consume(1);
                        return Some(Err(DecodeError::Truncated));
                    }
                    return None;
                }
                Scan::Header => {
                    let len = a[3];
                    if len < 2 {
                        rx.consume(1);
                        return Some(Err(DecodeError::BadLength));
                    }
                    let total = 4 + usize::from(len);
                    if a.len() < total {
                        if rx.front_is_stale() {
                            rx.consume(1);
                            return Some(Err(DecodeError::Truncated));
                        }
                        return None;
                    }
                    let (id, code) = (a[2], a[4]);
                    if checksum(id, len, code, &a[5..total - 1]) != a[total - 1] {
                        rx.consume(1);
                        return Some(Err(DecodeError::Checksum {
                            id,
                            instruction: code,
                        }));
                    }
                    break total;
                }
            }
        };
        let p = rx.take(total);
        Some(Ok(Packet {
            id: p[2],
            code: p[4],
            params: &p[5..total - 1],
        }))
    }
}

enum Scan {
    Empty,
    Skip,
    Need,
    Header,
}

/// Where the front of `a` stands: not a header start (skip a byte), a header with its ID and
/// length, or too short to tell.
fn header(a: &[u8]) -> Scan {
    match a {
        [] => Scan::Empty,
        [b, ..] if *b != 0xFF => Scan::Skip,
        [_] => Scan::Need,
        [_, b, ..] if *b != 0xFF => Scan::Skip,
        // `FF FF FF`: the header may start one byte later (ID 0xFF does not exist).
        [_, _, 0xFF, ..] => Scan::Skip,
        [_, _] | [_, _, _] => Scan::Need,
        _ => Scan::Header,
    }
}
