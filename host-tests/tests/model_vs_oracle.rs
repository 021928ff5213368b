//! Property tests: every public function of the fixed-point `model` against the f64
//! `oracle` (host-tests/src/oracle.rs), over the model's whole documented domain (the
//! bounds exported by `model::design`: n ∈ 1..=16, r ∈ [0.05, 5] mm, R ∈ [max(1 mm, r⁺),
//! 100 mm], E, G ∈ [1, 1000] GPa with G ≥ E/3, σ_allow ∈ [1, 10⁴] MPa, l ∈ [0.1, 100] mm,
//! t_c ∈ [0.01 mm, l), μ ∈ [0, 2]; L ∈ (0, l]; x anywhere; torques, angles, stiffnesses,
//! inertias and frequencies over their whole formats).
//!
//! Rule (see `host_tests::convert`): a model value matches when
//! `|got − want| ≤ max(1e-4·|want|, 2·LSB)` with the LSB of the output format. When the
//! model returns an error it must be the error the oracle predicts for that input (e.g. the
//! oracle's value is beyond the format → `Error::Overflow`); an error where the oracle's
//! value fits (outside a 1e-9 relative band around the format's bound) fails the test.
//! Errors are counted and printed, not skipped silently.
//!
//! Cases: 10 000 per property. `PROPTEST_CASES=N` overrides that for a longer run (proptest's
//! `Config::default()` reads the variable; [`config`] only replaces the default count when
//! it is unset). `PROPTEST_RNG_SEED=S` fixes the seed. Each property prints a one-line
//! report per function (max relative error, max |Δ|/tolerance, error counts): run with
//! `cargo test -p host-tests --test model_vs_oracle -- --nocapture`.
//!
//! Each property opens with the same few lines (build the design and the oracle, draw L)
//! on purpose: every test reads on its own, next to the oracle function it checks.

use std::cell::RefCell;
use std::collections::BTreeMap;
use std::fmt::Debug;

use host_tests::convert::{
    bits32, bits64, kg_mm2, mm, mpa, newton, nm, nm_rad, oracle_design, rad, rad_s, ratio, rel_err,
    tolerance, KG_MM2, LSB32, LSB64, MAX32, MAX64, MM, MPA,
};
use host_tests::oracle;
use model::design::{
    ALLOWABLE_STRESS_MAX, ALLOWABLE_STRESS_MIN, BEAM_LENGTH_MAX, BEAM_LENGTH_MIN, BEAM_RADIUS_MAX,
    BEAM_RADIUS_MIN, CLUTCH_THICKNESS_MIN, FRICTION_MAX, MODULUS_MAX, MODULUS_MIN,
    PITCH_RADIUS_MAX, PITCH_RADIUS_MIN,
};
use model::dynamics::{natural_frequency, stiffness_for_frequency, Tuning};
use model::fixmath::{icbrt, icbrt_round, isqrt, isqrt_round};
use model::{
    Angle, BeamModel, Branch, Design, DesignParams, Error, Frequency, Hysteresis, Inertia, Length,
    Ratio, Setting, Stiffness, Stress, Torque,
};
use proptest::prelude::*;
use proptest::test_runner::{Config, TestCaseError, TestCaseResult, TestRunner};

/// Cases per property unless `PROPTEST_CASES` is set.
const CASES: u32 = 10_000;

/// Relative band around a format bound (or a domain edge) inside which either outcome is
/// accepted: the model is accurate to ~1e-12, the oracle to ~1e-15.
const EDGE: f64 = 1e-9;

/// Slack for the oracle's own rounding where the model subtracts (free play): 16 ulp.
const ORACLE_EPS: f64 = 16.0 * f64::EPSILON;

fn config() -> Config {
    // Config::default() applies PROPTEST_CASES & co. from the environment.
    let base = Config::default();
    let cases = if std::env::var_os("PROPTEST_CASES").is_some() {
        base.cases
    } else {
        CASES
    };
    Config {
        cases,
        failure_persistence: None,
        ..base
    }
}

// ---------------------------------------------------------------------------------------
// Expected outcomes and the report.

/// What the oracle predicts for one model call.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Expect {
    /// A value (compared with the tolerance rule).
    Value,
    /// This error and no value.
    Fail(Error),
    /// At an edge: a value or this error.
    Either(Error),
}

/// A value `want` in a format whose magnitude bound is `max`.
fn fit(want: f64, max: f64) -> Expect {
    let m = want.abs();
    if m.is_nan() {
        Expect::Fail(Error::Overflow)
    } else if m < max * (1.0 - EDGE) {
        Expect::Value
    } else if m > max * (1.0 + EDGE) {
        Expect::Fail(Error::Overflow)
    } else {
        Expect::Either(Error::Overflow)
    }
}

/// The stricter of two expectations for a call that fails if either part fails.
fn both(a: Expect, b: Expect) -> Expect {
    match (a, b) {
        (Expect::Fail(e), _) | (_, Expect::Fail(e)) => Expect::Fail(e),
        (Expect::Either(e), _) | (_, Expect::Either(e)) => Expect::Either(e),
        _ => Expect::Value,
    }
}

#[derive(Default)]
struct Stat {
    compared: u64,
    /// Max relative error well above the resolution (|want| ≥ 1e6 LSB).
    max_rel: f64,
    /// Max relative error beyond the final ½-LSB rounding, over all |want| > 0.
    max_rel_net: f64,
    /// Max |Δ| in LSB of the output format.
    max_lsb: f64,
    /// Max |Δ|/tolerance over all comparisons (≤ 1 passes).
    max_ratio: f64,
    errors: BTreeMap<String, u64>,
}

struct Report {
    test: &'static str,
    stats: RefCell<BTreeMap<&'static str, Stat>>,
}

type Ctx<'a> = &'a dyn Fn() -> String;

impl Report {
    fn new(test: &'static str) -> Self {
        Report {
            test,
            stats: RefCell::new(BTreeMap::new()),
        }
    }

    /// Counts an outcome that is not a comparison (an expected error, a skipped input).
    fn count(&self, f: &'static str, what: String) {
        *self
            .stats
            .borrow_mut()
            .entry(f)
            .or_default()
            .errors
            .entry(what)
            .or_default() += 1;
    }

    /// Compares `got` with `want`: `|Δ| ≤ max(1e-4·|want|, 2·lsb) + slack`.
    fn value(
        &self,
        f: &'static str,
        got: f64,
        want: f64,
        lsb: f64,
        slack: f64,
        ctx: Ctx,
    ) -> TestCaseResult {
        let tol = tolerance(want, lsb) + slack;
        let err = (got - want).abs();
        {
            let mut stats = self.stats.borrow_mut();
            let s = stats.entry(f).or_default();
            s.compared += 1;
            s.max_ratio = s.max_ratio.max(err / tol);
            s.max_lsb = s.max_lsb.max(err / lsb);
            if want.abs() >= 1e6 * lsb {
                s.max_rel = s.max_rel.max(rel_err(got, want));
            }
            if want != 0.0 {
                s.max_rel_net = s.max_rel_net.max((err - 0.5 * lsb).max(0.0) / want.abs());
            }
        }
        if err <= tol {
            Ok(())
        } else {
            Err(TestCaseError::fail(format!(
                "{f}: model {got:e} vs oracle {want:e}: |Δ| = {err:e} > tol {tol:e}; {}",
                ctx()
            )))
        }
    }

