//! The emulated boards: building the firmware and running it under QEMU with its command
//! UART connected to this process over TCP.
//!
//! The firmware serves the protocol on USART2, QEMU's *second* `-serial` device, so QEMU
//! runs as
//!
//! ```text
//! qemu-system-arm -machine netduinoplus2 -display none -monitor none
//!     -serial null -serial tcp:127.0.0.1:PORT
//!     -semihosting-config enable=on,target=native,arg=vsa-firmware,arg=--serve[,arg=…]
//!     -icount shift=3,sleep=on,align=on -kernel ELF
//! ```
//!
//! (`sleep=on,align=on`: virtual time is the instruction count, 8 ns each, and QEMU sleeps
//! whenever the guest runs ahead of real time, so the board keeps time with the host's
//! heartbeats.) QEMU connects to PORT as a TCP client: [`QemuBoard::spawn`] binds a
//! listener on 127.0.0.1 first, starts QEMU, and accepts its connection. QEMU's stdout
//! carries the firmware's defmt log (binary defmt frames): a thread drains it into a
//! [`LogSink`]. The UART drops what arrives before the firmware enables it, so
//! [`QemuBoard::start`] pings every 50 ms until the firmware answers. Dropping the
//! [`QemuBoard`] kills QEMU.

use std::fmt;
use std::io::{Read, Write};
use std::net::TcpListener;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::str::FromStr;
use std::sync::mpsc::Sender;
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use crate::client::Client;
use crate::transport::TcpTransport;
use crate::{Error, Result};

/// How long to wait for QEMU to connect to the listener.
pub const CONNECT_TIMEOUT: Duration = Duration::from_secs(10);
/// How long to ping until the firmware answers.
pub const READY_TIMEOUT: Duration = Duration::from_secs(10);
/// Interval between the readiness pings.
pub const READY_PING_INTERVAL: Duration = Duration::from_millis(50);
/// `-icount shift`: 8 ns of virtual time per instruction (125 MIPS).
pub const ICOUNT_SHIFT: u32 = 3;
/// QEMU's stderr kept for error messages, bytes.
const STDERR_KEEP: usize = 16 * 1024;

/// An emulated board.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Board {
    /// QEMU `netduinoplus2`: STM32F405, Cortex-M4F (`thumbv7em-none-eabihf`).
    QemuM4,
    /// QEMU `netduino2`: STM32F205, Cortex-M3 (`thumbv7m-none-eabi`).
    QemuM3,
}

impl Board {
    /// Both emulated boards.
    pub const ALL: [Board; 2] = [Board::QemuM4, Board::QemuM3];

    /// The board's name and cargo feature: `qemu-m4`, `qemu-m3`.
    #[must_use]
    pub const fn name(self) -> &'static str {
        match self {
            Board::QemuM4 => "qemu-m4",
            Board::QemuM3 => "qemu-m3",
        }
    }

    /// The QEMU machine.
    #[must_use]
    pub const fn machine(self) -> &'static str {
        match self {
            Board::QemuM4 => "netduinoplus2",
            Board::QemuM3 => "netduino2",
        }
    }

    /// The Rust target triple.
    #[must_use]
    pub const fn target(self) -> &'static str {
        match self {
            Board::QemuM4 => "thumbv7em-none-eabihf",
            Board::QemuM3 => "thumbv7m-none-eabi",
        }
    }
}

impl fmt::Display for Board {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Board {
    type Err = String;

    fn from_str(s: &str) -> std::result::Result<Board, String> {
        Board::ALL
            .into_iter()
            .find(|b| b.name() == s)
            .ok_or_else(|| format!("unknown emulated board '{s}' (qemu-m4, qemu-m3)"))
    }
}

/// The vsa workspace to build the firmware in: `$VSA_WORKSPACE` if set, else the workspace
/// this crate was compiled in, if it is still there.
#[must_use]
pub fn workspace_root() -> Option<PathBuf> {
    let root = std::env::var_os("VSA_WORKSPACE")
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join(".."));
    root.join("firmware")
        .join("Cargo.toml")
        .is_file()
        .then(|| root.canonicalize().unwrap_or(root))
}

/// Where `cargo build --release` puts the firmware ELF for `board`:
/// `$CARGO_TARGET_DIR/<triple>/release/vsa-firmware` (`<root>/target` by default).
#[must_use]
pub fn elf_path(root: &Path, board: Board) -> PathBuf {
    let target_dir = std::env::var_os("CARGO_TARGET_DIR")
        .map(PathBuf::from)
        .map_or_else(|| root.join("target"), |d| root.join(d));
    target_dir
        .join(board.target())
        .join("release")
        .join("vsa-firmware")
}

