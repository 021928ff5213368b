//! `energy_per_cycle`: the motor's electrical energy per cycle of a periodic motion against
//! the clutch length L. The paper's motivation is that a compliant joint tuned to the
//! motion (k = J·ω², docs/design.md §2) stores and returns energy that a stiff one makes the
//! motor supply; this figure measures what the simulated actuator actually draws.
//!
//! # What is simulated
//!
//! The closed loop of `plant::harness` (the `model` crate's fixed-point controller, paper
//! preset [`Config::paper`], J_link = 1e-3 kg·m²) at L = 1.0 … 8.0 mm in 0.5 mm steps
//! ([`lengths`]: the whole adjustable range [t_c, l]). A setting the controller rejects
//! ([`Schedule::new`]) gets empty CSV cells and no point; none is rejected today. The
//! motion is a sine of the link reference, 0.2 rad about the start position, at 1 Hz
//! (slow: friction and the load dominate) and at 3 Hz (the inertial torque J·A·ω² =
//! 0.30 N·m dominates; peak duty ≈ 80 %, so this is about as fast as the servo can swing
//! 0.2 rad). Each motion runs twice ([`SERIES`]):
//!
//! * with a constant 0.2 N·m load on the link ([`LOAD_NM`]), which keeps the beams engaged
//!   on one side of the free play (the link's own inertial torque J_l·A·ω² is 0.008 N·m at
//!   1 Hz, 0.071 N·m at 3 Hz). With 0.1 and 0.15 N·m the rattle below still appeared at
//!   1 Hz at some L (3–5.5 mm and 4–4.5 mm); with 0.2 N·m at none;
//! * without load. The coupling torque then changes sign twice a cycle and the link floats
//!   in the free play ±φ_b = ±5.1 mrad; a controller that throws it from wall to wall pays
//!   for every bounce (design §11, step 8: the floating gear loop runs at ω_c/2 near the
//!   target and while the reference moves; at the full ω_c the 1 Hz sine drew up to 2.7×
//!   the rigid-body estimate, with an 11 Hz bounce at L = 4 mm).
//!
//! A run holds [`SETTLE_TICKS`] (the load is taken up; `vsa advise` holds longer at soft
//! settings, [`Motion::settle_ticks`]), starts the sine, skips the first
//! second ([`SKIP_TICKS`]: one cycle at 1 Hz, three at 3 Hz, the start transient; with the
//! load, later cycles agree with the counted ones to 4 digits; `vsa advise` skips longer
//! at soft settings, [`Motion::skip_ticks`]) and averages the energies
//! over the next whole cycles (2 at 1 Hz, 6 at 3 Hz).
//!
//! # What is integrated (f64, per 1 ms tick)
//!
//! V = duty/1000 · V_s (V_s = 12 V) is constant over a tick; i is the plant's true motor
//! current, sampled once per tick, at its end (`Sample::current_a`). Per cycle:
//!
//! * `electrical_j` = Σ V·i·dt: the net energy taken from the supply (regenerated energy
//!   counts negative: the H-bridge rectifies synchronously). **The plotted value.**
//!   Approximation: the end-of-tick current lags the tick's mean current by ≈ dt/2 in its
//!   back-EMF part. As the simulated motor has no inductance (i = (V − k_e·ω_g)/R), the
//!   exact tick integral is V·(V·dt − k_e·Δθ_g)/R, given as `electrical_exact_j`. The two
//!   differ by < 0.1 % at 1 Hz and 1.4 % at 3 Hz (with the load), the expected lag error
//!   k_e·J·A²·ω⁴·T·dt/(4·k_t) = 3.4 mJ at 3 Hz;
//! * `drawn_j` = Σ max(V·i, 0)·dt: what a supply that cannot take energy back delivers;
//! * `copper_j` = Σ R·i²·dt: the winding loss;
//! * `mechanical_j` = Σ k_t·i·Δθ_g: the motor torque's work on the output gear (the rest
//!   of V·i − R·i² is gearbox loss: the model's k_t/k_e is 0.52);
//! * `rigid_estimate_j`: a closed-form estimate for a rigid joint tracking θ = A·sin(ωt)
//!   exactly, with i = τ/k_t, τ = J·θ̈ + b·θ̇ + τ_c·sgn(θ̇) − τ_load (J = J_g + J_l, b
//!   and τ_c the plant's viscous and Coulomb friction, gear + link):
//!   ∮(R·i² + k_e·θ̇·i) dt = (R/k_t²)·T·[(J·A·ω²)²/2 + (b·A·ω)²/2 + τ_c² + τ_load²
//!   + (4/π)·b·A·ω·τ_c] + (k_e/k_t)·[b·A²·ω²·T/2 + 4·A·τ_c];
//! * `rms_error_rad`: RMS of reference − true link angle over the averaged cycles, and
//!   `limited`: a live limit (torque, current or duty) was active in them.
//!
//! # What it shows
//!
//! With the load the energy per cycle is flat in L: 0.343 J at 1 Hz over the whole range,
//! and at 3 Hz 0.244 J at L = 1 mm falling to 0.240 J at 8 mm; within 0.2 % (1 Hz) and
//! 1.2–2.8 % (3 Hz) of the rigid-body estimate. Copper loss is 90–95 % of it; the load's holding
//! current alone costs R·(τ_load/k_t)²·T = 0.32 J a cycle at 1 Hz and 0.11 J at 3 Hz. There
//! is no useful energy storage in this range: the link's anti-resonance √(k/J_l) is 19 Hz
//! at L = 8 mm and 426 Hz at 1 mm, far above the motion; the k = J_l·ω² that would tune the
//! joint to it is 0.04 N·m/rad at 1 Hz and 0.36 N·m/rad at 3 Hz, 40–350 times softer than
//! the softest setting (14 N·m/rad). The soft end saves what theory predicts: the gear
//! swings (1 − J_l·ω²/k) of the link's amplitude, 2.5 % less at 3 Hz and L = 8 mm, worth
//! 1.5 % of the energy. Without load the energy is the rigid body's: 0.99–1.06 times the
//! estimate at 1 Hz, 0.95–1.01 at 3 Hz (`cli/tests/figures.rs` holds it within 2×).

