//! `vsa design`: the design calculator (design.md §2).
//!
//! Parses the design (paper preset unless overridden), lets [`model::Design::new`] validate
//! it, computes a [`Report`] with the model crate, then renders it as a table or as JSON.
//! Every number printed comes from the model's fixed-point functions; the host only converts
//! units for display (mm → m, MPa → Pa, rad → °), with one exception, the second moment of
//! area I in the header, which the model does not expose (see [`second_moment_mm4`]).
//!
//! # JSON (`--json`)
//!
//! One object, SI units, exactly these keys. For a list of clutch lengths:
//!
//! ```text
//! {
//!   "design": {
//!     "beams": 4,                      // n
//!     "beam_radius_m": 0.0005,         // r
//!     "pitch_radius_m": 0.0078,        // R
//!     "modulus_pa": 2e11,              // E
//!     "shear_modulus_pa": 8e10,        // G
//!     "allowable_stress_pa": 1.5e9,    // σ_allow
//!     "beam_length_m": 0.008,          // l
//!     "clutch_thickness_m": 0.001      // t_c
//!   },
//!   "torque_nm": 2.0,                  // the load T
//!   "rows": [{
//!     "length_m": 0.001,               // clutch length L
//!     "stiffness_nm_per_rad": …,       // k, Euler–Bernoulli (paper eq. 4)
//!     "stiffness_shear_nm_per_rad": …, // k_T, shear-corrected (Timoshenko)
//!     "deflection_rad": …,             // θ = T/k (E–B)
//!     "beam_force_n": …,               // P = T/(n·R)
//!     "stress_pa": …,                  // σ = P·L·r/I at the beam root
//!     "torque_capacity_nm": …,         // τ_cap, σ = σ_allow
//!     "deflection_capacity_rad": …,    // θ_cap = τ_cap/k (E–B)
//!     "backlash_tilt_rad": …           // θ_b, paper eq. 7; null unless t_c ≤ L ≤ l
//!   }, …]
//! }
//! ```
//!
//! For `--stiffness K`: `{"stiffness_nm_per_rad", "clutch_length_m",
//! "clutch_length_shear_m"}`, the clutch lengths for k = K with the E–B and the shear-corrected
//! model, null where K is outside that model's adjustable range [k(l), k(t_c)].
//!
//! Any value outside its domain or format for one row is null and the rest of the row stands.

use clap::Args;
use fixed::types::I32F32;
use model::beam::BeamModel;
use model::design::{
    ALLOWABLE_STRESS_MAX, ALLOWABLE_STRESS_MIN, BEAMS_MAX, BEAMS_MIN, BEAM_LENGTH_MAX,
    BEAM_LENGTH_MIN, BEAM_RADIUS_MAX, BEAM_RADIUS_MIN, CLUTCH_THICKNESS_MIN, FRICTION_MAX,
    MODULUS_MAX, MODULUS_MIN, PITCH_RADIUS_MAX, PITCH_RADIUS_MIN,
};
use model::{Angle, Design, DesignParams, Force, Length, Ratio, Stiffness, Stress, Torque};
use serde::Serialize;

use crate::error::{CliError, CliResult};
use crate::format::{opt, sig, trim, Table, NONE};
use crate::units::{self, Decimal, Kind, Quantity};

/// Largest number of clutch lengths one `--lengths` range may produce.
const MAX_ROWS: u32 = 1000;

