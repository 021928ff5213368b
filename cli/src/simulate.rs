//! `vsa simulate`: the closed loop on the host — the fixed-point controller of the `model`
//! crate driving the simulated actuator of the `plant` crate (`plant::harness`) — with the
//! step-response and tracking metrics, a CSV of every tick and a JSON summary.
//!
//! ```text
//! vsa simulate [--clutch-length 3mm | --stiffness 250Nm/rad] [--inertia 1e-3] [--load 0.3Nm]
//!              (--step 0.5rad | --move 0.5rad:200ms | --sine 0.2rad:1Hz
//!               | --impedance 0.3rad:20Nm/rad:0.2Nms/rad[:0.1Nm])
//!              [--seconds 2] [--csv FILE] [--json] [--no-pot] [--settle 0.5]
//!              [--boot-under-load] [--plant NAME=VALUE]...
//! ```
//!
//! `--impedance` holds the target with a virtual stiffness, damping and feed-forward torque
//! (`model::control::impedance`); the report adds the link's deflection at rest against
//! (load + τ_ff)/k_v.
//!
//! `--plant` makes the simulated actuator off-nominal (`plant::overrides`: e.g.
//! `resistance=x1.3`, `supply=11.8V`, `pot-offset=3`); the controller keeps its nominal
//! configuration.
//!
//! The run holds for `--settle` seconds with the load applied (the coupling starts
//! deflected by it, the board's boot window passed with the actuator held, unless
//! `--boot-under-load`), gives the command, and runs `--seconds` more. Metrics are computed
//! from the plant's true state. Quantities accept a unit suffix (see [`parse`]); the
//! parsing here is deliberately minimal until it moves to the shared `units` module.

use std::fs::File;
use std::io::{BufWriter, Write};

use client::protocol::TARGET_MAX_URAD;
use model::control::{ClutchSetting, Command, Config, ControlError, ImpedanceCommand};
use model::{Angle, Design, Frequency, Inertia, Length, Stiffness, Torque};
use plant::harness::{self, Metrics, Sample, Scenario};
use plant::overrides::Overrides;

use crate::board::LOAD_MAX_MNM;
use crate::output;

