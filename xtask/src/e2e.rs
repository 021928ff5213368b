//! The end-to-end test of the host link: an emulated board serving the protocol
//! (`--serve`), driven through the same `client` library as `vsa`, is configured, enabled,
//! moved and recorded; 10 kB of random bytes are sent during a second move (which also
//! measures what the emulated USART takes per second); a target outside the position
//! window is refused; heartbeats are armed and the line is flooded with valid frames
//! faster than the USART takes them, so the heartbeats queue behind them (the board must
//! count the frames as link activity and latch nothing); then the heartbeats stop and the
//! board must latch `command-timeout`, which a clear must recover from for good.
//!
//! The recorded motion is held to the controller's tolerances for a 0.5 rad move with a
//! 0.3 N·m load (`--load-mnm 300`): overshoot ≤ 5 %, within ±1 encoder count of the target
//! from 400 ms after the command to the end of the recording (`plant::metrics`).

use std::io::Write;
use std::path::Path;
use std::sync::mpsc;
use std::time::{Duration, Instant};

use anyhow::{anyhow, bail, ensure, Context, Result};
use client::protocol::{encode_to_vec, Frame, Request};
use client::qemu::{Board as ClientBoard, LogSink, QemuBoard, QemuOptions};
use client::{Client, ErrorCode, FaultCode, State, TelemetryFrame};
use plant::metrics::{move_command_tick, StepResponse};
use plant::ENCODER_COUNT_RAD;

use crate::board::Board;
use crate::defmt_log::LogFormat;

/// One encoder count, µrad.
const COUNT_URAD: f64 = ENCODER_COUNT_RAD * 1e6;

/// Move target and duration.
const TARGET_URAD: i32 = 500_000;
const MOVE_MS: u32 = 300;

/// Telemetry rate of the recordings, Hz.
const RATE_HZ: u16 = 500;

/// Random bytes sent during the second move.
const GARBAGE_BYTES: usize = 10_000;

/// What the test measured.
pub struct Report {
    /// Overshoot of the first move, % of the move.
    pub overshoot_pct: f64,
    /// Largest |link − target| from 400 ms after the start of the first move, counts.
    pub settled_error_counts: f64,
    /// Samples recorded during the first move and their expected number.
    pub samples: usize,
    /// Samples the board dropped or the link lost in that recording.
    pub lost_samples: u64,
    /// Wall-clock time the 10 kB took to go out, and the protocol errors they caused.
    pub garbage_secs: f64,
    /// Bytes per second the emulated USART took during the garbage.
    pub usart_bytes_per_s: f64,
    /// Valid frames flooded onto the line while heartbeats were armed, their bytes, and
    /// the wall-clock time until the board had taken them all.
    pub flood_frames: usize,
    /// Bytes of the flood.
    pub flood_bytes: usize,
    /// Seconds until the board had taken the flood.
    pub flood_secs: f64,
    /// Protocol errors counted by the board after the garbage.
    pub protocol_errors: u32,
    /// |link − target| at the end of the move made under garbage, counts.
    pub garbage_move_error_counts: f64,
    /// Ticks from the last heartbeat's arming to the `command-timeout` fault (its value).
    pub timeout_ms: i32,
    /// What the clear after the timeout did.
    pub after_clear: String,
}

impl std::fmt::Display for Report {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "move 0.5 rad / 300 ms at 0.3 N·m: overshoot {:.2} %, within {:.2} counts from 400 ms on, {} samples at 500 Hz, {} lost; 10 kB garbage in {:.2} s during a move (USART {:.0} B/s): {} protocol errors, move ended {:.2} counts from its target, no fault; target outside the window refused; {} valid frames ({} B) flooded with heartbeats armed, taken in {:.2} s, no fault; command-timeout after {} ms, {}",
            self.overshoot_pct,
            self.settled_error_counts,
            self.samples,
            self.lost_samples,
            self.garbage_secs,
            self.usart_bytes_per_s,
            self.protocol_errors,
            self.garbage_move_error_counts,
            self.flood_frames,
            self.flood_bytes,
            self.flood_secs,
            self.timeout_ms,
            self.after_clear
        )
    }
}