/// Builds the firmware for `board` in the workspace at `root` (`cargo build --release -p
/// vsa-firmware --target <triple> --no-default-features --features <board>`; cargo's
/// progress goes to this process's stderr) and returns the ELF's path.
///
/// # Errors
/// [`Error::Qemu`] if cargo cannot be run, fails, or leaves no ELF.
pub fn build_firmware(root: &Path, board: Board) -> Result<PathBuf> {
    let cargo = std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into());
    let status = Command::new(&cargo)
        .current_dir(root)
        .args(["build", "--release", "-p", "vsa-firmware", "--target"])
        .arg(board.target())
        .args(["--no-default-features", "--features", board.name()])
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::inherit())
        .status()
        .map_err(|e| Error::Qemu(format!("running {}: {e}", Path::new(&cargo).display())))?;
    if !status.success() {
        return Err(Error::Qemu(format!(
            "building the {board} firmware failed ({status})"
        )));
    }
    let elf = elf_path(root, board);
    if elf.is_file() {
        Ok(elf)
    } else {
        Err(Error::Qemu(format!(
            "cargo built the {board} firmware but {} does not exist",
            elf.display()
        )))
    }
}

/// Where the firmware's defmt log bytes (QEMU's stdout) go.
pub enum LogSink {
    /// Dropped.
    Discard,
    /// Written (and flushed when QEMU's stdout closes).
    Writer(Box<dyn Write + Send>),
    /// Sent as chunks; a closed receiver stops nothing (the bytes are then dropped).
    Channel(Sender<Vec<u8>>),
}

impl fmt::Debug for LogSink {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            LogSink::Discard => "Discard",
            LogSink::Writer(_) => "Writer",
            LogSink::Channel(_) => "Channel",
        })
    }
}

impl LogSink {
    fn take(&mut self, bytes: &[u8]) {
        match self {
            LogSink::Discard => {}
            LogSink::Writer(w) => {
                if w.write_all(bytes).is_err() {
                    *self = LogSink::Discard;
                }
            }
            LogSink::Channel(tx) => {
                if tx.send(bytes.to_vec()).is_err() {
                    *self = LogSink::Discard;
                }
            }
        }
    }

    fn finish(&mut self) {
        if let LogSink::Writer(w) = self {
            let _ = w.flush();
        }
    }
}

/// How to run an emulated board.
#[derive(Clone, Debug)]
pub struct QemuOptions {
    /// The board.
    pub board: Board,
    /// The firmware ELF built for it.
    pub elf: PathBuf,
    /// Firmware arguments after `--serve` (semihosting command line; no commas).
    pub firmware_args: Vec<String>,
    /// The QEMU binary.
    pub qemu: PathBuf,
    /// `-icount shift=N,sleep=on[,align=on]`.
    pub icount_shift: u32,
    /// `align=on` in `-icount` (QEMU sleeps when the guest runs ahead of real time).
    pub align: bool,
    /// Which `-serial` device (0-based) is the firmware's command UART: 1 (USART2, the
    /// second device; the ones before it are `null`).
    pub serial_index: usize,
    /// How long QEMU may take to connect.
    pub connect_timeout: Duration,
    /// How long the firmware may take to answer a ping ([`QemuBoard::start`]).
    pub ready_timeout: Duration,
}

impl QemuOptions {
    /// Defaults for `board` running `elf`.
    #[must_use]
    pub fn new(board: Board, elf: impl Into<PathBuf>) -> QemuOptions {
        QemuOptions {
            board,
            elf: elf.into(),
            firmware_args: Vec::new(),
            qemu: PathBuf::from("qemu-system-arm"),
            icount_shift: ICOUNT_SHIFT,
            align: true,
            serial_index: 1,
            connect_timeout: CONNECT_TIMEOUT,
            ready_timeout: READY_TIMEOUT,
        }
    }

    /// The `-semihosting-config` value.
    fn semihosting(&self) -> Result<String> {
        let mut s = String::from("enable=on,target=native,arg=vsa-firmware,arg=--serve");
        for a in &self.firmware_args {
            if a.contains(',') || a.is_empty() {
                return Err(Error::Qemu(format!(
                    "firmware argument {a:?} may not be empty or contain ','"
                )));
            }
            s.push_str(",arg=");
            s.push_str(a);
        }
        Ok(s)
    }
}

