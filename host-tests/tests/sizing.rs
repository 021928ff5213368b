//! The explorer's per-design numbers (`model::sizing`, `model::material`) against the f64
//! oracle's independent formulas (docs/design.md §10): stored energy at capacity
//! n·σ²·π·r²·L/(24·E), θ_cap = σ·L²/(3·E·r·R), beam mass, envelope volume, slot fit; and a
//! brute-force grid: every design the model's check accepts meets every constraint by the
//! oracle, and every design it rejects misses one.
//!
//! `PROPTEST_CASES` sets the number of random designs (default 10 000 here).

use host_tests::convert::MPA;
use host_tests::oracle;
use model::material::{Material, MATERIALS};
use model::sizing::{beam_mass, energy_at_capacity, envelope_volume, slots_fit, Candidate, Goals};
use model::{Angle, Design, DesignParams, Length, Torque};
use proptest::prelude::*;

const MM: f64 = 1e-3;

fn fix(x: f64) -> i64 {
    (x * 4_294_967_296.0).round() as i64
}

fn len(mm: f64) -> Length {
    Length::from_bits(fix(mm))
}

fn f32_(bits: i64) -> f64 {
    bits as f64 / 4_294_967_296.0
}

/// The model's design and the oracle's, from the same (model-unit) parameters.
fn both(p: DesignParams) -> Option<(Design, oracle::Design)> {
    let d = Design::new(p).ok()?;
    let o = oracle::Design {
        n: u32::from(p.beams),
        r: f32_(p.beam_radius.to_bits()) * MM,
        pitch_r: f32_(p.pitch_radius.to_bits()) * MM,
        e: f32_(p.youngs_modulus.to_bits()) * MPA,
        g: f32_(p.shear_modulus.to_bits()) * MPA,
        sigma_allow: f32_(p.allowable_stress.to_bits()) * MPA,
        l: f32_(p.beam_length.to_bits()) * MM,
        t_c: f32_(p.clutch_thickness.to_bits()) * MM,
        mu: 0.4,
    };
    Some((d, o))
}

fn params(m: &Material, n: u8, r: f64, big_r: f64, l: f64, t_c: f64) -> DesignParams {
    DesignParams {
        beams: n,
        beam_radius: len(r),
        pitch_radius: len(big_r),
        youngs_modulus: m.youngs_modulus,
        shear_modulus: m.isotropic_shear(),
        allowable_stress: m.allowable_stress,
        beam_length: len(l),
        clutch_thickness: len(t_c),
        friction: DesignParams::PAPER.friction,
    }
}

fn rel(got: f64, want: f64) -> f64 {
    ((got - want) / want).abs()
}

