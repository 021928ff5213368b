//! The request/reply client.

use std::collections::VecDeque;
use std::time::{Duration, Instant};

use protocol::{
    encode_to_vec, Decoder, ErrorCode, Frame, Gains, Limits, Reply, Request, Status,
    TelemetrySample, NO_SEQ,
};

use crate::names::request_name;
use crate::transport::{SerialTransport, TcpTransport, Transport};
use crate::{Error, Result, HEARTBEAT_INTERVAL};

/// Default reply timeout, 1 s.
pub const DEFAULT_TIMEOUT: Duration = Duration::from_secs(1);

/// How long [`Client::enable`] asks again a board that answers `busy` (its 32 ms boot
/// window, with room for a loaded host and an emulated board's start).
pub const ENABLE_BUSY_WAIT: Duration = Duration::from_millis(500);

/// Default capacity of the telemetry buffer, samples (20 s at 500 Hz).
pub const DEFAULT_TELEMETRY_CAPACITY: usize = 10_000;

/// Heartbeats whose reply has not come yet that are remembered (older ones are forgotten
/// and their late replies count as stale).
const MAX_PENDING_HEARTBEATS: usize = 64;

/// Bytes read from the transport at a time.
const READ_CHUNK: usize = 512;

/// A telemetry frame as received.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TelemetryFrame {
    /// The frame's `seq`: the board's wrapping counter of samples taken (dropped ones
    /// included), so a jump of n + 1 means n samples were dropped or lost.
    pub counter: u16,
    /// The sample.
    pub sample: TelemetrySample,
}

/// What the client has seen since it was created (saturating counters).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[non_exhaustive]
pub struct Stats {
    /// Requests sent, heartbeats of the heartbeat mode not included.
    pub requests: u64,
    /// Replies matched to the request that was waiting for them.
    pub replies: u64,
    /// Heartbeats sent by the heartbeat mode.
    pub heartbeats: u64,
    /// Heartbeats of the heartbeat mode answered [`Reply::Ok`].
    pub heartbeat_acks: u64,
    /// Heartbeats of the heartbeat mode answered with anything else.
    pub heartbeat_refusals: u64,
    /// Byte runs from the board that did not decode as a frame (bad CRC, bad COBS, …).
    pub bad_frames: u64,
    /// Replies with a `seq` nothing was waiting for (e.g. late replies after a timeout).
    pub stale_replies: u64,
    /// [`Reply::Error`] frames with [`NO_SEQ`]: the board received a frame it could not
    /// decode.
    pub line_errors: u64,
    /// Telemetry frames received.
    pub telemetry: u64,
    /// Telemetry samples dropped by the client because its buffer was full.
    pub telemetry_overflow: u64,
    /// Requests sent again (same `seq`) because no reply came (see [`Client::set_retries`]).
    pub retries: u64,
}

fn bump(c: &mut u64) {
    *c = c.saturating_add(1);
}

/// A connection to a board: numbered requests, matched replies, buffered telemetry.
///
/// Every request gets exactly one reply with the same `seq`; the client numbers its
/// requests 1, 2, … (skipping [`NO_SEQ`] when the counter wraps) and waits for that reply
/// for at most [`Client::timeout`]. Telemetry frames that arrive meanwhile are kept in a
/// bounded buffer ([`Client::take_telemetry`]); bad frames and replies nobody waits for are
/// counted in [`Client::stats`] and skipped.
///
/// The typed helpers send their arguments as given (they do not check the ranges of
/// [`Request::validate`]; the board does and answers [`ErrorCode::OutOfRange`]).
pub struct Client {
    transport: Box<dyn Transport>,
    decoder: Decoder<Reply>,
    next_seq: u16,
    timeout: Duration,
    telemetry: VecDeque<TelemetryFrame>,
    capacity: usize,
    stats: Stats,
    heartbeat: bool,
    last_heartbeat: Option<Instant>,
    pending_heartbeats: VecDeque<u16>,
    awaiting: Vec<u16>,
    got: Option<Reply>,
    line_error: Option<ErrorCode>,
    flushed: bool,
    retries: u32,
    /// While waiting for a reply: give up on this attempt at once when the board reports a
    /// frame it could not decode (ours may have been the one the line corrupted).
    retry_on_line_error: bool,
}

/// Times an unanswered request is sent again, by default.
pub const DEFAULT_RETRIES: u32 = 2;