    /// Checks a fallible model result against the oracle's expectation and value.
    #[allow(clippy::too_many_arguments)]
    fn result<T: Debug>(
        &self,
        f: &'static str,
        got: model::Result<T>,
        expect: Expect,
        want: f64,
        lsb: f64,
        slack: f64,
        conv: impl Fn(&T) -> f64,
        ctx: Ctx,
    ) -> TestCaseResult {
        match (got, expect) {
            (Ok(v), Expect::Fail(e)) => Err(TestCaseError::fail(format!(
                "{f}: oracle predicts Err({e:?}) (value {want:e}), model returned Ok({v:?}); {}",
                ctx()
            ))),
            (Ok(v), _) => self.value(f, conv(&v), want, lsb, slack, ctx),
            (Err(e), Expect::Fail(x) | Expect::Either(x)) if e == x => {
                self.count(f, format!("{e:?}"));
                Ok(())
            }
            (Err(e), _) => Err(TestCaseError::fail(format!(
                "{f}: model returned Err({e:?}), oracle predicts {expect:?} (value {want:e}); {}",
                ctx()
            ))),
        }
    }

    fn print(&self, cases: u32) {
        println!(
            "[{}] {cases} cases (max: rel = relative error where |want| ≥ 1e6 LSB; rel-net = \
             relative error beyond the final ½-LSB rounding; LSB = |Δ| in output LSB)",
            self.test
        );
        for (f, s) in self.stats.borrow().iter() {
            let errors: Vec<String> = s.errors.iter().map(|(e, n)| format!("{e}×{n}")).collect();
            println!(
                "    {f:<40} compared {:>6}  rel {:.1e}  rel-net {:.1e}  {:>8.3} LSB  |Δ|/tol {:.3}  {}",
                s.compared,
                s.max_rel,
                s.max_rel_net,
                s.max_lsb,
                s.max_ratio,
                errors.join(" ")
            );
        }
    }
}

/// Runs `test` over `strategy` with [`config`], then prints the report.
fn run<S: Strategy>(
    name: &'static str,
    strategy: S,
    test: impl Fn(&Report, S::Value) -> TestCaseResult,
) where
    S::Value: Debug,
{
    let report = Report::new(name);
    let mut runner = TestRunner::new(config());
    let cases = runner.config().cases;
    let result = runner.run(&strategy, |v| test(&report, v));
    report.print(cases);
    if let Err(e) = result {
        panic!("{name}: {e}");
    }
}

// ---------------------------------------------------------------------------------------
// Strategies: uniforms in [0, 1] (with both ends often) mapped onto the model's domain.

fn unit() -> impl Strategy<Value = f64> + Clone {
    prop_oneof![1 => Just(0.0), 1 => Just(1.0), 8 => 0.0..=1.0f64]
}

/// Log-uniform bits in [lo, hi] (lo > 0); `u` = 0 / 1 give the ends exactly.
fn log_bits(lo: i64, hi: i64, u: f64) -> i64 {
    assert!(0 < lo && lo <= hi, "{lo} {hi}");
    if u <= 0.0 {
        return lo;
    }
    if u >= 1.0 {
        return hi;
    }
    let (a, b) = ((lo as f64).ln(), (hi as f64).ln());
    ((a + u * (b - a)).exp().round() as i64).clamp(lo, hi)
}

/// Log-uniform bits in [lo, hi] for 128-bit values (lo > 0).
fn log_bits128(lo: i128, hi: i128, u: f64) -> i128 {
    assert!(0 < lo && lo <= hi, "{lo} {hi}");
    if u <= 0.0 {
        return lo;
    }
    if u >= 1.0 {
        return hi;
    }
    let (a, b) = ((lo as f64).ln(), (hi as f64).ln());
    ((a + u * (b - a)).exp().round() as i128).clamp(lo, hi)
}

/// Uniform bits in [lo, hi].
fn lin_bits(lo: i64, hi: i64, u: f64) -> i64 {
    if u <= 0.0 {
        return lo;
    }
    if u >= 1.0 {
        return hi;
    }
    ((lo as f64 + u * (hi as f64 - lo as f64)).round() as i64).clamp(lo, hi)
}

/// A design anywhere in the documented domain from 8 uniforms (log-uniform in each range).
fn params_from(n: u8, u: [f64; 8]) -> DesignParams {
    let r = log_bits(BEAM_RADIUS_MIN.to_bits(), BEAM_RADIUS_MAX.to_bits(), u[0]);
    let big_r = log_bits(
        PITCH_RADIUS_MIN.to_bits().max(r + 1),
        PITCH_RADIUS_MAX.to_bits(),
        u[1],
    );
    let e = log_bits(MODULUS_MIN.to_bits(), MODULUS_MAX.to_bits(), u[2]);
    // G ≥ E/3 ⟺ 3G ≥ E (bits).
    let g = log_bits(
        MODULUS_MIN.to_bits().max((e + 2) / 3),
        MODULUS_MAX.to_bits(),
        u[3],
    );
    let sigma = log_bits(
        ALLOWABLE_STRESS_MIN.to_bits(),
        ALLOWABLE_STRESS_MAX.to_bits(),
        u[4],
    );
    let l = log_bits(BEAM_LENGTH_MIN.to_bits(), BEAM_LENGTH_MAX.to_bits(), u[5]);
    let tc = log_bits(CLUTCH_THICKNESS_MIN.to_bits(), l - 1, u[6]);
    let mu = lin_bits(0, FRICTION_MAX.to_bits(), u[7]);
    DesignParams {
        beams: n,
        beam_radius: Length::from_bits(r),
        pitch_radius: Length::from_bits(big_r),
        youngs_modulus: Stress::from_bits(e),
        shear_modulus: Stress::from_bits(g),
        allowable_stress: Stress::from_bits(sigma),
        beam_length: Length::from_bits(l),
        clutch_thickness: Length::from_bits(tc),
        friction: Ratio::from_bits(mu),
    }
}

fn design_params() -> impl Strategy<Value = DesignParams> {
    prop_oneof![
        1 => Just(DesignParams::PAPER),
        9 => (1u8..=16, proptest::array::uniform8(unit())).prop_map(|(n, u)| params_from(n, u)),
    ]
}

/// Selector of a clutch length in (0, l]: (mode, uniform).
type LenSel = (u8, f64);

fn len_sel() -> impl Strategy<Value = LenSel> {
    (0u8..5, unit())
}

/// In-range selector only ([t_c, l]).
fn len_sel_adjustable() -> impl Strategy<Value = LenSel> {
    (1u8..3, unit())
}

fn clutch_len(p: &DesignParams, (mode, u): LenSel) -> Length {
    let (tc, l) = (p.clutch_thickness.to_bits(), p.beam_length.to_bits());
    Length::from_bits(match mode {
        0 => log_bits(1, l, u),                // all of (0, l], log
        1 => lin_bits(tc, l, u),               // adjustable range, uniform
        2 => log_bits(tc, l, u),               // adjustable range, log
        3 => log_bits((l >> 12).max(1), l, u), // (l/4096, l]
        _ => lin_bits(1, l, u),                // all of (0, l], uniform
    })
}