#[test]
fn paper_preset_against_design_md() {
    // docs/design.md §10: the paper preset at L = 5 mm stores ≈ 7 mJ at θ_cap = 0.016 rad.
    let (d, o) = both(DesignParams::PAPER).unwrap();
    let l5 = Length::from_int(5);
    let e = energy_at_capacity(&d, l5).unwrap().to_num::<f64>();
    assert!(rel(e, o.energy_at_capacity(5.0 * MM)) < 1e-6);
    assert!((e - 7.36e-3).abs() < 0.01e-3, "{e}");
    let th = d.deflection_capacity(l5).unwrap().get().to_num::<f64>();
    assert!((th - 0.01603).abs() < 1e-5, "{th}");
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: std::env::var("PROPTEST_CASES").ok().and_then(|s| s.parse().ok()).unwrap_or(10_000),
        ..ProptestConfig::default()
    })]

    #[test]
    fn sizing_matches_the_oracle(
        mi in 0..MATERIALS.len(),
        n in 1u8..=16,
        r in 0.05f64..3.0,
        big_r_over_r in 1.05f64..30.0,
        l in 0.5f64..40.0,
        tc_frac in 0.01f64..0.9,
        clamp in 0.0f64..5.0,
    ) {
        let m = &MATERIALS[mi];
        let big_r = (r * big_r_over_r).min(100.0);
        let p = params(m, n, r, big_r, l, l * tc_frac);
        let Some((d, o)) = both(p) else { return Ok(()); };
        let l_m = o.l;
        let total = l + clamp;
        let total_m = f32_(len(total).to_bits()) * MM;
        // θ_cap: the model's E–B capacity function vs the oracle's closed form.
        let th = d.deflection_capacity(p.beam_length).unwrap().get().to_num::<f64>();
        let th_o = o.deflection_capacity_closed_form(l_m);
        prop_assert!((th - th_o).abs() <= 1e-6 * th_o + 1e-9, "θ_cap {th} vs {th_o}");
        // Energy at capacity: ½·τ_cap·θ_cap (model) vs n·σ²·π·r²·L/(24·E) (oracle).
        if let Ok(e) = energy_at_capacity(&d, p.beam_length) {
            let e_o = o.energy_at_capacity(l_m);
            prop_assert!((e.to_num::<f64>() - e_o).abs() <= 1e-6 * e_o + 1e-9, "energy {e} vs {e_o}");
        }
        if let Ok(mass) = beam_mass(&d, len(total), m.density_kg_m3) {
            let m_o = o.beam_mass(total_m, f64::from(m.density_kg_m3)) * 1e3;
            prop_assert!((mass.to_num::<f64>() - m_o).abs() <= 1e-6 * m_o + 1e-9, "mass {mass} g vs {m_o}");
        }
        if let Ok(v) = envelope_volume(&d, len(total)) {
            let v_o = o.envelope_volume(total_m) * 1e9;
            prop_assert!((v.to_num::<f64>() - v_o).abs() <= 1e-6 * v_o + 1e-9, "volume {v} mm³ vs {v_o}");
        }
        // Slot fit, away from the boundary: the model's sin(π/n) is a 256-step quarter
        // table, linearly interpolated, which reads low by up to h²/8·sin x (h = π/512,
        // |sin''| = sin): 4.7e-6 relative; twice that is left out.
        let rs = o.slot_radius();
        let chord = if n < 2 { f64::INFINITY } else { o.pitch_r * (std::f64::consts::PI / f64::from(n)).sin() };
        let gap = (chord.min(o.pitch_r) - rs) / rs;
        let h = std::f64::consts::PI / 512.0;
        if gap.abs() > 2.0 * h * h / 8.0 {
            prop_assert_eq!(slots_fit(&d), o.slots_fit(), "gap {}", gap);
        }
    }
}

/// The oracle's verdict on every constraint, with the smallest relative distance to a
/// bound (to leave out ties the two number formats may break differently).
fn oracle_verdict(
    o: &oracle::Design,
    total_m: f64,
    rho: f64,
    goals: (f64, f64, f64, f64),
) -> (bool, f64) {
    let (cap, defl, mass, vol) = goals;
    let c = o.torque_capacity(o.l) / cap - 1.0;
    let d = o.deflection_capacity_closed_form(o.l) / defl - 1.0;
    let m = 1.0 - o.beam_mass(total_m, rho) / mass;
    let v = 1.0 - o.envelope_volume(total_m) / vol;
    let fit = o.slots_fit();
    let margins = [c, d, m, v];
    let ok = fit && margins.iter().all(|&x| x >= 0.0);
    (
        ok,
        margins
            .iter()
            .map(|x| x.abs())
            .fold(f64::INFINITY, f64::min),
    )
}

/// Brute force: a grid of designs around the paper's goals, relaxed so that some pass.
#[test]
fn brute_force_grid_accepts_exactly_the_feasible_designs() {
    let goals = Goals {
        // Off the grid's round numbers, so that no design sits on a bound.
        min_capacity: Torque::from_bits(fix(0.4937)),
        min_deflection: Angle::from_bits(fix(0.0513)),
        // I32F32 g and mm³ (built through a model unit: this crate does not name `fixed`).
        max_mass_g: Torque::from_bits(fix(5.5)).get(),
        max_volume_mm3: Torque::from_bits(fix(6400.0)).get(),
    };
    let g_oracle = (0.4937, 0.0513, 5.5e-3, 6.4e-6);
    let (mut accepted, mut rejected, mut ties) = (0, 0, 0);
    for m in &MATERIALS {
        for n in [2u8, 3, 4, 6, 8] {
            for ri in 1..=20 {
                let r = 0.1 * f64::from(ri);
                for ki in 0..=24 {
                    let big_r = 2.0 + 0.5 * f64::from(ki);
                    for li in 0..=12 {
                        let l = 2.0 + 0.5 * f64::from(li);
                        let p = params(m, n, r, big_r, l, 1.0);
                        let Some((d, o)) = both(p) else { continue };
                        let total = len(l + 2.0);
                        let c = Candidate {
                            design: d,
                            total_length: total,
                            density_kg_m3: m.density_kg_m3,
                        };
                        let s = c.size().unwrap();
                        let model_ok = s.meets_all(&goals);
                        let (oracle_ok, dist) = oracle_verdict(
                            &o,
                            f32_(total.to_bits()) * MM,
                            f64::from(m.density_kg_m3),
                            g_oracle,
                        );
                        if dist < 1e-6 {
                            ties += 1;
                            continue;
                        }
                        assert_eq!(
                            model_ok, oracle_ok,
                            "{} n={n} r={r} R={big_r} l={l}: model {model_ok}, oracle {oracle_ok}",
                            m.key
                        );
                        if model_ok {
                            accepted += 1
                        } else {
                            rejected += 1
                        }
                    }
                }
            }
        }
    }
    println!("brute-force grid: {accepted} accepted, {rejected} rejected, {ties} ties");
    // The grid must hold both kinds, or the check proves nothing.
    assert!(
        accepted > 100 && rejected > 1000,
        "accepted {accepted}, rejected {rejected}"
    );
    assert!(ties < 5, "{ties} designs within 1e-6 of a bound");
}