use fixed::types::I32F32;
use model::control::{Command, Config, Schedule};
use model::{Angle, Design, Frequency, Length};
use plant::harness::{self, Scenario};
use plant::PlantConfig;
use plotters::prelude::SeriesLabelPosition;

use super::plot::{Figure, Panel, Series, COLORS};
use super::{c, Csv};
use crate::design::to_f64;
use crate::format::trim;

/// Amplitude of the sine, rad.
pub const AMPLITUDE_RAD: f64 = 0.2;
/// The constant load of the loaded series, N·m (pushes the link positive).
pub const LOAD_NM: f64 = 0.2;
/// Ticks of hold before the sine starts.
pub const SETTLE_TICKS: u32 = 200;
/// Ticks skipped after the sine starts (start-up transient), a whole number of cycles.
pub const SKIP_TICKS: u32 = 1000;

/// One series: a periodic motion under one load.
#[derive(Clone, Copy, Debug)]
pub struct Motion {
    /// Prefix of its CSV columns.
    pub key: &'static str,
    /// Sine amplitude, rad.
    pub amplitude_rad: f64,
    /// Sine frequency, Hz.
    pub frequency_hz: f64,
    /// Constant load torque on the link, N·m.
    pub load_nm: f64,
    /// Gravity arm m·g·l, N·m: the link hangs at the motion's centre (0 rad) and gravity
    /// pulls it back with −m·g·l·sin θ (`plant::harness::Scenario::gravity_nm`).
    pub gravity_nm: f64,
    /// Whole cycles averaged after `skip_ticks`.
    pub cycles: u32,
    /// Ticks of hold before the sine starts (the controller takes up the load).
    pub settle_ticks: u32,
    /// Ticks skipped after the sine starts (its start transient): [`SKIP_TICKS`] here.
    pub skip_ticks: u32,
}