impl std::fmt::Debug for Client {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Client")
            .field("transport", &self.transport.describe())
            .field("timeout", &self.timeout)
            .field("heartbeat", &self.heartbeat)
            .field("stats", &self.stats)
            .finish_non_exhaustive()
    }
}

impl Client {
    /// A client over `transport`, with the default timeout and no heartbeats.
    pub fn new(transport: impl Transport + 'static) -> Client {
        Client {
            transport: Box::new(transport),
            decoder: Decoder::new(),
            next_seq: 1,
            timeout: DEFAULT_TIMEOUT,
            telemetry: VecDeque::new(),
            capacity: DEFAULT_TELEMETRY_CAPACITY,
            stats: Stats::default(),
            heartbeat: false,
            last_heartbeat: None,
            pending_heartbeats: VecDeque::new(),
            awaiting: Vec::new(),
            got: None,
            line_error: None,
            flushed: false,
            retries: DEFAULT_RETRIES,
            retry_on_line_error: false,
        }
    }

    /// How many times an unanswered request is sent again with the same `seq` (the board
    /// answers a repeat with the reply it already gave, without carrying the request out
    /// twice). Each attempt waits [`Client::timeout`], or less when the board reports a
    /// frame it could not decode meanwhile. 0: never.
    pub fn set_retries(&mut self, retries: u32) {
        self.retries = retries;
    }

    /// Connects over TCP to `addr` (`host:port`), waiting at most the default timeout.
    ///
    /// # Errors
    /// [`Error::Io`] if the connection fails.
    pub fn connect_tcp(addr: &str) -> Result<Client> {
        TcpTransport::connect(addr, DEFAULT_TIMEOUT)
            .map(Client::new)
            .map_err(|source| Error::Io {
                transport: format!("tcp {addr}"),
                source,
            })
    }

    /// Opens the serial port `path` at `baud` baud, 8N1.
    ///
    /// # Errors
    /// [`Error::Io`] if the port cannot be opened.
    pub fn open_serial(path: &str, baud: u32) -> Result<Client> {
        SerialTransport::open(path, baud)
            .map(Client::new)
            .map_err(|source| Error::Io {
                transport: format!("serial {path}"),
                source,
            })
    }

    /// Sets the reply timeout (builder style).
    #[must_use]
    pub fn with_timeout(mut self, timeout: Duration) -> Client {
        self.timeout = timeout;
        self
    }

    /// Sets the reply timeout.
    pub fn set_timeout(&mut self, timeout: Duration) {
        self.timeout = timeout;
    }

    /// The reply timeout.
    #[must_use]
    pub fn timeout(&self) -> Duration {
        self.timeout
    }

    /// Turns the heartbeat mode on or off. When on, every blocking wait of the client
    /// (replies, [`Client::wait`], [`Client::record`], …) sends a [`Request::Heartbeat`]
    /// whenever [`HEARTBEAT_INTERVAL`] (20 ms) or more have passed since the last one. The
    /// board arms its 100 ms command timeout at the first heartbeat: once on, keep the
    /// client waiting (not idle) or the board latches `command-timeout`; end the session
    /// with [`Client::disarm_heartbeat`] (turning the mode off here sends nothing).
    pub fn set_heartbeat(&mut self, on: bool) {
        self.heartbeat = on;
    }

    /// Whether the heartbeat mode is on.
    #[must_use]
    pub fn heartbeat_enabled(&self) -> bool {
        self.heartbeat
    }

    /// Sets the capacity of the telemetry buffer, samples (at least 1). When it is full the
    /// oldest sample is dropped ([`Stats::telemetry_overflow`]).
    pub fn set_telemetry_capacity(&mut self, capacity: usize) {
        self.capacity = capacity.max(1);
        while self.telemetry.len() > self.capacity {
            self.telemetry.pop_front();
            bump(&mut self.stats.telemetry_overflow);
        }
    }

    /// Counters of what the client has seen.
    #[must_use]
    pub fn stats(&self) -> Stats {
        self.stats
    }

    /// The transport's description (`tcp 127.0.0.1:4000`, `serial /dev/ttyACM0`).
    #[must_use]
    pub fn describe(&self) -> String {
        self.transport.describe()
    }

    fn io(&self, source: std::io::Error) -> Error {
        Error::Io {
            transport: self.transport.describe(),
            source,
        }
    }

