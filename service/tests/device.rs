//! The command service on the host: the protocol handler driving `ServiceDevice` over a
//! servo, exactly as the firmware's command task does (there through RTIC's `lock`).

use model::control::Config;
use model::servo::{Servo, ServoState, TickInput};
use model::supervisor::SupervisorConfig;
use model::{Design, Length};
use protocol::{
    ErrorCode, FaultCode, Frame, Gains, Handler, Limits, Reply, Request, State, Status,
};
use service::{
    micro_to_q32, milli_to_q32, q32_to_micro, q32_to_milli, Actuator, Service, TelemetryGate,
};

mod common;
use common::Cell;

struct Board {
    actuator: Cell,
    service: Service,
    handler: Handler,
    seq: u16,
}

impl Board {
    fn new() -> Board {
        let design = Design::paper();
        let config = Config::paper(Length::from_int(3));
        let sup = SupervisorConfig::DEFAULT;
        let servo = Servo::new(&design, &config, &sup).unwrap();
        Board {
            actuator: Cell(Actuator::aligned(servo)),
            service: Service::new(design, config, sup),
            handler: Handler::new(),
            seq: 0,
        }
    }

    fn ask(&mut self, req: Request) -> Reply {
        self.seq += 1;
        let mut dev = self.service.device(&mut self.actuator);
        let reply = self
            .handler
            .handle_request(Frame::new(self.seq, req), &mut dev);
        assert_eq!(reply.seq, self.seq, "every reply carries its request's seq");
        reply.body
    }

    fn status(&mut self) -> Status {
        match self.ask(Request::GetStatus) {
            Reply::Status(s) => s,
            other => panic!("status request answered with {other:?}"),
        }
    }

    /// Runs `n` ticks with the link at rest at encoder count `enc`, 0 A.
    fn run(&mut self, n: u32, enc: u16) {
        self.run_at(n, enc, 512);
    }

    /// Runs `n` ticks with the link encoder at `enc` and the gear pot at `pot`, 0 A.
    fn run_at(&mut self, n: u32, enc: u16, pot: u16) {
        let input = TickInput {
            link_encoder: enc,
            gear_pot: Some(pot),
            current_adc: 2048,
            supply_adc: None,
            read_error: None,
        };
        for _ in 0..n {
            let out = self.actuator.0.servo.tick(&input);
            let _ = self.actuator.0.after_tick(&input, &out);
        }
    }

    /// Turns the link (by hand: the motor is off) from encoder count 0 to `to` counts, one
    /// count per tick, the gear pot following (beams unloaded).
    fn turn_by_hand(&mut self, to: u16) {
        for c in 0..=to {
            self.run_at(1, c, b_pot(c));
        }
    }
}

/// Stiffness of the paper design, E–B model, f64 from first principles (docs/design.md §2.2:
/// n = 4 beams of radius r = 0.5 mm, E = 200 GPa, pitch radius R = 7.8 mm):
/// k = n·3·E·I·R²/L³ = 12·E·I·R²/L³ with I = π·r⁴/4.
fn k_oracle(l_m: f64) -> f64 {
    let i = std::f64::consts::PI * 0.5e-3f64.powi(4) / 4.0;
    12.0 * 200e9 * i * 7.8e-3f64.powi(2) / l_m.powi(3)
}

#[test]
fn unit_conversions_round_to_nearest() {
    // 0.5 rad = 500 000 µrad; 1 A = 1000 mA; −1 µrad round trip.
    assert_eq!(q32_to_micro(1 << 31), 500_000);
    assert_eq!(q32_to_milli(1 << 32), 1_000);
    assert_eq!(q32_to_micro(micro_to_q32(-1)), -1);
    assert_eq!(q32_to_micro(micro_to_q32(6_283_185)), 6_283_185);
    assert_eq!(q32_to_milli(milli_to_q32(3_000)), 3_000);
    // Saturation instead of wrapping.
    assert_eq!(q32_to_micro(i64::MAX), i32::MAX);
    assert_eq!(q32_to_micro(i64::MIN), i32::MIN);
}

