//! Sensors: quantisation, clamping, wrap, noise determinism, fault hooks.

use plant::{
    CouplingConfig, Plant, PlantConfig, SensorConfig, SensorFault, SensorReadings, XorShift32,
    POT_COUNTS_PER_RAD,
};
use std::f64::consts::PI;

fn plant_with(sensors: SensorConfig) -> Plant {
    Plant::new(PlantConfig {
        sensors,
        coupling: CouplingConfig::linear(0.0),
        gear_locked: true,
        link_locked: true,
        ..PlantConfig::default()
    })
}

fn read_at(p: &mut Plant, gear: f64, link: f64) -> SensorReadings {
    p.set_state(gear, 0.0, link, 0.0);
    p.readings()
}

#[test]
fn pot_quantisation_and_clamping() {
    let mut p = plant_with(SensorConfig::default());
    let deg = PI / 180.0;
    assert_eq!(read_at(&mut p, 0.0, 0.0).gear_pot, 512);
    // 0.293° per count; rounds to nearest.
    let lsb = 1.0 / f64::from(POT_COUNTS_PER_RAD);
    assert!((lsb / deg - 300.0 / 1024.0).abs() < 1e-6);
    assert_eq!(read_at(&mut p, 0.49 * lsb, 0.0).gear_pot, 512);
    assert_eq!(read_at(&mut p, 0.51 * lsb, 0.0).gear_pot, 513);
    assert_eq!(read_at(&mut p, -0.51 * lsb, 0.0).gear_pot, 511);
    assert_eq!(read_at(&mut p, 10.0 * lsb, 0.0).gear_pot, 522);
    // 300° span: 0 at −150°, 1023 at +150° − 1 count, clamped beyond.
    assert_eq!(read_at(&mut p, -150.0 * deg, 0.0).gear_pot, 0);
    assert_eq!(read_at(&mut p, 149.8 * deg, 0.0).gear_pot, 1023);
    assert_eq!(read_at(&mut p, 200.0 * deg, 0.0).gear_pot, 1023);
    assert_eq!(read_at(&mut p, -200.0 * deg, 0.0).gear_pot, 0);
    assert_eq!(read_at(&mut p, 1.0e9, 0.0).gear_pot, 1023);
    assert_eq!(read_at(&mut p, -1.0e9, 0.0).gear_pot, 0);
    // A NaN angle (never produced by the plant) reads as some in-range value, no panic.
    assert!(read_at(&mut p, f64::NAN, f64::NAN).gear_pot <= 1023);
}

#[test]
fn encoder_quantisation_and_wrap() {
    let mut p = plant_with(SensorConfig::default());
    let lsb = 2.0 * PI / 4096.0;
    assert_eq!(read_at(&mut p, 0.0, 0.0).link_encoder, 0);
    assert_eq!(read_at(&mut p, 0.0, 0.99 * lsb).link_encoder, 0);
    assert_eq!(read_at(&mut p, 0.0, 1.01 * lsb).link_encoder, 1);
    assert_eq!(read_at(&mut p, 0.0, -0.5 * lsb).link_encoder, 4095);
    assert_eq!(read_at(&mut p, 0.0, PI).link_encoder, 2048);
    assert_eq!(read_at(&mut p, 0.0, 2.0 * PI + 5.5 * lsb).link_encoder, 5);
    assert_eq!(read_at(&mut p, 0.0, -6.0 * PI + 5.5 * lsb).link_encoder, 5);
    assert_eq!(
        read_at(&mut p, 0.0, 1000.0 * 2.0 * PI + 7.5 * lsb).link_encoder,
        7
    );
    // Mounting offset.
    let mut q = plant_with(SensorConfig {
        encoder_zero_counts: 4000,
        ..SensorConfig::default()
    });
    assert_eq!(read_at(&mut q, 0.0, 0.0).link_encoder, 4000);
    assert_eq!(read_at(&mut q, 0.0, 100.5 * lsb).link_encoder, 4);
}

#[test]
fn encoder_follows_slow_rotation_at_large_angles() {
    // f64 angle accumulation: 0.05 rad/s for 10 s starting at 1000 rad stays exact to
    // well under one count.
    let cfg = PlantConfig {
        coupling: CouplingConfig::linear(0.0),
        gear_locked: true,
        link: plant::LinkConfig {
            viscous_nm_s_per_rad: 0.0,
            ..plant::LinkConfig::default()
        },
        ..PlantConfig::default()
    };
    let mut p = Plant::new(cfg);
    p.set_state(0.0, 0.0, 1000.0, 0.05);
    for _ in 0..10_000 {
        p.step_tick(0);
    }
    let err = p.state().link_angle_rad - 1000.5;
    println!("link angle error after 10 s at 0.05 rad/s from 1000 rad: {err:.3e} rad");
    assert!(err.abs() < 1e-5);
}