/// A running emulated board. Dropping it kills QEMU.
pub struct QemuBoard {
    child: Child,
    board: Board,
    log_thread: Option<JoinHandle<()>>,
    stderr_thread: Option<JoinHandle<()>>,
    stderr: Arc<Mutex<Vec<u8>>>,
}

impl fmt::Debug for QemuBoard {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("QemuBoard")
            .field("board", &self.board)
            .field("pid", &self.child.id())
            .finish_non_exhaustive()
    }
}

impl QemuBoard {
    /// Starts `elf` on `board` serving the protocol, with `firmware_args` after `--serve`,
    /// the defmt log going to `log`, and returns the board and a client that the firmware
    /// has answered (pinged every 50 ms for up to 10 s).
    ///
    /// # Errors
    /// [`Error::Qemu`] if QEMU does not start or connect, or the firmware does not answer.
    pub fn start(
        board: Board,
        elf: &Path,
        firmware_args: &[String],
        log: LogSink,
    ) -> Result<(QemuBoard, Client)> {
        let mut opts = QemuOptions::new(board, elf);
        opts.firmware_args = firmware_args.to_vec();
        QemuBoard::start_with(&opts, log)
    }

    /// [`QemuBoard::start`] with every option.
    ///
    /// # Errors
    /// As [`QemuBoard::start`].
    pub fn start_with(opts: &QemuOptions, log: LogSink) -> Result<(QemuBoard, Client)> {
        let (mut qemu, transport) = QemuBoard::spawn(opts, log)?;
        let mut client = Client::new(transport);
        match client.wait_ready(opts.ready_timeout, READY_PING_INTERVAL) {
            Ok(()) => Ok((qemu, client)),
            Err(e) => {
                let what = match e {
                    Error::Timeout { .. } => {
                        format!("within {} s", opts.ready_timeout.as_secs())
                    }
                    other => format!("({other})"),
                };
                Err(Error::Qemu(format!(
                    "the {} firmware did not answer a ping {what}{}; is it a firmware that \
                     serves the protocol (--serve)?",
                    opts.board,
                    qemu.exit_report()
                )))
            }
        }
    }

    /// Starts QEMU and accepts its serial connection, without pinging.
    ///
    /// # Errors
    /// [`Error::Qemu`] if the ELF is missing, QEMU does not start, exits, or does not
    /// connect within the timeout.
    pub fn spawn(opts: &QemuOptions, mut log: LogSink) -> Result<(QemuBoard, TcpTransport)> {
        if !opts.elf.is_file() {
            return Err(Error::Qemu(format!(
                "firmware ELF {} does not exist",
                opts.elf.display()
            )));
        }
        let semihosting = opts.semihosting()?;
        let err = |what: &str, e: std::io::Error| Error::Qemu(format!("{what}: {e}"));
        let listener =
            TcpListener::bind("127.0.0.1:0").map_err(|e| err("binding 127.0.0.1:0", e))?;
        let port = listener
            .local_addr()
            .map_err(|e| err("listener address", e))?
            .port();
        let mut cmd = Command::new(&opts.qemu);
        cmd.args(["-machine", opts.board.machine()])
            .args(["-display", "none", "-monitor", "none"]);
        for _ in 0..opts.serial_index {
            cmd.args(["-serial", "null"]);
        }
        let mut child = cmd
            .arg("-serial")
            .arg(format!("tcp:127.0.0.1:{port}"))
            .arg("-semihosting-config")
            .arg(&semihosting)
            .arg("-icount")
            .arg(format!(
                "shift={},sleep=on{}",
                opts.icount_shift,
                if opts.align { ",align=on" } else { "" }
            ))
            .arg("-kernel")
            .arg(&opts.elf)
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .map_err(|e| err(&format!("starting {}", opts.qemu.display()), e))?;

        let stdout = child.stdout.take();
        let log_thread = stdout.map(|mut out| {
            std::thread::spawn(move || {
                let mut buf = [0u8; 4096];
                while let Ok(n) = out.read(&mut buf) {
                    match buf.get(..n) {
                        Some(b) if n > 0 => log.take(b),
                        _ => break,
                    }
                }
                log.finish();
            })
        });
        let stderr = Arc::new(Mutex::new(Vec::new()));
        let stderr_thread = child.stderr.take().map(|mut err_pipe| {
            let keep = Arc::clone(&stderr);
            std::thread::spawn(move || {
                let mut buf = [0u8; 1024];
                while let Ok(n) = err_pipe.read(&mut buf) {
                    let Some(b) = buf.get(..n).filter(|_| n > 0) else {
                        break;
                    };
                    if let Ok(mut k) = keep.lock() {
                        if k.len() < STDERR_KEEP {
                            k.extend_from_slice(b);
                        }
                    }
                }
            })
        });
        let mut qemu = QemuBoard {
            child,
            board: opts.board,
            log_thread,
            stderr_thread,
            stderr,
        };

        listener
            .set_nonblocking(true)
            .map_err(|e| err("listener", e))?;
        let start = Instant::now();
        let stream = loop {
            match listener.accept() {
                Ok((s, _)) => break s,
                Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {
                    if let Some(status) = qemu.try_wait() {
                        let stderr = qemu.stderr_text();
                        return Err(Error::Qemu(format!(
                            "QEMU exited ({status}) before connecting to the serial port{}",
                            if stderr.is_empty() {
                                String::new()
                            } else {
                                format!(": {stderr}")
                            }
                        )));
                    }
                    if start.elapsed() > opts.connect_timeout {
                        return Err(Error::Qemu(format!(
                            "QEMU did not connect to 127.0.0.1:{port} within {} s",
                            opts.connect_timeout.as_secs()
                        )));
                    }
                    std::thread::sleep(Duration::from_millis(5));
                }
                Err(e) => return Err(err("accepting QEMU's connection", e)),
            }
        };
        let transport = TcpTransport::from_stream(stream).map_err(|e| err("QEMU socket", e))?;
        Ok((qemu, transport))
    }

