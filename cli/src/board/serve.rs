//! `vsa serve-qemu`: keeps one emulated board running and relays a TCP port to its command
//! UART, so that later `vsa --tcp HOST:PORT …` invocations talk to the same board.
//!
//! One client at a time (others wait in the listen backlog). A 0x00 goes to the board when
//! a client connects, to flush any partial frame an earlier client left; what the board
//! sends while no client is connected (e.g. telemetry still streaming) is dropped.
//!
//! Towards the board the relay behaves like a serial line: it passes at most
//! [`LINE_RATE`] bytes per second (with a burst of [`LINE_BURST`]) and drops the bytes
//! beyond, counting them (reported when the client disconnects). Without that, a client
//! that sends faster than the emulated USART takes fills the socket buffers between here
//! and QEMU with minutes of backlog, during which the board answers nothing.

use std::io::{Read, Write};
use std::net::{TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::{Duration, Instant};

use clap::Args;
use client::qemu::{QemuBoard, QemuOptions, READY_PING_INTERVAL, READY_TIMEOUT};
use client::Client;

use super::ConnectArgs;
use crate::error::{CliError, CliResult};

/// Bytes per second the relay passes to the board: below what the emulated USART took on
/// the most loaded machine measured (1 158 B/s, `cargo xtask e2e` at a load of 13 on 2
/// cores; 8–11 kB/s on a quiet one, see docs/protocol.md, "The heartbeat rule"), so that the board
/// keeps up with the line and nothing queues in front of it. Twice what a `vsa script`
/// sends (a 9–11-byte heartbeat every 20 ms, one request at a time).
pub const LINE_RATE: f64 = 1_000.0;

/// Bytes the relay passes at once after a quiet spell: less than the firmware's receive
/// queue (255 bytes), so a burst never overflows it.
pub const LINE_BURST: f64 = 192.0;

/// A token bucket at [`LINE_RATE`] holding at most [`LINE_BURST`] bytes.
#[derive(Debug)]
pub struct Line {
    tokens: f64,
    last: Instant,
    /// Bytes dropped because they came faster than the line takes them.
    pub dropped: u64,
}

impl Line {
    /// A full bucket.
    #[must_use]
    pub fn new(now: Instant) -> Line {
        Line {
            tokens: LINE_BURST,
            last: now,
            dropped: 0,
        }
    }

    /// How many of `n` bytes arriving at `now` the line takes (the first ones); the rest
    /// are dropped and counted.
    pub fn admit(&mut self, n: usize, now: Instant) -> usize {
        let dt = now.saturating_duration_since(self.last).as_secs_f64();
        self.last = now;
        self.tokens = (self.tokens + dt * LINE_RATE).min(LINE_BURST);
        let take = (self.tokens.floor() as usize).min(n);
        self.tokens -= take as f64;
        self.dropped += (n - take) as u64;
        take
    }
}

/// Arguments of `vsa serve-qemu`.
#[derive(Args, Debug)]
pub struct ServeArgs {
    /// Address to accept `--tcp` clients on (port 0: any free port, printed)
    #[arg(long, value_name = "HOST:PORT", default_value = "127.0.0.1:0")]
    pub listen: String,
    /// Serve a Dynamixel bus instead: one emulated actuator per --ids on one simulated
    /// half-duplex bus, a pseudo-terminal linked at PATH (see `board::bus`)
    #[arg(long, value_name = "PATH")]
    pub bus: Option<std::path::PathBuf>,
    /// Dynamixel IDs of the actuators on --bus, comma separated
    #[arg(long, value_name = "ID,ID,…", default_value = "1", requires = "bus")]
    pub ids: String,
}

fn io_err(what: &str) -> impl Fn(std::io::Error) -> CliError + '_ {
    move |e| CliError::runtime(format!("{what}: {e}"))
}

