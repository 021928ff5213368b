//! The bring-up mode against the simulated actuator of a serving board: raw readings over
//! the protocol, and an open-loop nudge that turns the motor, and so the gear pot and the
//! link encoder, in the direction of its duty, then stops by itself.

use protocol::{ErrorCode, RawSensors, Reply, Request, NUDGE_DUTY_MAX_PERMILLE};

mod closed_loop;
mod common;

struct Bench(closed_loop::Bench);

impl Bench {
    fn new() -> Bench {
        Bench(closed_loop::Bench::new(0.0))
    }

    fn ask(&mut self, req: Request) -> Reply {
        self.0.ask(req)
    }

    fn sensors(&mut self) -> RawSensors {
        match self.ask(Request::GetSensors) {
            Reply::Sensors(r) => r,
            other => panic!("GetSensors answered {other:?}"),
        }
    }

    fn run(&mut self, ticks: u32) {
        for _ in 0..ticks {
            self.0.step();
        }
    }
}

/// Signed change of an encoder reading through the wrap (counts of 4096).
fn link_delta(now: u16, before: u16) -> i32 {
    model::sensors::encoder_delta(now, before)
}

#[test]
fn a_nudge_turns_the_motor_its_way_and_stops_by_itself() {
    let mut b = Bench::new();
    b.run(20);
    let rest = b.sensors();
    assert_eq!(rest.tick, 20);
    assert_eq!(rest.nudge_duty_permille, 0);

    let duty = NUDGE_DUTY_MAX_PERMILLE as i16;
    let nudge = |duty_permille| Request::Nudge {
        duty_permille,
        duration_ms: 300,
    };
    assert_eq!(b.ask(nudge(duty)), Reply::Ok);
    b.run(150);
    let during = b.sensors();
    assert_eq!(during.nudge_duty_permille, duty);
    b.run(400);
    let forward = b.sensors();
    assert_eq!(
        forward.nudge_duty_permille, 0,
        "the nudge outlived its 300 ms"
    );
    let pot = |r: &RawSensors| i32::from(r.gear_pot.unwrap());
    assert!(pot(&forward) > pot(&rest) + 2, "{rest:?} → {forward:?}");
    assert!(
        link_delta(forward.link_encoder, rest.link_encoder) > 10,
        "{rest:?} → {forward:?}"
    );

    // The other way back.
    assert_eq!(b.ask(nudge(-duty)), Reply::Ok);
    b.run(700);
    let back = b.sensors();
    assert!(pot(&back) < pot(&forward) - 2, "{forward:?} → {back:?}");
    assert!(
        link_delta(back.link_encoder, forward.link_encoder) < -10,
        "{forward:?} → {back:?}"
    );

    // Settled and off: the readings stay put.
    b.run(300);
    let still = b.sensors();
    b.run(200);
    assert!((pot(&b.sensors()) - pot(&still)).abs() <= 1);
}

/// The link comes up before the control tick (the firmware enables its UART, then starts
/// SysTick): a reading asked for then does not exist, and must not come back as zeros.
#[test]
fn no_reading_before_the_first_tick() {
    let mut b = Bench::new();
    assert_eq!(b.ask(Request::GetSensors), Reply::Error(ErrorCode::Busy));
    b.run(1);
    let first = b.sensors();
    assert_eq!(first.tick, 1);
    assert!(first.gear_pot.is_some(), "{first:?}");
}

#[test]
fn a_nudge_is_bounded_and_only_for_a_disabled_motor() {
    let mut b = Bench::new();
    b.run(20);
    let too_hard = Request::Nudge {
        duty_permille: NUDGE_DUTY_MAX_PERMILLE as i16 + 1,
        duration_ms: 100,
    };
    assert_eq!(b.ask(too_hard), Reply::Error(ErrorCode::OutOfRange));
    for duration_ms in [0, protocol::NUDGE_DURATION_MAX_MS + 1] {
        let r = b.ask(Request::Nudge {
            duty_permille: 50,
            duration_ms,
        });
        assert_eq!(r, Reply::Error(ErrorCode::OutOfRange), "{duration_ms} ms");
    }
    let ok = Request::Nudge {
        duty_permille: 50,
        duration_ms: 1000,
    };
    assert_eq!(b.ask(ok), Reply::Ok);
    b.run(10);
    // Disable ends it at once.
    assert_eq!(b.ask(Request::Disable), Reply::Ok);
    b.run(1);
    assert_eq!(b.sensors().nudge_duty_permille, 0);
    assert_eq!(b.ask(Request::Enable), Reply::Ok);
    assert_eq!(b.ask(ok), Reply::Error(ErrorCode::NotAllowed));
}