    fn alloc_seq(&mut self) -> u16 {
        let seq = self.next_seq;
        self.next_seq = match self.next_seq.wrapping_add(1) {
            NO_SEQ => 1,
            s => s,
        };
        seq
    }

    /// Encodes and writes one request frame; returns its `seq`. A 0x00 goes first on the
    /// first write, so that a partial frame left at the board by an earlier connection is
    /// flushed.
    fn send(&mut self, req: Request) -> Result<u16> {
        let seq = self.alloc_seq();
        self.send_as(seq, req)
    }

    /// [`Client::send`] with a given `seq` (a retry).
    fn send_as(&mut self, seq: u16, req: Request) -> Result<u16> {
        let frame = encode_to_vec(&Frame::new(seq, req)).map_err(Error::Encode)?;
        let r = if self.flushed {
            self.transport.write_all(&frame)
        } else {
            let mut bytes = Vec::with_capacity(frame.len() + 1);
            bytes.push(0);
            bytes.extend_from_slice(&frame);
            self.transport.write_all(&bytes)
        };
        r.map_err(|e| self.io(e))?;
        self.flushed = true;
        Ok(seq)
    }

    /// Sends `req` and waits for its reply. [`Reply::Error`] becomes [`Error::Refused`].
    ///
    /// # Errors
    /// [`Error::Io`], [`Error::Timeout`], [`Error::Refused`].
    pub fn request(&mut self, req: Request) -> Result<Reply> {
        let name = request_name(&req);
        let seq = self.send(req)?;
        bump(&mut self.stats.requests);
        if matches!(req, Request::Heartbeat) {
            self.last_heartbeat = Some(Instant::now());
        }
        let mut attempts = 0;
        let reply = loop {
            self.retry_on_line_error = attempts < self.retries;
            let r = self.wait_for(&[seq], self.timeout, name);
            self.retry_on_line_error = false;
            match r {
                Err(Error::Timeout { .. }) if attempts < self.retries => {
                    attempts += 1;
                    bump(&mut self.stats.retries);
                    self.send_as(seq, req)?;
                }
                r => break r?,
            }
        };
        match reply {
            Reply::Error(code) => Err(Error::Refused {
                request: name,
                code,
            }),
            reply => Ok(reply),
        }
    }

    pub(crate) fn request_ok(&mut self, req: Request) -> Result<()> {
        match self.request(req)? {
            Reply::Ok => Ok(()),
            reply => Err(Error::UnexpectedReply {
                request: request_name(&req),
                reply,
            }),
        }
    }

    /// Waits until a reply with one of `seqs` arrives (any kind, errors included).
    fn wait_for(&mut self, seqs: &[u16], timeout: Duration, name: &'static str) -> Result<Reply> {
        self.awaiting.clear();
        self.awaiting.extend_from_slice(seqs);
        self.got = None;
        self.line_error = None;
        let deadline = Instant::now() + timeout;
        let result = loop {
            if let Some(r) = self.got.take() {
                bump(&mut self.stats.replies);
                break Ok(r);
            }
            if Instant::now() >= deadline || (self.retry_on_line_error && self.line_error.is_some())
            {
                break Err(Error::Timeout {
                    request: name,
                    timeout,
                    line_error: self.line_error,
                });
            }
            if let Err(e) = self.service(deadline) {
                break Err(e);
            }
        };
        self.awaiting.clear();
        result
    }

    /// Sends a heartbeat if due, then reads once, waiting at most until `until` (or the
    /// next heartbeat), and handles what arrived.
    fn service(&mut self, until: Instant) -> Result<()> {
        self.heartbeat_if_due()?;
        let now = Instant::now();
        let mut wait = until.saturating_duration_since(now);
        if self.heartbeat {
            if let Some(last) = self.last_heartbeat {
                wait = wait.min((last + HEARTBEAT_INTERVAL).saturating_duration_since(now));
            }
        }
        let mut buf = [0u8; READ_CHUNK];
        let n = self
            .transport
            .read(&mut buf, wait)
            .map_err(|e| self.io(e))?;
        for &b in buf.get(..n).unwrap_or_default() {
            self.on_byte(b);
        }
        Ok(())
    }

