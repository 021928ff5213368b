//! The service closing the loop on the host: protocol requests drive the servo that runs
//! the simulated actuator of a serving board (`plant::served`), tick by tick, as on the
//! emulated board but without the UART.

use model::control::Config;
use model::servo::{Servo, TickInput};
use model::supervisor::SupervisorConfig;
use model::{Design, Length};
use plant::scenario::BridgeLines;
use plant::served::ServedActuator;
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
    // The load is hung on at the first driven tick; let the hold take it.
    b.run(1000);
    assert_eq!(b.ask(Request::StreamTelemetry { rate_hz: 500 }), Reply::Ok);
    let start = b.samples.len();
    assert_eq!(
        b.ask(Request::Move {
            target_urad: 500_000,
            duration_ms: 300
        }),
        Reply::Ok
    );
    b.run(1500);
    let rec = &b.samples[start..];
    let count_urad = std::f64::consts::TAU / 4096.0 * 1e6;
    let target = 500_000.0;
    let first = f64::from(rec[0].link_angle_urad);
    let peak = rec
        .iter()
        .map(|s| f64::from(s.link_angle_urad))
        .fold(f64::MIN, f64::max);
    let overshoot = (peak - target) / (target - first) * 100.0;
    assert!(overshoot <= 5.0, "overshoot {overshoot:.2} %");
    // Settled within ±1 count of the target by 400 ms after the move started, and stays.
    let t0 = rec[0].tick;
    let late = rec.iter().filter(|s| s.tick >= t0 + 400);
    let worst = late
        .map(|s| (f64::from(s.link_angle_urad) - target).abs())
        .fold(0.0, f64::max);
    eprintln!(
        "overshoot {overshoot:.2} %, largest error from 400 ms on {:.2} counts",
        worst / count_urad
    );
    // The measured angle is the centre of its count: ±1 count is ≤ 1.5 counts from it.
    assert!(worst <= 1.5 * count_urad, "error {worst:.0} µrad");
    match b.ask(Request::GetStatus) {
        Reply::Status(s) => {
            assert_eq!(s.state, State::Enabled);
            assert!(s.faults.is_empty());
            assert!(!s.moving);
        }
        other => panic!("{other:?}"),
    }
}
