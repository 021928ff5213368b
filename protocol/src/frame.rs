//! Framing: postcard + CRC-32 + COBS, the encoder and the streaming decoder.

use core::marker::PhantomData;

use crc::Crc;
use serde::{de::DeserializeOwned, Deserialize, Serialize};

use crate::msg::{ErrorCode, Reply, Request, TelemetrySample};
use crate::{CRC_LEN, MAX_FRAME, MAX_PAYLOAD, MAX_TELEMETRY_FRAME, NO_SEQ, VERSION};

/// The frame CRC: CRC-32/ISO-HDLC (zlib's `crc32`), table-driven (1 KiB table in flash).
pub const CRC: Crc<u32> = Crc::<u32>::new(&crc::CRC_32_ISO_HDLC);

/// A message body that travels in a [`Frame`]: [`Request`] or [`Reply`].
pub trait Message: Serialize + DeserializeOwned + sealed::Sealed {
    /// Number of variants: a frame whose variant index is not below this is
    /// [`FrameError::UnknownMessage`].
    const VARIANTS: u32;
}

mod sealed {
    pub trait Sealed {}
    impl Sealed for crate::Request {}
    impl Sealed for crate::Reply {}
}

impl Message for Request {
    const VARIANTS: u32 = 26;
}

impl Message for Reply {
    const VARIANTS: u32 = 9;
}

/// One frame: version, sequence number, body (postcard-encoded in this order).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Frame<M> {
    /// Protocol version, [`VERSION`] for frames built with [`Frame::new`].
    pub version: u8,
    /// Sequence number: chosen by the requester, echoed by the reply.
    pub seq: u16,
    /// The message.
    pub body: M,
}

impl<M> Frame<M> {
    /// A frame of the current [`VERSION`].
    pub const fn new(seq: u16, body: M) -> Self {
        Frame {
            version: VERSION,
            seq,
            body,
        }
    }
}

/// Why bytes did not make a frame. Each bad frame gives exactly one of these.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum FrameError {
    /// More than [`MAX_PAYLOAD`] decoded bytes before a 0x00: reported once, when the buffer
    /// overflows; the rest of the frame up to the next 0x00 is skipped silently.
    Overflow,
    /// Not valid COBS (a 0x00 inside a COBS block).
    Cobs,
    /// Too short to hold anything but a CRC (at most [`CRC_LEN`] bytes after COBS).
    Truncated,
    /// The CRC-32 does not match.
    Crc,
    /// CRC good, but the version is not [`VERSION`]. `seq` is recovered when the header
    /// decodes (its layout is the same in every version).
    Version {
        /// The version byte received.
        found: u8,
        /// The frame's `seq`, if it decoded.
        seq: Option<u16>,
    },
    /// CRC and version good, but the variant index is not a known message.
    UnknownMessage {
        /// The frame's `seq`.
        seq: u16,
        /// The variant index received.
        index: u32,
    },
    /// CRC good, but postcard could not decode the header or the body, or bytes follow the
    /// body.
    Decode {
        /// The frame's `seq`, if the header decoded.
        seq: Option<u16>,
    },
}

impl FrameError {
    /// The `seq` of the bad frame, when it can be trusted (the CRC matched and the header
    /// decoded).
    #[must_use]
    pub const fn seq(&self) -> Option<u16> {
        match *self {
            FrameError::Version { seq, .. } | FrameError::Decode { seq } => seq,
            FrameError::UnknownMessage { seq, .. } => Some(seq),
            FrameError::Overflow | FrameError::Cobs | FrameError::Truncated | FrameError::Crc => {
                None
            }
        }
    }

    /// The error code of the reply to this frame.
    #[must_use]
    pub const fn code(&self) -> ErrorCode {
        match self {
            FrameError::Overflow
            | FrameError::Cobs
            | FrameError::Truncated
            | FrameError::Decode { .. } => ErrorCode::BadFrame,
            FrameError::Crc => ErrorCode::BadCrc,
            FrameError::Version { .. } => ErrorCode::UnsupportedVersion,
            FrameError::UnknownMessage { .. } => ErrorCode::UnknownMessage,
        }
    }

    /// The reply to this frame: an error with [`FrameError::seq`], or [`NO_SEQ`].
    #[must_use]
    pub const fn reply(&self) -> Frame<Reply> {
        let seq = match self.seq() {
            Some(s) => s,
            None => NO_SEQ,
        };
        Frame::new(seq, Reply::Error(self.code()))
    }
}

impl core::fmt::Display for FrameError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            FrameError::Overflow => write!(f, "frame longer than {MAX_PAYLOAD} bytes"),
            FrameError::Cobs => f.write_str("invalid COBS"),
            FrameError::Truncated => f.write_str("frame too short"),
            FrameError::Crc => f.write_str("CRC mismatch"),
            FrameError::Version { found, .. } => {
                write!(f, "protocol version {found}, expected {VERSION}")
            }
            FrameError::UnknownMessage { index, .. } => write!(f, "unknown message {index}"),
            FrameError::Decode { .. } => f.write_str("undecodable message"),
        }
    }
}

