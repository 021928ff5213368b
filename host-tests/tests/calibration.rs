//! The calibration sequence (`model::calibration::sequence`) against simulated builds:
//! seeded random healthy builds (every unknown of a real build drawn within the ranges of
//! docs/calibration.md) and broken ones. The sequence sees only the raw readings, as the
//! sensor drivers deliver them; the test compares what it found with the plant's true
//! parameters.
//!
//! `CALIBRATION_BUILDS=500 cargo test -p host-tests --release --test calibration` runs more
//! builds (default 50).

use host_tests::calibrate::{calibrate, healthy_build};
use model::calibration::sequence::{Calibration, Failure, Progress};
use model::control::Config;
use model::servo::TickInput;
use model::{Design, Length};
use plant::harness::{allowable_stress_pa, plant_config};
use plant::{BridgeCommand, Plant, PlantConfig, SensorFault, XorShift32};

/// Longest run, ticks (the sequence takes about 5 s).
const MAX_TICKS: u32 = 20_000;

struct Outcome {
    progress: Progress,
    cal: Calibration,
    ticks: u32,
    peak_stress_ratio: f64,
    off_at_end: bool,
}

fn run(plant: &mut Plant, design: &Design) -> Outcome {
    let sigma = allowable_stress_pa(design);
    let mut peak = 0.0f64;
    let r = calibrate(plant, design, MAX_TICKS, |p| {
        peak = peak.max(f64::from(p.state().beam_stress_pa).abs() / sigma);
    });
    Outcome {
        progress: r.cal.progress(),
        cal: r.cal,
        ticks: r.ticks,
        peak_stress_ratio: peak,
        off_at_end: r.last_duty.is_none(),
    }
}

