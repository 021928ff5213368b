//! Board commands: talk to a real board (`--port`), a board or relay on TCP (`--tcp`), or
//! an emulated board started for this invocation (`--qemu`), through the `client` crate.
//!
//! Every argument is parsed and range-checked before the connection is made (bad input
//! exits with 2 and sends nothing); a refusal, a timeout or a lost connection exits with 1.

pub mod bus;
mod bus_settings;
mod calibrate;
mod config;
mod impedance;
mod quantities;
pub mod sensors;
pub mod serve;

use std::fmt::Write as _;
use std::io::Write as _;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Mutex, Once, PoisonError};
use std::time::{Duration, Instant};

use clap::{Args, Parser, Subcommand};
use client::protocol::{KD_MAX, KI_MAX, KP_MAX};
use client::qemu::{self, Board, LogSink, QemuBoard};
use client::{
    describe_fault, fault_name, state_name, urad_text, Client, ErrorCode, FaultCode, FaultSet,
    Gains, LimitFlags, Limits, Recording, Status,
};

use crate::error::{CliError, CliResult};
use crate::format::trim;
use crate::output;
use quantities::show;
pub use quantities::LOAD_MAX_MNM;

/// How to reach the board (global options, for board commands only).
#[derive(Args, Debug, Default, Clone)]
pub struct ConnectArgs {
    /// Serial port of a real board (ST-LINK virtual COM port), e.g. /dev/ttyACM0
    #[arg(
        long,
        global = true,
        value_name = "PATH",
        help_heading = "Board connection"
    )]
    pub port: Option<String>,
    /// Baud rate of --port [default: 921600]
    #[arg(
        long,
        global = true,
        value_name = "BAUD",
        help_heading = "Board connection"
    )]
    pub baud: Option<u32>,
    /// A board or `vsa serve-qemu` relay on TCP, e.g. 127.0.0.1:4000
    #[arg(
        long,
        global = true,
        value_name = "HOST:PORT",
        help_heading = "Board connection"
    )]
    pub tcp: Option<String>,
    /// Start an emulated board (QEMU) for this invocation only
    #[arg(long, global = true, help_heading = "Board connection")]
    pub qemu: bool,
    /// Emulated board for --qemu and serve-qemu [default: qemu-m4]
    #[arg(
        long,
        global = true,
        value_name = "BOARD",
        value_parser = ["qemu-m4", "qemu-m3"],
        help_heading = "Board connection"
    )]
    pub board: Option<String>,
    /// Firmware ELF for --qemu and serve-qemu [default: build it with cargo]
    #[arg(
        long,
        global = true,
        value_name = "PATH",
        help_heading = "Board connection"
    )]
    pub elf: Option<PathBuf>,
    /// Write the emulated firmware's raw defmt log bytes to FILE
    #[arg(
        long,
        global = true,
        value_name = "FILE",
        help_heading = "Board connection"
    )]
    pub qemu_log: Option<PathBuf>,
    /// Constant load the emulated board hangs on its link the first time the motor drives,
    /// e.g. 0.3Nm (|·| ≤ 2 N·m) [default: none]
    #[arg(
        long,
        global = true,
        value_name = "TORQUE",
        help_heading = "Board connection"
    )]
    pub qemu_load: Option<String>,
    /// Host file holding the emulated board's flash (its stored settings and fault log):
    /// read at boot, written after every store operation; created if absent. Without it
    /// the emulated store lives in RAM and is lost at exit
    #[arg(
        long,
        global = true,
        value_name = "FILE",
        help_heading = "Board connection"
    )]
    pub qemu_flash: Option<PathBuf>,
    /// Makes the emulated board's simulated actuator off-nominal, e.g.
    /// power-up-angle=0.8rad (repeatable; the names of `vsa simulate --plant`)
    #[arg(
        long,
        global = true,
        value_name = "NAME=VALUE",
        allow_hyphen_values = true,
        help_heading = "Board connection"
    )]
    pub qemu_plant: Vec<String>,
    /// Reply timeout, e.g. 2s [default: 1s]
    #[arg(
        long,
        global = true,
        value_name = "DURATION",
        help_heading = "Board connection"
    )]
    pub timeout: Option<String>,
}

