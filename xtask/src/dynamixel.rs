//! The Dynamixel bus with ROBOTIS' own `dynamixel-sdk`: three emulated boards (IDs 1–3,
//! each with a 0.3 N·m load) on the bus of `vsa serve-qemu --bus`, checked by
//! `dynamixel/tests/sdk_check.py` in Protocol 1.0 (pings, every control-table default,
//! broadcast torque enable, one SYNC_WRITE and the present positions within the
//! controller's tolerance, the present load's direction under the load, the angle-limit,
//! range and checksum error bits, back-to-back READs) and Protocol 2.0 (the X-series
//! table, broadcast ping, SYNC WRITE, SYNC READ, the error numbers). The boards log to
//! `target/dxl-log-BOARD.idN.log`; a failed check prints what each logged after boot.
//!
//! The SDK comes from PyPI into the virtual environment `target/venv` (`venv`).
//!
//! `DXL_LATENCY_MS` (default 2500) is the SDK's latency allowance: a status times out after
//! twice that plus 2 ms. QEMU's emulated USART takes the host's bytes slowly on a loaded
//! machine (about 1 kB/s at a load of 13 on 2 cores, see `e2e`), and a loaded host stalls
//! the emulators now and then for seconds (7 of 1 000 READs past 2 s on qemu-m3 at a load
//! of 14–18): the SDK's 16 ms default does not survive that. The port is opened at
//! 9 600 Bd (the emulated bus ignores the rate) because the SDK sizes its broadcast-ping
//! window from the rate alone: 4.4 s instead of 0.8 s at 1 Mbd, which the three statuses
//! missed at that load. `DXL_READS` (default 1 000) sets the number of back-to-back 1.0
//! READs: about 40 ms each at a load of 6–9 (76 s for the whole qemu-m4 check), 240 ms at
//! 15, so on a loaded host `DXL_READS=200` keeps the check to about a minute per board.

use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::Instant;

use anyhow::{bail, ensure, Context, Result};

use crate::board::Board;
use crate::cmd::{cargo, run_status, target_dir, workspace_root};
use crate::venv;

/// The emulated load on each board, mN·m (positive pushes the link positive, so the
/// actuator holds it by pushing CW: the AX direction bit is set).
const LOAD_MNM: i32 = 300;
/// How far a present position may be from its goal, AX counts (0.29° each): the
/// controller settles within an encoder count of the target (`e2e`).
const TOLERANCE_COUNTS: u32 = 2;
/// The clutch length the served boards start at, µm (`firmware::board::SERVED_CLUTCH_MM`).
const CLUTCH_UM: u32 = 3_000;
/// The served actuators' bridge supply, 0.1 V: 11.5 V, below the configured 12 V, which
/// the boards measure and report in Present Voltage.
const SUPPLY_DV: u32 = 115;
/// Back-to-back reads at return delay 0 and SYNC READs (each: 1.0 and 2.0 at delay 0).
const SHORT_READS: u32 = 100;
/// Back-to-back 1.0 READs unless `DXL_READS` says otherwise.
const DEFAULT_READS: u32 = 1_000;
/// The rate the SDK opens the bus at (see the module docs: the broadcast-ping window).
const SDK_BAUD: u32 = 9_600;

/// Clippy on the Nucleo's Dynamixel TTL build (`dynamixel-ttl`: USART2 single-wire half
/// duplex at the bus's rate), which the boards' own builds do not compile.
pub fn clippy_ttl() -> Command {
    let mut clippy = cargo();
    clippy
        .args(["clippy", "--release", "--package", "vsa-firmware"])
        .args(["--target", Board::NucleoF446re.target()])
        .args(["--no-default-features", "--features", "dynamixel-ttl"])
        .args(["--", "-D", "warnings"]);
    clippy
}

/// Kills the bus (and with it its QEMUs: `vsa` kills its boards on SIGTERM).
struct Bus(Child);

impl Drop for Bus {
    fn drop(&mut self) {
        let _ = Command::new("kill").arg(self.0.id().to_string()).status();
        let _ = self.0.wait();
    }
}