#[test]
fn calibration_finds_every_healthy_build() {
    let builds = host_tests::env_or("CALIBRATION_BUILDS", 50);
    let design = Design::paper();
    let mut rng = XorShift32::new(0x00C0_FFEE);
    let (mut worst_r, mut worst_ke, mut worst_j, mut worst_off, mut worst_gain) =
        (0.0f64, 0.0f64, 0.0f64, 0.0f64, 0.0f64);
    let mut worst_stress = 0.0f64;
    // The link's share alone (total − the datasheet gear's), against the true link inertia
    // and against the one the sense sees (× gain): reported, not within 10 % (module docs
    // of the sequence and docs/calibration.md say why).
    let (mut worst_link, mut worst_link_seen) = ((0.0f64, 0.0f64), (0.0f64, 0.0f64));
    let mut longest = 0;
    for b in 0..builds {
        let (pc, _, text) = healthy_build(&mut rng, &design);
        let mut plant = Plant::new(pc);
        let out = run(&mut plant, &design);
        assert_eq!(out.progress, Progress::Done, "build {b}: {text}");
        let res = *out.cal.result().unwrap();
        let c = res.correction;
        let enc = pc.sensors.encoder_direction;
        // Signs relative to the encoder, the reference (module docs of the sequence).
        assert_eq!(
            f64::from(c.motor_polarity.value()),
            f64::from(pc.motor.polarity * enc),
            "build {b} motor polarity: {text}"
        );
        assert_eq!(
            f64::from(c.pot_direction.value()),
            f64::from(pc.sensors.pot_direction * enc),
            "build {b} pot direction: {text}"
        );
        // Current offset, counts.
        let off = f64::from(c.current_offset_q16) / 65536.0 - 2048.0;
        let off_err = (off - f64::from(pc.sensors.current_offset_counts)).abs();
        assert!(off_err <= 2.0, "build {b} current offset {off:.2}: {text}");
        // Pot gain.
        let gain = f64::from(c.pot_gain_q16) / 65536.0;
        let gain_err = (gain / f64::from(pc.sensors.pot_gain) - 1.0).abs();
        assert!(gain_err <= 0.03, "build {b} pot gain {gain:.4}: {text}");
        // R as the current sense sees it (R / gain) and k_e, within 5 %.
        let g = f64::from(pc.sensors.current_gain);
        let r_true = f64::from(pc.motor.resistance_ohm) / g;
        let r_err = (f64::from(res.resistance_mohm) * 1e-3 / r_true - 1.0).abs();
        assert!(
            r_err <= 0.05,
            "build {b} R {} mΩ vs {r_true:.3}: {text}",
            res.resistance_mohm
        );
        let ke_true = f64::from(pc.motor.back_emf_v_s_per_rad);
        let ke_err = (f64::from(res.back_emf_uv_s_per_rad) * 1e-6 / ke_true - 1.0).abs();
        assert!(
            ke_err <= 0.05,
            "build {b} k_e {}: {text}",
            res.back_emf_uv_s_per_rad
        );
        // Total inertia as the sense sees it: the momentum k_t·∫i is read through the
        // sense's gain, so it comes out × gain (docs/calibration.md). The link's share
        // (total − the datasheet gear's 3.2e-3) is not within 10 % of a 0.3e-3 link:
        // checked on the total, within 10 %.
        let jg = f64::from(pc.motor.inertia_kg_m2);
        let j_seen = g * (f64::from(pc.link.inertia_kg_m2) + jg);
        let j_found = res.link_inertia_nano as f64 * 1e-9 + jg;
        let j_err = (j_found / j_seen - 1.0).abs();
        assert!(
            j_err <= 0.10,
            "build {b} J_total {j_found:.4e} vs {j_seen:.4e}: {text}"
        );
        assert!(out.peak_stress_ratio < 1.0, "build {b}: {text}");
        let jl = f64::from(pc.link.inertia_kg_m2);
        let jl_found = res.link_inertia_nano as f64 * 1e-9;
        let e = (jl_found / jl - 1.0).abs();
        if e > worst_link.0 {
            worst_link = (e, jl);
        }
        let e = (jl_found / (g * jl) - 1.0).abs();
        if e > worst_link_seen.0 {
            worst_link_seen = (e, jl);
        }
        worst_r = worst_r.max(r_err);
        worst_ke = worst_ke.max(ke_err);
        worst_j = worst_j.max(j_err);
        worst_off = worst_off.max(off_err);
        worst_gain = worst_gain.max(gain_err);
        worst_stress = worst_stress.max(out.peak_stress_ratio);
        longest = longest.max(out.ticks);
    }
    println!(
        "{builds} builds: worst current offset {worst_off:.2} counts, pot gain {:.2} %, R {:.2} %, k_e {:.2} %, J_total {:.2} %, peak stress {:.3} σ_allow, longest {longest} ticks",
        worst_gain * 100.0,
        worst_r * 100.0,
        worst_ke * 100.0,
        worst_j * 100.0,
        worst_stress
    );
    println!(
        "link inertia alone: worst {:.1} % (link {:.2e} kg·m²), as the sense sees it (× gain) {:.1} % (link {:.2e} kg·m²)",
        worst_link.0 * 100.0,
        worst_link.1,
        worst_link_seen.0 * 100.0,
        worst_link_seen.1
    );
}

/// A heavy link on a clutch much stiffer than configured is thrown back against the gear
/// after each move, so most moves start with the gear against the link: their start
/// current, extrapolated as if the gear crossed the free play alone, reads R high. Build 432
/// of the long run (L 1.51 mm configured, 1.05 mm actual, 4.35e-3 kg·m²) gave R 6.9 % high
/// until the sequence took R from the moves whose current fell over the first three ticks;
/// build 1 320 (1.83 → 1.38 mm, 4.66e-3 kg·m²) gave 5.3 % until it left out the highest
/// of the moves' R (the error is one-sided).
#[test]
fn a_gear_that_starts_against_a_heavy_link_still_gives_r() {
    let design = Design::paper();
    let mut rng = XorShift32::new(0x00C0_FFEE);
    for b in 0..=1320 {
        let (pc, _, text) = healthy_build(&mut rng, &design);
        if b != 432 && b != 1320 {
            continue;
        }
        let mut plant = Plant::new(pc);
        let out = run(&mut plant, &design);
        assert_eq!(out.progress, Progress::Done, "{text}");
        let r = f64::from(out.cal.result().unwrap().resistance_mohm) * 1e-3;
        let r_seen = f64::from(pc.motor.resistance_ohm) / f64::from(pc.sensors.current_gain);
        println!("build {b}, {text}: R {r:.3} Ω against {r_seen:.3} as the sense sees it");
        assert!(
            (r / r_seen - 1.0).abs() <= 0.05,
            "build {b}, {text}: R {r:.3} vs {r_seen:.3}"
        );
    }
}

