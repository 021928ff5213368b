//! Bad input: every non-physical design parameter, every argument outside its domain and
//! every overflowing combination returns its own error variant (never a panic, never a
//! wrapped value). Where an error depends on magnitudes (overflow, too soft, too stiff), the
//! f64 oracle first confirms that the input really is beyond the limit.

use host_tests::convert::{
    bits32, mm, nm, nm_rad, oracle_design, rad, LSB32, MAX32, MAX64, MM, MPA,
};
use host_tests::oracle;
use model::design::{
    ALLOWABLE_STRESS_MAX, ALLOWABLE_STRESS_MIN, BEAMS_MAX, BEAMS_MIN, BEAM_LENGTH_MAX,
    BEAM_LENGTH_MIN, BEAM_RADIUS_MAX, BEAM_RADIUS_MIN, CLUTCH_THICKNESS_MIN, FRICTION_MAX,
    MODULUS_MAX, MODULUS_MIN, PITCH_RADIUS_MAX, PITCH_RADIUS_MIN,
};
use model::dynamics::{natural_frequency, stiffness_for_frequency};
use model::{
    Angle, BeamModel, Branch, Design, DesignParams, Error, Frequency, Hysteresis, Inertia, Length,
    Ratio, Setting, Stiffness, Stress, Torque,
};

const MODELS: [BeamModel; 2] = [BeamModel::EulerBernoulli, BeamModel::Timoshenko];

fn with(f: impl FnOnce(&mut DesignParams)) -> Result<Design, Error> {
    let mut p = DesignParams::PAPER;
    f(&mut p);
    Design::new(p)
}

fn up(v: Length) -> Length {
    Length::from_bits(v.to_bits() + 1)
}

fn down(v: Length) -> Length {
    Length::from_bits(v.to_bits() - 1)
}

fn up_s(v: Stress) -> Stress {
    Stress::from_bits(v.to_bits() + 1)
}

fn down_s(v: Stress) -> Stress {
    Stress::from_bits(v.to_bits() - 1)
}

// ---------------------------------------------------------------------------------------
// Non-physical designs: each parameter just outside its range, and far outside.

#[test]
fn beam_count_out_of_range() {
    for n in [0, BEAMS_MIN - 1, BEAMS_MAX + 1, u8::MAX] {
        assert_eq!(
            with(|p| p.beams = n),
            Err(Error::BeamCountOutOfRange),
            "n = {n}"
        );
    }
    for n in [BEAMS_MIN, BEAMS_MAX] {
        assert!(with(|p| p.beams = n).is_ok(), "n = {n}");
    }
}

#[test]
fn beam_radius_out_of_range() {
    for r in [
        Length::ZERO,
        Length::from_int(-1),
        Length::MIN,
        down(BEAM_RADIUS_MIN),
        up(BEAM_RADIUS_MAX),
        Length::MAX,
    ] {
        assert_eq!(
            with(|p| p.beam_radius = r),
            Err(Error::BeamRadiusOutOfRange),
            "r = {r}"
        );
    }
    for r in [BEAM_RADIUS_MIN, BEAM_RADIUS_MAX] {
        assert!(with(|p| p.beam_radius = r).is_ok(), "r = {r}");
    }
}

#[test]
fn pitch_radius_out_of_range_or_not_above_beam_radius() {
    for big_r in [
        Length::ZERO,
        Length::from_int(-8),
        down(PITCH_RADIUS_MIN),
        up(PITCH_RADIUS_MAX),
        Length::MAX,
    ] {
        assert_eq!(
            with(|p| p.pitch_radius = big_r),
            Err(Error::PitchRadiusOutOfRange),
            "R = {big_r}"
        );
    }
    // R must exceed r: R = r and R = r − 1 LSB are rejected, R = r + 1 LSB accepted.
    let r = Length::from_int(3);
    for (big_r, ok) in [(r, false), (down(r), false), (up(r), true)] {
        let got = with(|p| {
            p.beam_radius = r;
            p.pitch_radius = big_r;
        });
        if ok {
            assert!(got.is_ok(), "R = {big_r}: {got:?}");
        } else {
            assert_eq!(got, Err(Error::PitchRadiusOutOfRange), "R = {big_r}");
        }
    }
}

