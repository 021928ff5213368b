//! `vsa serve-qemu --bus PATH --ids 1,2,3`: one emulated actuator per ID on one simulated
//! half-duplex Dynamixel bus, exposed as a pseudo-terminal at PATH (a symbolic link to
//! `/dev/pts/N`), so that any Dynamixel client opens it like a USB2Dynamixel adapter.
//!
//! The bus is a wire for Dynamixel traffic: what the client writes reaches every board,
//! and a Dynamixel packet a board sends reaches the client and every other board (a SYNC
//! READ status follows the status of the ID listed before it, as on a real bus), never the
//! board that sent it. Each board runs with `--dxl-id ID`. The boards keep our own
//! protocol on the same line, but it has no addresses: its frames from a board go to the
//! client only, because a board that heard another's reply would take it for a request
//! (an `Ok` reply and a `Ping` request are the same bytes) and answer it, and the two
//! would answer each other forever. Use our protocol with one ID on the bus.
//!
//! With `--qemu-flash PATH` each board keeps its settings store in its own file, PATH with
//! the extension `.idN.flash` for the factory ID N given in `--ids`: the bus settings
//! written on the bus (ID, baud, protocol, …) come back when the same command starts the
//! boards again.

use std::io::{Read, Write};
use std::net::TcpStream;
use std::os::fd::AsFd;
use std::path::Path;

use client::qemu::{LogSink, QemuBoard, QemuOptions, READY_PING_INTERVAL, READY_TIMEOUT};
use client::Client;
use nix::fcntl::OFlag;
use nix::poll::{poll, PollFd, PollFlags, PollTimeout};
use nix::pty::{grantpt, posix_openpt, ptsname_r, unlockpt, PtyMaster};
use nix::sys::termios::{cfmakeraw, tcgetattr, tcsetattr, SetArg};

use super::{Adopted, ConnectArgs};
use crate::error::{CliError, CliResult};

/// Parses `--ids`: Dynamixel IDs 0–252, comma separated, no repeats.
///
/// # Errors
/// A usage error naming `--ids`.
pub fn parse_ids(text: &str) -> CliResult<Vec<u8>> {
    let mut ids = Vec::new();
    for part in text.split(',') {
        let id = part
            .trim()
            .parse::<u8>()
            .ok()
            .filter(|&i| i <= 252)
            .ok_or_else(|| {
                CliError::usage("--ids", format!("{part:?} is not a Dynamixel ID (0–252)"))
            })?;
        if ids.contains(&id) {
            return Err(CliError::usage("--ids", format!("ID {id} given twice")));
        }
        ids.push(id);
    }
    Ok(ids)
}

/// The pseudo-terminal: its master, the slave held open (so that the master never reads
/// end-of-file between the client's opens), and the slave's path.
fn open_pty(link: &Path) -> CliResult<(PtyMaster, std::fs::File, String)> {
    let fail = |e: nix::Error| CliError::runtime(format!("cannot make the pseudo-terminal: {e}"));
    let master = posix_openpt(OFlag::O_RDWR | OFlag::O_NOCTTY).map_err(fail)?;
    grantpt(&master).map_err(fail)?;
    unlockpt(&master).map_err(fail)?;
    let path = ptsname_r(&master).map_err(fail)?;
    let slave = std::fs::OpenOptions::new()
        .read(true)
        .write(true)
        .open(&path)
        .map_err(|e| CliError::runtime(format!("{path}: {e}")))?;
    let mut t = tcgetattr(&slave).map_err(fail)?;
    cfmakeraw(&mut t);
    tcsetattr(&slave, SetArg::TCSANOW, &t).map_err(fail)?;
    if link.symlink_metadata().is_ok() {
        std::fs::remove_file(link).map_err(|e| {
            CliError::usage("--bus", format!("{}: cannot replace: {e}", link.display()))
        })?;
    }
    std::os::unix::fs::symlink(&path, link)
        .map_err(|e| CliError::usage("--bus", format!("{}: {e}", link.display())))?;
    Ok((master, slave, path))
}