/// Stiffness, deflection, stress, capacity and backlash of a beam design.
///
/// Defaults are the paper preset (design.md §2.2). Values take units: lengths `0.5mm`,
/// `500um`, `8e-3m`; moduli and stresses `200GPa`, `1500MPa`, `80e9Pa`; torques `2Nm`,
/// `300mNm`, `2N*m`; stiffness `500Nm/rad`.
#[derive(Args, Debug, Default)]
#[command(
    after_help = "Defaults: the paper preset (design.md §2.2). Values need units: \
lengths 0.5mm, 500um, 8e-3m; moduli and stresses 200GPa, 1500MPa, 80e9Pa; torques 2Nm, \
300mNm, 2N*m; stiffness 500Nm/rad.\n\nBad input: one line on stderr, exit code 2."
)]
pub struct DesignArgs {
    /// Number of beams n, 1..=16 [default: 4]
    #[arg(long, value_name = "N", allow_hyphen_values = true)]
    pub beams: Option<String>,
    /// Beam radius r [default: 0.5mm]
    #[arg(long, value_name = "R", allow_hyphen_values = true)]
    pub beam_radius: Option<String>,
    /// Pitch radius R, gear centre to beam centre [default: 7.8mm]
    #[arg(long, value_name = "R", allow_hyphen_values = true)]
    pub pitch_radius: Option<String>,
    /// Young's modulus E [default: 200GPa]
    #[arg(long, value_name = "E", allow_hyphen_values = true)]
    pub modulus: Option<String>,
    /// Shear modulus G [default: 80GPa]
    #[arg(long, value_name = "G", allow_hyphen_values = true)]
    pub shear_modulus: Option<String>,
    /// Allowable bending stress σ_allow [default: 1500MPa]
    #[arg(long, value_name = "S", allow_hyphen_values = true)]
    pub allowable_stress: Option<String>,
    /// Total usable beam length l, the softest setting [default: 8mm]
    #[arg(long, value_name = "L", allow_hyphen_values = true)]
    pub beam_length: Option<String>,
    /// Clutch plate thickness t_c, the stiffest setting [default: 1mm]
    #[arg(long, value_name = "T", allow_hyphen_values = true)]
    pub clutch_thickness: Option<String>,
    /// Kinetic friction coefficient μ, a bare number [default: 0.4]
    #[arg(long, value_name = "MU", allow_hyphen_values = true)]
    pub friction: Option<String>,
    /// Clutch lengths L: a list `1mm,2mm,3mm` or a range `START..END:STEP` [default: 1mm..5mm:1mm]
    #[arg(
        long,
        value_name = "LIST|RANGE",
        allow_hyphen_values = true,
        conflicts_with = "stiffness"
    )]
    pub lengths: Option<String>,
    /// Load torque T for deflection, force and stress [default: 2Nm]
    #[arg(
        long,
        value_name = "T",
        allow_hyphen_values = true,
        conflicts_with = "stiffness"
    )]
    pub torque: Option<String>,
    /// Instead of a table: the clutch length for this stiffness, e.g. 250Nm/rad
    #[arg(long, value_name = "K", allow_hyphen_values = true)]
    pub stiffness: Option<String>,
    /// Print one JSON object (SI units) instead of the table
    #[arg(long)]
    pub json: bool,
}

/// Runs `vsa design`; returns what to print on stdout.
pub fn run(args: &DesignArgs) -> CliResult<String> {
    let design = parse_design(args)?;
    if let Some(k) = &args.stiffness {
        let k = parse_stiffness(k)?;
        let inv = Inverse::compute(&design, k);
        return Ok(if args.json {
            json(&inv.to_json())?
        } else {
            inv.render(&design)
        });
    }
    let torque = match &args.torque {
        Some(t) => parse_torque(t)?,
        None => Torque::from_int(2),
    };
    let lengths = parse_lengths(args.lengths.as_deref().unwrap_or("1mm..5mm:1mm"), &design)?;
    let report = Report::compute(design, torque, &lengths);
    Ok(if args.json {
        json(&report.to_json())?
    } else {
        report.render()
    })
}

fn json<T: Serialize>(v: &T) -> CliResult<String> {
    serde_json::to_string_pretty(v)
        .map(|s| s + "\n")
        .map_err(|e| CliError::runtime(format!("cannot encode JSON: {e}")))
}

// ---------------------------------------------------------------------------------------
// Parsing and validation

/// A model value as f64 for printing (exact: every I32F32 value is an f64).
pub(crate) fn to_f64(x: I32F32) -> f64 {
    x.to_num::<f64>()
}

/// A parsed design parameter with the argument it came from, for messages.
struct Given {
    arg: &'static str,
    q: Quantity,
}

impl Given {
    /// The value as the user gave it, in the unit `unit` (10^unit_exp model units).
    fn shown(&self, unit_exp: i32, unit: &str) -> String {
        format!("{} {unit}", self.q.value_in(unit_exp))
    }
}

fn quantity(arg: &'static str, s: &Option<String>, kind: Kind) -> CliResult<Option<Given>> {
    s.as_deref()
        .map(|s| {
            units::parse(s, kind)
                .map(|q| Given { arg, q })
                .map_err(|e| CliError::usage(arg, e))
        })
        .transpose()
}

fn range_mm(lo: Length, hi: Length) -> String {
    format!(
        "[{}, {}] mm",
        trim(to_f64(lo.get())),
        trim(to_f64(hi.get()))
    )
}

fn range_gpa(lo: Stress, hi: Stress) -> String {
    format!(
        "[{}, {}] GPa",
        trim(to_f64(lo.get()) / 1e3),
        trim(to_f64(hi.get()) / 1e3)
    )
}