fn nominal_plant() -> (Design, PlantConfig) {
    let design = Design::paper();
    let config = Config::paper(Length::from_int(3));
    let mut pc = plant_config(&design, &config, 0.0).unwrap();
    pc.power_up_angle_rad = 0.4;
    pc.sensors.current_noise_counts = 1.0;
    pc.sensors.pot_noise_counts = 0.3;
    (design, pc)
}

#[test]
fn broken_builds_end_with_the_motor_off_and_the_right_message() {
    let (design, pc) = nominal_plant();
    type Break = fn(&mut PlantConfig, &mut Plant);
    let cases: [(&str, Break, Failure); 5] = [
        (
            "disconnected encoder",
            |_, p| p.faults_mut().link_encoder = SensorFault::Frozen,
            Failure::EncoderDead,
        ),
        (
            "pot stuck at a rail",
            |_, p| p.faults_mut().gear_pot = SensorFault::StuckAt(1023),
            Failure::PotRail,
        ),
        (
            "current sense at mid-scale",
            |_, p| p.faults_mut().current_adc = SensorFault::StuckAt(2048),
            Failure::CurrentDead,
        ),
        (
            "motor leads open",
            |c, _| c.motor.resistance_ohm = 1000.0,
            Failure::MotorOpen,
        ),
        (
            "gear jammed",
            |c, _| c.gear_locked = true,
            Failure::MotorBlocked,
        ),
    ];
    for (what, brk, want) in cases {
        let mut cfg = pc;
        let mut scratch = Plant::new(cfg);
        brk(&mut cfg, &mut scratch);
        let mut plant = Plant::new(cfg);
        *plant.faults_mut() = *scratch.faults_mut();
        let out = run(&mut plant, &design);
        assert_eq!(out.progress, Progress::Failed(want), "{what}");
        assert!(out.off_at_end, "{what}: motor off");
        println!(
            "{what}: {} after {} ticks: {}",
            want.name(),
            out.ticks,
            want.message()
        );
        assert!(out.peak_stress_ratio < 1.0);
    }
}

