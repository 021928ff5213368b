//! Emulated Dynamixel devices on one pseudo-terminal, like servos on a USB2Dynamixel.
//!
//! ```text
//! cargo run -p vsa-dynamixel --example pty_bus -- [--ids 1,2,3] [--link /tmp/vsa-dxl-bus]
//! ```
//!
//! Each ID is a [`Device`] over a [`MemoryBackend`] (an ideal servo: the present position
//! is the goal while torque is on), all starting in Protocol 1.0. Every byte the host
//! writes reaches every device; each reply is sent after its delay, and also reaches the
//! other devices (so a SYNC READ reply that follows another device's status is cued, as on
//! a real half-duplex line), never the device that sent it. The line counts as idle after
//! 1 ms without a byte. Prints `bus ready: PATH` once the link exists, then serves until
//! killed.

use dynamixel::{After, Device, MemoryBackend, Output, Protocol};
use nix::fcntl::OFlag;
use nix::poll::{poll, PollFd, PollFlags, PollTimeout};
use nix::pty::{grantpt, posix_openpt, ptsname_r, unlockpt, PtyMaster};
use nix::sys::termios::{cfmakeraw, tcgetattr, tcsetattr, SetArg};
use std::io::{Read, Write};
use std::os::fd::AsFd;
use std::process::ExitCode;
use std::time::{Duration, Instant};

/// No byte for this long: the line is idle.
const IDLE: Duration = Duration::from_millis(1);
/// A reply later than this is reported on stderr (the SDK gives up after about 34 ms).
const LATE: Duration = Duration::from_millis(5);

struct Args {
    ids: Vec<u8>,
    link: String,
}

fn parse_args() -> Result<Args, String> {
    let mut args = Args {
        ids: vec![1, 2, 3],
        link: "/tmp/vsa-dxl-bus".into(),
    };
    let mut it = std::env::args().skip(1);
    while let Some(a) = it.next() {
        let value = it.next().ok_or_else(|| format!("{a} needs a value"))?;
        match a.as_str() {
            "--ids" => {
                args.ids = value
                    .split(',')
                    .map(|s| s.trim().parse::<u8>().ok().filter(|&i| i <= 252))
                    .collect::<Option<Vec<_>>>()
                    .ok_or_else(|| format!("bad --ids {value:?}: IDs 0–252, comma separated"))?;
            }
            "--link" => args.link = value,
            _ => return Err(format!("unknown option {a}")),
        }
    }
    Ok(args)
}

struct Pending {
    due: Instant,
    from: usize,
    bytes: Vec<u8>,
}

fn open_pty(link: &str) -> nix::Result<(PtyMaster, std::fs::File, String)> {
    let master = posix_openpt(OFlag::O_RDWR | OFlag::O_NOCTTY)?;
    grantpt(&master)?;
    unlockpt(&master)?;
    let path = ptsname_r(&master)?;
    // Hold the slave open (raw) so the master never reads EOF between the host's opens.
    let slave = std::fs::OpenOptions::new()
        .read(true)
        .write(true)
        .open(&path)
        .map_err(|e| nix::Error::try_from(e).unwrap_or(nix::Error::EIO))?;
    let mut t = tcgetattr(&slave)?;
    cfmakeraw(&mut t);
    tcsetattr(&slave, SetArg::TCSANOW, &t)?;
    let _ = std::fs::remove_file(link);
    std::os::unix::fs::symlink(&path, link).map_err(|_| nix::Error::EIO)?;
    Ok((master, slave, path))
}

/// Queue a device's output; rebuild the device on REBOOT.
fn schedule(
    out: Output,
    from: usize,
    now: Instant,
    queue: &mut Vec<Pending>,
    reboot: &mut Vec<usize>,
) {
    if let Some(r) = out.reply {
        queue.push(Pending {
            due: now + Duration::from_micros(u64::from(r.delay_us)),
            from,
            bytes: r.bytes.to_vec(),
        });
    }
    if out.after == After::Reboot {
        reboot.push(from);
    }
}