#[test]
fn status_reports_the_configured_clutch_and_stiffness() {
    let mut b = Board::new();
    let s = b.status();
    assert_eq!(s.state, State::Disabled);
    assert_eq!(s.clutch_length_um, 3_000);
    let k = f64::from(s.stiffness_mnm_per_rad) / 1e3;
    let want = k_oracle(3e-3);
    assert!(
        (k / want - 1.0).abs() < 1e-4,
        "k(3 mm) = {k}, oracle {want}"
    );
}

#[test]
fn stiffness_request_returns_the_inverse_and_reconfigures() {
    let mut b = Board::new();
    // k = 895.9 N·m/rad ↔ L = 2 mm (docs/design.md §2.2).
    let k_mnm = (k_oracle(2e-3) * 1e3).round() as u32;
    match b.ask(Request::SetStiffness {
        stiffness_mnm_per_rad: k_mnm,
    }) {
        Reply::ClutchToSet { length_um } => assert!(
            (i64::from(length_um) - 2_000).abs() <= 1,
            "L(k) = {length_um} µm"
        ),
        other => panic!("{other:?}"),
    }
    let s = b.status();
    assert!((i64::from(s.clutch_length_um) - 2_000).abs() <= 1);
    assert!((i64::from(s.stiffness_mnm_per_rad) - i64::from(k_mnm)).abs() <= 2);
    // Outside the design's clutch range (L(k) < t_c): refused, nothing changes.
    let before = b.status();
    assert_eq!(
        b.ask(Request::SetStiffness {
            stiffness_mnm_per_rad: 4_000_000_000
        }),
        Reply::Error(ErrorCode::OutOfRange)
    );
    let mut after = b.status();
    after.protocol_errors = before.protocol_errors;
    after.tick = before.tick;
    assert_eq!(after, before);
}

#[test]
fn the_enable_state_machine_over_the_wire() {
    let mut b = Board::new();
    // Motions need an enabled servo.
    let mv = Request::Move {
        target_urad: 500_000,
        duration_ms: 300,
    };
    assert_eq!(b.ask(mv), Reply::Error(ErrorCode::NotAllowed));
    assert_eq!(b.ask(Request::Enable), Reply::Ok);
    b.run(5, 0);
    assert_eq!(b.ask(mv), Reply::Ok);
    b.run(1, 0);
    let s = b.status();
    assert_eq!(s.state, State::Enabled);
    assert!(s.moving);
    assert_eq!(b.ask(Request::Hold), Reply::Ok);
    assert_eq!(b.ask(Request::Disable), Reply::Ok);
    assert_eq!(b.status().state, State::Disabled);
}

#[test]
fn a_heartbeat_arms_the_timeout_and_its_fault_reaches_the_status() {
    let mut b = Board::new();
    assert_eq!(b.ask(Request::Enable), Reply::Ok);
    assert_eq!(b.ask(Request::Heartbeat), Reply::Ok);
    b.run(100, 0);
    assert_eq!(b.actuator.0.servo.state(), ServoState::Enabled);
    b.run(2, 0);
    let s = b.status();
    assert_eq!(s.state, State::Faulted);
    assert!(s.faults.contains(FaultCode::CommandTimeout));
    let first = s.first_fault.unwrap();
    assert_eq!(first.code, FaultCode::CommandTimeout);
    assert_eq!(first.tick, 102);
    // Faulted: enable and motions refused; clear → disabled; enable again works.
    assert_eq!(b.ask(Request::Enable), Reply::Error(ErrorCode::NotAllowed));
    assert_eq!(
        b.ask(Request::Step { target_urad: 0 }),
        Reply::Error(ErrorCode::NotAllowed)
    );
    assert_eq!(b.ask(Request::ClearFault), Reply::Ok);
    assert_eq!(b.status().state, State::Disabled);
    assert!(b.status().faults.is_empty());
    assert_eq!(b.ask(Request::Enable), Reply::Ok);
    assert_eq!(b.actuator.0.servo.state(), ServoState::Enabled);
    // The timeout ended the session that armed it: the clear holds.
    b.run(500, 0);
    assert_eq!(b.actuator.0.servo.state(), ServoState::Enabled);
}

