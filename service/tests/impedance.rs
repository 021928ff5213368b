//! `Request::Impedance` through the protocol handler and the service, as the firmware's
//! command task runs it: refused while disabled, above the joint's stiffness, or with a
//! target outside the position window; accepted otherwise, and then the servo carries it.

use model::control::Config;
use model::servo::Servo;
use model::supervisor::SupervisorConfig;
use model::{Design, Length};
use protocol::{ErrorCode, Frame, Handler, Reply, Request};
use service::{Actuator, Service};

mod common;
use common::Cell;

fn impedance(target_urad: i32, stiffness_mnm_per_rad: u32) -> Request {
    Request::Impedance {
        target_urad,
        stiffness_mnm_per_rad,
        damping_unms_per_rad: 200_000,
        torque_unm: -50_000,
    }
}

#[test]
fn refusals_and_acceptance() {
    let design = Design::paper();
    // L = 5 mm: k = 57.34 N·m/rad.
    let config = Config::paper(Length::from_int(5));
    let sup = SupervisorConfig::DEFAULT;
    let mut actuator = Cell(Actuator::aligned(
        Servo::new(&design, &config, &sup).unwrap(),
    ));
    let mut service = Service::new(design, config, sup);
    let mut handler = Handler::new();
    let mut ask = |actuator: &mut Cell, req: Request| {
        let mut dev = service.device(actuator);
        handler.handle_request(Frame::new(1, req), &mut dev).body
    };
    assert_eq!(
        ask(&mut actuator, impedance(300_000, 20_000)),
        Reply::Error(ErrorCode::NotAllowed)
    );
    assert_eq!(ask(&mut actuator, Request::Enable), Reply::Ok);
    assert_eq!(
        ask(&mut actuator, impedance(300_000, 57_400)),
        Reply::Error(ErrorCode::OutOfRange),
        "above the joint's 57.34 N·m/rad"
    );
    assert_eq!(
        ask(&mut actuator, impedance(2_540_000, 20_000)),
        Reply::Error(ErrorCode::OutOfRange),
        "outside the ±2.5 rad window"
    );
    assert_eq!(ask(&mut actuator, impedance(300_000, 57_300)), Reply::Ok);
    let cmd = actuator.0.servo.impedance_command().copied().unwrap();
    assert_eq!(cmd.target.to_bits(), service::micro_to_q32(300_000));
    assert_eq!(cmd.stiffness.get().to_num::<f64>(), 57.3);
    assert!((cmd.damping.to_num::<f64>() - 0.2).abs() < 1e-9);
    assert!((cmd.torque.get().to_num::<f64>() + 0.05).abs() < 1e-9);
    // A position command ends it.
    assert_eq!(ask(&mut actuator, Request::Hold), Reply::Ok);
    assert!(actuator.0.servo.impedance_command().is_none());
}