#[test]
fn current_adc_scale_offset_and_clamp() {
    let mut cfg = PlantConfig {
        coupling: CouplingConfig::linear(0.0),
        gear_locked: true,
        ..PlantConfig::default()
    };
    let mut p = Plant::new(cfg);
    assert_eq!(p.readings().current_adc, 2048);
    assert_eq!(p.step_tick(1000).current_adc, 2048 + 1536); // 1.5 A
    assert_eq!(p.step_tick(-1000).current_adc, 2048 - 1536);
    assert_eq!(p.step_tick(100).current_adc, 2048 + 154); // 0.15 A → 153.6
                                                          // 24 V supply: 3 A stall, clamps at the rails.
    cfg.motor.supply_voltage_v = 24.0;
    let mut hot = Plant::new(cfg);
    assert_eq!(hot.step_tick(1000).current_adc, 4095);
    assert_eq!(hot.step_tick(-1000).current_adc, 0);
    // Offset error.
    cfg.motor.supply_voltage_v = 12.0;
    cfg.sensors.current_offset_counts = -37.0;
    let mut off = Plant::new(cfg);
    assert_eq!(off.readings().current_adc, 2011);
    assert_eq!(off.step_tick(1000).current_adc, 2048 + 1536 - 37);
}

#[test]
fn noise_is_deterministic_and_has_the_configured_spread() {
    let sensors = SensorConfig {
        current_noise_counts: 3.0,
        noise_seed: 12345,
        ..SensorConfig::default()
    };
    let run = |seed: u32| {
        let mut p = plant_with(SensorConfig {
            noise_seed: seed,
            ..sensors
        });
        (0..5000)
            .map(|_| p.step_tick(0).current_adc)
            .collect::<Vec<u16>>()
    };
    let a = run(12345);
    let b = run(12345);
    let c = run(54321);
    assert_eq!(a, b, "same seed, same sequence");
    assert_ne!(a, c, "different seed, different sequence");
    let n = a.len() as f64;
    let mean = a.iter().map(|&x| f64::from(x)).sum::<f64>() / n;
    let var = a
        .iter()
        .map(|&x| (f64::from(x) - mean).powi(2))
        .sum::<f64>()
        / n;
    println!(
        "noise σ = 3 counts: mean {mean:.3}, std {:.3} counts",
        var.sqrt()
    );
    assert!((mean - 2048.0).abs() < 0.2);
    // Rounding adds 1/12 count² of variance.
    assert!((var.sqrt() - (9.0f64 + 1.0 / 12.0).sqrt()).abs() < 0.15);
    // Noise off: no spread at all.
    let mut quiet = plant_with(SensorConfig::default());
    assert!((0..100).all(|_| quiet.step_tick(0).current_adc == 2048));
}

#[test]
fn xorshift_reference_sequence() {
    // Marsaglia's xorshift32 (13, 17, 5) from seed 1.
    let mut r = XorShift32::new(1);
    assert_eq!(r.next_u32(), 270_369);
    assert_eq!(r.next_u32(), 67_634_689);
    assert_eq!(r.next_u32(), 2_647_435_461);
    let mut z = XorShift32::new(0);
    assert_ne!(z.next_u32(), 0);
    let mut u = XorShift32::new(7);
    for _ in 0..1000 {
        let x = u.next_unit();
        assert!((0.0..1.0).contains(&x));
        let g = u.next_gaussian();
        assert!(g.abs() <= 3.47);
    }
}

