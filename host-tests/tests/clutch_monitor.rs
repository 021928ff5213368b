//! A clutch set by hand to the wrong length (model::clutch_monitor, docs/calibration.md):
//! the controller and the supervisor are told L, the simulated beams are L + δ (softer and
//! weaker). With the clutch tolerance a board takes until a calibration confirms the
//! clutch (1 mm, a clutch slid by hand), moves and sines up to the
//! torque limit against a load never bend the beams beyond σ_allow (the true stress from
//! the plant), and where the pot resolves the deflection `clutch-mismatch` latches within
//! 1 s of the motion's start.

use host_tests::sim;
use model::servo::{Servo, TickInput};
use model::supervisor::FaultCode;
use model::Length;
use plant::harness::{allowable_stress_pa, bridge_command, plant_for, Scenario};
use plant::overrides::Override;
use service::clutch_confirmation::UNCONFIRMED_TOLERANCE_UM;
use service::length_from_um;

/// The clutch tolerance of the runs, mm.
const TOLERANCE_MM: f64 = UNCONFIRMED_TOLERANCE_UM as f64 / 1000.0;

/// τ_cap at the configured length, N·m.
fn capacity_nm(l: i32) -> f64 {
    let d = model::Design::paper();
    let s = model::Setting::new(&d, Length::from_int(l), model::BeamModel::EulerBernoulli).unwrap();
    s.torque_capacity().to_bits() as f64 / 4_294_967_296.0
}

/// The motions of the grid.
const MOTIONS: [&str; 5] = [
    "0.5 rad in 60 ms",
    "raw step 1 rad",
    "sine 0.3 rad 3 Hz",
    "heavy load, 1 rad in 100 ms",
    "0.7 of the weak capacity, 0.5 rad in 200 ms",
];

/// Whether the pot can resolve the wrong clutch under the run's static load: the softer
/// beams deflect at least one pot count further than the configured ones
/// (|τ|·(1/k(L + δ) − 1/k(L)), Euler–Bernoulli k of the f64 oracle, paper eq. 4).
fn resolvable(l_mm: f64, actual_mm: f64, load_nm: f64) -> bool {
    let d = host_tests::oracle::Design::paper();
    let extra =
        load_nm.abs() * (1.0 / d.stiffness(actual_mm * 1e-3) - 1.0 / d.stiffness(l_mm * 1e-3));
    extra >= pot_count_rad()
}

/// One count of the gear potentiometer, rad (its span over its counts).
fn pot_count_rad() -> f64 {
    (f64::from(model::sensors::POT_SPAN_DEG) / f64::from(model::sensors::POT_COUNTS)).to_radians()
}

struct Run {
    peak_ratio: f64,
    /// The largest compliance estimate relative to the configured one.
    ratio: f64,
    /// Ticks from the command to each latched fault.
    faults: Vec<(FaultCode, i64)>,
}

fn run(sc: &Scenario) -> Run {
    let mut plant = plant_for(sc).unwrap();
    let mut servo = Servo::new(&sc.design, &sc.config, &sc.supervision).unwrap();
    servo.enable().unwrap();
    let sigma = allowable_stress_pa(&sc.design);
    let mut r = plant.readings();
    let mut peak = 0.0f64;
    let mut ratio = 0.0f64;
    let mut faults = vec![];
    for tick in 0..sc.settle_ticks + sc.run_ticks {
        if tick == sc.settle_ticks {
            let _ = servo.command(sc.command);
        }
        let out = servo.tick(&TickInput {
            link_encoder: r.link_encoder,
            gear_pot: Some(r.gear_pot),
            current_adc: r.current_adc,
            supply_adc: Some(r.supply_adc),
            read_error: None,
        });
        let latched = servo.faults();
        for code in FaultCode::ALL {
            if latched.contains(code) && !faults.iter().any(|(c, _)| *c == code) {
                faults.push((code, i64::from(tick) - i64::from(sc.settle_ticks)));
            }
        }
        r = plant.step_tick_cmd(bridge_command(out.bridge));
        if let Some(q) = servo.supervisor().clutch_ratio_q16() {
            ratio = ratio.max(q as f64 / 65536.0);
        }
        peak = peak.max(f64::from(plant.state().beam_stress_pa).abs() / sigma);
    }
    Run {
        peak_ratio: peak,
        ratio,
        faults,
    }
}

