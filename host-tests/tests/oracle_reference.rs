//! Checks the f64 oracle (`host_tests::oracle`) against the published numbers in `docs/design.md`
//! §2.2, with tolerances taken from how each number is printed there (half a unit in the last
//! printed digit), plus internal consistency checks.

use host_tests::oracle::{
    natural_frequency, stiffness_for_frequency, Design, DomainError, HysteresisFollower,
};
use host_tests::reference::{assert_printed, TABLE_2_2 as TABLE};

const MM: f64 = 1e-3;
const MPA: f64 = 1e6;
/// The table's reference torque, 2 N·m.
const TAU_REF: f64 = 2.0;

#[test]
fn table_stiffness_euler_bernoulli() {
    let d = Design::paper();
    for (l_mm, k, ..) in TABLE {
        assert_printed(
            &format!("k at L = {l_mm} mm"),
            d.stiffness(f64::from(l_mm) * MM),
            k,
        );
    }
}

#[test]
fn table_stiffness_timoshenko() {
    let d = Design::paper();
    for (l_mm, _, k_t, ..) in TABLE {
        let value = d.stiffness_timoshenko(f64::from(l_mm) * MM);
        assert_printed(&format!("k_T at L = {l_mm} mm"), value, k_t);
    }
}

#[test]
fn table_deflection_at_2nm_degrees() {
    let d = Design::paper();
    for (l_mm, _, _, theta_deg, ..) in TABLE {
        let value = d.deflection(TAU_REF, f64::from(l_mm) * MM).to_degrees();
        assert_printed(&format!("θ at L = {l_mm} mm"), value, theta_deg);
    }
}

#[test]
fn table_root_stress_at_2nm_mpa() {
    let d = Design::paper();
    for (l_mm, _, _, _, sigma_mpa, _) in TABLE {
        let value = d.root_stress(TAU_REF, f64::from(l_mm) * MM) / MPA;
        assert_printed(&format!("σ at L = {l_mm} mm"), value, sigma_mpa);
    }
}

#[test]
fn table_torque_capacity() {
    let d = Design::paper();
    for (l_mm, _, _, _, _, tau_cap) in TABLE {
        let value = d.torque_capacity(f64::from(l_mm) * MM);
        assert_printed(&format!("τ_cap at L = {l_mm} mm"), value, tau_cap);
    }
}

#[test]
fn capacity_is_where_stress_reaches_sigma_allow() {
    let d = Design::paper();
    for l_mm in [1.0, 2.0, 3.0, 4.0, 5.0, 8.0] {
        let l = l_mm * MM;
        let sigma = d.root_stress(d.torque_capacity(l), l);
        assert!((sigma / d.sigma_allow - 1.0).abs() < 1e-12, "L = {l_mm} mm");
        let theta_cap = d.deflection_capacity(l);
        let expected = d.deflection(d.torque_capacity(l), l);
        assert!((theta_cap / expected - 1.0).abs() < 1e-12, "L = {l_mm} mm");
    }
    // §4: at L = 5 mm, 2 N·m overloads the preset's beams (3.3 GPa > 1.5 GPa).
    assert!(d.root_stress(TAU_REF, 5.0 * MM) > 2.0 * d.sigma_allow);
}

#[test]
fn timoshenko_ratio_at_1mm() {
    let d = Design::paper();
    let ratio = d.stiffness_timoshenko(MM) / d.stiffness(MM);
    assert_printed("k_T/k at L = 1 mm", ratio, "0.65");
    // Shear matters less as L grows; k_T < k always.
    let mut last = ratio;
    for l_mm in [2.0, 3.0, 4.0, 5.0] {
        let r = d.stiffness_timoshenko(l_mm * MM) / d.stiffness(l_mm * MM);
        assert!(r > last && r < 1.0, "L = {l_mm} mm: ratio {r}");
        last = r;
    }
}

#[test]
fn shear_coefficient_of_preset() {
    let d = Design::paper();
    // E = 200 GPa, G = 80 GPa: ν = 0.25, κ = 6·1.25/8.5 = 15/17.
    assert!((d.poisson() - 0.25).abs() < 1e-15);
    assert!((d.shear_coefficient() - 15.0 / 17.0).abs() < 1e-15);
}

#[test]
fn delta_max_and_theta_max_preset() {
    let d = Design::paper();
    assert_printed("δ_max in mm", d.delta_max() / MM, "0.32");
    assert_printed("θ_max in rad", d.theta_max(), "0.04");
}

