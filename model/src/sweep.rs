//! Deterministic sweep of the documented domain against f64 formulas (a smoke test; the
//! independent oracle and property tests live in host-tests).

use fixed::types::{I32F32, I64F64};

use crate::design::*;
use crate::dynamics::{natural_frequency, stiffness_for_frequency};
use crate::{
    Angle, BeamModel, Branch, Design, Error, Frequency, Inertia, Length, Ratio, Setting, Stiffness,
    Stress, Torque,
};

struct Rng(u64);

impl Rng {
    fn next(&mut self) -> f64 {
        // xorshift64*
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        (self.0.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 / (1u64 << 53) as f64
    }
    fn log_uniform(&mut self, lo: f64, hi: f64) -> f64 {
        (lo.ln() + (hi.ln() - lo.ln()) * self.next()).exp()
    }
    fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.next()
    }
}

const LSB: f64 = 1.0 / 4_294_967_296.0;
const LSB64: f64 = LSB * LSB;

/// f64 → I32F32 without `from_num` (the crate keeps float conversions out, even in tests).
fn fx(v: f64) -> I32F32 {
    I32F32::from_bits((v * 4_294_967_296.0).round() as i64)
}
fn to_f64(v: I32F32) -> f64 {
    v.to_num()
}

/// Checks `got` against `want`: relative 1e-4 or 2 LSB (`lsb`); an overflow error is
/// accepted only if |want| is at the edge of the format (`max`).
#[track_caller]
fn check(what: &str, got: Result<f64, Error>, want: f64, lsb: f64, max: f64) {
    match got {
        Ok(g) => {
            let err = (g - want).abs();
            assert!(
                err <= 1e-4 * want.abs() || err <= 2.0 * lsb,
                "{what}: got {g:e}, want {want:e}"
            );
        }
        Err(Error::Overflow) => assert!(
            want.abs() >= max * 0.999_999,
            "{what}: overflow for {want:e}"
        ),
        Err(e) => panic!("{what}: {e:?} for {want:e}"),
    }
}

