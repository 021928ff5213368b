//! Command and telemetry protocol of the vsa actuator, shared by the firmware and the host.
//!
//! `no_std`, allocation-free, `unsafe`-free and panic-free on every input.
//!
//! # Frames
//!
//! ```text
//! wire    = COBS(payload) 0x00
//! payload = postcard(Frame { version: u8, seq: u16, body }) ++ crc32_le(postcard bytes)
//! ```
//!
//! * `version` is [`VERSION`]. It is the first byte of every frame and `seq` (a postcard
//!   varint) follows it in every version, so a peer can always echo the `seq` of a frame
//!   whose version it does not speak.
//! * `seq` is chosen by the requester; the reply to a request carries the same `seq`.
//!   [`NO_SEQ`] (0) is reserved for error replies to frames whose `seq` cannot be trusted
//!   (bad COBS, bad CRC, too long, too short, undecodable header): hosts number their
//!   requests from 1 and skip 0 when the counter wraps. Telemetry frames are unsolicited and
//!   carry a telemetry counter instead (see [`Reply::Telemetry`]).
//! * `body` is a [`Request`] (host → device) or a [`Reply`] (device → host), postcard
//!   encoded: the variant index as a varint, then the fields, integers as varints (signed
//!   ones zig-zag encoded).
//! * The CRC is **CRC-32/ISO-HDLC** (the zlib/Ethernet CRC-32: poly 0x04C11DB7, reflected,
//!   init and xorout 0xFFFF_FFFF, check value 0xCBF4_3926 for `"123456789"`), over the
//!   postcard bytes, appended little-endian. 32 bits rather than 16 because the line also
//!   carries garbage (a random 0x00-delimited chunk passes a 16-bit CRC once in 65 536).
//! * COBS (consistent overhead byte stuffing) removes every 0x00 from the payload, so 0x00
//!   only ever ends a frame and a receiver resynchronises at the next 0x00 whatever it got
//!   before. Empty frames (0x00 0x00) are ignored: a sender may send a 0x00 first to flush
//!   a partial frame at the receiver.
//!
//! Every buffer is bounded: a frame is at most [`MAX_FRAME`] bytes on the wire including
//! its delimiter, its decoded payload at most [`MAX_PAYLOAD`] bytes.
//!
//! # Units on the wire
//!
//! Every quantity is an integer in a scaled SI unit, named by its field's suffix:
//!
//! | suffix | unit | type |
//! |---|---|---|
//! | `_um` | micrometre (clutch length) | `u32` |
//! | `_mnm_per_rad` | mN·m/rad (joint stiffness) | `u32` |
//! | `_urad` | microradian (angles, link side unless stated) | `i32`/`u32` |
//! | `_ms` | millisecond (durations; `tick` counts 1 kHz control ticks = ms) | `u32` |
//! | `_mhz` | millihertz (sine frequency) | `u32` |
//! | `_hz` | hertz (telemetry rate) | `u16` |
//! | `_ma` | milliampere (motor current) | `i16`/`u16` |
//! | `_unm` | µN·m (torque) | `i32`/`u32` |
//! | `_unms_per_rad` | µN·m·s/rad (damping) | `u32` |
//! | `_permille` | ‰ (PWM duty: ±1000 = ± the supply; ratios) | `i16`/`u16` |
//! | gains | 10⁻³ of the controller's units (see [`Gains`]) | `u64` |
//!
//! The ranges a request must satisfy are checked by [`Request::validate`]; the constants
//! below name them.
//!
//! # Receiving and handling requests
//!
//! [`Decoder`] is fed one byte at a time (from a UART receive interrupt): it never
//! allocates, does O(1) work per byte except at the delimiter (CRC and postcard over at most
//! [`MAX_PAYLOAD`] bytes), and returns each frame, or one [`FrameError`] per bad frame, when
//! its 0x00 arrives (an over-long frame is reported when it overflows and its rest is
//! skipped up to the next 0x00).
//!
//! [`Handler`] turns each decoder result into exactly one reply frame. Side effects go
//! through the [`Device`] trait, which the firmware implements; a frame that does not decode
//! or a request that fails [`Request::validate`] never reaches the device and only counts in
//! [`Handler::errors`].
//!
//! # Example
//!
//! ```
//! use protocol::{encode, Decoder, Frame, Request, MAX_FRAME};
//!
//! let mut wire = [0u8; MAX_FRAME];
//! let n = encode(&Frame::new(7, Request::Move { target_urad: 500_000, duration_ms: 300 }), &mut wire)?;
//! let mut rx = Decoder::<Request>::new();
//! let mut got = None;
//! for &b in &wire[..n] {
//!     if let Some(frame) = rx.feed(b)? {
//!         got = Some(frame);
//!     }
//! }
//! assert_eq!(got, Some(Frame::new(7, Request::Move { target_urad: 500_000, duration_ms: 300 })));
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
#![no_std]
#![forbid(unsafe_code)]
#![deny(missing_docs)]
#![deny(
    clippy::indexing_slicing,
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic
)]

