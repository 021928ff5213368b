//! An in-process fake board for tests: a thread serving the protocol on a TCP port with
//! [`protocol::Handler`] over a mock [`Device`], streaming telemetry on a real-time 1 kHz
//! tick, with switchable misbehaviour (dropped samples, garbage on the line, stale replies,
//! unanswered requests, slow replies).
//!
//! It accepts one connection at a time, any number in turn (each `vsa --tcp` invocation is
//! one); the device state persists across connections. It is not the firmware: the
//! "actuator" follows the reference at once, and only the command timeout and the
//! position window are supervised (with the firmware's rules: a target outside the window
//! is refused, a clear while the link is outside it clears nothing, any well-formed
//! request restarts an armed timeout, a latched timeout disarms it).

use std::collections::HashSet;
use std::io::{self, Read, Write};
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use protocol::{
    encode_to_vec, telemetry_frame, Decoder, Device, ErrorCode, FaultCode, FaultRecord, FaultSet,
    Frame, Gains, Handler, LimitFlags, Limits, LoggedFault, Reply, Request, State, Status,
    TelemetrySample, CLUTCH_MAX_UM, CLUTCH_MIN_UM,
};

use crate::names::request_name;

/// Stiffness at L = 1 mm of the paper preset, mN·m/rad (k ∝ 1/L³ in the fake).
const K_AT_1MM: f64 = 7_167_500.0;
/// The board's command timeout, ms.
pub const COMMAND_TIMEOUT_MS: u32 = 100;

/// How the fake board misbehaves (all off by default).
#[derive(Clone, Debug, Default)]
pub struct Behaviour {
    /// Drop every n-th telemetry sample at the board (its counter still advances and
    /// `telemetry_dropped` counts it), 0 = never.
    pub drop_every: u32,
    /// Send every n-th telemetry frame with a corrupted CRC ("lost on the line"), 0 = never.
    pub corrupt_every: u32,
    /// Send a run of garbage bytes (and a 0x00) before every reply.
    pub garbage_before_reply: bool,
    /// Send a reply with a `seq` nobody waits for before every reply.
    pub stale_before_reply: bool,
    /// Requests (by [`request_name`]) that get no reply.
    pub ignore: HashSet<&'static str>,
    /// Delay before each reply.
    pub reply_delay: Duration,
    /// Added to the board's tick (e.g. to record across the u32 tick wrap).
    pub tick_offset: u32,
}

/// The mock device behind the handler.
#[derive(Clone, Debug)]
pub struct MockDevice {
    /// Operating state.
    pub state: State,
    /// Latched faults.
    pub faults: FaultSet,
    /// First fault since the last clear.
    pub first_fault: Option<FaultRecord>,
    /// Clutch length, µm.
    pub clutch_length_um: u32,
    /// Stiffness, mN·m/rad.
    pub stiffness_mnm_per_rad: u32,
    /// Reference (and link angle: the fake follows at once), µrad.
    pub reference_urad: i32,
    /// Explicit gains, `None` for automatic.
    pub gains: Option<Gains>,
    /// Limits.
    pub limits: Limits,
    /// Telemetry rate, Hz.
    pub telemetry_rate_hz: u16,
    /// Samples dropped at the board.
    pub telemetry_dropped: u32,
    /// Heartbeats received.
    pub heartbeats: u32,
    /// Tick of the last heartbeat (the command timeout is armed once one came).
    pub last_heartbeat: Option<u32>,
    /// Command timeout, ms ([`COMMAND_TIMEOUT_MS`] like the firmware's by default).
    pub command_timeout_ms: u32,
    /// Every well-formed request the handler passed on, in order (pings and status
    /// requests included, heartbeats not).
    pub log: Vec<Request>,
    /// The current tick (ms since the fake started).
    pub tick: u32,
    /// The settings store: the saved configuration (clutch µm, gains, limits), `None`
    /// when nothing is saved (the defaults).
    pub stored: Option<(u32, Option<Gains>, Limits)>,
    /// The stored fault log, oldest first (every latched fault).
    pub fault_log: Vec<LoggedFault>,
}

