//! The emulated boards: building the firmware and running it under QEMU with its command
//! UART connected to this process over TCP.
//!
//! The firmware serves the protocol on USART2, QEMU's *second* `-serial` device, so QEMU
//! runs as
//!
//! ```text
//! qemu-system-arm -machine netduinoplus2 -display none -monitor none
//!     -serial null -serial tcp:127.0.0.1:PORT,nodelay=on
//!     -semihosting-config enable=on,target=native,arg=vsa-firmware,arg=--serve[,arg=…]
//!     -icount shift=3,sleep=on,align=on -kernel ELF
//! ```
//!
//! (`sleep=on,align=on`: virtual time is the instruction count, 8 ns each, and QEMU sleeps
//! whenever the guest runs ahead of real time, so the board keeps time with the host's
//! heartbeats.) QEMU connects to PORT as a TCP client: [`QemuBoard::spawn`] binds a
//! listener on 127.0.0.1 first, starts QEMU, and accepts its connection. [`QemuCommand`]
//! is the one definition of the command line, also used by the xtask.
//!
//! The firmware's defmt log (binary defmt frames) comes on QEMU's stdout: the firmware
//! writes it to the semihosting handle `:tt`, which QEMU 7.2 writes to its own stdout one
//! byte at a time, whatever `-semihosting-config chardev=` says (measured: such a chardev
//! stays empty). QEMU's own message on stdout, "Warning: The guest is now late by X to Y
//! seconds" (one `write` of the whole line, when the host is too busy to keep the board in
//! real time under `align=on`), lands in the middle of a binary frame. [`MessageFilter`]
//! takes such lines out of the byte stream, which restores the frame exactly; a thread
//! passes the rest to a [`LogSink`] as it comes and keeps the messages with QEMU's stderr
//! for error messages.
//!
//! QEMU dies with this process: it is started with the parent-death signal SIGKILL
//! (`prctl(PR_SET_PDEATHSIG)`), so not even a SIGKILL of `vsa` leaves it running. The UART
//! drops what arrives before the firmware enables it, so [`QemuBoard::start`] pings every
//! 50 ms until the firmware answers. Dropping the [`QemuBoard`] kills QEMU.

use std::fmt;
use std::io::{Read, Write};
use std::net::{TcpListener, TcpStream};
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

/// The workspace's cargo target directory: `$CARGO_TARGET_DIR` (relative to `root`), else
/// `<root>/target`.
#[must_use]
pub fn target_dir(root: &Path) -> PathBuf {
    std::env::var_os("CARGO_TARGET_DIR")
        .map(PathBuf::from)
        .map_or_else(|| root.join("target"), |d| root.join(d))
}

/// Where `cargo build --release` puts the firmware ELF for `board`:
/// `<target>/<triple>/release/vsa-firmware` ([`target_dir`]).
#[must_use]
pub fn elf_path(root: &Path, board: Board) -> PathBuf {
    target_dir(root)
        .join(board.target())
        .join("release")
        .join("vsa-firmware")
}

/// QEMU's executable.
pub const QEMU_BINARY: &str = "qemu-system-arm";

/// Where `cargo xtask` unpacks a private QEMU when the system's package cannot be
/// installed without removing another (docs/running.md): `<target>/qemu`.
#[must_use]
pub fn private_qemu_root(target_dir: &Path) -> PathBuf {
    target_dir.join("qemu")
}

/// The private QEMU's wrapper script, `<target>/qemu/bin/qemu-system-arm`.
#[must_use]
pub fn private_qemu(target_dir: &Path) -> PathBuf {
    private_qemu_root(target_dir).join("bin").join(QEMU_BINARY)
}

/// The QEMU to run: [`QEMU_BINARY`] if it is on `PATH`, else the workspace's private copy
/// ([`private_qemu`]) if there is one, else [`QEMU_BINARY`] (which then fails to start with
/// a message that says how to get it).
#[must_use]
pub fn default_qemu() -> PathBuf {
    let on_path = std::env::var_os("PATH")
        .is_some_and(|p| std::env::split_paths(&p).any(|d| d.join(QEMU_BINARY).is_file()));
    if !on_path {
        if let Some(private) = workspace_root()
            .map(|root| private_qemu(&target_dir(&root)))
            .filter(|p| p.is_file())
        {
            return private;
        }
    }
    PathBuf::from(QEMU_BINARY)
}

