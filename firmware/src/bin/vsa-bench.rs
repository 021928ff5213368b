//! `vsa-bench`: instruction counts of the control code on an emulated board.
//!
//! Run by `cargo xtask bench` under QEMU `-icount shift=N,sleep=off`: every instruction
//! advances virtual time by 2^N ns, and SysTick counts the core clock, so a SysTick
//! difference is `2^N·f_sysclk/10⁹` counts per instruction (QEMU has no cycle counter).
//! The firmware logs raw SysTick counts; the xtask converts them.
//!
//! # How a call is timed
//!
//! SysTick runs free (reload 2²⁴ − 1, no interrupt) while `init` runs the benchmarks with
//! interrupts masked. One measurement reads the counter, passes the input through
//! `core::hint::black_box` (so the call cannot be hoisted above the first reading or
//! constant-folded), makes the call, passes the result through `black_box` (so it cannot
//! sink below the second reading or be dropped) and reads the counter again. The same
//! measurement of an identity closure is the calibration, subtracted from every sample.
//!
//! # What is timed, over which inputs
//!
//! For each whole clutch length of the paper's beams, L = 1 … 8 mm, the servo (paper preset, default supervisor, the
//! clutch tolerance a board takes until a calibration confirms the clutch, so the clutch
//! monitor runs) runs 2000 ticks in closed loop with the simulated actuator (`plant`, 0.3 N·m load, as
//! in the step sweep; the plant is not timed): hold, a 0.5 rad raw step, a 200 ms
//! minimum-jerk move back, a 2 Hz sine. The f32 port runs the same script in its own
//! closed loop (a second plant), so each controller sees the sensors its own outputs
//! produce. Each tick times:
//!
//! * `control_step`: sensors read through the driver traits → the sensor-correction layer
//!   and `Servo::tick` (controller + supervisor; `model::calibration::pipeline`) → H-bridge
//!   driver (`drivers::tick_io`, as the firmware's tick); the plant
//!   excluded. `control_step_f32`: the same with the f32 port (`bench::float::FloatServo`).
//! * `control_step_unloaded`: `control_step` in the same script without load, a second
//!   pass (the other figures are the loaded pass's): the link floats in the free play at
//!   rest, where the catch of a floating link (`model::control::catch`) has the output.
//! * `controller`, `controller_f32`: `Controller::step` alone (a copy of the servo's
//!   controller fed the same measurements), and its f32 port.
//! * `capacity_check`: the per-tick beam capacity check |τ̂| ≤ τ_cap(L)
//!   (`Setting::within_capacity` on the torque estimate).
//! * `speed_tracker`: after each loaded tick, outside the control step (the service's
//!   per-tick work on a board): `Servo::track_speed`, the velocity feed-forward scale of a
//!   loaded move (`model::control::speed_scale`).
//! * `telemetry`: `protocol::encode_telemetry` of a sample built from the tick's output
//!   (postcard + CRC-32 + COBS into a frame buffer).
//!
//! Over 64 clutch lengths from t_c = 1 mm to l = 8 mm (paper design): `stiffness` k(L)
//! (`Design::stiffness`), `inverse` L(k) (`Design::clutch_length`, at k(L) of those
//! lengths), `capacity` τ_cap(L) (`Design::torque_capacity`), and the f32 k(L) and L(k).
//!
//! `tick_overhead`: after `init`, SysTick fires every 50 000 counts into an empty task
//! bound to it at the firmware's control priority (3). `idle` spins reading the counter;
//! the reading after each interrupt is late by one loop iteration plus the whole interrupt
//! (RTIC's handler around the empty task, entry and return); the loop iteration alone is
//! the smallest difference between readings without an interrupt. The difference is the
//! tick overhead: every instruction the CPU executes because a tick happened. (Exception
//! entry and return are not instructions: QEMU's icount does not count the hardware
//! stacking a real core spends 12 cycles on each way.)
//!
//! Each result is one line `RESULT bench name=NAME n=N sum=S min=A max=B` in SysTick counts
//! net of the calibration (the format: `firmware::report`); the run ends with `bench done`
//! and exit status 0.
#![no_std]
#![no_main]
#![deny(missing_docs)]