/// Signed I32F32 bits: special values, the whole format (log magnitude), or a moderate
/// range [lo, hi] of the unit (log magnitude).
fn any32(lo: f64, hi: f64) -> impl Strategy<Value = i64> {
    let (lo, hi) = (bits32(lo).unwrap(), bits32(hi).unwrap());
    prop_oneof![
        1 => Just(0i64),
        1 => Just(i64::MAX),
        1 => Just(i64::MIN),
        1 => Just(1i64),
        1 => Just(-1i64),
        8 => (any::<bool>(), unit()).prop_map(|(neg, u)| {
            let m = log_bits(1, i64::MAX, u);
            if neg { -m } else { m }
        }),
        8 => (any::<bool>(), unit()).prop_map(move |(neg, u)| {
            let m = log_bits(lo, hi, u);
            if neg { -m } else { m }
        }),
    ]
}

/// Positive I32F32 bits: the whole positive format or a moderate range.
fn pos32(lo: f64, hi: f64) -> impl Strategy<Value = i64> {
    let (lo, hi) = (bits32(lo).unwrap(), bits32(hi).unwrap());
    prop_oneof![
        1 => Just(1i64),
        1 => Just(i64::MAX),
        8 => unit().prop_map(|u| log_bits(1, i64::MAX, u)),
        8 => unit().prop_map(move |u| log_bits(lo, hi, u)),
    ]
}

/// Positive I64F64 stiffness bits: the whole positive format or 1e-3…1e6 N·m/rad.
fn pos_k() -> impl Strategy<Value = i128> {
    let (lo, hi) = (bits64(1e-3).unwrap(), bits64(1e6).unwrap());
    prop_oneof![
        1 => Just(1i128),
        1 => Just(i128::MAX),
        8 => unit().prop_map(|u| log_bits128(1, i128::MAX, u)),
        8 => unit().prop_map(move |u| log_bits128(lo, hi, u)),
    ]
}

fn build(p: &DesignParams) -> Result<(Design, oracle::Design), TestCaseError> {
    match Design::new(*p) {
        Ok(d) => Ok((d, oracle_design(p))),
        Err(e) => Err(TestCaseError::fail(format!(
            "Design::new rejected a design inside the documented domain: {e:?}; {p:?}"
        ))),
    }
}

fn model_of(timoshenko: bool) -> BeamModel {
    if timoshenko {
        BeamModel::Timoshenko
    } else {
        BeamModel::EulerBernoulli
    }
}

/// The oracle's stiffness for `model` at L (m).
fn o_stiffness(o: &oracle::Design, model: BeamModel, l_m: f64) -> f64 {
    match model {
        BeamModel::EulerBernoulli => o.stiffness(l_m),
        BeamModel::Timoshenko => o.stiffness_timoshenko(l_m),
    }
}

/// The oracle's inverse for `model` (k > 0), in mm.
fn o_length_mm(o: &oracle::Design, model: BeamModel, k: f64) -> f64 {
    let l = match model {
        BeamModel::EulerBernoulli => o.length_for_stiffness(k),
        BeamModel::Timoshenko => o.length_for_stiffness_timoshenko(k),
    };
    l.expect("k > 0 is in the oracle's domain") / MM
}

/// What `clutch_length` should return for an oracle length `want` (mm) at beam length
/// `l_bits`: too long (beyond l plus the model's documented 2⁻²⁰·l clamp), rounding to 0,
/// a value, or either at the edges.
fn expect_length(want: f64, l_bits: i64) -> Expect {
    let clamp = ((l_bits >> 20).max(1)) as f64;
    let limit = (l_bits as f64 + clamp) * LSB32;
    let band = EDGE * want + LSB32;
    if want > limit + band {
        Expect::Fail(Error::StiffnessTooLow)
    } else if want > limit - band {
        Expect::Either(Error::StiffnessTooLow)
    } else if want < 0.5 * LSB32 * (1.0 - EDGE) {
        Expect::Fail(Error::StiffnessTooHigh)
    } else if want <= 0.5 * LSB32 * (1.0 + EDGE) {
        Expect::Either(Error::StiffnessTooHigh)
    } else {
        Expect::Value
    }
}

// ---------------------------------------------------------------------------------------
// Design and its constants.

#[test]
fn design_constants() {
    run("design_constants", design_params(), |rep, p| {
        let (d, o) = build(&p)?;
        let ctx = || format!("{p:?}");
        prop_assert_eq!(d.params(), &p);
        prop_assert_eq!(d.adjustable_range(), (p.clutch_thickness, p.beam_length));
        rep.value(
            "Design::poisson_ratio",
            ratio(d.poisson_ratio()),
            o.poisson(),
            LSB32,
            0.0,
            &ctx,
        )?;
        rep.value(
            "Design::shear_coefficient",
            ratio(d.shear_coefficient()),
            o.shear_coefficient(),
            LSB32,
            0.0,
            &ctx,
        )?;
        rep.value(
            "Design::max_tip_deflection",
            mm(d.max_tip_deflection()),
            o.delta_max() / MM,
            LSB32,
            0.0,
            &ctx,
        )?;
        rep.value(
            "Design::bending_capacity",
            rad(d.bending_capacity()),
            o.theta_max(),
            LSB32,
            0.0,
            &ctx,
        )?;
        rep.value(
            "Design::slot_clearance",
            mm(d.slot_clearance()),
            o.slot_clearance() / MM,
            LSB32,
            0.0,
            &ctx,
        )?;
        rep.value(
            "Design::slot_radius",
            mm(d.slot_radius()),
            o.slot_radius() / MM,
            LSB32,
            0.0,
            &ctx,
        )?;
        rep.value(
            "Design::free_play",
            rad(d.free_play()),
            o.free_play(),
            LSB32,
            0.0,
            &ctx,
        )?;
        for model in [BeamModel::EulerBernoulli, BeamModel::Timoshenko] {
            let (soft, stiff) = d.stiffness_range(model);
            rep.value(
                "Design::stiffness_range (k(l))",
                nm_rad(soft),
                o_stiffness(&o, model, o.l),
                LSB64,
                0.0,
                &ctx,
            )?;
            rep.value(
                "Design::stiffness_range (k(t_c))",
                nm_rad(stiff),
                o_stiffness(&o, model, o.t_c),
                LSB64,
                0.0,
                &ctx,
            )?;
        }
        Ok(())
    });
}

// ---------------------------------------------------------------------------------------
// Beam: stiffness, inverse, deflection, force, stress, capacity.

