//! Protocol 2.0 packets (X series): `FF FF FD 00 ID LEN_L LEN_H INST P1..Pn CRC_L CRC_H`.
//!
//! * `LEN` = the stuffed length of `INST P1..Pn` + 2 (the CRC).
//! * Byte stuffing: inside `INST P1..Pn`, every `FF FF FD` is sent as `FF FF FD FD`, so the
//!   header `FF FF FD 00` never appears inside a packet.
//! * CRC: CRC-16/UMTS (poly 0x8005, init 0, not reflected, xorout 0; the `crc` crate's
//!   `CRC_16_UMTS`) over every byte before it, stuffed, sent little-endian.
//! * A status packet has `INST` = [`STATUS`] and the error byte as its first parameter
//!   ([`ErrorCode`], bit 7 [`ALERT`]).

use crate::error::{DecodeError, EncodeError};
use crate::rx::{self, Window};
use crc::{Crc, CRC_16_UMTS};

/// The four header bytes (the fourth is the reserved byte, 0x00).
pub const HEADER: [u8; 4] = [0xFF, 0xFF, 0xFD, 0x00];
/// The broadcast ID.
pub const BROADCAST_ID: u8 = 0xFE;
/// The largest device ID.
pub const MAX_ID: u8 = 252;
/// The instruction byte of a status packet.
pub const STATUS: u8 = 0x55;
/// Bit 7 of a status packet's error byte: the device has a hardware error (see its Hardware
/// Error Status register).
pub const ALERT: u8 = 0x80;
/// Longest packet on the wire, header and CRC included: 1024 bytes, the `dynamixel-sdk`'s
/// own limit (`TXPACKET_MAX_LEN`).
pub const MAX_PACKET: usize = 1024;

/// The Protocol 2.0 CRC.
pub const CRC: Crc<u16> = Crc::<u16>::new(&CRC_16_UMTS);

/// A status packet's error number (bits 0–6 of the error byte).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[repr(u8)]
pub enum ErrorCode {
    /// The instruction could not be processed.
    ResultFail = 1,
    /// Unknown instruction, or ACTION without REG WRITE.
    Instruction = 2,
    /// The instruction packet's CRC did not match.
    Crc = 3,
    /// A value outside the register's range.
    DataRange = 4,
    /// Data shorter than the register (part of a multi-byte register).
    DataLength = 5,
    /// A value outside a limit register (goal outside the position limits).
    DataLimit = 6,
    /// Read-only or undefined address, or an EEPROM write with torque enabled.
    Access = 7,
}

/// One decoded packet, unstuffed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Packet<'a> {
    /// Device ID (or [`BROADCAST_ID`]).
    pub id: u8,
    /// Instruction ([`STATUS`] for a status packet).
    pub instruction: u8,
    /// Parameters (a status packet: the error byte, then the data).
    pub params: &'a [u8],
}

/// Encode an instruction packet into `out`; returns its length.
///
/// # Errors
/// [`EncodeError::BadId`], [`EncodeError::TooLong`] beyond [`MAX_PACKET`],
/// [`EncodeError::BufferTooSmall`].
pub fn encode(
    id: u8,
    instruction: u8,
    params: &[u8],
    out: &mut [u8],
) -> Result<usize, EncodeError> {
    encode_parts(id, &[&[instruction], params], out)
}

/// Encode a status packet (`INST` = [`STATUS`], then `error`, then `data`).
///
/// # Errors
/// As [`encode`].
pub fn encode_status(id: u8, error: u8, data: &[u8], out: &mut [u8]) -> Result<usize, EncodeError> {
    encode_parts(id, &[&[STATUS, error], data], out)
}

/// Encode the concatenation of `parts` (instruction first) as one packet.
fn encode_parts(id: u8, parts: &[&[u8]], out: &mut [u8]) -> Result<usize, EncodeError> {
    if id > MAX_ID && id != BROADCAST_ID {
        return Err(EncodeError::BadId);
    }
    let mut w = 7;
    let mut run = 0u8; // consecutive 0xFF just written
    for &b in parts.iter().flat_map(|p| p.iter()) {
        put(out, &mut w, b)?;
        if b == 0xFD && run >= 2 {
            put(out, &mut w, 0xFD)?;
            run = 0;
        } else if b == 0xFF {
            run = run.saturating_add(1);
        } else {
            run = 0;
        }
    }
    let total = w + 2;
    if total > MAX_PACKET {
        return Err(EncodeError::TooLong);
    }
    if out.len() < total {
        return Err(EncodeError::BufferTooSmall);
    }
    // total ≤ MAX_PACKET < 65 536.
    let len = (total - 7) as u16;
    out[..4].copy_from_slice(&HEADER);
    out[4] = id;
    out[5..7].copy_from_slice(&len.to_le_bytes());
    let crc = CRC.checksum(&out[..w]);
    out[w..total].copy_from_slice(&crc.to_le_bytes());
    Ok(total)
}