mod bus;
mod calibration;
mod frame;
mod handler;
mod msg;
mod replay;
mod sensors;

pub use bus::BusChange;
pub use calibration::{Calibration, CalibrationProgress, CalibrationReport};
pub use frame::{
    decode_payload, encode, encode_raw, encode_telemetry, encode_to_vec, telemetry_frame, Decoder,
    EncodeError, Frame, FrameBuf, FrameError, Message, TelemetryFrameBuf, CRC,
};
pub use handler::{Device, ErrorCounters, Handler};
pub use msg::{
    ErrorCode, FaultCode, FaultRecord, FaultSet, Gains, LimitFlags, Limits, LoggedFault, Reply,
    Request, State, Status, TelemetrySample,
};
pub use replay::ReplyCache;
pub use sensors::{RawSensors, NUDGE_DURATION_MAX_MS, NUDGE_DUTY_MAX_PERMILLE};

/// Protocol version carried in every frame. A frame with another version is answered with
/// [`ErrorCode::UnsupportedVersion`] (echoing its `seq`).
pub const VERSION: u8 = 1;

/// `seq` of an error reply to a frame whose own `seq` could not be recovered.
pub const NO_SEQ: u16 = 0;

/// Bytes of the CRC-32 that ends every payload.
pub const CRC_LEN: usize = 4;

/// Largest postcard encoding of a [`Frame`] header: version (1) + `seq` varint (3).
pub const MAX_HEADER: usize = 1 + 3;

/// Largest postcard encoding of a [`Request`] body: `SetGains`, tag (1) + 3 × u64 (10).
pub const MAX_REQUEST_BODY: usize = 1 + 3 * 10;

/// Largest postcard encoding of a [`Reply`] body: `Status`, tag (1) + 53.
///
/// state 1, faults 3, first fault 1 + (code 1 + value 5 + tick 5), limits 1, clutch 5,
/// stiffness 5, clutch tolerance 3, tick 5, moving 1, telemetry rate 3, telemetry dropped
/// 5, protocol errors 5, differs from stored 1, calibration progress 3 (the calibration
/// report is 1 + 52).
pub const MAX_REPLY_BODY: usize = 1 + 53;

/// Largest postcard encoding of a telemetry reply body: tag (1) + 35 (see
/// [`TelemetrySample`]).
pub const MAX_TELEMETRY_BODY: usize = 1 + 35;

/// Largest decoded payload (header + body + CRC) of any frame, either direction, bytes.
/// A receiver that collects more than this before a 0x00 reports [`FrameError::Overflow`].
pub const MAX_PAYLOAD: usize = MAX_HEADER + max(MAX_REQUEST_BODY, MAX_REPLY_BODY) + CRC_LEN;

/// Largest frame on the wire, bytes: COBS adds one byte per started 254 bytes of payload,
/// plus the 0x00 delimiter. Encode into a buffer of this size and it always fits.
pub const MAX_FRAME: usize = cobs_max(MAX_PAYLOAD) + 1;

/// Largest telemetry frame on the wire, delimiter included, bytes.
pub const MAX_TELEMETRY_FRAME: usize = cobs_max(MAX_HEADER + MAX_TELEMETRY_BODY + CRC_LEN) + 1;