use core::hint::black_box;
use cortex_m::peripheral::{syst::SystClkSource, SYST};
use firmware::board;

/// SysTick reload for free-running measurements (24-bit counter).
const FREE_RELOAD: u32 = 0x00FF_FFFF;
/// SysTick period for the tick-overhead measurement, counts.
const TICK_PERIOD: u32 = 50_000;
/// Interrupts to measure.
const TICKS: u32 = 64;

/// Counts between two readings of the down-counter (at most one wrap of 2²⁴).
#[inline(always)]
fn elapsed(t0: u32, t1: u32) -> u32 {
    t0.wrapping_sub(t1) & FREE_RELOAD
}

/// Times `f(x)` in SysTick counts (see the crate docs).
#[inline(always)]
fn time<T, R>(x: T, f: impl FnOnce(T) -> R) -> (R, u32) {
    let t0 = SYST::get_current();
    let x = black_box(x);
    let r = black_box(f(x));
    let t1 = SYST::get_current();
    (r, elapsed(t0, t1))
}

/// Samples of one benchmark, SysTick counts net of the calibration.
#[derive(Clone, Copy)]
struct Stat {
    n: u32,
    sum: u64,
    min: u32,
    max: u32,
}

impl Stat {
    const fn new() -> Self {
        Self {
            n: 0,
            sum: 0,
            min: u32::MAX,
            max: 0,
        }
    }

    fn add(&mut self, counts: u32, calibration: u32) {
        let c = counts.saturating_sub(calibration);
        self.n += 1;
        self.sum += u64::from(c);
        self.min = self.min.min(c);
        self.max = self.max.max(c);
    }

    fn log(&self, name: &str) {
        defmt::println!(
            "RESULT bench name={=str} n={=u32} sum={=u64} min={=u32} max={=u32}",
            name,
            self.n,
            self.sum,
            if self.n == 0 { 0 } else { self.min },
            self.max
        );
    }
}

/// The smallest count of an empty measurement (two counter readings around an identity).
fn calibrate() -> u32 {
    let mut c = u32::MAX;
    for i in 0..32u32 {
        let (_, t) = time(i, |x| x);
        c = c.min(t);
    }
    c
}

mod suite {
    use super::{time, Stat};
    use bench::float::{
        length_mm, stiffness_nm_per_rad, FloatBeam, FloatController, FloatMeasurements,
        FloatSchedule, FloatServo,
    };
    use firmware::board::{at_rest, SimulatedIo, POT_AT_REST};
    use model::calibration::pipeline::Pipeline;
    use model::control::{Command, Config, Measurements};
    use model::sensors::POT_COUNT_Q32;
    use model::servo::Servo;
    use model::supervisor::SupervisorConfig;
    use model::{Angle, Design, Frequency, Length, Torque};
    use plant::harness::{plant_for, Scenario};
    use protocol::{encode_telemetry, FaultSet, LimitFlags, TelemetrySample, MAX_TELEMETRY_FRAME};
    use service::clutch_confirmation::UNCONFIRMED_TOLERANCE_UM;
    use service::length_from_um;

    /// Ticks per clutch length.
    const SEGMENT_TICKS: u32 = 2000;
    /// Clutch lengths of the beam-function sweep.
    const SWEEP: u32 = 64;

    /// I32F32 bits → millionths, saturated (µrad, µN·m).
    fn micro(bits: i64) -> i32 {
        ((i128::from(bits) * 1_000_000) >> 32).clamp(i128::from(i32::MIN), i128::from(i32::MAX))
            as i32
    }

    /// The command scheduled at `tick` of a segment.
    fn command_at(tick: u32) -> Option<Command> {
        match tick {
            300 => Some(Command::Step {
                target: Angle::from_bits(1 << 31), // 0.5 rad
            }),
            1000 => Some(Command::Move {
                target: Angle::ZERO,
                duration_ms: 200,
            }),
            1500 => Some(Command::Sine {
                amplitude: Angle::from_bits(429_496_730), // 0.1 rad
                frequency: Frequency::from_int(12),       // rad/s (≈ 2 Hz)
            }),
            _ => None,
        }
    }

