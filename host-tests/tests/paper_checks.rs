//! The paper's figures and docs/design.md's reference numbers, from the fixed-point model:
//! Fig. 5 (k and k_T for L = 1…5 mm), Fig. 6 (deflection at 2 N·m, L = 5 mm, for
//! r = 0.5 / 1 / 1.5 mm), the stress/capacity table of docs/design.md §2.2, the preset's
//! backlash numbers (§2 row 5) and the link's anti-resonance (§3).
//!
//! Each number is checked twice: the model within 0.5 % of the f64 oracle, and the oracle
//! against the number printed in docs/design.md (within half a unit of its last printed digit).

use host_tests::convert::{mm, mpa, nm, nm_rad, oracle_design, rad, rad_s, KG_MM2, MM, MPA};
use host_tests::oracle;
use host_tests::reference::{assert_printed, TABLE_2_2 as TABLE};
use model::dynamics::natural_frequency;
use model::{Design, DesignParams, Inertia, Length, Torque};

/// Model vs oracle on the paper's figures.
const FIG_TOL: f64 = 5e-3;

/// Asserts the model's `got` is within `rel` of the oracle's `want`.
#[track_caller]
fn assert_rel(what: &str, got: f64, want: f64, rel: f64) {
    assert!(
        ((got - want) / want).abs() <= rel,
        "{what}: model {got} vs oracle {want} (relative {:e} > {rel:e})",
        (got - want) / want
    );
}

fn paper() -> (Design, oracle::Design) {
    let d = Design::paper();
    assert_eq!(Design::new(DesignParams::PAPER), Ok(d));
    (d, oracle::Design::paper())
}

#[test]
fn paper_preset_is_the_oracles() {
    // The model's preset is the oracle's, up to R = 7.8 mm and μ = 0.4 held to 2⁻³².
    let (m, o) = (oracle_design(&DesignParams::PAPER), oracle::Design::paper());
    assert_eq!((m.n, m.r, m.e, m.g), (o.n, o.r, o.e, o.g));
    assert_eq!((m.sigma_allow, m.l, m.t_c), (o.sigma_allow, o.l, o.t_c));
    assert!(((m.pitch_r - o.pitch_r) / o.pitch_r).abs() < 1e-10);
    assert!(((m.mu - o.mu) / o.mu).abs() < 1e-9);
}

#[test]
fn fig5_stiffness_euler_bernoulli_and_timoshenko() {
    let (d, o) = paper();
    for (l, k, k_t, ..) in TABLE {
        let len = Length::from_int(l);
        let l_m = f64::from(l) * MM;
        assert_printed(&format!("k({l} mm)"), o.stiffness(l_m), k);
        assert_printed(&format!("k_T({l} mm)"), o.stiffness_timoshenko(l_m), k_t);
        let got = nm_rad(d.stiffness(len).unwrap());
        assert_rel(&format!("k({l} mm)"), got, o.stiffness(l_m), FIG_TOL);
        let got = nm_rad(d.stiffness_timoshenko(len).unwrap());
        assert_rel(
            &format!("k_T({l} mm)"),
            got,
            o.stiffness_timoshenko(l_m),
            FIG_TOL,
        );
    }
}

#[test]
fn fig5_timoshenko_ratio_at_1mm() {
    // docs/design.md row 4T: k_T/k = 0.65 at L = 1 mm, r = 0.5 mm.
    let (d, o) = paper();
    let ratio = o.stiffness_timoshenko(MM) / o.stiffness(MM);
    assert_printed("k_T/k at 1 mm", ratio, "0.65");
    let one = Length::from_int(1);
    let got = nm_rad(d.stiffness_timoshenko(one).unwrap()) / nm_rad(d.stiffness(one).unwrap());
    assert_rel("k_T/k at 1 mm", got, ratio, FIG_TOL);
}

#[test]
fn fig6_deflection_vs_beam_radius() {
    // 2 N·m at L = 5 mm; r in millionths of a mm, docs/design.md's E–B values in degrees.
    for (r_micro, printed) in [
        (500_000, "2.00"),
        (1_000_000, "0.125"),
        (1_500_000, "0.0247"),
    ] {
        let r = Length::from_micro(r_micro).unwrap();
        let p = DesignParams {
            beam_radius: r,
            ..DesignParams::PAPER
        };
        let (d, o) = (Design::new(p).unwrap(), oracle_design(&p));
        let want = o.deflection(2.0, 5.0 * MM).to_degrees();
        assert_printed(&format!("Fig. 6, r = {r} mm"), want, printed);
        let got = rad(d
            .deflection(Torque::from_int(2), Length::from_int(5))
            .unwrap());
        assert_rel(
            &format!("Fig. 6, r = {r} mm"),
            got.to_degrees(),
            want,
            FIG_TOL,
        );
    }
}

