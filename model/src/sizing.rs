//! Sizing a beam design against goals and an envelope (the explorer's per-design numbers):
//! stiffness range, stress-limited capacity and deflection at both ends of the clutch
//! travel, elastic energy stored at capacity, beam mass, the volume the beam ring takes,
//! the backlash of paper eqs. 5–7, and whether the clutch slots fit side by side.
//!
//! Everything is Euler–Bernoulli (paper eq. 4) and comes from the functions of this crate,
//! except the three quantities that are new here (docs/design.md §10):
//!
//! * energy at capacity E_cap = ½·τ_cap(l)·θ_cap(l) at the softest setting, J, I32F32
//!   (closed form: n·σ_allow²·π·r²·l/(24·E), ∝ σ²/E × active volume; the oracle checks it);
//! * beam mass m = n·π·r²·l_b·ρ, g, I32F32 (l_b the whole beam, clamped ends included);
//! * envelope volume V = π·(R + r_slot)²·l_b, mm³, I32F32: the cylinder the beam ring and
//!   its clutch slots sweep.
//!
//! The slots fit when a slot does not reach the axis (R > r_slot) and neighbouring slots do
//! not overlap: chord 2·R·sin(π/n) ≥ 2·r_slot for n ≥ 2 (r_slot = r + c, paper eq. 6).
//!
//! Slow maths (divisions, the products here) is configuration-time only; nothing here runs
//! per tick.

use fixed::types::I32F32;

use crate::beam::or_overflow as ov;
use crate::control::sine::{sin_q30, SIN_ONE};
use crate::design::Design;
use crate::error::Result;
use crate::fixmath::{SoftFloat, PI};
use crate::units::{Angle, Length, Stiffness, Torque};

const MEGA: SoftFloat = SoftFloat::from_u64(1_000_000);

fn len_s(l: Length) -> SoftFloat {
    SoftFloat::from_bits(l.to_bits(), 32).0
}

fn fix(s: SoftFloat) -> Result<I32F32> {
    Ok(I32F32::from_bits(ov(s.to_i64(32, false))?))
}

/// Elastic energy the beams store at the stress limit at clutch length `len`,
/// ½·τ_cap(L)·θ_cap(L), J (E–B).
///
/// # Errors
/// As [`Design::torque_capacity`]; [`crate::Error::Overflow`] if it does not fit I32F32.
pub fn energy_at_capacity(d: &Design, len: Length) -> Result<I32F32> {
    // Validates L as the capacity functions do.
    d.torque_capacity(len)?;
    // ½·(cap_coef/L)·(theta_cap_coef·L²) = ½·cap_coef·theta_cap_coef·L from the design's
    // unrounded constants (τ_cap and θ_cap rounded to I32F32 first would lose digits
    // where θ_cap is a few µrad). cap_coef is in N·m·mm, theta_cap_coef in 1/mm².
    let p = ov(ov(d.cap_coef.mul(d.theta_cap_coef))?.mul(len_s(len)))?;
    // ½·E in I32F32 bits = E·2³¹.
    Ok(I32F32::from_bits(ov(p.to_i64(31, false))?))
}

/// Mass of the n beams of whole length `total_length` (the clamped ends included) at
/// density `density_kg_m3`: n·π·r²·l_b·ρ, g.
///
/// # Errors
/// [`crate::Error::Overflow`] if it does not fit I32F32.
pub fn beam_mass(d: &Design, total_length: Length, density_kg_m3: u32) -> Result<I32F32> {
    let p = d.params();
    let r = len_s(p.beam_radius);
    // mm³ · kg/m³ = 10⁻⁹ kg = 10⁻⁶ g.
    let v = ov(ov(
        ov(ov(SoftFloat::from_u64(u64::from(p.beams)).mul(PI))?.mul(ov(r.mul(r))?))?
            .mul(len_s(total_length)),
    )?
    .mul(SoftFloat::from_u64(u64::from(density_kg_m3))))?;
    fix(ov(v.div(MEGA))?)
}

