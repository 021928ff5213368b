//! `vsa advise`: which clutch setting saves energy for a periodic task.
//!
//! The task: a link of inertia J_l following a sine A·sin(2π·f·t) about its start, or one
//! period of a recorded or planned trajectory repeated (`--trajectory`, a CSV of
//! `t_s,angle_rad`: given to the controller as minimum-jerk moves, each aimed at the sample
//! [`LOOK_AHEAD`] ahead and re-planned at every sample, so that the reference passes the
//! samples without stopping; a 0.2 rad, 1 Hz sine sampled every 20 ms costs within 0.1 % of
//! the sine command), with an optional constant load. For each clutch length L of the list (default: 15 lengths over
//! the whole adjustable range [t_c, l]) the task runs in closed loop on the host — the
//! `model` crate's controller against the `plant` crate's simulated actuator, through
//! [`crate::figures::energy::energy_per_cycle`], the same function as the
//! `energy_per_cycle` figure, so the answer includes what the controller really does; the
//! link is held for [`SETTLE_BANDWIDTHS`]/ω_c first at soft settings, and the task's start
//! transient skipped for [`SKIP_BANDWIDTHS`]/ω_c, so that the averaged cycles are the
//! task's, not the controller's take-up of the load or of the start — and the row gives:
//!
//! * the stiffness k(L) (Euler–Bernoulli) and the **natural frequency** of the actuator at
//!   that setting: the coupling mode in which gear and link swing against each other with
//!   no motor torque, ω_n = √(k/J_r), J_r = J_g·J_l/(J_g + J_l) ([`model::natural_frequency`]
//!   with the reduced inertia; J_g the gear-side inertia of the controller's motor
//!   parameters). A link that must follow A·sin(ωt) needs the motor torque
//!   T_m = −ω²·A·(J_l + J_g·(1 − J_l·ω²/k)) (lossless two-mass model), which vanishes at
//!   ω = ω_n: that setting costs only the losses. (√(k/J_l), the link alone on the beams,
//!   is where the gear stands still instead; it is the anti-resonance.)
//! * motor energy per cycle ∮V·i dt and its copper part ∮R·i² dt, J (module docs of
//!   [`crate::figures::energy`]); the RMS tracking error of the motion about its mean, and
//!   that mean (the offset: the start-up angle, read from the gear pot, misses the
//!   deflection the load holds, the same at every cycle and not the task's doing); whether
//!   a live limit acted;
//! * the peak true beam root stress over the averaged cycles, its safety factor σ_allow/σ
//!   and whether the task stays within the beams' capacity (σ ≤ σ_allow).
//!
//! The best setting is the one with the least energy per cycle among those within capacity
//! that track the task (RMS error ≤ 10 % of the motion's RMS, A/√2). Whether resonance
//! with the task is reachable: the stiffness it needs, k = J_r·ω² ([`model::Design::tune`]
//! with J_r), against the adjustable range [k(l), k(t_c)].
//!
//! # JSON (`--json`)
//!
//! `{"task": {...}, "rows": [{"length_m", "stiffness_nm_per_rad", "natural_frequency_hz",
//! "energy_per_cycle_j", "copper_loss_j", "rms_error_rad", "offset_rad", "limited", "peak_stress_pa",
//! "safety_factor", "within_capacity", "tracks"}], "best_length_m", "best_reason",
//! "resonance_reachable", "resonance_length_m", "stiffness_needed_nm_per_rad",
//! "stiffness_range_nm_per_rad": [soft, stiff]}`; a row the controller rejects has null
//! values.

use std::path::PathBuf;

use clap::Args;
use fixed::types::I32F32;
use model::control::{Command, Config, Schedule};
use model::dynamics::Tuning;
use model::{Angle, BeamModel, Design, Frequency, Inertia, Length};
use plotters::prelude::SeriesLabelPosition;
use serde::Serialize;

use crate::design::{parse_design, BeamArgs};
use crate::error::{CliError, CliResult};
use crate::explore::positive;
use crate::figures::energy::{
    energy_of_commands, energy_per_cycle, CycleEnergy, Motion, SETTLE_TICKS, SKIP_TICKS,
};
use crate::figures::plot::{Figure, Panel, Series, COLORS};
use crate::format::{sig, Table};
use crate::units::{self, Kind};

