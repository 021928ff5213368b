//! `vsa explore`: the feasible region of beam designs against goals, inside an envelope.
//!
//! Searches a grid of designs — material ([`model::material::MATERIALS`]), number of beams
//! n, beam radius r, pitch radius R ≤ `--max-pitch-radius`, softest active length l (the
//! whole beam is l + `--clamp-length`, at most `--max-beam-length`); the stiffest active
//! length is the clutch thickness t_c — and sizes each with [`model::sizing`] (fixed point,
//! Euler–Bernoulli): stiffness range, capacity and safe deflection at both ends of the
//! travel, energy stored at capacity, beam mass, envelope volume, backlash (paper
//! eqs. 5–7) and whether the clutch slots fit. A combination the model rejects (R ≤ r,
//! l ≤ t_c) is not a design and is only counted.
//!
//! Constraints ([`Constraint`]): capacity over the whole travel τ_cap(l) ≥ `--min-capacity`,
//! safe deflection at the softest setting θ_cap(l) ≥ `--min-deflection`, beam mass ≤
//! `--max-mass`, envelope volume ≤ `--max-volume`, slots fit. Defaults are the paper's goals
//! (paper sec. 1): the AX-12A's stall torque 1.5 N·m, ±0.2 rad, 10 % of its 55 g and of its
//! 32 × 50 × 40 mm = 64 cm³ (ROBOTIS e-manual: 54.6 g); the paper's 10 mm beams of which
//! 8 mm are usable (clamp 2 mm); R ≤ 14 mm (half the servo's 32 mm width less 2 mm of wall).
//!
//! Output: the designs meeting every constraint ranked by margin (the smallest of the
//! relative margins value/limit − 1, resp. 1 − value/limit); when none does, the closest
//! designs (largest smallest margin among those whose slots fit), the constraint that binds
//! (the one the closest design misses most) and, per constraint, how many designs would
//! meet all the others; the Pareto front of capacity ↑, deflection ↑, mass ↓ among the
//! designs within the envelope (slots fit, mass and volume within their limits); and the shortest active length any design of each
//! material would need for the goals (closed form, `min_active_length`).
//!
//! # JSON (`--json`)
//!
//! `{"designs": [...], "pareto": [...], "binding": NAME or null, "relaxed": {NAME: count},
//! "evaluated", "rejected_by_model", "feasible", "goals": {...}, "materials": [...]}`; each
//! design has `material`, `beams`, `beam_radius_m`, `pitch_radius_m`,
//! `active_length_min_m` (t_c), `active_length_max_m` (l), `beam_length_m` (whole),
//! `capacity_nm` and `deflection_capacity_rad` (softest setting), `capacity_stiff_nm`,
//! `deflection_stiff_rad`, `stiffness_min_nm_per_rad`, `stiffness_max_nm_per_rad`,
//! `energy_j`, `mass_kg`, `volume_m3`, `free_play_rad`, `backlash_tilt_soft_rad`,
//! `backlash_tilt_stiff_rad`, `fits`, `margin`, `meets_constraints`. `designs` holds the
//! ranked feasible designs, or the closest ones, at most `--top`; with `--all` every
//! design in grid order.

use std::cmp::Ordering;
use std::collections::{BTreeMap, HashMap};
use std::path::PathBuf;

use clap::Args;
use fixed::types::I32F32;
use model::material::{Material, MATERIALS};
use model::sizing::{Candidate, Constraint, Goals, Sizing};
use model::{Angle, Design, DesignParams, Length, Torque};
use plotters::prelude::SeriesLabelPosition;
use serde::Serialize;

use crate::error::{CliError, CliResult};
use crate::figures::plot::{Figure, Panel, Series, COLORS};
use crate::format::{sig, Table};
use crate::units::{self, Decimal, Kind};

/// Most values one grid axis may have.
const MAX_AXIS: u32 = 1000;
/// Most designs one search may evaluate.
const MAX_DESIGNS: usize = 2_000_000;