/// Arguments of `vsa simulate`.
#[derive(clap::Args, Debug, Clone)]
#[command(group(clap::ArgGroup::new("command").required(true).args(["step", "move_to", "sine", "impedance"])))]
pub struct SimulateArgs {
    /// Clutch (active beam) length, e.g. `3mm` (default 3 mm).
    #[arg(long, value_name = "LENGTH", conflicts_with = "stiffness")]
    pub clutch_length: Option<String>,
    /// Wanted joint stiffness instead of a length, e.g. `250Nm/rad`.
    #[arg(long, value_name = "STIFFNESS")]
    pub stiffness: Option<String>,
    /// How much longer than configured the hand-set clutch may be, e.g. `0.6mm` (0 to
    /// 5 mm, default 0): the controller's torque limit and the overload check use the
    /// beams' capacity at that longer length.
    #[arg(long, value_name = "LENGTH", default_value = "0mm")]
    pub clutch_tolerance: String,
    /// Do not run the clutch monitor (stiffness estimate, `clutch-mismatch`), which runs
    /// whenever the clutch tolerance is above 0: the overload check keeps the tolerance's
    /// weak capacity.
    #[arg(long)]
    pub no_clutch_monitor: bool,
    /// Link inertia, kg·m² (e.g. `1e-3`; a `kgm2` / `kg·m²` suffix is accepted).
    #[arg(long, value_name = "KG_M2", default_value = "1e-3")]
    pub inertia: String,
    /// Constant load torque on the link, e.g. `0.3Nm` (positive pushes the link positive).
    #[arg(
        long,
        value_name = "TORQUE",
        default_value = "0Nm",
        allow_hyphen_values = true
    )]
    pub load: String,
    /// Raw step to an absolute link angle, e.g. `0.5rad` or `30deg`.
    #[arg(long, value_name = "ANGLE", allow_hyphen_values = true)]
    pub step: Option<String>,
    /// Minimum-jerk move `ANGLE:DURATION`, e.g. `0.5rad:200ms`.
    #[arg(
        long = "move",
        value_name = "ANGLE:DURATION",
        allow_hyphen_values = true
    )]
    pub move_to: Option<String>,
    /// Sine about the start position `AMPLITUDE:FREQUENCY`, e.g. `0.2rad:1Hz`.
    #[arg(long, value_name = "AMPLITUDE:FREQUENCY", allow_hyphen_values = true)]
    pub sine: Option<String>,
    /// Impedance command `ANGLE:STIFFNESS:DAMPING[:TORQUE]`: hold the angle with a virtual
    /// stiffness (at most the joint's), damping and feed-forward torque, e.g.
    /// `0.3rad:20Nm/rad:0.2Nms/rad` or `0.3rad:20Nm/rad:0.2Nms/rad:0.1Nm`.
    #[arg(long, value_name = "A:K:D[:T]", allow_hyphen_values = true)]
    pub impedance: Option<String>,
    /// Run time after the command, s.
    #[arg(long, value_name = "S", default_value = "2")]
    pub seconds: String,
    /// Hold time before the command, s.
    #[arg(long, value_name = "S", default_value = "0.5")]
    pub settle: String,
    /// Write every tick to this CSV file.
    #[arg(long, value_name = "FILE")]
    pub csv: Option<std::path::PathBuf>,
    /// Print the metrics as JSON.
    #[arg(long)]
    pub json: bool,
    /// Run without the gear potentiometer (torque estimate from the current only).
    #[arg(long)]
    pub no_pot: bool,
    /// Power the board up with the load already hanging: the link falls while the boot
    /// window (32 ms, bridge off) measures the current offset and aligns the encoder; by
    /// default the window passes with the actuator held and the hold starts powered
    #[arg(long)]
    pub boot_under_load: bool,
    /// Change the simulated actuator (not the controller's model): `NAME=VALUE`, VALUE
    /// absolute with its unit or a factor `xF` of the nominal value; repeatable. Names:
    /// resistance (ohm), torque-constant (Nm/A), back-emf (Vs/rad), gear-inertia (kgm2),
    /// gear-friction (Nm), supply (V), current-offset (counts), current-gain (factor),
    /// pot-offset (counts), link-inertia (kgm2), link-friction (Nm), clutch (mm: the
    /// actual clutch length, whatever the controller was told).
    #[arg(long = "plant", value_name = "NAME=VALUE", allow_hyphen_values = true)]
    pub plant: Vec<String>,
}

/// A value and its unit suffix parsed from `s`: `"0.5rad"` → (0.5, "rad").
fn split_unit(s: &str) -> Result<(f64, String), String> {
    let s = s.trim();
    let end = s
        .char_indices()
        .find(|&(i, c)| {
            !(c.is_ascii_digit()
                || c == '.'
                || ((c == '-' || c == '+') && (i == 0 || s[..i].ends_with(['e', 'E'])))
                || ((c == 'e' || c == 'E')
                    && i > 0
                    && s[i + c.len_utf8()..]
                        .chars()
                        .next()
                        .is_some_and(|n| n.is_ascii_digit() || n == '-' || n == '+')))
        })
        .map_or(s.len(), |(i, _)| i);
    let v: f64 = s[..end]
        .parse()
        .map_err(|_| format!("`{s}`: not a number"))?;
    if !v.is_finite() {
        return Err(format!("`{s}`: not a finite number"));
    }
    let unit: String = s[end..].chars().filter(|c| !c.is_whitespace()).collect();
    Ok((v, unit))
}