/// The design from the arguments over the paper preset, validated by the model.
pub fn parse_design(args: &DesignArgs) -> CliResult<Design> {
    let mut p = DesignParams::PAPER;
    let beams_given = args
        .beams
        .as_deref()
        .map(|s| {
            let t = s.trim();
            t.parse::<u8>().map_err(|_| {
                CliError::usage(
                    "--beams",
                    format!("'{s}' is not a whole number in {BEAMS_MIN}..={BEAMS_MAX}"),
                )
            })
        })
        .transpose()?;
    if let Some(n) = beams_given {
        p.beams = n;
    }
    let r = quantity("--beam-radius", &args.beam_radius, Kind::Length)?;
    let big_r = quantity("--pitch-radius", &args.pitch_radius, Kind::Length)?;
    let e = quantity("--modulus", &args.modulus, Kind::Pressure)?;
    let g = quantity("--shear-modulus", &args.shear_modulus, Kind::Pressure)?;
    let s = quantity("--allowable-stress", &args.allowable_stress, Kind::Pressure)?;
    let l = quantity("--beam-length", &args.beam_length, Kind::Length)?;
    let tc = quantity("--clutch-thickness", &args.clutch_thickness, Kind::Length)?;
    let mu = args
        .friction
        .as_deref()
        .map(|s| units::parse_ratio(s).map_err(|e| CliError::usage("--friction", e)))
        .transpose()?;

    // Out-of-format values saturate, so that the model's range check reports them.
    let sat = |g: &Option<Given>| g.as_ref().map(|g| g.q.value.to_i32f32_saturating());
    if let Some(v) = sat(&r) {
        p.beam_radius = Length::from_fixed(v);
    }
    if let Some(v) = sat(&big_r) {
        p.pitch_radius = Length::from_fixed(v);
    }
    if let Some(v) = sat(&e) {
        p.youngs_modulus = Stress::from_fixed(v);
    }
    if let Some(v) = sat(&g) {
        p.shear_modulus = Stress::from_fixed(v);
    }
    if let Some(v) = sat(&s) {
        p.allowable_stress = Stress::from_fixed(v);
    }
    if let Some(v) = sat(&l) {
        p.beam_length = Length::from_fixed(v);
    }
    if let Some(v) = sat(&tc) {
        p.clutch_thickness = Length::from_fixed(v);
    }
    if let Some((_, v)) = mu {
        p.friction = v;
    }

    Design::new(p).map_err(|err| {
        use model::Error as E;
        // The argument at fault, the value as given (or the preset's), and the bound.
        let shown = |g: &Option<Given>, exp: i32, unit: &str, preset: f64| {
            g.as_ref()
                .map_or_else(|| format!("{} {unit}", trim(preset)), |g| g.shown(exp, unit))
        };
        let arg = |g: &Option<Given>, default: &'static str| g.as_ref().map_or(default, |g| g.arg);
        let pp = DesignParams::PAPER;
        match err {
            E::BeamCountOutOfRange => CliError::usage(
                "--beams",
                format!("{} is out of range {BEAMS_MIN}..={BEAMS_MAX}", p.beams),
            ),
            E::BeamRadiusOutOfRange => CliError::usage(
                "--beam-radius",
                format!(
                    "{} is out of range {}",
                    shown(&r, 0, "mm", to_f64(pp.beam_radius.get())),
                    range_mm(BEAM_RADIUS_MIN, BEAM_RADIUS_MAX)
                ),
            ),
            E::PitchRadiusOutOfRange => {
                let v = shown(&big_r, 0, "mm", to_f64(pp.pitch_radius.get()));
                if p.pitch_radius >= PITCH_RADIUS_MIN && p.pitch_radius <= PITCH_RADIUS_MAX {
                    CliError::usage(
                        arg(&big_r, "--pitch-radius"),
                        format!(
                            "{v} must be larger than the beam radius r = {}",
                            shown(&r, 0, "mm", to_f64(pp.beam_radius.get()))
                        ),
                    )
                } else {
                    CliError::usage(
                        "--pitch-radius",
                        format!(
                            "{v} is out of range {}",
                            range_mm(PITCH_RADIUS_MIN, PITCH_RADIUS_MAX)
                        ),
                    )
                }
            }
            E::YoungsModulusOutOfRange => CliError::usage(
                "--modulus",
                format!(
                    "{} is out of range {}",
                    shown(&e, 3, "GPa", to_f64(pp.youngs_modulus.get()) / 1e3),
                    range_gpa(MODULUS_MIN, MODULUS_MAX)
                ),
            ),
            E::ShearModulusOutOfRange => CliError::usage(
                "--shear-modulus",
                format!(
                    "{} is out of range {}",
                    shown(&g, 3, "GPa", to_f64(pp.shear_modulus.get()) / 1e3),
                    range_gpa(MODULUS_MIN, MODULUS_MAX)
                ),
            ),
            E::PoissonRatioNonPhysical => CliError::usage(
                arg(&g, "--modulus"),
                format!(
                    "G = {} is below E/3 for E = {} (Poisson's ratio ν = E/(2G) − 1 above 0.5 is non-physical)",
                    shown(&g, 3, "GPa", to_f64(pp.shear_modulus.get()) / 1e3),
                    shown(&e, 3, "GPa", to_f64(pp.youngs_modulus.get()) / 1e3)
                ),
            ),
            E::AllowableStressOutOfRange => CliError::usage(
                "--allowable-stress",
                format!(
                    "{} is out of range [{}, {}] MPa",
                    shown(&s, 0, "MPa", to_f64(pp.allowable_stress.get())),
                    trim(to_f64(ALLOWABLE_STRESS_MIN.get())),
                    trim(to_f64(ALLOWABLE_STRESS_MAX.get()))
                ),
            ),
            E::BeamLengthOutOfRange => CliError::usage(
                "--beam-length",
                format!(
                    "{} is out of range {}",
                    shown(&l, 0, "mm", to_f64(pp.beam_length.get())),
                    range_mm(BEAM_LENGTH_MIN, BEAM_LENGTH_MAX)
                ),
            ),
            E::ClutchThicknessOutOfRange if tc.is_none() => CliError::usage(
                "--beam-length",
                format!(
                    "{} must be larger than the clutch thickness t_c = {}",
                    shown(&l, 0, "mm", to_f64(pp.beam_length.get())),
                    shown(&tc, 0, "mm", to_f64(pp.clutch_thickness.get()))
                ),
            ),
            E::ClutchThicknessOutOfRange => CliError::usage(
                "--clutch-thickness",
                format!(
                    "{} is out of range [{} mm, l = {}) (t_c must be below the beam length)",
                    shown(&tc, 0, "mm", to_f64(pp.clutch_thickness.get())),
                    trim(to_f64(CLUTCH_THICKNESS_MIN.get())),
                    shown(&l, 0, "mm", to_f64(pp.beam_length.get()))
                ),
            ),
            E::FrictionOutOfRange => CliError::usage(
                "--friction",
                format!(
                    "{} is out of range [0, {}]",
                    mu.map_or(Decimal::ZERO, |(d, _)| d),
                    trim(to_f64(FRICTION_MAX.get()))
                ),
            ),
            other => CliError::usage("design", other.to_string()),
        }
    })
}

