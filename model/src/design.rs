//! The validated beam design (design.md §2): parameters, domain, and every derived constant,
//! computed once in [`Design::new`].
//!
//! Symbols: n beams of radius r at pitch radius R, Young's modulus E, shear modulus G,
//! allowable stress σ_allow, total usable beam length l, clutch plate thickness t_c,
//! kinetic friction μ. Derived here (units in parentheses, internal ones scaled):
//!
//! * I = π·r⁴/4 (mm⁴), A = π·r² (mm²);
//! * `C = n·3·E·I·R²` (N·mm⁴ → /10³: N·m·mm³), so that k(L) = C/L³ in N·m/rad with L in
//!   mm (paper eq. 4);
//! * ν = E/(2G) − 1, κ = 6(1+ν)/(7+6ν) = 3E/(G+3E), and the shear length
//!   s = I·(1 + 3E/G)/A (mm²), the shear term: L³/(3EI) + L/(κGA) = (L³ + s·L)/(3EI), so
//!   that k_T(L) = C/(L³ + s·L) (Timoshenko, row 4T);
//! * 1/(n·R) for P = τ/(n·R), r/I for σ = P·L·r/I, n·R·σ_allow·I/r for
//!   τ_cap = n·R·σ_allow·I/(r·L), and σ_allow/(3·E·r·R) for θ_cap = τ_cap/k = σ_allow·L²/(3·E·r·R);
//! * δ_max = σ_allow·l²/(3·E·r), θ_max = δ_max/l (eq. 5), c = θ_max·t_c, r_slot = r + c
//!   (eq. 6), φ_b = c/R;
//! * (6/5)·μ·R for the friction hysteresis (§2.1);
//! * the stiffness at both ends of the adjustable range [t_c, l], for both beam models.

use fixed::types::I32F32;

use crate::error::{Error, Result};
use crate::fixmath::{SoftFloat, FRAC_PI_4, PI};
use crate::stiffness::{k_eb, k_timo};
use crate::units::{Angle, Length, Ratio, Stiffness, Stress};

/// Smallest beam count n.
pub const BEAMS_MIN: u8 = 1;
/// Largest beam count n.
pub const BEAMS_MAX: u8 = 16;
/// Smallest beam radius r: 0.05 mm (nearest I32F32).
pub const BEAM_RADIUS_MIN: Length = Length::from_fixed(I32F32::lit("0.05"));
/// Largest beam radius r: 5 mm.
pub const BEAM_RADIUS_MAX: Length = Length::from_int(5);
/// Smallest pitch radius R: 1 mm (R must also exceed r).
pub const PITCH_RADIUS_MIN: Length = Length::from_int(1);
/// Largest pitch radius R: 100 mm.
pub const PITCH_RADIUS_MAX: Length = Length::from_int(100);
/// Smallest modulus (E or G): 1 GPa.
pub const MODULUS_MIN: Stress = Stress::from_int(1_000);
/// Largest modulus (E or G): 1000 GPa.
pub const MODULUS_MAX: Stress = Stress::from_int(1_000_000);
/// Smallest allowable stress σ_allow: 1 MPa.
pub const ALLOWABLE_STRESS_MIN: Stress = Stress::from_int(1);
/// Largest allowable stress σ_allow: 10 GPa.
pub const ALLOWABLE_STRESS_MAX: Stress = Stress::from_int(10_000);
/// Shortest total beam length l: 0.1 mm (nearest I32F32).
pub const BEAM_LENGTH_MIN: Length = Length::from_fixed(I32F32::lit("0.1"));
/// Longest total beam length l: 100 mm.
pub const BEAM_LENGTH_MAX: Length = Length::from_int(100);
/// Thinnest clutch plate t_c: 0.01 mm (nearest I32F32); t_c must also be below l.
pub const CLUTCH_THICKNESS_MIN: Length = Length::from_fixed(I32F32::lit("0.01"));
/// Largest friction coefficient μ (the smallest is 0).
pub const FRICTION_MAX: Ratio = Ratio::from_int(2);