/// Starts the boards, one per ID, and waits until each answers.
fn start_boards(ids: &[u8], conn: &ConnectArgs) -> CliResult<Vec<(Adopted, TcpStream)>> {
    let target = conn.qemu_target()?;
    let elf = target.elf()?;
    let mut boards = Vec::new();
    for &id in ids {
        let mut opts = QemuOptions::new(target.board, &elf);
        opts.firmware_args = vec!["--dxl-id".to_owned(), id.to_string()];
        opts.firmware_args.extend(target.actuator_args());
        // One flash per board, named for its factory ID: the same command line after a
        // power cycle gives each board its stored settings back.
        if let Some(f) = &conn.qemu_flash {
            let path = f.with_extension(format!("id{id}.flash"));
            let arg = client::qemu::flash_file_arg(&path)
                .map_err(|e| CliError::usage("--qemu-flash", e))?;
            opts.firmware_args.extend(["--flash".to_owned(), arg]);
        }
        let sink = match &target.log {
            None => LogSink::Discard,
            Some(p) => {
                let path = p.with_extension(format!("id{id}.log"));
                std::fs::File::create(&path)
                    .map(|f| LogSink::Writer(Box::new(std::io::BufWriter::new(f))))
                    .map_err(|e| {
                        CliError::usage("--qemu-log", format!("{}: {e}", path.display()))
                    })?
            }
        };
        let (qemu, transport) =
            QemuBoard::spawn(&opts, sink).map_err(|e| CliError::runtime(e.to_string()))?;
        let qemu = super::adopt(qemu);
        let stream = transport
            .stream()
            .try_clone()
            .map_err(|e| CliError::runtime(format!("QEMU socket: {e}")))?;
        let mut probe = Client::new(transport);
        if let Err(e) = probe.wait_ready(READY_TIMEOUT, READY_PING_INTERVAL) {
            return Err(CliError::runtime(format!(
                "the {} firmware with ID {id} did not answer: {e}{}",
                target.board,
                qemu.exit_report()
            )));
        }
        drop(probe);
        stream
            .set_read_timeout(None)
            .and_then(|()| stream.set_nodelay(true))
            .map_err(|e| CliError::runtime(format!("QEMU socket: {e}")))?;
        boards.push((qemu, stream));
    }
    Ok(boards)
}

/// Picks the Dynamixel packets out of what one board sends (both protocols: `FF FF ID LEN`
/// and `FF FF FD 00 ID LEN_L LEN_H`); everything else is our protocol's.
///
/// A packet is passed on only whole. The boards hear each other through their emulated
/// USARTs, a byte every millisecond or slower, so two of them can start talking before
/// either hears the other (a broadcast ping's slots are 3 ms apart); on a wire that is a
/// collision they would see at once, here the relay would interleave the two packets'
/// bytes and both arrive corrupt (at the client and at the other boards). Passing whole
/// packets makes the relay the wire's arbiter: the second packet follows the first.
#[derive(Debug, Default)]
struct Outbound {
    held: Vec<u8>,
}

/// What one board sent, sorted by [`Outbound::split`].
#[derive(Debug, Default, PartialEq, Eq)]
struct Split {
    /// For the client, in order: our protocol's bytes and whole Dynamixel packets.
    client: Vec<u8>,
    /// For the other boards: the whole Dynamixel packets only.
    packets: Vec<u8>,
}

impl Outbound {
    /// Sorts `bytes` (after those held from before): a packet's bytes are held until it is
    /// whole.
    fn split(&mut self, bytes: &[u8]) -> Split {
        let mut out = Split::default();
        for &b in bytes {
            self.held.push(b);
            loop {
                let h = &self.held;
                let total = match h.as_slice() {
                    [] => break,
                    [0xFF] | [0xFF, 0xFF] | [0xFF, 0xFF, 0xFD, ..] if h.len() < 7 => break,
                    [0xFF, 0xFF, 0xFD, _, _, lo, hi, ..] => {
                        7 + usize::from(*lo) + 256 * usize::from(*hi)
                    }
                    [0xFF, 0xFF, _] => break,
                    [0xFF, 0xFF, _, len, ..] => 4 + usize::from(*len),
                    _ => {
                        // Not a packet start: our protocol's byte.
                        out.client.push(self.held.remove(0));
                        continue;
                    }
                };
                if h.len() >= total {
                    let packet: Vec<u8> = self.held.drain(..total).collect();
                    out.client.extend_from_slice(&packet);
                    out.packets.extend(packet);
                } else {
                    break;
                }
            }
        }
        out
    }
}