fn parse_torque(s: &str) -> CliResult<Torque> {
    let q = units::parse(s, Kind::Torque).map_err(|e| CliError::usage("--torque", e))?;
    if q.value.negative {
        return Err(CliError::usage(
            "--torque",
            format!("{q} is negative: give the magnitude of the load"),
        ));
    }
    q.torque().ok_or_else(|| {
        CliError::usage(
            "--torque",
            format!(
                "{q} is too large (torques stay below {} N·m)",
                sig(to_f64(Torque::MAX.get()), 2)
            ),
        )
    })
}

fn parse_stiffness(s: &str) -> CliResult<Stiffness> {
    let q = units::parse(s, Kind::Stiffness).map_err(|e| CliError::usage("--stiffness", e))?;
    if q.value.negative || q.value.is_zero() {
        return Err(CliError::usage(
            "--stiffness",
            format!("{q} must be positive"),
        ));
    }
    let k = q.stiffness().ok_or_else(|| {
        CliError::usage(
            "--stiffness",
            format!(
                "{q} is too large (stiffness stays below {} N·m/rad)",
                sig(Stiffness::MAX.get().to_num::<f64>(), 2)
            ),
        )
    })?;
    if k == Stiffness::ZERO {
        return Err(CliError::usage(
            "--stiffness",
            format!("{q} rounds to zero"),
        ));
    }
    Ok(k)
}

/// Clutch lengths from `1mm,2mm` or `1mm..5mm:1mm` (end included), each in (0, l].
pub fn parse_lengths(s: &str, design: &Design) -> CliResult<Vec<Length>> {
    const ARG: &str = "--lengths";
    let q = |t: &str| units::parse(t, Kind::Length).map_err(|e| CliError::usage(ARG, e));
    let decimals: Vec<Decimal> = if let Some((start, rest)) = s.split_once("..") {
        let Some((end, step)) = rest.split_once(':') else {
            return Err(CliError::usage(
                ARG,
                format!("'{s}' is not a range START..END:STEP (e.g. 1mm..5mm:1mm)"),
            ));
        };
        let (a, b, st) = (q(start)?.value, q(end)?.value, q(step)?.value);
        if st.negative || st.is_zero() {
            return Err(CliError::usage(
                ARG,
                format!("step {st} mm must be positive"),
            ));
        }
        if b.cmp_value(a).is_lt() {
            return Err(CliError::usage(
                ARG,
                format!("range end {b} mm is below its start {a} mm"),
            ));
        }
        let mut v = Vec::new();
        for i in 0.. {
            let x = a.add_times(i, st).ok_or_else(|| {
                CliError::usage(ARG, format!("'{s}' cannot be enumerated exactly"))
            })?;
            if x.cmp_value(b).is_gt() {
                break;
            }
            if i >= MAX_ROWS {
                return Err(CliError::usage(
                    ARG,
                    format!("'{s}' gives more than {MAX_ROWS} lengths"),
                ));
            }
            v.push(x);
        }
        v
    } else {
        s.split(',')
            .map(|t| q(t).map(|q| q.value))
            .collect::<CliResult<_>>()?
    };
    if decimals.len() > MAX_ROWS as usize {
        return Err(CliError::usage(
            ARG,
            format!("more than {MAX_ROWS} lengths"),
        ));
    }
    let l = design.params().beam_length;
    decimals
        .into_iter()
        .map(|d| {
            let len = Length::from_fixed(d.to_i32f32_saturating());
            if len <= Length::ZERO || len > l {
                Err(CliError::usage(
                    ARG,
                    format!(
                        "{d} mm is out of range (0, {}] mm (0 < L ≤ beam length l)",
                        trim(to_f64(l.get()))
                    ),
                ))
            } else {
                Ok(len)
            }
        })
        .collect()
}