impl ConnectArgs {
    /// The first connection option given, if any (to reject them where they mean nothing).
    pub fn first_given(&self) -> Option<&'static str> {
        [
            (self.port.is_some(), "--port"),
            (self.baud.is_some(), "--baud"),
            (self.tcp.is_some(), "--tcp"),
            (self.qemu, "--qemu"),
            (self.board.is_some(), "--board"),
            (self.elf.is_some(), "--elf"),
            (self.qemu_log.is_some(), "--qemu-log"),
            (self.qemu_load.is_some(), "--qemu-load"),
            (self.qemu_flash.is_some(), "--qemu-flash"),
            (!self.qemu_plant.is_empty(), "--qemu-plant"),
            (self.timeout.is_some(), "--timeout"),
        ]
        .into_iter()
        .find_map(|(given, name)| given.then_some(name))
    }

    /// Which board the options select.
    fn target(&self) -> CliResult<Target> {
        let chosen: Vec<&str> = [
            (self.port.is_some(), "--port"),
            (self.tcp.is_some(), "--tcp"),
            (self.qemu, "--qemu"),
        ]
        .into_iter()
        .filter_map(|(g, n)| g.then_some(n))
        .collect();
        match chosen.as_slice() {
            [] => {
                return Err(CliError {
                    arg: None,
                    reason: "no board connection: give --port PATH, --tcp HOST:PORT or --qemu"
                        .to_string(),
                    code: 2,
                })
            }
            [_] => {}
            [a, b, ..] => {
                return Err(CliError::usage(a, format!("cannot be combined with {b}")));
            }
        }
        if self.baud.is_some() && self.port.is_none() {
            return Err(CliError::usage("--baud", "only applies to --port"));
        }
        if !self.qemu {
            for (given, name) in [
                (self.board.is_some(), "--board"),
                (self.elf.is_some(), "--elf"),
                (self.qemu_log.is_some(), "--qemu-log"),
                (self.qemu_load.is_some(), "--qemu-load"),
                (self.qemu_flash.is_some(), "--qemu-flash"),
                (!self.qemu_plant.is_empty(), "--qemu-plant"),
            ] {
                if given {
                    return Err(CliError::usage(name, "only applies to --qemu"));
                }
            }
        }
        Ok(if let Some(p) = &self.port {
            Target::Serial {
                path: p.clone(),
                baud: self.baud.unwrap_or(client::DEFAULT_BAUD),
            }
        } else if let Some(t) = &self.tcp {
            let port = t
                .rsplit_once(':')
                .map(|(host, port)| (host, port.parse::<u16>()));
            match port {
                Some((host, Ok(p))) if !host.is_empty() && p != 0 => Target::Tcp(t.clone()),
                _ => {
                    return Err(CliError::usage(
                        "--tcp",
                        format!("'{t}' is not HOST:PORT (e.g. 127.0.0.1:4000)"),
                    ))
                }
            }
        } else {
            Target::Qemu(self.qemu_target()?)
        })
    }

    /// The emulated board options.
    pub fn qemu_target(&self) -> CliResult<QemuTarget> {
        let board = match &self.board {
            Some(b) => b.parse().map_err(|e| CliError::usage("--board", e))?,
            None => Board::QemuM4,
        };
        let load_mnm = match &self.qemu_load {
            Some(t) => quantities::torque_mnm("--qemu-load", t)?,
            None => 0,
        };
        let flash = match &self.qemu_flash {
            Some(f) => {
                Some(qemu::flash_file_arg(f).map_err(|e| CliError::usage("--qemu-flash", e))?)
            }
            None => None,
        };
        for o in &self.qemu_plant {
            // The one parser of the overrides; the firmware parses the same text again.
            plant::overrides::Override::parse(o)
                .map_err(|e| CliError::usage("--qemu-plant", format!("`{o}`: {e}")))?;
        }
        Ok(QemuTarget {
            board,
            elf: self.elf.clone(),
            log: self.qemu_log.clone(),
            load_mnm,
            flash,
            plant: self.qemu_plant.clone(),
        })
    }

    /// The reply timeout.
    fn reply_timeout(&self) -> CliResult<Duration> {
        match &self.timeout {
            Some(t) => quantities::duration("--timeout", t, 3600),
            None => Ok(client::DEFAULT_TIMEOUT),
        }
    }
}

/// An emulated board to start.
#[derive(Debug, Clone)]
pub struct QemuTarget {
    board: Board,
    elf: Option<PathBuf>,
    log: Option<PathBuf>,
    /// `--load-mnm` of the served firmware, mN·m.
    load_mnm: i32,
    /// `--flash` of the served firmware.
    flash: Option<String>,
    /// `--plant NAME=VALUE` of the served firmware, checked.
    plant: Vec<String>,
}

impl QemuTarget {
    /// The ELF to run: `--elf`, or the firmware built with cargo now.
    fn elf(&self) -> CliResult<PathBuf> {
        if let Some(e) = &self.elf {
            if !e.is_file() {
                return Err(CliError::usage(
                    "--elf",
                    format!("{} does not exist", e.display()),
                ));
            }
            return Ok(e.clone());
        }
        let root = qemu::workspace_root().ok_or_else(|| {
            CliError::usage(
                "--qemu",
                "cannot find the vsa workspace to build the firmware in: pass --elf PATH \
                 or set VSA_WORKSPACE",
            )
        })?;
        let _ = writeln!(
            std::io::stderr(),
            "building the {} firmware in {} …",
            self.board,
            root.display()
        );
        qemu::build_firmware(&root, self.board).map_err(|e| CliError::runtime(e.to_string()))
    }

    /// Where the defmt log goes.
    fn sink(&self) -> CliResult<LogSink> {
        match &self.log {
            None => Ok(LogSink::Discard),
            Some(p) => std::fs::File::create(p)
                .map(|f| LogSink::Writer(Box::new(std::io::BufWriter::new(f))))
                .map_err(|e| CliError::usage("--qemu-log", format!("{}: {e}", p.display()))),
        }
    }

    /// The served firmware's arguments for the simulated actuator: its load and its
    /// changes from the nominal one (`--qemu-load`, `--qemu-plant`).
    fn actuator_args(&self) -> Vec<String> {
        let mut args = if self.load_mnm == 0 {
            Vec::new()
        } else {
            vec!["--load-mnm".to_owned(), self.load_mnm.to_string()]
        };
        for o in &self.plant {
            args.extend(["--plant".to_owned(), o.clone()]);
        }
        args
    }

    /// The served firmware's arguments: [`QemuTarget::actuator_args`] and the flash file.
    fn firmware_args(&self) -> Vec<String> {
        let mut args = self.actuator_args();
        if let Some(f) = &self.flash {
            args.extend(["--flash".to_owned(), f.clone()]);
        }
        args
    }

    /// Builds (if needed) and starts the board; returns it and a client it has answered.
    pub fn start(&self) -> CliResult<(Adopted, Client)> {
        let elf = self.elf()?;
        let sink = self.sink()?;
        let firmware_args = self.firmware_args();
        let (board, mut client) = QemuBoard::start(self.board, &elf, &firmware_args, sink)
            .map_err(|e| CliError::runtime(e.to_string()))?;
        // A board just powered up aligns its encoder to the pot for 32 ms with the motor
        // off and refuses an enable until then (docs/calibration.md): give it 100 ms.
        client
            .wait(Duration::from_millis(100))
            .map_err(|e| CliError::runtime(e.to_string()))?;
        Ok((adopt(board), client))
    }
}

