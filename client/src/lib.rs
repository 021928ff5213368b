//! Host side of the vsa command and telemetry protocol (the `protocol` crate): the client
//! used by the `vsa` command line and by the xtask's end-to-end tests.
//!
//! * [`Transport`]: a byte stream to a board — [`SerialTransport`] (the real board's
//!   ST-LINK virtual COM port, 921 600 baud 8N1) or [`TcpTransport`] (an emulated board, a
//!   relay, or the in-process [`fake`] board).
//! * [`Client`]: numbers requests (`seq` 1, 2, … skipping 0 on wrap), waits for the reply
//!   with the same `seq` (timeout 1 s by default), keeps the telemetry that arrives
//!   meanwhile in a bounded buffer, counts and skips bad frames and stale replies, and
//!   optionally sends a heartbeat every 20 ms during every wait ([`Client::set_heartbeat`]).
//!   Typed helpers take and return the protocol's integer units (µrad, µm, mN·m/rad, mHz,
//!   Hz, mA, µN·m, ‰): see [`protocol`].
//! * [`Client::record`]: streams telemetry for a given span of board ticks and reports the
//!   gaps and the board's dropped-sample counter ([`Recording`]).
//! * [`csv`]: telemetry samples to CSV in SI units (s, rad, A, N·m, duty fraction) and back.
//! * [`qemu`]: builds the firmware and starts it on an emulated board (QEMU) whose USART1 is
//!   a TCP connection to this process; the board is killed when its handle drops.
//!
//! ```no_run
//! use client::Client;
//! use std::time::Duration;
//!
//! let mut c = Client::connect_tcp("127.0.0.1:4000")?;
//! c.set_clutch_length(3_000)?; // µm
//! c.enable()?;
//! c.move_to(500_000, 300)?; // µrad, ms
//! let rec = c.record(Duration::from_secs(2), 500, |_| {})?;
//! println!("{} samples, {} missing", rec.samples.len(), rec.missing_samples);
//! # Ok::<(), client::Error>(())
//! ```
#![deny(unsafe_code)]
#![deny(missing_docs)]

mod calibration;
mod client;
pub mod csv;
pub mod fake;
mod names;
pub mod qemu;
mod record;
mod settings;
mod transport;

use std::time::Duration;

pub use client::{
    Client, Stats, TelemetryFrame, DEFAULT_RETRIES, DEFAULT_TELEMETRY_CAPACITY, DEFAULT_TIMEOUT,
};
pub use names::{
    describe_fault, fault_name, fault_value_unit, persisting_advice, request_name, state_name,
    urad_text,
};
pub use protocol;
pub use protocol::{
    ErrorCode, FaultCode, FaultRecord, FaultSet, Gains, LimitFlags, Limits, Reply, Request, State,
    Status, TelemetrySample,
};
pub use record::{find_gaps, Gap, RecordProgress, Recording};
pub use transport::{SerialTransport, TcpTransport, Transport, DEFAULT_BAUD};

/// Interval between heartbeats in heartbeat mode, ms (the board's command timeout is
/// 100 ms).
pub const HEARTBEAT_INTERVAL: Duration = Duration::from_millis(20);

/// What can go wrong talking to a board.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// Reading from or writing to the transport failed (or the peer closed it).
    #[error("{transport}: {source}")]
    Io {
        /// The transport, as [`Transport::describe`] gives it.
        transport: String,
        /// The I/O error.
        #[source]
        source: std::io::Error,
    },
    /// No reply with the request's `seq` within the timeout.
    #[error(
        "no reply to {request} within {} ms{}",
        timeout.as_millis(),
        line_error.map_or_else(String::new, |c| format!(
            " (meanwhile the board reported a garbled frame: {c})"
        ))
    )]
    Timeout {
        /// The request's name ([`request_name`]).
        request: &'static str,
        /// How long the client waited.
        timeout: Duration,
        /// An error reply without `seq` that arrived meanwhile: the board could not decode
        /// a frame, possibly this request.
        line_error: Option<ErrorCode>,
    },
    /// The board answered [`Reply::Error`]: nothing changed.
    #[error("the board refused {request}: {code}")]
    Refused {
        /// The request's name.
        request: &'static str,
        /// Why.
        code: ErrorCode,
    },
    /// The board cleared nothing: the condition of a latched fault still holds.
    #[error("the board cleared nothing: {}", crate::names::persisting_advice(record, limits.as_ref()))]
    FaultPersists {
        /// The fault, its value now and the tick it was last seen at.
        record: FaultRecord,
        /// The limits in force, if the board gave them.
        limits: Option<Limits>,
    },
    /// The board answered with a reply of the wrong kind.
    #[error("unexpected reply to {request}: {reply:?}")]
    UnexpectedReply {
        /// The request's name.
        request: &'static str,
        /// What came back.
        reply: Reply,
    },
    /// No telemetry sample arrived within the timeout while recording.
    #[error("no telemetry within {} ms while recording", timeout.as_millis())]
    NoTelemetry {
        /// How long the client waited.
        timeout: Duration,
    },
    /// A telemetry sample's tick was not after the previous one's.
    #[error("telemetry went back from tick {from} to tick {to} (did the board restart?)")]
    TickBackwards {
        /// Tick of the previous sample.
        from: u32,
        /// Tick of this sample.
        to: u32,
    },
    /// An argument of a client function is unusable (e.g. a recording rate of 0 Hz).
    #[error("{0}")]
    InvalidArgument(String),
    /// A frame could not be encoded (cannot happen for the protocol's messages).
    #[error("encoding a frame: {0}")]
    Encode(protocol::EncodeError),
    /// A CSV file did not parse.
    #[error("line {line}: {reason}")]
    Csv {
        /// 1-based line number.
        line: usize,
        /// What is wrong with it.
        reason: String,
    },
    /// Building the firmware or running the emulated board failed.
    #[error("{0}")]
    Qemu(String),
}

/// Result with [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;