/// Clutch lengths of the default list.
const DEFAULT_ROWS: u32 = 15;
/// Most clutch lengths one run may simulate.
const MAX_ROWS: u32 = 200;
/// Seconds of motion averaged at least (whole cycles).
const AVERAGED_S: f64 = 2.0;
/// Samples ahead that each move of a trajectory aims at (re-planned at every sample).
const LOOK_AHEAD: usize = 4;
/// A row tracks the task when its RMS error is at most this fraction of the motion's RMS.
const TRACKING_TOLERANCE: f64 = 0.1;
/// Hold before the task, in units of 1/ω_c: the controller takes up a load with its three
/// poles at ω_c (docs/design.md §11), so at soft settings (ω_c down to a few rad/s) the
/// energy figure's 0.2 s hold leaves the take-up in the averaged cycles. Measured with
/// `--beam-length 20mm --inertia 3.2e-3kgm2 --load 0.17Nm` at L = 15 mm (ω_c = 5.2 rad/s):
/// the link is within 1 mrad of its reference 3.9 s after the load is applied.
const SETTLE_BANDWIDTHS: f64 = 20.0;
/// Longest hold, ticks (ω_c ≥ 2 rad/s).
const MAX_SETTLE_TICKS: u32 = 10_000;
/// Start transient skipped before the averaged cycles, in units of 1/ω_c: the sine
/// starts with a step of velocity, and the slow loop of soft settings takes that long to
/// correct the position error it leaves. Measured on the hand check of
/// `cli/tests/advise.rs` at L = 15 mm (ω_c = 5.2 rad/s): the mean link error is still
/// 0.4–6 mrad between 1 and 2 s after the start and below 0.7 mrad after 1.9 s.
const SKIP_BANDWIDTHS: f64 = 10.0;

/// The clutch setting that saves energy for a periodic task (closed-loop simulation).
#[derive(Args, Debug, Default)]
#[command(
    after_help = "The task: the link follows AMPLITUDE·sin(2π·FREQUENCY·t), or one period \
of a recorded or planned trajectory repeated (--trajectory: a CSV of t_s,angle_rad rows, \
an optional header, times rising by at least 10 ms, ending where it starts; angles relative \
to the first), with an optional constant load. Design options as in `vsa design` (paper \
preset unless given). Values need units: 1e-3kgm2, 0.2rad, 2Hz, 0.2Nm, \
1mm..8mm:0.5mm.\n\nBad input: one line on stderr, exit code 2."
)]
pub struct AdviseArgs {
    /// The beam design.
    #[command(flatten)]
    pub beam: BeamArgs,
    /// Link inertia J_l [default: 1e-3kgm2]
    #[arg(long, value_name = "J", allow_hyphen_values = true)]
    pub inertia: Option<String>,
    /// Sine amplitude A of the link [default: 0.2rad]
    #[arg(long, value_name = "ANGLE", allow_hyphen_values = true)]
    pub amplitude: Option<String>,
    /// Sine frequency f [default: 1Hz]
    #[arg(long, value_name = "F", allow_hyphen_values = true)]
    pub frequency: Option<String>,
    /// Instead of the sine: one period of a trajectory, CSV `t_s,angle_rad` (see below)
    #[arg(long, value_name = "CSV", conflicts_with_all = ["amplitude", "frequency"])]
    pub trajectory: Option<PathBuf>,
    /// Constant load torque on the link (positive pushes the link positive) [default: 0Nm]
    #[arg(long, value_name = "T", allow_hyphen_values = true)]
    pub load: Option<String>,
    /// Gravity arm m·g·l of the link, e.g. 0.2Nm: the link hangs straight down at the
    /// task's centre and gravity pulls it back with −m·g·l·sin θ [default: 0Nm]
    #[arg(long, value_name = "M·G·L", allow_hyphen_values = true)]
    pub gravity: Option<String>,
    /// Clutch lengths: a list or START..END:STEP [default: 15 over t_c..l]
    #[arg(long, value_name = "LIST|RANGE", allow_hyphen_values = true)]
    pub lengths: Option<String>,
    /// Print one JSON object (SI units) instead of the table
    #[arg(long)]
    pub json: bool,
    /// Draw energy per cycle vs L to this .svg or .png
    #[arg(long, value_name = "FILE")]
    pub figure: Option<PathBuf>,
}

/// The task as parsed.
#[derive(Clone, Debug)]
struct Task {
    inertia: Inertia,
    amplitude_rad: f64,
    frequency_hz: f64,
    load_nm: f64,
    /// Gravity arm m·g·l, N·m (≥ 0).
    gravity_nm: f64,
    /// RMS of the motion about its mean, rad (the tracking tolerance's base).
    motion_rms_rad: f64,
    /// A trajectory instead of the sine.
    trajectory: Option<Trajectory>,
}

/// One clutch length.
#[derive(Clone, Copy, Debug)]
struct Row {
    length: Length,
    stiffness: f64,
    natural_hz: Option<f64>,
    run: Option<CycleEnergy>,
    within_capacity: Option<bool>,
    tracks: Option<bool>,
}