/// Builds the firmware for `board` in the workspace at `root` (`cargo build --release -p
/// vsa-firmware --bin vsa-firmware --target <triple> --no-default-features --features
/// <board>`: only the program that serves the protocol, not the benchmark images; cargo's
/// progress goes to this process's stderr) and returns the ELF's path.
///
/// # Errors
/// [`Error::Qemu`] if cargo cannot be run, fails, or leaves no ELF.
pub fn build_firmware(root: &Path, board: Board) -> Result<PathBuf> {
    let cargo = std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into());
    let status = Command::new(&cargo)
        .current_dir(root)
        .args([
            "build",
            "--release",
            "-p",
            "vsa-firmware",
            "--bin",
            "vsa-firmware",
        ])
        .arg("--target")
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

/// The command line of an emulated board: the one definition for `vsa --qemu`, `vsa
/// serve-qemu`, `cargo xtask e2e` and the xtask's scenario runs.
#[derive(Clone, Debug)]
pub struct QemuCommand {
    /// The QEMU binary.
    pub qemu: PathBuf,
    /// The QEMU machine ([`Board::machine`]).
    pub machine: String,
    /// The firmware ELF.
    pub elf: PathBuf,
    /// The firmware's command line (semihosting), its name first; no commas, none empty.
    pub argv: Vec<String>,
    /// The `-serial` devices, in order (USART1, USART2, …).
    pub serials: Vec<String>,
    /// The `-icount` value.
    pub icount: String,
}

impl QemuCommand {
    /// The `-semihosting-config` value.
    ///
    /// # Errors
    /// [`Error::Qemu`] for an argument that is empty or contains ','.
    pub fn semihosting(&self) -> Result<String> {
        let mut s = String::from("enable=on,target=native");
        for a in &self.argv {
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

    /// The process to spawn: stdin closed, stdout (the defmt log, see [`MessageFilter`])
    /// and stderr piped, and SIGKILL to QEMU when the thread that spawns it (the caller's)
    /// ends.
    ///
    /// # Errors
    /// As [`QemuCommand::semihosting`].
    pub fn command(&self) -> Result<Command> {
        let mut cmd = Command::new(&self.qemu);
        cmd.args(["-machine", &self.machine])
            .args(["-display", "none", "-monitor", "none"]);
        for s in &self.serials {
            cmd.arg("-serial").arg(s);
        }
        cmd.arg("-semihosting-config")
            .arg(self.semihosting()?)
            .arg("-icount")
            .arg(&self.icount)
            .arg("-kernel")
            .arg(&self.elf)
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped());
        die_with_parent(&mut cmd);
        Ok(cmd)
    }
}

/// Makes the child get SIGKILL when its parent dies (Linux `PR_SET_PDEATHSIG`), and exit
/// at once if the parent is already gone. Its own process group: a Ctrl-C at the terminal
/// reaches only the parent, which kills it in order (and reports no lost connection).
#[cfg(target_os = "linux")]
#[allow(unsafe_code)]
fn die_with_parent(cmd: &mut Command) {
    use std::os::unix::process::CommandExt;
    cmd.process_group(0);
    let parent = std::process::id();
    // SAFETY: between fork and exec only async-signal-safe calls are made (prctl,
    // getppid, _exit), with no allocation and no lock.
    unsafe {
        cmd.pre_exec(move || {
            if libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGKILL, 0, 0, 0) != 0 {
                return Err(std::io::Error::last_os_error());
            }
            if u32::try_from(libc::getppid()).ok() != Some(parent) {
                libc::_exit(1);
            }
            Ok(())
        });
    }
}

#[cfg(not(target_os = "linux"))]
fn die_with_parent(_cmd: &mut Command) {}

/// A listener on a free port of 127.0.0.1 for QEMU to connect to.
///
/// # Errors
/// [`Error::Qemu`] if binding fails.
pub fn listen() -> Result<(TcpListener, u16)> {
    let err = |e: std::io::Error| Error::Qemu(format!("binding 127.0.0.1:0: {e}"));
    let l = TcpListener::bind("127.0.0.1:0").map_err(err)?;
    let port = l.local_addr().map_err(err)?.port();
    l.set_nonblocking(true).map_err(err)?;
    Ok((l, port))
}

