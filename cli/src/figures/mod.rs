//! `vsa figures --out DIR`: the paper's figures (design.md §8) for the paper preset, as SVG,
//! PNG and the CSV behind each, all values from the model crate.
//!
//! * `fig4_hysteresis`: friction hysteresis loops at x = 0.2·l, 0.5·l, 0.8·l, one cycle
//!   0 → +θ_cap → −θ_cap → +θ_cap through the model's [`Hysteresis`] state machine
//!   (without free play, as in the paper), and the friction part τ − k·φ;
//! * `fig5_stiffness`: k(L) and k_T(L) over the adjustable range [t_c, l], linear and log;
//! * `fig6_deflection`: deflection at 2 N·m vs L for r = 0.5 / 1 / 1.5 mm (log), dashed where
//!   2 N·m exceeds the stress-limited capacity;
//! * `capacity`: stress-limited torque capacity τ_cap(L) with the 2 N·m line.

mod closed_loop;
mod energy;
pub(crate) mod plot;
mod text;

use std::fmt::Write as _;
use std::io::Write as _;
use std::path::{Path, PathBuf};

use clap::Args;
use fixed::types::I32F32;
use model::beam::BeamModel;
use model::{Angle, Design, DesignParams, Hysteresis, Length, Setting, Torque};
use plotters::prelude::SeriesLabelPosition;

use crate::design::to_f64;
use crate::error::{CliError, CliResult};
use crate::format::trim;
use plot::{Figure, Panel, Series, COLORS};

/// Draw the paper's figures for the paper preset.
#[derive(Args, Debug)]
pub struct FiguresArgs {
    /// Output directory (created if missing)
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
}

/// The load of Fig. 6 and of the capacity figure, 2 N·m.
const LOAD: Torque = Torque::from_int(2);
/// Intervals of the L grids.
const GRID: i64 = 140;
/// Samples per quarter cycle of a hysteresis loop.
const QUARTER: i64 = 100;

/// The data behind a figure, one CSV file.
pub struct Csv {
    header: String,
    rows: Vec<String>,
}

impl Csv {
    fn new(header: impl Into<String>) -> Csv {
        Csv {
            header: header.into(),
            rows: Vec::new(),
        }
    }

    fn push(&mut self, cells: &[String]) {
        self.rows.push(cells.join(","));
    }

    fn text(&self) -> String {
        let mut s = String::with_capacity(64 * (self.rows.len() + 1));
        let _ = writeln!(s, "{}", self.header);
        for r in &self.rows {
            let _ = writeln!(s, "{r}");
        }
        s
    }
}

/// Runs `vsa figures`: writes every figure, one progress line per figure on stderr.
pub fn run(args: &FiguresArgs) -> CliResult<()> {
    let out = &args.out;
    std::fs::create_dir_all(out)
        .map_err(|e| CliError::usage("--out", format!("cannot create {}: {e}", out.display())))?;
    plot::register_font().map_err(CliError::runtime)?;
    let design = Design::paper();
    type Make = fn(&Design) -> Result<(Figure, Csv), String>;
    let figures: [(&str, Make); 7] = [
        ("fig4_hysteresis", fig4_hysteresis),
        ("fig5_stiffness", fig5_stiffness),
        ("fig6_deflection", fig6_deflection),
        ("capacity", capacity),
        (
            "fig8_identified_stiffness",
            closed_loop::fig8_identified_stiffness,
        ),
        ("fig9_step_responses", closed_loop::fig9_step_responses),
        ("energy_per_cycle", energy::energy_per_cycle_figure),
    ];
    for (name, make) in figures {
        let (fig, csv) = make(&design).map_err(|e| CliError::runtime(format!("{name}: {e}")))?;
        let stem = out.join(name);
        write_figure(&stem, &fig, &csv).map_err(CliError::runtime)?;
        let _ = writeln!(
            std::io::stderr(),
            "wrote {} (.svg, .png, .csv)",
            stem.display()
        );
    }
    Ok(())
}