/// Parses `s` as a quantity with one of `units` (suffix, factor to the base unit); an
/// empty suffix takes the first unit.
pub fn parse(s: &str, what: &str, units: &[(&str, f64)]) -> Result<f64, String> {
    let (v, unit) = split_unit(s).map_err(|e| format!("{what} {e}"))?;
    if unit.is_empty() {
        return Ok(v * units.first().map_or(1.0, |u| u.1));
    }
    units
        .iter()
        .find(|(u, _)| u.eq_ignore_ascii_case(&unit))
        .map(|(_, f)| v * f)
        .ok_or_else(|| {
            let known: Vec<&str> = units.iter().map(|u| u.0).collect();
            format!(
                "{what} `{s}`: unknown unit `{unit}` (use {})",
                known.join(", ")
            )
        })
}

const LENGTH_MM: &[(&str, f64)] = &[("mm", 1.0), ("m", 1000.0), ("um", 1e-3), ("µm", 1e-3)];
const STIFFNESS: &[(&str, f64)] = &[("Nm/rad", 1.0), ("N·m/rad", 1.0), ("N.m/rad", 1.0)];
const TORQUE: &[(&str, f64)] = &[("Nm", 1.0), ("N·m", 1.0), ("N.m", 1.0), ("mNm", 1e-3)];
const ANGLE: &[(&str, f64)] = &[
    ("rad", 1.0),
    ("mrad", 1e-3),
    ("deg", std::f64::consts::PI / 180.0),
    ("°", std::f64::consts::PI / 180.0),
];
const TIME_S: &[(&str, f64)] = &[("s", 1.0), ("ms", 1e-3)];
const FREQ_RAD_S: &[(&str, f64)] = &[("Hz", std::f64::consts::TAU), ("rad/s", 1.0)];
const DAMPING: &[(&str, f64)] = &[
    ("Nms/rad", 1.0),
    ("N·m·s/rad", 1.0),
    ("N.m.s/rad", 1.0),
    ("mNms/rad", 1e-3),
];
const INERTIA: &[(&str, f64)] = &[
    ("kgm2", 1.0),
    ("kg·m²", 1.0),
    ("kg.m2", 1.0),
    ("kgmm2", 1e-6),
];

fn micro(v: f64, what: &str) -> Result<i64, String> {
    let m = (v * 1e6).round();
    if m.abs() < 9.0e15 {
        Ok(m as i64)
    } else {
        Err(format!("{what}: {v} is out of range"))
    }
}

/// A commanded angle, within what the actuator's gear pot measures (the board's bound).
fn angle(v: f64, what: &str) -> Result<Angle, String> {
    let max = f64::from(TARGET_MAX_URAD) / 1e6;
    if !(-max..=max).contains(&v) {
        return Err(format!(
            "{what}: {v} rad is outside ±{max} rad (what the gear pot measures)"
        ));
    }
    Angle::from_micro(micro(v, what)?).map_err(|e| format!("{what}: {e}"))
}

fn pair<'a>(s: &'a str, what: &str) -> Result<(&'a str, &'a str), String> {
    s.split_once(':')
        .ok_or_else(|| format!("{what} `{s}`: expected `A:B`, e.g. `0.5rad:200ms`"))
}

/// The controller configuration for the arguments (paper preset design).
fn config(args: &SimulateArgs) -> Result<Config, String> {
    let mut cfg = Config::paper(Length::from_int(3));
    if let Some(k) = &args.stiffness {
        let k = parse(k, "--stiffness", STIFFNESS)?;
        cfg.clutch = ClutchSetting::Stiffness(Stiffness::from_micro(micro(k, "--stiffness")?));
    } else if let Some(l) = &args.clutch_length {
        let l = parse(l, "--clutch-length", LENGTH_MM)?;
        cfg.clutch = ClutchSetting::Length(
            Length::from_micro(micro(l, "--clutch-length")?)
                .map_err(|e| format!("--clutch-length: {e}"))?,
        );
    }
    let j = parse(&args.inertia, "--inertia", INERTIA)? * 1e6; // kg·mm²
    cfg.link_inertia =
        Inertia::from_micro(micro(j, "--inertia")?).map_err(|e| format!("--inertia: {e}"))?;
    let tol = parse(&args.clutch_tolerance, "--clutch-tolerance", LENGTH_MM)?;
    let max = model::control::MAX_CLUTCH_TOLERANCE_MM;
    if !(0.0..=f64::from(max)).contains(&tol) {
        return Err(format!(
            "--clutch-tolerance: {tol} mm is outside 0 to {max} mm"
        ));
    }
    cfg.limits.clutch_tolerance = Length::from_micro(micro(tol, "--clutch-tolerance")?)
        .map_err(|e| format!("--clutch-tolerance: {e}"))?;
    Ok(cfg)
}