/// Search the beam designs that meet capacity, deflection, mass and volume goals.
#[derive(Args, Debug, Default)]
#[command(
    after_help = "Defaults: the paper's goals for the AX-12A (1.5 N·m at every setting, \
±0.2 rad at the softest, 5.5 g, 6.4 cm³) and its envelope (10 mm beams, 2 mm clamped, \
R ≤ 14 mm). Grids: a list 2,4,6 or a range START..END:STEP.\n\nBad input: one line on \
stderr, exit code 2."
)]
pub struct ExploreArgs {
    /// Smallest torque capacity over the clutch travel [default: 1.5Nm]
    #[arg(long, value_name = "T", allow_hyphen_values = true)]
    pub min_capacity: Option<String>,
    /// Smallest safe deflection at the softest setting [default: 0.2rad]
    #[arg(long, value_name = "ANGLE", allow_hyphen_values = true)]
    pub min_deflection: Option<String>,
    /// Largest added beam mass [default: 5.5g]
    #[arg(long, value_name = "M", allow_hyphen_values = true)]
    pub max_mass: Option<String>,
    /// Largest envelope volume of the beam ring [default: 6.4cm3]
    #[arg(long, value_name = "V", allow_hyphen_values = true)]
    pub max_volume: Option<String>,
    /// Largest pitch radius R [default: 14mm]
    #[arg(long, value_name = "R", allow_hyphen_values = true)]
    pub max_pitch_radius: Option<String>,
    /// Largest whole beam length (active + clamped) [default: 10mm]
    #[arg(long, value_name = "L", allow_hyphen_values = true)]
    pub max_beam_length: Option<String>,
    /// Beam length held in the gear and the shaft, not usable [default: 2mm]
    #[arg(long, value_name = "L", allow_hyphen_values = true)]
    pub clamp_length: Option<String>,
    /// Clutch plate thickness t_c: the stiffest active length [default: 1mm]
    #[arg(long, value_name = "T", allow_hyphen_values = true)]
    pub clutch_thickness: Option<String>,
    /// Materials, comma-separated (`--materials list` shows them) [default: all]
    #[arg(long, value_name = "LIST")]
    pub materials: Option<String>,
    /// Numbers of beams [default: 2,3,4,6,8]
    #[arg(long, value_name = "LIST", allow_hyphen_values = true)]
    pub beams: Option<String>,
    /// Beam radii [default: 0.1mm..2mm:0.05mm]
    #[arg(long, value_name = "LIST|RANGE", allow_hyphen_values = true)]
    pub beam_radii: Option<String>,
    /// Pitch radii, up to --max-pitch-radius [default: 2mm..14mm:0.5mm]
    #[arg(long, value_name = "LIST|RANGE", allow_hyphen_values = true)]
    pub pitch_radii: Option<String>,
    /// Softest active lengths l, up to --max-beam-length − --clamp-length [default: 2mm..8mm:0.5mm]
    #[arg(long, value_name = "LIST|RANGE", allow_hyphen_values = true)]
    pub active_lengths: Option<String>,
    /// Designs listed [default: 10]
    #[arg(long, value_name = "N")]
    pub top: Option<usize>,
    /// List every design evaluated (in `designs`), not only the best
    #[arg(long)]
    pub all: bool,
    /// Print one JSON object (SI units) instead of the tables
    #[arg(long)]
    pub json: bool,
    /// Draw the achievable (capacity, deflection) region to this .svg or .png
    #[arg(long, value_name = "FILE")]
    pub figure: Option<PathBuf>,
}

/// Runs `vsa explore`; returns what to print on stdout.
pub fn run(args: &ExploreArgs) -> CliResult<String> {
    if args.materials.as_deref() == Some("list") {
        return Ok(material_list());
    }
    let spec = Spec::parse(args)?;
    let result = search(&spec)?;
    if let Some(path) = &args.figure {
        write_figure(&spec, &result, path)?;
    }
    if args.json {
        serde_json::to_string_pretty(&result.to_json(&spec, args))
            .map(|s| s + "\n")
            .map_err(|e| CliError::runtime(format!("cannot encode JSON: {e}")))
    } else {
        Ok(result.render(&spec, args.top.unwrap_or(10)))
    }
}

// ---------------------------------------------------------------------------------------
// Arguments

/// What to search and against which goals.
#[derive(Clone, Debug)]
pub struct Spec {
    goals: Goals,
    max_pitch_radius: Length,
    max_beam_length: Length,
    clamp: Length,
    clutch_thickness: Length,
    materials: Vec<&'static Material>,
    beams: Vec<u8>,
    radii: Vec<Length>,
    pitch_radii: Vec<Length>,
    lengths: Vec<Length>,
}

/// A positive quantity of `kind` from `s` (or `default`), in the model's unit; shared with
/// `vsa advise`.
pub fn positive(
    arg: &'static str,
    s: Option<&str>,
    default: &str,
    kind: Kind,
) -> CliResult<I32F32> {
    let s = s.unwrap_or(default);
    let q = units::parse(s, kind).map_err(|e| CliError::usage(arg, e))?;
    if q.value.negative || q.value.is_zero() {
        return Err(CliError::usage(arg, format!("{q} must be positive")));
    }
    q.value
        .to_i32f32()
        .filter(|v| *v > I32F32::ZERO)
        .ok_or_else(|| CliError::usage(arg, format!("{q} is out of range")))
}