/// The emulated boards this process started. They are killed when their [`Adopted`]
/// handle drops, and also on Ctrl-C, SIGTERM or SIGHUP (QEMU would otherwise outlive
/// `vsa`, spinning).
static BOARDS: Mutex<Vec<QemuBoard>> = Mutex::new(Vec::new());

/// An emulated board kept in [`BOARDS`]; dropping it kills QEMU.
pub struct Adopted {
    pid: u32,
}

/// Set when a signal stops `vsa` (the handler is killing the boards and exiting).
static INTERRUPTED: AtomicBool = AtomicBool::new(false);

/// If a signal is stopping `vsa`, waits for the handler to end the process (with 130)
/// instead of reporting the lost connection that killing the board caused.
pub fn park_if_interrupted() {
    if INTERRUPTED.load(Ordering::SeqCst) {
        loop {
            std::thread::park();
        }
    }
}

/// Takes `board` into [`BOARDS`] (installing the signal handler once).
pub fn adopt(board: QemuBoard) -> Adopted {
    static HANDLER: Once = Once::new();
    HANDLER.call_once(|| {
        // Without the handler a signal still ends `vsa`; only the cleanup is lost (QEMU
        // dies with `vsa` anyway: see `client::qemu`).
        let _ = ctrlc::set_handler(|| {
            INTERRUPTED.store(true, Ordering::SeqCst);
            BOARDS
                .lock()
                .unwrap_or_else(PoisonError::into_inner)
                .clear();
            std::process::exit(130);
        });
    });
    let pid = board.pid();
    BOARDS
        .lock()
        .unwrap_or_else(PoisonError::into_inner)
        .push(board);
    Adopted { pid }
}

impl Adopted {
    /// QEMU's process id.
    pub fn pid(&self) -> u32 {
        self.pid
    }

    /// [`QemuBoard::exit_report`].
    pub fn exit_report(&self) -> String {
        let mut boards = BOARDS.lock().unwrap_or_else(PoisonError::into_inner);
        boards
            .iter_mut()
            .find(|b| b.pid() == self.pid)
            .map_or_else(String::new, QemuBoard::exit_report)
    }
}

impl Drop for Adopted {
    fn drop(&mut self) {
        let board = {
            let mut boards = BOARDS.lock().unwrap_or_else(PoisonError::into_inner);
            boards
                .iter()
                .position(|b| b.pid() == self.pid)
                .map(|i| boards.swap_remove(i))
        };
        drop(board); // kills QEMU, outside the lock
    }
}

enum Target {
    Serial { path: String, baud: u32 },
    Tcp(String),
    Qemu(QemuTarget),
}

/// A connected board for one invocation (the emulated board, if any, dies with it).
pub struct Session {
    client: Client,
    qemu: Option<Adopted>,
}

impl Session {
    /// Connects as `conn` says.
    pub fn open(conn: &ConnectArgs) -> CliResult<Session> {
        let target = conn.target()?;
        let timeout = conn.reply_timeout()?;
        let (client, qemu) = match target {
            Target::Serial { path, baud } => (
                Client::open_serial(&path, baud).map_err(|e| CliError::runtime(e.to_string()))?,
                None,
            ),
            Target::Tcp(addr) => (
                Client::connect_tcp(&addr).map_err(|e| CliError::runtime(e.to_string()))?,
                None,
            ),
            Target::Qemu(q) => {
                let (board, client) = q.start()?;
                (client, Some(board))
            }
        };
        Ok(Session {
            client: client.with_timeout(timeout),
            qemu,
        })
    }

    /// A client error as a CLI error (exit 1), with QEMU's exit status if it died.
    fn fail(&mut self, e: &client::Error) -> CliError {
        let mut msg = e.to_string();
        if let Some(q) = &self.qemu {
            msg.push_str(&q.exit_report());
        }
        CliError::runtime(msg)
    }
}

