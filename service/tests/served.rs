//! The service closing the loop on the host: protocol requests drive the servo that runs
//! the simulated actuator of a serving board (`plant::served`), tick by tick, as on the
//! emulated board but without the UART.

use model::control::Config;
use model::servo::{Servo, TickInput};
use model::supervisor::SupervisorConfig;
use model::{Design, Length};
use plant::metrics::StepResponse;
use plant::scenario::BridgeLines;
use plant::served::ServedActuator;
use plant::ENCODER_COUNT_RAD;
use protocol::{Frame, Handler, Reply, Request, State, TelemetrySample};
use service::{Actuator, Service};

mod common;
use common::Cell;

struct Bench {
    actuator: Cell,
    service: Service,
    handler: Handler,
    world: ServedActuator,
    lines: BridgeLines,
    samples: Vec<TelemetrySample>,
    seq: u16,
}

impl Bench {
    fn new(load_nm: f32) -> Bench {
        let design = Design::paper();
        let config = Config::paper(Length::from_int(3));
        let sup = SupervisorConfig::DEFAULT;
        Bench {
            actuator: Cell(Actuator::new(Servo::new(&design, &config, &sup).unwrap())),
            service: Service::new(design, config, sup),
            handler: Handler::new(),
            world: ServedActuator::new(design, &config, load_nm).unwrap(),
            lines: BridgeLines::default(),
            samples: Vec::new(),
            seq: 0,
        }
    }

    fn ask(&mut self, req: Request) -> Reply {
        self.seq += 1;
        let mut dev = self.service.device(&mut self.actuator);
        self.handler
            .handle_request(Frame::new(self.seq, req), &mut dev)
            .body
    }

    fn run(&mut self, ticks: u32) {
        for _ in 0..ticks {
            let a = &mut self.actuator.0;
            let r = self.world.tick(self.lines, a.servo.controller().schedule());
            let input = TickInput {
                link_encoder: r.link_encoder,
                gear_pot: Some(r.gear_pot),
                current_adc: r.current_adc,
                read_error: None,
            };
            let out = a.servo.tick(&input);
            self.lines = BridgeLines::for_demand(out.bridge);
            if let Some((_, s)) = a.after_tick(&input, &out) {
                self.samples.push(s);
            }
            assert!(out.new_fault.is_none(), "fault {:?}", out.new_fault);
        }
    }
}

#[test]
fn a_commanded_move_with_the_load_meets_the_controller_tolerances() {
    let mut b = Bench::new(0.3);
    b.run(50);
    assert_eq!(b.ask(Request::Enable), Reply::Ok);
    // Telemetry from the start of the hold: the samples before the move give its start.
    assert_eq!(b.ask(Request::StreamTelemetry { rate_hz: 500 }), Reply::Ok);
    // The load is hung on at the first driven tick; let the hold take it.
    b.run(1000);
    let command_tick = b.actuator.0.servo.ticks();
    let target = 500_000.0;
    assert_eq!(
        b.ask(Request::Move {
            target_urad: 500_000,
            duration_ms: 300
        }),
        Reply::Ok
    );
    b.run(1500);
    // The figures of `plant::metrics`, clock from the command. The measured angle is the
    // centre of its count: ±1 count of the true angle is ≤ 1.5 counts of it. Steady from
    // 400 ms: settled by then and stays.
    let count_urad = ENCODER_COUNT_RAD * 1e6;
    let start = b
        .samples
        .iter()
        .rev()
        .find(|s| s.tick <= command_tick)
        .map(|s| f64::from(s.link_angle_urad))
        .expect("samples before the move");
    let mut step = StepResponse::new(start, target, 1.5 * count_urad, 0.4);
    for s in b.samples.iter().filter(|s| s.tick > command_tick) {
        let t_s = f64::from(s.tick - command_tick) * 1e-3;
        step.record(t_s, f64::from(s.link_angle_urad));
    }
    let f = step.figures();
    eprintln!(
        "overshoot {:.2} %, settling {:?} s, largest error from 400 ms on {:.2} counts",
        f.overshoot_pct,
        f.settling_time_s,
        f.steady_state_error / count_urad
    );
    assert!(f.overshoot_pct <= 5.0, "{f:?}");
    assert!(f.settling_time_s.is_some_and(|t| t <= 0.4), "{f:?}");
    assert!(f.steady_state_error <= 1.5 * count_urad, "{f:?}");
    match b.ask(Request::GetStatus) {
        Reply::Status(s) => {
            assert_eq!(s.state, State::Enabled);
            assert!(s.faults.is_empty());
            assert!(!s.moving);
        }
        other => panic!("{other:?}"),
    }
}
