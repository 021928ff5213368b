//! The figures that run the simulated actuator (`plant` crate):
//!
//! * `fig8_identified_stiffness`: a static load test at L = 1…5 mm. The plant is built with
//!   the coupling of [`harness::plant_config`] (the model's k(L), free play, hysteresis),
//!   the output gear **locked** (test fixture) and, as a load-test rig would, a damper on
//!   the link (≈ 0.7 of critical, no effect on the static equilibria) so that each load
//!   level settles. An external torque is applied on the link in a ramp of ± levels within
//!   ±0.8·τ_cap(L) (0 → +max → −max → 0, [`LEVELS`] levels per side, so the hysteresis
//!   loop is traversed once and averages out); each level is held [`HOLD_TICKS`] ms and the
//!   deflection φ = θ_gear − θ_link is averaged over the last [`AVG_TICKS`] ms, both
//!   the true one and the one the board measures (gear pot − link encoder, each count
//!   converted at its centre). The coupling torque at rest equals −τ_ext. The fit is linear
//!   least squares of the deflection on the torque, φ = τ/k + sign(τ)·φ_b + φ_0 (compliance,
//!   free play, offset), which is the slope beyond the free play.
//! * `fig9_step_responses`: the harness's step scenario (0.5 rad raw step, 0.5 s hold) at
//!   L = 1…5 mm, without load and against a constant 0.3 N·m ([`FIG9_LOAD_NM`]); the link
//!   angle minus its start, over the target minus that start, filtered by a
//!   2nd-order Butterworth low pass at 4 Hz (bilinear transform with pre-warping at the
//!   1 kHz tick, f64 on the host, started at rest at the initial value), t = 0…1 s.

use model::control::{Command, Config};
use model::sensors::encoder_delta;
use model::{Angle, Design, Length};
use plant::harness::{self, Scenario};
use plant::{Plant, ENCODER_COUNT_RAD, POT_COUNTS_PER_RAD};
use plotters::prelude::SeriesLabelPosition;

use super::plot::{Figure, Panel, Series, COLORS};
use super::{c, Csv};
use crate::design::to_f64;
use crate::format::trim;

/// Load levels per side of the load test.
pub const LEVELS: i32 = 5;
/// Ticks each load level is held.
pub const HOLD_TICKS: u32 = 150;
/// Ticks averaged at the end of each level.
pub const AVG_TICKS: u32 = 20;
/// Smallest elastic deflection span, in encoder counts, for an identified k.
pub const MIN_SPAN_COUNTS: f64 = 2.0;
/// The clutch settings of Figs. 8 and 9, mm.
pub const SETTINGS: [i32; 5] = [1, 2, 3, 4, 5];
/// Step of Fig. 9, rad.
pub const STEP_RAD: f64 = 0.5;
/// Cut-off of the Fig. 9 low pass, Hz.
pub const CUTOFF_HZ: f64 = 4.0;

fn err<E: std::fmt::Display>(what: &'static str) -> impl Fn(E) -> String {
    move |e| format!("{what}: {e}")
}

/// Result of one load test.
#[derive(Clone, Copy, Debug)]
pub struct LoadTest {
    /// k identified from the true deflection, N·m/rad.
    pub k_true: f64,
    /// k identified from the sensor deflection, N·m/rad.
    pub k_sensor: f64,
}

/// Least squares of y on (x, sign s, 1): returns the coefficient of x.
fn fit_slope(pts: &[(f64, f64, f64)]) -> Option<f64> {
    // Normal equations A·p = b for p = (a, b, c) in y = a·x + b·s + c.
    let mut m = [[0.0f64; 3]; 3];
    let mut v = [0.0f64; 3];
    for &(x, s, y) in pts {
        let r = [x, s, 1.0];
        for i in 0..3 {
            for j in 0..3 {
                m[i][j] += r[i] * r[j];
            }
            v[i] += r[i] * y;
        }
    }
    // Gaussian elimination with partial pivoting.
    for col in 0..3 {
        let piv = (col..3).max_by(|&a, &b| m[a][col].abs().total_cmp(&m[b][col].abs()))?;
        m.swap(col, piv);
        v.swap(col, piv);
        if m[col][col].abs() < 1e-300 {
            return None;
        }
        let pivot = m[col];
        for row in col + 1..3 {
            let k = m[row][col] / pivot[col];
            for (a, b) in m[row].iter_mut().zip(pivot).skip(col) {
                *a -= k * b;
            }
            v[row] -= k * v[col];
        }
    }
    let mut p = [0.0f64; 3];
    for i in (0..3).rev() {
        let s: f64 = (i + 1..3).map(|j| m[i][j] * p[j]).sum();
        p[i] = (v[i] - s) / m[i][i];
    }
    Some(p[0])
}