/// One byte heard by device `i`, polled at once: a packet that switches the protocol must
/// be acted on before the next byte (which may already be in the other protocol).
fn hear(
    d: &mut Device<MemoryBackend>,
    byte: u8,
    i: usize,
    now: Instant,
    queue: &mut Vec<Pending>,
    reboot: &mut Vec<usize>,
) {
    d.push(byte);
    while let Some(out) = d.poll() {
        schedule(out, i, now, queue, reboot);
    }
}

fn main() -> ExitCode {
    let args = match parse_args() {
        Ok(a) => a,
        Err(e) => {
            eprintln!("pty_bus: {e}");
            return ExitCode::from(2);
        }
    };
    let (mut master, _slave, path) = match open_pty(&args.link) {
        Ok(p) => p,
        Err(e) => {
            eprintln!("pty_bus: cannot make the pseudo-terminal: {e}");
            return ExitCode::FAILURE;
        }
    };
    let mut devices: Vec<Device<MemoryBackend>> = args
        .ids
        .iter()
        .map(|&id| Device::new(MemoryBackend::new(id, Protocol::V1)))
        .collect();
    println!("bus ready: {} -> {path}, ids {:?}", args.link, args.ids);
    let _ = std::io::stdout().flush();

    let mut queue: Vec<Pending> = Vec::new();
    let mut reboot = Vec::new();
    let mut last_rx: Option<Instant> = None;
    let mut buf = [0u8; 4096];
    loop {
        let now = Instant::now();
        // Send what is due (in due order), and let the other devices hear it.
        queue.sort_by_key(|p| p.due);
        while queue.first().is_some_and(|p| p.due <= now) {
            let p = queue.remove(0);
            if master.write_all(&p.bytes).is_err() {
                eprintln!("pty_bus: write failed");
                return ExitCode::FAILURE;
            }
            let sent = Instant::now();
            let late = sent.saturating_duration_since(p.due);
            if late > LATE {
                eprintln!(
                    "pty_bus: a reply went out {:.1} ms late",
                    late.as_secs_f64() * 1e3
                );
            }
            for (i, d) in devices.iter_mut().enumerate().filter(|(i, _)| *i != p.from) {
                for &b in &p.bytes {
                    hear(d, b, i, sent, &mut queue, &mut reboot);
                }
            }
        }
        for i in reboot.drain(..) {
            let backend = devices[i].backend().clone();
            devices[i] = Device::new(backend);
        }
        // Wait for bytes, the idle line, or the next reply; short waits sleep precisely.
        let wait = queue
            .iter()
            .map(|p| p.due.saturating_duration_since(now))
            .chain(last_rx.map(|t| (t + IDLE).saturating_duration_since(now)))
            .min()
            .unwrap_or(Duration::from_millis(100));
        if wait < Duration::from_millis(1) && !queue.is_empty() {
            std::thread::sleep(wait);
            continue;
        }
        // Rounded up: a zero timeout would spin through the idle window.
        let ms = wait.as_micros().div_ceil(1000).clamp(1, 100);
        let timeout = PollTimeout::try_from(ms as i32).unwrap_or(PollTimeout::MAX);
        let mut fds = [PollFd::new(master.as_fd(), PollFlags::POLLIN)];
        if poll(&mut fds, timeout).is_err() {
            continue;
        }
        let readable = fds[0]
            .revents()
            .is_some_and(|r| r.contains(PollFlags::POLLIN));
        let now = Instant::now();
        if readable {
            let n = match master.read(&mut buf) {
                Ok(n) => n,
                Err(e) if e.raw_os_error() == Some(nix::libc::EIO) => 0,
                Err(e) => {
                    eprintln!("pty_bus: read failed: {e}");
                    return ExitCode::FAILURE;
                }
            };
            for (i, d) in devices.iter_mut().enumerate() {
                for &b in &buf[..n] {
                    hear(d, b, i, now, &mut queue, &mut reboot);
                }
            }
            last_rx = Some(now);
        } else if last_rx.is_some_and(|t| now >= t + IDLE) {
            for (i, d) in devices.iter_mut().enumerate() {
                d.idle();
                while let Some(out) = d.poll() {
                    schedule(out, i, now, &mut queue, &mut reboot);
                }
            }
            last_rx = None;
        }
    }
}