#[test]
fn stiffness_both_models() {
    run(
        "stiffness_both_models",
        (design_params(), len_sel()),
        |rep, (p, ls)| {
            let (d, o) = build(&p)?;
            let len = clutch_len(&p, ls);
            let l_m = mm(len) * MM;
            let ctx = || format!("L = {len}; {p:?}");
            let want = o.stiffness(l_m);
            rep.result(
                "Design::stiffness",
                d.stiffness(len),
                fit(want, MAX64),
                want,
                LSB64,
                0.0,
                |k| nm_rad(*k),
                &ctx,
            )?;
            let want = o.stiffness_timoshenko(l_m);
            rep.result(
                "Design::stiffness_timoshenko",
                d.stiffness_timoshenko(len),
                fit(want, MAX64),
                want,
                LSB64,
                0.0,
                |k| nm_rad(*k),
                &ctx,
            )?;
            prop_assert_eq!(
                BeamModel::EulerBernoulli.stiffness(&d, len),
                d.stiffness(len)
            );
            prop_assert_eq!(
                BeamModel::Timoshenko.stiffness(&d, len),
                d.stiffness_timoshenko(len)
            );
            Ok(())
        },
    );
}

#[test]
fn clutch_length_both_models() {
    // k: the whole positive I64F64 range, a moderate range, or k(L) for L in (0, l].
    let k_sel = prop_oneof![
        1 => pos_k().prop_map(|b| (b, None)),
        1 => len_sel().prop_map(|ls| (0, Some(ls))),
    ];
    run(
        "clutch_length_both_models",
        (design_params(), k_sel, any::<bool>()),
        |rep, (p, (kb, ls), timo)| {
            let (d, o) = build(&p)?;
            let model = model_of(timo);
            let kb = match ls {
                Some(ls) => {
                    let k = o_stiffness(&o, model, mm(clutch_len(&p, ls)) * MM);
                    match bits64(k) {
                        Some(b) if b > 0 => b,
                        _ => {
                            rep.count("(input)", "k(L) beyond I64F64, skipped".into());
                            return Ok(());
                        }
                    }
                }
                None => kb,
            };
            let k = Stiffness::from_bits(kb);
            let want = o_length_mm(&o, model, nm_rad(k));
            let ctx = || format!("{model:?}, k = {k}; {p:?}");
            let (f, got) = match model {
                BeamModel::EulerBernoulli => ("Design::clutch_length", d.clutch_length(k)),
                BeamModel::Timoshenko => (
                    "Design::clutch_length_timoshenko",
                    d.clutch_length_timoshenko(k),
                ),
            };
            prop_assert_eq!(model.clutch_length(&d, k), got);
            let expect = expect_length(want, p.beam_length.to_bits());
            rep.result(f, got, expect, want, LSB32, 0.0, |l| mm(*l), &ctx)
        },
    );
}

#[test]
fn round_trips() {
    run(
        "round_trips",
        (design_params(), len_sel(), any::<bool>(), unit()),
        |rep, (p, ls, timo, u)| {
            let (d, _) = build(&p)?;
            let model = model_of(timo);
            let len = clutch_len(&p, ls);
            let ctx = || format!("{model:?}, L = {len}; {p:?}");
            // L → k → L, anywhere in (0, l].
            let name = match model {
                BeamModel::EulerBernoulli => "L→k→L (E–B)",
                BeamModel::Timoshenko => "L→k→L (Timoshenko)",
            };
            match model.stiffness(&d, len) {
                Ok(k) => match model.clutch_length(&d, k) {
                    Ok(back) => rep.value(name, mm(back), mm(len), LSB32, 0.0, &ctx)?,
                    Err(e) => {
                        return Err(TestCaseError::fail(format!(
                            "{name}: k = {k} back to Err({e:?}); {}",
                            ctx()
                        )))
                    }
                },
                // Checked against the oracle in `stiffness_both_models`.
                Err(e) => rep.count(name, format!("k(L) {e:?}, skipped")),
            }
            // k → L → k over the adjustable stiffness range [k(l), k(t_c)].
            let (soft, stiff) = d.stiffness_range(model);
            let k = Stiffness::from_bits(log_bits128(soft.to_bits(), stiff.to_bits(), u));
            let name = match model {
                BeamModel::EulerBernoulli => "k→L→k (E–B, adjustable)",
                BeamModel::Timoshenko => "k→L→k (Timoshenko, adjustable)",
            };
            let ctx = || format!("{model:?}, k = {k}; {p:?}");
            let back = model
                .clutch_length(&d, k)
                .and_then(|l| model.stiffness(&d, l));
            match back {
                Ok(kk) => rep.value(name, nm_rad(kk), nm_rad(k), LSB64, 0.0, &ctx),
                Err(e) => Err(TestCaseError::fail(format!(
                    "{name}: Err({e:?}) inside the adjustable range; {}",
                    ctx()
                ))),
            }
        },
    );
}

#[test]
fn deflection_force_stress() {
    run(
        "deflection_force_stress",
        (design_params(), len_sel(), any32(1e-3, 10.0)),
        |rep, (p, ls, tb)| {
            let (d, o) = build(&p)?;
            let len = clutch_len(&p, ls);
            let l_m = mm(len) * MM;
            let tau = Torque::from_bits(tb);
            let t = nm(tau);
            let ctx = || format!("τ = {tau}, L = {len}; {p:?}");
            let want = o.deflection(t, l_m);
            rep.result(
                "Design::deflection",
                d.deflection(tau, len),
                fit(want, MAX32),
                want,
                LSB32,
                0.0,
                |a| rad(*a),
                &ctx,
            )?;
            let want = o.beam_force(t);
            rep.result(
                "Design::beam_force",
                d.beam_force(tau),
                fit(want, MAX32),
                want,
                LSB32,
                0.0,
                |f| newton(*f),
                &ctx,
            )?;
            let want = o.root_stress(t, l_m) / MPA;
            rep.result(
                "Design::root_stress",
                d.root_stress(tau, len),
                fit(want, MAX32),
                want,
                LSB32,
                0.0,
                |s| mpa(*s),
                &ctx,
            )
        },
    );
}

#[test]
fn capacities() {
    run(
        "capacities",
        (design_params(), len_sel()),
        |rep, (p, ls)| {
            let (d, o) = build(&p)?;
            let len = clutch_len(&p, ls);
            let l_m = mm(len) * MM;
            let ctx = || format!("L = {len}; {p:?}");
            let want = o.torque_capacity(l_m);
            rep.result(
                "Design::torque_capacity",
                d.torque_capacity(len),
                fit(want, MAX32),
                want,
                LSB32,
                0.0,
                |t| nm(*t),
                &ctx,
            )?;
            let want = o.deflection_capacity(l_m);
            rep.result(
                "Design::deflection_capacity",
                d.deflection_capacity(len),
                fit(want, MAX32),
                want,
                LSB32,
                0.0,
                |a| rad(*a),
                &ctx,
            )?;
            let want = o.torque_capacity(l_m) / o.stiffness_timoshenko(l_m);
            rep.result(
                "Design::deflection_capacity_timoshenko",
                d.deflection_capacity_timoshenko(len),
                fit(want, MAX32),
                want,
                LSB32,
                0.0,
                |a| rad(*a),
                &ctx,
            )
        },
    );
}