#[test]
fn moduli_out_of_range() {
    for e in [
        Stress::ZERO,
        Stress::from_int(-200_000),
        down_s(MODULUS_MIN),
        up_s(MODULUS_MAX),
    ] {
        assert_eq!(
            with(|p| p.youngs_modulus = e),
            Err(Error::YoungsModulusOutOfRange),
            "E = {e}"
        );
        assert_eq!(
            with(|p| p.shear_modulus = e),
            Err(Error::ShearModulusOutOfRange),
            "G = {e}"
        );
    }
}

#[test]
fn poisson_ratio_above_one_half() {
    // ν = E/(2G) − 1 > 0.5 ⟺ G < E/3 (oracle: ν of the rejected designs is above 0.5).
    let e = Stress::from_int(300_000);
    for (g, ok) in [
        (Stress::from_int(100_000), true), // ν = 0.5 exactly
        (down_s(Stress::from_int(100_000)), false),
        (Stress::from_int(60_000), false),
        (MODULUS_MIN, false),
    ] {
        let mut p = DesignParams::PAPER;
        p.youngs_modulus = e;
        p.shear_modulus = g;
        let nu = oracle_design(&p).poisson();
        assert_eq!(nu > 0.5, !ok, "G = {g}: oracle ν = {nu}");
        let got = Design::new(p);
        if ok {
            assert!(got.is_ok(), "G = {g}: {got:?}");
        } else {
            assert_eq!(got, Err(Error::PoissonRatioNonPhysical), "G = {g}");
        }
    }
}

#[test]
fn allowable_stress_out_of_range() {
    for s in [
        Stress::ZERO,
        Stress::from_int(-1_500),
        down_s(ALLOWABLE_STRESS_MIN),
        up_s(ALLOWABLE_STRESS_MAX),
        Stress::MAX,
    ] {
        assert_eq!(
            with(|p| p.allowable_stress = s),
            Err(Error::AllowableStressOutOfRange),
            "σ_allow = {s}"
        );
    }
}

#[test]
fn beam_length_out_of_range() {
    for l in [
        Length::ZERO,
        Length::from_int(-8),
        down(BEAM_LENGTH_MIN),
        up(BEAM_LENGTH_MAX),
    ] {
        // Keep t_c below l where l itself is valid-looking, so that l is the first fault.
        assert_eq!(
            with(|p| {
                p.beam_length = l;
                p.clutch_thickness = CLUTCH_THICKNESS_MIN;
            }),
            Err(Error::BeamLengthOutOfRange),
            "l = {l}"
        );
    }
}

#[test]
fn clutch_thickness_out_of_range() {
    let l = DesignParams::PAPER.beam_length;
    for tc in [
        Length::ZERO,
        Length::from_int(-1),
        down(CLUTCH_THICKNESS_MIN),
        l,
        up(l),
        Length::MAX,
    ] {
        assert_eq!(
            with(|p| p.clutch_thickness = tc),
            Err(Error::ClutchThicknessOutOfRange),
            "t_c = {tc}"
        );
    }
    assert!(with(|p| p.clutch_thickness = down(l)).is_ok());
    assert!(with(|p| p.clutch_thickness = CLUTCH_THICKNESS_MIN).is_ok());
}

#[test]
fn friction_out_of_range() {
    let above = Ratio::from_bits(FRICTION_MAX.to_bits() + 1);
    for mu in [Ratio::from_bits(-1), Ratio::from_int(-1), above, Ratio::MAX] {
        assert_eq!(
            with(|p| p.friction = mu),
            Err(Error::FrictionOutOfRange),
            "μ = {mu}"
        );
    }
    for mu in [Ratio::ZERO, FRICTION_MAX] {
        assert!(with(|p| p.friction = mu).is_ok());
    }
}

// ---------------------------------------------------------------------------------------
// Arguments outside their domain.

fn bad_lengths(d: &Design) -> [Length; 6] {
    let l = d.params().beam_length;
    [
        Length::ZERO,
        Length::from_bits(-1),
        Length::from_int(-5),
        Length::MIN,
        up(l),
        Length::MAX,
    ]
}