// ---------------------------------------------------------------------------------------
// The report

/// One clutch length: every quantity the model gives, `None` outside its domain or format.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Row {
    /// Clutch length L.
    pub length: Length,
    /// k(L), Euler–Bernoulli (paper eq. 4).
    pub stiffness: Option<Stiffness>,
    /// k_T(L), shear-corrected.
    pub stiffness_shear: Option<Stiffness>,
    /// θ = T/k (E–B).
    pub deflection: Option<Angle>,
    /// P = T/(n·R).
    pub beam_force: Option<Force>,
    /// σ = P·L·r/I.
    pub stress: Option<Stress>,
    /// τ_cap(L).
    pub torque_capacity: Option<Torque>,
    /// θ_cap(L) = τ_cap/k (E–B).
    pub deflection_capacity: Option<Angle>,
    /// θ_b(L), paper eq. 7 (only for t_c ≤ L ≤ l).
    pub backlash_tilt: Option<Angle>,
}

/// The calculator's result for a design, a load and a list of clutch lengths.
#[derive(Clone, Debug, PartialEq)]
pub struct Report {
    /// The validated design.
    pub design: Design,
    /// The load T.
    pub torque: Torque,
    /// One row per clutch length.
    pub rows: Vec<Row>,
}

impl Report {
    /// Computes every row with the model.
    pub fn compute(design: Design, torque: Torque, lengths: &[Length]) -> Report {
        let d = &design;
        let rows = lengths
            .iter()
            .map(|&len| Row {
                length: len,
                stiffness: d.stiffness(len).ok(),
                stiffness_shear: d.stiffness_timoshenko(len).ok(),
                deflection: d.deflection(torque, len).ok(),
                beam_force: d.beam_force(torque).ok(),
                stress: d.root_stress(torque, len).ok(),
                torque_capacity: d.torque_capacity(len).ok(),
                deflection_capacity: d.deflection_capacity(len).ok(),
                backlash_tilt: d.tilt_backlash(len).ok(),
            })
            .collect();
        Report {
            design,
            torque,
            rows,
        }
    }

    /// The JSON document (see the module docs).
    pub fn to_json(&self) -> JsonReport {
        let mm = |v: Length| si(to_f64(v.get()) * 1e-3);
        JsonReport {
            design: JsonDesign::of(&self.design),
            torque_nm: si(to_f64(self.torque.get())),
            rows: self
                .rows
                .iter()
                .map(|r| JsonRow {
                    length_m: mm(r.length),
                    stiffness_nm_per_rad: r.stiffness.map(|k| si(k64(k))),
                    stiffness_shear_nm_per_rad: r.stiffness_shear.map(|k| si(k64(k))),
                    deflection_rad: r.deflection.map(|a| si(to_f64(a.get()))),
                    beam_force_n: r.beam_force.map(|v| si(to_f64(v.get()))),
                    stress_pa: r.stress.map(|v| si(to_f64(v.get()) * 1e6)),
                    torque_capacity_nm: r.torque_capacity.map(|v| si(to_f64(v.get()))),
                    deflection_capacity_rad: r.deflection_capacity.map(|a| si(to_f64(a.get()))),
                    backlash_tilt_rad: r.backlash_tilt.map(|a| si(to_f64(a.get()))),
                })
                .collect(),
        }
    }