fn lengths(arg: &'static str, s: &str, max: Length) -> CliResult<Vec<Length>> {
    let v = units::parse_list(s, Kind::Length, MAX_AXIS, "values")
        .map_err(|e| CliError::usage(arg, e))?;
    v.into_iter()
        .map(|d: Decimal| {
            let x = Length::from_fixed(d.to_i32f32_saturating());
            if d.negative || x <= Length::ZERO || x > max {
                Err(CliError::usage(
                    arg,
                    format!("{d} mm is out of range (0, {}] mm", sig(f(max.get()), 4)),
                ))
            } else {
                Ok(x)
            }
        })
        .collect()
}

fn f(x: I32F32) -> f64 {
    x.to_num()
}

impl Spec {
    fn parse(a: &ExploreArgs) -> CliResult<Spec> {
        let goals = Goals {
            min_capacity: Torque::from_fixed(positive(
                "--min-capacity",
                a.min_capacity.as_deref(),
                "1.5Nm",
                Kind::Torque,
            )?),
            min_deflection: Angle::from_fixed(positive(
                "--min-deflection",
                a.min_deflection.as_deref(),
                "0.2rad",
                Kind::Angle,
            )?),
            max_mass_g: positive("--max-mass", a.max_mass.as_deref(), "5.5g", Kind::Mass)?,
            max_volume_mm3: positive(
                "--max-volume",
                a.max_volume.as_deref(),
                "6.4cm3",
                Kind::Volume,
            )?,
        };
        let len = |arg, s: &Option<String>, d| positive(arg, s.as_deref(), d, Kind::Length);
        let max_pitch_radius =
            Length::from_fixed(len("--max-pitch-radius", &a.max_pitch_radius, "14mm")?);
        let max_beam_length =
            Length::from_fixed(len("--max-beam-length", &a.max_beam_length, "10mm")?);
        let clamp = Length::from_fixed(len("--clamp-length", &a.clamp_length, "2mm")?);
        let clutch_thickness =
            Length::from_fixed(len("--clutch-thickness", &a.clutch_thickness, "1mm")?);
        let max_active = Length::from_fixed(max_beam_length.get().saturating_sub(clamp.get()));
        if max_active <= clutch_thickness {
            return Err(CliError::usage(
                "--max-beam-length",
                format!(
                    "{} mm less the {} mm clamp leaves no clutch travel beyond t_c = {} mm",
                    sig(f(max_beam_length.get()), 4),
                    sig(f(clamp.get()), 4),
                    sig(f(clutch_thickness.get()), 4)
                ),
            ));
        }
        let materials = match a.materials.as_deref() {
            None => MATERIALS.iter().collect(),
            Some(s) => s
                .split(',')
                .map(|k| {
                    model::material::find(k.trim()).ok_or_else(|| {
                        CliError::usage(
                            "--materials",
                            format!(
                                "unknown material '{}' (known: {})",
                                k.trim(),
                                MATERIALS.map(|m| m.key).join(", ")
                            ),
                        )
                    })
                })
                .collect::<CliResult<Vec<_>>>()?,
        };
        let beams = a
            .beams
            .as_deref()
            .unwrap_or("2,3,4,6,8")
            .split(',')
            .map(|t| {
                t.trim()
                    .parse::<u8>()
                    .ok()
                    .filter(|n| (model::design::BEAMS_MIN..=model::design::BEAMS_MAX).contains(n))
                    .ok_or_else(|| {
                        CliError::usage(
                            "--beams",
                            format!(
                                "'{}' is not a whole number in {}..={}",
                                t.trim(),
                                model::design::BEAMS_MIN,
                                model::design::BEAMS_MAX
                            ),
                        )
                    })
            })
            .collect::<CliResult<Vec<_>>>()?;
        let radii = lengths(
            "--beam-radii",
            a.beam_radii.as_deref().unwrap_or("0.1mm..2mm:0.05mm"),
            model::design::BEAM_RADIUS_MAX,
        )?;
        let default_pitch = format!("2mm..{}mm:0.5mm", f(max_pitch_radius.get()));
        let pitch_radii = lengths(
            "--pitch-radii",
            a.pitch_radii.as_deref().unwrap_or(&default_pitch),
            max_pitch_radius,
        )?;
        let default_active = format!("2mm..{}mm:0.5mm", f(max_active.get()));
        let lengths = lengths(
            "--active-lengths",
            a.active_lengths.as_deref().unwrap_or(&default_active),
            max_active,
        )?;
        let total = materials.len() * beams.len() * radii.len() * pitch_radii.len() * lengths.len();
        if total > MAX_DESIGNS {
            return Err(CliError::usage(
                "explore",
                format!("the grid has {total} designs, more than {MAX_DESIGNS}: use coarser steps"),
            ));
        }
        Ok(Spec {
            goals,
            max_pitch_radius,
            max_beam_length,
            clamp,
            clutch_thickness,
            materials,
            beams,
            radii,
            pitch_radii,
            lengths,
        })
    }
}