    fn heartbeat_if_due(&mut self) -> Result<()> {
        if !self.heartbeat {
            return Ok(());
        }
        let now = Instant::now();
        if self
            .last_heartbeat
            .is_some_and(|t| now.duration_since(t) < HEARTBEAT_INTERVAL)
        {
            return Ok(());
        }
        let seq = self.send(Request::Heartbeat)?;
        self.last_heartbeat = Some(now);
        bump(&mut self.stats.heartbeats);
        if self.pending_heartbeats.len() >= MAX_PENDING_HEARTBEATS {
            self.pending_heartbeats.pop_front();
        }
        self.pending_heartbeats.push_back(seq);
        Ok(())
    }

    fn on_byte(&mut self, b: u8) {
        match self.decoder.feed(b) {
            Ok(None) => {}
            Ok(Some(frame)) => self.on_frame(frame),
            Err(_) => bump(&mut self.stats.bad_frames),
        }
    }

    fn on_frame(&mut self, frame: Frame<Reply>) {
        let seq = frame.seq;
        match frame.body {
            Reply::Telemetry(sample) => {
                bump(&mut self.stats.telemetry);
                if self.telemetry.len() >= self.capacity {
                    self.telemetry.pop_front();
                    bump(&mut self.stats.telemetry_overflow);
                }
                self.telemetry.push_back(TelemetryFrame {
                    counter: seq,
                    sample,
                });
            }
            body if self.got.is_none() && self.awaiting.contains(&seq) => self.got = Some(body),
            body => {
                if let Some(i) = self.pending_heartbeats.iter().position(|&s| s == seq) {
                    self.pending_heartbeats.remove(i);
                    if body == Reply::Ok {
                        bump(&mut self.stats.heartbeat_acks);
                    } else {
                        bump(&mut self.stats.heartbeat_refusals);
                    }
                } else if let (NO_SEQ, Reply::Error(code)) = (seq, body) {
                    bump(&mut self.stats.line_errors);
                    self.line_error = Some(code);
                } else {
                    bump(&mut self.stats.stale_replies);
                }
            }
        }
    }

    /// Waits for `duration`, handling what arrives (telemetry is buffered) and sending
    /// heartbeats in heartbeat mode.
    ///
    /// # Errors
    /// [`Error::Io`].
    pub fn wait(&mut self, duration: Duration) -> Result<()> {
        let deadline = Instant::now() + duration;
        while Instant::now() < deadline {
            self.service(deadline)?;
        }
        Ok(())
    }

    /// Handles whatever has arrived, waiting at most 1 ms.
    ///
    /// # Errors
    /// [`Error::Io`].
    pub fn poll(&mut self) -> Result<()> {
        self.service(Instant::now())
    }

    /// Pings every `every` until the board answers one of the pings (late answers count),
    /// for at most `total`. For boards that drop what arrives before their UART is up.
    ///
    /// # Errors
    /// [`Error::Timeout`] if no ping was answered within `total`; [`Error::Io`].
    pub fn wait_ready(&mut self, total: Duration, every: Duration) -> Result<()> {
        let start = Instant::now();
        let mut sent = Vec::new();
        loop {
            let seq = self.send(Request::Ping)?;
            bump(&mut self.stats.requests);
            sent.push(seq);
            let left = total.saturating_sub(start.elapsed());
            match self.wait_for(&sent, every.min(left), "ping") {
                Ok(_) => return Ok(()),
                Err(Error::Timeout { .. }) if start.elapsed() < total => {}
                Err(Error::Timeout { line_error, .. }) => {
                    return Err(Error::Timeout {
                        request: "ping",
                        timeout: total,
                        line_error,
                    })
                }
                Err(e) => return Err(e),
            }
        }
    }

    /// The buffered telemetry, oldest first; empties the buffer.
    pub fn take_telemetry(&mut self) -> Vec<TelemetryFrame> {
        self.telemetry.drain(..).collect()
    }

    /// Number of buffered telemetry samples.
    #[must_use]
    pub fn telemetry_len(&self) -> usize {
        self.telemetry.len()
    }

    /// Drops the buffered telemetry.
    pub fn clear_telemetry(&mut self) {
        self.telemetry.clear();
    }