/// Runs `vsa advise`; returns what to print on stdout.
pub fn run(args: &AdviseArgs) -> CliResult<String> {
    let design = parse_design(&args.beam)?;
    let task = parse_task(args)?;
    let lengths = parse_lengths(args, &design)?;
    let cfg0 = config(&design, &task, design.adjustable_range().0)?;
    let j_red = reduced_inertia(&cfg0, task.inertia)?;
    let motion = motion(&task);
    let sigma = f(design.params().allowable_stress.get()) * 1e6;
    let mut rows = Vec::new();
    for &len in &lengths {
        let k = design
            .stiffness(len)
            .map_err(|e| CliError::usage("--lengths", e.to_string()))?;
        let natural_hz = if task.gravity_nm == 0.0 {
            model::natural_frequency(k, j_red)
                .ok()
                .map(|w| f(w.get()) / std::f64::consts::TAU)
        } else {
            let jg = f(cfg0.motor.rotor_inertia.get()) * 1e-6;
            let jl = f(task.inertia.get()) * 1e-6;
            Some(coupling_mode(k.get().to_num(), jg, jl, task.gravity_nm) / std::f64::consts::TAU)
        };
        let cfg = config(&design, &task, len)?;
        let motion = Motion {
            settle_ticks: bandwidths_ticks(&design, &cfg, SETTLE_BANDWIDTHS, SETTLE_TICKS),
            skip_ticks: bandwidths_ticks(&design, &cfg, SKIP_BANDWIDTHS, SKIP_TICKS),
            ..motion
        };
        let run = match &task.trajectory {
            None => energy_per_cycle(&design, &cfg, &motion),
            Some(tr) => match tr.command_at(0) {
                Some(first) => energy_of_commands(&design, &cfg, &motion, first, |n| tr.script(n)),
                None => Err("the trajectory's first move is out of range".into()),
            },
        }
        .map_err(CliError::runtime)?;
        let motion_rms = task.motion_rms_rad;
        rows.push(Row {
            length: len,
            stiffness: k.get().to_num(),
            natural_hz,
            run,
            within_capacity: run.map(|r| r.peak_stress_pa <= sigma),
            tracks: run.map(|r| r.periodic_rms_error_rad <= TRACKING_TOLERANCE * motion_rms),
        });
    }
    let advice = Advice::new(&design, &task, &cfg0, j_red, rows)?;
    if let Some(path) = &args.figure {
        advice.figure(&task, path)?;
    }
    if args.json {
        serde_json::to_string_pretty(&advice.to_json(&task, sigma))
            .map(|s| s + "\n")
            .map_err(|e| CliError::runtime(format!("cannot encode JSON: {e}")))
    } else {
        Ok(advice.render(&task, sigma))
    }
}

fn f(x: I32F32) -> f64 {
    x.to_num()
}

fn parse_task(a: &AdviseArgs) -> CliResult<Task> {
    let inertia = Inertia::from_fixed(positive(
        "--inertia",
        a.inertia.as_deref(),
        "1e-3kgm2",
        Kind::Inertia,
    )?);
    let amplitude = positive("--amplitude", a.amplitude.as_deref(), "0.2rad", Kind::Angle)?;
    let frequency = positive(
        "--frequency",
        a.frequency.as_deref(),
        "1Hz",
        Kind::Frequency,
    )?;
    let max_hz = f64::from(model::control::trajectory::MAX_SINE_RAD_S) / std::f64::consts::TAU;
    if f(frequency) > max_hz {
        return Err(CliError::usage(
            "--frequency",
            format!(
                "{} Hz is above the controller's {} Hz",
                sig(f(frequency), 4),
                sig(max_hz, 3)
            ),
        ));
    }
    let load_s = a.load.as_deref().unwrap_or("0Nm");
    let load = units::parse(load_s, Kind::Torque).map_err(|e| CliError::usage("--load", e))?;
    let load_nm = load
        .value
        .to_i32f32()
        .map(|v| if load.value.negative { -f(v) } else { f(v) })
        .filter(|v| v.abs() <= 100.0)
        .ok_or_else(|| {
            CliError::usage("--load", format!("{load} is out of range [-100, 100] N·m"))
        })?;
    let gravity_nm = match a.gravity.as_deref() {
        None => 0.0,
        Some(s) => {
            let g = units::parse(s, Kind::Torque).map_err(|e| CliError::usage("--gravity", e))?;
            g.value
                .to_i32f32()
                .map(f)
                .filter(|v| !g.value.negative && *v <= 100.0)
                .ok_or_else(|| {
                    CliError::usage(
                        "--gravity",
                        format!("{g} is out of range [0, 100] N·m (m·g·l of a hanging link)"),
                    )
                })?
        }
    };
    if let Some(path) = &a.trajectory {
        let samples = read_trajectory(path)?;
        let period = samples.period_ticks;
        let mean = samples.points.iter().map(|p| p.1).sum::<f64>() / samples.points.len() as f64;
        // The samples' spread stands for the motion's (piecewise, by sample time).
        let mut sq = 0.0;
        let mut amp: f64 = 0.0;
        for (i, &(t, x)) in samples.points.iter().enumerate() {
            let next = samples.points.get(i + 1).map_or(period, |p| p.0);
            sq += (x - mean).powi(2) * f64::from(next - t);
            amp = amp.max(x.abs());
        }
        return Ok(Task {
            inertia,
            amplitude_rad: amp,
            frequency_hz: 1000.0 / f64::from(period),
            load_nm,
            gravity_nm,
            motion_rms_rad: (sq / f64::from(period)).sqrt(),
            trajectory: Some(samples),
        });
    }
    Ok(Task {
        inertia,
        amplitude_rad: f(amplitude),
        frequency_hz: f(frequency),
        load_nm,
        gravity_nm,
        motion_rms_rad: f(amplitude) / std::f64::consts::SQRT_2,
        trajectory: None,
    })
}

