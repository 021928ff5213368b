//! The sensor-correction layer in the closed loop on the host: an incremental encoder of
//! another resolution and direction, powered up away from the pot's centre, works once
//! the correction is configured with its counts per turn and direction (what the stored
//! calibration gives the board), and does not with the nominal correction.

use model::calibration::correction::{SensorCorrection, Sign};
use model::control::{Command, Config};
use model::{Angle, Length};
use plant::harness::{run, Metrics, Scenario};
use plant::overrides::Overrides;

fn step(correction: SensorCorrection, plant: &[&str]) -> Metrics {
    let mut sc = Scenario::new(
        Config::paper(Length::from_int(3)),
        Command::Step {
            target: Angle::from_micro(1_100_000).unwrap(),
        },
    );
    // The step sweep's 0.3 N·m load keeps the beams in contact (without it the link
    // rattles in the free play, whatever the encoder).
    sc.load_nm = 0.3;
    sc.plant = Overrides::parse_all(plant.iter().copied()).unwrap();
    sc.correction = correction;
    run(&sc, |_| {}).unwrap()
}

#[test]
fn counts_per_turn_and_direction_come_from_the_configuration() {
    // 1000 counts per turn counting down, link powered up at +0.8 rad with the encoder at 0.
    let build = [
        "encoder-counts=1000",
        "encoder-direction=-1",
        "power-up-angle=0.8rad",
    ];
    let configured = SensorCorrection {
        encoder_counts_per_turn: 1000,
        encoder_direction: Sign::Minus,
        ..SensorCorrection::NOMINAL
    };
    let m = step(configured, &build);
    println!("configured: {m:?}");
    assert!(m.faults.is_empty(), "{m:?}");
    // One raw count is 4.1 canonical counts: the servo holds within one.
    assert!(m.steady_state_error_counts <= 4.096, "{m:?}");
    assert!(m.overshoot_pct <= 10.0, "{m:?}");
    // The same build read as a 4096-count encoder counting up: the supervisor stops it.
    let m = step(SensorCorrection::NOMINAL, &build);
    println!("nominal correction: {:?}", m.first_fault);
    assert!(!m.faults.is_empty(), "{m:?}");
    // And the nominal build is unchanged with the nominal correction.
    let m = step(SensorCorrection::NOMINAL, &["power-up-angle=0.8rad"]);
    println!("nominal build: {m:?}");
    assert!(m.faults.is_empty(), "{m:?}");
    assert!(m.steady_state_error_counts <= 1.0, "{m:?}");
}
