//! The supervisor's deflection check sized from the pot's error as calibration measured it
//! (docs/calibration.md, "The pot's error table"). A simulated actuator whose pot has a
//! bow (`pot-nonlinearity`) and noise (`pot-noise`) is calibrated through its raw readings
//! only, as `calibration.rs` does (the table is never built from the plant's parameters);
//! the servo then runs 0.5 rad moves on that plant behind the correction calibration found,
//! once with the supervisor's fixed pot tolerance and once with the measured table, and a
//! load beyond the beams' capacity is applied with the table in force.
//!
//! `cargo test -p host-tests --release --test pot_error -- --nocapture` prints the figures.

use host_tests::calibrate::calibrate;
use model::calibration::pot_error::PotErrorTable;
use model::calibration::sequence::{CalibrationResult, Progress};
use model::control::Config;
use model::supervisor::{FaultCode, SupervisorConfig};
use model::{Angle, Command, Design, Length};
use plant::harness::{allowable_stress_pa, plant_config, run_script, Disturbance, Scenario};
use plant::overrides::Overrides;
use plant::Plant;

/// The simulated actuator: a pot with a bow of 8 counts over its track and 1.5 counts of
/// noise (the calibration accepts up to 2, docs/calibration.md), the link at −0.8 rad at
/// power-up (the encoder is aligned to the pot there).
const POT: &str = "pot-nonlinearity=8counts pot-noise=1.5counts power-up-angle=-0.8rad";
/// The power-up angle of `POT`, rad: the moves go ±0.5 rad from there.
const START_RAD: f64 = -0.8;
/// The load step of the overload runs, N·m: beyond τ_cap at both lengths (1.53 N·m at
/// 3 mm, 0.92 N·m at 5 mm, docs/design.md §3).
const PUSH_NM: f32 = 2.0;

/// Longest calibration run, ticks.
const MAX_TICKS: u32 = 20_000;

fn overrides() -> Overrides {
    Overrides::parse_all(POT.split(' ')).expect("overrides")
}

/// Calibrates the plant `overrides` make of the nominal one at `l_mm` through its raw
/// readings (the sequence and the plant meet only at the sensor and bridge interface).
fn calibrated(design: &Design, l_mm: i32) -> CalibrationResult {
    let config = Config::paper(Length::from_int(l_mm));
    let pc = overrides().apply(&plant_config(design, &config, 0.0).unwrap());
    let mut plant = Plant::new(pc);
    let run = calibrate(&mut plant, design, MAX_TICKS, |_| {});
    assert_eq!(run.cal.progress(), Progress::Done);
    *run.cal.result().unwrap()
}

/// What a run showed.
struct Outcome {
    first: Option<(FaultCode, u32)>,
    faults: model::supervisor::FaultSet,
    /// First tick the true beam stress exceeded σ_allow.
    over_tick: Option<u32>,
    peak_ratio: f64,
    peak_before_fault_ratio: f64,
}

/// The servo on the plant with `POT`, behind `cal`'s correction, supervised by
/// `supervision`: at L = `l_mm` with the closed-loop tests' 0.3 N·m load, hanging from
/// power-up, four 0.5 rad moves of 400 ms one second apart from the power-up angle (+0.5,
/// back, −0.5, back), and `push` N·m added on the link at the second move if given.
fn moves(
    design: &Design,
    l_mm: i32,
    cal: &CalibrationResult,
    supervision: SupervisorConfig,
    push: Option<f32>,
) -> Outcome {
    let config = Config::paper(Length::from_int(l_mm));
    let mv = |rad: f64| Command::Move {
        target: Angle::from_bits((rad * 4_294_967_296.0) as i64),
        duration_ms: 400,
    };
    let mv = |rad: f64| mv(rad + START_RAD);
    let mut sc = Scenario::new(config, mv(0.5));
    sc.design = *design;
    sc.load_nm = 0.3;
    sc.settle_ticks = 500;
    sc.run_ticks = 4000;
    sc.plant = overrides();
    sc.correction = cal.correction;
    sc.supervision = supervision;
    // The board powers up under the load: the encoder is aligned to the pot while the
    // link falls (docs/design.md §11, "The boot window before the hold").
    sc.boot_held = false;
    sc.disturbance = push.map(|torque_nm| Disturbance {
        after_command_ticks: 1000,
        torque_nm,
    });
    let script = |n: u32| match n {
        1000 => Some(mv(0.0)),
        2000 => Some(mv(-0.5)),
        3000 => Some(mv(0.0)),
        _ => None,
    };
    let sigma = allowable_stress_pa(design);
    let mut over_tick = None;
    let m = run_script(&sc, script, |s| {
        if over_tick.is_none() && f64::from(s.beam_stress_pa).abs() > sigma {
            over_tick = Some(s.tick);
        }
    })
    .expect("run");
    Outcome {
        first: m.first_fault.map(|f| (f.code, f.tick)),
        faults: m.faults,
        over_tick,
        peak_ratio: m.peak_stress_ratio,
        peak_before_fault_ratio: m.peak_stress_before_fault_pa / sigma,
    }
}