/// After calibration the correction makes a miswired build behave like the nominal one:
/// every sign reversed, offsets and gains off, the link anywhere at power-up; the servo
/// (configured nominally) runs on the corrected readings and the bridge gets the corrected
/// duty. A 0.5 rad minimum-jerk move then meets the closed-loop limits of
/// `closed_loop.rs` (overshoot ≤ 5 %, settled within ±1 count, beams below σ_allow).
#[test]
fn a_calibrated_miswired_build_moves_like_the_nominal_one() {
    use model::calibration::correction::Corrector;
    use model::servo::{BridgeDemand, Servo};
    use model::supervisor::SupervisorConfig;
    let design = Design::paper();
    let config = Config::paper(Length::from_int(3));
    let mut pc = plant_config(&design, &config, 0.0).unwrap();
    pc.motor.polarity = -1.0;
    pc.sensors.pot_direction = -1.0;
    pc.sensors.pot_center_counts = 530.0;
    pc.sensors.pot_gain = 1.06;
    pc.sensors.current_offset_counts = -250.0;
    pc.sensors.current_gain = 1.0;
    pc.sensors.encoder_zero_counts = 3000;
    pc.sensors.pot_noise_counts = 0.3;
    pc.sensors.current_noise_counts = 1.0;
    pc.power_up_angle_rad = 0.8;
    let mut plant = Plant::new(pc);
    let out = run(&mut plant, &design);
    assert_eq!(out.progress, Progress::Done);
    let mut correction = out.cal.result().unwrap().correction;
    // The pot's centre is the absolute zero: this build's pot reads 530 there.
    correction.pot_center_q16 = 530 << 16;
    let mut corrector = Corrector::new(&correction).unwrap();
    // Power-up again somewhere else (the calibration left the link near the middle).
    // With the closed-loop tests' 0.3 N·m load (a free link limit-cycles in the free
    // play, docs/design.md §9).
    let mut loaded = PlantConfig {
        power_up_angle_rad: -0.6,
        ..pc
    };
    loaded.load.constant_nm = -0.3;
    let mut plant = Plant::new(loaded);
    // Hanging on the beams at power-up (as `plant::harness::plant_for` preloads).
    let c = loaded.coupling;
    let phi = c.free_play_rad + 0.3 / c.stiffness_nm_per_rad;
    plant.set_state(-0.6 + f64::from(phi), 0.0, -0.6, 0.0);
    let mut servo = Servo::new(&design, &config, &SupervisorConfig::DEFAULT).unwrap();
    let sigma = allowable_stress_pa(&design);
    let (mut peak, mut ticks_on, mut max_angle) = (0.0f64, 0, f64::MIN);
    // The servo's frame is the pot's (aligned at power-up): the move is checked relative
    // to the true angle when it starts, to the link's ±1 count plus the hold's ±1.
    let mut target = f64::NAN;
    let mut last_far = 0;
    let band = std::f64::consts::TAU / 4096.0 * 2.0;
    for tick in 0..3000 {
        let r = plant.readings();
        let raw = TickInput {
            link_encoder: r.link_encoder,
            gear_pot: Some(r.gear_pot),
            current_adc: r.current_adc,
            supply_adc: Some(r.supply_adc),
            read_error: None,
        };
        let Some(input) = corrector.input(&raw) else {
            plant.step_tick_cmd(BridgeCommand::Coast);
            continue;
        };
        if ticks_on == 0 {
            servo.enable().unwrap();
        }
        if ticks_on == 300 {
            // The servo's frame is the pot's, aligned within the free play: the move is
            // relative, from where the link is held.
            target = plant.state().link_angle_rad + 0.5;
            let at = servo.controller().trajectory().target();
            servo
                .command(model::Command::Move {
                    target: model::Angle::from_bits(at.to_bits() + (1i64 << 31)),
                    duration_ms: 300,
                })
                .unwrap();
        }
        ticks_on += 1;
        let o = servo.tick(&input);
        assert!(o.new_fault.is_none(), "tick {tick}: {:?}", o.new_fault);
        let cmd = match o.bridge {
            BridgeDemand::Drive(d) => BridgeCommand::Drive(corrector.duty(d)),
            BridgeDemand::Off => BridgeCommand::Coast,
            BridgeDemand::Brake => BridgeCommand::Brake,
        };
        plant.step_tick_cmd(cmd);
        let st = plant.state();
        peak = peak.max(f64::from(st.beam_stress_pa).abs() / sigma);
        if ticks_on > 300 {
            max_angle = max_angle.max(st.link_angle_rad);
            if (st.link_angle_rad - target).abs() > band {
                last_far = ticks_on;
            }
        }
    }
    let overshoot = (max_angle - target).max(0.0) / 0.5 * 100.0;
    let end = plant.state().link_angle_rad;
    println!(
        "after calibration: link {end:.4} rad (target {target:.4}), overshoot {overshoot:.2} %, settled {} ms after the command, peak {peak:.3} σ_allow",
        last_far - 300
    );
    assert!(overshoot <= 5.0);
    assert!((end - target).abs() <= band);
    assert!(peak < 1.0);
}