/// Accepts QEMU's connection to `listener` (what: for messages), giving up when `child`
/// exits (with its status and `stderr()`) or after `timeout`.
///
/// # Errors
/// [`Error::Qemu`].
pub fn accept_from(
    listener: &TcpListener,
    what: &str,
    child: &mut Child,
    stderr: impl Fn() -> String,
    timeout: Duration,
) -> Result<TcpStream> {
    let start = Instant::now();
    loop {
        match listener.accept() {
            Ok((s, _)) => {
                s.set_nonblocking(false)
                    .map_err(|e| Error::Qemu(format!("{what}: {e}")))?;
                return Ok(s);
            }
            Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {
                if let Ok(Some(status)) = child.try_wait() {
                    let text = stderr();
                    return Err(Error::Qemu(format!(
                        "QEMU exited ({status}) before connecting {what}{}",
                        if text.is_empty() {
                            String::new()
                        } else {
                            format!(": {text}")
                        }
                    )));
                }
                if start.elapsed() > timeout {
                    return Err(Error::Qemu(format!(
                        "QEMU did not connect {what} within {} s",
                        timeout.as_secs()
                    )));
                }
                std::thread::sleep(Duration::from_millis(5));
            }
            Err(e) => return Err(Error::Qemu(format!("accepting QEMU's {what}: {e}"))),
        }
    }
}

/// What QEMU itself writes on its stdout, in the middle of the firmware's log: each such
/// line starts with one of these and ends with a newline.
pub const QEMU_MESSAGES: [&[u8]; 1] = [b"Warning: The guest is now late by "];

/// Longest QEMU message line kept apart, bytes (the warning is 53).
const MESSAGE_MAX: usize = 120;

/// Splits QEMU's stdout into the firmware's log bytes and QEMU's own message lines
/// ([`QEMU_MESSAGES`]), across any chunking of the stream.
#[derive(Clone, Debug, Default)]
pub struct MessageFilter {
    /// Bytes that may be the start of a message (a prefix of one).
    pending: Vec<u8>,
    /// Inside a message (its prefix matched) until the newline.
    in_message: bool,
}

impl MessageFilter {
    /// A filter at the start of a stream.
    #[must_use]
    pub fn new() -> MessageFilter {
        MessageFilter::default()
    }

    /// Feeds `bytes`: the log bytes go to `log`, whole message lines to `messages`.
    pub fn feed(&mut self, bytes: &[u8], log: &mut Vec<u8>, messages: &mut Vec<u8>) {
        for &b in bytes {
            self.pending.push(b);
            if self.in_message {
                if b == b'\n' || self.pending.len() >= MESSAGE_MAX {
                    messages.append(&mut self.pending);
                    self.in_message = false;
                }
                continue;
            }
            loop {
                let p = self.pending.as_slice();
                if p.is_empty() {
                    break;
                }
                if QEMU_MESSAGES.iter().any(|m| m.len() == p.len() && *m == p) {
                    self.in_message = true;
                    break;
                }
                if QEMU_MESSAGES.iter().any(|m| m.starts_with(p)) {
                    break;
                }
                // Not a message here: the first byte is log, the rest may start one.
                log.push(self.pending.remove(0));
            }
        }
    }

    /// The end of the stream: what was held back as a possible message start is log.
    pub fn finish(&mut self, log: &mut Vec<u8>, messages: &mut Vec<u8>) {
        if self.in_message {
            messages.append(&mut self.pending);
        } else {
            log.append(&mut self.pending);
        }
        self.in_message = false;
    }
}