/// Runs the bus until a board stops or the process is stopped (Ctrl-C).
pub fn run(link: &Path, ids: &[u8], conn: &ConnectArgs) -> CliResult<()> {
    if ids.is_empty() {
        return Err(CliError::usage("--ids", "no ID given"));
    }
    let mut boards = start_boards(ids, conn)?;
    let (mut master, _slave, pts) = open_pty(link)?;
    super::out(&format!(
        "bus ready: {} -> {pts}, IDs {}; Ctrl-C stops\n",
        link.display(),
        ids.iter().map(u8::to_string).collect::<Vec<_>>().join(",")
    ));
    let mut buf = [0u8; 4096];
    let mut outbound: Vec<Outbound> = boards.iter().map(|_| Outbound::default()).collect();
    let result = loop {
        let readable: Vec<bool> = {
            let mut fds = vec![PollFd::new(master.as_fd(), PollFlags::POLLIN)];
            fds.extend(
                boards
                    .iter()
                    .map(|(_, s)| PollFd::new(s.as_fd(), PollFlags::POLLIN)),
            );
            if let Err(e) = poll(&mut fds, PollTimeout::from(200u8)) {
                if e == nix::Error::EINTR {
                    continue;
                }
                break Err(CliError::runtime(format!("poll: {e}")));
            }
            fds.iter()
                .map(|f| f.revents().is_some_and(|r| !r.is_empty()))
                .collect()
        };
        if readable[0] {
            match master.read(&mut buf) {
                Ok(n) if n > 0 => {
                    for (_, s) in &mut boards {
                        let _ = s.write_all(&buf[..n]);
                    }
                }
                // No client has the terminal open right now (EIO) or nothing came.
                _ => std::thread::sleep(std::time::Duration::from_millis(1)),
            }
        }
        let mut stopped = None;
        for i in 0..boards.len() {
            if !readable[i + 1] {
                continue;
            }
            let n = match boards[i].1.read(&mut buf) {
                Ok(0) | Err(_) => {
                    stopped = Some(i);
                    break;
                }
                Ok(n) => n,
            };
            let split = outbound[i].split(&buf[..n]);
            if !split.client.is_empty() {
                let _ = master.write_all(&split.client);
            }
            for (j, (_, s)) in boards.iter_mut().enumerate() {
                if j != i && !split.packets.is_empty() {
                    let _ = s.write_all(&split.packets);
                }
            }
        }
        if let Some(i) = stopped {
            break Err(CliError::runtime(format!(
                "the board with ID {} closed the connection{}",
                ids[i],
                boards[i].0.exit_report()
            )));
        }
    };
    let _ = std::fs::remove_file(link);
    super::park_if_interrupted();
    result
}

#[cfg(test)]
mod tests {
    use super::{parse_ids, Outbound};

    #[test]
    fn only_dynamixel_packets_go_to_the_other_boards() {
        let mut o = Outbound::default();
        let v1 = [0xFF, 0xFF, 0x01, 0x02, 0x00, 0xFC];
        let v2 = [
            0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x04, 0x00, 0x55, 0x00, 0xA1, 0x0C,
        ];
        // One of our frames (no 0xFF start), then a 1.0 status split across two reads:
        // the frame goes to the client at once, the status only once whole.
        let first = o.split(&[0x03, 0x01, 0x02, 0x00, 0xFF, 0xFF, 0x01]);
        assert_eq!(first.client, [0x03, 0x01, 0x02, 0x00]);
        assert!(first.packets.is_empty());
        let second = o.split(&v1[3..]);
        assert_eq!(
            (second.client.as_slice(), second.packets.as_slice()),
            (&v1[..], &v1[..])
        );
        let mut both = v2.to_vec();
        both.extend_from_slice(&[0x02, 0x05, 0x00]);
        both.extend_from_slice(&v1);
        let mut expected = v2.to_vec();
        expected.extend_from_slice(&v1);
        let third = o.split(&both);
        assert_eq!(third.packets, expected);
        assert_eq!(third.client, both);
    }

    #[test]
    fn ids_are_checked() {
        assert_eq!(parse_ids("1,2, 3").unwrap(), [1, 2, 3]);
        assert!(parse_ids("1,1").is_err());
        assert!(parse_ids("253").is_err());
        assert!(parse_ids("").is_err());
    }
}
