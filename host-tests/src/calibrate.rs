//! The calibration sequence run against a simulated actuator the way a board runs it: the
//! plant's raw readings in, the bridge duty out, nothing else shared (the tests compare
//! what it found with the plant's parameters, which the sequence never reads).

use model::calibration::correction::Sign;
use model::calibration::sequence::{Calibration, CalibrationConfig, Progress};
use model::control::MotorParams;
use model::servo::TickInput;
use model::Design;
use plant::{BridgeCommand, Plant};

/// A run: the sequence as it ended, the ticks run and the last duty (`None`: motor off).
pub struct Run {
    /// The sequence (its progress and result).
    pub cal: Calibration,
    /// Ticks run.
    pub ticks: u32,
    /// The duty of the last tick.
    pub last_duty: Option<i16>,
}

/// Calibrates `plant` (a `design` actuator with the datasheet AX-12A motor and a 4096-count
/// encoder as the reference direction) for at most `max_ticks`; `on_tick` sees the plant
/// after each tick.
///
/// # Panics
/// The design's longest clutch setting cannot be built.
pub fn calibrate(
    plant: &mut Plant,
    design: &Design,
    max_ticks: u32,
    mut on_tick: impl FnMut(&Plant),
) -> Run {
    let cfg = CalibrationConfig::new(design, &MotorParams::AX12A, Sign::Plus, 4096)
        .expect("the design's longest setting");
    let mut cal = Calibration::new(&cfg);
    let (mut ticks, mut last_duty) = (0, None);
    while ticks < max_ticks {
        let r = plant.readings();
        last_duty = cal.step(&TickInput {
            link_encoder: r.link_encoder,
            gear_pot: Some(r.gear_pot),
            current_adc: r.current_adc,
            read_error: None,
        });
        plant.step_tick_cmd(last_duty.map_or(BridgeCommand::Coast, BridgeCommand::Drive));
        on_tick(plant);
        ticks += 1;
        if !matches!(cal.progress(), Progress::Running { .. }) {
            break;
        }
    }
    Run {
        cal,
        ticks,
        last_duty,
    }
}