fn material_list() -> String {
    let mut t = Table::new(&[
        ("material", ""),
        ("E", "GPa"),
        ("G", "GPa"),
        ("σ_allow", "MPa"),
        ("σ_allow/E", ""),
        ("ρ", "kg/m³"),
    ]);
    for m in &MATERIALS {
        let e = f(m.youngs_modulus.get());
        let s = f(m.allowable_stress.get());
        t.row(vec![
            m.key.to_string(),
            sig(e / 1e3, 4),
            sig(f(m.shear_modulus.get()) / 1e3, 3),
            sig(s, 4),
            sig(s / e, 3),
            m.density_kg_m3.to_string(),
        ]);
    }
    let mut out = t.render();
    out.push_str("\nSources:\n");
    for m in &MATERIALS {
        out.push_str(&format!("  {} ({}): {}\n", m.key, m.name, m.source));
    }
    out
}

// ---------------------------------------------------------------------------------------
// The search

/// One evaluated design.
#[derive(Clone, Copy, Debug)]
pub struct Entry {
    material: &'static Material,
    params: DesignParams,
    total_length: Length,
    s: Sizing,
    meets: [bool; 5],
    /// Relative margins of capacity, deflection, mass, volume (negative: missed).
    margins: [f64; 4],
}

impl Entry {
    fn feasible(&self) -> bool {
        self.meets.iter().all(|&m| m)
    }

    /// The smallest of the four relative margins.
    fn margin(&self) -> f64 {
        self.margins.iter().copied().fold(f64::INFINITY, f64::min)
    }

    fn capacity(&self) -> f64 {
        f(self.s.capacity_soft.get())
    }

    fn deflection(&self) -> f64 {
        f(self.s.deflection_soft.get())
    }

    fn mass_g(&self) -> f64 {
        f(self.s.mass_g)
    }
}

/// Result of a search.
pub struct Found {
    entries: Vec<Entry>,
    rejected_by_model: usize,
    /// Indices into `entries`: feasible ranked by margin, or the closest ones.
    ranked: Vec<usize>,
    feasible: usize,
    pareto: Vec<usize>,
    binding: Option<Constraint>,
    relaxed: Vec<(Constraint, usize)>,
}

