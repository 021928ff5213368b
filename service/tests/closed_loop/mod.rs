//! The service closing the loop on the host, as the firmware's control tick does: the
//! simulated actuator of a serving board (`plant::served`) → raw readings → servo → the
//! actuator's bridge demand (a nudge's, or the servo's) → the bridge lines; protocol
//! requests through the handler between ticks, as the link task applies them.

use model::control::Config;
use model::servo::{Servo, TickInput, TickOutput};
use model::supervisor::SupervisorConfig;
use model::{Design, Length};
use plant::scenario::BridgeLines;
use plant::served::ServedActuator;
use protocol::{Frame, Handler, Reply, Request};
use service::{Actuator, Service};

use crate::common::Cell;

/// A serving board without the UART.
pub struct Bench {
    pub actuator: Cell,
    pub service: Service,
    handler: Handler,
    world: ServedActuator,
    lines: BridgeLines,
    seq: u16,
}

impl Bench {
    /// The paper design at L = 3 mm, default supervision, `load_nm` hung on the link once
    /// the motor drives.
    pub fn new(load_nm: f32) -> Bench {
        let design = Design::paper();
        let config = Config::paper(Length::from_int(3));
        let sup = SupervisorConfig::DEFAULT;
        Bench {
            actuator: Cell(Actuator::aligned(
                Servo::new(&design, &config, &sup).unwrap(),
            )),
            service: Service::new(design, config, sup),
            handler: Handler::new(),
            world: ServedActuator::new(design, &config, load_nm).unwrap(),
            lines: BridgeLines::default(),
            seq: 0,
        }
    }

    /// The simulated actuator (to warm its motor or hang a load on it).
    #[allow(dead_code)] // not every test binary that shares this module uses it
    pub fn plant(&mut self) -> &mut plant::Plant {
        self.world.plant_mut()
    }

    /// One request, answered.
    pub fn ask(&mut self, req: Request) -> Reply {
        self.seq += 1;
        let mut dev = self.service.device(&mut self.actuator);
        self.handler
            .handle_request(Frame::new(self.seq, req), &mut dev)
            .body
    }

    /// One control tick; no fault may latch.
    pub fn step(&mut self) -> (TickInput, TickOutput) {
        let (input, out) = self.tick();
        assert!(out.new_fault.is_none(), "fault {:?}", out.new_fault);
        (input, out)
    }

    /// One control tick (the firmware's: `Actuator::control`), then what the command task
    /// does every tick (a finished calibration applied).
    pub fn tick(&mut self) -> (TickInput, TickOutput) {
        let a = &mut self.actuator.0;
        let r = self.world.tick(self.lines, a.servo.controller().schedule());
        let raw = TickInput {
            link_encoder: r.link_encoder,
            gear_pot: Some(r.gear_pot),
            current_adc: r.current_adc,
            supply_adc: Some(r.supply_adc),
            read_error: None,
        };
        let (out, demand) = a.control(&raw);
        let input = *a.pipeline.input();
        self.lines = BridgeLines::for_demand(demand);
        // The live values the status and the Dynamixel registers report, as the firmware's
        // tick publishes them.
        let _ = a.after_tick(&input, &out);
        self.service.finish_calibration(&mut self.actuator);
        (input, out)
    }
}