impl core::error::Error for FrameError {}

/// Why a frame could not be encoded.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum EncodeError {
    /// The output buffer is too small (a [`MAX_FRAME`]-byte buffer always fits).
    BufferTooSmall,
    /// The message does not fit [`MAX_PAYLOAD`] (cannot happen for this crate's messages).
    TooLarge,
}

impl core::fmt::Display for EncodeError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            EncodeError::BufferTooSmall => "output buffer too small",
            EncodeError::TooLarge => "message larger than the maximum payload",
        })
    }
}

impl core::error::Error for EncodeError {}

/// An encoded frame, delimiter included.
pub type FrameBuf = heapless::Vec<u8, MAX_FRAME>;

/// An encoded telemetry frame, delimiter included (the element of the firmware's bounded
/// telemetry queue).
pub type TelemetryFrameBuf = heapless::Vec<u8, MAX_TELEMETRY_FRAME>;

/// Encodes `frame` into `out` (COBS, 0x00-terminated) and returns the number of bytes
/// written, at most [`MAX_FRAME`].
///
/// # Errors
/// [`EncodeError::BufferTooSmall`] if `out` is too small (never for [`MAX_FRAME`] bytes).
pub fn encode<M: Message>(frame: &Frame<M>, out: &mut [u8]) -> Result<usize, EncodeError> {
    let mut data = [0u8; MAX_PAYLOAD - CRC_LEN];
    let n = postcard::to_slice(frame, &mut data)
        .map_err(|_| EncodeError::TooLarge)?
        .len();
    encode_raw(data.get(..n).ok_or(EncodeError::TooLarge)?, out)
}

/// Frames arbitrary bytes as if they were a postcard-encoded [`Frame`]: appends the
/// CRC-32, COBS-encodes, terminates with 0x00; returns the bytes written. For tests and
/// diagnostic tools that need frames with a good CRC around any content.
///
/// # Errors
/// [`EncodeError::TooLarge`] if `data` is longer than [`MAX_PAYLOAD`] − [`CRC_LEN`];
/// [`EncodeError::BufferTooSmall`] if `out` is too small.
pub fn encode_raw(data: &[u8], out: &mut [u8]) -> Result<usize, EncodeError> {
    let mut payload = [0u8; MAX_PAYLOAD];
    let n = data.len();
    let (head, rest) = payload
        .split_at_mut_checked(n)
        .ok_or(EncodeError::TooLarge)?;
    head.copy_from_slice(data);
    rest.get_mut(..CRC_LEN)
        .ok_or(EncodeError::TooLarge)?
        .copy_from_slice(&CRC.checksum(data).to_le_bytes());
    let payload = payload
        .get(..n.saturating_add(CRC_LEN))
        .ok_or(EncodeError::TooLarge)?;
    let len = cobs::try_encode(payload, out).map_err(|_| EncodeError::BufferTooSmall)?;
    *out.get_mut(len).ok_or(EncodeError::BufferTooSmall)? = 0;
    Ok(len.saturating_add(1)) // len < out.len(): never saturates
}

/// [`encode`] into a bounded vector.
///
/// # Errors
/// [`EncodeError::TooLarge`] never for this crate's messages.
pub fn encode_to_vec<M: Message>(frame: &Frame<M>) -> Result<FrameBuf, EncodeError> {
    let mut buf = [0u8; MAX_FRAME];
    let n = encode(frame, &mut buf)?;
    FrameBuf::from_slice(buf.get(..n).ok_or(EncodeError::TooLarge)?)
        .map_err(|_| EncodeError::TooLarge)
}

/// Encodes a telemetry sample as a [`Reply::Telemetry`] frame into `out`; `seq` is the
/// telemetry counter (see [`Reply::Telemetry`]). Returns the bytes written, at most
/// [`MAX_TELEMETRY_FRAME`].
///
/// # Errors
/// [`EncodeError::BufferTooSmall`] if `out` is too small (never for
/// [`MAX_TELEMETRY_FRAME`] bytes).
pub fn encode_telemetry(
    seq: u16,
    sample: &TelemetrySample,
    out: &mut [u8],
) -> Result<usize, EncodeError> {
    encode(&Frame::new(seq, Reply::Telemetry(*sample)), out)
}

/// [`encode_telemetry`] into a bounded vector, ready for a telemetry queue.
///
/// # Errors
/// [`EncodeError::TooLarge`] never.
pub fn telemetry_frame(
    seq: u16,
    sample: &TelemetrySample,
) -> Result<TelemetryFrameBuf, EncodeError> {
    let mut buf = [0u8; MAX_TELEMETRY_FRAME];
    let n = encode_telemetry(seq, sample, &mut buf)?;
    TelemetryFrameBuf::from_slice(buf.get(..n).ok_or(EncodeError::TooLarge)?)
        .map_err(|_| EncodeError::TooLarge)
}