#[test]
fn other_requests_keep_an_armed_timeout_alive_and_a_disarm_ends_it() {
    let mut b = Board::new();
    assert_eq!(b.ask(Request::Enable), Reply::Ok);
    assert_eq!(b.ask(Request::Heartbeat), Reply::Ok);
    // 1 s of status requests every 60 ms and no heartbeat: the link is alive.
    for _ in 0..17 {
        b.run(60, 0);
        b.status();
    }
    assert_eq!(b.actuator.0.servo.state(), ServoState::Enabled);
    // Silence: the timeout fires 101 ticks after the tick the last request preceded.
    b.run(101, 0);
    assert_eq!(b.actuator.0.servo.state(), ServoState::Enabled);
    b.run(1, 0);
    assert_eq!(b.actuator.0.servo.state(), ServoState::Faulted);
    assert_eq!(b.ask(Request::ClearFault), Reply::Ok);
    assert_eq!(b.ask(Request::Enable), Reply::Ok);
    // Armed again, then disarmed: silence is no fault.
    assert_eq!(b.ask(Request::Heartbeat), Reply::Ok);
    b.run(50, 0);
    assert_eq!(b.ask(Request::DisarmHeartbeat), Reply::Ok);
    b.run(1_000, 0);
    assert_eq!(b.actuator.0.servo.state(), ServoState::Enabled);
}

#[test]
fn targets_outside_the_position_window_are_refused() {
    let mut b = Board::new();
    assert_eq!(b.ask(Request::Enable), Reply::Ok);
    b.run(5, 0);
    let mv = |t: i32| Request::Move {
        target_urad: t,
        duration_ms: 300,
    };
    let refused = Reply::Error(ErrorCode::OutOfRange);
    assert_eq!(b.ask(mv(2_500_001)), refused);
    assert_eq!(
        b.ask(Request::Step {
            target_urad: -2_500_001
        }),
        refused
    );
    assert_eq!(b.ask(mv(2_500_000)), Reply::Ok);
    assert_eq!(b.ask(Request::Hold), Reply::Ok);
    let narrow = Limits {
        position_min_urad: -500_000,
        position_max_urad: 500_000,
        ..Limits::DEFAULT
    };
    assert_eq!(b.ask(Request::SetLimits(narrow)), Reply::Ok);
    assert_eq!(b.ask(Request::GetLimits), Reply::Limits(narrow));
    assert_eq!(b.ask(mv(600_000)), refused);
    // A sine about the link's angle now (0): ±0.6 rad leaves the window, ±0.4 does not.
    let sine = |a: u32| Request::Sine {
        amplitude_urad: a,
        frequency_mhz: 1_000,
    };
    assert_eq!(b.ask(sine(600_000)), refused);
    assert_eq!(b.ask(sine(400_000)), Reply::Ok);
}

#[test]
fn the_default_limits_are_what_get_limits_reports() {
    let mut b = Board::new();
    assert_eq!(b.ask(Request::GetLimits), Reply::Limits(Limits::DEFAULT));
}

#[test]
fn a_clear_while_the_link_is_outside_the_window_clears_nothing_and_says_where() {
    let mut b = Board::new();
    // 1643 counts = 2.5203 rad: outside the default ±2.5 rad window.
    b.turn_by_hand(1_643);
    let s = b.status();
    assert_eq!(s.state, State::Faulted);
    assert_eq!(s.first_fault.unwrap().code, FaultCode::PositionLimit);
    let Reply::FaultPersists(now) = b.ask(Request::ClearFault) else {
        panic!("the clear should have been refused");
    };
    assert_eq!(now.code, FaultCode::PositionLimit);
    // The measured angle is the centre of count 1643.
    let expected = (1_643.5 * std::f64::consts::TAU / 4096.0 * 1e6).round();
    assert!((f64::from(now.value) - expected).abs() <= 1.0, "{now:?}");
    assert_eq!(b.status().state, State::Faulted, "nothing cleared");
    // The way out: widen the window; after a tick the clear holds and enable works.
    let wide = Limits {
        position_max_urad: 2_540_000,
        ..Limits::DEFAULT
    };
    assert_eq!(b.ask(Request::SetLimits(wide)), Reply::Ok);
    b.run_at(1, 1_643, b_pot(1_643));
    assert_eq!(b.ask(Request::ClearFault), Reply::Ok);
    b.run_at(5, 1_643, b_pot(1_643));
    assert_eq!(b.ask(Request::Enable), Reply::Ok);
    assert_eq!(
        b.ask(Request::Move {
            target_urad: 0,
            duration_ms: 1_000
        }),
        Reply::Ok
    );
}