/// The board commands (also the lines of `vsa script`).
#[derive(Subcommand, Debug, Clone)]
pub enum BoardCommand {
    /// Check that the board answers, and how fast
    Ping,
    /// State, faults, configuration and counters of the board
    Status,
    /// Motor on, holding the current position (refused while a fault is latched)
    Enable,
    /// Motor off
    Disable,
    /// Clear the latched faults (the motor stays off until `enable`); refused, with the way
    /// out, while a fault's condition persists
    Clear,
    /// Tell the board where the clutch sits, e.g. `clutch 3mm` (1–8 mm)
    Clutch {
        /// Active beam length, e.g. 3mm
        #[arg(value_name = "LENGTH", allow_hyphen_values = true)]
        length: String,
    },
    /// Configure for a joint stiffness, e.g. `stiffness 250Nm/rad`; prints the clutch length to set
    Stiffness {
        /// Joint stiffness, e.g. 250Nm/rad
        #[arg(value_name = "STIFFNESS", allow_hyphen_values = true)]
        stiffness: String,
    },
    /// Minimum-jerk move of the link to an absolute angle, e.g. `move 0.5rad --duration 300ms`
    Move {
        /// Target link angle (rad, mrad, urad or deg), |·| ≤ 2.54 rad and inside the
        /// board's position window
        #[arg(value_name = "ANGLE", allow_hyphen_values = true)]
        target: String,
        /// Duration of the move, 1 ms – 60 s
        #[arg(long, value_name = "DURATION", default_value = "500ms")]
        duration: String,
    },
    /// Reference step to an absolute link angle, e.g. `step 0.5rad`
    Step {
        /// Target link angle (rad, mrad, urad or deg), |·| ≤ 2.54 rad and inside the
        /// board's position window
        #[arg(value_name = "ANGLE", allow_hyphen_values = true)]
        target: String,
    },
    /// Sine about the current link angle, e.g. `sine 0.2rad --frequency 1Hz`
    Sine {
        /// Amplitude, 0–1 rad
        #[arg(value_name = "AMPLITUDE", allow_hyphen_values = true)]
        amplitude: String,
        /// Frequency, 0.01–20 Hz
        #[arg(long, value_name = "FREQUENCY")]
        frequency: String,
    },
    /// Stop any motion and hold the current reference
    Hold,
    /// Hold an angle as a spring-damper softer than the clutch setting, e.g.
    /// `impedance 0.3rad --stiffness 20Nm/rad --damping 0.2Nms/rad [--torque 0.1Nm]`
    Impedance(impedance::ImpedanceArgs),
    /// Explicit PID gains (`--kp 800 --ki 2000 --kd 20`), or `--auto` for the scheduled ones
    Gains(GainsArgs),
    /// Live limits and the position window; options not given take their defaults
    Limits(LimitsArgs),
    /// Wait, e.g. `wait 500ms` (in a script: heartbeats go on, telemetry is dropped)
    Wait {
        /// How long (a bare number is in seconds), up to 1 h
        #[arg(value_name = "DURATION")]
        duration: String,
    },
    /// Record telemetry: samples, gaps and drops; optionally to a CSV in SI units
    Record(RecordArgs),
    /// The board's stored configuration: save, load, show, reset (factory reset)
    #[command(subcommand)]
    Config(config::ConfigCommand),
    /// The faults latched now, or with --log the fault log kept in flash
    Faults(config::FaultsArgs),
    /// The Dynamixel bus settings, e.g. `bus --protocol 1` or `bus --id 4 --baud 57600`
    Bus(bus_settings::BusArgs),
    /// Calibrate a real build (motor disabled): polarity, sensor directions and offsets,
    /// motor resistance and back-EMF, link inertia; stored on the board (`--show`: print it)
    Calibrate(calibrate::CalibrateArgs),
}

/// Arguments of `gains`.
#[derive(Args, Debug, Clone)]
pub struct GainsArgs {
    /// Proportional gain, ‰ duty per rad (0–10⁶)
    #[arg(long, value_name = "KP")]
    pub kp: Option<String>,
    /// Integral gain, ‰ duty per rad·s (0–10⁷)
    #[arg(long, value_name = "KI")]
    pub ki: Option<String>,
    /// Derivative gain, ‰ duty per rad/s (0–10⁴)
    #[arg(long, value_name = "KD")]
    pub kd: Option<String>,
    /// Back to the stiffness-scheduled gains
    #[arg(long, conflicts_with_all = ["kp", "ki", "kd"])]
    pub auto: bool,
}

/// Arguments of `limits`.
#[derive(Args, Debug, Clone)]
pub struct LimitsArgs {
    /// Fraction of the beams' torque capacity the coupling may use, e.g. 0.85 or 85% [default: 0.85]
    #[arg(long, value_name = "FRACTION")]
    pub torque_margin: Option<String>,
    /// Motor current limit, e.g. 1.2A [default: 1.5A]
    #[arg(long, value_name = "CURRENT")]
    pub current: Option<String>,
    /// Motor torque limit at the output, e.g. 1.5Nm [default: 1.5Nm]
    #[arg(long, value_name = "TORQUE")]
    pub motor_torque: Option<String>,
    /// Largest |PWM duty|, e.g. 0.8 or 80% [default: 1]
    #[arg(long, value_name = "FRACTION")]
    pub duty: Option<String>,
    /// Lower end of the position window, e.g. -2.5rad [default: -2.5rad]
    #[arg(long, value_name = "ANGLE", allow_hyphen_values = true)]
    pub position_min: Option<String>,
    /// Upper end of the position window, e.g. 2.5rad [default: 2.5rad]
    #[arg(long, value_name = "ANGLE", allow_hyphen_values = true)]
    pub position_max: Option<String>,
    /// How much longer than set the hand-set clutch may be, 0–5 mm: the torque limit and
    /// the overload check use the beams' capacity at that length, e.g. 0.6mm [default: 0mm]
    #[arg(long, value_name = "LENGTH")]
    pub clutch_tolerance: Option<String>,
}

/// Arguments of `record`.
#[derive(Args, Debug, Clone)]
pub struct RecordArgs {
    /// Span of board time to record (a bare number is in seconds), up to 1 h
    #[arg(long, value_name = "DURATION", default_value = "2")]
    pub seconds: String,
    /// Samples per second, 10–500 Hz
    #[arg(long, value_name = "HZ", default_value = "500")]
    pub rate: String,
    /// Write the samples here (s, rad, A, N·m, duty fraction)
    #[arg(long, value_name = "FILE")]
    pub csv: Option<PathBuf>,
}

/// A board command with its arguments converted to wire units and checked.
#[derive(Debug, Clone)]
enum Action {
    Ping,
    Status,
    Enable,
    Disable,
    Clear,
    Clutch(u32),
    Stiffness(u32),
    Move {
        target: i32,
        duration_ms: u32,
    },
    Step(i32),
    Sine {
        amplitude: u32,
        frequency_mhz: u32,
    },
    Hold,
    Impedance(impedance::Plan),
    Gains(Option<Gains>),
    Limits(Limits),
    Wait(Duration),
    Record {
        span: Duration,
        rate: u16,
        csv: Option<PathBuf>,
    },
    Config(config::ConfigCommand),
    Faults(config::FaultsArgs),
    Bus(client::protocol::BusChange),
    Calibrate(calibrate::CalibrateArgs),
}