/// The raw parameters of a design (SI symbols, scaled units). Validate with [`Design::new`].
///
/// Domain (each bound inclusive unless noted; the bounds are the constants of this
/// module): n ∈ 1..=16; r ∈ [0.05, 5] mm; R ∈ [1, 100] mm and R > r; E, G ∈ [1, 1000] GPa
/// and G ≥ E/3 (ν = E/(2G) − 1 ≤ 0.5; ν > −1 holds for any positive E, G);
/// σ_allow ∈ [1, 10 000] MPa; l ∈ [0.1, 100] mm; t_c ∈ [0.01 mm, l) (strictly below l);
/// μ ∈ [0, 2].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DesignParams {
    /// Number of beams n.
    pub beams: u8,
    /// Beam radius r.
    pub beam_radius: Length,
    /// Pitch radius R (gear centre to beam centre).
    pub pitch_radius: Length,
    /// Young's modulus E.
    pub youngs_modulus: Stress,
    /// Shear modulus G.
    pub shear_modulus: Stress,
    /// Allowable bending stress σ_allow.
    pub allowable_stress: Stress,
    /// Total usable beam length l (the softest clutch setting).
    pub beam_length: Length,
    /// Clutch plate thickness t_c (the stiffest clutch setting).
    pub clutch_thickness: Length,
    /// Kinetic friction coefficient μ between clutch and beams.
    pub friction: Ratio,
}

impl DesignParams {
    /// The paper's actuator (design.md §2.2): n = 4, r = 0.5 mm, R = 7.8 mm, E = 200 GPa,
    /// G = 80 GPa, σ_allow = 1.5 GPa, l = 8 mm, t_c = 1 mm, μ = 0.4.
    pub const PAPER: DesignParams = DesignParams {
        beams: 4,
        beam_radius: Length::from_fixed(I32F32::lit("0.5")),
        pitch_radius: Length::from_fixed(I32F32::lit("7.8")),
        youngs_modulus: Stress::from_int(200_000),
        shear_modulus: Stress::from_int(80_000),
        allowable_stress: Stress::from_int(1_500),
        beam_length: Length::from_int(8),
        clutch_thickness: Length::from_int(1),
        friction: Ratio::from_fixed(I32F32::lit("0.4")),
    };
}

/// A validated design with its derived constants (see the module docs).
///
/// Construction does the divisions; the functions on it ([`crate::beam`],
/// [`crate::backlash`], [`crate::dynamics`]) and on a [`crate::Setting`] are products of
/// precomputed constants, plus one division by L where L is an argument.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Design {
    params: DesignParams,
    /// l (mm).
    pub(crate) l: SoftFloat,
    /// C = n·3·E·I·R²/10³ (N·m·mm³) (k = C/L³).
    pub(crate) c_k: SoftFloat,
    /// 1/C (1/(N·m·mm³)).
    pub(crate) inv_c_k: SoftFloat,
    /// s = I·(1 + 3E/G)/A (mm²) (k_T = C/(L³ + s·L)).
    pub(crate) shear: SoftFloat,
    /// 10³/(n·R) (N per N·m) (P = τ/(n·R), R in mm).
    pub(crate) force_per_torque: SoftFloat,
    /// 10³·r/(n·R·I) (MPa per N·m per mm of L) (σ = P·L·r/I).
    pub(crate) stress_coef: SoftFloat,
    /// n·R·σ_allow·I/(10³·r) (N·m·mm) (τ_cap = this / L).
    pub(crate) cap_coef: SoftFloat,
    /// σ_allow/(3·E·r·R) (1/mm²) (θ_cap = this·L² E–B, this·(L² + s) Timoshenko).
    pub(crate) theta_cap_coef: SoftFloat,
    /// c (mm).
    pub(crate) clearance_s: SoftFloat,
    /// φ_b (rad).
    pub(crate) free_play_s: SoftFloat,
    /// (6/5)·μ·R (mm) (hysteresis a = this / L (1/rad)).
    pub(crate) friction_coef: SoftFloat,
    pub(crate) max_tip_deflection: Length,
    pub(crate) bending_capacity: Angle,
    pub(crate) clearance: Length,
    pub(crate) slot_radius: Length,
    pub(crate) free_play: Angle,
    poisson: Ratio,
    shear_factor: Ratio,
    /// k(l), k(t_c), k_T(l), k_T(t_c).
    pub(crate) range_eb: (Stiffness, Stiffness),
    pub(crate) range_t: (Stiffness, Stiffness),
}

