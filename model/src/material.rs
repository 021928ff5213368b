//! Beam materials: Young's modulus E, shear modulus G, allowable bending stress σ_allow and
//! density ρ, each with its source.
//!
//! For deflection what matters is σ_allow/E: the stress-limited deflection is
//! θ_cap = σ_allow·L²/(3·E·r·R) (docs/design.md §10), and the energy a beam stores at capacity is
//! σ_allow²/(24·E) per unit of active volume. The table lists that ratio's spread: spring
//! steel 0.0075, glass-fibre rod 0.020 (2.7 times steel's).
//!
//! What σ_allow is: for the metals the stress the beam may reach in service without
//! yielding (the paper preset's 1.5 GPa for spring steel, docs/design.md §2; the 0.2 % yield
//! strength or about 70 % of the minimum tensile strength of wire for the others); for the
//! fibre rods, which do not yield, their flexural *strength*, i.e. no margin at all — an
//! optimistic value that favours them.
//!
//! G: the shear-corrected (Timoshenko) stiffness is the only place it enters. A fibre rod
//! is not isotropic: its in-plane shear modulus is 10–30 times below E, which the model's
//! isotropic check (G ≥ E/3, [`crate::DesignParams`]) rejects. [`Material::isotropic_shear`]
//! gives the G to build a [`crate::Design`] with; every Euler–Bernoulli quantity (k, τ_cap,
//! θ_cap, stored energy) is independent of it.
//!
//! Units as in the rest of the crate: stresses in MPa ([`Stress`], I32F32); density in
//! kg/m³ (integer).

use fixed::types::I32F32;

use crate::units::Stress;

/// One beam material.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Material {
    /// Short name for the command line, e.g. `spring-steel`.
    pub key: &'static str,
    /// What it is, e.g. `spring steel (music wire)`.
    pub name: &'static str,
    /// Young's modulus E (along the rod for the fibre rods).
    pub youngs_modulus: Stress,
    /// Shear modulus G (in-plane shear for the fibre rods).
    pub shear_modulus: Stress,
    /// Allowable bending stress σ_allow (see the module docs).
    pub allowable_stress: Stress,
    /// Density ρ, kg/m³.
    pub density_kg_m3: u32,
    /// Where the numbers come from.
    pub source: &'static str,
}

impl Material {
    /// The shear modulus to build a [`crate::Design`] with: G, raised to E/3 where G is
    /// below it (the fibre rods; see the module docs). Only the shear-corrected stiffness
    /// depends on it.
    #[must_use]
    pub fn isotropic_shear(&self) -> Stress {
        let third = Stress::from_fixed(self.youngs_modulus.get() / 3 + I32F32::DELTA);
        if self.shear_modulus < third {
            third
        } else {
            self.shear_modulus
        }
    }
}

const fn mpa(v: i32) -> Stress {
    Stress::from_int(v)
}

/// Spring steel, the paper preset's material (docs/design.md §2.2).
pub const SPRING_STEEL: Material = Material {
    key: "spring-steel",
    name: "spring steel (music wire)",
    youngs_modulus: mpa(200_000),
    shear_modulus: mpa(80_000),
    allowable_stress: mpa(1_500),
    density_kg_m3: 7_850,
    source:
        "E, G: the paper (sec. 3); sigma_allow: docs/design.md sec. 2 (the project's default); \
             density: carbon spring steel, ASTM A228 music wire, 7.85 g/cm3",
};