/// Clutch length range accepted by [`Request::SetClutchLength`], µm: 1–8 mm. 8 mm is the
/// whole usable beam length l of the paper preset (docs/design.md §2.2); the paper's own design
/// range is 1–5 mm. The firmware may refuse lengths its configured design cannot reach
/// ([`ErrorCode::OutOfRange`] from the [`Device`]).
pub const CLUTCH_MIN_UM: u32 = 1_000;
/// Upper end of the clutch length range, µm (see [`CLUTCH_MIN_UM`]).
pub const CLUTCH_MAX_UM: u32 = 8_000;

/// Smallest stiffness accepted by [`Request::SetStiffness`], mN·m/rad (> 0). Whether the
/// model's inverse L(k) lands in the clutch range is the device's check.
pub const STIFFNESS_MIN_MNM_PER_RAD: u32 = 1;

/// Largest |target| of a motion command and |end| of the position window, µrad: 2.54 rad.
///
/// What the sensors can measure: the gear pot spans 300° in 1024 counts and saturates 511
/// counts from its centre, at ±2.613 rad of gear angle; beyond that a measured deflection
/// is wrong and the supervisor latches `beam-overload` for as long as the link stays out
/// there. 2.54 rad leaves 73 mrad for the overshoot and the beams' deflection envelope
/// (φ_b + θ_cap(L) + the pot's calibration tolerance: 67 mrad at L = 8 mm; checked by the
/// service's tests). A device also refuses a target outside its configured position window.
pub const TARGET_MAX_URAD: u32 = 2_540_000;

/// Smallest virtual stiffness of [`Request::Impedance`], mN·m/rad (0.1 N·m/rad: 1/k_v
/// must fit the controller's format). The largest is the joint stiffness at the clutch
/// setting, the device's check.
pub const IMPEDANCE_STIFFNESS_MIN_MNM_PER_RAD: u32 = 100;
/// Largest virtual damping of [`Request::Impedance`], µN·m·s/rad (100 N·m·s/rad).
pub const IMPEDANCE_DAMPING_MAX_UNMS_PER_RAD: u32 = 100_000_000;
/// Largest |feed-forward torque| of [`Request::Impedance`], µN·m (100 N·m).
pub const IMPEDANCE_TORQUE_MAX_UNM: u32 = 100_000_000;

/// Move duration range, ms: 1 ms – 60 s.
pub const MOVE_DURATION_MIN_MS: u32 = 1;
/// Upper end of the move duration range, ms.
pub const MOVE_DURATION_MAX_MS: u32 = 60_000;

/// Largest sine amplitude, µrad (1 rad).
pub const SINE_AMPLITUDE_MAX_URAD: u32 = 1_000_000;
/// Sine frequency range, mHz: 0.01–20 Hz.
pub const SINE_FREQUENCY_MIN_MHZ: u32 = 10;
/// Upper end of the sine frequency range, mHz.
pub const SINE_FREQUENCY_MAX_MHZ: u32 = 20_000;

/// Largest proportional gain, 10⁻³ ‰/rad (10⁶ ‰/rad, the controller's bound).
pub const KP_MAX: u64 = 1_000_000_000;
/// Largest integral gain, 10⁻³ ‰/(rad·s) (10⁷ ‰/(rad·s)).
pub const KI_MAX: u64 = 10_000_000_000;
/// Largest derivative gain, 10⁻³ ‰·s/rad (10⁴ ‰·s/rad).
pub const KD_MAX: u64 = 10_000_000;

/// Largest current limit, mA (10 A).
pub const CURRENT_LIMIT_MAX_MA: u16 = 10_000;
/// Largest motor torque limit at the output, µN·m (100 N·m).
pub const MOTOR_TORQUE_LIMIT_MAX_UNM: u32 = 100_000_000;
/// Largest clutch tolerance, µm (5 mm, `model::control::Limits::clutch_tolerance`).
pub const CLUTCH_TOLERANCE_MAX_UM: u16 = 5_000;

/// Telemetry rate range when streaming, Hz (0 turns the stream off).
pub const TELEMETRY_RATE_MIN_HZ: u16 = 10;
/// Upper end of the telemetry rate range, Hz.
pub const TELEMETRY_RATE_MAX_HZ: u16 = 500;

const fn max(a: usize, b: usize) -> usize {
    if a > b {
        a
    } else {
        b
    }
}

/// COBS-encoded length of `n` bytes (without the delimiter): one overhead byte per started
/// 254-byte block.
const fn cobs_max(n: usize) -> usize {
    n + n / 254 + 1
}