/// Runs the test on `board` with `elf` (built with the board's feature).
pub fn run(board: Board, elf: &Path) -> Result<Report> {
    let client_board = match board {
        Board::QemuM4 => ClientBoard::QemuM4,
        Board::QemuM3 => ClientBoard::QemuM3,
        Board::NucleoF446re => bail!("the end-to-end test runs on an emulated board"),
    };
    let mut opts = QemuOptions::new(client_board, elf);
    opts.firmware_args = vec!["--load-mnm".into(), "300".into()];
    let (log_tx, log_rx) = mpsc::channel();
    let (qemu, transport) = QemuBoard::spawn(&opts, LogSink::Channel(log_tx))
        .map_err(|e| anyhow!("starting the emulated board: {e}"))?;
    let mut garbage_line = transport
        .stream()
        .try_clone()
        .context("cloning the board's socket")?;
    let mut client = Client::new(transport);
    client
        .wait_ready(Duration::from_secs(10), Duration::from_millis(50))
        .map_err(|e| anyhow!("the served firmware did not answer: {e}"))?;

    let result = session(&mut client, &mut garbage_line);
    drop(client);
    drop(qemu); // kills QEMU; the log channel then ends
    let log = decode_log(elf, &log_rx)?;
    let report = result?;
    check_log(&log)?;
    Ok(report)
}