impl Task {
    /// The gravity load in words (empty without one).
    fn gravity_text(&self) -> String {
        if self.gravity_nm == 0.0 {
            String::new()
        } else {
            format!(
                ", gravity m·g·l = {} N·m (hanging at the task's centre)",
                sig(self.gravity_nm, 4)
            )
        }
    }

    /// The motion in words.
    fn describe(&self) -> String {
        match &self.trajectory {
            None => format!(
                "sine {} rad at {} Hz",
                sig(self.amplitude_rad, 4),
                sig(self.frequency_hz, 4)
            ),
            Some(t) => format!(
                "trajectory of {} samples, period {} s ({} Hz), up to {} rad from its start",
                t.points.len() + 1,
                sig(f64::from(t.period_ticks) / 1000.0, 4),
                sig(self.frequency_hz, 4),
                sig(self.amplitude_rad, 3)
            ),
        }
    }
}

/// One period of a trajectory: (tick from its start, angle relative to its first sample),
/// the last sample (back at the first angle) dropped, and the period in ticks.
#[derive(Clone, Debug)]
struct Trajectory {
    points: Vec<(u32, f64)>,
    period_ticks: u32,
}

impl Trajectory {
    /// The move planned at sample `i` (of the periodic sequence): a minimum-jerk move to the
    /// sample two ahead, due at that sample's time. Re-planned at every sample, so the
    /// reference passes each sample moving instead of stopping at it.
    fn command_at(&self, i: usize) -> Option<Command> {
        let n = self.points.len();
        let (t0, _) = self.points[i % n];
        let j = i + LOOK_AHEAD;
        let (tj, xj) = self.points[j % n];
        let tj = tj + self.period_ticks * (j / n - i / n) as u32;
        Some(Command::Move {
            target: Angle::from_micro((xj * 1e6).round() as i64).ok()?,
            duration_ms: tj - t0,
        })
    }

    /// The command `n` ticks after the start, if a sample falls there.
    fn script(&self, n: u32) -> Option<Command> {
        let k = n % self.period_ticks;
        let i = self.points.binary_search_by_key(&k, |p| p.0).ok()?;
        self.command_at(i)
    }
}

fn read_trajectory(path: &std::path::Path) -> CliResult<Trajectory> {
    const ARG: &str = "--trajectory";
    let text = std::fs::read_to_string(path)
        .map_err(|e| CliError::usage(ARG, format!("{}: {e}", path.display())))?;
    let bad = |line: usize, why: String| CliError::usage(ARG, format!("line {line}: {why}"));
    let mut raw: Vec<(f64, f64)> = Vec::new();
    for (no, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() {
            continue;
        }
        let cells: Vec<&str> = line.split(',').map(str::trim).collect();
        let nums: Option<Vec<f64>> = cells.iter().map(|c| c.parse::<f64>().ok()).collect();
        match nums {
            None if raw.is_empty() && no == 0 => continue, // a header
            Some(v) if v.len() == 2 && v.iter().all(|x| x.is_finite()) => raw.push((v[0], v[1])),
            _ => {
                return Err(bad(
                    no + 1,
                    format!("'{line}' is not two numbers t_s,angle_rad"),
                ))
            }
        }
    }
    if raw.len() < 3 {
        return Err(CliError::usage(
            ARG,
            "a period needs at least 3 samples t_s,angle_rad",
        ));
    }
    let (t0, x0) = raw[0];
    let max_rad = f64::from(model::control::trajectory::MAX_ANGLE_RAD) / 10.0;
    let mut points = Vec::with_capacity(raw.len());
    for (i, &(t, x)) in raw.iter().enumerate() {
        let tick = ((t - t0) * 1000.0).round();
        let rel = x - x0;
        if rel.abs() > max_rad {
            return Err(bad(
                i + 1,
                format!("{x} rad is more than {max_rad} rad from the first sample"),
            ));
        }
        if !(0.0..=600_000.0).contains(&tick) {
            return Err(bad(
                i + 1,
                format!("{t} s is outside the first 600 s of the file"),
            ));
        }
        let tick = tick as u32;
        if let Some(&(prev, _)) = points.last() {
            let step: u32 = tick.saturating_sub(prev);
            if tick <= prev || step < model::control::trajectory::MIN_MOVE_MS {
                return Err(bad(
                    i + 1,
                    format!(
                        "samples must be at least {} ms apart, in rising time",
                        model::control::trajectory::MIN_MOVE_MS
                    ),
                ));
            }
        }
        points.push((tick, rel));
    }
    let (period_ticks, last) = points.pop().unwrap_or((0, 0.0));
    if last.abs() > 1e-6 {
        return Err(CliError::usage(
            ARG,
            format!(
                "one period must end where it starts (last angle {} rad from the first)",
                sig(last, 3)
            ),
        ));
    }
    Ok(Trajectory {
        points,
        period_ticks,
    })
}