#[test]
fn tilt_backlash() {
    let x_sel = prop_oneof![
        4 => len_sel().prop_map(|ls| (0u8, ls, 0i64)),
        1 => (1u8..5).prop_map(|edge| (edge, (0, 0.0), 0)),
        2 => any32(1e-3, 200.0).prop_map(|b| (5u8, (0, 0.0), b)),
    ];
    run(
        "tilt_backlash",
        (design_params(), x_sel),
        |rep, (p, (mode, ls, b))| {
            let (d, o) = build(&p)?;
            let (tc, l) = (p.clutch_thickness.to_bits(), p.beam_length.to_bits());
            let x = Length::from_bits(match mode {
                0 => clutch_len(&p, ls).to_bits(),
                1 => tc - 1,
                2 => tc,
                3 => l,
                4 => l + 1,
                _ => b,
            });
            let ctx = || format!("x = {x}; {p:?}");
            // The oracle's domain check is exact here: x, t_c and l convert to f64 exactly.
            let (expect, want) = match o.backlash_tilt(mm(x) * MM) {
                Ok(v) => (Expect::Value, v),
                Err(_) => (Expect::Fail(Error::BacklashPositionOutOfRange), f64::NAN),
            };
            rep.result(
                "Design::tilt_backlash",
                d.tilt_backlash(x),
                expect,
                want,
                LSB32,
                0.0,
                |a| rad(*a),
                &ctx,
            )
        },
    );
}

// ---------------------------------------------------------------------------------------
// Setting: precomputed per-tick functions.

#[test]
fn setting_functions() {
    run(
        "setting_functions",
        (
            design_params(),
            len_sel(),
            any::<bool>(),
            (any32(1e-3, 10.0), any32(1e-6, 1.0), any32(1e-6, 1.0)),
            pos32(1.0, 1e6),
        ),
        |rep, (p, ls, timo, (tb, thb, phb), jb)| {
            let (d, o) = build(&p)?;
            let model = model_of(timo);
            let len = clutch_len(&p, ls);
            let l_m = mm(len) * MM;
            let k_o = o_stiffness(&o, model, l_m);
            let cap_o = o.torque_capacity(l_m);
            let theta_cap_o = cap_o / k_o;
            let ctx = || format!("{model:?}, L = {len}; {p:?}");
            let expect = both(
                fit(k_o, MAX64),
                both(fit(cap_o, MAX32), fit(theta_cap_o, MAX32)),
            );
            let s = match (Setting::new(&d, len, model), expect) {
                (Ok(s), Expect::Value | Expect::Either(_)) => s,
                (Err(e), Expect::Fail(x) | Expect::Either(x)) if e == x => {
                    rep.count("Setting::new", format!("{e:?}"));
                    return Ok(());
                }
                (got, _) => {
                    return Err(TestCaseError::fail(format!(
                        "Setting::new: {got:?}, oracle predicts {expect:?} (k {k_o:e}, τ_cap {cap_o:e}, θ_cap {theta_cap_o:e}); {}",
                        ctx()
                    )))
                }
            };
            // Getters: the Design's own functions, and the oracle.
            prop_assert_eq!(s.length(), len);
            prop_assert_eq!(s.model(), model);
            prop_assert_eq!(Ok(s.stiffness()), model.stiffness(&d, len));
            prop_assert_eq!(Ok(s.torque_capacity()), d.torque_capacity(len));
            let dc = match model {
                BeamModel::EulerBernoulli => d.deflection_capacity(len),
                BeamModel::Timoshenko => d.deflection_capacity_timoshenko(len),
            };
            prop_assert_eq!(Ok(s.deflection_capacity()), dc);
            prop_assert_eq!(s.free_play(), d.free_play());
            prop_assert_eq!(s.tilt_backlash(), d.tilt_backlash(len).ok());
            rep.value(
                "Setting::stiffness",
                nm_rad(s.stiffness()),
                k_o,
                LSB64,
                0.0,
                &ctx,
            )?;
            rep.value(
                "Setting::torque_capacity",
                nm(s.torque_capacity()),
                cap_o,
                LSB32,
                0.0,
                &ctx,
            )?;
            rep.value(
                "Setting::deflection_capacity",
                rad(s.deflection_capacity()),
                theta_cap_o,
                LSB32,
                0.0,
                &ctx,
            )?;
            match (s.tilt_backlash(), o.backlash_tilt(l_m)) {
                (Some(a), Ok(want)) => {
                    rep.value("Setting::tilt_backlash", rad(a), want, LSB32, 0.0, &ctx)?;
                }
                (None, Err(_)) => rep.count("Setting::tilt_backlash", "None (L < t_c)".into()),
                (got, want) => {
                    return Err(TestCaseError::fail(format!(
                        "Setting::tilt_backlash: {got:?} vs oracle {want:?}; {}",
                        ctx()
                    )))
                }
            }

            let tau = Torque::from_bits(tb);
            let t = nm(tau);
            let ctx = || format!("{model:?}, L = {len}, τ = {tau}; {p:?}");
            let want = t / k_o;
            rep.result(
                "Setting::deflection",
                s.deflection(tau),
                fit(want, MAX32),
                want,
                LSB32,
                0.0,
                |a| rad(*a),
                &ctx,
            )?;
            let want = o.beam_force(t);
            rep.result(
                "Setting::beam_force",
                s.beam_force(tau),
                fit(want, MAX32),
                want,
                LSB32,
                0.0,
                |f| newton(*f),
                &ctx,
            )?;
            let want = o.root_stress(t, l_m) / MPA;
            rep.result(
                "Setting::root_stress",
                s.root_stress(tau),
                fit(want, MAX32),
                want,
                LSB32,
                0.0,
                |x| mpa(*x),
                &ctx,
            )?;
            let margin = t.abs() - cap_o;
            if margin.abs() > EDGE * cap_o + 2.0 * LSB32 {
                prop_assert_eq!(s.within_capacity(tau), margin <= 0.0, "{}", ctx());
                rep.count(
                    "Setting::within_capacity",
                    format!("checked {}", margin <= 0.0),
                );
            } else {
                rep.count(
                    "Setting::within_capacity",
                    "at the edge, not checked".into(),
                );
            }

            let theta = Angle::from_bits(thb);
            let ctx = || format!("{model:?}, L = {len}, θ = {theta}; {p:?}");
            let want = k_o * rad(theta);
            rep.result(
                "Setting::elastic_torque",
                s.elastic_torque(theta),
                fit(want, MAX32),
                want,
                LSB32,
                0.0,
                |t| nm(*t),
                &ctx,
            )?;

            // Free-play dead zone; the oracle's coupling torque is E–B: scale to this k.
            let phi = Angle::from_bits(phb);
            let ctx = || format!("{model:?}, L = {len}, φ = {phi}; {p:?}");
            let want = o.coupling_torque(rad(phi), l_m) * (k_o / o.stiffness(l_m));
            let slack = k_o * o.free_play() * ORACLE_EPS;
            rep.result(
                "Setting::coupling_torque",
                s.coupling_torque(phi),
                fit(want, MAX32),
                want,
                LSB32,
                slack,
                |t| nm(*t),
                &ctx,
            )?;

            let j = Inertia::from_bits(jb);
            let ctx = || format!("{model:?}, L = {len}, J = {j}; {p:?}");
            let want = oracle::natural_frequency(k_o, kg_mm2(j) * KG_MM2);
            rep.result(
                "Setting::natural_frequency",
                s.natural_frequency(j),
                fit(want, MAX32),
                want,
                LSB32,
                0.0,
                |w| rad_s(*w),
                &ctx,
            )
        },
    );
}