/// The gear pot's count for a link at encoder count `c` with unloaded beams.
fn b_pot(c: u16) -> u16 {
    let rad = f64::from(c) * std::f64::consts::TAU / 4096.0;
    (512.0 + rad * 1024.0 / (300f64.to_radians())).round() as u16
}

#[test]
fn the_largest_target_stays_inside_what_the_gear_pot_measures() {
    // The pot saturates 511 counts above its centre (300° over 1024 counts); a link at the
    // largest target with the beams bent to the edge of their envelope at the longest
    // clutch length must still read below that.
    let design = Design::paper();
    let pot_max_rad = 511.0 * 300f64.to_radians() / 1024.0;
    let max = f64::from(protocol::TARGET_MAX_URAD) / 1e6;
    for l_mm in 1..=8 {
        let config = Config::paper(Length::from_int(l_mm));
        let servo = Servo::new(&design, &config, &SupervisorConfig::DEFAULT).unwrap();
        let envelope: f64 = servo.supervisor().deflection_envelope().get().to_num();
        assert!(
            max + envelope < pot_max_rad,
            "L = {l_mm} mm: {max} + {envelope} rad ≥ {pot_max_rad} rad"
        );
    }
}

#[test]
fn a_clutch_tolerance_over_the_wire_derates_the_torque_limit_and_the_check() {
    let mut b = Board::new();
    let cap = b
        .actuator
        .0
        .servo
        .controller()
        .schedule()
        .setting()
        .torque_capacity();
    let full = b.actuator.0.servo.controller().schedule().torque_limit();
    // More than the tolerance a board takes until a calibration confirms the clutch.
    let limits = Limits {
        clutch_tolerance_um: 1_500,
        ..Limits::DEFAULT
    };
    assert_eq!(b.ask(Request::SetLimits(limits)), Reply::Ok);
    assert_eq!(b.ask(Request::GetLimits), Reply::Limits(limits));
    // At 3 mm a clutch up to 1.5 mm long: τ_cap·3/4.5 for the check, 0.85 of it for the
    // controller (τ_cap ∝ 1/L).
    let servo = &b.actuator.0.servo;
    let nm = |t: model::Torque| t.get().to_num::<f64>();
    let weak = nm(cap) * 3.0 / 4.5;
    assert!((nm(servo.supervisor().checked_capacity()) - weak).abs() < 1e-6);
    let derated = nm(servo.controller().schedule().torque_limit());
    assert!((derated - 0.85 * weak).abs() < 1e-4, "{derated}");
    assert!((nm(full) - 0.85 * nm(cap)).abs() < 1e-4);
    // Beyond 5 mm: refused, nothing changes.
    let too_long = Limits {
        clutch_tolerance_um: 5_001,
        ..Limits::DEFAULT
    };
    assert_eq!(
        b.ask(Request::SetLimits(too_long)),
        Reply::Error(ErrorCode::OutOfRange)
    );
    assert_eq!(b.ask(Request::GetLimits), Reply::Limits(limits));
}

#[test]
fn limits_and_gains_are_prepared_and_installed() {
    let mut b = Board::new();
    let mut limits = Limits::DEFAULT;
    assert_eq!(b.ask(Request::SetLimits(limits)), Reply::Ok);
    let sup = b.service.supervision();
    assert_eq!(sup.trip_current_a, fixed::types::I32F32::lit("1.75"));
    assert_eq!(
        b.actuator.0.servo.supervisor().config().trip_current_a,
        fixed::types::I32F32::lit("1.75")
    );
    // A current limit the ADC cannot measure (trip ≥ 2 A) is refused by the supervisor.
    limits.current_ma = 1_800;
    assert_eq!(
        b.ask(Request::SetLimits(limits)),
        Reply::Error(ErrorCode::OutOfRange)
    );
    assert_eq!(
        b.service.config().limits.max_current_a,
        fixed::types::I32F32::lit("1.5")
    );
    let g = Gains {
        kp: 2_000_000,
        ki: 0,
        kd: 10_000,
    };
    assert_eq!(b.ask(Request::SetGains(g)), Reply::Ok);
    let installed = b.actuator.0.servo.controller().schedule().gains();
    assert_eq!(installed.kp, fixed::types::I32F32::from_num(2_000));
    assert_eq!(installed.kd, fixed::types::I32F32::from_num(10));
    assert_eq!(b.ask(Request::AutoGains), Reply::Ok);
    assert_ne!(
        b.actuator.0.servo.controller().schedule().gains().kp,
        installed.kp
    );
}