fn parse_lengths(a: &AdviseArgs, d: &Design) -> CliResult<Vec<Length>> {
    let (lo, hi) = d.adjustable_range();
    let Some(s) = a.lengths.as_deref() else {
        let (a, b) = (i128::from(lo.to_bits()), i128::from(hi.to_bits()));
        let n = i128::from(DEFAULT_ROWS - 1);
        return Ok((0..=n)
            .map(|i| Length::from_bits((a + (b - a) * i / n) as i64))
            .collect());
    };
    let v = units::parse_list(s, Kind::Length, MAX_ROWS, "lengths")
        .map_err(|e| CliError::usage("--lengths", e))?;
    v.into_iter()
        .map(|dec| {
            let len = Length::from_fixed(dec.to_i32f32_saturating());
            if dec.negative || len < lo || len > hi {
                Err(CliError::usage(
                    "--lengths",
                    format!(
                        "{dec} mm is outside the adjustable range [t_c, l] = [{}, {}] mm",
                        sig(f(lo.get()), 4),
                        sig(f(hi.get()), 4)
                    ),
                ))
            } else {
                Ok(len)
            }
        })
        .collect()
}

/// The controller's configuration for the task at clutch length `len` (paper preset
/// otherwise: AX-12A motor, default limits, scheduled gains).
fn config(d: &Design, task: &Task, len: Length) -> CliResult<Config> {
    let mut cfg = Config::paper(len);
    cfg.link_inertia = task.inertia;
    model::control::Schedule::new(d, &cfg)
        .map(|_| cfg)
        .or_else(|e| match e {
            model::ControlError::InertiaOutOfRange => Err(CliError::usage(
                "--inertia",
                format!(
                    "{} kg·m² is out of the controller's range [{}, {}] kg·m²",
                    sig(f(task.inertia.get()) * 1e-6, 4),
                    sig(f64::from(model::control::MIN_INERTIA) * 1e-6, 3),
                    sig(f64::from(model::control::MAX_INERTIA) * 1e-6, 3)
                ),
            )),
            // Other rejections depend on the setting: that row is null.
            _ => Ok(cfg),
        })
}

/// The coupling mode with gravity, rad/s: the larger root ω² of
/// J_g·J_l·ω⁴ − (k·(J_g + J_l) + J_g·G)·ω² + G·k = 0 (the frequencies at which the
/// lossless two-mass model needs no motor torque, G = m·g·l; SI units). Without gravity
/// it is √(k/J_r), [`model::natural_frequency`]. f64: the gravity case only (host side).
fn coupling_mode(k: f64, jg: f64, jl: f64, g: f64) -> f64 {
    let (a, b, c) = (jg * jl, k * (jg + jl) + jg * g, g * k);
    ((b + (b * b - 4.0 * a * c).max(0.0).sqrt()) / (2.0 * a)).sqrt()
}

/// The stiffness at which the lossless two-mass model needs no motor torque to make the
/// link follow a sine of ω: T_m ∝ (G − J_l·ω²)·(1 − J_g·ω²/k) − J_g·ω² = 0, so
/// k = J_g·ω²·(G − J_l·ω²)/(G − (J_g + J_l)·ω²) (G = m·g·l; J_r·ω² when G = 0); `None`
/// when no positive stiffness does it (G between J_l·ω² and (J_g + J_l)·ω²). SI units.
fn stiffness_for_task(omega: f64, jg: f64, jl: f64, g: f64) -> Option<f64> {
    let w2 = omega * omega;
    let k = jg * w2 * (g - jl * w2) / (g - (jg + jl) * w2);
    (k.is_finite() && k > 0.0).then_some(k)
}

/// J_r = J_g·J_l/(J_g + J_l), kg·mm² (J_g: the configured gear-side inertia).
fn reduced_inertia(cfg: &Config, j_link: Inertia) -> CliResult<Inertia> {
    let jg = f(cfg.motor.rotor_inertia.get());
    let jl = f(j_link.get());
    let jr = jg * jl / (jg + jl);
    I32F32::checked_from_num(jr)
        .filter(|v| *v > I32F32::ZERO)
        .map(Inertia::from_fixed)
        .ok_or_else(|| CliError::usage("--inertia", "the reduced inertia is out of range"))
}