/// Checks a command's arguments (errors name the command and the argument).
fn plan(cmd: &BoardCommand) -> CliResult<Action> {
    Ok(match cmd {
        BoardCommand::Ping => Action::Ping,
        BoardCommand::Status => Action::Status,
        BoardCommand::Enable => Action::Enable,
        BoardCommand::Disable => Action::Disable,
        BoardCommand::Clear => Action::Clear,
        BoardCommand::Clutch { length } => Action::Clutch(quantities::length_um("clutch", length)?),
        BoardCommand::Stiffness { stiffness } => {
            Action::Stiffness(quantities::stiffness_mnm_per_rad("stiffness", stiffness)?)
        }
        BoardCommand::Move { target, duration } => Action::Move {
            target: quantities::angle_urad("move", target)?,
            duration_ms: quantities::move_duration_ms("move --duration", duration)?,
        },
        BoardCommand::Step { target } => Action::Step(quantities::angle_urad("step", target)?),
        BoardCommand::Sine {
            amplitude,
            frequency,
        } => Action::Sine {
            amplitude: quantities::amplitude_urad("sine", amplitude)?,
            frequency_mhz: quantities::frequency_mhz("sine --frequency", frequency)?,
        },
        BoardCommand::Hold => Action::Hold,
        BoardCommand::Config(c) => Action::Config(*c),
        BoardCommand::Faults(f) => Action::Faults(*f),
        BoardCommand::Calibrate(a) => Action::Calibrate(*a),
        BoardCommand::Impedance(a) => Action::Impedance(impedance::plan(a)?),
        BoardCommand::Bus(a) => Action::Bus(bus_settings::plan(a)?),
        BoardCommand::Gains(g) => Action::Gains(plan_gains(g)?),
        BoardCommand::Limits(l) => Action::Limits(plan_limits(l)?),
        BoardCommand::Wait { duration } => {
            Action::Wait(quantities::duration("wait", duration, 3600)?)
        }
        BoardCommand::Record(r) => Action::Record {
            span: quantities::duration("record --seconds", &r.seconds, 3600)?,
            rate: quantities::rate_hz("record --rate", &r.rate, false)?,
            csv: r.csv.clone(),
        },
    })
}

fn plan_gains(g: &GainsArgs) -> CliResult<Option<Gains>> {
    if g.auto {
        return Ok(None);
    }
    match (&g.kp, &g.ki, &g.kd) {
        (Some(kp), Some(ki), Some(kd)) => Ok(Some(Gains {
            kp: quantities::gain("gains --kp", kp, KP_MAX)?,
            ki: quantities::gain("gains --ki", ki, KI_MAX)?,
            kd: quantities::gain("gains --kd", kd, KD_MAX)?,
        })),
        _ => Err(CliError::usage(
            "gains",
            "give all of --kp, --ki and --kd, or --auto",
        )),
    }
}

fn plan_limits(l: &LimitsArgs) -> CliResult<Limits> {
    let d = Limits::DEFAULT;
    let lim = Limits {
        torque_margin_permille: match &l.torque_margin {
            Some(s) => quantities::permille("limits --torque-margin", s)?,
            None => d.torque_margin_permille,
        },
        current_ma: match &l.current {
            Some(s) => quantities::current_ma("limits --current", s)?,
            None => d.current_ma,
        },
        motor_torque_unm: match &l.motor_torque {
            Some(s) => quantities::torque_unm("limits --motor-torque", s)?,
            None => d.motor_torque_unm,
        },
        duty_permille: match &l.duty {
            Some(s) => quantities::permille("limits --duty", s)?,
            None => d.duty_permille,
        },
        position_min_urad: match &l.position_min {
            Some(s) => quantities::angle_urad("limits --position-min", s)?,
            None => d.position_min_urad,
        },
        position_max_urad: match &l.position_max {
            Some(s) => quantities::angle_urad("limits --position-max", s)?,
            None => d.position_max_urad,
        },
        clutch_tolerance_um: match &l.clutch_tolerance {
            Some(s) => quantities::tolerance_um("limits --clutch-tolerance", s)?,
            None => d.clutch_tolerance_um,
        },
    };
    if lim.position_min_urad >= lim.position_max_urad {
        return Err(CliError::usage(
            "limits",
            format!(
                "the position window [{}, {}] rad is empty",
                show(lim.position_min_urad.into(), 6),
                show(lim.position_max_urad.into(), 6)
            ),
        ));
    }
    Ok(lim)
}

/// Writes `s` to stdout now (a closed pipe is not an error).
fn out(s: &str) {
    let mut o = std::io::stdout().lock();
    let _ = o.write_all(s.as_bytes()).and_then(|()| o.flush());
}

/// Runs one board command for this invocation.
pub fn run(cmd: &BoardCommand, conn: &ConnectArgs) -> CliResult<()> {
    let action = plan(cmd)?;
    let mut session = Session::open(conn)?;
    exec(&action, &mut session)
}