fn command(args: &SimulateArgs) -> Result<(Command, Option<f64>), String> {
    if let Some(s) = &args.step {
        return Ok((
            Command::Step {
                target: angle(parse(s, "--step", ANGLE)?, "--step")?,
            },
            None,
        ));
    }
    if let Some(s) = &args.move_to {
        let (a, t) = pair(s, "--move")?;
        let ms = parse(t, "--move duration", TIME_S)? * 1e3;
        if !(0.0..=u32::MAX as f64).contains(&ms.round()) {
            return Err(format!("--move duration `{t}` out of range"));
        }
        return Ok((
            Command::Move {
                target: angle(parse(a, "--move target", ANGLE)?, "--move")?,
                duration_ms: ms.round() as u32,
            },
            None,
        ));
    }
    if let Some(s) = &args.sine {
        let (a, f) = pair(s, "--sine")?;
        let w = parse(f, "--sine frequency", FREQ_RAD_S)?;
        let freq = Frequency::from_micro(micro(w, "--sine frequency")?)
            .map_err(|e| format!("--sine frequency: {e}"))?;
        return Ok((
            Command::Sine {
                amplitude: angle(parse(a, "--sine amplitude", ANGLE)?, "--sine")?,
                frequency: freq,
            },
            Some(std::f64::consts::TAU / w),
        ));
    }
    if args.impedance.is_some() {
        // The impedance command replaces it (`impedance`).
        return Ok((Command::Hold, None));
    }
    Err("give one of --step, --move, --sine, --impedance".into())
}

/// The `--impedance` command, if given, and its expected static deflection per N·m of
/// load plus τ_ff/k_v, rad.
fn impedance(args: &SimulateArgs) -> Result<Option<(ImpedanceCommand, f64, f64)>, String> {
    let Some(s) = &args.impedance else {
        return Ok(None);
    };
    let what = "--impedance";
    let parts: Vec<&str> = s.split(':').collect();
    let [a, k, d, rest @ ..] = parts.as_slice() else {
        return Err(format!(
            "{what} `{s}`: expected `ANGLE:STIFFNESS:DAMPING[:TORQUE]`, e.g. \
             `0.3rad:20Nm/rad:0.2Nms/rad`"
        ));
    };
    let t = match rest {
        [] => 0.0,
        [t] => parse(t, "--impedance torque", TORQUE)?,
        _ => return Err(format!("{what} `{s}`: more than four fields")),
    };
    let k = parse(k, "--impedance stiffness", STIFFNESS)?;
    let d = parse(d, "--impedance damping", DAMPING)?;
    if k <= 0.0 {
        return Err(format!("{what}: stiffness {k} N·m/rad is not positive"));
    }
    let cmd = ImpedanceCommand {
        target: angle(parse(a, "--impedance angle", ANGLE)?, what)?,
        stiffness: Stiffness::from_micro(micro(k, "--impedance stiffness")?),
        damping: fixed::types::I32F32::checked_from_num(d)
            .ok_or_else(|| format!("{what}: damping {d} N·m·s/rad is out of range"))?,
        torque: Torque::from_micro(micro(t, "--impedance torque")?)
            .map_err(|e| format!("{what} torque: {e}"))?,
    };
    Ok(Some((cmd, 1.0 / k, t / k)))
}