#[test]
fn clutch_length_outside_zero_to_l() {
    let d = Design::paper();
    let tau = Torque::from_int(1);
    for len in bad_lengths(&d) {
        let e = Some(Error::ClutchLengthOutOfRange);
        assert_eq!(d.stiffness(len).err(), e, "L = {len}");
        assert_eq!(d.stiffness_timoshenko(len).err(), e, "L = {len}");
        assert_eq!(d.deflection(tau, len).err(), e, "L = {len}");
        assert_eq!(d.root_stress(tau, len).err(), e, "L = {len}");
        assert_eq!(d.torque_capacity(len).err(), e, "L = {len}");
        assert_eq!(d.deflection_capacity(len).err(), e, "L = {len}");
        assert_eq!(d.deflection_capacity_timoshenko(len).err(), e, "L = {len}");
        for m in MODELS {
            assert_eq!(m.stiffness(&d, len).err(), e, "L = {len}");
            assert_eq!(Setting::new(&d, len, m).err(), e, "L = {len}");
        }
    }
}

#[test]
fn clutch_position_outside_tc_to_l() {
    let d = Design::paper();
    let (tc, l) = d.adjustable_range();
    for x in [
        down(tc),
        up(l),
        Length::ZERO,
        Length::from_int(-3),
        Length::MIN,
        Length::MAX,
    ] {
        let o = oracle::Design::paper();
        assert!(
            o.backlash_tilt(mm(x) * MM).is_err(),
            "oracle accepts x = {x}"
        );
        assert_eq!(
            d.tilt_backlash(x),
            Err(Error::BacklashPositionOutOfRange),
            "x = {x}"
        );
    }
    // Below t_c a setting exists, without the beam-tilt backlash.
    let s = Setting::new(&d, down(tc), BeamModel::EulerBernoulli).unwrap();
    assert_eq!(s.tilt_backlash(), None);
    assert!(d.tilt_backlash(tc).is_ok() && d.tilt_backlash(l).is_ok());
}

#[test]
fn inverse_of_non_positive_stiffness() {
    let d = Design::paper();
    for k in [
        Stiffness::ZERO,
        Stiffness::from_bits(-1),
        Stiffness::from_int(-100),
        Stiffness::from_bits(i128::MIN),
    ] {
        let e = Some(Error::StiffnessNotPositive);
        assert_eq!(d.clutch_length(k).err(), e, "k = {k}");
        assert_eq!(d.clutch_length_timoshenko(k).err(), e, "k = {k}");
        for m in MODELS {
            assert_eq!(m.clutch_length(&d, k).err(), e, "k = {k}");
        }
        assert_eq!(
            natural_frequency(k, Inertia::from_int(1000)).err(),
            e,
            "k = {k}"
        );
    }
}

#[test]
fn inverse_of_too_soft_and_too_stiff() {
    let (d, o) = (Design::paper(), oracle::Design::paper());
    let l_mm = o.l / MM;
    // Softer than k(l): L(k) beyond l (oracle), far more than the model's 1 ppm clamp.
    for k in [
        Stiffness::DELTA,
        Stiffness::from_int(1),
        Stiffness::from_int(13),
    ] {
        let want = o.length_for_stiffness(nm_rad(k)).unwrap() / MM;
        assert!(want > l_mm * 1.001, "k = {k}: oracle L = {want} mm");
        assert_eq!(d.clutch_length(k), Err(Error::StiffnessTooLow), "k = {k}");
        let want = o.length_for_stiffness_timoshenko(nm_rad(k)).unwrap() / MM;
        assert!(want > l_mm * 1.001, "k = {k}: oracle L_T = {want} mm");
        assert_eq!(
            d.clutch_length_timoshenko(k),
            Err(Error::StiffnessTooLow),
            "k = {k}"
        );
    }
    // Timoshenko: the stiffest representable k needs L below half an LSB (oracle).
    let want = o
        .length_for_stiffness_timoshenko(nm_rad(Stiffness::MAX))
        .unwrap()
        / MM;
    assert!(want < 0.5 * LSB32, "oracle L_T(k_max) = {want} mm");
    assert_eq!(
        d.clutch_length_timoshenko(Stiffness::MAX),
        Err(Error::StiffnessTooHigh)
    );
    // E–B: the same k still has a representable length (not an error).
    let want = o.length_for_stiffness(nm_rad(Stiffness::MAX)).unwrap() / MM;
    assert!(want > 2.0 * LSB32, "oracle L(k_max) = {want} mm");
    let got = mm(d.clutch_length(Stiffness::MAX).unwrap());
    assert!((got - want).abs() <= (1e-4 * want).max(2.0 * LSB32));
}