fn session(c: &mut Client, garbage_line: &mut impl Write) -> Result<Report> {
    let err = |what: &'static str| move |e: client::Error| anyhow!("{what}: {e}");
    let s = c.status().map_err(err("status"))?;
    ensure!(
        s.state == State::Disabled && s.faults.is_empty(),
        "fresh board: {s:?}"
    );
    c.set_clutch_length(3_000).map_err(err("clutch 3 mm"))?;
    // k(3 mm) = 265.5 N·m/rad (docs/design.md §2.2): the inverse must give back 3 mm.
    let l = c.set_stiffness(265_500).map_err(err("stiffness"))?;
    ensure!(
        (2_990..=3_010).contains(&l),
        "L(265.5 N·m/rad) = {l} µm, expected 3000 ± 10"
    );
    // No heartbeat yet: the command timeout is armed by the first one (tested last).
    c.enable().map_err(err("enable"))?;
    // The load is hung on at the first driven tick: let the hold take it.
    wait_board(c, 800)?;

    // First move, recorded at 500 Hz.
    c.stream_telemetry(RATE_HZ).map_err(err("telemetry"))?;
    c.wait(Duration::from_millis(50)).map_err(err("wait"))?;
    let start = c.status().map_err(err("status"))?.tick;
    c.move_to(TARGET_URAD, MOVE_MS).map_err(err("move"))?;
    // 1.3 s of board time (a loaded host may run the board slower than real time).
    let mut frames = Vec::new();
    let t = Instant::now();
    while frames
        .last()
        .is_none_or(|f: &TelemetryFrame| f.sample.tick < start + 1_300)
    {
        ensure!(
            t.elapsed() < BOARD_WAIT_MAX,
            "the board stopped sending telemetry"
        );
        c.wait(Duration::from_millis(50))
            .map_err(err("recording"))?;
        frames.extend(c.take_telemetry());
    }
    c.stream_telemetry(0).map_err(err("telemetry off"))?;
    c.wait(Duration::from_millis(50)).map_err(err("wait"))?;
    let (overshoot_pct, settled_error_counts, samples, lost_samples) = check_move(&frames)?;

    // Second move with 10 kB of garbage on the line while it runs, in one burst (no
    // heartbeats are armed yet: a heartbeat sent into the burst would be garbled with it).
    c.move_to(0, MOVE_MS).map_err(err("second move"))?;
    let mut rng = 0x2545_f491_u32;
    let garbage: Vec<u8> = (0..GARBAGE_BYTES)
        .map(|_| {
            rng ^= rng << 13;
            rng ^= rng >> 17;
            rng ^= rng << 5;
            (rng >> 24) as u8
        })
        .collect();
    let t = Instant::now();
    garbage_line
        .write_all(&garbage)
        .context("sending garbage")?;
    // A delimiter ends whatever frame the garbage left open.
    garbage_line.write_all(&[0]).context("sending garbage")?;
    garbage_line.flush().context("sending garbage")?;
    // The board has taken the burst when it answers a request sent after it (QEMU hands
    // the guest one byte per receive interrupt: seconds for 10 kB on the slower M3).
    c.wait_ready(Duration::from_secs(30), Duration::from_millis(200))
        .map_err(err("ping after the garbage"))?;
    let garbage_secs = t.elapsed().as_secs_f64();
    let usart_bytes_per_s = (GARBAGE_BYTES + 1) as f64 / garbage_secs;
    wait_board(c, 800)?;
    let s = c.status().map_err(err("status after garbage"))?;
    ensure!(
        s.state == State::Enabled && s.faults.is_empty(),
        "after the garbage: state {:?}, faults {:?} (first {:?})",
        s.state,
        s.faults,
        s.first_fault
    );
    ensure!(!s.moving, "the move under garbage did not complete");
    ensure!(
        s.protocol_errors > 0,
        "10 kB of garbage counted no protocol error"
    );
    let end = {
        c.stream_telemetry(100).map_err(err("telemetry"))?;
        let f = c
            .next_telemetry(Duration::from_secs(2))
            .map_err(err("sample"))?
            .ok_or_else(|| anyhow!("no telemetry sample after the garbage"))?;
        c.stream_telemetry(0).map_err(err("telemetry off"))?;
        f.sample
    };
    let garbage_move_error_counts = f64::from(end.link_angle_urad).abs() / COUNT_URAD;
    ensure!(
        garbage_move_error_counts <= 1.5,
        "move under garbage ended {garbage_move_error_counts:.2} counts from its target"
    );

    // A target outside the position window (±2.5 rad) is refused, nothing moves.
    match c.move_to(2_520_000, MOVE_MS) {
        Err(client::Error::Refused {
            code: ErrorCode::OutOfRange,
            ..
        }) => {}
        other => bail!("a move to 2.52 rad (outside ±2.5 rad) gave {other:?}"),
    }

    // Heartbeats armed, then a flood of valid frames (status requests) for 1 s at twice
    // what the USART takes: the heartbeats queue behind them for up to a second, and the
    // board must take the frames themselves as link activity.
    c.set_heartbeat(true);
    c.heartbeat().map_err(err("heartbeat"))?;
    c.move_to(TARGET_URAD, MOVE_MS)
        .map_err(err("move under the flood"))?;
    let frame = encode_to_vec(&Frame::new(60_000, Request::GetStatus))
        .map_err(|e| anyhow!("encoding: {e}"))?;
    let flood_frames = (2.0 * usart_bytes_per_s / frame.len() as f64).ceil() as usize;
    let t = Instant::now();
    for i in 0..flood_frames {
        garbage_line.write_all(&frame).context("flooding")?;
        // Spread over a second, as a chatty host would send them.
        let due = Duration::from_secs_f64((i + 1) as f64 / flood_frames as f64);
        c.wait(due.saturating_sub(t.elapsed()))
            .map_err(err("heartbeats during the flood"))?;
    }
    c.wait_ready(Duration::from_secs(30), Duration::from_millis(200))
        .map_err(err("ping after the flood"))?;
    let flood_secs = t.elapsed().as_secs_f64();
    wait_board(c, 300)?;
    let s = c.status().map_err(err("status"))?;
    ensure!(
        s.faults.is_empty() && s.state == State::Enabled,
        "a fault while the heartbeats were queued behind valid frames: {:?}, first {:?}",
        s.faults,
        s.first_fault
    );
    // Watched through telemetry (board to host: not link activity), in board time.
    c.stream_telemetry(50).map_err(err("telemetry"))?;
    c.set_heartbeat(false);
    let t = Instant::now();
    let mut first_tick = None;
    loop {
        ensure!(
            t.elapsed() < BOARD_WAIT_MAX,
            "the board stopped sending telemetry"
        );
        c.wait(Duration::from_millis(20)).map_err(err("timeout"))?;
        let frames = c.take_telemetry();
        let Some(last) = frames.last() else { continue };
        let first = *first_tick.get_or_insert(frames[0].sample.tick);
        if last.sample.faults.contains(FaultCode::CommandTimeout)
            || last.sample.tick > first + 1_000
        {
            break;
        }
    }
    c.stream_telemetry(0).map_err(err("telemetry off"))?;
    let s = c.status().map_err(err("status after timeout"))?;
    let first = s
        .first_fault
        .ok_or_else(|| anyhow!("no fault after the heartbeats stopped: {s:?}"))?;
    ensure!(
        s.state == State::Faulted && first.code == FaultCode::CommandTimeout,
        "after the heartbeats stopped: state {:?}, first fault {first:?}",
        s.state
    );
    ensure!(
        (101..=102).contains(&first.value),
        "command-timeout after {} ms, expected 101 (timeout 100 ms)",
        first.value
    );
    // The timeout ended the session: its condition does not persist (it used to re-latch
    // at once, for ever). With the motor off the 0.3 N·m load falls and bends the beams
    // beyond their envelope, a condition that does persist: then the clear must say so
    // and clear nothing.
    let after_clear = match c.clear_fault() {
        Ok(()) => {
            wait_board(c, 200)?;
            let after = c.status().map_err(err("status after clear"))?;
            ensure!(
                !after.faults.contains(FaultCode::CommandTimeout),
                "command-timeout latched again after the clear: {after:?}"
            );
            "cleared for good".to_string()
        }
        Err(client::Error::FaultPersists { record, .. }) => {
            ensure!(
                record.code != FaultCode::CommandTimeout,
                "the clear found the command timeout persisting"
            );
            format!("the clear refused: {} persists", record.code.name())
        }
        Err(e) => bail!("clear: {e}"),
    };
    Ok(Report {
        overshoot_pct,
        settled_error_counts,
        samples,
        lost_samples,
        garbage_secs,
        usart_bytes_per_s,
        flood_frames,
        flood_bytes: flood_frames * frame.len(),
        flood_secs,
        protocol_errors: s.protocol_errors,
        garbage_move_error_counts,
        timeout_ms: first.value,
        after_clear,
    })
}