#[test]
fn slot_clearance_radius_and_free_play() {
    let d = Design::paper();
    let c = d.theta_max() * d.t_c;
    assert_eq!(d.slot_clearance(), c);
    assert_eq!(d.slot_radius(), d.r + c);
    assert_eq!(d.free_play(), c / d.pitch_r);
    // Preset: c = 0.04 · 1 mm = 40 µm, slot radius 0.54 mm, free play 40 µm / 7.8 mm.
    assert!((d.slot_clearance() - 40e-6).abs() < 1e-18);
    assert!((d.slot_radius() - 0.54e-3).abs() < 1e-15);
    assert!((d.free_play() - 40e-6 / 7.8e-3).abs() < 1e-15);
}

#[test]
fn fig6_deflection_vs_beam_radius() {
    // docs/design.md §2.2: L = 5 mm, 2 N·m, r = 0.5 / 1 / 1.5 mm → 2.00° / 0.125° / 0.0247°.
    for (r_mm, printed) in [(0.5, "2.00"), (1.0, "0.125"), (1.5, "0.0247")] {
        let d = Design {
            r: r_mm * MM,
            ..Design::paper()
        };
        let value = d.deflection(TAU_REF, 5.0 * MM).to_degrees();
        assert_printed(&format!("Fig. 6, r = {r_mm} mm"), value, printed);
    }
}

#[test]
fn inverse_euler_bernoulli_roundtrip() {
    let d = Design::paper();
    for i in 0..=80 {
        let l = (0.1 + 0.1 * f64::from(i)) * MM;
        let back = d.length_for_stiffness(d.stiffness(l)).unwrap();
        assert!((back / l - 1.0).abs() < 1e-12, "L = {l}: back {back}");
    }
}

#[test]
fn inverse_timoshenko_roundtrip() {
    let d = Design::paper();
    for i in 0..=80 {
        let l = (0.1 + 0.1 * f64::from(i)) * MM;
        let back = d
            .length_for_stiffness_timoshenko(d.stiffness_timoshenko(l))
            .unwrap();
        assert!((back / l - 1.0).abs() < 1e-12, "L = {l}: back {back}");
    }
    // The shear-corrected length for a given stiffness is shorter than the E–B one.
    let k = 1000.0;
    let l_eb = d.length_for_stiffness(k).unwrap();
    let l_t = d.length_for_stiffness_timoshenko(k).unwrap();
    assert!(l_t < l_eb);
}

#[test]
fn inverses_reject_non_positive_stiffness() {
    let d = Design::paper();
    for k in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        assert!(d.length_for_stiffness(k).is_err(), "k = {k}");
        assert!(d.length_for_stiffness_timoshenko(k).is_err(), "k = {k}");
    }
}

#[test]
fn backlash_tilt_domain() {
    let d = Design::paper();
    // Inside the range, including both ends.
    assert!((d.backlash_tilt(d.t_c).unwrap() - d.theta_max()).abs() < 1e-15);
    let at_l = d.backlash_tilt(d.l).unwrap();
    assert!((at_l - d.theta_max() * d.t_c / d.l).abs() < 1e-15);
    assert!((d.backlash_tilt(4.0 * MM).unwrap() - 0.01).abs() < 1e-15);
    // Outside: domain errors.
    for x in [
        0.0,
        0.5 * MM,
        0.999 * MM,
        8.001 * MM,
        10.0 * MM,
        -MM,
        f64::NAN,
    ] {
        match d.backlash_tilt(x) {
            Err(DomainError::OutOfRange { min, max, .. }) => {
                assert_eq!((min, max), (d.t_c, d.l));
            }
            other => panic!("x = {x}: expected a domain error, got {other:?}"),
        }
    }
}

#[test]
fn hysteresis_branch_ordering() {
    let d = Design::paper();
    for l_mm in [1.0, 1.6, 4.0, 6.4] {
        let l = l_mm * MM;
        for i in 1..=50 {
            let phi = 0.001 * f64::from(i);
            let elastic = d.stiffness(l) * phi;
            let load = d.torque_loading(phi, l);
            let unload = d.torque_unloading(phi, l);
            assert!(
                load >= elastic && elastic >= unload,
                "L = {l_mm} mm, φ = {phi}"
            );
            assert!(load > unload);
            // Odd symmetry: the branches mirror for negative deflection.
            assert!((d.torque_loading(-phi, l) + load).abs() <= 1e-12 * load);
            assert!((d.torque_unloading(-phi, l) + unload).abs() <= 1e-12 * load);
        }
    }
}