fn write_figure(stem: &Path, fig: &Figure, csv: &Csv) -> Result<(), String> {
    let path = stem.with_extension("csv");
    std::fs::write(&path, csv.text()).map_err(|e| format!("{}: {e}", path.display()))?;
    fig.write(stem)
}

/// A number for CSV: the f64 nearest to the model's value (shortest round-trip form).
fn c(x: f64) -> String {
    format!("{x}")
}

fn co(x: Option<f64>) -> String {
    x.map_or_else(String::new, c)
}

/// GRID + 1 clutch lengths from `lo` to `hi` inclusive, in fixed point (integer mm land on
/// the grid for the paper preset: 1 + 7·i/140 mm).
fn grid(lo: Length, hi: Length) -> Vec<Length> {
    let (a, b) = (i128::from(lo.to_bits()), i128::from(hi.to_bits()));
    (0..=GRID)
        .map(|i| Length::from_bits((a + (b - a) * i128::from(i) / i128::from(GRID)) as i64))
        .collect()
}

fn model_err(what: &str) -> impl Fn(model::Error) -> String + '_ {
    move |e| format!("{what}: {e}")
}

/// Fig. 4: friction hysteresis loops at x = 0.2·l, 0.5·l, 0.8·l.
pub fn fig4_hysteresis(d: &Design) -> Result<(Figure, Csv), String> {
    let l = d.params().beam_length;
    let mut csv =
        Csv::new("x_mm,step,phi_rad,branch,torque_nm,elastic_torque_nm,friction_torque_nm");
    let mut loops = Vec::new();
    let mut friction = Vec::new();
    for (i, (name, frac)) in [
        ("0.2", I32F32::lit("0.2")),
        ("0.5", I32F32::lit("0.5")),
        ("0.8", I32F32::lit("0.8")),
    ]
    .into_iter()
    .enumerate()
    {
        let x = Length::from_fixed(l.get().saturating_mul(frac));
        let s = Setting::new(d, x, BeamModel::EulerBernoulli).map_err(model_err("setting"))?;
        let amp = i128::from(s.deflection_capacity().to_bits());
        // 0 → +A → −A → +A, without repeating the turning points.
        let ks = (0..=QUARTER)
            .chain((-QUARTER..QUARTER).rev())
            .chain(-QUARTER + 1..=QUARTER);
        let mut h = Hysteresis::without_free_play();
        let (mut pts, mut fr) = (Vec::new(), Vec::new());
        for (step, k) in ks.enumerate() {
            let phi = Angle::from_bits((amp * i128::from(k) / i128::from(QUARTER)) as i64);
            let tau = h.step(&s, phi).map_err(model_err("hysteresis"))?;
            let elastic = s.elastic_torque(phi).map_err(model_err("elastic torque"))?;
            let friction_part = tau
                .checked_sub(elastic)
                .ok_or_else(|| "friction torque overflows".to_string())?;
            let branch = match h.branch() {
                model::Branch::Loading => "loading",
                model::Branch::Unloading => "unloading",
            };
            csv.push(&[
                c(to_f64(x.get())),
                step.to_string(),
                c(to_f64(phi.get())),
                branch.to_string(),
                c(to_f64(tau.get())),
                c(to_f64(elastic.get())),
                c(to_f64(friction_part.get())),
            ]);
            pts.push((to_f64(phi.get()), to_f64(tau.get())));
            fr.push((to_f64(phi.get()), to_f64(friction_part.get())));
        }
        let label = format!(
            "x = {name}·l = {} mm (±{} rad)",
            trim(to_f64(x.get())),
            crate::format::sig(to_f64(s.deflection_capacity().get()), 3)
        );
        loops.push(Series {
            label: Some(label.clone()),
            points: pts,
            color: COLORS[i],
            dashed: false,
            marker: false,
        });
        friction.push(Series {
            label: Some(format!("x = {name}·l")),
            points: fr,
            color: COLORS[i],
            dashed: false,
            marker: false,
        });
    }
    let fig = Figure {
        title: format!(
            "Fig. 4 — friction hysteresis, one cycle to ±θ_cap (E–B, μ = {}, no free play)",
            trim(to_f64(d.params().friction.get()))
        ),
        panels: vec![
            Panel {
                caption: "torque vs output rotation, to ±θ_cap at each x".into(),
                x_label: "output rotation φ (rad)".into(),
                y_label: "coupling torque τ (N·m)".into(),
                log_y: false,
                y_zero: false,
                headroom: 0.15,
                x_margin: 0.0,
                series: loops,
                legend: SeriesLabelPosition::UpperLeft,
            },
            Panel {
                caption: "friction part τ − k·φ: > 0 loading, < 0 unloading (for φ > 0)".into(),
                x_label: "output rotation φ (rad)".into(),
                y_label: "τ − k·φ (N·m)".into(),
                log_y: false,
                y_zero: false,
                headroom: 0.35,
                x_margin: 0.03,
                series: friction,
                legend: SeriesLabelPosition::UpperLeft,
            },
        ],
        size: (1500, 650),
    };
    Ok((fig, csv))
}