/// Every material the explorer knows.
pub const MATERIALS: [Material; 6] = [
    SPRING_STEEL,
    Material {
        key: "stainless",
        name: "stainless spring wire (AISI 302, ASTM A313)",
        youngs_modulus: mpa(193_000),
        shear_modulus: mpa(69_000),
        allowable_stress: mpa(1_300),
        density_kg_m3: 7_920,
        source: "E = 28e6 psi, G = 10e6 psi (Diamond Wire Spring Co., spring material \
                 properties, AISI 302/304 ASTM A313); minimum tensile strength of 1 mm \
                 (0.039 in) wire 275 ksi = 1.90 GPa (ASTM A313 Type 302 table, InterWire \
                 Group), sigma_allow = 70 % of it; density 7.92 g/cm3 (AISI 302)",
    },
    Material {
        key: "titanium",
        name: "titanium Ti-6Al-4V (grade 5, annealed)",
        youngs_modulus: mpa(114_000),
        shear_modulus: mpa(44_000),
        allowable_stress: mpa(830),
        density_kg_m3: 4_430,
        source: "ASM/MatWeb, Titanium Ti-6Al-4V (Grade 5), Annealed Bar: E 114 GPa, \
                 G 44 GPa, yield 830 MPa, 4.43 g/cm3",
    },
    Material {
        key: "copper-beryllium",
        name: "copper-beryllium C17200 (hardened)",
        youngs_modulus: mpa(131_000),
        shear_modulus: mpa(50_000),
        allowable_stress: mpa(1_110),
        density_kg_m3: 8_250,
        source: "E 131 GPa, G 50 GPa (Fisk Alloy, C17200 physical properties); yield \
                 1110 MPa, 8250 kg/m3 (material-properties.org, beryllium copper)",
    },
    Material {
        key: "glass-fibre",
        name: "glass-fibre rod (pultruded E-glass, 75 % glass by weight)",
        youngs_modulus: mpa(41_400),
        shear_modulus: mpa(5_000),
        allowable_stress: mpa(827),
        density_kg_m3: 2_000,
        source: "Goodwinds / Tencom pultruded solid rod: flexural modulus 6.0e6 psi = \
                 41.4 GPa, flexural strength 120 ksi = 827 MPa (no margin), specific \
                 gravity 2.0; G: typical in-plane shear modulus of unidirectional \
                 E-glass/epoxy, about 5 GPa (estimate)",
    },
    Material {
        key: "carbon-fibre",
        name: "carbon-fibre rod (pultruded, epoxy)",
        youngs_modulus: mpa(127_000),
        shear_modulus: mpa(4_315),
        allowable_stress: mpa(1_370),
        density_kg_m3: 1_500,
        source: "Goodwinds carbon, minimum properties: flexural modulus 18.5e6 psi = \
                 127 GPa, flexural strength 200 ksi = 1.37 GPa (no margin), 1.5 g/cm3; \
                 G_xy 4315 MPa of a CFRP (Manufacturing Rev. 2020, table 2)",
    },
];

/// The material named `key` (as in [`Material::key`]).
#[must_use]
pub fn find(key: &str) -> Option<&'static Material> {
    MATERIALS.iter().find(|m| m.key == key)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Design, DesignParams};

    #[test]
    fn every_material_builds_a_design_with_the_paper_geometry() {
        for m in &MATERIALS {
            let mut p = DesignParams::PAPER;
            p.youngs_modulus = m.youngs_modulus;
            p.shear_modulus = m.isotropic_shear();
            p.allowable_stress = m.allowable_stress;
            assert!(Design::new(p).is_ok(), "{}", m.key);
        }
    }

    #[test]
    fn spring_steel_is_the_paper_preset() {
        let p = DesignParams::PAPER;
        assert_eq!(SPRING_STEEL.youngs_modulus, p.youngs_modulus);
        assert_eq!(SPRING_STEEL.shear_modulus, p.shear_modulus);
        assert_eq!(SPRING_STEEL.allowable_stress, p.allowable_stress);
        assert_eq!(find("spring-steel"), Some(&MATERIALS[0]));
        assert_eq!(find("unobtainium"), None);
    }

    #[test]
    fn glass_fibre_deflects_about_three_times_steel() {
        let ratio = |m: &Material| {
            m.allowable_stress.get().to_num::<f64>() / m.youngs_modulus.get().to_num::<f64>()
        };
        let g = ratio(find("glass-fibre").unwrap()) / ratio(&SPRING_STEEL);
        assert!((2.5..3.0).contains(&g), "{g}");
    }
}