/// ∫₀^φmax (τ_load − τ_unload) dφ by the trapezoid rule.
fn loop_area_numeric(d: &Design, phi_max: f64, l: f64) -> f64 {
    let steps = 10_000;
    let h = phi_max / f64::from(steps);
    let gap = |phi: f64| d.torque_loading(phi, l) - d.torque_unloading(phi, l);
    let inner: f64 = (1..steps).map(|i| gap(h * f64::from(i))).sum();
    h * (0.5 * gap(0.0) + inner + 0.5 * gap(phi_max))
}

#[test]
fn hysteresis_loop_area_grows_with_phi_and_shorter_length() {
    let d = Design::paper();
    // Closed form matches the numerical integral of the branches.
    for (phi, l_mm) in [(0.01, 1.6), (0.04, 4.0), (0.02, 6.4)] {
        let closed = d.hysteresis_loop_energy(phi, l_mm * MM);
        let numeric = loop_area_numeric(&d, phi, l_mm * MM);
        assert!(
            (closed / numeric - 1.0).abs() < 1e-6,
            "{closed} vs {numeric}"
        );
    }
    // Grows with φ at fixed L.
    let l = 4.0 * MM;
    let mut last = 0.0;
    for i in 1..=10 {
        let e = d.hysteresis_loop_energy(0.005 * f64::from(i), l);
        assert!(e > last);
        last = e;
    }
    // Grows as L shrinks, at fixed φ (x = 0.8l, 0.5l, 0.2l as in Fig. 4).
    let phi = 0.01;
    let areas: Vec<f64> = [0.8, 0.5, 0.2]
        .iter()
        .map(|f| d.hysteresis_loop_energy(phi, f * d.l))
        .collect();
    assert!(areas[0] < areas[1] && areas[1] < areas[2], "{areas:?}");
}

/// The hysteresis as an equivalent damper: for a swing φ₀ ± Δ on one side the branches
/// enclose W = (2·k·c/3)·((φ₀ + Δ)³ − (φ₀ − Δ)³) = 4·k·c·φ₀²·Δ + (4/3)·k·c·Δ³ with
/// c = (6/5)·μ·R/L (integrated by hand from the §2.1 branches k·φ·(1 ± c·φ)), and a damper
/// b dissipates π·b·ω·Δ² a cycle. A damper that size in the two-mass model takes W a cycle
/// from the motor (its mechanical input grows by W at the coupling mode, where the
/// undamped model needs none).
#[test]
fn hysteresis_damping_dissipates_the_loop() {
    let d = Design::paper();
    for (phi0, delta, w, l_mm) in [
        (0.08, 0.03, 36.4, 15.0),
        (0.003, 0.001, 36.4, 5.0),
        (0.02, 0.02, 10.0, 3.0),
    ] {
        let l = l_mm * MM;
        let k = d.stiffness(l);
        let c = 1.2 * d.mu * d.pitch_r / l;
        let w_loop = 4.0 * k * c * phi0 * phi0 * delta + 4.0 / 3.0 * k * c * delta.powi(3);
        let b = d.hysteresis_damping(phi0, delta, w, l);
        let want = w_loop / (std::f64::consts::PI * w * delta * delta);
        assert!((b / want - 1.0).abs() < 1e-9, "{b} vs {want}");
    }
    assert_eq!(d.hysteresis_damping(0.01, 0.0, 10.0, 4.0 * MM), 0.0);
    // Without copper loss and other friction the motor's electrical input is
    // (k_e/k_t) × what the coupling damper dissipates, π·b_c·ω·|Θ_g − Θ_l|².
    let m = host_tests::oracle::TwoMass {
        j_gear: 3.2e-3,
        j_link: 3.2e-3,
        k: 2.0,
        b_coupling: 4e-3,
        b_gear: 0.0,
        b_link: 0.0,
        resistance: 0.0,
        k_t: 1.0,
        k_e: 1.94,
        load: 0.0,
    };
    let (a, w) = (0.015, m.natural_frequency());
    let delta = m.deflection_amplitude(a, w);
    let want = 1.94 * std::f64::consts::PI * 4e-3 * w * delta * delta;
    let got = m.energy_per_cycle(a, w);
    assert!((got / want - 1.0).abs() < 1e-9, "{got} vs {want}");
}