/// Fig. 5: stiffness vs clutch length, both beam models, linear and log.
pub fn fig5_stiffness(d: &Design) -> Result<(Figure, Csv), String> {
    let (lo, hi) = d.adjustable_range();
    let mut csv = Csv::new("length_mm,stiffness_nm_per_rad,stiffness_shear_nm_per_rad");
    let (mut eb, mut sh) = (Vec::new(), Vec::new());
    for len in grid(lo, hi) {
        let k = d.stiffness(len).ok().map(|k| k.get().to_num::<f64>());
        let kt = d
            .stiffness_timoshenko(len)
            .ok()
            .map(|k| k.get().to_num::<f64>());
        let x = to_f64(len.get());
        csv.push(&[c(x), co(k), co(kt)]);
        eb.extend(k.map(|k| (x, k)));
        sh.extend(kt.map(|k| (x, k)));
    }
    let series = || {
        vec![
            Series {
                label: Some("Euler–Bernoulli, paper eq. 4".into()),
                points: eb.clone(),
                color: COLORS[0],
                dashed: false,
                marker: false,
            },
            Series {
                label: Some("shear-corrected (Timoshenko)".into()),
                points: sh.clone(),
                color: COLORS[1],
                dashed: true,
                marker: false,
            },
        ]
    };
    let panel = |log_y: bool| Panel {
        caption: if log_y { "log scale" } else { "linear scale" }.into(),
        x_label: "clutch length L (mm)".into(),
        y_label: "joint stiffness k (N·m/rad)".into(),
        log_y,
        y_zero: true,
        headroom: 0.0,
        x_margin: 0.0,
        series: series(),
        legend: SeriesLabelPosition::UpperRight,
    };
    let fig = Figure {
        title: format!(
            "Fig. 5 — joint stiffness vs clutch length over the adjustable range [t_c, l] = [{}, {}] mm",
            trim(to_f64(lo.get())),
            trim(to_f64(hi.get()))
        ),
        panels: vec![panel(false), panel(true)],
        size: (1500, 650),
    };
    Ok((fig, csv))
}