#[test]
fn telemetry_gate_passes_the_rate_evenly() {
    for rate in [10u16, 100, 300, 333, 500] {
        let mut g = TelemetryGate::default();
        g.set_rate(rate);
        let mut seqs = Vec::new();
        for _ in 0..1000 {
            if let Some(s) = g.due() {
                seqs.push(s);
            }
        }
        assert_eq!(seqs.len(), usize::from(rate), "rate {rate}");
        assert!(seqs.windows(2).all(|w| w[1] == w[0].wrapping_add(1)));
    }
    let mut g = TelemetryGate::default();
    assert!((0..1000).all(|_| g.due().is_none()), "off by default");
}

#[test]
fn telemetry_samples_are_in_wire_units() {
    let mut b = Board::new();
    assert_eq!(b.ask(Request::StreamTelemetry { rate_hz: 500 }), Reply::Ok);
    // 1 A (2048 + 1024 counts), link at count 100 (centre of the count: 100.5·2π/4096 rad),
    // pot 10 counts above centre (10·300°/1024).
    let input = TickInput {
        link_encoder: 100,
        gear_pot: Some(522),
        current_adc: 3072,
        supply_adc: None,
        read_error: None,
    };
    let mut samples = Vec::new();
    for _ in 0..10 {
        let out = b.actuator.0.servo.tick(&input);
        if let Some(s) = b.actuator.0.after_tick(&input, &out) {
            samples.push(s);
        }
    }
    assert_eq!(samples.len(), 5);
    let (seq, s) = samples[4];
    assert_eq!(seq, 5);
    assert_eq!(s.tick, 10);
    assert_eq!(s.current_ma, 1000);
    let link = 100.5 * std::f64::consts::TAU / 4096.0 * 1e6;
    assert!((f64::from(s.link_angle_urad) - link).abs() <= 1.0, "{s:?}");
    let gear = 10.0 * 300f64.to_radians() / 1024.0 * 1e6;
    assert!((f64::from(s.gear_angle_urad) - gear).abs() <= 1.0, "{s:?}");
    assert_eq!(s.duty_permille, 0, "disabled: nothing applied");
}

#[test]
fn bad_requests_change_nothing_but_the_error_count() {
    let mut b = Board::new();
    let before = b.status();
    for req in [
        Request::SetClutchLength { length_um: 0 },
        Request::SetClutchLength { length_um: 9_000 },
        Request::StreamTelemetry { rate_hz: 5 },
        Request::Move {
            target_urad: 7_000_000,
            duration_ms: 100,
        },
    ] {
        assert_eq!(b.ask(req), Reply::Error(ErrorCode::OutOfRange), "{req:?}");
    }
    let after = b.status();
    assert_eq!(after.protocol_errors, before.protocol_errors + 4);
    assert_eq!(
        Status {
            protocol_errors: before.protocol_errors,
            ..after
        },
        before
    );
}

#[test]
fn enable_is_busy_during_the_boot_window_then_accepted() {
    let design = Design::paper();
    let config = Config::paper(Length::from_int(3));
    let sup = SupervisorConfig::DEFAULT;
    let mut b = Board::new();
    b.actuator = Cell(Actuator::new(Servo::new(&design, &config, &sup).unwrap()));
    let input = TickInput {
        link_encoder: 0,
        gear_pot: Some(512),
        current_adc: 2048,
        supply_adc: None,
        read_error: None,
    };
    // The 32-tick window (model::calibration::correction::BOOT_TICKS), counted here on
    // its own: busy on every tick of it, the state still disabled.
    for tick in 0..32 {
        assert_eq!(
            b.ask(Request::Enable),
            Reply::Error(ErrorCode::Busy),
            "tick {tick}"
        );
        let _ = b.actuator.0.tick(&input);
    }
    assert_eq!(b.ask(Request::Enable), Reply::Ok);
    assert_eq!(b.status().state, State::Enabled);
}
