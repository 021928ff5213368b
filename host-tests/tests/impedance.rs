//! Closed-loop proof of the impedance command (docs/design.md §11, "Impedance command") on
//! the simulated actuator: paper preset, J_link = 1e-3 kg·m², clutch lengths 1…8 mm,
//! several virtual stiffnesses and dampings, static external torques of both signs, nominal
//! and off-nominal actuators (`plant::overrides`, which the controller does not see).
//!
//! Each run holds 0.5 s at 0 rad, the external torque put on at the end of the boot window, then gives
//! the impedance command (target 0.2 rad) and runs 2 s. The oracle is the virtual spring's
//! static deflection (τ_ext + τ_ff)/k_v from the numbers given, and the physical stiffness
//! for the refusal is the f64 oracle's k(L) (`host_tests::oracle`). Figures: the mean true
//! link angle over the last 500 ms, the peak true beam stress, the latched faults
//! (`cargo test -p host-tests --test impedance -- --nocapture` prints them).

use host_tests::oracle;
use host_tests::sim::{self, COUNT_RAD};
use model::calibration::correction::BOOT_TICKS;
use model::control::{ImpedanceCommand, ImpedanceError};
use model::servo::ServoError;
use model::{Angle, Stiffness, Torque};
use plant::harness::{self, Scenario};
use plant::overrides::Overrides;

/// Target of every run, rad.
const TARGET_RAD: f64 = 0.2;
/// Softest k_v of the grids, N·m/rad: one count × k_v = 0.015 N·m, what the static torque
/// estimate resolves (gear Coulomb friction 0.01 N·m; at L = 8 mm the pot's half count
/// times k and its blend weight, 0.017 N·m). Softer, the deflection is within that
/// torque / k_v (docs/design.md §11, "Impedance command").
const K_V_MIN: f64 = 10.0;
/// The static external torques, N·m.
const LOADS: [f64; 4] = [0.25, -0.25, 0.15, -0.15];
/// Tick of the run at which the external torque is put on the link: the first after the
/// boot window, as the servo starts holding. Put on later, into a hold already at rest, the
/// link crosses the free play and hits the beams: with `resistance=x0.8` at 4 mm and
/// −0.15 N·m that impact reached 1.09 σ_allow (tick 60) and 1.20 σ_allow (tick 80), the
/// position hold's free-play impacts (docs/design.md §11, "Not reached yet"), not the
/// impedance command's.
const LOAD_AFTER_BOOT_TICKS: i32 = BOOT_TICKS as i32 + 1;
/// Relative tolerance of the deflection.
const REL_TOL: f64 = 0.05;

fn command(k_v: f64, d_v: f64, ff: f64) -> ImpedanceCommand {
    ImpedanceCommand {
        target: Angle::from_micro((TARGET_RAD * 1e6) as i64).unwrap(),
        stiffness: Stiffness::from_micro((k_v * 1e6).round() as i64),
        damping: fixed::types::I32F32::from_num(d_v),
        torque: Torque::from_micro((ff * 1e6).round() as i64).unwrap(),
    }
}

struct Case {
    l_mm: i32,
    k_v: f64,
    d_v: f64,
    ff: f64,
    load: f64,
    plant: &'static str,
}

struct Outcome {
    deflection: f64,
    want: f64,
    error_counts: f64,
    stress_ratio: f64,
    faults: bool,
    first_fault: Option<model::supervisor::Fault>,
    span_counts: i32,
}

fn run(c: &Case) -> Outcome {
    // The torque arrives after power-up: with it on the link
    // during the boot window the pot's alignment takes the beams' deflection then as zero,
    // and the torque estimate carries k times that (docs/calibration.md, "The link's
    // absolute angle at start-up").
    let mut sc: Scenario = sim::scenario(c.l_mm, model::Command::Hold, 0.0);
    sc.disturbance = Some(harness::Disturbance {
        after_command_ticks: LOAD_AFTER_BOOT_TICKS - sc.settle_ticks as i32,
        torque_nm: c.load as f32,
    });
    sc.impedance = Some(command(c.k_v, c.d_v, c.ff));
    if !c.plant.is_empty() {
        sc.plant = Overrides::parse_all(c.plant.split(' ')).expect("overrides");
    }
    let window_from = sc.settle_ticks + sc.run_ticks - 500;
    let (mut sum, mut n) = (0.0, 0.0);
    let m = harness::run(&sc, |s| {
        if s.tick >= window_from {
            sum += s.link_angle_rad;
            n += 1.0;
        }
    })
    .expect("accepted");
    // From the target in the true frame: the servo's frame is set at power-up from the pot
    // (`harness::frame_shift`), a few counts from the true one under a load.
    let deflection = sum / n - m.target_rad;
    let want = (c.load + c.ff) / c.k_v;
    Outcome {
        deflection,
        want,
        error_counts: (deflection - want).abs() / COUNT_RAD,
        stress_ratio: m.peak_stress_ratio,
        faults: !m.faults.is_empty(),
        first_fault: m.first_fault,
        span_counts: m.steady_count_span,
    }
}

/// The figures of a set of runs: failures, and the worst of each metric with its line.
#[derive(Default)]
struct Summary {
    runs: usize,
    failures: Vec<String>,
    /// Largest |deflection − want| / tolerance (≤ 1 passes).
    worst_error: (f64, String),
    /// Largest peak stress / σ_allow.
    worst_stress: (f64, String),
}