/// The closed-form bound is a real bound: over a fine grid of every material, no design
/// shorter than the shortest active length meets capacity, deflection and fit together.
#[test]
fn no_design_beats_the_shortest_active_length() {
    let (t, th) = (1.5, 0.2);
    let mut checked = 0;
    for m in &MATERIALS {
        let e = m.youngs_modulus.get().to_num::<f64>() * MPA;
        let s = m.allowable_stress.get().to_num::<f64>() * MPA;
        let l_min = oracle::min_active_length(t, th, e, s);
        for n in [2u8, 4, 8, 16] {
            for ri in 1..=20 {
                let r = 0.1 * f64::from(ri);
                for ki in 0..=30 {
                    let big_r = 1.0 + 0.5 * f64::from(ki);
                    for li in 1..=15 {
                        let l = f64::from(li);
                        if l * MM >= l_min {
                            continue;
                        }
                        let p = params(m, n, r, big_r, l, 0.5);
                        let Some((d, o)) = both(p) else { continue };
                        let s = Candidate {
                            design: d,
                            total_length: len(l),
                            density_kg_m3: 1,
                        }
                        .size()
                        .unwrap();
                        let meets = s.capacity_soft >= Torque::from_bits(fix(t))
                            && s.deflection_soft >= Angle::from_bits(fix(th))
                            && s.fits;
                        assert!(
                            !meets,
                            "{} n={n} r={r} R={big_r} l={l} beats L_min = {}",
                            m.key, l_min
                        );
                        assert!(
                            !(o.torque_capacity(o.l) >= t
                                && o.deflection_capacity(o.l) >= th
                                && o.slots_fit())
                        );
                        checked += 1;
                    }
                }
            }
        }
    }
    println!("{checked} designs below the bound checked");
    assert!(checked > 50_000, "{checked}");
}

/// The linear two-mass model by hand: with no friction and no load, at the coupling mode
/// ω² = k·(1/J_g + 1/J_l) the motor supplies no torque (the gear swings J_l/J_g times the
/// link's amplitude, in opposition), and with a rigid coupling the energy is the rigid
/// body's copper loss R·((J_g + J_l)·A·ω²/k_t)²·T/2.
#[test]
fn two_mass_model_by_hand() {
    let m = oracle::TwoMass {
        j_gear: 3.2e-3,
        j_link: 1.6e-3,
        k: 2.0,
        b_coupling: 0.0,
        b_gear: 0.0,
        b_link: 0.0,
        resistance: 8.0,
        k_t: 1.0,
        k_e: 1.94,
        load: 0.0,
    };
    let w = m.natural_frequency();
    assert!((w * w - 2.0 * (1.0 / 3.2e-3 + 1.0 / 1.6e-3)).abs() < 1e-9);
    let a = 0.1;
    assert!(m.energy_per_cycle(a, w).abs() < 1e-15);
    assert!((m.gear_amplitude(a, w) - a * 0.5).abs() < 1e-12);
    let rigid = oracle::TwoMass { k: 1e12, ..m };
    let w1 = 10.0;
    let t = std::f64::consts::TAU / w1;
    let want = 8.0 * (4.8e-3 * a * w1 * w1).powi(2) / 2.0 * t;
    assert!((rigid.energy_per_cycle(a, w1) - want).abs() < 1e-9 * want);
    // A load adds its holding current's copper loss, R·(τ/k_t)²·T.
    let loaded = oracle::TwoMass { load: 0.2, ..rigid };
    assert!((loaded.energy_per_cycle(a, w1) - want - 8.0 * 0.04 * t).abs() < 1e-9);
}