#[test]
fn dynamics_non_positive_arguments() {
    let (k, j, w) = (
        Stiffness::from_int(100),
        Inertia::from_int(1000),
        Frequency::from_int(50),
    );
    let d = Design::paper();
    for bad in [Inertia::ZERO, Inertia::from_bits(-1), Inertia::MIN] {
        assert_eq!(natural_frequency(k, bad), Err(Error::InertiaNotPositive));
        assert_eq!(
            stiffness_for_frequency(bad, w),
            Err(Error::InertiaNotPositive)
        );
        for m in MODELS {
            assert_eq!(d.tune(bad, w, m), Err(Error::InertiaNotPositive));
        }
    }
    for bad in [Frequency::ZERO, Frequency::from_bits(-1), Frequency::MIN] {
        assert_eq!(
            stiffness_for_frequency(j, bad),
            Err(Error::FrequencyNotPositive)
        );
        for m in MODELS {
            assert_eq!(d.tune(j, bad, m), Err(Error::FrequencyNotPositive));
        }
    }
    // Both bad: the first argument is reported.
    assert_eq!(
        natural_frequency(Stiffness::ZERO, Inertia::ZERO),
        Err(Error::StiffnessNotPositive)
    );
    assert_eq!(
        stiffness_for_frequency(Inertia::ZERO, Frequency::ZERO),
        Err(Error::InertiaNotPositive)
    );
}

// ---------------------------------------------------------------------------------------
// Overflowing combinations: the oracle's value is beyond the format, the model says so.

#[test]
fn stiffness_beyond_i64f64() {
    let (d, o) = (Design::paper(), oracle::Design::paper());
    // L = 1 LSB (2.3e-10 mm): k ≈ 7e31 N·m/rad.
    let len = Length::DELTA;
    let l_m = mm(len) * MM;
    assert!(o.stiffness(l_m) > MAX64);
    assert_eq!(d.stiffness(len), Err(Error::Overflow));
    // τ_cap ≈ 2e10 N·m > 2³¹ too, so the setting overflows for both models (k_T ∝ 1/L at
    // short L fits I64F64 here, ≈ 6e13 N·m/rad).
    assert!(o.stiffness_timoshenko(l_m) < MAX64);
    for m in MODELS {
        assert_eq!(Setting::new(&d, len, m), Err(Error::Overflow), "{m:?}");
    }
    assert!(o.torque_capacity(l_m) > MAX32);
    assert_eq!(d.torque_capacity(len), Err(Error::Overflow));
    // The stiffest design of the domain at t_c_min still fits (oracle: k ≈ 2.4e17).
    let p = DesignParams {
        beams: BEAMS_MAX,
        beam_radius: BEAM_RADIUS_MAX,
        pitch_radius: PITCH_RADIUS_MAX,
        youngs_modulus: MODULUS_MAX,
        shear_modulus: MODULUS_MAX,
        clutch_thickness: CLUTCH_THICKNESS_MIN,
        ..DesignParams::PAPER
    };
    let (d, o) = (Design::new(p).unwrap(), oracle_design(&p));
    let want = o.stiffness(o.t_c);
    assert!(want < MAX64);
    let got = nm_rad(d.stiffness(CLUTCH_THICKNESS_MIN).unwrap());
    assert!(((got - want) / want).abs() < 1e-4);
    // … and a quarter of t_c does not (k ∝ 1/L³: ≈ 1.5e19).
    let quarter = Length::from_bits(CLUTCH_THICKNESS_MIN.to_bits() / 4);
    assert!(o.stiffness(mm(quarter) * MM) > MAX64);
    assert_eq!(d.stiffness(quarter), Err(Error::Overflow));
}

#[test]
fn huge_torque_at_long_length() {
    let (d, o) = (Design::paper(), oracle::Design::paper());
    let l = d.params().beam_length;
    let l_m = o.l;
    for tau in [Torque::MAX, Torque::MIN, Torque::from_int(10_000_000)] {
        let t = nm(tau);
        assert!((o.root_stress(t, l_m) / MPA).abs() > MAX32, "τ = {tau}");
        assert_eq!(d.root_stress(tau, l), Err(Error::Overflow), "τ = {tau}");
        let s = Setting::new(&d, l, BeamModel::EulerBernoulli).unwrap();
        assert_eq!(s.root_stress(tau), Err(Error::Overflow), "τ = {tau}");
    }
    // P = τ/(n·R) beyond 2³¹ N.
    assert!(o.beam_force(nm(Torque::MAX)) > MAX32);
    assert_eq!(d.beam_force(Torque::MAX), Err(Error::Overflow));
    // θ = τ/k beyond 2³¹ rad on a thin, soft beam.
    let p = DesignParams {
        beam_radius: BEAM_RADIUS_MIN,
        ..DesignParams::PAPER
    };
    let (thin, o_thin) = (Design::new(p).unwrap(), oracle_design(&p));
    assert!(o_thin.deflection(nm(Torque::MAX), l_m) > MAX32);
    assert_eq!(thin.deflection(Torque::MAX, l), Err(Error::Overflow));
    for m in MODELS {
        let s = Setting::new(&thin, l, m).unwrap();
        assert_eq!(s.deflection(Torque::MAX), Err(Error::Overflow), "{m:?}");
    }
}