/// Carries out one action and prints its result.
fn exec(action: &Action, s: &mut Session) -> CliResult<()> {
    let c = &mut s.client;
    let r: Result<String, client::Error> = match action {
        Action::Ping => {
            let t = Instant::now();
            c.ping().map(|()| {
                format!(
                    "{} answered in {:.1} ms\n",
                    c.describe(),
                    t.elapsed().as_secs_f64() * 1e3
                )
            })
        }
        Action::Status => c.status().map(|st| status_text(&st)),
        Action::Enable => c.enable().map(|()| "enabled\n".to_string()),
        Action::Disable => c.disable().map(|()| "disabled\n".to_string()),
        Action::Clear => clear(c).map(|()| "faults cleared\n".to_string()),
        Action::Clutch(um) => c.set_clutch_length(*um).and_then(|()| {
            let st = c.status()?;
            Ok(format!(
                "clutch L = {} mm configured: k = {} N·m/rad\n",
                show((*um).into(), 3),
                show(st.stiffness_mnm_per_rad.into(), 3)
            ))
        }),
        Action::Stiffness(k) => c.set_stiffness(*k).map(|um| {
            format!(
                "configured for k = {} N·m/rad: set the clutch to L = {} mm\n",
                show((*k).into(), 3),
                show(um.into(), 3)
            )
        }),
        Action::Move {
            target,
            duration_ms,
        } => c.move_to(*target, *duration_ms).map(|()| {
            format!(
                "moving to {} rad in {} ms\n",
                show((*target).into(), 6),
                duration_ms
            )
        }),
        Action::Step(t) => c
            .step_to(*t)
            .map(|()| format!("step to {} rad\n", show((*t).into(), 6))),
        Action::Sine {
            amplitude,
            frequency_mhz,
        } => c.sine(*amplitude, *frequency_mhz).map(|()| {
            format!(
                "sine of {} rad at {} Hz\n",
                show((*amplitude).into(), 6),
                show((*frequency_mhz).into(), 3)
            )
        }),
        Action::Hold => c.hold().map(|()| "holding\n".to_string()),
        Action::Gains(Some(g)) => c.set_gains(*g).map(|()| {
            format!(
                "gains set: kp {} ‰/rad, ki {} ‰/(rad·s), kd {} ‰·s/rad\n",
                show(g.kp as i64, 3),
                show(g.ki as i64, 3),
                show(g.kd as i64, 3)
            )
        }),
        Action::Gains(None) => c
            .auto_gains()
            .map(|()| "automatic (stiffness-scheduled) gains\n".to_string()),
        Action::Limits(l) => c.set_limits(l).map(|()| {
            format!(
                "limits set: torque margin {}, current {} A, motor torque {} N·m, duty {}, \
                 position [{}, {}] rad, clutch tolerance {} mm\n",
                show(l.torque_margin_permille.into(), 3),
                show(l.current_ma.into(), 3),
                show(l.motor_torque_unm.into(), 6),
                show(l.duty_permille.into(), 3),
                show(l.position_min_urad.into(), 6),
                show(l.position_max_urad.into(), 6),
                show(l.clutch_tolerance_um.into(), 3)
            )
        }),
        Action::Wait(d) => c.wait(*d).map(|()| {
            c.clear_telemetry();
            String::new()
        }),
        Action::Record { span, rate, csv } => return record(s, *span, *rate, csv.as_ref()),
        Action::Config(cmd) => config::config(c, *cmd),
        Action::Faults(args) => config::faults(c, *args),
        Action::Impedance(p) => return impedance::run(s, p),
        Action::Bus(c) => return bus_settings::run(s, c),
        Action::Calibrate(a) => return calibrate::run(s, a),
    };
    match r {
        Ok(text) => {
            out(&text);
            Ok(())
        }
        Err(client::Error::Refused {
            request,
            code: ErrorCode::OutOfRange,
        }) if matches!(
            action,
            Action::Move { .. } | Action::Step(_) | Action::Sine { .. }
        ) =>
        {
            Err(outside_window(s, action, request))
        }
        Err(e) => Err(s.fail(&e)),
    }
}

/// Clears the faults. A condition judged at the tick before a reconfiguration (e.g. a
/// window just widened) may still be reported once: asked again after a few ticks.
fn clear(c: &mut Client) -> Result<(), client::Error> {
    match c.clear_fault() {
        Err(client::Error::FaultPersists { .. }) => {
            c.wait(Duration::from_millis(20))?;
            c.clear_fault()
        }
        r => r,
    }
}

/// The refusal of a motion whose target lies outside the board's position window, with
/// the window (asked from the board).
fn outside_window(s: &mut Session, action: &Action, request: &str) -> CliError {
    let what = match action {
        Action::Move { target, .. } | Action::Step(target) => {
            format!("target {}", urad_text((*target).into()))
        }
        Action::Sine { amplitude, .. } => format!(
            "a sine of ±{} about the link's angle now",
            urad_text((*amplitude).into())
        ),
        _ => "the motion".to_string(),
    };
    match s.client.limits() {
        Ok(l) => CliError::runtime(format!(
            "the board refused {request}: {what} is outside the position window [{}, {}] \
             rad (`limits --position-min/--position-max` widen it, up to ±{})",
            show(l.position_min_urad.into(), 6),
            show(l.position_max_urad.into(), 6),
            urad_text(client::protocol::TARGET_MAX_URAD.into())
        )),
        Err(e) => s.fail(&e),
    }
}