// ---------------------------------------------------------------------------------------
// Hysteresis.

/// φ where the friction factor (6/5)·μ·R·|φ|/L reaches 1, from the oracle's branches
/// (∞ for μ = 0).
fn phi_unit_factor(o: &oracle::Design, l_m: f64) -> f64 {
    let a1 = o.torque_loading(1.0, l_m) / o.stiffness(l_m) - 1.0;
    if a1 > 0.0 {
        1.0 / a1
    } else {
        f64::INFINITY
    }
}

/// The oracle's branch torque for `model` (its branches use the E–B k: rescaled).
fn o_branch(o: &oracle::Design, model: BeamModel, phi: f64, l_m: f64, b: Branch) -> f64 {
    let scale = o_stiffness(o, model, l_m) / o.stiffness(l_m);
    match b {
        Branch::Loading => o.torque_loading(phi, l_m) * scale,
        Branch::Unloading => o.torque_unloading(phi, l_m) * scale,
    }
}

/// The oracle's deflection beyond the free play, sign(φ)·max(|φ| − φ_b, 0).
fn o_beyond(o: &oracle::Design, phi: f64) -> f64 {
    (phi.abs() - o.free_play()).max(0.0).copysign(phi)
}

/// Slack for the oracle's rounding of φ_b (only matters when |φ| − φ_b cancels):
/// |dτ/dφ| ≤ k + 2·|τ_load|/|φ|.
fn dead_zone_slack(o: &oracle::Design, model: BeamModel, phi_e: f64, l_m: f64) -> f64 {
    let k = o_stiffness(o, model, l_m);
    let slope = if phi_e == 0.0 {
        k
    } else {
        k + 2.0 * (o_branch(o, model, phi_e, l_m, Branch::Loading) / phi_e).abs()
    };
    slope * o.free_play() * ORACLE_EPS
}

#[test]
fn hysteresis_branches() {
    // φ: a fraction (1e-6 … 4) of the φ where the friction factor is 1, or any angle.
    let phi_sel = prop_oneof![
        3 => (any::<bool>(), unit()).prop_map(|(neg, u)| (true, if neg { -u } else { u }, 0i64)),
        1 => any32(1e-6, 1.0).prop_map(|b| (false, 0.0, b)),
    ];
    run(
        "hysteresis_branches",
        (
            design_params(),
            len_sel(),
            any::<bool>(),
            phi_sel,
            any::<bool>(),
        ),
        |rep, (p, ls, timo, (relative, u, b), loading)| {
            let (d, o) = build(&p)?;
            let model = model_of(timo);
            let len = clutch_len(&p, ls);
            let l_m = mm(len) * MM;
            let Ok(s) = Setting::new(&d, len, model) else {
                rep.count(
                    "(input)",
                    "Setting::new failed (see setting_functions)".into(),
                );
                return Ok(());
            };
            let star = phi_unit_factor(&o, l_m);
            let bits = if relative && star.is_finite() {
                // |u| ∈ [0, 1] → 10^(−6 + 6.6·|u|) · φ*, signed.
                let f = 10f64.powf(-6.0 + 6.6 * u.abs()) * star;
                bits32(f.copysign(u)).unwrap_or(if u < 0.0 { i64::MIN } else { i64::MAX })
            } else {
                b
            };
            let phi = Angle::from_bits(bits);
            let ph = rad(phi);
            let branch = if loading {
                Branch::Loading
            } else {
                Branch::Unloading
            };
            let ctx = || format!("{model:?} {branch:?}, L = {len}, φ = {phi}; {p:?}");

            // Without free play (paper Fig. 4).
            let mut want = o_branch(&o, model, ph, l_m, branch);
            let load = o_branch(&o, model, ph, l_m, Branch::Loading);
            if branch == Branch::Unloading && want * ph < 0.0 {
                // Beyond φ*: the oracle's factor 1 − a is negative (torque reverses); the
                // model clamps the factor at 0 (documented convention). Check the model's.
                rep.count(
                    "Setting::branch_torque",
                    "unloading beyond φ*: model clamp".into(),
                );
                want = 0.0;
            }
            rep.result(
                "Setting::branch_torque",
                s.branch_torque(phi, branch),
                fit(want, MAX32),
                want,
                LSB32,
                load.abs() * ORACLE_EPS,
                |t| nm(*t),
                &ctx,
            )?;

            // With free play: the branch formula on φ_e.
            let pe = o_beyond(&o, ph);
            let mut want = o_branch(&o, model, pe, l_m, branch);
            if branch == Branch::Unloading && want * pe < 0.0 {
                rep.count(
                    "Setting::hysteretic_coupling_torque",
                    "unloading beyond φ*: model clamp".into(),
                );
                want = 0.0;
            }
            rep.result(
                "Setting::hysteretic_coupling_torque",
                s.hysteretic_coupling_torque(phi, branch),
                fit(want, MAX32),
                want,
                LSB32,
                dead_zone_slack(&o, model, pe, l_m),
                |t| nm(*t),
                &ctx,
            )
        },
    );
}

#[derive(Clone, Copy, Debug)]
enum Step {
    /// The previous φ again.
    Repeat,
    /// φ = 0.
    Zero,
    /// Back to rest (both sides).
    Reset,
    /// φ = this fraction (in [−1, 1]) of the sequence's amplitude.
    To(f64),
}

fn steps() -> impl Strategy<Value = Vec<Step>> {
    proptest::collection::vec(
        prop_oneof![
            2 => Just(Step::Repeat),
            1 => Just(Step::Zero),
            1 => Just(Step::Reset),
            12 => (-1.0f64..=1.0).prop_map(Step::To),
        ],
        1..40,
    )
}

/// A follower at rest at φ = 0 (the model's `Hysteresis` starts there: the oracle's
/// follower has no history and answers its first call elastically, so feed it 0 first).
fn follower_at_rest(o: &oracle::Design, l_m: f64) -> oracle::HysteresisFollower {
    let mut f = oracle::HysteresisFollower::new(*o, l_m);
    f.step(0.0);
    f
}