    /// The readable report: design header, table, then one warning line per overloaded L.
    pub fn render(&self) -> String {
        let p = self.design.params();
        let mut out = header(&self.design);
        let t = to_f64(self.torque.get());
        out.push_str(&format!("\nLoad T = {} N·m\n\n", trim(t)));
        let mut table = Table::new(&[
            ("L", "mm"),
            ("k (E–B)", "N·m/rad"),
            ("k (shear)", "N·m/rad"),
            ("θ at T", "rad"),
            ("θ at T", "°"),
            ("P/beam", "N"),
            ("σ root", "MPa"),
            ("σ_allow/σ", ""),
            ("τ_cap", "N·m"),
            ("θ_cap", "rad"),
            ("θ_b tilt", "rad"),
        ]);
        let sigma_allow = to_f64(p.allowable_stress.get());
        let mut warnings = String::new();
        for r in &self.rows {
            let theta = r.deflection.map(|a| to_f64(a.get()));
            let stress = r.stress.map(|s| to_f64(s.get()));
            table.row(vec![
                sig(to_f64(r.length.get()), 4),
                opt(r.stiffness.map(k64), 5),
                opt(r.stiffness_shear.map(k64), 5),
                opt(theta, 3),
                opt(theta.map(f64::to_degrees), 3),
                opt(r.beam_force.map(|v| to_f64(v.get())), 3),
                opt(stress, 3),
                // Safety factor: a ratio of the model's σ_allow and σ (display only).
                stress
                    .filter(|s| *s > 0.0)
                    .map_or_else(|| NONE.to_string(), |s| sig(sigma_allow / s, 3)),
                opt(r.torque_capacity.map(|v| to_f64(v.get())), 3),
                opt(r.deflection_capacity.map(|a| to_f64(a.get())), 3),
                opt(r.backlash_tilt.map(|a| to_f64(a.get())), 3),
            ]);
            match r.torque_capacity {
                Some(cap) if self.torque > cap => {
                    warnings.push_str(&format!(
                        "WARNING L = {} mm: {} N·m exceeds the stress-limited capacity {} N·m (σ = {} > σ_allow = {} MPa): the beams would yield\n",
                        sig(to_f64(r.length.get()), 4),
                        sig(t, 4),
                        sig(to_f64(cap.get()), 3),
                        stress.map_or_else(|| "beyond range".to_string(), |s| format!("{} MPa", sig(s, 4))),
                        trim(sigma_allow),
                    ));
                }
                None => warnings.push_str(&format!(
                    "WARNING L = {} mm: the torque capacity is out of range of the model's format\n",
                    sig(to_f64(r.length.get()), 4)
                )),
                Some(_) => {}
            }
        }
        out.push_str(&table.render());
        out.push_str(&format!(
            "\nk: paper eq. 4 (Euler–Bernoulli); shear: Timoshenko. θ, θ_cap: E–B. θ_b: beam-tilt backlash, paper eq. 7, defined for t_c ≤ L ≤ l ({NONE} outside).\n"
        ));
        if !warnings.is_empty() {
            out.push('\n');
            out.push_str(&warnings);
        }
        out
    }
}

/// The second moment of area I = π·r⁴/4 of one beam in mm⁴, for the header only.
///
/// The model computes I inside [`Design::new`] but does not expose it, so this one number
/// is computed on the host in f64 from the model's r; no other output depends on it.
pub fn second_moment_mm4(d: &Design) -> f64 {
    let r = to_f64(d.params().beam_radius.get());
    std::f64::consts::PI * r.powi(4) / 4.0
}

/// The design and its derived constants, as text.
pub fn header(d: &Design) -> String {
    let p = d.params();
    let preset = *p == DesignParams::PAPER;
    let mm = |v: Length| format!("{} mm", trim(to_f64(v.get())));
    let gpa = |v: Stress| format!("{} GPa", trim(to_f64(v.get()) / 1e3));
    let rad = |a: Angle| to_f64(a.get());
    let (l_min, l_max) = d.adjustable_range();
    let (k_soft, k_stiff) = d.stiffness_range(BeamModel::EulerBernoulli);
    let (kt_soft, kt_stiff) = d.stiffness_range(BeamModel::Timoshenko);
    let ratio = |r: Ratio| trim(to_f64(r.get()));
    let mut s = format!(
        "Design{}\n",
        if preset {
            " (paper preset, design.md §2.2)"
        } else {
            ""
        }
    );
    s += &format!(
        "  n = {} beams, r = {}, R = {}, E = {}, G = {} (ν = {}, κ = {})\n",
        p.beams,
        mm(p.beam_radius),
        mm(p.pitch_radius),
        gpa(p.youngs_modulus),
        gpa(p.shear_modulus),
        ratio(d.poisson_ratio()),
        sig(to_f64(d.shear_coefficient().get()), 4),
    );
    s += &format!(
        "  σ_allow = {} MPa, l = {}, t_c = {}, μ = {}\n",
        trim(to_f64(p.allowable_stress.get())),
        mm(p.beam_length),
        mm(p.clutch_thickness),
        ratio(p.friction),
    );
    s += "Derived\n";
    s += &format!("  I = πr⁴/4 = {} mm⁴\n", sig(second_moment_mm4(d), 6));
    s += &format!(
        "  δ_max = σ_allow·l²/(3Er) = {} mm, θ_max = δ_max/l = {} rad (eq. 5)\n",
        sig(to_f64(d.max_tip_deflection().get()), 4),
        sig(rad(d.bending_capacity()), 4),
    );
    s += &format!(
        "  slot clearance c = θ_max·t_c = {} mm, slot radius r + c = {} mm (eq. 6)\n",
        sig(to_f64(d.slot_clearance().get()), 4),
        sig(to_f64(d.slot_radius().get()), 4),
    );
    s += &format!(
        "  output free play φ_b = c/R = {} rad = {}°\n",
        sig(rad(d.free_play()), 4),
        sig(rad(d.free_play()).to_degrees(), 3),
    );
    s += &format!(
        "  adjustable range L ∈ [{}, {}] mm: k ∈ [{}, {}] N·m/rad (E–B), [{}, {}] N·m/rad (shear)\n",
        trim(to_f64(l_min.get())),
        trim(to_f64(l_max.get())),
        sig(k64(k_soft), 5),
        sig(k64(k_stiff), 5),
        sig(k64(kt_soft), 5),
        sig(k64(kt_stiff), 5),
    );
    s
}