fn record(s: &mut Session, span: Duration, rate: u16, csv: Option<&PathBuf>) -> CliResult<()> {
    // Fail on an unwritable CSV before recording; the file itself is only replaced once
    // the recording is complete.
    if let Some(p) = csv {
        output::check_writable(p).map_err(|e| CliError::usage("record --csv", e))?;
    }
    let bar = (span >= Duration::from_secs(1)).then(|| {
        let b = indicatif::ProgressBar::new(u64::try_from(span.as_millis()).unwrap_or(u64::MAX));
        if let Ok(style) =
            indicatif::ProgressStyle::with_template("recording [{bar:40}] {pos}/{len} ms {msg}")
        {
            b.set_style(style.progress_chars("=> "));
        }
        b
    });
    let result = s.client.record(span, rate, |p| {
        if let Some(b) = &bar {
            b.set_position(p.ticks_done.into());
            b.set_message(format!("{} samples", p.samples));
        }
    });
    if let Some(b) = &bar {
        b.finish_and_clear();
    }
    let rec = result.map_err(|e| s.fail(&e))?;
    let mut text = record_summary(&rec);
    if let Some(p) = csv {
        output::write_text(p, |w| client::csv::write_csv(w, &rec.samples))
            .map_err(CliError::runtime)?;
        let _ = writeln!(text, "wrote {}", p.display());
    }
    out(&text);
    let new = rec.new_faults();
    if new.is_empty() {
        Ok(())
    } else {
        Err(CliError::runtime(format!(
            "fault latched during the recording: {}{}",
            fault_list(new),
            rec.first_fault_after
                .as_ref()
                .map_or_else(String::new, |f| format!(
                    "; first fault {}",
                    describe_fault(f)
                ))
        )))
    }
}

/// Faults that latched while `action` ran: those in `after` not in `before`, named, with
/// the board's first fault. `None` when none did.
fn new_fault_report(before: FaultSet, after: &Status) -> Option<String> {
    let new = FaultSet(after.faults.0 & !before.0);
    (!new.is_empty()).then(|| {
        format!(
            "fault latched: {}{}; the motor is off (`status` for details, `clear` to \
             recover)",
            fault_list(new),
            after
                .first_fault
                .as_ref()
                .map_or_else(String::new, |f| format!(
                    "; first fault {}",
                    describe_fault(f)
                ))
        )
    })
}

/// The summary of a recording.
fn record_summary(r: &Recording) -> String {
    let mut s = String::new();
    let (first, last) = (
        r.samples.first().map_or(0, |x| x.tick),
        r.samples.last().map_or(0, |x| x.tick),
    );
    let _ = writeln!(
        s,
        "recorded {} of {} samples at {} Hz over {} s (ticks {first}–{last})",
        r.samples.len(),
        r.expected_samples(),
        r.rate_hz,
        trim(f64::from(r.ticks) / 1e3),
    );
    let _ = writeln!(
        s,
        "missing {} in {} gaps; board dropped {} ({} since boot); {} bad frames",
        r.missing_samples,
        r.gaps.len(),
        r.dropped,
        r.dropped_total,
        r.bad_frames
    );
    for g in r.gaps.iter().take(5) {
        let _ = writeln!(
            s,
            "  gap: {} missing between ticks {} and {}",
            g.missing, g.after_tick, g.before_tick
        );
    }
    if r.gaps.len() > 5 {
        let _ = writeln!(s, "  … and {} more gaps", r.gaps.len() - 5);
    }
    s
}

/// The faults of a set by name, `none` if empty.
fn fault_list(f: client::FaultSet) -> String {
    if f.is_empty() {
        return "none".to_string();
    }
    let mut names: Vec<String> = FaultCode::ALL
        .into_iter()
        .filter(|c| f.contains(*c))
        .map(|c| format!("{} ({})", fault_name(c), c.code()))
        .collect();
    let known = FaultCode::ALL.iter().fold(0u16, |m, c| m | c.bit());
    for bit in 0..16 {
        if f.0 & !known & (1 << bit) != 0 {
            names.push(format!("unknown bit {bit}"));
        }
    }
    names.join(", ")
}

fn limit_list(l: LimitFlags) -> String {
    let names: Vec<&str> = [
        (LimitFlags::TORQUE, "torque"),
        (LimitFlags::CURRENT, "current"),
        (LimitFlags::DUTY, "duty"),
    ]
    .into_iter()
    .filter(|(m, _)| l.any(*m))
    .map(|(_, n)| n)
    .collect();
    if names.is_empty() {
        "none".to_string()
    } else {
        names.join(", ")
    }
}

/// The status as aligned `name  value` lines.
fn status_text(st: &Status) -> String {
    let rows = [
        ("state", state_name(st.state).to_string()),
        ("faults", fault_list(st.faults)),
        (
            "first fault",
            st.first_fault
                .as_ref()
                .map_or_else(|| "–".to_string(), describe_fault),
        ),
        ("live limits", limit_list(st.limits)),
        (
            "clutch length",
            format!("{} mm", show(st.clutch_length_um.into(), 3)),
        ),
        (
            "stiffness",
            format!("{} N·m/rad", show(st.stiffness_mnm_per_rad.into(), 3)),
        ),
        (
            "clutch tolerance",
            format!(
                "{} mm (the beams' limits hold for a clutch this much longer than set)",
                show(st.clutch_tolerance_um.into(), 3)
            ),
        ),
        (
            "tick",
            format!("{} ({} s)", st.tick, trim(f64::from(st.tick) / 1e3)),
        ),
        ("moving", if st.moving { "yes" } else { "no" }.to_string()),
        (
            "telemetry",
            if st.telemetry_rate_hz == 0 {
                format!("off, {} samples dropped", st.telemetry_dropped)
            } else {
                format!(
                    "{} Hz, {} samples dropped",
                    st.telemetry_rate_hz, st.telemetry_dropped
                )
            },
        ),
        ("protocol errors", st.protocol_errors.to_string()),
        (
            "stored config",
            config::stored_line(st.differs_from_stored).to_string(),
        ),
        ("calibration", calibrate::progress_text(st.calibration)),
    ];
    let mut s = String::new();
    for (k, v) in rows {
        let _ = writeln!(s, "{k:<16} {v}");
    }
    s
}