/// Longest wall-clock wait for a span of board time.
const BOARD_WAIT_MAX: Duration = Duration::from_secs(60);

/// Waits for `ticks` ms of board time (a loaded host may run the board slower than real
/// time), handling what arrives, heartbeats going on in heartbeat mode.
fn wait_board(c: &mut Client, ticks: u32) -> Result<()> {
    let err = |e: client::Error| anyhow!("waiting for the board: {e}");
    let t0 = board_tick(c)?;
    let t = Instant::now();
    loop {
        c.wait(Duration::from_millis(20)).map_err(err)?;
        if board_tick(c)? >= t0 + ticks {
            c.clear_telemetry();
            return Ok(());
        }
        ensure!(t.elapsed() < BOARD_WAIT_MAX, "the board's time stood still");
    }
}

/// Times a status request for the board's clock is sent anew after the client's own
/// retries went unanswered.
const CLOCK_READS: u32 = 3;

/// The board's tick, from a status request. Here the test only reads the board's clock:
/// a request that went unanswered (after the garbage or the flood the line may still carry
/// their tail, and the client's retries end early on each garbled frame the board reports)
/// is sent anew, up to [`CLOCK_READS`] times, and said on stderr; what the line does to
/// requests is checked where the garbage and the flood are sent.
fn board_tick(c: &mut Client) -> Result<u32> {
    let mut reads = 0;
    loop {
        match c.status() {
            Ok(s) => return Ok(s.tick),
            Err(e @ client::Error::Timeout { .. }) if reads < CLOCK_READS => {
                reads += 1;
                eprintln!("[e2e] reading the board's clock: {e}; asked again");
            }
            Err(e) => return Err(anyhow!("waiting for the board: {e}")),
        }
    }
}