/// Volume of the cylinder the beam ring sweeps, π·(R + r_slot)²·l_b, mm³.
///
/// # Errors
/// [`crate::Error::Overflow`] if it does not fit I32F32.
pub fn envelope_volume(d: &Design, total_length: Length) -> Result<I32F32> {
    let outer = ov(len_s(d.params().pitch_radius).add(len_s(d.slot_radius())))?;
    fix(ov(
        ov(PI.mul(ov(outer.mul(outer))?))?.mul(len_s(total_length))
    )?)
}

/// Whether the clutch slots fit (see the module docs).
#[must_use]
pub fn slots_fit(d: &Design) -> bool {
    let p = d.params();
    let rs = d.slot_radius().get();
    if p.pitch_radius.get() <= rs {
        return false;
    }
    if p.beams < 2 {
        return true;
    }
    // sin(π/n) as a phase of 2³²/(2n) turns; R·sin(π/n) ≥ r_slot.
    let phase = (1u64 << 31) / u64::from(p.beams);
    let s = i64::from(sin_q30(phase as u32));
    let lhs = i128::from(p.pitch_radius.to_bits()) * i128::from(s);
    let rhs = i128::from(rs.to_bits()) * i128::from(SIN_ONE);
    lhs >= rhs
}

/// A beam design in its envelope: the validated design (its beam length l is the softest
/// active length, its clutch thickness t_c the stiffest), the whole beam length l_b ≥ l
/// (clamped ends included) and the material's density.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Candidate {
    /// The design.
    pub design: Design,
    /// Whole beam length l_b.
    pub total_length: Length,
    /// Density ρ, kg/m³.
    pub density_kg_m3: u32,
}

/// What a [`Candidate`] does, E–B throughout.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Sizing {
    /// k(l), the softest setting.
    pub stiffness_min: Stiffness,
    /// k(t_c), the stiffest setting.
    pub stiffness_max: Stiffness,
    /// τ_cap(l): the capacity over the whole travel (it falls as 1/L).
    pub capacity_soft: Torque,
    /// τ_cap(t_c).
    pub capacity_stiff: Torque,
    /// θ_cap(l): the largest safe deflection.
    pub deflection_soft: Angle,
    /// θ_cap(t_c).
    pub deflection_stiff: Angle,
    /// Energy stored at capacity at the softest setting, J.
    pub energy_j: I32F32,
    /// Beam mass, g.
    pub mass_g: I32F32,
    /// Envelope volume, mm³.
    pub volume_mm3: I32F32,
    /// Output free play φ_b = c/R.
    pub free_play: Angle,
    /// Beam-tilt backlash θ_b at x = l and x = t_c (paper eq. 7).
    pub backlash_tilt: (Angle, Angle),
    /// The clutch slots fit.
    pub fits: bool,
}

impl Candidate {
    /// Evaluates the candidate.
    ///
    /// # Errors
    /// A quantity that does not fit its format ([`crate::Error::Overflow`]).
    pub fn size(&self) -> Result<Sizing> {
        let d = &self.design;
        let (stiff, soft) = d.adjustable_range();
        let (stiffness_min, stiffness_max) =
            d.stiffness_range(crate::beam::BeamModel::EulerBernoulli);
        Ok(Sizing {
            stiffness_min,
            stiffness_max,
            capacity_soft: d.torque_capacity(soft)?,
            capacity_stiff: d.torque_capacity(stiff)?,
            deflection_soft: d.deflection_capacity(soft)?,
            deflection_stiff: d.deflection_capacity(stiff)?,
            energy_j: energy_at_capacity(d, soft)?,
            mass_g: beam_mass(d, self.total_length, self.density_kg_m3)?,
            volume_mm3: envelope_volume(d, self.total_length)?,
            free_play: d.free_play(),
            backlash_tilt: (d.tilt_backlash(soft)?, d.tilt_backlash(stiff)?),
            fits: slots_fit(d),
        })
    }
}