impl Summary {
    fn check(&mut self, c: &Case) {
        let o = run(c);
        let tol = (REL_TOL * o.want.abs()).max(COUNT_RAD);
        let err = (o.deflection - o.want).abs();
        let ok = err <= tol && !o.faults && o.stress_ratio <= 1.0;
        let line = format!(
            "L = {} mm, k_v {:.2}, d_v {:.2}, ff {:+.2}, load {:+.2}, plant [{}]: deflection \
             {:+.5} rad (want {:+.5}, error {:.2} counts = {:.1} %), span {} counts, stress \
             {:.3} σ_allow{}",
            c.l_mm,
            c.k_v,
            c.d_v,
            c.ff,
            c.load,
            c.plant,
            o.deflection,
            o.want,
            o.error_counts,
            100.0 * err / o.want.abs().max(1e-12),
            o.span_counts,
            o.stress_ratio,
            if o.faults {
                format!(", FAULT {:?}", o.first_fault)
            } else {
                String::new()
            }
        );
        self.runs += 1;
        if err / tol > self.worst_error.0 {
            self.worst_error = (err / tol, line.clone());
        }
        if o.stress_ratio > self.worst_stress.0 {
            self.worst_stress = (o.stress_ratio, line.clone());
        }
        if !ok {
            self.failures.push(line);
        }
    }

    /// Prints the figures and fails on any violation.
    fn assert_none(&self) {
        for b in &self.failures {
            println!("FAIL {b}");
        }
        println!(
            "{} runs; worst deflection error {:.2} of its tolerance: {}",
            self.runs, self.worst_error.0, self.worst_error.1
        );
        println!(
            "worst peak stress {:.3} σ_allow: {}",
            self.worst_stress.0, self.worst_stress.1
        );
        assert!(self.failures.is_empty(), "{} failures", self.failures.len());
    }
}

/// The grid at one plant: clutch lengths 1…8 mm; k_v = `soft`, 20 N·m/rad, k/2 and
/// 0.9·k (those not above k(L) nor below `k_min`); d_v = 0.05, 0.2, 1 N·m·s/rad in turn; τ_ff = 0 and
/// 0.05 N·m in turn; external torques `loads`, N·m.
fn grid(sum: &mut Summary, plant: &'static str, soft: f64, k_min: f64, loads: &[f64]) {
    let d = oracle::Design::paper();
    let mut n = 0usize;
    for l in 1..=8 {
        let k = d.stiffness(f64::from(l) * 1e-3);
        for k_v in [soft, 20.0, 0.5 * k, 0.9 * k] {
            if k_v > k || k_v < k_min {
                continue;
            }
            for &load in loads {
                n += 1;
                sum.check(&Case {
                    l_mm: l,
                    k_v,
                    d_v: [0.05, 0.2, 1.0][n % 3],
                    ff: [0.0, 0.05][n % 2],
                    load,
                    plant,
                });
            }
        }
    }
}

#[test]
fn a_static_torque_deflects_the_link_by_torque_over_virtual_stiffness() {
    let mut sum = Summary::default();
    grid(&mut sum, "", 10.0, K_V_MIN, &LOADS);
    sum.assert_none();
}

/// Off-nominal actuators whose static torque estimate stays within what one count at
/// [`K_V_MIN`] allows; the others are the long run's (docs/design.md §11, "Impedance
/// command").
const OFF_NOMINAL: [&str; 14] = [
    "resistance=x0.8",
    "resistance=x1.4",
    "supply=10.5V",
    "supply=12.6V",
    "back-emf=x0.9",
    "back-emf=x1.1",
    "gear-inertia=x0.8",
    "gear-inertia=x1.25",
    "gear-friction=x0.5",
    "link-inertia=x0.5",
    "link-inertia=x3",
    "torque-constant=x0.95",
    "current-gain=x1.05",
    "current-offset=5",
];

#[test]
fn the_same_on_off_nominal_actuators() {
    let mut sum = Summary::default();
    // Half the loads each (both signs, both sizes), for time.
    for (i, p) in OFF_NOMINAL.into_iter().enumerate() {
        let loads = if i % 2 == 0 {
            [0.25, -0.15]
        } else {
            [-0.25, 0.15]
        };
        grid(&mut sum, p, 20.0, K_V_MIN, &loads);
    }
    sum.assert_none();
}

/// Long run: `PLANTS="resistance=x1.4,gear-friction=x3" SOFT=20 KMIN=10 cargo test -p
/// host-tests --test impedance any_plant -- --ignored --nocapture` (comma-separated plants,
/// each a space-separated list of overrides; SOFT the first k_v of each clutch length,
/// KMIN the softest k_v run, N·m/rad).
#[test]
#[ignore]
fn any_plant() {
    let num = |k: &str, d: f64| std::env::var(k).map_or(d, |s| s.parse().expect(k));
    let (soft, k_min) = (num("SOFT", 10.0), num("KMIN", K_V_MIN));
    let mut sum = Summary::default();
    for p in std::env::var("PLANTS").unwrap_or_default().split(',') {
        grid(
            &mut sum,
            Box::leak(p.to_owned().into_boxed_str()),
            soft,
            k_min,
            &LOADS,
        );
    }
    sum.assert_none();
}

#[test]
fn refuses_more_than_the_beams() {
    let d = oracle::Design::paper();
    for l in 1..=8 {
        let k = d.stiffness(f64::from(l) * 1e-3);
        let mut sc: Scenario = sim::scenario(l, model::Command::Hold, 0.0);
        sc.impedance = Some(command(k * 1.001, 0.2, 0.0));
        let r = harness::run(&sc, |_| {});
        assert_eq!(
            r.err(),
            Some(ServoError::Impedance(
                ImpedanceError::StiffnessAbovePhysical
            )),
            "L = {l} mm"
        );
    }
}