/// Arguments of `vsa script`.
#[derive(Args, Debug)]
pub struct ScriptArgs {
    /// Board commands, one per argument, run in order on one connection, e.g.
    /// "clutch 3mm" "enable" "move 0.5rad --duration 300ms" "record --seconds 2 --csv out.csv"
    #[arg(value_name = "COMMAND", required = true, num_args = 1..)]
    pub commands: Vec<String>,
    /// Send no heartbeats. By default the script sends one every 20 ms while it waits,
    /// which arms the board's 100 ms command timeout, and disarms it when it ends (also
    /// after a failed command); a script killed on the way leaves it armed, and the board
    /// latches `command-timeout` (motor off) 100 ms later.
    #[arg(long)]
    pub no_heartbeat: bool,
}

/// One line of a script.
#[derive(Parser, Debug)]
#[command(name = "script", no_binary_name = true, disable_help_flag = true)]
struct ScriptLine {
    #[command(subcommand)]
    command: BoardCommand,
}

/// Splits a command line into words: whitespace separates, '…' and "…" quote.
fn split_words(s: &str) -> Result<Vec<String>, String> {
    let mut words = Vec::new();
    let mut cur = String::new();
    let mut in_word = false;
    let mut quote: Option<char> = None;
    for ch in s.chars() {
        match (quote, ch) {
            (Some(q), c) if c == q => quote = None,
            (Some(_), c) => cur.push(c),
            (None, '\'' | '"') => {
                quote = Some(ch);
                in_word = true;
            }
            (None, c) if c.is_whitespace() => {
                if in_word {
                    words.push(std::mem::take(&mut cur));
                    in_word = false;
                }
            }
            (None, c) => {
                cur.push(c);
                in_word = true;
            }
        }
    }
    if quote.is_some() {
        return Err("unterminated quote".to_string());
    }
    if in_word {
        words.push(cur);
    }
    Ok(words)
}

/// Runs `vsa script`: parses and checks every line first, then runs them on one session.
pub fn script(a: &ScriptArgs, conn: &ConnectArgs) -> CliResult<()> {
    let mut actions = Vec::with_capacity(a.commands.len());
    for (i, line) in a.commands.iter().enumerate() {
        let at = || format!("script command {} ('{line}')", i + 1);
        let words = split_words(line).map_err(|e| CliError::usage(&at(), e))?;
        if words.is_empty() {
            return Err(CliError::usage(&at(), "empty command"));
        }
        let parsed = ScriptLine::try_parse_from(&words).map_err(|e| {
            let text = e.render().to_string();
            let first = text
                .lines()
                .next()
                .unwrap_or("bad command")
                .trim_start_matches("error: ")
                .to_string();
            CliError::usage(&at(), first)
        })?;
        let action = plan(&parsed.command).map_err(|e| CliError::usage(&at(), e.to_string()))?;
        if let Action::Record { csv: Some(p), .. } = &action {
            output::check_writable(p)
                .map_err(|e| CliError::usage(&at(), format!("record --csv: {e}")))?;
        }
        actions.push((line.clone(), action));
    }
    let mut session = Session::open(conn)?;
    session.client.set_heartbeat(!a.no_heartbeat);
    let result = run_script(&actions, &mut session);
    if !a.no_heartbeat {
        // The session ends here: the board's command timeout must not outlive it.
        if let Err(e) = session.client.disarm_heartbeat() {
            if result.is_ok() {
                return Err(session.fail(&e));
            }
        }
    }
    result
}

/// Runs the checked lines of a script; after each, any fault that latched meanwhile ends
/// the script with exit status 1.
fn run_script(actions: &[(String, Action)], session: &mut Session) -> CliResult<()> {
    let mut before = session
        .client
        .status()
        .map_err(|e| session.fail(&e))?
        .faults;
    for (i, (line, action)) in actions.iter().enumerate() {
        let at = |e: CliError| CliError {
            arg: Some(format!("script command {} ('{line}')", i + 1)),
            reason: e.to_string(),
            code: e.code,
        };
        out(&format!("> {line}\n"));
        let done = exec(action, session);
        let after = session.client.status().map_err(|e| at(session.fail(&e)))?;
        if let Some(report) = new_fault_report(before, &after) {
            // The command's own error (if any) is the fault's consequence.
            return Err(at(CliError::runtime(report)));
        }
        done.map_err(at)?;
        before = after.faults;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn words() {
        assert_eq!(
            split_words("record --csv 'my file.csv'  --seconds 2").unwrap(),
            vec!["record", "--csv", "my file.csv", "--seconds", "2"]
        );
        assert_eq!(split_words(" a \"\" b").unwrap(), vec!["a", "", "b"]);
        assert!(split_words("a 'b").is_err());
        assert!(split_words("   ").unwrap().is_empty());
    }

    #[test]
    fn status_lines() {
        let st = Status {
            faults: client::FaultSet::EMPTY
                .with(FaultCode::OverCurrent)
                .with(FaultCode::CommandTimeout),
            clutch_length_um: 3_000,
            stiffness_mnm_per_rad: 265_463,
            clutch_tolerance_um: 600,
            tick: 12_345,
            telemetry_rate_hz: 500,
            ..Status::default()
        };
        let s = status_text(&st);
        assert!(
            s.contains("faults           over-current (3), command-timeout (9)"),
            "{s}"
        );
        assert!(s.contains("clutch length    3 mm"), "{s}");
        assert!(s.contains("stiffness        265.463 N·m/rad"), "{s}");
        assert!(s.contains("clutch tolerance 0.6 mm (the beams'"), "{s}");
        assert!(s.contains("tick             12345 (12.345 s)"), "{s}");
        assert!(
            s.contains("telemetry        500 Hz, 0 samples dropped"),
            "{s}"
        );
        assert_eq!(fault_list(client::FaultSet(1 << 12)), "unknown bit 12");
    }
}