/// Moves and sines up to the torque limit on a clutch up to 1 mm longer than configured.
/// The clutch tolerance is the board's unconfirmed one. With `monitor` the clutch monitor runs
/// (`clutch-mismatch` possible); without it only the tolerance's weak capacity protects the
/// beams. Returns the
/// labels of the runs that latched `clutch-mismatch`, and asserts that no run bends the
/// beams beyond σ_allow and none with the right clutch latches `clutch-mismatch`.
fn wrong_clutch_grid(monitor: bool) -> Vec<String> {
    let mut worst = 0.0f64;
    let mut caught = vec![];
    let mut over: Vec<String> = vec![];
    let mut false_trips: Vec<String> = vec![];
    let mut missed: Vec<String> = vec![];
    // Every whole clutch length of the paper's beams, and the beams no longer than they are.
    let beam_mm = host_tests::oracle::Design::paper().l * 1e3;
    for l in 1..=8 {
        for delta_um in [0, 250, 500, 1000] {
            let actual_mm = f64::from(l) + f64::from(delta_um) * 1e-3;
            if actual_mm > beam_mm + 1e-9 {
                continue;
            }
            for (name, cmd, load) in [
                ("0.5 rad in 60 ms", sim::min_jerk("0.5", 60), -0.3f32),
                ("raw step 1 rad", sim::raw_step("1"), -0.3),
                ("sine 0.3 rad 3 Hz", sim::sine("0.3", 3), -0.3),
                (
                    "heavy load, 1 rad in 100 ms",
                    sim::min_jerk("1", 100),
                    -(0.5 * capacity_nm(l)).min(0.5) as f32,
                ),
                (
                    MOTIONS[4],
                    sim::min_jerk("0.5", 200),
                    // τ_cap ∝ 1/L: the capacity of the longest clutch the tolerance
                    // allows; at most 0.8 N·m (what the motor holds while it moves the
                    // link 0.5 rad in 200 ms at 1 and 2 mm).
                    -(0.7 * capacity_nm(l) * f64::from(l) / (f64::from(l) + TOLERANCE_MM)).min(0.8)
                        as f32,
                ),
            ] {
                let mut sc = sim::scenario(l, cmd, load);
                sc.config.limits.clutch_tolerance = length_from_um(UNCONFIRMED_TOLERANCE_UM);
                sc.supervision.clutch_monitor = monitor;
                sc.plant
                    .set(Override::parse(&format!("clutch={actual_mm}mm")).unwrap());
                let out = run(&sc);
                let label = format!("L {l} mm, actual {actual_mm} mm, {name}");
                let label = if monitor {
                    label
                } else {
                    format!("{label} (monitor off)")
                };
                let mismatch = out
                    .faults
                    .iter()
                    .find(|(c, _)| *c == FaultCode::ClutchMismatch);
                println!(
                    "{label}: peak {:.3} σ_allow, compliance up to {:.2}×, faults {:?}",
                    out.peak_ratio, out.ratio, out.faults
                );
                if out.peak_ratio > 1.0 {
                    over.push(format!("{label}: {:.3}", out.peak_ratio));
                }
                if delta_um == 0 && mismatch.is_some() {
                    false_trips.push(label.clone());
                }
                let within_1_s = mismatch.is_some_and(|(_, t)| *t <= 1000);
                if monitor && resolvable(f64::from(l), actual_mm, f64::from(load)) && !within_1_s {
                    missed.push(label.clone());
                }
                if let Some((_, t)) = mismatch {
                    caught.push(label.clone());
                    // Within 1 s where the pot resolves the deflection (1 mm, below);
                    // half a millimetre is caught late if at all (docs/calibration.md).
                    assert!(
                        delta_um < 1000 || *t <= 1000,
                        "{label}: mismatch after {t} ms"
                    );
                }
                worst = worst.max(out.peak_ratio);
            }
        }
    }
    println!(
        "worst peak stress {worst:.3} σ_allow; clutch-mismatch caught in: {caught:#?}; \
         over σ_allow: {over:#?}; false mismatch: {false_trips:#?}; resolvable, not caught \
         within 1 s: {missed:#?}"
    );
    assert!(
        missed.is_empty(),
        "resolvable wrong clutch not caught within 1 s: {missed:?}"
    );
    assert!(
        false_trips.is_empty(),
        "clutch-mismatch with the right clutch"
    );
    // With the controller's torque limit on the weak capacity (the clutch tolerance) no
    // case bends the beams beyond σ_allow; before, 4 mm set at 5 mm under a 3 Hz sine
    // reached 1.10 σ_allow (docs/calibration.md).
    assert!(over.is_empty(), "cases beyond σ_allow: {over:?}");
    caught
}