impl Default for MockDevice {
    fn default() -> Self {
        MockDevice {
            state: State::Disabled,
            faults: FaultSet::EMPTY,
            first_fault: None,
            clutch_length_um: 3_000,
            stiffness_mnm_per_rad: stiffness(3_000),
            reference_urad: 0,
            gains: None,
            limits: Limits::DEFAULT,
            telemetry_rate_hz: 0,
            telemetry_dropped: 0,
            heartbeats: 0,
            last_heartbeat: None,
            command_timeout_ms: COMMAND_TIMEOUT_MS,
            log: Vec::new(),
            tick: 0,
            stored: None,
            fault_log: Vec::new(),
        }
    }
}

fn stiffness(length_um: u32) -> u32 {
    let l_mm = f64::from(length_um) / 1000.0;
    (K_AT_1MM / (l_mm * l_mm * l_mm)).round() as u32
}

impl MockDevice {
    fn motion_allowed(&self) -> Result<(), ErrorCode> {
        if self.state == State::Enabled {
            Ok(())
        } else {
            Err(ErrorCode::NotAllowed)
        }
    }

    fn within_window(&self, urad: i32) -> bool {
        (self.limits.position_min_urad..=self.limits.position_max_urad).contains(&urad)
    }

    /// A motion to `target_urad`: refused outside the position window, as the firmware.
    fn motion_to(&mut self, target_urad: i32) -> Result<(), ErrorCode> {
        if !self.within_window(target_urad) {
            return Err(ErrorCode::OutOfRange);
        }
        self.motion_allowed()?;
        self.reference_urad = target_urad;
        Ok(())
    }

    fn latch(&mut self, code: FaultCode, value: i32) {
        if !self.faults.contains(code) {
            self.faults = self.faults.with(code);
            self.first_fault.get_or_insert(FaultRecord {
                code,
                value,
                tick: self.tick,
            });
            self.state = State::Faulted;
            let seq = u32::try_from(self.fault_log.len()).unwrap_or(u32::MAX);
            let fault = FaultRecord {
                code,
                value,
                tick: self.tick,
            };
            self.fault_log.push(LoggedFault { seq, fault });
        }
    }

    /// The running configuration as the fake stores it.
    fn running(&self) -> (u32, Option<Gains>, Limits) {
        (self.clutch_length_um, self.gains, self.limits)
    }

    /// The stored configuration, or the defaults.
    fn stored_or_default(&self) -> (u32, Option<Gains>, Limits) {
        self.stored
            .unwrap_or_else(|| MockDevice::default().running())
    }

    /// The link angle (the fake follows the reference), µrad.
    fn link_urad(&self) -> i32 {
        self.reference_urad.saturating_sub(120)
    }

    /// Latches the command timeout if heartbeats were armed and none came in time (and
    /// disarms it), and the position limit while the link is outside the window.
    fn supervise(&mut self) {
        if let Some(t) = self.last_heartbeat {
            let since = self.tick.wrapping_sub(t);
            if since > self.command_timeout_ms {
                self.latch(
                    FaultCode::CommandTimeout,
                    i32::try_from(since).unwrap_or(i32::MAX),
                );
                self.last_heartbeat = None;
            }
        }
        if !self.within_window(self.link_urad()) {
            self.latch(FaultCode::PositionLimit, self.link_urad());
        }
    }

    fn sample(&self, tick: u32) -> TelemetrySample {
        TelemetrySample {
            tick,
            reference_urad: self.reference_urad,
            link_angle_urad: self.link_urad(),
            gear_angle_urad: self.reference_urad.saturating_add(3_400),
            current_ma: if self.state == State::Enabled { 212 } else { 0 },
            torque_unm: -41_230,
            duty_permille: if self.state == State::Enabled { 87 } else { 0 },
            faults: self.faults,
            limits: LimitFlags::NONE,
        }
    }
}

impl Device for MockDevice {
    fn enable(&mut self) -> Result<(), ErrorCode> {
        if self.state == State::Faulted {
            return Err(ErrorCode::NotAllowed);
        }
        self.state = State::Enabled;
        Ok(())
    }

    fn disable(&mut self) -> Result<(), ErrorCode> {
        if self.state == State::Enabled {
            self.state = State::Disabled;
        }
        Ok(())
    }