    /// The closed-loop benchmarks at each clutch length.
    pub fn closed_loop(cal: u32) {
        let mut step = Stat::new();
        let mut step_unloaded = Stat::new();
        let mut step_f = Stat::new();
        let mut ctl_s = Stat::new();
        let mut ctl_f = Stat::new();
        let mut cap = Stat::new();
        let mut speed = Stat::new();
        let mut tel = Stat::new();
        let mut worst_duty_diff: i32 = 0;
        let mut sum_duty_diff: u64 = 0;
        let mut faults: u32 = 0;
        let mut worst_angle_urad: u32 = 0;
        let mut ticks: u32 = 0;
        let design = Design::paper();
        let mut buf = [0u8; MAX_TELEMETRY_FRAME];
        // The script with the load, then without: a link floating in the free play at rest,
        // where the catch (`model::control::catch`) has the output. The same code times
        // both (one call site, one inlining); the other figures are the loaded pass's.
        for (mm, load_nm) in (1..=8)
            .map(|mm| (mm, 0.3))
            .chain((1..=8).map(|mm| (mm, 0.0)))
        {
            let loaded = load_nm > 0.0;
            // As a board runs until a calibration confirms the clutch: the clutch taken
            // longer by the unconfirmed tolerance, the clutch monitor running.
            let mut config = Config::paper(Length::from_int(mm));
            config.limits.clutch_tolerance = length_from_um(UNCONFIRMED_TOLERANCE_UM);
            let Ok(mut servo) = Servo::new(&design, &config, &SupervisorConfig::DEFAULT) else {
                defmt::error!("bench: servo rejected at L = {=i32} mm", mm);
                continue;
            };
            let mut fservo = FloatServo::new(&servo, &config);
            let mut scenario = Scenario::new(config, Command::Hold);
            scenario.load_nm = load_nm;
            let (Ok(mut plant), Ok(mut fplant)) = (plant_for(&scenario), plant_for(&scenario))
            else {
                defmt::error!("bench: plant rejected at L = {=i32} mm", mm);
                continue;
            };
            let (mut io, mut fio): (SimulatedIo, SimulatedIo) = (at_rest(), at_rest());
            // The sensor-correction layer as on the boards, its boot window over (the plant
            // starts at rest at 0 rad with the encoder at 0: the identity).
            let mut pipeline = Pipeline::nominal();
            pipeline.assume_aligned();
            let _ = servo.enable();
            let _ = fservo.enable();
            let mut ctl = servo.controller().clone();
            let mut fctl =
                FloatController::new(FloatSchedule::new(servo.controller().schedule(), &config));
            let setting = *servo.controller().schedule().setting();
            let mut readings = plant.readings();
            let mut freadings = fplant.readings();
            for tick in 0..SEGMENT_TICKS {
                if let Some(cmd) = command_at(tick) {
                    // The f32 port runs the move the fixed-point controller planned.
                    let cmd = servo.controller().planned(cmd);
                    let _ = servo.command(cmd);
                    let _ = ctl.command(cmd);
                    fservo.command(cmd);
                    fctl.command(cmd);
                }
                io.present(
                    readings.link_encoder,
                    readings.gear_pot,
                    readings.current_adc,
                    readings.supply_adc,
                );
                fio.present(
                    freadings.link_encoder,
                    freadings.gear_pot,
                    freadings.current_adc,
                    freadings.supply_adc,
                );

                // The same step for the two servos (fixed point, then the f32 port): two
                // closures on purpose, each timed on its own concrete types.
                let (out, c) = time((&mut io, &mut servo, &mut pipeline), |(io, servo, p)| {
                    let raw = io.read_inputs();
                    let out = p.tick(servo, &raw);
                    io.drive(out.bridge);
                    out
                });
                if !loaded {
                    step_unloaded.add(c, cal);
                    servo.track_speed(&out);
                    readings = plant.step_tick(io.applied_duty());
                    continue;
                }
                step.add(c, cal);
                let (_, c) = time((&mut servo, &out), |(servo, out)| servo.track_speed(out));
                speed.add(c, cal);
                let (fout, c) = time((&mut fio, &mut fservo), |(io, servo)| {
                    let input = io.read_inputs();
                    let out = servo.tick(&input);
                    io.drive(out.bridge);
                    out
                });
                step_f.add(c, cal);

                let m = Measurements {
                    link_encoder: readings.link_encoder,
                    gear_pot: Some(readings.gear_pot),
                    current_adc: readings.current_adc,
                    applied_duty: None,
                };
                let (_, c) = time((&mut ctl, &m), |(ctl, m)| ctl.step(m));
                ctl_s.add(c, cal);
                let fm = FloatMeasurements {
                    link_encoder: m.link_encoder,
                    gear_pot: m.gear_pot,
                    current_adc: m.current_adc,
                    applied_duty: None,
                };
                let (_, c) = time((&mut fctl, &fm), |(ctl, m)| ctl.step(m));
                ctl_f.add(c, cal);

                let (_, c) = time((&setting, out.control.torque_estimate), |(s, t)| {
                    s.within_capacity(t)
                });
                cap.add(c, cal);

                let sample = TelemetrySample {
                    tick: out.tick,
                    reference_urad: micro(out.control.reference.to_bits()),
                    link_angle_urad: micro(out.control.link_angle.to_bits()),
                    gear_angle_urad: micro(
                        i64::from(i32::from(readings.gear_pot) - i32::from(POT_AT_REST))
                            * POT_COUNT_Q32,
                    ),
                    current_ma: (micro(out.control.current.to_bits()) / 1000) as i16,
                    torque_unm: micro(out.control.torque_estimate.to_bits()),
                    duty_permille: io.applied_duty(),
                    faults: FaultSet(servo.faults().0),
                    limits: LimitFlags(
                        u8::from(out.control.flags.torque_limited)
                            | u8::from(out.control.flags.current_limited) << 1
                            | u8::from(out.control.flags.duty_saturated) << 2,
                    ),
                };
                let (_, c) = time((tick as u16, &sample, &mut buf), |(seq, s, b)| {
                    encode_telemetry(seq, s, b)
                });
                tel.add(c, cal);

                // How far the f32 port's closed loop is from the fixed-point one.
                let d = (i32::from(io.applied_duty()) - i32::from(fio.applied_duty())).abs();
                worst_duty_diff = worst_duty_diff.max(d);
                sum_duty_diff += u64::from(d.unsigned_abs());
                faults += u32::from(out.new_fault.is_some()) + u32::from(fout.new_fault.is_some());
                let a = plant.state().link_angle_rad - fplant.state().link_angle_rad;
                worst_angle_urad = worst_angle_urad.max((libm::fabs(a) * 1e6) as u32);
                ticks += 1;

                readings = plant.step_tick(io.applied_duty());
                freadings = fplant.step_tick(fio.applied_duty());
            }
            if !servo.faults().is_empty() {
                defmt::warn!(
                    "bench: faults {=u16:#x} latched at L = {=i32} mm",
                    servo.faults().0,
                    mm
                );
            }
        }
        step.log("control_step");
        step_unloaded.log("control_step_unloaded");
        step_f.log("control_step_f32");
        ctl_s.log("controller");
        ctl_f.log("controller_f32");
        cap.log("capacity_check");
        speed.log("speed_tracker");
        tel.log("telemetry");
        defmt::println!(
            "RESULT f32_agreement ticks={=u32} duty_diff_mean_permille={=f32} duty_diff_max_permille={=i32} link_angle_diff_max_urad={=u32} faults={=u32}",
            ticks,
            sum_duty_diff as f32 / ticks.max(1) as f32,
            worst_duty_diff,
            worst_angle_urad,
            faults
        );
    }