/// Unwraps an `Option` in a `const fn`, mapping `None` to [`Error::Overflow`].
macro_rules! some_or_overflow {
    ($e:expr) => {
        match $e {
            Some(v) => v,
            None => return Err(Error::Overflow),
        }
    };
}

const fn within(v: i64, lo: i64, hi: i64) -> bool {
    v >= lo && v <= hi
}

/// A positive I32F32 length/stress/ratio as a `SoftFloat` (exact).
const fn pos(bits: i64) -> SoftFloat {
    SoftFloat::from_bits(bits, 32).0
}

const fn to_fix(s: SoftFloat) -> Option<i64> {
    s.to_i64(32, false)
}

const fn to_stiffness(s: SoftFloat) -> Option<Stiffness> {
    match s.to_i128(64, false) {
        Some(b) => Some(Stiffness::from_bits(b)),
        None => None,
    }
}

impl Design {
    /// The paper's design ([`DesignParams::PAPER`]), validated at compile time.
    pub const PAPER: Design = match Design::new(DesignParams::PAPER) {
        Ok(d) => d,
        Err(_) => panic!("the paper preset is a valid design"),
    };

    /// The paper's design (design.md §2.2).
    #[must_use]
    pub const fn paper() -> Design {
        Self::PAPER
    }

    /// Validates `p` against the domain (see [`DesignParams`]) and computes the derived
    /// constants.
    ///
    /// # Errors
    /// The first violated bound, as `Error::*OutOfRange` or
    /// [`Error::PoissonRatioNonPhysical`]; [`Error::Overflow`] never happens inside the
    /// domain but is returned rather than wrapped.
    pub const fn new(p: DesignParams) -> Result<Design> {
        if p.beams < BEAMS_MIN || p.beams > BEAMS_MAX {
            return Err(Error::BeamCountOutOfRange);
        }
        let (rb, pb) = (p.beam_radius.to_bits(), p.pitch_radius.to_bits());
        if !within(rb, BEAM_RADIUS_MIN.to_bits(), BEAM_RADIUS_MAX.to_bits()) {
            return Err(Error::BeamRadiusOutOfRange);
        }
        if !within(pb, PITCH_RADIUS_MIN.to_bits(), PITCH_RADIUS_MAX.to_bits()) || pb <= rb {
            return Err(Error::PitchRadiusOutOfRange);
        }
        let (eb, gb) = (p.youngs_modulus.to_bits(), p.shear_modulus.to_bits());
        if !within(eb, MODULUS_MIN.to_bits(), MODULUS_MAX.to_bits()) {
            return Err(Error::YoungsModulusOutOfRange);
        }
        if !within(gb, MODULUS_MIN.to_bits(), MODULUS_MAX.to_bits()) {
            return Err(Error::ShearModulusOutOfRange);
        }
        // ν = E/(2G) − 1 ≤ 0.5 ⟺ 3G ≥ E (both < 2^52 in bits: no overflow).
        if 3 * gb < eb {
            return Err(Error::PoissonRatioNonPhysical);
        }
        let sb = p.allowable_stress.to_bits();
        if !within(
            sb,
            ALLOWABLE_STRESS_MIN.to_bits(),
            ALLOWABLE_STRESS_MAX.to_bits(),
        ) {
            return Err(Error::AllowableStressOutOfRange);
        }
        let lb = p.beam_length.to_bits();
        if !within(lb, BEAM_LENGTH_MIN.to_bits(), BEAM_LENGTH_MAX.to_bits()) {
            return Err(Error::BeamLengthOutOfRange);
        }
        let tb = p.clutch_thickness.to_bits();
        if tb < CLUTCH_THICKNESS_MIN.to_bits() || tb >= lb {
            return Err(Error::ClutchThicknessOutOfRange);
        }
        if !within(p.friction.to_bits(), 0, FRICTION_MAX.to_bits()) {
            return Err(Error::FrictionOutOfRange);
        }

        let n = SoftFloat::from_u64(p.beams as u64);
        let three = SoftFloat::from_u64(3);
        let thousand = SoftFloat::from_u64(1000);
        let (r, big_r, e, g) = (pos(rb), pos(pb), pos(eb), pos(gb));
        let (sigma, l, tc) = (pos(sb), pos(lb), pos(tb));
        let mu = pos(p.friction.to_bits());

        // Section properties.
        let r2 = some_or_overflow!(r.mul(r));
        let i = some_or_overflow!(some_or_overflow!(r2.mul(r2)).mul(FRAC_PI_4));
        let area = some_or_overflow!(r2.mul(PI));
        let nr = some_or_overflow!(n.mul(big_r));

        // Paper eq. 4: C = n·3·E·I·R² in N·mm³·mm, /1000 for N·m with L in mm.
        let c_k = some_or_overflow!(
            // eq. 4
            some_or_overflow!(some_or_overflow!(some_or_overflow!(
                some_or_overflow!(n.mul(three)).mul(e)
            )
            .mul(i))
            .mul(some_or_overflow!(big_r.mul(big_r))))
            .div(thousand)
        );
        let inv_c_k = some_or_overflow!(c_k.recip());

        // Row 4T: with κ = 3E/(G+3E), L/(κGA) = L·(1 + 3E/G)/(3EA), hence
        // k_T = C/(L³ + s·L), s = (I/A)·(1 + 3E/G).
        let e_over_g = some_or_overflow!(e.div(g));
        let one_3eg = some_or_overflow!(SoftFloat::ONE.add(some_or_overflow!(three.mul(e_over_g))));
        let shear = some_or_overflow!(some_or_overflow!(i.div(area)).mul(one_3eg)); // eq. 4T
                                                                                    // ν = E/(2G) − 1 (in (−1, 0.5]), κ = 3E/G / (1 + 3E/G).
        let half_eg = some_or_overflow!(to_fix(some_or_overflow!(
            e_over_g.div(SoftFloat::from_u64(2))
        )));
        let poisson = Ratio::from_bits(half_eg - (1 << 32));
        let shear_factor = Ratio::from_bits(some_or_overflow!(to_fix(some_or_overflow!(
            some_or_overflow!(three.mul(e_over_g)).div(one_3eg)
        ))));

        // P = τ/(n·R): τ in N·m, R in mm → 1000/(n·R) N per N·m.
        let force_per_torque = some_or_overflow!(thousand.div(nr)); // eq. 2
                                                                    // σ = P·L·r/I (N·mm·mm/mm⁴ = MPa).
        let stress_coef = some_or_overflow!(some_or_overflow!(force_per_torque.mul(r)).div(i));
        // τ_cap·L = n·R·σ_allow·I/r (N·mm·mm) / 1000 → N·m·mm.
        let cap_coef = some_or_overflow!(some_or_overflow!(some_or_overflow!(some_or_overflow!(
            nr.mul(sigma)
        )
        .mul(i))
        .div(r))
        .div(thousand));
        // θ_cap = τ_cap/k = σ_allow·L²/(3·E·r·R).
        let theta_cap_coef = some_or_overflow!(sigma.div(some_or_overflow!(some_or_overflow!(
            some_or_overflow!(three.mul(e)).mul(r)
        )
        .mul(big_r))));

        // Paper eqs. 5–6 and the free play.
        // eq. 5: θ_max = δ_max/l with δ_max = σ_allow·l²/(3·E·r).
        let theta_max = some_or_overflow!(some_or_overflow!(sigma.mul(l))
            .div(some_or_overflow!(some_or_overflow!(three.mul(e)).mul(r))));
        let delta_max = some_or_overflow!(theta_max.mul(l));
        let clearance_s = some_or_overflow!(theta_max.mul(tc)); // eq. 6
        let free_play_s = some_or_overflow!(clearance_s.div(big_r));
        let slot = some_or_overflow!(r.add(clearance_s)); // eq. 6

        // §2.1: a(L) = (6/5)·μ·δ/L per unit φ with δ = R·φ.
        let friction_coef = some_or_overflow!(some_or_overflow!(some_or_overflow!(
            SoftFloat::from_u64(6).mul(mu)
        )
        .mul(big_r))
        .div(SoftFloat::from_u64(5)));

        let range_eb = (
            some_or_overflow!(to_stiffness(some_or_overflow!(k_eb(c_k, l)))),
            some_or_overflow!(to_stiffness(some_or_overflow!(k_eb(c_k, tc)))),
        );
        let range_t = (
            some_or_overflow!(to_stiffness(some_or_overflow!(k_timo(c_k, shear, l)))),
            some_or_overflow!(to_stiffness(some_or_overflow!(k_timo(c_k, shear, tc)))),
        );

        Ok(Design {
            params: p,
            l,
            c_k,
            inv_c_k,
            shear,
            force_per_torque,
            stress_coef,
            cap_coef,
            theta_cap_coef,
            clearance_s,
            free_play_s,
            friction_coef,
            max_tip_deflection: Length::from_bits(some_or_overflow!(to_fix(delta_max))),
            bending_capacity: Angle::from_bits(some_or_overflow!(to_fix(theta_max))),
            clearance: Length::from_bits(some_or_overflow!(to_fix(clearance_s))),
            slot_radius: Length::from_bits(some_or_overflow!(to_fix(slot))),
            free_play: Angle::from_bits(some_or_overflow!(to_fix(free_play_s))),
            poisson,
            shear_factor,
            range_eb,
            range_t,
        })
    }