/// The four series: 1 Hz and 3 Hz, with and without the load.
pub const SERIES: [Motion; 4] = [
    Motion {
        key: "loaded_1hz",
        amplitude_rad: AMPLITUDE_RAD,
        frequency_hz: 1.0,
        load_nm: LOAD_NM,
        gravity_nm: 0.0,
        cycles: 2,
        settle_ticks: SETTLE_TICKS,
        skip_ticks: SKIP_TICKS,
    },
    Motion {
        key: "loaded_3hz",
        amplitude_rad: AMPLITUDE_RAD,
        frequency_hz: 3.0,
        load_nm: LOAD_NM,
        gravity_nm: 0.0,
        cycles: 6,
        settle_ticks: SETTLE_TICKS,
        skip_ticks: SKIP_TICKS,
    },
    Motion {
        key: "unloaded_1hz",
        amplitude_rad: AMPLITUDE_RAD,
        frequency_hz: 1.0,
        load_nm: 0.0,
        gravity_nm: 0.0,
        cycles: 2,
        settle_ticks: SETTLE_TICKS,
        skip_ticks: SKIP_TICKS,
    },
    Motion {
        key: "unloaded_3hz",
        amplitude_rad: AMPLITUDE_RAD,
        frequency_hz: 3.0,
        load_nm: 0.0,
        gravity_nm: 0.0,
        cycles: 6,
        settle_ticks: SETTLE_TICKS,
        skip_ticks: SKIP_TICKS,
    },
];

/// The per-series CSV columns, after the key.
const COLUMNS: [&str; 8] = [
    "electrical_j",
    "electrical_exact_j",
    "drawn_j",
    "copper_j",
    "mechanical_j",
    "rigid_estimate_j",
    "rms_error_rad",
    "limited",
];

/// Energies per cycle of one run (see the module docs).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CycleEnergy {
    /// Σ V·i·dt per cycle, J.
    pub electrical_j: f64,
    /// Σ V·(V·dt − k_e·Δθ_g)/R per cycle, J.
    pub electrical_exact_j: f64,
    /// Σ max(V·i, 0)·dt per cycle, J.
    pub drawn_j: f64,
    /// Σ R·i²·dt per cycle, J.
    pub copper_j: f64,
    /// Σ k_t·i·Δθ_g per cycle, J.
    pub mechanical_j: f64,
    /// RMS of reference − true link angle over the averaged cycles, rad.
    pub rms_error_rad: f64,
    /// The mean of that error over the averaged cycles, rad: a constant offset, such as
    /// the start-up angle's (read from the gear pot, it misses the deflection the load
    /// holds), and the RMS about it, rad: how well the motion itself is followed.
    pub mean_error_rad: f64,
    pub periodic_rms_error_rad: f64,
    /// A live limit was active in the averaged cycles.
    pub limited: bool,
    /// Largest |true beam root stress| over the averaged cycles, Pa.
    pub peak_stress_pa: f64,
}

fn err<E: std::fmt::Display>(what: &'static str) -> impl Fn(E) -> String {
    move |e| format!("{what}: {e}")
}

/// Ticks of `m.cycles` cycles of `m`, to the nearest tick (exact for the figure's
/// motions; the energies are divided by the cycles the window really holds).
fn window_ticks(m: &Motion) -> Result<u32, String> {
    let t = f64::from(m.cycles) * 1000.0 / m.frequency_hz;
    if !(1.0..=f64::from(u32::MAX / 2)).contains(&t) {
        return Err(format!(
            "{} cycles at {} Hz do not fit in a simulation window",
            m.cycles, m.frequency_hz
        ));
    }
    Ok(t.round() as u32)
}

/// The rigid-body estimate of the electrical energy per cycle for the plant `pc` (see the
/// module docs for the formula), J.
pub fn rigid_estimate(pc: &PlantConfig, m: &Motion) -> f64 {
    let r = f64::from(pc.motor.resistance_ohm);
    let kt = f64::from(pc.motor.torque_constant_nm_per_a);
    let ke = f64::from(pc.motor.back_emf_v_s_per_rad);
    let j = f64::from(pc.motor.inertia_kg_m2) + f64::from(pc.link.inertia_kg_m2);
    let b = f64::from(pc.motor.viscous_nm_s_per_rad) + f64::from(pc.link.viscous_nm_s_per_rad);
    let tc = f64::from(pc.motor.coulomb_nm) + f64::from(pc.link.coulomb_nm);
    let (a, w) = (m.amplitude_rad, std::f64::consts::TAU * m.frequency_hz);
    let period = 1.0 / m.frequency_hz;
    let (acc, vel) = (j * a * w * w, b * a * w);
    let mean_sq = acc * acc / 2.0
        + vel * vel / 2.0
        + tc * tc
        + m.load_nm * m.load_nm
        + 4.0 / std::f64::consts::PI * vel * tc;
    r / (kt * kt) * mean_sq * period + ke / kt * (b * a * a * w * w * period / 2.0 + 4.0 * a * tc)
}