fn search(spec: &Spec) -> CliResult<Found> {
    let g = &spec.goals;
    let mut entries = Vec::new();
    let mut rejected = 0usize;
    for &m in &spec.materials {
        for &n in &spec.beams {
            for &r in &spec.radii {
                for &big_r in &spec.pitch_radii {
                    for &l in &spec.lengths {
                        let p = DesignParams {
                            beams: n,
                            beam_radius: r,
                            pitch_radius: big_r,
                            youngs_modulus: m.youngs_modulus,
                            shear_modulus: m.isotropic_shear(),
                            allowable_stress: m.allowable_stress,
                            beam_length: l,
                            clutch_thickness: spec.clutch_thickness,
                            friction: DesignParams::PAPER.friction,
                        };
                        let Ok(design) = Design::new(p) else {
                            rejected += 1;
                            continue;
                        };
                        let total_length =
                            Length::from_fixed(l.get().saturating_add(spec.clamp.get()));
                        let c = Candidate {
                            design,
                            total_length,
                            density_kg_m3: m.density_kg_m3,
                        };
                        let Ok(s) = c.size() else {
                            rejected += 1;
                            continue;
                        };
                        let meets = Constraint::ALL.map(|c| s.meets(c, g));
                        let margins = [
                            f(s.capacity_soft.get()) / f(g.min_capacity.get()) - 1.0,
                            f(s.deflection_soft.get()) / f(g.min_deflection.get()) - 1.0,
                            1.0 - f(s.mass_g) / f(g.max_mass_g),
                            1.0 - f(s.volume_mm3) / f(g.max_volume_mm3),
                        ];
                        entries.push(Entry {
                            material: m,
                            params: p,
                            total_length,
                            s,
                            meets,
                            margins,
                        });
                    }
                }
            }
        }
    }
    let by_margin = |a: &usize, b: &usize| {
        entries[*b]
            .margin()
            .partial_cmp(&entries[*a].margin())
            .unwrap_or(Ordering::Equal)
    };
    let mut feasible: Vec<usize> = (0..entries.len())
        .filter(|&i| entries[i].feasible())
        .collect();
    feasible.sort_by(by_margin);
    let n_feasible = feasible.len();
    let (ranked, binding) = if feasible.is_empty() {
        let mut fit: Vec<usize> = (0..entries.len()).filter(|&i| entries[i].s.fits).collect();
        fit.sort_by(by_margin);
        let binding = fit.first().map(|&i| {
            let e = &entries[i];
            let worst = (0..4)
                .min_by(|&a, &b| {
                    e.margins[a]
                        .partial_cmp(&e.margins[b])
                        .unwrap_or(Ordering::Equal)
                })
                .unwrap_or(0);
            Constraint::ALL[worst]
        });
        (fit, binding.or(Some(Constraint::Fit)))
    } else {
        (feasible, None)
    };
    let relaxed = Constraint::ALL
        .iter()
        .enumerate()
        .map(|(k, &c)| {
            let count = entries
                .iter()
                .filter(|e| e.meets.iter().enumerate().all(|(j, &m)| j == k || m))
                .count();
            (c, count)
        })
        .collect();
    let pareto = pareto_front(&entries);
    Ok(Found {
        entries,
        rejected_by_model: rejected,
        ranked,
        feasible: n_feasible,
        pareto,
        binding,
        relaxed,
    })
}

/// Total order on finite f64 (the sizes are finite).
#[derive(Clone, Copy, Debug)]
struct Key(f64);
impl PartialEq for Key {
    fn eq(&self, o: &Self) -> bool {
        self.cmp(o) == Ordering::Equal
    }
}
impl Eq for Key {}
impl PartialOrd for Key {
    fn partial_cmp(&self, o: &Self) -> Option<Ordering> {
        Some(self.cmp(o))
    }
}
impl Ord for Key {
    fn cmp(&self, o: &Self) -> Ordering {
        self.0.total_cmp(&o.0)
    }
}

/// Indices of the designs within the envelope (slots fit, mass and volume within their
/// limits) that are not dominated in
/// (capacity ↑, deflection ↑, mass ↓): sweep by mass, keep the (capacity, deflection)
/// staircase of the lighter designs.
fn pareto_front(entries: &[Entry]) -> Vec<usize> {
    let mut idx: Vec<usize> = (0..entries.len())
        .filter(|&i| entries[i].meets[2] && entries[i].meets[3] && entries[i].meets[4])
        .collect();
    idx.sort_by(|&a, &b| {
        let (x, y) = (&entries[a], &entries[b]);
        x.mass_g()
            .total_cmp(&y.mass_g())
            .then(y.capacity().total_cmp(&x.capacity()))
            .then(y.deflection().total_cmp(&x.deflection()))
    });
    // capacity → deflection, deflection falling as capacity rises.
    let mut stair: BTreeMap<Key, f64> = BTreeMap::new();
    let mut front = Vec::new();
    for i in idx {
        let (c, d) = (entries[i].capacity(), entries[i].deflection());
        if let Some((_, &best)) = stair.range(Key(c)..).next() {
            if best >= d {
                continue;
            }
        }
        let dominated: Vec<Key> = stair
            .range(..=Key(c))
            .filter(|(_, &dd)| dd <= d)
            .map(|(k, _)| *k)
            .collect();
        for k in dominated {
            stair.remove(&k);
        }
        stair.insert(Key(c), d);
        front.push(i);
    }
    front
}

// ---------------------------------------------------------------------------------------
// Output

#[derive(Serialize)]
struct JsonDesign {
    material: &'static str,
    beams: u8,
    beam_radius_m: f64,
    pitch_radius_m: f64,
    active_length_min_m: f64,
    active_length_max_m: f64,
    beam_length_m: f64,
    capacity_nm: f64,
    deflection_capacity_rad: f64,
    capacity_stiff_nm: f64,
    deflection_stiff_rad: f64,
    stiffness_min_nm_per_rad: f64,
    stiffness_max_nm_per_rad: f64,
    energy_j: f64,
    mass_kg: f64,
    volume_m3: f64,
    free_play_rad: f64,
    backlash_tilt_soft_rad: f64,
    backlash_tilt_stiff_rad: f64,
    fits: bool,
    margin: f64,
    meets_constraints: bool,
}