/// A time in ticks (ms), within [`min_ms`, 3600 s].
fn ticks(s: &str, what: &str, min_ms: u32) -> Result<u32, String> {
    let t = parse(s, what, TIME_S)?;
    let ms = (t * 1e3).round();
    if !(f64::from(min_ms)..=3.6e6).contains(&ms) {
        return Err(format!(
            "{what} `{s}` outside [{}, 3600] s",
            f64::from(min_ms) / 1e3
        ));
    }
    Ok(ms as u32)
}

/// The metrics as a JSON object (keys of the issue plus a few more; null for a figure that
/// does not exist, e.g. a settling time when the link never settles, or the step figures
/// of a sine run when `tracking`).
#[must_use]
pub fn metrics_json(m: &Metrics, tracking: bool) -> String {
    let opt = |v: Option<f64>| v.map_or("null".to_string(), |x| format!("{x}"));
    let step = |v: f64| {
        if tracking {
            "null".to_string()
        } else {
            format!("{v}")
        }
    };
    let step_opt = |v: Option<f64>| if tracking { None } else { v };
    format!(
        concat!(
            "{{\"overshoot_pct\":{},\"settling_time_s\":{},\"steady_state_error_counts\":{},",
            "\"peak_stress_pa\":{},\"rms_error_rad\":{},\"torque_limited\":{},",
            "\"rise_time_s\":{},\"peak_stress_ratio\":{},\"allowable_stress_pa\":{},",
            "\"max_error_rad\":{},\"current_limited\":{},\"duty_saturated\":{},",
            "\"steady_duty_span\":{},\"steady_count_span\":{},\"peak_spring_torque_nm\":{},",
            "\"target_rad\":{},\"output_hash\":\"{:016x}\",\"ticks\":{},\"faults\":[{}],",
            "\"move_ms\":{}}}"
        ),
        step(m.overshoot_pct),
        opt(step_opt(m.settling_time_s)),
        step(m.steady_state_error_counts),
        m.peak_stress_pa,
        m.rms_error_rad,
        m.torque_limited,
        opt(step_opt(m.rise_time_s)),
        m.peak_stress_ratio,
        m.allowable_stress_pa,
        m.max_error_rad,
        m.current_limited,
        m.duty_saturated,
        m.steady_duty_span,
        m.steady_count_span,
        m.peak_spring_torque_nm,
        m.target_rad,
        m.output_hash,
        m.ticks,
        fault_names(m)
            .iter()
            .map(|n| format!("\"{n}\""))
            .collect::<Vec<_>>()
            .join(","),
        m.move_ms.map_or("null".to_string(), |ms| ms.to_string()),
    )
}

/// Names of the faults latched during the run, in code order.
fn fault_names(m: &Metrics) -> Vec<&'static str> {
    model::supervisor::FaultCode::ALL
        .iter()
        .filter(|c| m.faults.contains(**c))
        .map(|c| c.name())
        .collect()
}

/// The `--plant` overrides.
fn overrides(args: &SimulateArgs) -> Result<Overrides, String> {
    let mut o = Overrides::NONE;
    for s in &args.plant {
        o.push_str(s).map_err(|e| format!("--plant `{s}`: {e}"))?;
    }
    Ok(o)
}

/// CSV header of [`csv_row`].
pub const CSV_HEADER: &str = "t_s,reference_rad,link_angle_rad,gear_angle_rad,duty_permille,\
current_a,torque_estimate_nm,beam_stress_pa";

/// One CSV line (no newline).
#[must_use]
pub fn csv_row(s: &Sample) -> String {
    format!(
        "{:.3},{:.7},{:.7},{:.7},{},{:.5},{:.5},{:.0}",
        s.t_s,
        s.reference_rad,
        s.link_angle_rad,
        s.gear_angle_rad,
        s.duty,
        s.current_a,
        s.torque_estimate_nm,
        s.beam_stress_pa
    )
}