#[test]
fn table_deflection_stress_and_capacity() {
    let (d, o) = paper();
    let two = Torque::from_int(2);
    for (l, _, _, theta, sigma, cap) in TABLE {
        let len = Length::from_int(l);
        let l_m = f64::from(l) * MM;
        let want = o.deflection(2.0, l_m).to_degrees();
        assert_printed(&format!("θ({l} mm) at 2 N·m"), want, theta);
        let got = rad(d.deflection(two, len).unwrap()).to_degrees();
        assert_rel(&format!("θ({l} mm) at 2 N·m"), got, want, FIG_TOL);

        let want = o.root_stress(2.0, l_m) / MPA;
        assert_printed(&format!("σ({l} mm) at 2 N·m"), want, sigma);
        let got = mpa(d.root_stress(two, len).unwrap());
        assert_rel(&format!("σ({l} mm) at 2 N·m"), got, want, FIG_TOL);

        let want = o.torque_capacity(l_m);
        assert_printed(&format!("τ_cap({l} mm)"), want, cap);
        let got = nm(d.torque_capacity(len).unwrap());
        assert_rel(&format!("τ_cap({l} mm)"), got, want, FIG_TOL);

        // The capacity is where the stress reaches σ_allow = 1.5 GPa.
        let at_cap = mpa(d.root_stress(d.torque_capacity(len).unwrap(), len).unwrap());
        assert_rel(
            &format!("σ(τ_cap({l} mm))"),
            at_cap,
            o.sigma_allow / MPA,
            1e-6,
        );
    }
    // docs/design.md §4: at L = 5 mm, 2 N·m is beyond the stress limit (3.3 GPa > 1.5 GPa).
    let five = Length::from_int(5);
    assert!(two > d.torque_capacity(five).unwrap());
    assert!(mpa(d.root_stress(two, five).unwrap()) > 2.0 * o.sigma_allow / MPA);
}

#[test]
fn preset_backlash_numbers() {
    // docs/design.md §2 row 5: δ_max = 0.32 mm → θ_max = 0.04 rad for the preset.
    let (d, o) = paper();
    assert_printed("δ_max (mm)", o.delta_max() / MM, "0.32");
    assert_printed("θ_max (rad)", o.theta_max(), "0.04");
    assert_rel(
        "δ_max",
        mm(d.max_tip_deflection()),
        o.delta_max() / MM,
        1e-6,
    );
    assert_rel("θ_max", rad(d.bending_capacity()), o.theta_max(), 1e-6);
    assert_rel("c", mm(d.slot_clearance()), o.slot_clearance() / MM, 1e-6);
    assert_rel("r_slot", mm(d.slot_radius()), o.slot_radius() / MM, 1e-6);
    assert_rel("φ_b", rad(d.free_play()), o.free_play(), 1e-6);
}

#[test]
fn link_anti_resonance_and_torque_per_count() {
    // docs/design.md §3: J_link = 1e-3 kg·m² → 426 Hz at L = 1 mm, 38 Hz at L = 5 mm; torque per
    // gear-encoder count (300°/1024) is 36.7 N·m at L = 1 mm and 0.29 N·m at L = 5 mm.
    let (d, o) = paper();
    let j = Inertia::from_int(1000); // kg·mm²
    let count = (300.0f64 / 1024.0).to_radians();
    for (l, hz, per_count) in [(1, "426", "36.7"), (5, "38", "0.29")] {
        let l_m = f64::from(l) * MM;
        let want = oracle::natural_frequency(o.stiffness(l_m), 1000.0 * KG_MM2);
        assert_printed(&format!("f_n({l} mm) Hz"), want / std::f64::consts::TAU, hz);
        let k = d.stiffness(Length::from_int(l)).unwrap();
        let got = rad_s(natural_frequency(k, j).unwrap());
        assert_rel(&format!("ω_n({l} mm)"), got, want, FIG_TOL);
        // docs/design.md prints 36.7 for k(1 mm)·q = 36.650 (rounded twice): allow one unit in
        // its last digit here instead of a half.
        let printed: f64 = per_count.parse().unwrap();
        let unit =
            10f64.powi(-i32::try_from(per_count.split('.').nth(1).map_or(0, str::len)).unwrap());
        let want = o.stiffness(l_m) * count;
        assert!(
            (want - printed).abs() <= unit,
            "τ per count ({l} mm): oracle {want} vs docs/design.md {per_count}"
        );
    }
}
