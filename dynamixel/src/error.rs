//! Errors of the packet codecs and of instruction execution, shared by both protocols.

use core::fmt;

/// Why a run of received bytes did not make a packet. The decoders report one per rejected
/// candidate and go on scanning at the byte after its first header byte.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum DecodeError {
    /// A complete packet whose checksum (1.0) or CRC (2.0) does not match. `id` and
    /// `instruction` are as received: they may be the corrupted bytes.
    Checksum {
        /// The ID byte received.
        id: u8,
        /// The instruction byte received (1.0: also the error byte of a status packet).
        instruction: u8,
    },
    /// The length field is below the smallest packet (1.0: 2; 2.0: 3).
    BadLength,
    /// The length field announces more than the decoder holds (2.0 only: 1.0 packets always
    /// fit).
    TooLong,
    /// The line went idle ([`crate::v1::Decoder::idle`]) before the packet was complete.
    Truncated,
    /// 2.0: a packet with a good CRC where `FF FF FD` is not followed by the stuffing `FD`.
    Stuffing,
}

impl fmt::Display for DecodeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            DecodeError::Checksum { id, instruction } => {
                write!(
                    f,
                    "checksum mismatch (id {id}, instruction 0x{instruction:02x})"
                )
            }
            DecodeError::BadLength => f.write_str("length field below the smallest packet"),
            DecodeError::TooLong => f.write_str("length field beyond the decoder's buffer"),
            DecodeError::Truncated => f.write_str("packet cut short by an idle line"),
            DecodeError::Stuffing => f.write_str("missing byte stuffing after FF FF FD"),
        }
    }
}

/// Why a packet could not be encoded.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum EncodeError {
    /// The output buffer is too small for the packet.
    BufferTooSmall,
    /// The parameters exceed what the length field (or, 2.0, [`crate::v2::MAX_PACKET`])
    /// allows.
    TooLong,
    /// The ID is not a valid packet ID (1.0: 0–253 or 0xFE; 2.0: 0–252 or 0xFE).
    BadId,
}

impl fmt::Display for EncodeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            EncodeError::BufferTooSmall => f.write_str("output buffer too small"),
            EncodeError::TooLong => f.write_str("too many parameters for one packet"),
            EncodeError::BadId => f.write_str("invalid packet id"),
        }
    }
}

/// Why the device refused an instruction, independent of the protocol: each protocol maps
/// it onto its status error ([`Refusal::v1_bits`], [`Refusal::v2_code`]). Backends return
/// it from [`crate::Backend::check`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum Refusal {
    /// Unknown instruction, malformed parameters, or ACTION with nothing registered.
    Instruction,
    /// A write to a read-only or undefined address, a read beyond the table, or an EEPROM
    /// write while the EEPROM is locked (1.0 Lock, 2.0 torque enabled).
    Access,
    /// A value outside the register's range.
    Range,
    /// A goal outside the angle (1.0) or position (2.0) limits.
    Limit,
    /// A write that covers part of a multi-byte register, or a zero-length read or write.
    Length,
    /// The actuator could not carry out a valid request.
    Failed,
}

impl Refusal {
    /// The Protocol 1.0 error bits for this refusal ([`crate::v1::error`]).
    #[must_use]
    pub const fn v1_bits(self) -> u8 {
        use crate::v1::error;
        match self {
            Refusal::Instruction => error::INSTRUCTION,
            Refusal::Limit => error::ANGLE_LIMIT,
            Refusal::Access | Refusal::Range | Refusal::Length | Refusal::Failed => error::RANGE,
        }
    }

    /// The Protocol 2.0 error number for this refusal.
    #[must_use]
    pub const fn v2_code(self) -> crate::v2::ErrorCode {
        use crate::v2::ErrorCode;
        match self {
            Refusal::Instruction => ErrorCode::Instruction,
            Refusal::Access => ErrorCode::Access,
            Refusal::Range => ErrorCode::DataRange,
            Refusal::Limit => ErrorCode::DataLimit,
            Refusal::Length => ErrorCode::DataLength,
            Refusal::Failed => ErrorCode::ResultFail,
        }
    }
}

impl fmt::Display for Refusal {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Refusal::Instruction => "instruction error",
            Refusal::Access => "access error",
            Refusal::Range => "value out of range",
            Refusal::Limit => "goal outside the limits",
            Refusal::Length => "partial register or empty data",
            Refusal::Failed => "the actuator could not carry it out",
        })
    }
}