/// The model's `Hysteresis` state machine against the oracle's `HysteresisFollower` on
/// random φ sequences: same branch wherever the oracle's torque identifies one, torques
/// within tolerance, on the domain where the two conventions coincide (amplitude below φ*,
/// where the unloading factor is ≥ 0; with free play the follower is fed φ_e).
#[test]
fn hysteresis_state_machine() {
    assert_eq!(Hysteresis::default(), Hysteresis::new());
    run(
        "hysteresis_state_machine",
        (
            design_params(),
            len_sel_adjustable(),
            any::<bool>(),
            any::<bool>(),
            unit(),
            steps(),
        ),
        |rep, (p, ls, timo, with_free_play, amp, steps)| {
            let (d, o) = build(&p)?;
            let model = model_of(timo);
            let len = clutch_len(&p, ls);
            let l_m = mm(len) * MM;
            let Ok(s) = Setting::new(&d, len, model) else {
                rep.count(
                    "(input)",
                    "Setting::new failed (see setting_functions)".into(),
                );
                return Ok(());
            };
            // Amplitude: 1e-4 … 1 of min(0.999·φ*, 1000 rad), plus φ_b with free play.
            let span = (0.999 * phi_unit_factor(&o, l_m)).min(1e3) * 10f64.powf(-4.0 * amp);
            let amplitude = span + if with_free_play { o.free_play() } else { 0.0 };
            let mut h = if with_free_play {
                Hysteresis::new()
            } else {
                Hysteresis::without_free_play()
            };
            let mut f = follower_at_rest(&o, l_m);
            let mut last = Angle::ZERO;
            let name = if with_free_play {
                "Hysteresis::step (free play)"
            } else {
                "Hysteresis::step"
            };
            for (i, step) in steps.iter().enumerate() {
                let phi = match *step {
                    Step::Reset => {
                        h.reset();
                        f = follower_at_rest(&o, l_m);
                        prop_assert_eq!((h.branch(), h.last()), (Branch::Loading, Angle::ZERO));
                        last = Angle::ZERO;
                        continue;
                    }
                    Step::Repeat => last,
                    Step::Zero => Angle::ZERO,
                    Step::To(v) => Angle::from_bits(bits32(v * amplitude).unwrap_or(0)),
                };
                last = phi;
                let ph = rad(phi);
                let ctx = || {
                    format!(
                        "{model:?}, free play {with_free_play}, L = {len}, step {i} φ = {phi}, steps {steps:?}; {p:?}"
                    )
                };
                let got = h.step(&s, phi);
                prop_assert_eq!(h.last(), phi);
                let po = if with_free_play { o_beyond(&o, ph) } else { ph };
                let scale = o_stiffness(&o, model, l_m) / o.stiffness(l_m);
                let raw = f.step(po);
                let (tl, tu) = (o.torque_loading(po, l_m), o.torque_unloading(po, l_m));
                // The oracle's branch, where its torque identifies one.
                let branch_o = if tl == tu {
                    None
                } else if raw == tl {
                    Some(Branch::Loading)
                } else if raw == tu {
                    Some(Branch::Unloading)
                } else {
                    return Err(TestCaseError::fail(format!(
                        "oracle follower returned neither branch: {raw:e} ({tl:e}, {tu:e}); {}",
                        ctx()
                    )));
                };
                match branch_o {
                    Some(b) => {
                        prop_assert_eq!(h.branch(), b, "{}", ctx());
                        rep.count("Hysteresis branch", format!("{b:?} agreed"));
                    }
                    None => rep.count(
                        "Hysteresis branch",
                        "no branch to compare (τ independent of it)".into(),
                    ),
                }
                let want = raw * scale;
                let slack = if with_free_play {
                    dead_zone_slack(&o, model, po, l_m)
                } else {
                    (tl * scale).abs() * ORACLE_EPS
                };
                rep.result(
                    name,
                    got,
                    fit(want, MAX32),
                    want,
                    LSB32,
                    slack,
                    |t| nm(*t),
                    &ctx,
                )?;
            }
            Ok(())
        },
    );
}

// ---------------------------------------------------------------------------------------
// Dynamics.

#[test]
fn natural_frequency_and_inverse() {
    run(
        "natural_frequency_and_inverse",
        (pos_k(), pos32(1.0, 1e6), pos32(1.0, 1e5)),
        |rep, (kb, jb, wb)| {
            let k = Stiffness::from_bits(kb);
            let j = Inertia::from_bits(jb);
            let w = Frequency::from_bits(wb);
            let ctx = || format!("k = {k}, J = {j}, ω = {w}");
            let j_si = kg_mm2(j) * KG_MM2;
            let want = oracle::natural_frequency(nm_rad(k), j_si);
            rep.result(
                "dynamics::natural_frequency",
                natural_frequency(k, j),
                fit(want, MAX32),
                want,
                LSB32,
                0.0,
                |w| rad_s(*w),
                &ctx,
            )?;
            let want = oracle::stiffness_for_frequency(j_si, rad_s(w));
            rep.result(
                "dynamics::stiffness_for_frequency",
                stiffness_for_frequency(j, w),
                fit(want, MAX64),
                want,
                LSB64,
                0.0,
                |k| nm_rad(*k),
                &ctx,
            )
        },
    );
}

#[test]
fn tune() {
    // ω: the natural frequency of k(L) for L in the adjustable range (±), or any ω > 0.
    let w_sel = prop_oneof![
        1 => pos32(1.0, 1e5).prop_map(|b| (b, None)),
        1 => (len_sel_adjustable(), -1.0..=1.0f64).prop_map(|(ls, v)| (0, Some((ls, v)))),
    ];
    run(
        "tune",
        (design_params(), any::<bool>(), pos32(1.0, 1e6), w_sel),
        |rep, (p, timo, jb, (wb, near))| {
            let (d, o) = build(&p)?;
            let model = model_of(timo);
            let j = Inertia::from_bits(jb);
            let j_si = kg_mm2(j) * KG_MM2;
            let wb = match near {
                // ω_n(k(L))·(1 ± 10 %): in range, or just outside it.
                Some((ls, v)) => {
                    let k = o_stiffness(&o, model, mm(clutch_len(&p, ls)) * MM);
                    let w = oracle::natural_frequency(k, j_si) * (1.0 + 0.1 * v);
                    match bits32(w) {
                        Some(b) if b > 0 => b,
                        _ => {
                            rep.count("(input)", "ω beyond I32F32 or 0, skipped".into());
                            return Ok(());
                        }
                    }
                }
                None => wb,
            };
            let w = Frequency::from_bits(wb);
            let ctx = || format!("{model:?}, J = {j}, ω = {w}; {p:?}");
            let k = oracle::stiffness_for_frequency(j_si, rad_s(w));
            let got = d.tune(j, w, model);
            let t = match (got, fit(k, MAX64)) {
                (Ok(t), Expect::Value | Expect::Either(_)) => t,
                (Err(Error::Overflow), Expect::Fail(_) | Expect::Either(_)) => {
                    rep.count("Design::tune", "Overflow".into());
                    return Ok(());
                }
                (got, e) => {
                    return Err(TestCaseError::fail(format!(
                        "Design::tune: {got:?}, oracle predicts {e:?} for k = {k:e}; {}",
                        ctx()
                    )))
                }
            };
            let (soft, stiff) = (o_stiffness(&o, model, o.l), o_stiffness(&o, model, o.t_c));
            let band = |x: f64| EDGE * x + 2.0 * LSB64;
            let variant = match t {
                Tuning::InRange { .. } => "InRange",
                Tuning::TooSoft { .. } => "TooSoft",
                Tuning::TooStiff { .. } => "TooStiff",
            };
            let want_variant = if k < soft - band(soft) {
                Some("TooSoft")
            } else if k > stiff + band(stiff) {
                Some("TooStiff")
            } else if k > soft + band(soft) && k < stiff - band(stiff) {
                Some("InRange")
            } else {
                None
            };
            if let Some(v) = want_variant {
                prop_assert_eq!(variant, v, "{}", ctx());
            }
            rep.count("Design::tune", variant.into());
            rep.value(
                "Design::tune (stiffness)",
                nm_rad(t.stiffness()),
                k,
                LSB64,
                0.0,
                &ctx,
            )?;
            let want_len = o_length_mm(&o, model, k).clamp(o.t_c / MM, o.l / MM);
            match t {
                Tuning::TooSoft { nearest, .. } => prop_assert_eq!(nearest, p.beam_length),
                Tuning::TooStiff { nearest, .. } => prop_assert_eq!(nearest, p.clutch_thickness),
                Tuning::InRange { length, .. } => prop_assert!(
                    length >= p.clutch_thickness && length <= p.beam_length,
                    "{length} outside the adjustable range; {}",
                    ctx()
                ),
            }
            rep.value(
                "Design::tune (length)",
                mm(t.length()),
                want_len,
                LSB32,
                0.0,
                &ctx,
            )
        },
    );
}