/// The static load test at clutch length `len`.
pub fn load_test(d: &Design, len: Length) -> Result<LoadTest, String> {
    let cfg = Config::paper(len);
    let mut pc = harness::plant_config(d, &cfg, 0.0).map_err(err("plant"))?;
    pc.gear_locked = true;
    let k = f64::from(pc.coupling.stiffness_nm_per_rad);
    let j = f64::from(pc.link.inertia_kg_m2);
    pc.link.viscous_nm_s_per_rad = (1.4 * (k * j).sqrt()) as f32;
    let cap = to_f64(d.torque_capacity(len).map_err(err("capacity"))?.get());
    let mut plant = Plant::new(pc);
    let levels = (1..=LEVELS)
        .chain((-LEVELS..LEVELS).rev())
        .chain(-LEVELS + 1..0);
    let pot0 = f64::from(pc.sensors.pot_center_counts);
    let (mut tru, mut sen) = (Vec::new(), Vec::new());
    for lv in levels {
        let tau_ext = 0.8 * cap * f64::from(lv) / f64::from(LEVELS);
        plant.set_external_torque(tau_ext as f32);
        let (mut sum_t, mut sum_s) = (0.0, 0.0);
        for t in 0..HOLD_TICKS {
            let r = plant.step_tick(0);
            if t >= HOLD_TICKS - AVG_TICKS {
                let st = plant.state();
                sum_t += st.gear_angle_rad - st.link_angle_rad;
                let gear = (f64::from(r.gear_pot) - pot0) / f64::from(POT_COUNTS_PER_RAD);
                let e = encoder_delta(r.link_encoder, 0);
                let link = (f64::from(e) + 0.5) * ENCODER_COUNT_RAD;
                sum_s += gear - link;
            }
        }
        let n = f64::from(AVG_TICKS);
        let tau = -tau_ext; // coupling torque on the link at rest
        let s = tau.signum();
        tru.push((tau, s, sum_t / n));
        sen.push((tau, s, sum_s / n));
    }
    // Not identifiable when the elastic part of the deflection spans fewer than
    // [`MIN_SPAN_COUNTS`] encoder counts (the fit would only see quantisation).
    let span = 1.6 * cap;
    let k_of = |p: &[(f64, f64, f64)], min_span: f64| {
        fit_slope(p)
            .filter(|c| *c > 0.0 && c * span >= min_span)
            .map_or(f64::NAN, |c| 1.0 / c)
    };
    Ok(LoadTest {
        k_true: k_of(&tru, 0.0),
        k_sensor: k_of(&sen, MIN_SPAN_COUNTS * ENCODER_COUNT_RAD),
    })
}

/// Fig. 8: stiffness identified from a simulated static load test vs the model.
pub fn fig8_identified_stiffness(d: &Design) -> Result<(Figure, Csv), String> {
    let mut csv = Csv::new(
        "length_mm,k_model_nm_per_rad,k_model_shear_nm_per_rad,k_identified_true_nm_per_rad,k_identified_sensor_nm_per_rad",
    );
    let (mut eb, mut sh, mut it, mut is) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for l in 100..=500 {
        let len = Length::from_micro(l * 10_000).map_err(err("length"))?;
        let x = to_f64(len.get());
        eb.push((x, d.stiffness(len).map_err(err("k"))?.get().to_num::<f64>()));
        sh.push((
            x,
            d.stiffness_timoshenko(len)
                .map_err(err("k_T"))?
                .get()
                .to_num::<f64>(),
        ));
    }
    for l in SETTINGS {
        let len = Length::from_int(l);
        let k = d.stiffness(len).map_err(err("k"))?.get().to_num::<f64>();
        let kt = d
            .stiffness_timoshenko(len)
            .map_err(err("k_T"))?
            .get()
            .to_num::<f64>();
        let t = load_test(d, len)?;
        let x = f64::from(l);
        csv.push(&[
            c(x),
            c(k),
            c(kt),
            c(t.k_true),
            if t.k_sensor.is_finite() {
                c(t.k_sensor)
            } else {
                String::new()
            },
        ]);
        it.push((x, t.k_true));
        if t.k_sensor.is_finite() {
            is.push((x, t.k_sensor));
        }
    }
    let series = vec![
        Series {
            label: Some("model, Euler–Bernoulli".into()),
            points: eb,
            color: COLORS[0],
            dashed: false,
            marker: false,
        },
        Series {
            label: Some("model, Timoshenko".into()),
            points: sh,
            color: COLORS[1],
            dashed: true,
            marker: false,
        },
        Series {
            label: Some("identified, true deflection".into()),
            points: it,
            color: COLORS[2],
            dashed: false,
            marker: true,
        },
        Series {
            label: Some("identified, sensors (pot − encoder)".into()),
            points: is,
            color: COLORS[3],
            dashed: false,
            marker: true,
        },
    ];
    let fig = Figure {
        title: "Fig. 8 — stiffness identified from a simulated static load test vs the model"
            .into(),
        panels: vec![Panel {
            caption: format!(
                "gear locked, {LEVELS} load levels per side within ±0.8·τ_cap(L); no sensor fit below {MIN_SPAN_COUNTS} counts of span"

            ),
            x_label: "clutch length L (mm)".into(),
            y_label: "joint stiffness k (N·m/rad)".into(),
            log_y: true,
            y_zero: false,
            headroom: 0.0,
            x_margin: 0.04,
            series,
            legend: SeriesLabelPosition::UpperRight,
        }],
        size: (1000, 700),
    };
    Ok((fig, csv))
}

