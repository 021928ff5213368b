//! Running a firmware ELF on its emulated board and decoding what it logs.
//!
//! The command line is the client crate's ([`client::qemu::QemuCommand`]), and so is the
//! filter that takes QEMU's own messages out of its stdout, where the firmware's defmt
//! frames come ([`client::qemu::MessageFilter`]): the messages go to this process's
//! stderr, the frames to the decoder intact. QEMU dies with this process.

use anyhow::{anyhow, bail, Context, Result};
use client::qemu::{MessageFilter, QemuCommand};
use std::io::{Read, Write};
use std::path::Path;
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
    let mut argv = vec!["vsa-firmware".to_owned()];
    argv.extend(args.iter().cloned());
    let line = QemuCommand {
        qemu: "qemu-system-arm".into(),
        machine: machine.to_owned(),
        elf: elf.to_path_buf(),
        argv,
        serials: vec!["null".to_owned()],
        icount: format!("shift={shift},sleep=off"),
    };
    let mut child = line
        .command()
        .map_err(|e| anyhow!("{e}"))?
        .spawn()
        .context("starting qemu-system-arm")?;
    // QEMU's stderr goes to ours.
    let relay = child.stderr.take().map(|mut pipe| {
        std::thread::spawn(move || {
            let mut buf = [0u8; 1024];
            while let Ok(n) = pipe.read(&mut buf) {
                if n == 0 || std::io::stderr().write_all(&buf[..n]).is_err() {
                    break;
                }
            }
        })
    });

    // Read QEMU's stdout (the defmt bytes, QEMU's messages taken out to stderr) on a
    // thread, so the wall-clock limit below can still fire if the firmware hangs.
    let mut stdout = child.stdout.take().context("QEMU stdout")?;
    let (tx, rx) = mpsc::channel::<Vec<u8>>();
    let reader = std::thread::spawn(move || {
        let mut filter = MessageFilter::new();
        let mut buf = [0u8; 4096];
        loop {
            let n = stdout.read(&mut buf).unwrap_or(0);
            let (mut log, mut messages) = (Vec::new(), Vec::new());
            if n == 0 {
                filter.finish(&mut log, &mut messages);
            } else {
                filter.feed(&buf[..n], &mut log, &mut messages);
            }
            let _ = std::io::stderr().write_all(&messages);
            if (!log.is_empty() && tx.send(log).is_err()) || n == 0 {
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
    if let Some(r) = relay {
        let _ = r.join();
    }
    let exit_code = status.code().unwrap_or(-1);
    Ok(RunOutcome {
        lines,
        exit_code,
        malformed_frames: decoder.malformed(),
    })
}