/// Runs the scenario, each tick into `writer` if any (flushed at the end). Also returns the
/// mean true link angle over the steady window, rad.
fn run_with(sc: &Scenario, writer: &mut Option<BufWriter<File>>) -> Result<(Metrics, f64), String> {
    let mut io_err: Option<std::io::Error> = None;
    let window_from = (sc.settle_ticks + sc.run_ticks).saturating_sub(sc.steady_window_ticks);
    let (mut sum, mut n) = (0.0, 0u32);
    let m = harness::run(sc, |s| {
        if s.tick >= window_from {
            sum += s.link_angle_rad;
            n += 1;
        }
        if let (Some(w), None) = (writer.as_mut(), io_err.as_ref()) {
            if let Err(e) = writeln!(w, "{}", csv_row(s)) {
                io_err = Some(e);
            }
        }
    })
    .map_err(|e| e.to_string())?;
    if let Some(e) = io_err {
        return Err(format!("--csv: {e}"));
    }
    if let Some(w) = writer {
        w.flush().map_err(|e| format!("--csv: {e}"))?;
    }
    Ok((m, sum / f64::from(n.max(1))))
}

/// Runs `vsa simulate`.
///
/// # Errors
/// A bad argument, a configuration or command the controller rejects, or an I/O error
/// writing the CSV.
pub fn run(args: &SimulateArgs) -> Result<(), String> {
    let cfg = config(args)?;
    let (cmd, period_s) = command(args)?;
    let load = parse(&args.load, "--load", TORQUE)?;
    let load_max = f64::from(LOAD_MAX_MNM) / 1e3;
    if !(-load_max..=load_max).contains(&load) {
        return Err(format!(
            "--load: {load} N·m is outside ±{load_max} N·m (more than the actuator's beams \
             and motor carry)"
        ));
    }
    let mut sc = Scenario::new(cfg, cmd);
    let imp = impedance(args)?;
    sc.impedance = imp.map(|i| i.0);
    sc.plant = overrides(args)?;
    sc.design = Design::paper();
    sc.load_nm = load as f32;
    sc.settle_ticks = ticks(&args.settle, "--settle", 0)?;
    // At least one tick after the command: a run without one has no response to report.
    sc.run_ticks = ticks(&args.seconds, "--seconds", 1)?;
    sc.use_pot = !args.no_pot;
    sc.boot_held = !args.boot_under_load;
    sc.supervision.clutch_monitor = !args.no_clutch_monitor;
    sc.steady_window_ticks = 500.min(sc.run_ticks);
    // For a sine, the RMS error skips the first period (start transient).
    sc.rms_from_ticks = period_s.map_or(0, |p| ((p * 1e3).round() as u32).min(sc.run_ticks));

    let sched = model::control::Schedule::new(&sc.design, &cfg).map_err(|e| {
        // Name the argument the configuration came from.
        let arg = match e {
            ControlError::InertiaOutOfRange => "--inertia",
            ControlError::StiffnessOutOfRange => "--stiffness",
            ControlError::ClutchOutOfRange => "--clutch-length",
            _ => "the configuration",
        };
        format!("{arg}: {e}")
    })?;
    if let Some((c, _, _)) = &imp {
        if c.stiffness > sched.stiffness() {
            return Err(format!(
                "--impedance: virtual stiffness {} N·m/rad is above the joint's k = {:.3} \
                 N·m/rad at this clutch setting",
                c.stiffness.get().to_num::<f64>(),
                sched.stiffness().get().to_num::<f64>()
            ));
        }
    }
    // The CSV goes to a temporary file, renamed over `--csv` only if the run succeeds.
    let (m, rest_rad) = match &args.csv {
        None => run_with(&sc, &mut None)?,
        Some(path) => {
            let mut metrics = Err(String::new());
            output::write_atomically(path, |tmp| {
                let f = File::create(tmp)
                    .map_err(|e| format!("--csv: cannot write {}: {e}", path.display()))?;
                let mut w = BufWriter::new(f);
                writeln!(w, "{CSV_HEADER}")
                    .map_err(|e| format!("--csv: {}: {e}", path.display()))?;
                metrics = run_with(&sc, &mut Some(w));
                metrics.as_ref().map(drop).map_err(Clone::clone)
            })
            // A run that went through and a rename that did not: name the argument.
            .map_err(|e| {
                if metrics.is_ok() {
                    format!("--csv: {e}")
                } else {
                    e
                }
            })?;
            metrics?
        }
    };

    if args.json {
        let json = metrics_json(&m, period_s.is_some());
        match &imp {
            // The impedance figures: the deflection at rest and (load + τ_ff)/k_v.
            Some((_, per_nm, ff)) => println!(
                "{},\"deflection_rad\":{},\"expected_deflection_rad\":{}}}",
                json.trim_end_matches('}'),
                // In the servo's frame: the target as the true frame has it (`Metrics::target_rad`).
                rest_rad - m.target_rad,
                load * per_nm + ff
            ),
            None => println!("{json}"),
        }
        return Ok(());
    }
    let k = sched.stiffness().get().to_num::<f64>();
    let l = sched.setting().length().get().to_num::<f64>();
    println!(
        "clutch L = {l:.3} mm, k = {k:.1} N·m/rad, bandwidth {:.1} rad/s, torque limit {:.3} N·m",
        sched.bandwidth().get().to_num::<f64>(),
        sched.torque_limit().get().to_num::<f64>()
    );
    let ms = |v: Option<f64>| v.map_or("–".to_string(), |t| format!("{:.0} ms", t * 1e3));
    if let (Some(planned), Command::Move { duration_ms, .. }) = (m.move_ms, sc.command) {
        if planned > duration_ms {
            println!(
                "move               {planned} ms instead of {duration_ms} ms: the shortest the limits allow"
            );
        }
    }
    if let Some((_, per_nm, ff)) = &imp {
        // In the servo's frame, as above.
        let target = m.target_rad;
        println!(
            "deflection at rest {:+.5} rad ({:+.2} counts) from the target; \
             (load + τ_ff)/k_v = {:+.5} rad",
            rest_rad - target,
            (rest_rad - target) / plant::ENCODER_COUNT_RAD,
            load * per_nm + ff
        );
    } else if period_s.is_none() {
        println!("overshoot          {:.2} %", m.overshoot_pct);
        println!("rise time 10–90 %  {}", ms(m.rise_time_s));
        println!("settling (±1 cnt)  {}", ms(m.settling_time_s));
        println!(
            "steady-state error {:.2} counts",
            m.steady_state_error_counts
        );
    }
    println!(
        "peak beam stress   {:.0} MPa ({:.3} of σ_allow)",
        m.peak_stress_pa / 1e6,
        m.peak_stress_ratio
    );
    println!("RMS tracking error {:.3e} rad", m.rms_error_rad);
    println!(
        "limits             torque {}, current {}, duty {}",
        m.torque_limited, m.current_limited, m.duty_saturated
    );
    let faults = fault_names(&m);
    match m.first_fault {
        Some(f) => println!(
            "faults             {} (first at {} ms)",
            faults.join(", "),
            i64::from(f.tick) - i64::from(sc.settle_ticks)
        ),
        None => println!("faults             none"),
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_units() {
        assert_eq!(parse("3mm", "x", LENGTH_MM), Ok(3.0));
        assert_eq!(parse("3", "x", LENGTH_MM), Ok(3.0));
        assert_eq!(parse("250Nm/rad", "x", STIFFNESS), Ok(250.0));
        assert_eq!(parse("0.3 N·m", "x", TORQUE), Ok(0.3));
        assert_eq!(parse("-0.3Nm", "x", TORQUE), Ok(-0.3));
        assert_eq!(parse("1e-3", "x", INERTIA), Ok(1e-3));
        assert_eq!(parse("200ms", "x", TIME_S), Ok(0.2));
        assert!((parse("1Hz", "x", FREQ_RAD_S).unwrap() - std::f64::consts::TAU).abs() < 1e-12);
        assert!(parse("3 furlongs", "x", LENGTH_MM).is_err());
        assert!(parse("abc", "x", LENGTH_MM).is_err());
    }
}