/// A constraint of the explorer.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Constraint {
    /// τ_cap(l) ≥ the wanted capacity.
    Capacity,
    /// θ_cap(l) ≥ the wanted deflection.
    Deflection,
    /// Beam mass ≤ the allowed added mass.
    Mass,
    /// Envelope volume ≤ the allowed added volume.
    Volume,
    /// The clutch slots fit.
    Fit,
}

impl Constraint {
    /// Every constraint, in report order.
    pub const ALL: [Constraint; 5] = [
        Constraint::Capacity,
        Constraint::Deflection,
        Constraint::Mass,
        Constraint::Volume,
        Constraint::Fit,
    ];

    /// Its name in reports and JSON.
    #[must_use]
    pub const fn name(self) -> &'static str {
        match self {
            Constraint::Capacity => "capacity",
            Constraint::Deflection => "deflection",
            Constraint::Mass => "mass",
            Constraint::Volume => "volume",
            Constraint::Fit => "fit",
        }
    }
}

/// The user's goals (each bound inclusive).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Goals {
    /// Smallest capacity over the travel, N·m.
    pub min_capacity: Torque,
    /// Smallest safe deflection at the softest setting, rad.
    pub min_deflection: Angle,
    /// Largest beam mass, g.
    pub max_mass_g: I32F32,
    /// Largest envelope volume, mm³.
    pub max_volume_mm3: I32F32,
}

impl Sizing {
    /// Whether `c` holds for `goals` (exact comparisons).
    #[must_use]
    pub fn meets(&self, c: Constraint, goals: &Goals) -> bool {
        match c {
            Constraint::Capacity => self.capacity_soft >= goals.min_capacity,
            Constraint::Deflection => self.deflection_soft >= goals.min_deflection,
            Constraint::Mass => self.mass_g <= goals.max_mass_g,
            Constraint::Volume => self.volume_mm3 <= goals.max_volume_mm3,
            Constraint::Fit => self.fits,
        }
    }

    /// Whether every constraint holds.
    #[must_use]
    pub fn meets_all(&self, goals: &Goals) -> bool {
        Constraint::ALL.iter().all(|&c| self.meets(c, goals))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::DesignParams;

    fn f(x: I32F32) -> f64 {
        x.to_num()
    }

    #[test]
    fn paper_design_numbers() {
        let d = Design::paper();
        let c = Candidate {
            design: d,
            total_length: Length::from_int(10),
            density_kg_m3: 7850,
        };
        let s = c.size().unwrap();
        // n·π·r²·l_b·ρ = 4·π·0.25·10 mm³ · 7.85e-3 g/mm³ = 0.2466 g.
        assert!((f(s.mass_g) - 0.246_615).abs() < 1e-5, "{}", s.mass_g);
        // E_cap at l = 8 mm: 4·1500²·π·0.25·8/(24·200e3) N·mm = 0.011781 J.
        assert!((f(s.energy_j) - 0.011_781).abs() < 1e-5, "{}", s.energy_j);
        assert!(s.fits);
        let goals = Goals {
            min_capacity: Torque::from_fixed(I32F32::lit("1.5")),
            min_deflection: Angle::from_fixed(I32F32::lit("0.2")),
            max_mass_g: I32F32::lit("5.5"),
            max_volume_mm3: I32F32::from_num(6400),
        };
        assert!(!s.meets(Constraint::Capacity, &goals));
        assert!(!s.meets(Constraint::Deflection, &goals));
        assert!(s.meets(Constraint::Mass, &goals));
        assert!(s.meets(Constraint::Volume, &goals));
        assert!(!s.meets_all(&goals));
    }

    #[test]
    fn slots_that_overlap_do_not_fit() {
        let mut p = DesignParams::PAPER;
        p.beams = 16;
        p.beam_radius = Length::from_int(2);
        p.pitch_radius = Length::from_int(8);
        assert!(!slots_fit(&Design::new(p).unwrap()));
        p.beams = 4;
        assert!(slots_fit(&Design::new(p).unwrap()));
    }
}