    /// The parameters this design was built from.
    #[must_use]
    pub const fn params(&self) -> &DesignParams {
        &self.params
    }

    /// Poisson's ratio ν = E/(2G) − 1, in (−1, 0.5].
    #[must_use]
    pub const fn poisson_ratio(&self) -> Ratio {
        self.poisson
    }

    /// Timoshenko shear coefficient κ = 6(1+ν)/(7+6ν) of a round section, in (0, 0.9].
    #[must_use]
    pub const fn shear_coefficient(&self) -> Ratio {
        self.shear_factor
    }

    /// The adjustable range of the clutch length, `(L_min, L_max) = (t_c, l)`.
    ///
    /// The clutch plate cannot sit closer to the gear than its own thickness, and eq. 7
    /// (beam-tilt backlash) is defined on the same interval. For the paper preset this is
    /// [1, 8] mm; the paper itself uses 1–5 mm.
    #[must_use]
    pub const fn adjustable_range(&self) -> (Length, Length) {
        (self.params.clutch_thickness, self.params.beam_length)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn with(f: impl FnOnce(&mut DesignParams)) -> Result<Design> {
        let mut p = DesignParams::PAPER;
        f(&mut p);
        Design::new(p)
    }

    #[test]
    fn paper_preset_is_valid_and_derived() {
        let d = Design::paper();
        assert_eq!(Design::new(DesignParams::PAPER), Ok(d));
        let nu = d.poisson_ratio().get().to_num::<f64>();
        assert!((nu - 0.25).abs() < 1e-9);
        let kappa = d.shear_coefficient().get().to_num::<f64>();
        assert!((kappa - 7.5 / 8.5).abs() < 1e-9);
        assert_eq!(
            d.adjustable_range(),
            (Length::from_int(1), Length::from_int(8))
        );
    }

    #[test]
    fn every_validation_error() {
        use Error::*;
        assert_eq!(with(|p| p.beams = 0), Err(BeamCountOutOfRange));
        assert_eq!(with(|p| p.beams = 17), Err(BeamCountOutOfRange));
        assert_eq!(
            with(|p| p.beam_radius = Length::ZERO),
            Err(BeamRadiusOutOfRange)
        );
        assert_eq!(
            with(|p| p.beam_radius = Length::from_int(6)),
            Err(BeamRadiusOutOfRange)
        );
        assert_eq!(
            with(|p| p.pitch_radius = Length::from_int(-7)),
            Err(PitchRadiusOutOfRange)
        );
        assert_eq!(
            with(|p| p.pitch_radius = Length::from_int(101)),
            Err(PitchRadiusOutOfRange)
        );
        assert_eq!(
            with(|p| {
                p.beam_radius = Length::from_int(3);
                p.pitch_radius = Length::from_int(2);
            }),
            Err(PitchRadiusOutOfRange)
        );
        assert_eq!(
            with(|p| p.youngs_modulus = Stress::ZERO),
            Err(YoungsModulusOutOfRange)
        );
        assert_eq!(
            with(|p| p.shear_modulus = Stress::from_int(-1)),
            Err(ShearModulusOutOfRange)
        );
        // G = 60 GPa < E/3 = 66.7 GPa: ν = 0.667.
        assert_eq!(
            with(|p| p.shear_modulus = Stress::from_int(60_000)),
            Err(PoissonRatioNonPhysical)
        );
        assert_eq!(
            with(|p| p.allowable_stress = Stress::ZERO),
            Err(AllowableStressOutOfRange)
        );
        assert_eq!(
            with(|p| p.beam_length = Length::from_int(-8)),
            Err(BeamLengthOutOfRange)
        );
        assert_eq!(
            with(|p| p.beam_length = Length::from_int(101)),
            Err(BeamLengthOutOfRange)
        );
        assert_eq!(
            with(|p| p.clutch_thickness = Length::from_int(8)),
            Err(ClutchThicknessOutOfRange)
        );
        assert_eq!(
            with(|p| p.clutch_thickness = Length::ZERO),
            Err(ClutchThicknessOutOfRange)
        );
        assert_eq!(
            with(|p| p.friction = Ratio::from_int(-1)),
            Err(FrictionOutOfRange)
        );
        assert_eq!(
            with(|p| p.friction = Ratio::from_int(3)),
            Err(FrictionOutOfRange)
        );
        // ν = 0.5 exactly (G = E/3) and frictionless are accepted.
        assert!(with(|p| {
            p.youngs_modulus = Stress::from_int(300_000);
            p.shear_modulus = Stress::from_int(100_000);
            p.friction = Ratio::ZERO;
        })
        .is_ok());
    }

    #[test]
    fn extreme_corners_of_the_domain_build() {
        for (r, big_r, e, l, tc, n) in [
            (
                BEAM_RADIUS_MIN,
                PITCH_RADIUS_MIN,
                MODULUS_MIN,
                BEAM_LENGTH_MAX,
                CLUTCH_THICKNESS_MIN,
                1,
            ),
            (
                BEAM_RADIUS_MAX,
                PITCH_RADIUS_MAX,
                MODULUS_MAX,
                BEAM_LENGTH_MAX,
                CLUTCH_THICKNESS_MIN,
                16,
            ),
            (
                BEAM_RADIUS_MAX,
                PITCH_RADIUS_MAX,
                MODULUS_MAX,
                BEAM_LENGTH_MIN,
                CLUTCH_THICKNESS_MIN,
                16,
            ),
            (
                BEAM_RADIUS_MIN,
                PITCH_RADIUS_MIN,
                MODULUS_MIN,
                BEAM_LENGTH_MIN,
                CLUTCH_THICKNESS_MIN,
                1,
            ),
        ] {
            for (g, sigma) in [
                (MODULUS_MAX, ALLOWABLE_STRESS_MAX),
                (e, ALLOWABLE_STRESS_MIN),
            ] {
                let d = Design::new(DesignParams {
                    beams: n,
                    beam_radius: r,
                    pitch_radius: big_r,
                    youngs_modulus: e,
                    shear_modulus: g,
                    allowable_stress: sigma,
                    beam_length: l,
                    clutch_thickness: tc,
                    friction: FRICTION_MAX,
                });
                assert!(d.is_ok(), "{r} {big_r} {e} {g} {l} {sigma}: {d:?}");
            }
        }
    }
}