/// Where the firmware's defmt log bytes go.
pub enum LogSink {
    /// Dropped.
    Discard,
    /// Written, and flushed after every chunk (a log file follows the run).
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
                // Flushed as it comes: the file follows the run.
                if w.write_all(bytes).and_then(|()| w.flush()).is_err() {
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

pub use store::FLASH_FILE_PATH_MAX as FLASH_PATH_MAX;

/// `path` as the firmware's `--flash` argument: the semihosting command line is split at
/// spaces and QEMU's option at commas, so neither may appear; at most [`FLASH_PATH_MAX`]
/// bytes.
///
/// # Errors
/// Why the path cannot be passed, as a phrase for the user.
pub fn flash_file_arg(path: &Path) -> std::result::Result<String, String> {
    let s = path
        .to_str()
        .ok_or_else(|| format!("'{}' is not UTF-8", path.display()))?;
    if s.is_empty() || s.contains([',', ' ', '\t', '\n']) {
        return Err(format!(
            "'{s}': the emulated board takes a path without spaces or commas"
        ));
    }
    if s.len() > FLASH_PATH_MAX {
        return Err(format!(
            "'{s}' is longer than the emulated board's {FLASH_PATH_MAX} bytes"
        ));
    }
    Ok(s.to_owned())
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
            qemu: default_qemu(),
            icount_shift: ICOUNT_SHIFT,
            align: true,
            serial_index: 1,
            connect_timeout: CONNECT_TIMEOUT,
            ready_timeout: READY_TIMEOUT,
        }
    }

    /// The command line, with the command UART on TCP port `serial_port` of 127.0.0.1.
    #[must_use]
    pub fn qemu_command(&self, serial_port: u16) -> QemuCommand {
        let mut argv = vec!["vsa-firmware".to_owned(), "--serve".to_owned()];
        argv.extend(self.firmware_args.iter().cloned());
        let mut serials = vec!["null".to_owned(); self.serial_index];
        // nodelay: a status written byte by byte must not wait for an ACK (Nagle).
        serials.push(format!("tcp:127.0.0.1:{serial_port},nodelay=on"));
        QemuCommand {
            qemu: self.qemu.clone(),
            machine: self.board.machine().to_owned(),
            elf: self.elf.clone(),
            argv,
            serials,
            icount: format!(
                "shift={},sleep=on{}",
                self.icount_shift,
                if self.align { ",align=on" } else { "" }
            ),
        }
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
        let err = |what: &str, e: std::io::Error| Error::Qemu(format!("{what}: {e}"));
        let (serial_listener, serial_port) = listen()?;
        let mut child = opts
            .qemu_command(serial_port)
            .command()?
            .spawn()
            .map_err(|e| {
                let mut m = format!("starting {}: {e}", opts.qemu.display());
                if e.kind() == std::io::ErrorKind::NotFound {
                    m.push_str(
                        " (QEMU is not installed: `cargo xtask run` installs it, or a private \
                         copy under target/qemu when the system package cannot be installed)",
                    );
                }
                Error::Qemu(m)
            })?;

        // QEMU's own messages (stderr, and the lines taken out of stdout), kept for error
        // messages.
        let stderr = Arc::new(Mutex::new(Vec::new()));
        let keep = {
            let stderr = Arc::clone(&stderr);
            move |b: &[u8]| {
                if let Ok(mut k) = stderr.lock() {
                    if k.len() < STDERR_KEEP {
                        k.extend_from_slice(b);
                    }
                }
            }
        };
        let log_thread = child.stdout.take().map(|mut out| {
            let keep = keep.clone();
            std::thread::spawn(move || {
                let mut filter = MessageFilter::new();
                let (mut bytes, mut messages) = (Vec::new(), Vec::new());
                let mut buf = [0u8; 4096];
                loop {
                    let n = out.read(&mut buf).unwrap_or(0);
                    match buf.get(..n) {
                        Some(b) if n > 0 => filter.feed(b, &mut bytes, &mut messages),
                        _ => filter.finish(&mut bytes, &mut messages),
                    }
                    if !bytes.is_empty() {
                        log.take(&bytes);
                        bytes.clear();
                    }
                    keep(&messages);
                    messages.clear();
                    if n == 0 {
                        break;
                    }
                }
                log.finish();
            })
        });
        let stderr_thread = child.stderr.take().map(|mut pipe| {
            std::thread::spawn(move || {
                let mut buf = [0u8; 1024];
                while let Ok(n) = pipe.read(&mut buf) {
                    let Some(b) = buf.get(..n).filter(|_| n > 0) else {
                        break;
                    };
                    keep(b);
                }
            })
        });
        let text = {
            let stderr = Arc::clone(&stderr);
            move || {
                stderr
                    .lock()
                    .map(|b| String::from_utf8_lossy(&b).trim().to_string())
                    .unwrap_or_default()
            }
        };
        let mut qemu = QemuBoard {
            child,
            board: opts.board,
            log_thread,
            stderr_thread,
            stderr,
        };
        let stream = accept_from(
            &serial_listener,
            "to the serial port",
            &mut qemu.child,
            text,
            opts.connect_timeout,
        )?;
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

    /// QEMU's own messages so far (stderr and the lines taken out of stdout; at most
    /// 16 KiB), trimmed.
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
        let c = o.qemu_command(4000);
        assert_eq!(
            c.semihosting().unwrap(),
            "enable=on,target=native,arg=vsa-firmware,arg=--serve"
        );
        assert_eq!(c.serials, ["null", "tcp:127.0.0.1:4000,nodelay=on"]);
        let line: Vec<String> = c
            .command()
            .unwrap()
            .get_args()
            .map(|a| a.to_string_lossy().into_owned())
            .collect();
        assert_eq!(
            line.join(" "),
            "-machine netduinoplus2 -display none -monitor none -serial null -serial \
             tcp:127.0.0.1:4000,nodelay=on -semihosting-config enable=on,target=native,arg=vsa-firmware,\
             arg=--serve -icount shift=3,sleep=on,align=on -kernel x"
        );
        o.firmware_args = vec!["--seconds".into(), "3".into()];
        assert!(o
            .qemu_command(1)
            .semihosting()
            .unwrap()
            .ends_with(",arg=--seconds,arg=3"));
        o.firmware_args = vec!["a,b".into()];
        assert!(o.qemu_command(1).semihosting().is_err());
    }

