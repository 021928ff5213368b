//! The calibration sequence run against a simulated actuator the way a board runs it: the
//! plant's raw readings in, the bridge duty out, nothing else shared (the tests compare
//! what it found with the plant's parameters, which the sequence never reads).

use model::calibration::correction::Sign;
use model::calibration::sequence::{Calibration, CalibrationConfig, Progress};
use model::control::Config;
use model::control::MotorParams;
use model::servo::TickInput;
use model::Design;
use model::Length;
use plant::harness::{coupling_at, plant_config};
use plant::overrides::{Override, Overrides, Param, Value};
use plant::{BridgeCommand, Plant, PlantConfig, XorShift32};

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
            supply_adc: Some(r.supply_adc),
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

/// A random healthy build, every unknown of a real build drawn within the ranges of
/// docs/calibration.md ("Measured"): the simulated actuator, the clutch length it is
/// configured with (µm; the actual one is within ±0.5 mm of it) and a description.
///
/// # Panics
/// The paper preset's clutch settings cannot be built (a bug).
#[must_use]
pub fn healthy_build(rng: &mut XorShift32, design: &Design) -> (PlantConfig, u32, String) {
    let mut u = |lo: f32, hi: f32| lo + (hi - lo) * rng.next_unit();
    let sign = |v: f32| if v < 0.5 { -1.0 } else { 1.0 };
    let l_cfg = u(1.5, 5.0);
    let config = Config::paper(Length::from_micro((l_cfg * 1e6) as i64).unwrap());
    let mut pc = plant_config(design, &config, 0.0).unwrap();
    let actual = (l_cfg + u(-0.5, 0.5)).clamp(1.0, 5.5);
    pc.coupling = coupling_at(design, &config, actual * 1e-3).unwrap();
    pc.clutch_length_m = actual * 1e-3;
    pc.motor.polarity = sign(u(0.0, 1.0));
    pc.sensors.encoder_direction = sign(u(0.0, 1.0));
    pc.sensors.pot_direction = sign(u(0.0, 1.0));
    pc.sensors.encoder_zero_counts = u(0.0, 4095.0) as u16;
    pc.sensors.current_offset_counts = u(-409.0, 409.0).round();
    pc.sensors.current_gain = u(0.9, 1.1);
    pc.sensors.pot_center_counts = 512.0 + u(-102.0, 102.0).round();
    pc.sensors.pot_gain = u(0.9, 1.1);
    pc.sensors.pot_nonlinearity_counts = u(-2.0, 2.0);
    pc.sensors.pot_noise_counts = u(0.2, 0.5);
    pc.sensors.current_noise_counts = u(0.5, 2.0);
    pc.sensors.noise_seed = u(1.0, 1e6) as u32;
    pc.motor.resistance_ohm *= u(0.85, 1.15);
    pc.motor.back_emf_v_s_per_rad *= u(0.85, 1.15);
    pc.motor.coulomb_nm *= u(0.85, 1.15);
    pc.link.inertia_kg_m2 = u(0.3e-3, 5e-3);
    pc.power_up_angle_rad = u(-1.2, 1.2);
    let text = format!(
        "L {l_cfg:.2}→{actual:.2} mm, pol {} enc {} pot {}, I off {} gain {:.3}, pot off {} gain {:.3}, R {:.2} ke {:.3} J_l {:.2e} at {:.2} rad",
        pc.motor.polarity,
        pc.sensors.encoder_direction,
        pc.sensors.pot_direction,
        pc.sensors.current_offset_counts,
        pc.sensors.current_gain,
        pc.sensors.pot_center_counts - 512.0,
        pc.sensors.pot_gain,
        pc.motor.resistance_ohm,
        pc.motor.back_emf_v_s_per_rad,
        pc.link.inertia_kg_m2,
        pc.power_up_angle_rad,
    );
    (pc, (l_cfg * 1000.0).round() as u32, text)
}

/// `pc` as overrides of any nominal actuator: every parameter an absolute value, so that
/// the harness builds the same actuator whatever the controller is configured with.
#[must_use]
pub fn overrides_of(pc: &PlantConfig) -> Overrides {
    let mut o = Overrides::NONE;
    for param in Param::ALL {
        o.set(Override {
            param,
            value: Value::Absolute(param.get(pc)),
        });
    }
    o
}
