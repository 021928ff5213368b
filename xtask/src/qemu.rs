//! Running a firmware ELF on its emulated board and decoding what it logs.

use anyhow::{bail, Context, Result};
use std::io::Read;
use std::path::Path;
use std::process::{Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use crate::board::Board;
use crate::defmt_log::LogFormat;

/// `-icount shift=3`: virtual time advances 8 ns per instruction (125 MIPS), and
/// `sleep=off` lets WFI skip ahead: runs are deterministic and faster than real time.
pub const ICOUNT_SHIFT: u32 = 3;

/// What an emulated run produced.
pub struct RunOutcome {
    /// Decoded log lines, in order.
    pub lines: Vec<String>,
    /// QEMU's exit code (the firmware's semihosting exit status).
    pub exit_code: i32,
    /// defmt frames that did not decode.
    pub malformed_frames: usize,
}

/// Runs `elf` on `board`'s QEMU machine with `args` on the semihosting command line,
/// at `-icount shift=`[`ICOUNT_SHIFT`]. Each decoded line is passed to `on_line` as soon
/// as it arrives.
pub fn run(
    board: Board,
    elf: &Path,
    args: &[String],
    wall_limit: Duration,
    on_line: impl FnMut(&str),
) -> Result<RunOutcome> {
    run_with_shift(board, elf, args, ICOUNT_SHIFT, wall_limit, on_line)
}

/// [`run`] at `-icount shift=shift` (one instruction = 2^shift ns of virtual time).
pub fn run_with_shift(
    board: Board,
    elf: &Path,
    args: &[String],
    shift: u32,
    wall_limit: Duration,
    mut on_line: impl FnMut(&str),
) -> Result<RunOutcome> {
    let machine = board
        .qemu_machine()
        .with_context(|| format!("{} is a real board, not an emulated one", board.feature()))?;
    let format = LogFormat::from_elf(elf)?;
    let mut semihosting = String::from("enable=on,target=native,arg=vsa-firmware");
    for arg in args {
        if arg.contains(',') {
            bail!("firmware argument {arg:?} may not contain ','");
        }
        semihosting.push_str(",arg=");
        semihosting.push_str(arg);
    }
    let mut child = Command::new("qemu-system-arm")
        .args(["-machine", machine, "-display", "none", "-monitor", "none"])
        .args(["-serial", "null"])
        .args(["-semihosting-config", &semihosting])
        .args(["-icount", &format!("shift={shift},sleep=off")])
        .arg("-kernel")
        .arg(elf)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .context("starting qemu-system-arm")?;

    // Read QEMU's stdout (the defmt bytes) on a thread, so the wall-clock limit below
    // can still fire if the firmware hangs.
    let mut stdout = child.stdout.take().context("QEMU stdout")?;
    let (tx, rx) = mpsc::channel::<Vec<u8>>();
    let reader = std::thread::spawn(move || {
        let mut buf = [0u8; 4096];
        while let Ok(n) = stdout.read(&mut buf) {
            if n == 0 || tx.send(buf[..n].to_vec()).is_err() {
                break;
            }
        }
    });

    let mut decoder = format.decoder();
    let mut lines = Vec::new();
    let deadline = Instant::now() + wall_limit;
    loop {
        match rx.recv_timeout(Duration::from_millis(100)) {
            Ok(bytes) => {
                for line in decoder.feed(&bytes) {
                    on_line(&line);
                    lines.push(line);
                }
            }
            Err(mpsc::RecvTimeoutError::Disconnected) => break,
            Err(mpsc::RecvTimeoutError::Timeout) => {
                if Instant::now() > deadline {
                    let _ = child.kill();
                    let _ = child.wait();
                    bail!(
                        "the firmware did not exit within {} s of wall-clock time; QEMU killed",
                        wall_limit.as_secs()
                    );
                }
            }
        }
    }
    let _ = reader.join();
    let status = child.wait().context("waiting for QEMU")?;
    let exit_code = status.code().unwrap_or(-1);
    Ok(RunOutcome {
        lines,
        exit_code,
        malformed_frames: decoder.malformed(),
    })
}