fn k64(k: Stiffness) -> f64 {
    k.get().to_num::<f64>()
}

/// Rounds to 10 significant digits for JSON, about the resolution of the model's I32F32
/// results (2⁻³² of the unit): 7.8 mm is 0.0078, not 0.0078000000000466 (the nearest
/// I32F32 to 7.8, in metres).
fn si(x: f64) -> f64 {
    format!("{x:.9e}").parse().unwrap_or(x)
}

// ---------------------------------------------------------------------------------------
// Inverse: clutch length for a stiffness

/// Where a wanted stiffness falls for one beam model.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Fit {
    /// In the adjustable range, at this clutch length.
    At(Length),
    /// Softer than the softest setting: nearest end L = l with this k.
    TooSoft(Stiffness),
    /// Stiffer than the stiffest setting: nearest end L = t_c with this k.
    TooStiff(Stiffness),
    /// The model found no length (should not happen inside the range).
    Failed(model::Error),
}

/// The clutch length for a wanted stiffness, with both models.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Inverse {
    /// The wanted k.
    pub stiffness: Stiffness,
    /// Euler–Bernoulli (eq. 4 inverted).
    pub eb: Fit,
    /// Shear-corrected (Timoshenko).
    pub shear: Fit,
}

impl Inverse {
    /// Computes both fits.
    pub fn compute(d: &Design, k: Stiffness) -> Inverse {
        let fit = |m: BeamModel| {
            let (soft, stiff) = d.stiffness_range(m);
            if k < soft {
                Fit::TooSoft(soft)
            } else if k > stiff {
                Fit::TooStiff(stiff)
            } else {
                match m.clutch_length(d, k) {
                    Ok(l) => Fit::At(l),
                    Err(e) => Fit::Failed(e),
                }
            }
        };
        Inverse {
            stiffness: k,
            eb: fit(BeamModel::EulerBernoulli),
            shear: fit(BeamModel::Timoshenko),
        }
    }

    /// The JSON document (see the module docs).
    pub fn to_json(self) -> JsonInverse {
        let m = |fit: Fit| match fit {
            Fit::At(l) => Some(si(to_f64(l.get()) * 1e-3)),
            _ => None,
        };
        JsonInverse {
            stiffness_nm_per_rad: si(k64(self.stiffness)),
            clutch_length_m: m(self.eb),
            clutch_length_shear_m: m(self.shear),
        }
    }

    /// The readable answer.
    pub fn render(&self, d: &Design) -> String {
        let (t_c, l) = d.adjustable_range();
        let k = trim(k64(self.stiffness));
        let mut s = header(d);
        s += &format!("\nClutch length for k = {k} N·m/rad\n");
        for (name, fit, m) in [
            (
                "Euler–Bernoulli (eq. 4)",
                self.eb,
                BeamModel::EulerBernoulli,
            ),
            ("shear-corrected        ", self.shear, BeamModel::Timoshenko),
        ] {
            let (soft, stiff) = d.stiffness_range(m);
            let range = format!("[{}, {}] N·m/rad", sig(k64(soft), 5), sig(k64(stiff), 5));
            s += &match fit {
                Fit::At(len) => format!("  {name}  L = {} mm\n", sig(to_f64(len.get()), 5)),
                Fit::TooSoft(end) => format!(
                    "  {name}  {NONE}: k = {k} N·m/rad is below the adjustable range {range}; nearest end: L = l = {} mm (softest), k = {} N·m/rad\n",
                    trim(to_f64(l.get())),
                    sig(k64(end), 5)
                ),
                Fit::TooStiff(end) => format!(
                    "  {name}  {NONE}: k = {k} N·m/rad is above the adjustable range {range}; nearest end: L = t_c = {} mm (stiffest), k = {} N·m/rad\n",
                    trim(to_f64(t_c.get())),
                    sig(k64(end), 5)
                ),
                Fit::Failed(e) => format!("  {name}  {NONE}: {e}\n"),
            };
        }
        s
    }
}

// ---------------------------------------------------------------------------------------
// JSON documents

/// `"design"` of the JSON report.
#[derive(Serialize, Debug)]
pub struct JsonDesign {
    beams: u8,
    beam_radius_m: f64,
    pitch_radius_m: f64,
    modulus_pa: f64,
    shear_modulus_pa: f64,
    allowable_stress_pa: f64,
    beam_length_m: f64,
    clutch_thickness_m: f64,
}

impl JsonDesign {
    fn of(d: &Design) -> JsonDesign {
        let p = d.params();
        let m = |v: Length| si(to_f64(v.get()) * 1e-3);
        let pa = |v: Stress| si(to_f64(v.get()) * 1e6);
        JsonDesign {
            beams: p.beams,
            beam_radius_m: m(p.beam_radius),
            pitch_radius_m: m(p.pitch_radius),
            modulus_pa: pa(p.youngs_modulus),
            shear_modulus_pa: pa(p.shear_modulus),
            allowable_stress_pa: pa(p.allowable_stress),
            beam_length_m: m(p.beam_length),
            clutch_thickness_m: m(p.clutch_thickness),
        }
    }
}