    /// The board.
    #[must_use]
    pub fn board(&self) -> Board {
        self.board
    }

    /// QEMU's process id.
    #[must_use]
    pub fn pid(&self) -> u32 {
        self.child.id()
    }

    /// QEMU's exit status if it has exited (the firmware's semihosting exit status).
    pub fn try_wait(&mut self) -> Option<ExitStatus> {
        self.child.try_wait().ok().flatten()
    }

    /// What QEMU wrote on stderr so far (at most 16 KiB), trimmed.
    #[must_use]
    pub fn stderr_text(&self) -> String {
        self.stderr
            .lock()
            .map(|b| String::from_utf8_lossy(&b).trim().to_string())
            .unwrap_or_default()
    }

    /// `"; QEMU exited (status): stderr"` if QEMU has exited (waiting up to 300 ms for it
    /// to), else `""`: to append to an error message when the connection fails.
    pub fn exit_report(&mut self) -> String {
        let start = Instant::now();
        let mut status = self.try_wait();
        while status.is_none() && start.elapsed() < Duration::from_millis(300) {
            std::thread::sleep(Duration::from_millis(10));
            status = self.try_wait();
        }
        match status {
            None => String::new(),
            Some(status) => {
                // Give the stderr thread a moment to collect the last words.
                std::thread::sleep(Duration::from_millis(50));
                let stderr = self.stderr_text();
                if stderr.is_empty() {
                    format!("; QEMU exited ({status})")
                } else {
                    format!("; QEMU exited ({status}): {stderr}")
                }
            }
        }
    }

    /// Kills QEMU and waits for it and the log thread (the sink has every byte after this).
    pub fn kill(&mut self) {
        if self.try_wait().is_none() {
            let _ = self.child.kill();
        }
        let _ = self.child.wait();
        if let Some(t) = self.log_thread.take() {
            let _ = t.join();
        }
        if let Some(t) = self.stderr_thread.take() {
            let _ = t.join();
        }
    }
}

impl Drop for QemuBoard {
    fn drop(&mut self) {
        self.kill();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn boards() {
        assert_eq!("qemu-m3".parse::<Board>(), Ok(Board::QemuM3));
        assert!("nucleo".parse::<Board>().is_err());
        assert_eq!(Board::QemuM4.machine(), "netduinoplus2");
        let mut o = QemuOptions::new(Board::QemuM4, "x");
        assert_eq!(
            o.semihosting().unwrap(),
            "enable=on,target=native,arg=vsa-firmware,arg=--serve"
        );
        o.firmware_args = vec!["--seconds".into(), "3".into()];
        assert!(o.semihosting().unwrap().ends_with(",arg=--seconds,arg=3"));
        o.firmware_args = vec!["a,b".into()];
        assert!(o.semihosting().is_err());
    }

    #[test]
    fn missing_elf_is_a_clear_error() {
        let o = QemuOptions::new(Board::QemuM4, "/nonexistent/vsa-firmware");
        let e = QemuBoard::spawn(&o, LogSink::Discard).unwrap_err();
        assert!(e.to_string().contains("does not exist"), "{e}");
    }
}