fn motion(task: &Task) -> Motion {
    let period_ticks = task.trajectory.as_ref().map(|t| t.period_ticks);
    Motion {
        key: "advise",
        amplitude_rad: task.amplitude_rad,
        frequency_hz: task.frequency_hz,
        load_nm: task.load_nm,
        gravity_nm: task.gravity_nm,
        cycles: match period_ticks {
            // Whole periods of the trajectory, at least AVERAGED_S.
            Some(p) => (AVERAGED_S * 1000.0 / f64::from(p)).ceil().max(1.0) as u32,
            None => (AVERAGED_S * task.frequency_hz).ceil().max(1.0) as u32,
        },
        settle_ticks: SETTLE_TICKS,
        skip_ticks: SKIP_TICKS,
    }
}

/// Ticks of `n`/ω_c at the setting `cfg` (ω_c the controller's scheduled bandwidth,
/// [`Schedule::bandwidth`]), at least `least` (the energy figure's hold or skip) and at
/// most [`MAX_SETTLE_TICKS`]; `least` for a setting the controller rejects.
fn bandwidths_ticks(d: &Design, cfg: &Config, n: f64, least: u32) -> u32 {
    Schedule::new(d, cfg).map_or(least, |s| {
        let w = f(s.bandwidth().get());
        let ticks = (n / w * 1000.0).ceil();
        if ticks.is_finite() && ticks > f64::from(least) {
            ticks.min(f64::from(MAX_SETTLE_TICKS)) as u32
        } else {
            least
        }
    })
}

/// "Resonance … is out of reach": `k` needed, `ratio` times `way` than the end `end_k` at
/// L = `end`.
fn out_of_reach(
    task: &Task,
    formula: &str,
    k: f64,
    ratio: f64,
    way: &str,
    end_k: f64,
    end: &str,
) -> String {
    let side = if way == "softer" {
        "softest"
    } else {
        "stiffest"
    };
    format!(
        "Resonance with the task ({} Hz) is out of reach: it needs k = {formula} = {} N·m/rad, \
{} times {way} than the {side} setting ({} N·m/rad at L = {end}).",
        sig(task.frequency_hz, 4),
        sig(k, 3),
        sig(ratio, 3),
        sig(end_k, 4)
    )
}

/// The rows and what they mean.
struct Advice {
    rows: Vec<Row>,
    best: Option<usize>,
    /// Where the setting that needs no motor torque for the task lies; `None` when no
    /// positive stiffness does it (gravity, see [`stiffness_for_task`]).
    tuning: Option<Tuning>,
    /// The formula of the stiffness needed, as printed.
    formula: &'static str,
    stiffness_range: (f64, f64),
}

#[derive(Serialize)]
struct JsonRow {
    length_m: f64,
    stiffness_nm_per_rad: f64,
    natural_frequency_hz: Option<f64>,
    energy_per_cycle_j: Option<f64>,
    copper_loss_j: Option<f64>,
    rms_error_rad: Option<f64>,
    offset_rad: Option<f64>,
    limited: Option<bool>,
    peak_stress_pa: Option<f64>,
    safety_factor: Option<f64>,
    within_capacity: Option<bool>,
    tracks: Option<bool>,
}

#[derive(Serialize)]
struct JsonTask {
    inertia_kg_m2: f64,
    amplitude_rad: f64,
    frequency_hz: f64,
    load_nm: f64,
    gravity_nm: f64,
}

#[derive(Serialize)]
struct JsonAdvice {
    task: JsonTask,
    rows: Vec<JsonRow>,
    best_length_m: Option<f64>,
    best_reason: String,
    resonance_reachable: bool,
    resonance_length_m: Option<f64>,
    stiffness_needed_nm_per_rad: Option<f64>,
    stiffness_range_nm_per_rad: [f64; 2],
}

impl Advice {
    fn new(
        d: &Design,
        task: &Task,
        cfg: &Config,
        j_red: Inertia,
        rows: Vec<Row>,
    ) -> CliResult<Advice> {
        let omega = Frequency::from_hz(I32F32::from_num(task.frequency_hz))
            .map_err(|e| CliError::usage("--frequency", e.to_string()))?;
        // The inertia whose k = J·ω² is the stiffness the task needs: J_r without gravity.
        let (j_tune, formula) = if task.gravity_nm == 0.0 {
            (Some(j_red), "J_r·ω²")
        } else {
            let w = f(omega.get());
            let jg = f(cfg.motor.rotor_inertia.get()) * 1e-6;
            let jl = f(task.inertia.get()) * 1e-6;
            let j = stiffness_for_task(w, jg, jl, task.gravity_nm)
                .and_then(|k| I32F32::checked_from_num(k / (w * w) * 1e6))
                .map(Inertia::from_fixed);
            (j, "J_g·ω²·(m·g·l − J_l·ω²)/(m·g·l − (J_g + J_l)·ω²)")
        };
        let tuning = j_tune
            .map(|j| d.tune(j, omega, BeamModel::EulerBernoulli))
            .transpose()
            .map_err(|e| CliError::usage("--frequency", e.to_string()))?;
        let (soft, stiff) = d.stiffness_range(BeamModel::EulerBernoulli);
        let best = rows
            .iter()
            .enumerate()
            .filter(|(_, r)| r.within_capacity == Some(true) && r.tracks == Some(true))
            .filter_map(|(i, r)| r.run.map(|e| (i, e.electrical_j)))
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .map(|(i, _)| i);
        Ok(Advice {
            rows,
            best,
            tuning,
            formula,
            stiffness_range: (soft.get().to_num(), stiff.get().to_num()),
        })
    }