    /// The oldest buffered telemetry sample, waiting at most `timeout` for one to arrive.
    /// `Ok(None)` if none came.
    ///
    /// # Errors
    /// [`Error::Io`].
    pub fn next_telemetry(&mut self, timeout: Duration) -> Result<Option<TelemetryFrame>> {
        let deadline = Instant::now() + timeout;
        loop {
            if let Some(t) = self.telemetry.pop_front() {
                return Ok(Some(t));
            }
            if Instant::now() >= deadline {
                return Ok(None);
            }
            self.service(deadline)?;
        }
    }

    /// [`Request::Ping`].
    ///
    /// # Errors
    /// [`Error::Io`], [`Error::Timeout`], [`Error::Refused`], [`Error::UnexpectedReply`].
    pub fn ping(&mut self) -> Result<()> {
        self.request_ok(Request::Ping)
    }

    /// [`Request::GetStatus`].
    ///
    /// # Errors
    /// As [`Client::ping`].
    pub fn status(&mut self) -> Result<Status> {
        match self.request(Request::GetStatus)? {
            Reply::Status(s) => Ok(s),
            reply => Err(Error::UnexpectedReply {
                request: "status",
                reply,
            }),
        }
    }

    /// [`Client::request`], asked again 1 ms apart while the board answers `busy` (a state
    /// that ends by itself: its boot window, its first control tick), for up to `wait`.
    ///
    /// # Errors
    /// As [`Client::request`]; the last `busy` refusal if the board is still busy after
    /// `wait`.
    pub fn request_while_busy(&mut self, req: Request, wait: Duration) -> Result<Reply> {
        let start = Instant::now();
        loop {
            match self.request(req) {
                Err(Error::Refused {
                    code: ErrorCode::Busy,
                    ..
                }) if start.elapsed() < wait => {
                    self.wait(Duration::from_millis(1))?;
                }
                other => return other,
            }
        }
    }

    /// [`Request::Enable`]: motor on, holding the current position (refused while a fault
    /// is latched). A board that answers `busy` (its boot window: the encoder is being
    /// aligned to the pot with the motor off, docs/calibration.md) is asked again for up
    /// to `ENABLE_BUSY_WAIT` ([`Client::request_while_busy`]).
    ///
    /// # Errors
    /// As [`Client::ping`]; the last refusal if the board is still busy after the wait (a
    /// calibration running).
    pub fn enable(&mut self) -> Result<()> {
        match self.request_while_busy(Request::Enable, ENABLE_BUSY_WAIT)? {
            Reply::Ok => Ok(()),
            reply => Err(Error::UnexpectedReply {
                request: request_name(&Request::Enable),
                reply,
            }),
        }
    }

    /// [`Request::Disable`]: motor off.
    ///
    /// # Errors
    /// As [`Client::ping`].
    pub fn disable(&mut self) -> Result<()> {
        self.request_ok(Request::Disable)
    }

    /// [`Request::ClearFault`]: clears the latched faults (the motor stays off).
    ///
    /// # Errors
    /// As [`Client::ping`]; [`Error::FaultPersists`] when the board cleared nothing because
    /// the condition of a fault still holds (with the limits in force, if the board gave
    /// them).
    pub fn clear_fault(&mut self) -> Result<()> {
        match self.request(Request::ClearFault)? {
            Reply::Ok => Ok(()),
            Reply::FaultPersists(record) => Err(Error::FaultPersists {
                record,
                limits: self.limits().ok(),
            }),
            reply => Err(Error::UnexpectedReply {
                request: "clear-fault",
                reply,
            }),
        }
    }

    /// [`Request::GetLimits`]: the live limits and the position window in force.
    ///
    /// # Errors
    /// As [`Client::ping`].
    pub fn limits(&mut self) -> Result<Limits> {
        match self.request(Request::GetLimits)? {
            Reply::Limits(l) => Ok(l),
            reply => Err(Error::UnexpectedReply {
                request: "get-limits",
                reply,
            }),
        }
    }

    /// [`Request::SetClutchLength`]: the clutch sits at `length_um` µm (1 000–8 000).
    ///
    /// # Errors
    /// As [`Client::ping`].
    pub fn set_clutch_length(&mut self, length_um: u32) -> Result<()> {
        self.request_ok(Request::SetClutchLength { length_um })
    }