    /// k(L), L(k), τ_cap(L) over the adjustable range, fixed point and f32.
    pub fn beam(cal: u32) {
        let design = Design::paper();
        let fbeam = FloatBeam::new(&design);
        let (t_c, l) = design.adjustable_range();
        let (mut k_s, mut k_f, mut inv_s, mut inv_f, mut cap) = (
            Stat::new(),
            Stat::new(),
            Stat::new(),
            Stat::new(),
            Stat::new(),
        );
        let mut errors: u32 = 0;
        let span = l.to_bits() - t_c.to_bits();
        for i in 0..SWEEP {
            let len = Length::from_bits(t_c.to_bits() + span * i64::from(i) / i64::from(SWEEP - 1));
            let (k, c) = time((&design, len), |(d, len)| d.stiffness(len));
            k_s.add(c, cal);
            let lf = length_mm(len);
            let (_, c) = time((&fbeam, lf), |(b, l)| b.stiffness(l));
            k_f.add(c, cal);
            let Ok(k) = k else {
                errors += 1;
                continue;
            };
            let (back, c) = time((&design, k), |(d, k)| d.clutch_length(k));
            inv_s.add(c, cal);
            if back != Ok(len) {
                errors += 1;
            }
            let kf = stiffness_nm_per_rad(k);
            let (_, c) = time((&fbeam, kf), |(b, k)| b.clutch_length(k));
            inv_f.add(c, cal);
            let (t, c) = time((&design, len), |(d, len)| d.torque_capacity(len));
            cap.add(c, cal);
            errors += u32::from(t.map_or(true, |t: Torque| t.to_bits() <= 0));
        }
        k_s.log("stiffness");
        k_f.log("stiffness_f32");
        inv_s.log("inverse");
        inv_f.log("inverse_f32");
        cap.log("capacity");
        if errors != 0 {
            defmt::error!("bench: {=u32} beam-function results were wrong", errors);
        }
    }
}