    fn stiffest(&self) -> Option<&Row> {
        self.rows
            .iter()
            .filter(|r| r.run.is_some())
            .min_by(|a, b| a.length.cmp(&b.length))
    }

    fn reason(&self) -> String {
        let Some(b) = self.best.map(|i| &self.rows[i]) else {
            return "no setting both stays within the beams' capacity and tracks the task".into();
        };
        let e = b.run.map_or(0.0, |r| r.electrical_j);
        let mut s = format!(
            "L = {} mm uses the least energy per cycle ({} J) of the settings within capacity \
that track the task",
            sig(f(b.length.get()), 4),
            sig(e, 3)
        );
        if let Some(st) = self.stiffest().and_then(|r| r.run) {
            if st.electrical_j > 0.0 {
                s.push_str(&format!(
                    "; {} % {} than at the stiffest setting",
                    sig((1.0 - e / st.electrical_j).abs() * 100.0, 3),
                    if e <= st.electrical_j { "less" } else { "more" }
                ));
            }
        }
        if let Some(fn_hz) = b.natural_hz {
            s.push_str(&format!("; its natural frequency is {} Hz", sig(fn_hz, 3)));
        }
        s
    }

    fn resonance_text(&self, task: &Task) -> String {
        let Some(tuning) = self.tuning else {
            return format!(
                "Resonance with the task ({} Hz) is out of reach at any stiffness: with \
gravity m·g·l = {} N·m between J_l·ω² and (J_g + J_l)·ω², k = {} would be negative.",
                sig(task.frequency_hz, 4),
                sig(task.gravity_nm, 4),
                self.formula
            );
        };
        let k = tuning.stiffness().get().to_num::<f64>();
        let (soft, stiff) = self.stiffness_range;
        let formula = self.formula;
        match tuning {
            Tuning::InRange { length, .. } => format!(
                "Resonance with the task ({} Hz) is reachable: k = {formula} = {} N·m/rad at \
L = {} mm.",
                sig(task.frequency_hz, 4),
                sig(k, 4),
                sig(f(length.get()), 4)
            ),
            Tuning::TooSoft { .. } => out_of_reach(task, formula, k, soft / k, "softer", soft, "l"),
            Tuning::TooStiff { .. } => {
                out_of_reach(task, formula, k, k / stiff, "stiffer", stiff, "t_c")
            }
        }
    }

    fn to_json(&self, task: &Task, sigma: f64) -> JsonAdvice {
        JsonAdvice {
            task: JsonTask {
                inertia_kg_m2: f(task.inertia.get()) * 1e-6,
                amplitude_rad: task.amplitude_rad,
                frequency_hz: task.frequency_hz,
                load_nm: task.load_nm,
                gravity_nm: task.gravity_nm,
            },
            rows: self
                .rows
                .iter()
                .map(|r| JsonRow {
                    length_m: f(r.length.get()) * 1e-3,
                    stiffness_nm_per_rad: r.stiffness,
                    natural_frequency_hz: r.natural_hz,
                    energy_per_cycle_j: r.run.map(|e| e.electrical_j),
                    copper_loss_j: r.run.map(|e| e.copper_j),
                    rms_error_rad: r.run.map(|e| e.periodic_rms_error_rad),
                    offset_rad: r.run.map(|e| e.mean_error_rad),
                    limited: r.run.map(|e| e.limited),
                    peak_stress_pa: r.run.map(|e| e.peak_stress_pa),
                    safety_factor: r
                        .run
                        .filter(|e| e.peak_stress_pa > 0.0)
                        .map(|e| sigma / e.peak_stress_pa),
                    within_capacity: r.within_capacity,
                    tracks: r.tracks,
                })
                .collect(),
            best_length_m: self.best.map(|i| f(self.rows[i].length.get()) * 1e-3),
            best_reason: self.reason(),
            resonance_reachable: matches!(self.tuning, Some(Tuning::InRange { .. })),
            resonance_length_m: match self.tuning {
                Some(Tuning::InRange { length, .. }) => Some(f(length.get()) * 1e-3),
                _ => None,
            },
            stiffness_needed_nm_per_rad: self.tuning.map(|t| t.stiffness().get().to_num()),
            stiffness_range_nm_per_rad: [self.stiffness_range.0, self.stiffness_range.1],
        }
    }