fn put(out: &mut [u8], w: &mut usize, b: u8) -> Result<(), EncodeError> {
    if *w + 2 >= MAX_PACKET {
        return Err(EncodeError::TooLong);
    }
    *out.get_mut(*w).ok_or(EncodeError::BufferTooSmall)? = b;
    *w += 1;
    Ok(())
}

/// Remove the stuffing from `bytes` in place; returns the unstuffed length, or `None` when
/// an `FF FF FD` is not followed by its stuffing `FD`.
fn unstuff(bytes: &mut [u8]) -> Option<usize> {
    let mut w = 0;
    let mut run = 0u8;
    let mut skip = false;
    for r in 0..bytes.len() {
        let b = bytes[r];
        if skip {
            if b != 0xFD {
                return None;
            }
            skip = false;
            continue;
        }
        bytes[w] = b;
        w += 1;
        if b == 0xFD && run >= 2 {
            skip = true;
            run = 0;
        } else if b == 0xFF {
            run = run.saturating_add(1);
        } else {
            run = 0;
        }
    }
    (!skip).then_some(w)
}

/// Streaming Protocol 2.0 decoder, used like [`crate::v1::Decoder`]: [`Decoder::push`]
/// each byte, [`Decoder::idle`] when the line goes quiet, [`Decoder::next`] until `None`.
///
/// A candidate is rejected (and reported once) for a bad length, a length beyond
/// [`MAX_PACKET`], a CRC mismatch, bad stuffing or an idle line before its end; scanning
/// then resumes one byte after its header. Stuffing guarantees that a valid packet holds no
/// header, so a rejected candidate never hides a valid packet's start inside a longer one.
pub type Decoder = rx::Decoder<Framing, { MAX_PACKET }>;

/// Protocol 2.0 packet framing, for [`Decoder`].
pub struct Framing;

impl rx::Framing for Framing {
    type Packet<'a> = Packet<'a>;

    fn next<const N: usize>(rx: &mut Window<N>) -> Option<Result<Packet<'_>, DecodeError>> {
        let total = loop {
            let a = rx.avail();
            let need = match a {
                [] => return None,
                [b, ..] if *b != 0xFF => None,
                [_, b, ..] if *b != 0xFF => None,
                [_, _, b, ..] if *b != 0xFD => None,
                [_, _, _, b, ..] if *b != 0x00 => None,
                // IDs 0xFD and 0xFF are never used (they would look like a header).
                [_, _, _, _, 0xFD | 0xFF, ..] => None,
                _ if a.len() < 7 => Some(7),
                _ => {
                    let len = usize::from(u16::from_le_bytes([a[5], a[6]]));
                    if len < 3 {
                        rx.consume(1);
                        return Some(Err(DecodeError::BadLength));
                    }
                    if len + 7 > MAX_PACKET {
                        rx.consume(1);
                        return Some(Err(DecodeError::TooLong));
                    }
                    Some(len + 7)
                }
            };
            let Some(total) = need else {
                rx.consume(1);
                continue;
            };
            if a.len() < total {
                if rx.front_is_stale() {
                    rx.consume(1);
                    return Some(Err(DecodeError::Truncated));
                }
                return None;
            }
            let crc = u16::from_le_bytes([a[total - 2], a[total - 1]]);
            if CRC.checksum(&a[..total - 2]) != crc {
                let (id, instruction) = (a[4], a[7]);
                rx.consume(1);
                return Some(Err(DecodeError::Checksum { id, instruction }));
            }
            break total;
        };
        let p = rx.take(total);
        let id = p[4];
        let body = &mut p[7..total - 2];
        let Some(n) = unstuff(body) else {
            return Some(Err(DecodeError::Stuffing));
        };
        let body = &p[7..7 + n];
        Some(Ok(Packet {
            id,
            instruction: body[0],
            params: &body[1..],
        }))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stuffing_round_trip_on_the_tricky_runs() {
        for src in [
            &[0xFFu8, 0xFF, 0xFD][..],
            &[0xFF, 0xFF, 0xFD, 0xFD],
            &[0xFF, 0xFF, 0xFF, 0xFD, 0xFF, 0xFF, 0xFD],
            &[0xFD, 0xFF, 0xFD, 0xFF, 0xFF],
        ] {
            let mut out = [0u8; 64];
            let n = encode(1, 0x03, src, &mut out).unwrap();
            let mut d = Decoder::new();
            for &b in &out[..n] {
                d.push(b);
            }
            let p = d.next().unwrap().unwrap();
            assert_eq!(p.params, src);
        }
    }
}