/// `vsa serve-qemu --bus` on `board` with `elf` and `args`, its bus at `link`, once it
/// says it is ready.
fn start_bus(vsa: &Path, board: Board, elf: &Path, link: &Path, args: &[&str]) -> Result<Bus> {
    let mut child = Command::new(vsa)
        .args(["serve-qemu", "--board", board.feature(), "--elf"])
        .arg(elf)
        .arg("--bus")
        .arg(link)
        .args(args)
        .stdout(Stdio::piped())
        .spawn()
        .with_context(|| format!("starting {}", vsa.display()))?;
    let stdout = child.stdout.take().context("the bus's stdout")?;
    let bus = Bus(child);
    let mut ready = String::new();
    BufReader::new(stdout)
        .read_line(&mut ready)
        .context("reading the bus's first line")?;
    ensure!(
        ready.starts_with("bus ready"),
        "vsa serve-qemu --bus said {ready:?}"
    );
    println!("[{} dynamixel] {}", board.feature(), ready.trim());
    Ok(bus)
}

/// Prints what a check printed, prefixed with the board; the number of `ok` and `note`
/// lines.
fn relay(board: Board, out: &std::process::Output) -> (usize, usize) {
    let (mut passed, mut notes) = (0, 0);
    for line in String::from_utf8_lossy(&out.stdout).lines() {
        println!("[{} dynamixel] {line}", board.feature());
        passed += usize::from(line.starts_with("ok "));
        notes += usize::from(line.starts_with("note "));
    }
    let err = String::from_utf8_lossy(&out.stderr);
    if !err.trim().is_empty() {
        eprintln!("{err}");
    }
    (passed, notes)
}

/// Runs the checks on `board` with the firmware `elf` (the three-board bus, then the bus
/// settings across power cycles); returns the summary.
pub fn run(board: Board, elf: &Path) -> Result<String> {
    let python = venv::python_with("dynamixel_sdk, serial", &["dynamixel-sdk", "pyserial"])?;
    run_status(cargo().args(["build", "--quiet", "-p", "vsa-cli", "--bin", "vsa"]))
        .context("building vsa")?;
    let vsa = target_dir().join("debug").join("vsa");
    let bus = three_boards(&python, &vsa, board, elf)?;
    let stored = power_cycles(&python, &vsa, board, elf)?;
    Ok(format!("{bus}; {stored}"))
}

/// The three boards under load with `sdk_check.py`.
fn three_boards(python: &Path, vsa: &Path, board: Board, elf: &Path) -> Result<String> {
    let link = target_dir().join(format!("dxl-bus-{}", board.feature()));
    let log = target_dir().join(format!("dxl-log-{}", board.feature()));
    let load = format!("{}Nm", f64::from(LOAD_MNM) / 1000.0);
    let log_arg = log.to_string_lossy();
    let bus = start_bus(
        vsa,
        board,
        elf,
        &link,
        &[
            "--qemu-load",
            &load,
            "--qemu-plant",
            &format!("supply={}V", f64::from(SUPPLY_DV) / 10.0),
            "--ids",
            "1,2,3",
            "--qemu-log",
            &log_arg,
        ],
    )?;

    let latency = std::env::var("DXL_LATENCY_MS").unwrap_or_else(|_| "2500".into());
    let reads = std::env::var("DXL_READS").unwrap_or_else(|_| DEFAULT_READS.to_string());
    let started = Instant::now();
    let out = Command::new(python)
        .arg(workspace_root().join("dynamixel/tests/sdk_check.py"))
        .arg(&link)
        .args(["--latency-ms", &latency, "--reads", &reads])
        .args(["--zero-delay-reads", &SHORT_READS.to_string()])
        .args(["--baud", &SDK_BAUD.to_string()])
        .args(["--sync-reads", &SHORT_READS.to_string()])
        .args(["--tolerance", &TOLERANCE_COUNTS.to_string()])
        .args(["--clutch-um", &CLUTCH_UM.to_string(), "--load", "cw"])
        .args(["--voltage", &SUPPLY_DV.to_string()])
        .output()
        .context("running sdk_check.py")?;
    let secs = started.elapsed().as_secs_f64();
    drop(bus);
    let (passed, notes) = relay(board, &out);
    if !out.status.success() {
        board_logs(board, elf, &log);
        bail!("dynamixel-sdk checks failed on {}", board.feature());
    }
    let notes = match notes {
        0 => String::new(),
        n => format!(" ({n} notes above)"),
    };
    Ok(format!(
        "{passed} dynamixel-sdk checks passed in {secs:.0} s{notes}"
    ))
}