// ---------------------------------------------------------------------------------------
// Units and integer roots (no oracle counterpart: exact arithmetic is the reference).

#[test]
fn units() {
    let micro = prop_oneof![
        1 => Just(i64::MAX),
        1 => Just(i64::MIN),
        8 => (any::<bool>(), unit()).prop_map(|(neg, u)| {
            let m = log_bits(1, i64::MAX, u);
            if neg { -m } else { m }
        }),
    ];
    run(
        "units",
        (
            micro,
            prop_oneof![any::<i32>(), -2_200_000..=2_200_000i32],
            any32(1e-3, 1e6),
            any::<i64>(),
            any::<i64>(),
        ),
        |rep, (v, gpa, hb, a, b)| {
            let ctx = || format!("v = {v}, gpa = {gpa}, hz bits = {hb}, a = {a}, b = {b}");
            let want = v as f64 * 1e-6;
            rep.result(
                "Length::from_micro",
                Length::from_micro(v),
                fit(want, MAX32),
                want,
                LSB32,
                0.0,
                |l| mm(*l),
                &ctx,
            )?;
            rep.value(
                "Stiffness::from_micro",
                nm_rad(Stiffness::from_micro(v)),
                want,
                LSB64,
                0.0,
                &ctx,
            )?;
            let want = f64::from(gpa) * 1000.0;
            rep.result(
                "Stress::from_gpa",
                Stress::from_gpa(gpa),
                fit(want, MAX32),
                want,
                LSB32,
                0.0,
                |s| mpa(*s),
                &ctx,
            )?;
            // Frequency::from_hz takes an I32F32: borrow one from a Length.
            let hz = Length::from_bits(hb).get();
            let want = hz.to_num::<f64>() * std::f64::consts::TAU;
            rep.result(
                "Frequency::from_hz",
                Frequency::from_hz(hz),
                fit(want, MAX32),
                want,
                LSB32,
                0.0,
                |w| rad_s(*w),
                &ctx,
            )?;
            let w = Frequency::from_bits(hb);
            let want = rad_s(w) / std::f64::consts::TAU;
            rep.value(
                "Frequency::to_hz",
                w.to_hz().to_num::<f64>(),
                want,
                LSB32,
                0.0,
                &ctx,
            )?;
            // Checked and saturating arithmetic against i128 on the bits.
            let (x, y) = (Torque::from_bits(a), Torque::from_bits(b));
            let fits = |v: i128| i64::try_from(v).ok().map(Torque::from_bits);
            let sat = |v: i128| Torque::from_bits(v.clamp(i64::MIN.into(), i64::MAX.into()) as i64);
            let (a, b) = (i128::from(a), i128::from(b));
            prop_assert_eq!(x.checked_add(y), fits(a + b));
            prop_assert_eq!(x.checked_sub(y), fits(a - b));
            prop_assert_eq!(x.checked_neg(), fits(-a));
            prop_assert_eq!(x.saturating_add(y), sat(a + b));
            prop_assert_eq!(x.saturating_sub(y), sat(a - b));
            prop_assert_eq!(x.saturating_abs(), sat(a.abs()));
            prop_assert_eq!(x.is_negative(), a < 0);
            prop_assert_eq!(x.to_bits(), a as i64);
            rep.count("checked/saturating ops", "exact".into());
            Ok(())
        },
    );
}

/// 128-bit n: special values, perfect powers ± 1, or log-uniform over all of u128.
fn root_input() -> impl Strategy<Value = u128> {
    prop_oneof![
        1 => Just(0u128),
        1 => Just(1u128),
        1 => Just(u128::MAX),
        2 => (1u128..=u128::from(u64::MAX), -1i8..=1).prop_map(|(r, d)| (r * r).wrapping_add_signed(d.into())),
        2 => (1u128..(1 << 42), -1i8..=1).prop_map(|(r, d)| (r * r * r).wrapping_add_signed(d.into())),
        8 => (0u32..128, any::<u128>()).prop_map(|(bits, v)| if bits == 0 { 0 } else { v >> (128 - bits) }),
    ]
}

#[test]
fn integer_roots() {
    run("integer_roots", root_input(), |rep, n| {
        // Floor square root: r² ≤ n < (r+1)², remainder n − r².
        let (r, rem) = isqrt(n);
        prop_assert!(r * r <= n, "isqrt({n}) = {r}");
        prop_assert!(
            (r + 1).checked_mul(r + 1).is_none_or(|s| s > n),
            "isqrt({n}) = {r}"
        );
        prop_assert_eq!(rem, n - r * r);
        // Floor cube root: y³ ≤ n < (y+1)³.
        let (y, rem) = icbrt(n);
        prop_assert!(y * y * y <= n, "icbrt({n}) = {y}");
        let next = (y + 1)
            .checked_mul(y + 1)
            .and_then(|s| s.checked_mul(y + 1));
        prop_assert!(next.is_none_or(|c| c > n), "icbrt({n}) = {y}");
        prop_assert_eq!(rem, n - y * y * y);
        // Rounded roots: |root − n^(1/p)| ≤ 1/2 ⟺ (2r−1)^p ≤ 2^p·n ≤ (2r+1)^p (exact where
        // 8n fits; no ties are possible for integers).
        if n < 1 << 124 {
            let r = isqrt_round(n);
            let lo = (2 * r).saturating_sub(1);
            prop_assert!(
                lo * lo <= 4 * n && 4 * n <= (2 * r + 1) * (2 * r + 1),
                "isqrt_round({n}) = {r}"
            );
            let y = icbrt_round(n);
            let lo = (2 * y).saturating_sub(1);
            prop_assert!(
                lo * lo * lo <= 8 * n && 8 * n <= (2 * y + 1) * (2 * y + 1) * (2 * y + 1),
                "icbrt_round({n}) = {y}"
            );
            rep.count("isqrt_round/icbrt_round", "exact".into());
        } else {
            // Near the top: rounding is floor or floor + 1, consistent with the floor root.
            let (f, _) = isqrt(n);
            prop_assert!(isqrt_round(n) == f || isqrt_round(n) == f + 1);
            let (f, _) = icbrt(n);
            prop_assert!(icbrt_round(n) == f || icbrt_round(n) == f + 1);
            rep.count(
                "isqrt_round/icbrt_round",
                "top range: floor or floor+1".into(),
            );
        }
        rep.count("isqrt/icbrt", "exact".into());
        Ok(())
    });
}