    /// [`Request::SetStiffness`]: configures the controller for `stiffness_mnm_per_rad`
    /// mN·m/rad and returns the clutch length to set by hand, µm.
    ///
    /// # Errors
    /// As [`Client::ping`]; [`ErrorCode::OutOfRange`] if the design cannot reach it.
    pub fn set_stiffness(&mut self, stiffness_mnm_per_rad: u32) -> Result<u32> {
        let req = Request::SetStiffness {
            stiffness_mnm_per_rad,
        };
        match self.request(req)? {
            Reply::ClutchToSet { length_um } => Ok(length_um),
            reply => Err(Error::UnexpectedReply {
                request: "set-stiffness",
                reply,
            }),
        }
    }

    /// [`Request::Move`]: minimum-jerk move to `target_urad` µrad in `duration_ms` ms.
    ///
    /// # Errors
    /// As [`Client::ping`].
    pub fn move_to(&mut self, target_urad: i32, duration_ms: u32) -> Result<()> {
        self.request_ok(Request::Move {
            target_urad,
            duration_ms,
        })
    }

    /// [`Request::Step`]: reference step to `target_urad` µrad.
    ///
    /// # Errors
    /// As [`Client::ping`].
    pub fn step_to(&mut self, target_urad: i32) -> Result<()> {
        self.request_ok(Request::Step { target_urad })
    }

    /// [`Request::Sine`]: sine of `amplitude_urad` µrad at `frequency_mhz` mHz about the
    /// current link angle.
    ///
    /// # Errors
    /// As [`Client::ping`].
    pub fn sine(&mut self, amplitude_urad: u32, frequency_mhz: u32) -> Result<()> {
        self.request_ok(Request::Sine {
            amplitude_urad,
            frequency_mhz,
        })
    }

    /// [`Request::Impedance`]: hold `target_urad` µrad with virtual stiffness
    /// `stiffness_mnm_per_rad` mN·m/rad, damping `damping_unms_per_rad` µN·m·s/rad and
    /// feed-forward torque `torque_unm` µN·m.
    ///
    /// # Errors
    /// As [`Client::ping`]; the board refuses a stiffness above the joint's.
    pub fn impedance(
        &mut self,
        target_urad: i32,
        stiffness_mnm_per_rad: u32,
        damping_unms_per_rad: u32,
        torque_unm: i32,
    ) -> Result<()> {
        self.request_ok(Request::Impedance {
            target_urad,
            stiffness_mnm_per_rad,
            damping_unms_per_rad,
            torque_unm,
        })
    }

    /// [`Request::Hold`]: stop any motion, hold the current reference.
    ///
    /// # Errors
    /// As [`Client::ping`].
    pub fn hold(&mut self) -> Result<()> {
        self.request_ok(Request::Hold)
    }

    /// [`Request::SetGains`]: explicit PID gains (10⁻³ of ‰/rad, ‰/(rad·s), ‰·s/rad).
    ///
    /// # Errors
    /// As [`Client::ping`].
    pub fn set_gains(&mut self, gains: Gains) -> Result<()> {
        self.request_ok(Request::SetGains(gains))
    }

    /// [`Request::AutoGains`]: back to the stiffness-scheduled gains.
    ///
    /// # Errors
    /// As [`Client::ping`].
    pub fn auto_gains(&mut self) -> Result<()> {
        self.request_ok(Request::AutoGains)
    }

    /// [`Request::SetLimits`].
    ///
    /// # Errors
    /// As [`Client::ping`].
    pub fn set_limits(&mut self, limits: &Limits) -> Result<()> {
        self.request_ok(Request::SetLimits(*limits))
    }

    /// [`Request::StreamTelemetry`]: `rate_hz` 0 (off) or 10–500 Hz.
    ///
    /// # Errors
    /// As [`Client::ping`].
    pub fn stream_telemetry(&mut self, rate_hz: u16) -> Result<()> {
        self.request_ok(Request::StreamTelemetry { rate_hz })
    }

    /// [`Request::Heartbeat`], waiting for its reply (arms the board's command timeout).
    ///
    /// # Errors
    /// As [`Client::ping`].
    pub fn heartbeat(&mut self) -> Result<()> {
        self.request_ok(Request::Heartbeat)
    }

    /// Ends a heartbeat session: stops the heartbeat mode and sends
    /// [`Request::DisarmHeartbeat`], so the board's command timeout is off again.
    ///
    /// # Errors
    /// As [`Client::ping`].
    pub fn disarm_heartbeat(&mut self) -> Result<()> {
        self.heartbeat = false;
        self.request_ok(Request::DisarmHeartbeat)
    }
}