/// After a failed check: what each board logged beyond its boot (faults, warnings, stored
/// settings), decoded, to tell a board that faulted or stopped from a lost packet.
fn board_logs(board: Board, elf: &Path, log: &Path) {
    let format = match crate::defmt_log::LogFormat::from_elf(elf) {
        Ok(f) => f,
        Err(e) => {
            eprintln!("xtask: the boards' logs cannot be decoded: {e:#}");
            return;
        }
    };
    for id in 1..=3 {
        let path = log.with_extension(format!("id{id}.log"));
        let Ok(bytes) = std::fs::read(&path) else {
            eprintln!("xtask: no log at {}", path.display());
            continue;
        };
        let mut decoder = format.decoder();
        let lines = decoder.feed(&bytes);
        // Boot lines are stamped 0 µs; the first lines after them say what happened.
        let after_boot: Vec<&String> = lines
            .iter()
            .filter(|l| !l.trim_start().starts_with("0.000"))
            .collect();
        let n = after_boot.len();
        println!(
            "[{} dynamixel] board {id}'s log: {n} lines after boot{}",
            board.feature(),
            if n > 20 {
                ", the first and last 10:"
            } else {
                ":"
            }
        );
        for (i, line) in after_boot.iter().enumerate() {
            if i < 10 || i + 10 >= n {
                println!("[{} dynamixel]   {line}", board.feature());
            }
        }
    }
}

/// One board with a flash file, power-cycled three times (`sdk_persist.py`'s steps, with
/// `vsa bus` switching the protocol and the ID in between).
fn power_cycles(python: &Path, vsa: &Path, board: Board, elf: &Path) -> Result<String> {
    let link = target_dir().join(format!("dxl-persist-{}", board.feature()));
    let flash = target_dir().join(format!("dxl-flash-{}", board.feature()));
    let flash_file = flash.with_extension("id1.flash");
    if flash_file.exists() {
        std::fs::remove_file(&flash_file)
            .with_context(|| format!("removing {}", flash_file.display()))?;
    }
    let latency = std::env::var("DXL_LATENCY_MS").unwrap_or_else(|_| "2500".into());
    let started = Instant::now();
    let mut passed = 0;
    let flash_arg = flash.to_string_lossy().into_owned();
    let args = ["--ids", "1", "--qemu-flash", flash_arg.as_str()];
    let step = |name: &str, passed: &mut usize| -> Result<()> {
        let out = Command::new(python)
            .arg(workspace_root().join("dynamixel/tests/sdk_persist.py"))
            .arg(&link)
            .arg(name)
            .args(["--latency-ms", &latency, "--baud", &SDK_BAUD.to_string()])
            .output()
            .context("running sdk_persist.py")?;
        *passed += relay(board, &out).0;
        ensure!(
            out.status.success(),
            "sdk_persist.py {name} failed on {}",
            board.feature()
        );
        Ok(())
    };
    let vsa_bus = |args: &[&str]| -> Result<()> {
        let out = Command::new(vsa)
            .arg("--port")
            .arg(&link)
            .arg("bus")
            .args(args)
            .output()
            .context("running vsa bus")?;
        print!(
            "[{} dynamixel] vsa bus {}: {}",
            board.feature(),
            args.join(" "),
            String::from_utf8_lossy(&out.stdout)
        );
        ensure!(
            out.status.success(),
            "vsa bus {} failed: {}",
            args.join(" "),
            String::from_utf8_lossy(&out.stderr).trim()
        );
        Ok(())
    };
    {
        let _bus = start_bus(vsa, board, elf, &link, &args)?;
        step("fresh", &mut passed)?;
    }
    {
        let _bus = start_bus(vsa, board, elf, &link, &args)?;
        step("stored", &mut passed)?;
        vsa_bus(&["--protocol", "2"])?;
        step("switched", &mut passed)?;
        vsa_bus(&["--protocol", "2", "--id", "6"])?;
    }
    {
        let _bus = start_bus(vsa, board, elf, &link, &args)?;
        step("vsa", &mut passed)?;
    }
    let _ = std::fs::remove_file(&flash_file);
    Ok(format!(
        "{passed} checks of the stored bus settings over 3 power cycles in {:.0} s",
        started.elapsed().as_secs_f64()
    ))
}