    /// QEMU's warning inserted between two bytes of a defmt frame (as `strace` shows it:
    /// the log comes one byte per `write`, the warning as one 53-byte `write`), fed in every
    /// chunking: the log comes out exactly as the firmware wrote it.
    #[test]
    fn qemu_messages_are_taken_out_of_the_log_exactly() {
        let log: Vec<u8> = b"\x00\r\x01z\x05w0.1.03@qemu-WWarn\x00\xff"
            .iter()
            .copied()
            .chain((0..=255u8).rev())
            .collect();
        let warning = b"Warning: The guest is now late by 1.0 to 2.0 seconds\n";
        assert_eq!(warning.len(), 53);
        for at in [0, 1, 7, 19, 20, log.len()] {
            let mut stream = log[..at].to_vec();
            stream.extend_from_slice(warning);
            stream.extend_from_slice(&log[at..]);
            stream.extend_from_slice(warning);
            for chunk in [1, 2, 5, 53, 4096] {
                let mut f = MessageFilter::new();
                let (mut out, mut msgs) = (Vec::new(), Vec::new());
                for c in stream.chunks(chunk) {
                    f.feed(c, &mut out, &mut msgs);
                }
                f.finish(&mut out, &mut msgs);
                assert_eq!(out, log, "at {at}, chunks of {chunk}");
                assert_eq!(msgs, [&warning[..], &warning[..]].concat());
            }
        }
        // A stream that ends inside a possible start keeps its bytes.
        let mut f = MessageFilter::new();
        let (mut out, mut msgs) = (Vec::new(), Vec::new());
        f.feed(b"abcWarning: The", &mut out, &mut msgs);
        f.finish(&mut out, &mut msgs);
        assert_eq!(out, b"abcWarning: The");
        assert!(msgs.is_empty());
    }

    #[test]
    fn missing_elf_is_a_clear_error() {
        let o = QemuOptions::new(Board::QemuM4, "/nonexistent/vsa-firmware");
        let e = QemuBoard::spawn(&o, LogSink::Discard).unwrap_err();
        assert!(e.to_string().contains("does not exist"), "{e}");
    }

    #[test]
    fn missing_qemu_says_how_to_get_it() {
        let mut o = QemuOptions::new(
            Board::QemuM4,
            concat!(env!("CARGO_MANIFEST_DIR"), "/Cargo.toml"),
        );
        o.qemu = PathBuf::from("/nonexistent/qemu-system-arm");
        let e = QemuBoard::spawn(&o, LogSink::Discard).unwrap_err();
        assert!(
            e.to_string().contains("`cargo xtask run` installs it"),
            "{e}"
        );
    }
}