/// Runs `m` with the controller configured by `cfg` (clutch setting, link inertia, …) and
/// integrates the energies; `Ok(None)` when the controller rejects the configuration.
/// (`vsa advise` runs its tasks through this function too.)
pub fn energy_per_cycle(
    d: &Design,
    cfg: &Config,
    m: &Motion,
) -> Result<Option<CycleEnergy>, String> {
    let cmd = Command::Sine {
        amplitude: Angle::from_micro((m.amplitude_rad * 1e6).round() as i64)
            .map_err(err("amplitude"))?,
        frequency: Frequency::from_hz(I32F32::from_num(m.frequency_hz))
            .map_err(err("frequency"))?,
    };
    energy_of_commands(d, cfg, m, cmd, |_| None)
}

/// As [`energy_per_cycle`] for any periodic motion of frequency `m.frequency_hz` given as
/// commands: `first` when the motion starts, `script(n)` n ticks later
/// ([`harness::run_script`]); `m.amplitude_rad` is not used.
pub fn energy_of_commands(
    d: &Design,
    cfg: &Config,
    m: &Motion,
    first: Command,
    script: impl FnMut(u32) -> Option<Command>,
) -> Result<Option<CycleEnergy>, String> {
    let cfg = *cfg;
    if Schedule::new(d, &cfg).is_err() {
        return Ok(None);
    }
    let pc = harness::plant_config(d, &cfg, m.load_nm as f32).map_err(err("plant"))?;
    let window = window_ticks(m)?;
    let cmd = first;
    let mut sc = Scenario::new(cfg, cmd);
    sc.design = *d;
    sc.load_nm = m.load_nm as f32;
    sc.gravity_nm = m.gravity_nm as f32;
    sc.settle_ticks = m.settle_ticks;
    sc.run_ticks = m.skip_ticks.saturating_add(window);
    sc.rms_from_ticks = m.skip_ticks;
    let vs = f64::from(pc.motor.supply_voltage_v);
    let r = f64::from(pc.motor.resistance_ohm);
    let kt = f64::from(pc.motor.torque_constant_nm_per_a);
    let ke = f64::from(pc.motor.back_emf_v_s_per_rad);
    let dt = f64::from(plant::TICK_S);
    let full = f64::from(plant::DUTY_FULL_SCALE);
    let from = m.settle_ticks.saturating_add(m.skip_ticks);
    let mut e = CycleEnergy::default();
    let mut last_gear = 0.0f64;
    let (mut e_sum, mut e_sq, mut e_n) = (0.0f64, 0.0f64, 0.0f64);
    let metrics = harness::run_script(&sc, script, |s| {
        if s.tick >= from {
            let v = f64::from(s.duty).clamp(-full, full) / full * vs;
            let i = f64::from(s.current_a);
            let dg = s.gear_angle_rad - last_gear;
            e.electrical_j += v * i * dt;
            e.electrical_exact_j += v * (v * dt - ke * dg) / r;
            e.drawn_j += (v * i).max(0.0) * dt;
            e.copper_j += r * i * i * dt;
            e.mechanical_j += kt * i * dg;
            e.limited |=
                s.flags.torque_limited || s.flags.current_limited || s.flags.duty_saturated;
            e.peak_stress_pa = e.peak_stress_pa.max(f64::from(s.beam_stress_pa).abs());
            let err = s.reference_rad - s.link_angle_rad;
            e_sum += err;
            e_sq += err * err;
            e_n += 1.0;
        }
        last_gear = s.gear_angle_rad;
    })
    .map_err(err("controller"))?;
    let n = f64::from(window) * m.frequency_hz / 1000.0;
    e.electrical_j /= n;
    e.electrical_exact_j /= n;
    e.drawn_j /= n;
    e.copper_j /= n;
    e.mechanical_j /= n;
    e.rms_error_rad = metrics.rms_error_rad;
    if e_n > 0.0 {
        e.mean_error_rad = e_sum / e_n;
        e.periodic_rms_error_rad = (e_sq / e_n - e.mean_error_rad.powi(2)).max(0.0).sqrt();
    }
    Ok(Some(e))
}