/// 2nd-order Butterworth low pass at `fc` Hz for samples every `dt` s (bilinear transform,
/// pre-warped), started at rest at `x0`.
pub fn butterworth(xs: &[f64], fc: f64, dt: f64, x0: f64) -> Vec<f64> {
    let k = (std::f64::consts::PI * fc * dt).tan();
    let q = std::f64::consts::SQRT_2;
    let norm = 1.0 / (1.0 + q * k + k * k);
    let b0 = k * k * norm;
    let (b1, b2) = (2.0 * b0, b0);
    let a1 = 2.0 * (k * k - 1.0) * norm;
    let a2 = (1.0 - q * k + k * k) * norm;
    let (mut x1, mut x2, mut y1, mut y2) = (x0, x0, x0, x0);
    xs.iter()
        .map(|&x| {
            let y = b0 * x + b1 * x1 + b2 * x2 - a1 * y1 - a2 * y2;
            (x2, x1, y2, y1) = (x1, x, y1, y);
            y
        })
        .collect()
}

/// The constant load of Fig. 9's second panel, N·m: against the step (the link is pushed
/// back towards its start), as in the closed-loop tests.
pub const FIG9_LOAD_NM: f64 = -0.3;

/// The normalised, filtered step response at `len` with a constant `load_nm` on the link:
/// (t, y) for t in (0, 1] s.
pub fn step_response(d: &Design, len: Length, load_nm: f64) -> Result<Vec<(f64, f64)>, String> {
    let target = Angle::from_micro((STEP_RAD * 1e6) as i64).map_err(err("angle"))?;
    let mut sc = Scenario::new(Config::paper(len), Command::Step { target });
    sc.design = *d;
    sc.load_nm = load_nm as f32;
    // Held 0.5 s first, so that a load has been taken up before the step (as in the
    // closed-loop tests); normalised by the step from where the link starts to the
    // target, both in the plant's true frame.
    sc.settle_ticks = 500;
    sc.run_ticks = 1000;
    let (mut t, mut theta) = (Vec::new(), Vec::new());
    let m = harness::run(&sc, |s| {
        if s.t_s > 0.0 {
            t.push(s.t_s);
            theta.push(s.link_angle_rad);
        }
    })
    .map_err(err("controller"))?;
    let a0 = theta.first().copied().unwrap_or(0.0);
    let y: Vec<f64> = theta
        .iter()
        .map(|a| (a - a0) / (m.target_rad - a0))
        .collect();
    let yf = butterworth(&y, CUTOFF_HZ, 1e-3, 0.0);
    Ok(t.into_iter().zip(yf).collect())
}

/// Fig. 9: normalised step responses at the five settings, without load and against
/// [`FIG9_LOAD_NM`].
pub fn fig9_step_responses(d: &Design) -> Result<(Figure, Csv), String> {
    let loads = [(0.0, ""), (FIG9_LOAD_NM, "_loaded")];
    let mut header = String::from("t_s");
    for (_, suffix) in loads {
        for l in SETTINGS {
            header.push_str(&format!(",y_L{l}mm{suffix}"));
        }
    }
    let mut csv = Csv::new(header);
    let mut curves = Vec::new();
    for (load, _) in loads {
        for l in SETTINGS {
            curves.push(step_response(d, Length::from_int(l), load)?);
        }
    }
    for i in 0..curves[0].len() {
        let mut row = vec![format!("{:.3}", curves[0][i].0)];
        row.extend(curves.iter().map(|cv| c(cv[i].1)));
        csv.push(&row);
    }
    let mut panels = Vec::new();
    let captions = [
        "no load".to_string(),
        format!("{} N·m against the step", trim(FIG9_LOAD_NM.abs())),
    ];
    let mut curves = curves.into_iter();
    for caption in captions {
        let series = SETTINGS
            .into_iter()
            .zip(curves.by_ref())
            .enumerate()
            .map(|(i, (l, pts))| {
                let k = d
                    .stiffness(Length::from_int(l))
                    .map_or(f64::NAN, |k| k.get().to_num::<f64>());
                Series {
                    label: Some(format!("L = {l} mm (k = {} N·m/rad)", trim(k.round()))),
                    points: pts,
                    color: COLORS[i],
                    dashed: false,
                    marker: false,
                }
            })
            .collect();
        panels.push(Panel {
            caption: format!(
                "{caption}: link angle / step, 2nd-order Butterworth low pass at {} Hz",
                trim(CUTOFF_HZ)
            ),
            x_label: "time after the command t (s)".into(),
            y_label: "normalised link angle (–)".into(),
            log_y: false,
            y_zero: true,
            headroom: 0.0,
            x_margin: 0.0,
            series,
            legend: SeriesLabelPosition::LowerRight,
        });
    }
    let fig = Figure {
        title: format!(
            "Fig. 9 — normalised step responses, {STEP_RAD} rad raw step, J = 1e-3 kg·m²"
        ),
        panels,
        size: (1600, 700),
    };
    Ok((fig, csv))
}