fn with_table(t: PotErrorTable) -> SupervisorConfig {
    SupervisorConfig {
        pot_error: Some(t),
        ..SupervisorConfig::DEFAULT
    }
}

#[test]
fn the_measured_table_stops_false_trips_and_keeps_real_overloads() {
    let design = Design::paper();
    for l_mm in [3, 5] {
        let cal = calibrated(&design, l_mm);
        let t = cal.pot_error;
        println!(
            "L = {l_mm} mm, {POT}: table (pot counts × 100) {:?}, RMS residual {} centi",
            t.centi, cal.pot_error_centi
        );
        assert!(t.is_valid());
        // Oracle of the size, from the plant's pot as specified (not from the plant): in the
        // bins the ±0.6 rad calibration moves cross (canonical 395..629, bins 6..9) the
        // entry is |reading − line| at most + the margin, where the reading's error is the
        // noise (at most 2√3·σ: the sum of four uniforms), the rounding (½ count) and the
        // bow's departure from the fitted line (below 0.1 of its amplitude within ±0.72 rad
        // of the track's phase), and the margin is 3 measured σ (σ ≤ 1.5 + ½ for the
        // rounding); at least the margin's floor, ½ count, and every entry at least the
        // smallest measured one (the unvisited bins).
        let sigma = 1.5;
        let most = 2.0 * 3f64.sqrt() * sigma + 0.5 + 0.1 * 8.0 + 3.0 * (sigma + 0.5);
        let least = t.centi[6..=9].iter().copied().min().unwrap();
        for (b, &e) in t.centi.iter().enumerate() {
            assert!(
                f64::from(e) / 100.0 <= most,
                "bin {b}: {e} > {most:.2} counts"
            );
            assert!(e >= 50 && e >= least, "bin {b}: {e}");
        }

        let fixed = moves(&design, l_mm, &cal, SupervisorConfig::DEFAULT, None);
        let table = moves(&design, l_mm, &cal, with_table(t), None);
        println!(
            "  0.5 rad moves: fixed tolerance → {:?} (peak stress {:.3} σ_allow); measured table → {:?} (peak stress {:.3} σ_allow)",
            fixed.first, fixed.peak_ratio, table.first, table.peak_ratio
        );
        // The deflection check trips (beam-overload, or sensor-stuck where the link count
        // happened not to change) while the beams carry less than σ_allow: a false trip.
        assert!(
            matches!(
                fixed.first,
                Some((FaultCode::BeamOverload | FaultCode::SensorStuck, _))
            ),
            "L = {l_mm} mm: the fixed tolerance should trip: {:?}",
            fixed.first
        );
        assert!(fixed.peak_before_fault_ratio < 1.0, "not a false trip");
        assert_eq!(
            table.first, None,
            "L = {l_mm} mm: false trip with the table"
        );
        assert!(table.peak_ratio < 1.0);

        // A real overload: PUSH_NM stepped onto the link. The step bends the beams beyond
        // σ_allow within a few ticks whatever the supervisor does (the link's inertia on
        // the beams); the table must latch beam-overload as the fixed tolerance does.
        let a = moves(
            &design,
            l_mm,
            &cal,
            SupervisorConfig::DEFAULT,
            Some(PUSH_NM),
        );
        let b = moves(&design, l_mm, &cal, with_table(t), Some(PUSH_NM));
        for (name, o) in [("fixed tolerance", &a), ("measured table", &b)] {
            println!(
                "  {PUSH_NM} N·m stepped on at tick 1500, {name}: first fault {:?}, true stress beyond σ_allow from tick {:?}, peak until the latch {:.3} σ_allow, overall {:.3}",
                o.first, o.over_tick, o.peak_before_fault_ratio, o.peak_ratio
            );
        }
        assert!(b.faults.contains(FaultCode::BeamOverload));
        let (fa, fb) = (a.first.unwrap(), b.first.unwrap());
        assert_eq!(fb.0, FaultCode::BeamOverload);
        assert!(
            fb.1 <= fa.1 + 1,
            "the table latches later: {fb:?} vs {fa:?}"
        );
    }
}