/// Checks the recording of the first move with the figures of `plant::metrics` (clock
/// from the tick the board took the command, recovered from the recorded reference);
/// returns overshoot %, the settled error (counts), the samples and the samples lost.
fn check_move(frames: &[TelemetryFrame]) -> Result<(f64, f64, usize, u64)> {
    ensure!(frames.len() > 100, "only {} samples recorded", frames.len());
    let lost: u64 = frames
        .windows(2)
        .map(|w| u64::from(w[1].counter.wrapping_sub(w[0].counter).saturating_sub(1)))
        .sum();
    let r0 = frames[0].sample.reference_urad;
    let refs: Vec<(u32, i32)> = frames
        .iter()
        .map(|f| (f.sample.tick, f.sample.reference_urad))
        .collect();
    let t0 = move_command_tick(r0, TARGET_URAD, MOVE_MS, &refs)
        .ok_or_else(|| anyhow!("the reference never moved"))?;
    let start = frames
        .iter()
        .rev()
        .find(|f| f.sample.tick <= t0)
        .ok_or_else(|| anyhow!("no sample before the move"))?;
    let last = frames.last().map_or(t0, |f| f.sample.tick);
    ensure!(
        last >= t0 + 1_000,
        "the recording ends {} ms after the move started",
        last.saturating_sub(t0)
    );
    // The measured angle is the centre of its count: ±1 count of the true angle is ≤ 1.5
    // counts of it. Steady from 400 ms: settled by then and stays.
    let mut step = StepResponse::new(
        f64::from(start.sample.link_angle_urad),
        f64::from(TARGET_URAD),
        1.5 * COUNT_URAD,
        0.4,
    );
    for f in frames.iter().filter(|f| f.sample.tick > t0) {
        let t_s = f64::from(f.sample.tick - t0) * 1e-3;
        step.record(t_s, f64::from(f.sample.link_angle_urad));
    }
    let fig = step.figures();
    let overshoot = fig.overshoot_pct;
    let settled = fig.steady_state_error / COUNT_URAD;
    ensure!(overshoot <= 5.0, "overshoot {overshoot:.2} % > 5 %");
    ensure!(
        settled <= 1.5,
        "from 400 ms after the move started the link was up to {settled:.2} counts from the target"
    );
    Ok((overshoot, settled, frames.len(), lost))
}

fn decode_log(elf: &Path, rx: &mpsc::Receiver<Vec<u8>>) -> Result<Vec<String>> {
    let format = LogFormat::from_elf(elf)?;
    let mut decoder = format.decoder();
    let mut lines = Vec::new();
    while let Ok(bytes) = rx.recv_timeout(Duration::from_secs(5)) {
        lines.extend(decoder.feed(&bytes));
    }
    Ok(lines)
}

/// The board's own log: no overrun, and no fault but the expected timeout (and what the
/// falling load causes after it).
fn check_log(lines: &[String]) -> Result<()> {
    if let Some(l) = lines.iter().find(|l| l.contains("overruns")) {
        bail!("the board logged an overrun: {l}");
    }
    let faults: Vec<&String> = lines.iter().filter(|l| l.contains("FAULT")).collect();
    match faults.first() {
        Some(l) if l.contains("FAULT command-timeout") => Ok(()),
        Some(l) => bail!("the first fault the board logged is not the timeout: {l}"),
        None => bail!("the board logged no FAULT line for the timeout"),
    }
}
