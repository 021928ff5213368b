//! Power-up anywhere, on an emulated board: the link at rest away from the pot's centre
//! and the incremental encoder reading zero there (`--plant power-up-angle=…`), and the
//! build is imperfect (a bowed, noisy pot; a current sense with an offset and noise). The
//! board must align the encoder to the pot in its boot window with the motor off, latch
//! nothing, report the link angle (telemetry) within the free play plus one pot count and
//! the bow of the true one, and then move.

use std::path::Path;
use std::time::Duration;

use anyhow::{anyhow, bail, ensure, Result};
use client::qemu::{Board as ClientBoard, LogSink, QemuBoard, QemuOptions};
use client::{Client, State, TelemetryFrame};
use model::control::{Config, Schedule};
use model::sensors::POT_COUNT_Q32;
use model::{Design, Length};

use crate::board::Board;

/// True link angles at power-up, rad: either side of the pot's centre.
const ANGLES_RAD: [f64; 2] = [0.8, -1.2];
/// The build is as imperfect as a real one without calibration may be: a pot bowed by
/// this many counts over its track (A·sin(2π·c/1024)) with noise, and a current sense off
/// by tens of counts with noise (what the boot window measures).
const POT_BOW_COUNTS: f64 = 1.5;
/// The rest of the imperfect build, `--plant` overrides (docs/calibration.md).
const IMPERFECT: [&str; 3] = ["pot-noise=0.3", "current-offset=30", "current-noise=1"];
/// The move made after power-up, rad from where the link is.
const MOVE_RAD: f64 = 0.3;
/// Its duration, ms.
const MOVE_MS: u32 = 300;
/// How far the link may end from the move's target, encoder counts (the controller's
/// ±1 count and the count's centre).
const MOVE_TOLERANCE_COUNTS: f64 = 2.0;

fn q32(bits: i64) -> f64 {
    bits as f64 / 4_294_967_296.0
}

/// The newest telemetry sample within `wait`.
fn latest(client: &mut Client, wait: Duration) -> Result<TelemetryFrame> {
    client.clear_telemetry();
    client.wait(wait)?;
    client
        .take_telemetry()
        .pop()
        .ok_or_else(|| anyhow!("no telemetry within {} ms", wait.as_millis()))
}

/// One power-up at `angle` rad; what it measured.
fn one(board: ClientBoard, elf: &Path, angle: f64) -> Result<String> {
    let mut opts = QemuOptions::new(board, elf);
    // The step sweep's 0.3 N·m, hung on at the first driven tick, keeps the beams in
    // contact for the move (a free link floats in the free play).
    opts.firmware_args = vec![
        "--plant".into(),
        format!("power-up-angle={angle}rad"),
        "--plant".into(),
        format!("pot-nonlinearity={POT_BOW_COUNTS}"),
        "--load-mnm".into(),
        "300".into(),
    ];
    for o in IMPERFECT {
        opts.firmware_args.extend(["--plant".into(), o.into()]);
    }
    let (_qemu, mut client) =
        QemuBoard::start_with(&opts, LogSink::Discard).map_err(|e| anyhow!("{e}"))?;
    // The boot window: 32 ms of alignment, the motor off.
    client.wait(Duration::from_millis(100))?;
    let st = client.status()?;
    ensure!(
        st.faults.is_empty() && st.state == State::Disabled,
        "after power-up at {angle} rad: {st:?}"
    );
    // The free play at the board's clutch length, plus one pot count and the pot's bow:
    // how far the link angle from the pot may be from the true one (docs/calibration.md).
    let length = Length::from_micro(i64::from(st.clutch_length_um) * 1000)
        .map_err(|e| anyhow!("clutch length {} µm: {e:?}", st.clutch_length_um))?;
    let sched = Schedule::new(&Design::paper(), &Config::paper(length))
        .map_err(|e| anyhow!("schedule: {e:?}"))?;
    let tolerance = q32(sched.free_play().to_bits()) + (1.0 + POT_BOW_COUNTS) * q32(POT_COUNT_Q32);
    client.stream_telemetry(100)?;
    let at_rest = latest(&mut client, Duration::from_millis(200))?.sample;
    let seen = f64::from(at_rest.link_angle_urad) * 1e-6;
    ensure!(
        (seen - angle).abs() <= tolerance,
        "link at {angle} rad reported at {seen:.4} rad (tolerance {tolerance:.4} rad)"
    );
    ensure!(
        at_rest.faults.is_empty(),
        "fault latched at rest: {:?}",
        at_rest.faults
    );
    client.enable()?;
    let target = seen + MOVE_RAD;
    client.move_to((target * 1e6).round() as i32, MOVE_MS)?;
    let end = latest(&mut client, Duration::from_millis(u64::from(MOVE_MS) + 600))?.sample;
    let count = q32(model::sensors::ENCODER_COUNT_Q32);
    let error = (f64::from(end.link_angle_urad) * 1e-6 - target).abs() / count;
    let st = client.status()?;
    if !st.faults.is_empty() {
        bail!("fault during the move from {angle} rad: {st:?}");
    }
    ensure!(
        error <= MOVE_TOLERANCE_COUNTS,
        "the move from {angle} rad ended {error:.2} counts from its target"
    );
    Ok(format!(
        "at {angle:+} rad: reported {seen:+.4} rad (|error| {:.4} ≤ {tolerance:.4}), no fault, moved +{MOVE_RAD} rad to within {error:.2} counts",
        (seen - angle).abs()
    ))
}

/// Powers `board` (running `elf`) up at each of [`ANGLES_RAD`].
pub fn check(board: Board, elf: &Path) -> Result<String> {
    let client_board = match board {
        Board::QemuM4 => ClientBoard::QemuM4,
        Board::QemuM3 => ClientBoard::QemuM3,
        Board::NucleoF446re => bail!("the power-up check runs on an emulated board"),
    };
    let mut out = Vec::new();
    for angle in ANGLES_RAD {
        out.push(one(client_board, elf, angle)?);
    }
    Ok(out.join("; "))
}
