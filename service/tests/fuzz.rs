//! The handler over the real service (not a mock): any request with any field values, in
//! any servo state, either is carried out or is refused with an error reply and changes
//! nothing — neither the servo (controller, supervisor, state) nor the configuration in
//! force nor the telemetry setting. `PROPTEST_CASES` overrides the 10 000 cases (100 000 pass in 6 s in release).

use model::control::Config;
use model::servo::{Servo, TickInput};
use model::supervisor::SupervisorConfig;
use model::{Design, Length};
use proptest::prelude::*;
use protocol::{Frame, Gains, Handler, Limits, Reply, Request};
use service::{Actuator, Service};

mod common;
use common::Cell;

/// Limits from (margin ‰, current mA, motor torque µN·m, duty ‰, position min, max µrad,
/// clutch tolerance µm).
fn limits_from((m, c, t, d, lo, hi, tol): (u16, u16, u32, u16, i32, i32, u16)) -> Limits {
    Limits {
        torque_margin_permille: m,
        current_ma: c,
        motor_torque_unm: t,
        duty_permille: d,
        position_min_urad: lo,
        position_max_urad: hi,
        clutch_tolerance_um: tol,
    }
}

/// Any request, fields over their whole types (most are out of range), and in range.
fn request() -> impl Strategy<Value = Request> {
    let limits = (
        any::<u16>(),
        any::<u16>(),
        any::<u32>(),
        any::<u16>(),
        any::<i32>(),
        any::<i32>(),
        any::<u16>(),
    )
        .prop_map(limits_from);
    let near_limits = (
        1u16..=1000,
        1u16..=2500,
        1u32..=3_000_000,
        1u16..=1000,
        -3_000_000i32..0,
        0i32..3_000_000,
        0u16..=6_000,
    )
        .prop_map(limits_from);
    prop_oneof![
        Just(Request::Ping),
        Just(Request::GetStatus),
        Just(Request::Enable),
        Just(Request::Disable),
        Just(Request::ClearFault),
        Just(Request::Hold),
        Just(Request::AutoGains),
        Just(Request::Heartbeat),
        Just(Request::DisarmHeartbeat),
        Just(Request::GetLimits),
        any::<u32>().prop_map(|length_um| Request::SetClutchLength { length_um }),
        (0u32..10_000).prop_map(|length_um| Request::SetClutchLength { length_um }),
        any::<u32>().prop_map(|k| Request::SetStiffness {
            stiffness_mnm_per_rad: k
        }),
        (0u32..10_000_000).prop_map(|k| Request::SetStiffness {
            stiffness_mnm_per_rad: k
        }),
        (any::<i32>(), any::<u32>()).prop_map(|(t, d)| Request::Move {
            target_urad: t,
            duration_ms: d
        }),
        (-7_000_000i32..7_000_000, 0u32..70_000).prop_map(|(t, d)| Request::Move {
            target_urad: t,
            duration_ms: d
        }),
        any::<i32>().prop_map(|t| Request::Step { target_urad: t }),
        (any::<u32>(), any::<u32>()).prop_map(|(a, f)| Request::Sine {
            amplitude_urad: a,
            frequency_mhz: f
        }),
        (0u32..1_100_000, 0u32..25_000).prop_map(|(a, f)| Request::Sine {
            amplitude_urad: a,
            frequency_mhz: f
        }),
        (any::<u64>(), any::<u64>(), any::<u64>())
            .prop_map(|(kp, ki, kd)| Request::SetGains(Gains { kp, ki, kd })),
        (0u64..2_000_000_000, 0u64..20_000_000_000, 0u64..20_000_000)
            .prop_map(|(kp, ki, kd)| Request::SetGains(Gains { kp, ki, kd })),
        limits.prop_map(Request::SetLimits),
        near_limits.prop_map(Request::SetLimits),
        any::<u16>().prop_map(|rate_hz| Request::StreamTelemetry { rate_hz }),
        (any::<i32>(), any::<u32>(), any::<u32>(), any::<i32>()).prop_map(|(t, k, d, f)| {
            Request::Impedance {
                target_urad: t,
                stiffness_mnm_per_rad: k,
                damping_unms_per_rad: d,
                torque_unm: f,
            }
        }),
        (
            -3_000_000i32..3_000_000,
            0u32..8_000_000,
            0u32..110_000_000,
            -110_000_000i32..110_000_000
        )
            .prop_map(|(t, k, d, f)| Request::Impedance {
                target_urad: t,
                stiffness_mnm_per_rad: k,
                damping_unms_per_rad: d,
                torque_unm: f,
            }),
    ]
}

/// Everything a refused request must leave as it was — but the time of the last link
/// activity: any valid request, refused or not, restarts an armed command timeout (whether
/// it is armed is kept).
fn fingerprint(a: &Actuator, s: &Service) -> String {
    let servo = format!("{:?}", a.servo);
    let servo = match servo.find("last_heartbeat: Some(") {
        Some(at) => {
            let rest = &servo[at..];
            let end = rest.find(')').map_or(servo.len(), |e| at + e);
            format!("{}last_heartbeat: Some(_{}", &servo[..at], &servo[end..])
        }
        None => servo,
    };
    format!(
        "{servo} {:?} {:?} {:?}",
        a.telemetry,
        s.config(),
        s.supervision()
    )
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(
        std::env::var("PROPTEST_CASES").ok().and_then(|v| v.parse().ok()).unwrap_or(10_000)
    ))]

    #[test]
    fn a_refused_request_changes_nothing(
        state in 0u8..3,
        clutch_mm in 1i32..=5,
        reqs in prop::collection::vec(request(), 1..6),
    ) {
        let design = Design::paper();
        let config = Config::paper(Length::from_int(clutch_mm));
        let sup = SupervisorConfig::DEFAULT;
        let servo = Servo::new(&design, &config, &sup).unwrap();
        let mut actuator = Cell(Actuator::aligned(servo));
        let mut service = Service::new(design, config, sup);
        let mut handler = Handler::new();
        let input = TickInput { link_encoder: 0, gear_pot: Some(512), current_adc: 2048, supply_adc: Some(2400), read_error: None };
        // The three states: disabled, enabled, faulted (an ADC rail reading).
        if state >= 1 {
            actuator.0.servo.enable().unwrap();
        }
        for _ in 0..3 {
            let _ = actuator.0.servo.tick(&input);
        }
        if state == 2 {
            let _ = actuator.0.servo.tick(&TickInput { current_adc: 4095, ..input });
        }
        for (i, req) in reqs.into_iter().enumerate() {
            let before = fingerprint(&actuator.0, &service);
            let seq = i as u16 + 1;
            let reply = {
                let mut dev = service.device(&mut actuator);
                handler.handle_request(Frame::new(seq, req), &mut dev)
            };
            prop_assert_eq!(reply.seq, seq);
            if let Reply::Error(_) = reply.body {
                prop_assert_eq!(&fingerprint(&actuator.0, &service), &before, "{:?}", req);
            }
            let _ = actuator.0.servo.tick(&input);
        }
    }
}