#[test]
fn domain_sweep_against_f64() {
    let mut rng = Rng(0x9E37_79B9_7F4A_7C15);
    let max32 = 2f64.powi(31);
    let max64 = 2f64.powi(63);
    let mut ran = 0;
    for case in 0..3000 {
        let n = 1 + (rng.next() * 16.0) as u8;
        let r = to_f64(fx(rng.log_uniform(0.05, 5.0)));
        let big_r = to_f64(fx(rng.log_uniform(1.0, 100.0).max(r * 1.01)));
        let e = to_f64(fx(rng.log_uniform(1e3, 1e6)));
        let g = to_f64(fx(rng.log_uniform(e / 3.0, 1e6).clamp(e / 2.99, 1e6)));
        if g < e / 3.0 || g < 1e3 {
            continue;
        }
        let sigma = to_f64(fx(rng.log_uniform(1.0, 1e4)));
        let l = to_f64(fx(rng.log_uniform(0.1, 100.0)));
        let tc = to_f64(fx(rng.log_uniform(0.01, l * 0.999)));
        let mu = to_f64(fx(rng.uniform(0.0, 2.0)));
        let d = Design::new(DesignParams {
            beams: n,
            beam_radius: Length::from_fixed(fx(r)),
            pitch_radius: Length::from_fixed(fx(big_r)),
            youngs_modulus: Stress::from_fixed(fx(e)),
            shear_modulus: Stress::from_fixed(fx(g)),
            allowable_stress: Stress::from_fixed(fx(sigma)),
            beam_length: Length::from_fixed(fx(l)),
            clutch_thickness: Length::from_fixed(fx(tc)),
            friction: Ratio::from_fixed(fx(mu)),
        })
        .unwrap_or_else(|err| panic!("case {case}: {err:?}"));
        ran += 1;
        let nf = f64::from(n);
        let i = core::f64::consts::PI * r.powi(4) / 4.0;
        let area = core::f64::consts::PI * r * r;
        let c = nf * 3.0 * e * i * big_r * big_r / 1000.0;
        let nu = e / (2.0 * g) - 1.0;
        let kappa = 6.0 * (1.0 + nu) / (7.0 + 6.0 * nu);
        check("nu", Ok(to_f64(d.poisson_ratio().get())), nu, LSB, max32);
        check(
            "kappa",
            Ok(to_f64(d.shear_coefficient().get())),
            kappa,
            LSB,
            max32,
        );

        // L log-uniform over (0, l], sometimes exactly l or t_c.
        let len = match case % 10 {
            0 => l,
            1 => tc,
            _ => to_f64(fx(rng.log_uniform(1e-6, l))),
        };
        let lf = Length::from_fixed(fx(len));
        let k = c / len.powi(3);
        let kt =
            nf * big_r * big_r / (len.powi(3) / (3.0 * e * i) + len / (kappa * g * area)) / 1000.0;
        let to64 = |s: Result<Stiffness, Error>| s.map(|v| v.get().to_num::<f64>());
        check("k", to64(d.stiffness(lf)), k, LSB64, max64);
        check("k_T", to64(d.stiffness_timoshenko(lf)), kt, LSB64, max64);

        // Round trips L → k → L.
        for m in [BeamModel::EulerBernoulli, BeamModel::Timoshenko] {
            if let Ok(kk) = m.stiffness(&d, lf) {
                let back = m.clutch_length(&d, kk).map(|v| to_f64(v.get()));
                check("L(k(L))", back, len, LSB, max32);
            }
        }
        // Inverse from a random stiffness in [k(l), ~k(0.001 l)].
        let kw = rng
            .log_uniform(c / l.powi(3), c / (l * 1e-3).powi(3))
            .min(9e18);
        let kwf = Stiffness::from_fixed(I64F64::from_bits((kw * 2f64.powi(64)) as i128));
        let kwq = kwf.get().to_num::<f64>();
        match d.clutch_length(kwf) {
            Ok(v) => check("L(k)", Ok(to_f64(v.get())), (c / kwq).cbrt(), LSB, max32),
            Err(Error::StiffnessTooLow) => assert!((c / kwq).cbrt() > l * 0.999_99),
            Err(err) => panic!("L(k): {err:?}"),
        }

        let tau = to_f64(fx(
            rng.log_uniform(LSB, 1e9) * if rng.next() < 0.5 { -1.0 } else { 1.0 }
        ));
        let tf = Torque::from_fixed(fx(tau));
        let th = |v: Result<Angle, Error>| v.map(|a| to_f64(a.get()));
        check("theta", th(d.deflection(tf, lf)), tau / k, LSB, max32);
        let p = tau * 1000.0 / (nf * big_r);
        check(
            "P",
            d.beam_force(tf).map(|v| to_f64(v.get())),
            p,
            LSB,
            max32,
        );
        check(
            "sigma",
            d.root_stress(tf, lf).map(|v| to_f64(v.get())),
            p * len * r / i,
            LSB,
            max32,
        );
        let cap = nf * big_r * sigma * i / (r * len) / 1000.0;
        check(
            "tau_cap",
            d.torque_capacity(lf).map(|v| to_f64(v.get())),
            cap,
            LSB,
            max32,
        );
        check(
            "theta_cap",
            th(d.deflection_capacity(lf)),
            cap / k,
            LSB,
            max32,
        );
        check(
            "theta_cap_T",
            th(d.deflection_capacity_timoshenko(lf)),
            cap / kt,
            LSB,
            max32,
        );

        let theta_max = sigma * l / (3.0 * e * r);
        check(
            "delta_max",
            Ok(to_f64(d.max_tip_deflection().get())),
            theta_max * l,
            LSB,
            max32,
        );
        check(
            "theta_max",
            Ok(to_f64(d.bending_capacity().get())),
            theta_max,
            LSB,
            max32,
        );
        check(
            "c",
            Ok(to_f64(d.slot_clearance().get())),
            theta_max * tc,
            LSB,
            max32,
        );
        check(
            "r_slot",
            Ok(to_f64(d.slot_radius().get())),
            r + theta_max * tc,
            LSB,
            max32,
        );
        let phi_b = theta_max * tc / big_r;
        check("phi_b", Ok(to_f64(d.free_play().get())), phi_b, LSB, max32);
        if len >= tc {
            check(
                "theta_b",
                th(d.tilt_backlash(lf)),
                theta_max * tc / len,
                LSB,
                max32,
            );
        } else {
            assert_eq!(d.tilt_backlash(lf), Err(Error::BacklashPositionOutOfRange));
        }

        // Setting, per-tick functions.
        for (m, kk) in [(BeamModel::EulerBernoulli, k), (BeamModel::Timoshenko, kt)] {
            let s = match Setting::new(&d, lf, m) {
                Ok(s) => s,
                Err(Error::Overflow) => {
                    assert!(kk > 9e18 || cap > max32 * 0.999 || cap / kk > max32 * 0.999);
                    continue;
                }
                Err(err) => panic!("{err:?}"),
            };
            check("S.theta", th(s.deflection(tf)), tau / kk, LSB, max32);
            check(
                "S.sigma",
                s.root_stress(tf).map(|v| to_f64(v.get())),
                p * len * r / i,
                LSB,
                max32,
            );
            let phi = to_f64(fx(
                rng.log_uniform(1e-9, 10.0) * if rng.next() < 0.5 { -1.0 } else { 1.0 }
            ));
            let pf = Angle::from_fixed(fx(phi));
            let tq = |v: Result<Torque, Error>| v.map(|t| to_f64(t.get()));
            check("S.tau", tq(s.elastic_torque(pf)), kk * phi, LSB, max32);
            let pe = (phi.abs() - phi_b).max(0.0) * phi.signum();
            check("coupling", tq(s.coupling_torque(pf)), kk * pe, LSB, max32);
            let a = 1.2 * mu * big_r / len;
            for (b, sign) in [(Branch::Loading, 1.0), (Branch::Unloading, -1.0)] {
                let want = kk * phi * (1.0 + sign * a * phi.abs()).max(0.0);
                check("branch", tq(s.branch_torque(pf, b)), want, LSB, max32);
                let want = kk * pe * (1.0 + sign * a * pe.abs()).max(0.0);
                check(
                    "hyst",
                    tq(s.hysteretic_coupling_torque(pf, b)),
                    want,
                    LSB,
                    max32,
                );
            }
        }

        // Dynamics.
        let j = to_f64(fx(rng.log_uniform(1e-3, 1e9)));
        let jf = Inertia::from_fixed(fx(j));
        if let Ok(kk) = d.stiffness(lf) {
            let kq = kk.get().to_num::<f64>();
            if kq > 0.0 {
                let w = natural_frequency(kk, jf).map(|v| to_f64(v.get()));
                check("omega", w, (kq * 1e6 / j).sqrt(), LSB, max32);
            }
        }
        let w = to_f64(fx(rng.log_uniform(1e-3, 1e7)));
        let kj = stiffness_for_frequency(jf, Frequency::from_fixed(fx(w)));
        check("k(J,w)", to64(kj), j * w * w / 1e6, LSB64, max64);
    }
    assert!(ran > 2500, "{ran}");
}