#[test]
fn a_longer_clutch_never_overloads_the_beams() {
    assert!(wrong_clutch_grid(false).is_empty());
}

#[test]
fn the_monitor_catches_a_longer_clutch_where_resolvable() {
    let caught = wrong_clutch_grid(true);
    // Where the pot resolves the deflection (the paper's beams at 5 mm), a clutch 1 mm
    // too long is caught in every motion. 0.5 mm (compliance 1.33×, just beyond 1.25×)
    // only under the heavy load (printed above): with 0.3 N·m the still hold reads the
    // same pot count at 5 and 5.5 mm, and the monitor decides on its estimate's lower
    // bound, the pot's half-count quantisation taken against it.
    for name in MOTIONS {
        let label = format!("L 5 mm, actual 6 mm, {name}");
        assert!(caught.contains(&label), "{label}: not caught");
    }
}

/// The monitor alone, fed the deflection of beams `softer` times as compliant as the
/// f64 oracle's at the configured length (paper eq. 4) under a slow sine of motor torque whose RMS deflects the beams 1.8 pot counts (the monitor's evidence
/// is one): its estimate relative to the configured compliance, and whether it latched a
/// mismatch.
fn monitor_on_beams(l_mm: i32, softer: f64) -> (f64, bool) {
    use model::clutch_monitor::{ClutchLimits, ClutchMonitor};
    use model::control::{Config, Output};
    let mut config = Config::paper(Length::from_int(l_mm));
    config.limits.clutch_tolerance = length_from_um(UNCONFIRMED_TOLERANCE_UM);
    let sched = model::control::Schedule::new(&model::Design::paper(), &config).unwrap();
    let lim = ClutchLimits::new(&sched);
    let free_play = sched.free_play().to_bits() as f64 / 2f64.powi(32);
    let k = host_tests::oracle::Design::paper().stiffness(f64::from(l_mm) * 1e-3);
    let amplitude = 2.5 * k * pot_count_rad();
    let mut monitor = ClutchMonitor::new();
    let mut latched = false;
    for tick in 0..2000 {
        let tau = amplitude * (f64::from(tick) * std::f64::consts::TAU / 400.0).sin();
        let phi = softer * tau / k + free_play * tau.signum();
        let out = Output {
            motor_torque_q16: (tau * 65536.0) as i32,
            ..Output::default()
        };
        latched |= monitor.update((phi * 2f64.powi(32)) as i64, &out, &lim);
    }
    let ratio = monitor.ratio_q16(&lim).map_or(0.0, |r| r as f64 / 65536.0);
    (ratio, latched)
}

#[test]
fn the_monitor_measures_the_configured_compliance_at_every_clutch_length() {
    // Beams as configured: the estimate within 3 % of 1, no mismatch; beams 1.6× as
    // compliant (a clutch 17 % longer): a mismatch. At 7 and 8 mm (k = 20.9 and
    // 14.0 N·m/rad) the configured compliance once saturated at 1/32 N·m/rad and the
    // right beams read 1.53× and 2.27× soft. From 3 mm: below, a pot count of
    // deflection takes more than the regression's 4 N·m bound (the monitor undecided).
    for l in 3..=8 {
        let (ratio, latched) = monitor_on_beams(l, 1.0);
        println!("L {l} mm, configured beams: estimate {ratio:.4}×, mismatch {latched}");
        assert!((ratio - 1.0).abs() < 0.03, "L {l} mm: {ratio}");
        assert!(!latched, "L {l} mm: false mismatch");
        let (ratio, latched) = monitor_on_beams(l, 1.6);
        println!("L {l} mm, beams 1.6× as compliant: estimate {ratio:.4}×, mismatch {latched}");
        assert!((ratio - 1.6).abs() < 0.05, "L {l} mm: {ratio}");
        assert!(latched, "L {l} mm: softer beams not flagged");
    }
}