impl JsonDesign {
    fn of(e: &Entry) -> JsonDesign {
        let s = &e.s;
        let mm = |l: Length| f(l.get()) * 1e-3;
        JsonDesign {
            material: e.material.key,
            beams: e.params.beams,
            beam_radius_m: mm(e.params.beam_radius),
            pitch_radius_m: mm(e.params.pitch_radius),
            active_length_min_m: mm(e.params.clutch_thickness),
            active_length_max_m: mm(e.params.beam_length),
            beam_length_m: mm(e.total_length),
            capacity_nm: e.capacity(),
            deflection_capacity_rad: e.deflection(),
            capacity_stiff_nm: f(s.capacity_stiff.get()),
            deflection_stiff_rad: f(s.deflection_stiff.get()),
            stiffness_min_nm_per_rad: s.stiffness_min.get().to_num(),
            stiffness_max_nm_per_rad: s.stiffness_max.get().to_num(),
            energy_j: f(s.energy_j),
            mass_kg: e.mass_g() * 1e-3,
            volume_m3: f(s.volume_mm3) * 1e-9,
            free_play_rad: f(s.free_play.get()),
            backlash_tilt_soft_rad: f(s.backlash_tilt.0.get()),
            backlash_tilt_stiff_rad: f(s.backlash_tilt.1.get()),
            fits: s.fits,
            margin: e.margin(),
            meets_constraints: e.feasible(),
        }
    }
}

#[derive(Serialize)]
struct JsonGoals {
    min_capacity_nm: f64,
    min_deflection_rad: f64,
    max_mass_kg: f64,
    max_volume_m3: f64,
    max_pitch_radius_m: f64,
    max_beam_length_m: f64,
    clamp_length_m: f64,
    clutch_thickness_m: f64,
}

#[derive(Serialize)]
struct JsonMaterial {
    key: &'static str,
    name: &'static str,
    modulus_pa: f64,
    shear_modulus_pa: f64,
    allowable_stress_pa: f64,
    density_kg_m3: u32,
    min_active_length_m: f64,
    source: &'static str,
}

#[derive(Serialize)]
struct JsonFound {
    goals: JsonGoals,
    evaluated: usize,
    rejected_by_model: usize,
    feasible: usize,
    binding: Option<&'static str>,
    relaxed: HashMap<&'static str, usize>,
    materials: Vec<JsonMaterial>,
    designs: Vec<JsonDesign>,
    pareto: Vec<JsonDesign>,
}

/// The shortest active length with which beams of `m` can meet the capacity and deflection
/// goals at once, whatever n, r and R (packed side by side, n → ∞; docs/design.md §10):
/// L³ = 36·T·E²·θ²/(π²·σ³), m.
fn min_active_length(m: &Material, g: &Goals) -> f64 {
    let e = f(m.youngs_modulus.get()) * 1e6;
    let s = f(m.allowable_stress.get()) * 1e6;
    let t = f(g.min_capacity.get());
    let th = f(g.min_deflection.get());
    let pi = std::f64::consts::PI;
    (36.0 * t * e * e * th * th / (pi * pi * s.powi(3))).cbrt()
}

impl Found {
    fn to_json(&self, spec: &Spec, args: &ExploreArgs) -> JsonFound {
        let g = &spec.goals;
        let mm = |l: Length| f(l.get()) * 1e-3;
        let designs = if args.all {
            self.entries.iter().map(JsonDesign::of).collect()
        } else {
            self.ranked
                .iter()
                .take(args.top.unwrap_or(10))
                .map(|&i| JsonDesign::of(&self.entries[i]))
                .collect()
        };
        JsonFound {
            goals: JsonGoals {
                min_capacity_nm: f(g.min_capacity.get()),
                min_deflection_rad: f(g.min_deflection.get()),
                max_mass_kg: f(g.max_mass_g) * 1e-3,
                max_volume_m3: f(g.max_volume_mm3) * 1e-9,
                max_pitch_radius_m: mm(spec.max_pitch_radius),
                max_beam_length_m: mm(spec.max_beam_length),
                clamp_length_m: mm(spec.clamp),
                clutch_thickness_m: mm(spec.clutch_thickness),
            },
            evaluated: self.entries.len(),
            rejected_by_model: self.rejected_by_model,
            feasible: self.feasible,
            binding: self.binding.map(Constraint::name),
            relaxed: self.relaxed.iter().map(|(c, n)| (c.name(), *n)).collect(),
            materials: spec
                .materials
                .iter()
                .map(|m| JsonMaterial {
                    key: m.key,
                    name: m.name,
                    modulus_pa: f(m.youngs_modulus.get()) * 1e6,
                    shear_modulus_pa: f(m.shear_modulus.get()) * 1e6,
                    allowable_stress_pa: f(m.allowable_stress.get()) * 1e6,
                    density_kg_m3: m.density_kg_m3,
                    min_active_length_m: min_active_length(m, g),
                    source: m.source,
                })
                .collect(),
            designs,
            pareto: self
                .pareto
                .iter()
                .map(|&i| JsonDesign::of(&self.entries[i]))
                .collect(),
        }
    }