    fn clear_fault(&mut self) -> Result<(), ErrorCode> {
        self.faults = FaultSet::EMPTY;
        self.first_fault = None;
        if self.state == State::Faulted {
            self.state = State::Disabled;
        }
        Ok(())
    }

    fn set_clutch_length(&mut self, length_um: u32) -> Result<(), ErrorCode> {
        if self.state == State::Enabled {
            return Err(ErrorCode::Busy);
        }
        self.clutch_length_um = length_um;
        self.stiffness_mnm_per_rad = stiffness(length_um);
        Ok(())
    }

    fn set_stiffness(&mut self, k: u32) -> Result<u32, ErrorCode> {
        let l_um = (1000.0 * (K_AT_1MM / f64::from(k)).cbrt()).round();
        if !(f64::from(CLUTCH_MIN_UM)..=f64::from(CLUTCH_MAX_UM)).contains(&l_um) {
            return Err(ErrorCode::OutOfRange);
        }
        if self.state == State::Enabled {
            return Err(ErrorCode::Busy);
        }
        self.clutch_length_um = l_um as u32;
        self.stiffness_mnm_per_rad = k;
        Ok(l_um as u32)
    }

    fn command_move(&mut self, target_urad: i32, _duration_ms: u32) -> Result<(), ErrorCode> {
        self.motion_to(target_urad)
    }

    fn command_step(&mut self, target_urad: i32) -> Result<(), ErrorCode> {
        self.motion_to(target_urad)
    }

    fn command_sine(&mut self, _amplitude: u32, _frequency: u32) -> Result<(), ErrorCode> {
        self.motion_allowed()
    }

    fn hold(&mut self) -> Result<(), ErrorCode> {
        Ok(())
    }

    fn set_gains(&mut self, gains: Option<Gains>) -> Result<(), ErrorCode> {
        self.gains = gains;
        Ok(())
    }

    fn set_limits(&mut self, limits: &Limits) -> Result<(), ErrorCode> {
        self.limits = *limits;
        Ok(())
    }

    fn set_telemetry_rate(&mut self, rate_hz: u16) -> Result<(), ErrorCode> {
        self.telemetry_rate_hz = rate_hz;
        Ok(())
    }

    fn heartbeat(&mut self) {
        self.heartbeats = self.heartbeats.saturating_add(1);
        self.last_heartbeat = Some(self.tick);
    }

    fn disarm_heartbeat(&mut self) {
        self.last_heartbeat = None;
    }

    fn link_activity(&mut self) {
        if self.last_heartbeat.is_some() {
            self.last_heartbeat = Some(self.tick);
        }
    }

    fn limits(&mut self) -> Limits {
        self.limits
    }

    /// As the firmware: refused above the joint's stiffness; the fake link goes to the
    /// target (no external torque on it).
    fn impedance(&mut self, target_urad: i32, k: u32, _d: u32, _t: i32) -> Result<(), ErrorCode> {
        if k > self.stiffness_mnm_per_rad {
            return Err(ErrorCode::OutOfRange);
        }
        self.motion_to(target_urad)
    }

    fn persisting_fault(&mut self) -> Option<FaultRecord> {
        let link = self.link_urad();
        (self.faults.contains(FaultCode::PositionLimit) && !self.within_window(link)).then_some(
            FaultRecord {
                code: FaultCode::PositionLimit,
                value: link,
                tick: self.tick,
            },
        )
    }

    fn status(&mut self) -> Status {
        Status {
            state: self.state,
            faults: self.faults,
            first_fault: self.first_fault,
            limits: LimitFlags::NONE,
            clutch_length_um: self.clutch_length_um,
            stiffness_mnm_per_rad: self.stiffness_mnm_per_rad,
            clutch_tolerance_um: 0,
            tick: self.tick,
            moving: false,
            telemetry_rate_hz: self.telemetry_rate_hz,
            telemetry_dropped: self.telemetry_dropped,
            protocol_errors: 0,
            differs_from_stored: self.running() != self.stored_or_default(),
            calibration: protocol::CalibrationProgress::Idle,
        }
    }

    fn save(&mut self) -> Result<(), ErrorCode> {
        if self.state == State::Enabled {
            return Err(ErrorCode::NotAllowed);
        }
        self.stored = Some(self.running());
        Ok(())
    }