/// The follower's torque is the branch's: equal to a few ulps (an optimised build
/// evaluates the same expression inlined in another order of rounding).
fn assert_same(got: f64, branch: f64) {
    assert!(
        (got - branch).abs() <= 4.0 * f64::EPSILON * branch.abs(),
        "{got} against the branch's {branch}"
    );
}

#[test]
fn hysteresis_follower_switches_on_reversal() {
    let d = Design::paper();
    let l = 0.5 * d.l;
    let mut h = HysteresisFollower::new(d, l);
    // No motion yet: elastic.
    assert_eq!(h.step(0.0), 0.0);
    assert_eq!(h.direction(), None);
    // Loading up to 0.02 rad.
    for i in 1..=20 {
        let phi = 0.001 * f64::from(i);
        assert_same(h.step(phi), d.torque_loading(phi, l));
    }
    // Standing still keeps the branch.
    assert_same(h.step(0.02), d.torque_loading(0.02, l));
    // Reversal: unloading at the same point drops the torque.
    let t = h.step(0.019);
    assert_same(t, d.torque_unloading(0.019, l));
    assert!(t < d.stiffness(l) * 0.019);
    // Through zero into negative deflection: loading again (|φ| grows), mirrored.
    for i in (-20..=18).rev() {
        let phi = 0.001 * f64::from(i);
        let t = h.step(phi);
        if phi > 0.0 {
            assert_same(t, d.torque_unloading(phi, l));
        } else {
            assert_same(t, d.torque_loading(phi, l));
        }
    }
    // Reversal at the negative end: unloading towards zero.
    let t = h.step(-0.019);
    assert_same(t, d.torque_unloading(-0.019, l));
    assert!(t > d.stiffness(l) * -0.019);
    // A closed cycle dissipates energy: ∮ τ dφ over one loop is positive, and matches twice
    // the 0 → φ → 0 loop energy (both half-loops).
    let mut h = HysteresisFollower::new(d, l);
    let amp = 0.02;
    let n = 4000;
    let path: Vec<f64> = (0..=4 * n)
        .map(|i| {
            let s = f64::from(i) / f64::from(n);
            // Triangle wave 0 → amp → 0 → −amp → 0.
            match s {
                s if s <= 1.0 => amp * s,
                s if s <= 3.0 => amp * (2.0 - s),
                s => amp * (s - 4.0),
            }
        })
        .collect();
    let taus: Vec<f64> = path.iter().map(|&p| h.step(p)).collect();
    let work: f64 = path
        .windows(2)
        .zip(taus.windows(2))
        .map(|(p, t)| 0.5 * (t[0] + t[1]) * (p[1] - p[0]))
        .sum();
    let expected = 2.0 * d.hysteresis_loop_energy(amp, l);
    assert!(work > 0.0);
    assert!((work / expected - 1.0).abs() < 1e-2, "{work} vs {expected}");
}

#[test]
fn coupling_torque_dead_zone() {
    let d = Design::paper();
    let l = 3.0 * MM;
    let k = d.stiffness(l);
    let phi_b = d.free_play();
    assert_eq!(d.coupling_torque(0.0, l), 0.0);
    assert_eq!(d.coupling_torque(phi_b, l), 0.0);
    assert_eq!(d.coupling_torque(-phi_b, l), 0.0);
    assert_eq!(d.coupling_torque(0.5 * phi_b, l), 0.0);
    let phi = phi_b + 0.01;
    assert!((d.coupling_torque(phi, l) - k * 0.01).abs() < 1e-9);
    assert!((d.coupling_torque(-phi, l) + k * 0.01).abs() < 1e-9);
    // Continuous at the edge of the dead zone and odd.
    let just_out = phi_b * (1.0 + 1e-9);
    assert!(d.coupling_torque(just_out, l).abs() < 1e-6);
}

#[test]
fn natural_frequency_roundtrip() {
    let j = 1e-3;
    let k = 265.0;
    let w = natural_frequency(k, j);
    assert!((w * w * j / k - 1.0).abs() < 1e-14);
    assert!((stiffness_for_frequency(j, w) / k - 1.0).abs() < 1e-14);
    // Stiffness to put the link at 2 Hz with J = 1e-3 kg·m², and the clutch length for it.
    let omega = 2.0 * std::f64::consts::PI * 2.0;
    let k = stiffness_for_frequency(j, omega);
    let d = Design::paper();
    let l = d.length_for_stiffness(k).unwrap();
    assert!((natural_frequency(d.stiffness(l), j) / omega - 1.0).abs() < 1e-12);
}