/// Runs `vsa serve-qemu` until QEMU exits or the process is stopped (Ctrl-C).
pub fn run(a: &ServeArgs, conn: &ConnectArgs) -> CliResult<()> {
    for (given, name) in [
        (conn.port.is_some(), "--port"),
        (conn.baud.is_some(), "--baud"),
        (conn.tcp.is_some(), "--tcp"),
    ] {
        if given {
            return Err(CliError::usage(
                name,
                "serve-qemu always starts an emulated board (use --board, --elf, --qemu-log)",
            ));
        }
    }
    if let Some(path) = &a.bus {
        return super::bus::run(path, &super::bus::parse_ids(&a.ids)?, conn);
    }
    let listener = TcpListener::bind(&a.listen)
        .map_err(|e| CliError::usage("--listen", format!("{}: {e}", a.listen)))?;
    let addr = listener.local_addr().map_err(io_err("--listen"))?;
    let target = conn.qemu_target()?;
    let elf = target.elf()?;
    let sink = target.sink()?;
    let mut opts = QemuOptions::new(target.board, elf);
    opts.firmware_args = target.firmware_args();
    let (qemu, transport) =
        QemuBoard::spawn(&opts, sink).map_err(|e| CliError::runtime(e.to_string()))?;
    let qemu = super::adopt(qemu);
    let to_qemu = transport
        .stream()
        .try_clone()
        .map_err(io_err("QEMU socket"))?;
    let mut probe = Client::new(transport);
    if let Err(e) = probe.wait_ready(READY_TIMEOUT, READY_PING_INTERVAL) {
        return Err(CliError::runtime(format!(
            "the {} firmware did not answer: {e}{}",
            target.board,
            qemu.exit_report()
        )));
    }
    drop(probe);
    to_qemu
        .set_read_timeout(None)
        .map_err(io_err("QEMU socket"))?;
    let from_qemu = to_qemu.try_clone().map_err(io_err("QEMU socket"))?;
    super::out(&format!(
        "serving {} (QEMU pid {}) on {addr}: run `vsa --tcp {addr} COMMAND`; Ctrl-C stops\n",
        target.board,
        qemu.pid()
    ));

    let current: Arc<Mutex<Option<TcpStream>>> = Arc::new(Mutex::new(None));
    let dead = Arc::new(AtomicBool::new(false));
    {
        let (current, dead) = (Arc::clone(&current), Arc::clone(&dead));
        std::thread::spawn(move || board_to_client(from_qemu, &current, &dead));
    }
    relay(&listener, to_qemu, &current, &dead)?;
    Err(CliError::runtime(format!(
        "QEMU closed the connection{}",
        qemu.exit_report()
    )))
}

/// Copies the board's bytes to the current client, or drops them.
fn board_to_client(mut from: TcpStream, current: &Mutex<Option<TcpStream>>, dead: &AtomicBool) {
    let mut buf = [0u8; 4096];
    loop {
        let n = match from.read(&mut buf) {
            Ok(0) | Err(_) => break,
            Ok(n) => n,
        };
        let mut cur = current.lock().unwrap_or_else(PoisonError::into_inner);
        if let (Some(c), Some(bytes)) = (cur.as_mut(), buf.get(..n)) {
            if c.write_all(bytes).is_err() {
                *cur = None;
            }
        }
    }
    dead.store(true, Ordering::Relaxed);
}

/// Accepts clients one at a time and copies their bytes to the board; returns when the
/// board's connection is gone.
fn relay(
    listener: &TcpListener,
    mut to: TcpStream,
    current: &Mutex<Option<TcpStream>>,
    dead: &AtomicBool,
) -> CliResult<()> {
    listener.set_nonblocking(true).map_err(io_err("listener"))?;
    let mut buf = [0u8; 4096];
    while !dead.load(Ordering::Relaxed) {
        let (mut client, peer) = match listener.accept() {
            Ok(c) => c,
            Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {
                std::thread::sleep(Duration::from_millis(20));
                continue;
            }
            Err(e) => return Err(io_err("accepting a client")(e)),
        };
        let setup = client
            .set_nonblocking(false)
            .and_then(|()| client.set_nodelay(true))
            .and_then(|()| client.set_read_timeout(Some(Duration::from_millis(100))))
            .and_then(|()| client.try_clone());
        let Ok(writer) = setup else { continue };
        eprintln!("client {peer} connected");
        *current.lock().unwrap_or_else(PoisonError::into_inner) = Some(writer);
        if to.write_all(&[0]).is_err() {
            return Ok(());
        }
        let mut line = Line::new(Instant::now());
        loop {
            match client.read(&mut buf) {
                Ok(0) => break,
                Ok(n) => {
                    let take = line.admit(n, Instant::now());
                    if to.write_all(buf.get(..take).unwrap_or_default()).is_err() {
                        return Ok(());
                    }
                }
                Err(e)
                    if matches!(
                        e.kind(),
                        std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                    ) =>
                {
                    if dead.load(Ordering::Relaxed) {
                        return Ok(());
                    }
                }
                Err(_) => break,
            }
        }
        *current.lock().unwrap_or_else(PoisonError::into_inner) = None;
        if line.dropped > 0 {
            eprintln!(
                "client {peer} disconnected; {} bytes beyond the line rate ({LINE_RATE} B/s) \
                 dropped",
                line.dropped
            );
        } else {
            eprintln!("client {peer} disconnected");
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_line_passes_its_rate_and_drops_the_rest() {
        let t0 = Instant::now();
        let mut line = Line::new(t0);
        // A 5 s flood of 100 kB/s, in 1 kB reads every 10 ms.
        let mut passed = 0;
        for i in 1..=500 {
            passed += line.admit(1_000, t0 + Duration::from_millis(10 * i));
        }
        // The burst, then the rate for the 4.99 s after the first read.
        let expected = LINE_BURST + 4.99 * LINE_RATE;
        assert!(
            (passed as f64 - expected).abs() <= 1.0,
            "{passed} vs {expected}"
        );
        assert_eq!(line.dropped, 500_000 - passed as u64);
        // After a quiet second a frame passes whole.
        assert_eq!(line.admit(57, t0 + Duration::from_secs(6)), 57);
    }
}