    fn load(&mut self) -> Result<(), ErrorCode> {
        let (clutch, gains, limits) = self.stored_or_default();
        self.clutch_length_um = clutch;
        self.stiffness_mnm_per_rad = stiffness(clutch);
        (self.gains, self.limits) = (gains, limits);
        Ok(())
    }

    fn factory_reset(&mut self) -> Result<(), ErrorCode> {
        if self.state == State::Enabled {
            return Err(ErrorCode::NotAllowed);
        }
        self.stored = None;
        self.fault_log.clear();
        self.load()
    }

    fn faults_log(&mut self, index: u8) -> Result<(u8, Option<LoggedFault>), ErrorCode> {
        // The store keeps the last 16.
        let kept = &self.fault_log[self.fault_log.len().saturating_sub(16)..];
        let count = u8::try_from(kept.len()).unwrap_or(u8::MAX);
        Ok((count, kept.iter().rev().nth(usize::from(index)).copied()))
    }
}

/// What the fake board shares with its owner.
#[derive(Debug, Default)]
pub struct Shared {
    /// The device.
    pub device: MockDevice,
    /// The misbehaviour.
    pub behaviour: Behaviour,
    /// Protocol errors seen by the handler (bad frames and refusals), all connections.
    pub protocol_errors: u32,
    /// Connections accepted so far.
    pub connections: u32,
}

/// A fake board serving the protocol on 127.0.0.1 (a thread; stopped on drop).
pub struct FakeBoard {
    addr: SocketAddr,
    shared: Arc<Mutex<Shared>>,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl std::fmt::Debug for FakeBoard {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("FakeBoard")
            .field("addr", &self.addr)
            .finish_non_exhaustive()
    }
}

fn lock(m: &Mutex<Shared>) -> MutexGuard<'_, Shared> {
    m.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}

impl FakeBoard {
    /// Starts a well-behaved fake board on a free port of 127.0.0.1.
    ///
    /// # Errors
    /// Binding the port failed.
    pub fn start() -> io::Result<FakeBoard> {
        FakeBoard::with_behaviour(Behaviour::default())
    }

    /// Starts a fake board that misbehaves as `behaviour` says.
    ///
    /// # Errors
    /// Binding the port failed.
    pub fn with_behaviour(behaviour: Behaviour) -> io::Result<FakeBoard> {
        let listener = TcpListener::bind("127.0.0.1:0")?;
        listener.set_nonblocking(true)?;
        let addr = listener.local_addr()?;
        let shared = Arc::new(Mutex::new(Shared {
            behaviour,
            ..Shared::default()
        }));
        let stop = Arc::new(AtomicBool::new(false));
        let thread = {
            let (shared, stop) = (Arc::clone(&shared), Arc::clone(&stop));
            std::thread::spawn(move || serve(&listener, &shared, &stop))
        };
        Ok(FakeBoard {
            addr,
            shared,
            stop,
            thread: Some(thread),
        })
    }

    /// The address to connect to.
    #[must_use]
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    /// The shared state (device, behaviour, counters): lock it to look or change.
    pub fn shared(&self) -> MutexGuard<'_, Shared> {
        lock(&self.shared)
    }
}