mod ticks {
    //! The RTIC tick overhead, measured from `idle` (see the crate docs).
    use super::{Stat, TICKS, TICK_PERIOD};
    use cortex_m::peripheral::SYST;

    /// Spins reading SysTick until `TICKS` interrupts were seen, then logs the overhead.
    pub fn measure() -> Stat {
        let reload = TICK_PERIOD - 1;
        let mut gaps = [0u32; TICKS as usize];
        let mut seen = 0usize;
        let mut base = u32::MAX;
        let mut prev = SYST::get_current();
        while seen < gaps.len() {
            let now = SYST::get_current();
            if now > prev {
                // The counter reloaded since the last reading: the interrupt ran in between.
                if let Some(g) = gaps.get_mut(seen) {
                    *g = prev + (reload + 1) - now;
                }
                seen += 1;
            } else {
                base = base.min(prev - now);
            }
            prev = now;
        }
        let mut stat = Stat::new();
        // The first gap may include the start of the loop: skip it.
        for &g in gaps.iter().skip(1) {
            stat.add(g, base);
        }
        stat
    }
}

#[rtic::app(device = firmware::board::pac)]
mod app {
    use super::{board, SystClkSource, FREE_RELOAD, TICK_PERIOD};
    use cortex_m::peripheral::SYST;

    #[shared]
    struct Shared {}

    #[local]
    struct Local {}

    #[init]
    fn init(cx: init::Context) -> (Shared, Local) {
        let mut syst = cx.core.SYST;
        syst.set_clock_source(SystClkSource::Core);
        syst.set_reload(FREE_RELOAD);
        syst.clear_current();
        syst.disable_interrupt();
        syst.enable_counter();
        defmt::println!("bench board {=str}", board::NAME);
        defmt::println!("RESULT clock sysclk_hz={=u32}", board::SYSCLK_HZ);
        let cal = super::calibrate();
        defmt::println!("bench calibration: {=u32} counts", cal);
        super::suite::beam(cal);
        super::suite::closed_loop(cal);

        syst.disable_counter();
        syst.set_reload(TICK_PERIOD - 1);
        syst.clear_current();
        syst.enable_interrupt();
        syst.enable_counter();
        (Shared {}, Local {})
    }

    /// The empty task whose overhead is measured, at the firmware's control priority.
    #[task(binds = SysTick, priority = 3)]
    fn tick(_: tick::Context) {}

    #[idle]
    fn idle(_: idle::Context) -> ! {
        let stat = super::ticks::measure();
        let _ = SYST::get_current();
        stat.log("tick_overhead");
        defmt::println!("bench done");
        board::exit(true)
    }
}