#[test]
fn fault_hooks() {
    let cfg = PlantConfig {
        coupling: CouplingConfig::linear(0.0),
        gear_locked: true,
        ..PlantConfig::default()
    };
    let mut p = Plant::new(cfg);
    p.set_state(0.1, 0.0, 0.2, 0.0);
    let healthy = p.step_tick(500);
    // Saturated ADC, stuck pot, encoder jump.
    p.faults_mut().current_adc = SensorFault::StuckAt(4095);
    p.faults_mut().gear_pot = SensorFault::StuckAt(9999);
    p.faults_mut().link_encoder = SensorFault::Offset(-200);
    let r = p.step_tick(500);
    assert_eq!(r.current_adc, 4095);
    assert_eq!(r.gear_pot, 1023, "stuck value clamped to the pot range");
    assert_eq!(
        i32::from(r.link_encoder),
        (i32::from(healthy.link_encoder) - 200).rem_euclid(4096)
    );
    // Frozen: repeats the last reading whatever happens.
    p.faults_mut().current_adc = SensorFault::Frozen;
    p.faults_mut().gear_pot = SensorFault::None;
    let r2 = p.step_tick(-1000);
    assert_eq!(r2.current_adc, 4095);
    assert_eq!(r2.gear_pot, healthy.gear_pot);
    // Offset on a clamped channel clamps.
    p.faults_mut().current_adc = SensorFault::Offset(-5000);
    assert_eq!(p.step_tick(0).current_adc, 0);
    // Back to healthy.
    *p.faults_mut() = Default::default();
    assert_eq!(p.step_tick(500), healthy);
}

#[test]
fn a_real_build_reads_reversed_offset_and_scaled() {
    use plant::overrides::Overrides;
    let o = Overrides::parse_all([
        "encoder-direction=-1",
        "encoder-counts=4000",
        "encoder-zero=17",
        "pot-direction=-1",
        "pot-gain=1.1",
        "motor-polarity=-1",
        "power-up-angle=0.5rad",
    ])
    .unwrap();
    let pc = o.apply(&PlantConfig {
        coupling: CouplingConfig::linear(0.0),
        gear_locked: true,
        ..PlantConfig::default()
    });
    let mut p = Plant::new(pc);
    // Incremental encoder: its power-up value wherever the link is.
    assert_eq!(p.readings().link_encoder, 17);
    // The pot is absolute: 0.5 rad at −1.1 × 195.57 counts/rad below the centre.
    let want = (512.0 - 0.5 * 1.1 * f64::from(plant::POT_COUNTS_PER_RAD)).round() as u16;
    assert_eq!(p.readings().gear_pot, want);
    // The link turns −0.1 rad: a reversed 4000-count encoder counts up 63.66 → 63 (floor).
    p.set_state(0.5, 0.0, 0.4, 0.0);
    assert_eq!(p.readings().link_encoder, 17 + 63);
    // Swapped motor leads: a positive duty drives the (locked) gear negative, and the
    // bridge's sense still reads a positive current.
    let r = p.step_tick(1000);
    assert_eq!(p.state().motor_current_a, -1.5);
    assert_eq!(r.current_adc, 2048 + 1536);
}

#[test]
fn pot_noise_and_bow_are_seeded_and_bounded() {
    let run = |seed: u32| {
        let mut p = plant_with(SensorConfig {
            pot_noise_counts: 0.5,
            pot_nonlinearity_counts: 2.0,
            noise_seed: seed,
            ..SensorConfig::default()
        });
        (0..2000)
            .map(|_| p.step_tick(0).gear_pot)
            .collect::<Vec<u16>>()
    };
    let (a, b) = (run(7), run(7));
    assert_eq!(a, b, "same seed, same readings");
    // At gear angle 0 the bow is 0 (sin of half a turn): noise only, within ±3.46σ.
    assert!(
        a.iter().all(|&c| (510..=514).contains(&c)),
        "{:?}",
        &a[..20]
    );
    assert!(a.iter().any(|&c| c != 512), "the noise shows");
}

#[test]
fn supply_sense_scale_gain_and_clamp() {
    // 5 mV of supply a count: 12 V reads 2 400, 10.5 V 2 100, 12.6 V 2 520.
    let mut p = plant_with(SensorConfig::default());
    assert_eq!(read_at(&mut p, 0.0, 0.0).supply_adc, 2400);
    for (volts, counts) in [
        (10.5, 2100),
        (12.6, 2520),
        (11.1025, 2221),
        (0.0, 0),
        (30.0, 4095),
    ] {
        p.set_supply(volts);
        assert_eq!(read_at(&mut p, 0.0, 0.0).supply_adc, counts, "{volts} V");
    }
    // A divider 2 % high reads 12 V as 12.24 V.
    let mut p = plant_with(SensorConfig {
        supply_sense_gain: 1.02,
        ..SensorConfig::default()
    });
    assert_eq!(read_at(&mut p, 0.0, 0.0).supply_adc, 2448);
    // Its fault hook, as the other channels'.
    p.faults_mut().supply_adc = SensorFault::StuckAt(0);
    assert_eq!(read_at(&mut p, 0.0, 0.0).supply_adc, 0);
}