/// Fig. 6: deflection at 2 N·m vs clutch length for three beam radii.
pub fn fig6_deflection(d: &Design) -> Result<(Figure, Csv), String> {
    let (lo, hi) = d.adjustable_range();
    let mut csv = Csv::new(
        "length_mm,beam_radius_mm,deflection_rad,deflection_deg,torque_capacity_nm,within_capacity",
    );
    let mut series = Vec::new();
    for (i, r) in [I32F32::lit("0.5"), I32F32::lit("1"), I32F32::lit("1.5")]
        .into_iter()
        .enumerate()
    {
        let p = DesignParams {
            beam_radius: Length::from_fixed(r),
            ..*d.params()
        };
        let dr = Design::new(p).map_err(model_err("design"))?;
        let (mut ok, mut over) = (Vec::new(), Vec::new());
        for len in grid(lo, hi) {
            let theta = dr.deflection(LOAD, len).ok().map(|a| to_f64(a.get()));
            let cap = dr.torque_capacity(len).ok();
            let within = cap.map(|cap| LOAD <= cap);
            csv.push(&[
                c(to_f64(len.get())),
                c(to_f64(r)),
                co(theta),
                co(theta.map(f64::to_degrees)),
                co(cap.map(|t| to_f64(t.get()))),
                within.map_or_else(String::new, |w| w.to_string()),
            ]);
            if let Some(th) = theta {
                let pt = (to_f64(len.get()), th.to_degrees());
                if within == Some(true) {
                    ok.push(pt);
                } else {
                    // Start the dashed part at the last point within capacity.
                    if over.is_empty() {
                        over.extend(ok.last().copied());
                    }
                    over.push(pt);
                }
            }
        }
        let label = format!("r = {} mm", trim(to_f64(r)));
        let has_ok = !ok.is_empty();
        series.push(Series {
            label: has_ok.then(|| label.clone()),
            points: ok,
            color: COLORS[i],
            dashed: false,
            marker: false,
        });
        series.push(Series {
            label: (!has_ok).then_some(label),
            points: over,
            color: COLORS[i],
            dashed: true,
            marker: false,
        });
    }
    let fig = Figure {
        title: format!(
            "Fig. 6 — deflection at {} N·m vs clutch length (E–B, n = {}, R = {} mm)",
            trim(to_f64(LOAD.get())),
            d.params().beams,
            trim(to_f64(d.params().pitch_radius.get()))
        ),
        panels: vec![Panel {
            caption: "dashed: the load exceeds the stress-limited capacity (beams yield)".into(),
            x_label: "clutch length L (mm)".into(),
            y_label: "deflection θ (°)".into(),
            log_y: true,
            y_zero: false,
            headroom: 0.0,
            x_margin: 0.0,
            series,
            legend: SeriesLabelPosition::LowerRight,
        }],
        size: (1000, 700),
    };
    Ok((fig, csv))
}

/// Stress-limited torque capacity vs clutch length, with the 2 N·m load.
pub fn capacity(d: &Design) -> Result<(Figure, Csv), String> {
    let (lo, hi) = d.adjustable_range();
    let mut csv = Csv::new("length_mm,torque_capacity_nm,deflection_capacity_rad,load_nm");
    let mut pts = Vec::new();
    for len in grid(lo, hi) {
        let cap = d.torque_capacity(len).ok().map(|t| to_f64(t.get()));
        let th = d.deflection_capacity(len).ok().map(|a| to_f64(a.get()));
        csv.push(&[c(to_f64(len.get())), co(cap), co(th), c(to_f64(LOAD.get()))]);
        pts.extend(cap.map(|t| (to_f64(len.get()), t)));
    }
    let load = to_f64(LOAD.get());
    let (x0, x1) = (to_f64(lo.get()), to_f64(hi.get()));
    let p = d.params();
    let fig = Figure {
        title: format!(
            "Stress-limited torque capacity vs clutch length (σ_allow = {} MPa, r = {} mm)",
            trim(to_f64(p.allowable_stress.get())),
            trim(to_f64(p.beam_radius.get()))
        ),
        panels: vec![Panel {
            caption: "the beams yield where the load is above the capacity".into(),
            x_label: "clutch length L (mm)".into(),
            y_label: "torque (N·m)".into(),
            log_y: false,
            y_zero: true,
            headroom: 0.0,
            x_margin: 0.0,
            series: vec![
                Series {
                    label: Some("capacity τ_cap(L) = n·R·σ_allow·I/(r·L)".into()),
                    points: pts,
                    color: COLORS[0],
                    dashed: false,
                    marker: false,
                },
                Series {
                    label: Some(format!("load {} N·m", trim(load))),
                    points: vec![(x0, load), (x1, load)],
                    color: COLORS[3],
                    dashed: true,
                    marker: false,
                },
            ],
            legend: SeriesLabelPosition::UpperRight,
        }],
        size: (1000, 700),
    };
    Ok((fig, csv))
}