/// Decodes one COBS-decoded payload (postcard frame + CRC, no delimiter).
///
/// # Errors
/// [`FrameError::Truncated`], [`FrameError::Crc`], [`FrameError::Version`],
/// [`FrameError::UnknownMessage`] or [`FrameError::Decode`].
pub fn decode_payload<M: Message>(payload: &[u8]) -> Result<Frame<M>, FrameError> {
    let (data, crc) = payload
        .split_last_chunk::<CRC_LEN>()
        .ok_or(FrameError::Truncated)?;
    if CRC.checksum(data) != u32::from_le_bytes(*crc) {
        return Err(FrameError::Crc);
    }
    let (version, rest) = data.split_first().ok_or(FrameError::Truncated)?;
    // From here on the CRC matched: the frame is what the peer sent.
    let seq_and_rest = postcard::take_from_bytes::<u16>(rest).ok();
    let seq = seq_and_rest.map(|(s, _)| s);
    if *version != VERSION {
        return Err(FrameError::Version {
            found: *version,
            seq,
        });
    }
    let (seq, body) = seq_and_rest.ok_or(FrameError::Decode { seq: None })?;
    let (index, _) = postcard::take_from_bytes::<u32>(body)
        .map_err(|_| FrameError::Decode { seq: Some(seq) })?;
    if index >= M::VARIANTS {
        return Err(FrameError::UnknownMessage { seq, index });
    }
    match postcard::take_from_bytes::<M>(body) {
        Ok((msg, [])) => Ok(Frame {
            version: *version,
            seq,
            body: msg,
        }),
        _ => Err(FrameError::Decode { seq: Some(seq) }),
    }
}

/// Streaming frame decoder, fed one byte at a time (e.g. from a UART receive interrupt).
///
/// Holds at most [`MAX_PAYLOAD`] decoded bytes; never allocates. COBS is undone byte by
/// byte; the CRC and postcard run when the 0x00 delimiter arrives. Each non-empty
/// 0x00-delimited chunk of input yields exactly one `Ok(Some(frame))` or one `Err(_)`; an
/// over-long chunk yields [`FrameError::Overflow`] as soon as it overflows and nothing at
/// its 0x00. After an error the decoder has already resynchronised: it starts afresh after
/// the next 0x00.
#[derive(Debug)]
pub struct Decoder<M> {
    cobs: cobs::DecoderState,
    buf: heapless::Vec<u8, MAX_PAYLOAD>,
    skipping: bool,
    _msg: PhantomData<fn() -> M>,
}

impl<M: Message> Default for Decoder<M> {
    fn default() -> Self {
        Self::new()
    }
}

impl<M: Message> Decoder<M> {
    /// An idle decoder (`const`: it can live in a `static`).
    #[must_use]
    pub const fn new() -> Self {
        Decoder {
            cobs: cobs::DecoderState::Idle,
            buf: heapless::Vec::new(),
            skipping: false,
            _msg: PhantomData,
        }
    }

    /// Drops any partial frame; the next byte starts a new frame.
    pub fn reset(&mut self) {
        self.cobs = cobs::DecoderState::Idle;
        self.buf.clear();
        self.skipping = false;
    }

    /// Whether the decoder is between frames (no partial frame buffered or being skipped).
    #[must_use]
    pub fn is_idle(&self) -> bool {
        matches!(self.cobs, cobs::DecoderState::Idle) && !self.skipping
    }

    /// Feeds one received byte.
    ///
    /// Returns `Ok(Some(frame))` when `byte` completes a good frame, `Ok(None)` when more
    /// bytes are needed (or an empty frame was skipped).
    ///
    /// # Errors
    /// One [`FrameError`] per bad frame (see the type docs).
    pub fn feed(&mut self, byte: u8) -> Result<Option<Frame<M>>, FrameError> {
        if self.skipping {
            if byte == 0 {
                self.reset();
            }
            return Ok(None);
        }
        match self.cobs.feed(byte) {
            Ok(cobs::DecodeResult::NoData) => Ok(None),
            Ok(cobs::DecodeResult::DataContinue(b)) => {
                if self.buf.push(b).is_err() {
                    self.reset();
                    // A 0x00 cannot reach here (it ends the frame), so skip to the next one.
                    self.skipping = true;
                    return Err(FrameError::Overflow);
                }
                Ok(None)
            }
            Ok(cobs::DecodeResult::DataComplete) => {
                let result = decode_payload::<M>(&self.buf);
                self.reset();
                result.map(Some)
            }
            Err(_) => {
                // Only a 0x00 inside a block gets here: the frame ended, start afresh.
                self.reset();
                Err(FrameError::Cobs)
            }
        }
    }
}
