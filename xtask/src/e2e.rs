//! The end-to-end test of the host link: an emulated board serving the protocol
//! (`--serve`), driven through the same `client` library as `vsa`, is configured, enabled,
//! moved and recorded; 10 kB of random bytes are sent during a second move; then the
//! heartbeats stop and the board must latch `command-timeout`.
//!
//! The recorded motion is held to the controller's tolerances for a 0.5 rad move with a
//! 0.3 N·m load (`--load-mnm 300`): overshoot ≤ 5 %, within ±1 encoder count of the target
//! from 400 ms after the command to the end of the recording (`plant::metrics`).

use std::io::Write;
use std::path::Path;
use std::sync::mpsc;
use std::time::{Duration, Instant};

use anyhow::{anyhow, bail, ensure, Context, Result};
use client::qemu::{Board as ClientBoard, LogSink, QemuBoard, QemuOptions};
use client::{Client, FaultCode, State, TelemetryFrame};
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
    /// Protocol errors counted by the board after the garbage.
    pub protocol_errors: u32,
    /// |link − target| at the end of the move made under garbage, counts.
    pub garbage_move_error_counts: f64,
    /// Ticks from the last heartbeat's arming to the `command-timeout` fault (its value).
    pub timeout_ms: i32,
}

impl std::fmt::Display for Report {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "move 0.5 rad / 300 ms at 0.3 N·m: overshoot {:.2} %, within {:.2} counts from 400 ms on, {} samples at 500 Hz, {} lost; 10 kB garbage in {:.2} s during a move: {} protocol errors, move ended {:.2} counts from its target, no fault; command-timeout after {} ms",
            self.overshoot_pct,
            self.settled_error_counts,
            self.samples,
            self.lost_samples,
            self.garbage_secs,
            self.protocol_errors,
            self.garbage_move_error_counts,
            self.timeout_ms
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
    c.wait(Duration::from_millis(800)).map_err(err("hold"))?;

    // First move, recorded at 500 Hz.
    c.stream_telemetry(RATE_HZ).map_err(err("telemetry"))?;
    c.wait(Duration::from_millis(50)).map_err(err("wait"))?;
    c.move_to(TARGET_URAD, MOVE_MS).map_err(err("move"))?;
    c.wait(Duration::from_millis(1_300))
        .map_err(err("recording"))?;
    c.stream_telemetry(0).map_err(err("telemetry off"))?;
    c.wait(Duration::from_millis(50)).map_err(err("wait"))?;
    let frames = c.take_telemetry();
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
    c.wait(Duration::from_millis(800))
        .map_err(err("after garbage"))?;
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

    // Heartbeats for a while, then none: command-timeout after the timeout (100 ms) + a
    // tick.
    c.set_heartbeat(true);
    c.heartbeat().map_err(err("heartbeat"))?;
    c.wait(Duration::from_millis(300))
        .map_err(err("heartbeats"))?;
    ensure!(
        c.status().map_err(err("status"))?.faults.is_empty(),
        "a fault while the heartbeats were coming"
    );
    c.set_heartbeat(false);
    c.wait(Duration::from_millis(400)).map_err(err("timeout"))?;
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
    c.clear_fault().map_err(err("clear"))?;
    Ok(Report {
        overshoot_pct,
        settled_error_counts,
        samples,
        lost_samples,
        garbage_secs,
        protocol_errors: s.protocol_errors,
        garbage_move_error_counts,
        timeout_ms: first.value,
    })
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