    fn table(&self, idx: &[usize]) -> String {
        let mut t = Table::new(&[
            ("material", ""),
            ("n", ""),
            ("r", "mm"),
            ("R", "mm"),
            ("l", "mm"),
            ("τ_cap(l)", "N·m"),
            ("θ_cap(l)", "rad"),
            ("k", "N·m/rad"),
            ("E_cap", "mJ"),
            ("mass", "g"),
            ("volume", "cm³"),
            ("φ_b", "mrad"),
            ("margin", "%"),
        ]);
        for &i in idx {
            let e = &self.entries[i];
            let s = &e.s;
            t.row(vec![
                e.material.key.to_string(),
                e.params.beams.to_string(),
                sig(f(e.params.beam_radius.get()), 3),
                sig(f(e.params.pitch_radius.get()), 3),
                sig(f(e.params.beam_length.get()), 3),
                sig(e.capacity(), 3),
                sig(e.deflection(), 3),
                format!(
                    "{}–{}",
                    sig(s.stiffness_min.get().to_num(), 3),
                    sig(s.stiffness_max.get().to_num(), 3)
                ),
                sig(f(s.energy_j) * 1e3, 3),
                sig(e.mass_g(), 3),
                sig(f(s.volume_mm3) * 1e-3, 3),
                sig(f(s.free_play.get()) * 1e3, 3),
                format!("{:+.1}", e.margin() * 100.0),
            ]);
        }
        t.render()
    }

    fn render(&self, spec: &Spec, top: usize) -> String {
        let g = &spec.goals;
        let mut out = format!(
            "Goals: capacity ≥ {} N·m over the travel, safe deflection ≥ {} rad at the softest \
setting, beam mass ≤ {} g, envelope ≤ {} cm³; R ≤ {} mm, beams ≤ {} mm ({} mm clamped), \
t_c = {} mm.\n{} designs evaluated ({} combinations the model rejects), {} meet every \
constraint.\n\n",
            sig(f(g.min_capacity.get()), 4),
            sig(f(g.min_deflection.get()), 4),
            sig(f(g.max_mass_g), 4),
            sig(f(g.max_volume_mm3) * 1e-3, 4),
            sig(f(spec.max_pitch_radius.get()), 4),
            sig(f(spec.max_beam_length.get()), 4),
            sig(f(spec.clamp.get()), 4),
            sig(f(spec.clutch_thickness.get()), 4),
            self.entries.len(),
            self.rejected_by_model,
            self.feasible,
        );
        let shown: Vec<usize> = self.ranked.iter().take(top).copied().collect();
        if self.feasible > 0 {
            out.push_str("Designs meeting every constraint, best margin first:\n");
            out.push_str(&self.table(&shown));
        } else {
            out.push_str(&format!(
                "No design meets every constraint. Binding: {}.\n",
                self.binding.map_or("none", Constraint::name)
            ));
            out.push_str("Designs meeting every constraint but one:\n");
            for (c, n) in &self.relaxed {
                out.push_str(&format!("  without {:<10} {n}\n", c.name()));
            }
            out.push_str("\nClosest designs (slots fit; largest smallest margin first):\n");
            out.push_str(&self.table(&shown));
        }
        out.push_str(
            "\nShortest active length any design of each material needs for the capacity and \
deflection goals together (L³ = 36·T·E²·θ²/(π²·σ³)):\n",
        );
        for m in &spec.materials {
            out.push_str(&format!(
                "  {:<17} {} mm\n",
                m.key,
                sig(min_active_length(m, g) * 1e3, 3)
            ));
        }
        out.push_str(&format!(
            "\nPareto front (capacity ↑, deflection ↑, mass ↓; slots fit, within the mass and \
volume): {} designs; the {} with the most stored energy:\n",
            self.pareto.len(),
            top.min(self.pareto.len())
        ));
        let mut best: Vec<usize> = self.pareto.clone();
        best.sort_by(|&a, &b| {
            f(self.entries[b].s.energy_j).total_cmp(&f(self.entries[a].s.energy_j))
        });
        best.truncate(top);
        out.push_str(&self.table(&best));
        out
    }
}