#[test]
fn torque_from_huge_deflection() {
    let (d, o) = (Design::paper(), oracle::Design::paper());
    let one = Length::from_int(1);
    let l_m = MM;
    let big = rad(Angle::MAX);
    assert!(o.stiffness(l_m) * big > MAX32);
    assert!(o.coupling_torque(big, l_m) > MAX32);
    assert!(o.torque_loading(big, l_m) > MAX32);
    for m in MODELS {
        let s = Setting::new(&d, one, m).unwrap();
        assert_eq!(s.elastic_torque(Angle::MAX), Err(Error::Overflow), "{m:?}");
        assert_eq!(s.elastic_torque(Angle::MIN), Err(Error::Overflow), "{m:?}");
        assert_eq!(s.coupling_torque(Angle::MAX), Err(Error::Overflow), "{m:?}");
        assert_eq!(
            s.branch_torque(Angle::MAX, Branch::Loading),
            Err(Error::Overflow)
        );
        assert_eq!(
            s.hysteretic_coupling_torque(Angle::MIN, Branch::Loading),
            Err(Error::Overflow)
        );
        // The state machine records the deflection even when the torque overflows.
        let mut h = Hysteresis::new();
        assert_eq!(h.step(&s, Angle::MAX), Err(Error::Overflow));
        assert_eq!((h.last(), h.branch()), (Angle::MAX, Branch::Loading));
    }
}

#[test]
fn frequency_and_stiffness_beyond_their_formats() {
    // ω = √(k/J) with k = 9.2e18 N·m/rad and J = 2.3e-16 kg·m².
    let (k, j) = (Stiffness::MAX, Inertia::DELTA);
    assert!(oracle::natural_frequency(nm_rad(k), host_tests::convert::kg_mm2(j) * 1e-6) > MAX32);
    assert_eq!(natural_frequency(k, j), Err(Error::Overflow));
    // k = J·ω² with J = 2.1e3 kg·m², ω = 2.1e9 rad/s.
    let (j, w) = (Inertia::MAX, Frequency::MAX);
    let want = oracle::stiffness_for_frequency(
        host_tests::convert::kg_mm2(j) * 1e-6,
        host_tests::convert::rad_s(w),
    );
    assert!(want > MAX64);
    assert_eq!(stiffness_for_frequency(j, w), Err(Error::Overflow));
    let d = Design::paper();
    for m in MODELS {
        assert_eq!(d.tune(j, w, m), Err(Error::Overflow));
    }
}

#[test]
fn unit_constructors_beyond_their_formats() {
    // 1e-6·i64::MAX mm = 9.2e12 mm > 2³¹ mm.
    assert!(i64::MAX as f64 * 1e-6 > MAX32);
    assert_eq!(Length::from_micro(i64::MAX), Err(Error::Overflow));
    assert_eq!(Length::from_micro(i64::MIN), Err(Error::Overflow));
    // 2147484 GPa = 2.147484e9 MPa > 2³¹ MPa; 2147483 GPa fits.
    const { assert!(2_147_484_000.0 > MAX32 && 2_147_483_000.0 < MAX32) };
    assert_eq!(Stress::from_gpa(2_147_484), Err(Error::Overflow));
    assert!(Stress::from_gpa(2_147_483).is_ok());
    assert_eq!(Stress::from_gpa(i32::MIN), Err(Error::Overflow));
    // 2π·3.5e8 Hz > 2³¹ rad/s.
    let hz = Length::from_bits(bits32(3.5e8).unwrap()).get();
    const { assert!(3.5e8 * std::f64::consts::TAU > MAX32) };
    assert_eq!(Frequency::from_hz(hz), Err(Error::Overflow));
}