/// One row of the JSON report.
#[derive(Serialize, Debug)]
pub struct JsonRow {
    length_m: f64,
    stiffness_nm_per_rad: Option<f64>,
    stiffness_shear_nm_per_rad: Option<f64>,
    deflection_rad: Option<f64>,
    beam_force_n: Option<f64>,
    stress_pa: Option<f64>,
    torque_capacity_nm: Option<f64>,
    deflection_capacity_rad: Option<f64>,
    backlash_tilt_rad: Option<f64>,
}

/// The JSON report.
#[derive(Serialize, Debug)]
pub struct JsonReport {
    design: JsonDesign,
    torque_nm: f64,
    rows: Vec<JsonRow>,
}

/// The JSON answer of `--stiffness`.
#[derive(Serialize, Debug)]
pub struct JsonInverse {
    stiffness_nm_per_rad: f64,
    clutch_length_m: Option<f64>,
    clutch_length_shear_m: Option<f64>,
}

#[cfg(test)]
mod tests {
    use super::*;

    fn args(f: impl FnOnce(&mut DesignArgs)) -> DesignArgs {
        let mut a = DesignArgs::default();
        f(&mut a);
        a
    }

    #[test]
    fn lengths_lists_and_ranges() {
        let d = Design::paper();
        let v = parse_lengths("1mm..5mm:1mm", &d).unwrap();
        assert_eq!(v, (1..=5).map(Length::from_int).collect::<Vec<_>>());
        let v = parse_lengths("1mm..2mm:0.1mm", &d).unwrap();
        assert_eq!(v.len(), 11);
        assert_eq!(v[10], Length::from_int(2));
        let v = parse_lengths("1mm, 2.5mm,3e-3m", &d).unwrap();
        assert_eq!(v[2], Length::from_int(3));
        assert!(parse_lengths("9mm", &d).is_err());
        assert!(parse_lengths("0mm", &d).is_err());
        assert!(parse_lengths("-1mm", &d).is_err());
        assert!(parse_lengths("1mm..5mm", &d).is_err());
        assert!(parse_lengths("5mm..1mm:1mm", &d).is_err());
        assert!(parse_lengths("1mm..5mm:0mm", &d).is_err());
        assert!(parse_lengths("1mm..5mm:1nm", &d).is_err());
        assert!(parse_lengths("1mm..8mm:1um", &d).is_err());
        assert!(parse_lengths("1e40mm", &d).is_err());
    }

    #[test]
    fn design_errors_name_the_argument() {
        let e = parse_design(&args(|a| a.beam_radius = Some("0mm".into()))).unwrap_err();
        assert_eq!(
            e.to_string(),
            "--beam-radius: 0 mm is out of range [0.05, 5] mm"
        );
        let e = parse_design(&args(|a| a.beam_radius = Some("1e30m".into()))).unwrap_err();
        assert!(e
            .to_string()
            .starts_with("--beam-radius: 1e33 mm is out of range"));
        let e = parse_design(&args(|a| a.modulus = Some("2000GPa".into()))).unwrap_err();
        assert_eq!(
            e.to_string(),
            "--modulus: 2000 GPa is out of range [1, 1000] GPa"
        );
        let e = parse_design(&args(|a| a.shear_modulus = Some("60GPa".into()))).unwrap_err();
        assert!(e.to_string().starts_with("--shear-modulus: G = 60 GPa"));
        let e = parse_design(&args(|a| a.pitch_radius = Some("0.4mm".into()))).unwrap_err();
        assert!(e
            .to_string()
            .starts_with("--pitch-radius: 0.4 mm is out of range"));
        let e = parse_design(&args(|a| {
            a.beam_radius = Some("3mm".into());
            a.pitch_radius = Some("2mm".into());
        }))
        .unwrap_err();
        assert!(e
            .to_string()
            .contains("larger than the beam radius r = 3 mm"));
        let e = parse_design(&args(|a| a.clutch_thickness = Some("8mm".into()))).unwrap_err();
        assert!(e.to_string().starts_with("--clutch-thickness: 8 mm"));
        let e = parse_design(&args(|a| a.beams = Some("300".into()))).unwrap_err();
        assert!(e.to_string().starts_with("--beams:"));
        let e = parse_design(&args(|a| a.friction = Some("3".into()))).unwrap_err();
        assert_eq!(e.to_string(), "--friction: 3 is out of range [0, 2]");
        assert!(parse_design(&args(|_| ())).is_ok());
    }

    #[test]
    fn inverse_ends() {
        let d = Design::paper();
        let inv = Inverse::compute(&d, Stiffness::from_int(1));
        assert!(matches!(inv.eb, Fit::TooSoft(_)));
        let inv = Inverse::compute(&d, Stiffness::from_int(5000));
        assert!(matches!(inv.eb, Fit::At(_)));
        assert!(matches!(inv.shear, Fit::TooStiff(_)));
    }
}