// ---------------------------------------------------------------------------------------
// The figure

/// Upper-right boundary of (capacity, deflection) over `pts`: for rising capacity, the
/// largest deflection reachable at that capacity or more.
fn boundary(mut pts: Vec<(f64, f64)>) -> Vec<(f64, f64)> {
    pts.sort_by(|a, b| b.0.total_cmp(&a.0));
    let mut best = f64::NEG_INFINITY;
    let mut out = Vec::new();
    for (c, d) in pts {
        if d > best {
            best = d;
            out.push((c, d));
        }
    }
    out.reverse();
    out
}

fn write_figure(spec: &Spec, found: &Found, path: &std::path::Path) -> CliResult<()> {
    crate::figures::plot::register_font().map_err(CliError::runtime)?;
    let g = &spec.goals;
    // The region near the goal: capacities up to 4 times the goal's.
    let x_max = 4.0 * f(g.min_capacity.get());
    let mut series = Vec::new();
    for (ci, m) in spec.materials.iter().enumerate() {
        let pts: Vec<(f64, f64)> = found
            .entries
            .iter()
            .filter(|e| std::ptr::eq(e.material, *m) && e.meets[2] && e.meets[3] && e.meets[4])
            .map(|e| (e.capacity(), e.deflection()))
            .collect();
        series.push(Series {
            label: Some(format!("{} (within mass and volume)", m.key)),
            points: boundary(pts).into_iter().filter(|p| p.0 <= x_max).collect(),
            color: COLORS[ci % COLORS.len()],
            dashed: ci >= COLORS.len(),
            marker: false,
        });
    }
    let paper = Design::paper();
    let l5 = Length::from_int(5);
    let black = plotters::style::RGBColor(0, 0, 0);
    if let (Ok(c), Ok(d)) = (paper.torque_capacity(l5), paper.deflection_capacity(l5)) {
        series.push(Series {
            label: Some("paper design at L = 5 mm".into()),
            points: vec![(f(c.get()), f(d.get()))],
            color: plotters::style::RGBColor(120, 120, 120),
            dashed: false,
            marker: true,
        });
    }
    series.push(Series {
        label: Some("goal".into()),
        points: vec![(f(g.min_capacity.get()), f(g.min_deflection.get()))],
        color: black,
        dashed: false,
        marker: true,
    });
    let fig = Figure {
        title: format!(
            "Achievable beam designs — beams ≤ {} mm ({} mm clamped), R ≤ {} mm, ≤ {} g, ≤ {} cm³",
            sig(f(spec.max_beam_length.get()), 3),
            sig(f(spec.clamp.get()), 3),
            sig(f(spec.max_pitch_radius.get()), 3),
            sig(f(g.max_mass_g), 3),
            sig(f(g.max_volume_mm3) * 1e-3, 3)
        ),
        panels: vec![Panel {
            caption: "each curve: the largest safe deflection reachable at each capacity or \
more (the achievable region lies below it)"
                .into(),
            x_label: "torque capacity τ_cap at the softest setting (N·m)".into(),
            y_label: "safe deflection θ_cap at the softest setting (rad)".into(),
            log_y: true,
            y_zero: false,
            headroom: 0.0,
            x_margin: 0.02,
            series,
            legend: SeriesLabelPosition::UpperRight,
        }],
        size: (1300, 800),
    };
    write_atomic(path, |tmp| fig.write_file(tmp, false))
}

/// Writes a figure to `path` whole or not at all ([`crate::output::write_atomically`]); an
/// image format the writer does not know is a usage error of `--figure`. Shared with
/// `vsa advise`.
pub fn write_atomic(
    path: &std::path::Path,
    write: impl FnOnce(&std::path::Path) -> Result<(), String>,
) -> CliResult<()> {
    if path.file_name().and_then(|n| n.to_str()).is_none() {
        return Err(CliError::usage(
            "--figure",
            format!("{}: not a file name", path.display()),
        ));
    }
    crate::output::write_atomically(path, write).map_err(|e| {
        if e.contains("unknown image format") {
            CliError::usage("--figure", e)
        } else {
            CliError::runtime(e)
        }
    })
}