impl Drop for FakeBoard {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

fn serve(listener: &TcpListener, shared: &Mutex<Shared>, stop: &AtomicBool) {
    let start = Instant::now();
    while !stop.load(Ordering::Relaxed) {
        match listener.accept() {
            Ok((stream, _)) => {
                lock(shared).connections += 1;
                // A failed connection just ends; the next one may come.
                let _ = connection(stream, shared, stop, start);
            }
            Err(_) => std::thread::sleep(Duration::from_millis(2)),
        }
    }
}

/// Telemetry schedule: sample n of the current stream is due at tick `t0 + n·1000/rate`.
struct Stream {
    rate: u16,
    t0: u32,
    n: u64,
    counter: u16,
}

fn now_tick(start: Instant) -> u32 {
    u32::try_from(start.elapsed().as_millis()).unwrap_or(u32::MAX)
}

fn connection(
    mut stream: TcpStream,
    shared: &Mutex<Shared>,
    stop: &AtomicBool,
    start: Instant,
) -> io::Result<()> {
    stream.set_nonblocking(false)?;
    stream.set_nodelay(true)?;
    stream.set_read_timeout(Some(Duration::from_millis(1)))?;
    let mut decoder = Decoder::<Request>::new();
    let mut handler = Handler::new();
    let mut telemetry: Option<Stream> = None;
    let mut counter: u16 = 0;
    let mut buf = [0u8; 256];
    let mut errors_seen = 0u32;
    while !stop.load(Ordering::Relaxed) {
        let n = match stream.read(&mut buf) {
            Ok(0) => return Ok(()),
            Ok(n) => n,
            Err(e)
                if matches!(
                    e.kind(),
                    io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut
                ) =>
            {
                0
            }
            Err(e) => return Err(e),
        };
        let mut out = Vec::new();
        {
            let mut sh = lock(shared);
            sh.device.tick = now_tick(start).wrapping_add(sh.behaviour.tick_offset);
            sh.device.supervise();
            for &b in buf.get(..n).unwrap_or_default() {
                let frame = match decoder.feed(b) {
                    Ok(None) => continue,
                    Ok(Some(f)) => Ok(f),
                    Err(e) => Err(e),
                };
                let ignored = frame
                    .as_ref()
                    .is_ok_and(|f| sh.behaviour.ignore.contains(request_name(&f.body)));
                if let Ok(f) = &frame {
                    if f.body != Request::Heartbeat {
                        sh.device.log.push(f.body);
                    }
                }
                let reply = handler.handle(frame, &mut sh.device);
                if ignored {
                    continue;
                }
                if sh.behaviour.garbage_before_reply {
                    out.extend_from_slice(&[0x55, 0x13, 0x00, 0x07, 0xff, 0xfe, 0x42, 0x00]);
                }
                if sh.behaviour.stale_before_reply {
                    if let Ok(f) =
                        encode_to_vec(&Frame::new(reply.seq.wrapping_add(7919), Reply::Ok))
                    {
                        out.extend_from_slice(&f);
                    }
                }
                if let Ok(f) = encode_to_vec(&reply) {
                    out.extend_from_slice(&f);
                }
            }
            let total = handler.errors().total();
            sh.protocol_errors = sh.protocol_errors.saturating_add(total - errors_seen);
            errors_seen = total;
            let delay = sh.behaviour.reply_delay;
            if !out.is_empty() && !delay.is_zero() {
                drop(sh);
                std::thread::sleep(delay);
                sh = lock(shared);
            }

            // Telemetry due up to now.
            let rate = sh.device.telemetry_rate_hz;
            let offset = sh.behaviour.tick_offset;
            let tick = now_tick(start);
            if telemetry.as_ref().map(|s| s.rate) != Some(rate) {
                telemetry = (rate > 0).then_some(Stream {
                    rate,
                    t0: tick,
                    n: 0,
                    counter,
                });
            }
            let (drop_every, corrupt_every) = (sh.behaviour.drop_every, sh.behaviour.corrupt_every);
            if let Some(s) = telemetry.as_mut() {
                loop {
                    let due = u64::from(s.t0) + s.n * 1000 / u64::from(s.rate);
                    if due > u64::from(tick) {
                        break;
                    }
                    let due = u32::try_from(due).unwrap_or(u32::MAX);
                    s.n += 1;
                    s.counter = s.counter.wrapping_add(1);
                    counter = s.counter;
                    if drop_every > 0 && s.n % u64::from(drop_every) == 0 {
                        sh.device.telemetry_dropped += 1;
                        continue;
                    }
                    let corrupt = corrupt_every > 0 && s.n % u64::from(corrupt_every) == 0;
                    let sample = sh.device.sample(due.wrapping_add(offset));
                    if let Ok(f) = telemetry_frame(s.counter, &sample) {
                        let at = out.len();
                        out.extend_from_slice(&f);
                        if corrupt {
                            if let Some(x) = out.get_mut(at + 2) {
                                *x = if *x == 0xAA { 0x55 } else { 0xAA };
                            }
                        }
                    }
                }
            }
        }
        if !out.is_empty() {
            stream.write_all(&out)?;
        }
    }
    Ok(())
}