/// The clutch lengths: 1.0 … 8.0 mm in 0.5 mm steps (exact in I32F32).
pub fn lengths() -> Vec<Length> {
    (2..=16).map(|h| Length::from_bits(h << 31)).collect()
}

fn label(m: &Motion) -> String {
    format!("{} Hz", trim(m.frequency_hz))
}

/// The figure: energy per cycle vs L, loaded (left) and unloaded (right).
pub fn energy_per_cycle_figure(d: &Design) -> Result<(Figure, Csv), String> {
    let mut header = String::from("length_mm,stiffness_nm_per_rad,antiresonance_hz");
    for m in &SERIES {
        for col in COLUMNS {
            header.push_str(&format!(",{}_{col}", m.key));
        }
    }
    let mut csv = Csv::new(header);
    let j_link = to_f64(Config::paper(Length::from_int(1)).link_inertia.get()) * 1e-6;
    let mut sim: Vec<Vec<(f64, f64)>> = vec![Vec::new(); SERIES.len()];
    let mut est: Vec<Vec<(f64, f64)>> = vec![Vec::new(); SERIES.len()];
    for len in lengths() {
        let x = to_f64(len.get());
        let k = d.stiffness(len).map_err(err("k"))?.get().to_num::<f64>();
        let mut row = vec![c(x), c(k), c((k / j_link).sqrt() / std::f64::consts::TAU)];
        for (i, m) in SERIES.iter().enumerate() {
            let run = energy_per_cycle(d, &Config::paper(len), m)?;
            let rigid = harness::plant_config(d, &Config::paper(len), m.load_nm as f32)
                .ok()
                .map(|pc| rigid_estimate(&pc, m));
            match run {
                Some(e) => {
                    row.extend([
                        c(e.electrical_j),
                        c(e.electrical_exact_j),
                        c(e.drawn_j),
                        c(e.copper_j),
                        c(e.mechanical_j),
                        rigid.map_or_else(String::new, c),
                        c(e.rms_error_rad),
                        e.limited.to_string(),
                    ]);
                    sim[i].push((x, e.electrical_j));
                }
                None => row.extend(std::iter::repeat_n(String::new(), COLUMNS.len())),
            }
            est[i].extend(rigid.map(|r| (x, r)));
        }
        csv.push(&row);
    }
    let panel = |idx: [usize; 2], caption: String, log_y: bool| {
        let mut series = Vec::new();
        for (ci, &i) in idx.iter().enumerate() {
            series.push(Series {
                label: Some(format!("{}, simulated ∮V·i dt", label(&SERIES[i]))),
                points: sim[i].clone(),
                color: COLORS[ci],
                dashed: false,
                marker: false,
            });
            series.push(Series {
                label: Some(format!("{}, rigid-body estimate", label(&SERIES[i]))),
                points: est[i].clone(),
                color: COLORS[ci],
                dashed: true,
                marker: false,
            });
        }
        Panel {
            caption,
            x_label: "clutch length L (mm)".into(),
            y_label: "motor electrical energy per cycle (J)".into(),
            log_y,
            y_zero: true,
            headroom: 0.45,
            x_margin: 0.0,
            series,
            legend: SeriesLabelPosition::UpperRight,
        }
    };
    let fig = Figure {
        title: format!(
            "Motor energy per cycle vs clutch length — sine {} rad at 1 Hz and 3 Hz, J_link = {j_link:e} kg·m²",
            trim(AMPLITUDE_RAD)
        ),
        panels: vec![
            panel(
                [0, 1],
                format!(
                    "constant {} N·m load: the beams stay engaged",
                    trim(LOAD_NM)
                ),
                false,
            ),
            panel(
                [2, 3],
                "no load: the link floats in the free play (log scale)".into(),
                true,
            ),
        ],
        size: (1500, 650),
    };
    Ok((fig, csv))
}