    fn render(&self, task: &Task, sigma: f64) -> String {
        let mut out = format!(
            "Task: link {} kg·m², {}, load {} N·m{}; closed loop (vsa simulate's controller and \
simulated actuator), energies averaged over whole cycles.\n",
            sig(f(task.inertia.get()) * 1e-6, 4),
            task.describe(),
            sig(task.load_nm, 4),
            task.gravity_text()
        );
        let mut t = Table::new(&[
            ("L", "mm"),
            ("k", "N·m/rad"),
            ("f_n", "Hz"),
            ("energy/cycle", "J"),
            ("copper", "J"),
            ("RMS error", "mrad"),
            ("offset", "mrad"),
            ("peak σ", "MPa"),
            ("safety", ""),
            ("within capacity", ""),
            ("tracks", ""),
            ("", ""),
        ]);
        let o = |x: Option<f64>, n: usize| x.map_or_else(|| "–".to_string(), |v| sig(v, n));
        for (i, r) in self.rows.iter().enumerate() {
            let e = r.run;
            t.row(vec![
                sig(f(r.length.get()), 4),
                sig(r.stiffness, 4),
                o(r.natural_hz, 3),
                o(e.map(|e| e.electrical_j), 4),
                o(e.map(|e| e.copper_j), 4),
                o(e.map(|e| e.periodic_rms_error_rad * 1e3), 3),
                o(e.map(|e| e.mean_error_rad * 1e3), 3),
                o(e.map(|e| e.peak_stress_pa * 1e-6), 4),
                o(
                    e.filter(|e| e.peak_stress_pa > 0.0)
                        .map(|e| sigma / e.peak_stress_pa),
                    3,
                ),
                r.within_capacity
                    .map_or("–".into(), |b| if b { "yes" } else { "NO" }.into()),
                r.tracks
                    .map_or("–".into(), |b| if b { "yes" } else { "NO" }.into()),
                if Some(i) == self.best { "← best" } else { "" }.into(),
            ]);
        }
        out.push_str(&t.render());
        out.push_str(&format!("\nBest: {}.\n", self.reason()));
        out.push_str(&self.resonance_text(task));
        out.push('\n');
        out
    }

    fn figure(&self, task: &Task, path: &std::path::Path) -> CliResult<()> {
        crate::figures::plot::register_font().map_err(CliError::runtime)?;
        let pts = |g: fn(&CycleEnergy) -> f64| -> Vec<(f64, f64)> {
            self.rows
                .iter()
                .filter_map(|r| r.run.map(|e| (f(r.length.get()), g(&e))))
                .collect()
        };
        let energy = pts(|e| e.electrical_j);
        let top = energy.iter().map(|p| p.1).fold(0.0, f64::max);
        let mut series = vec![
            Series {
                label: Some("motor energy per cycle ∮V·i dt (closed loop)".into()),
                points: energy,
                color: COLORS[0],
                dashed: false,
                marker: false,
            },
            Series {
                label: Some("copper loss ∮R·i² dt".into()),
                points: pts(|e| e.copper_j),
                color: COLORS[1],
                dashed: true,
                marker: false,
            },
        ];
        if let Some(Tuning::InRange { length, .. }) = self.tuning {
            let x = f(length.get());
            series.push(Series {
                label: Some(format!("resonance with the task, L = {} mm", sig(x, 3))),
                points: vec![(x, 0.0), (x, top)],
                color: COLORS[3],
                dashed: true,
                marker: false,
            });
        }
        if let Some(b) = self.best.map(|i| &self.rows[i]) {
            series.push(Series {
                label: Some(format!(
                    "best setting, L = {} mm",
                    sig(f(b.length.get()), 3)
                )),
                points: b
                    .run
                    .map(|e| vec![(f(b.length.get()), e.electrical_j)])
                    .unwrap_or_default(),
                color: COLORS[2],
                dashed: false,
                marker: true,
            });
        }
        let fig = Figure {
            title: format!(
                "Energy per cycle vs clutch length — link {} kg·m², {}, load {} N·m{}",
                sig(f(task.inertia.get()) * 1e-6, 3),
                task.describe(),
                sig(task.load_nm, 3),
                task.gravity_text()
            ),
            panels: vec![Panel {
                caption: self.resonance_text(task),
                x_label: "clutch length L (mm)".into(),
                y_label: "energy per cycle (J)".into(),
                log_y: false,
                y_zero: true,
                headroom: 0.3,
                x_margin: 0.02,
                series,
                legend: SeriesLabelPosition::UpperRight,
            }],
            size: (1300, 700),
        };
        crate::explore::write_atomic(path, |tmp| fig.write_file(tmp, false))
    }
}
