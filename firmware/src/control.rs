//! The control period run by the 1 kHz tick: sensors (through the driver traits) → servo
//! (controller + supervisor, `model::servo`) → H-bridge driver, with the world around it
//! advanced first (on the emulated boards the simulated actuator; on the real board the
//! watchdog feed).
//!
//! The control step (sensor reads, [`Servo::tick`], the bridge writes) is timed on its own,
//! separately from the world's part (the plant on the emulated boards), in SysTick counts;
//! under QEMU icount these convert to instructions (see [`StepStats`]).

use crate::board::{self, Io, World};
use crate::timing;
use cortex_m::peripheral::{SCB, SYST};
use drivers::{AngleSensor, BridgeState, CurrentSensor};
use heapless::spsc::Producer;
use model::servo::{BridgeDemand, TickInput};
use model::supervisor::{Fault, Sensor};
use service::link::Sample;
use service::Actuator;

/// Per-tick cost accounting, SysTick counts (core clock).
#[derive(Clone, Copy, Debug, Default, defmt::Format)]
pub struct StepStats {
    /// Ticks counted.
    pub ticks: u32,
    /// Sum and largest cost of the control step (sensors → servo → bridge).
    pub step_sum: u64,
    /// Largest control step.
    pub step_max: u32,
    /// Sum of the world's part (the plant on the emulated boards).
    pub world_sum: u64,
    /// Largest world part.
    pub world_max: u32,
}

/// What one tick produced that the application must know about.
pub struct TickResult {
    /// A fault latched in this tick (the motor is already off).
    pub fault: Option<Fault>,
    /// The period overran.
    pub overran: bool,
    /// SysTick counts the whole tick took.
    pub busy_counts: u32,
    /// A telemetry sample went into the link's queue in this tick.
    pub sampled: bool,
}

/// The per-tick state: the board's I/O and the world around it (the servo is in the
/// [`Actuator`] shared with the link task).
pub struct ControlLoop {
    io: Io,
    world: World,
    last: TickInput,
    stats: StepStats,
    bridge_errors: u32,
}

impl ControlLoop {
    /// A loop over `io` in `world`.
    pub fn new(io: Io, world: World) -> Self {
        Self {
            io,
            world,
            last: TickInput {
                link_encoder: 0,
                gear_pot: None,
                current_adc: 2048,
                read_error: None,
            },
            stats: StepStats::default(),
            bridge_errors: 0,
        }
    }

    /// The cost accounting so far.
    pub fn stats(&self) -> StepStats {
        self.stats
    }

    /// H-bridge driver errors so far.
    pub fn bridge_errors(&self) -> u32 {
        self.bridge_errors
    }

    /// The world (scenario events on the emulated boards).
    pub fn world_mut(&mut self) -> &mut World {
        &mut self.world
    }

    /// Reads the three sensors; a failed read keeps the last value and is reported.
    fn read_inputs(&mut self) -> TickInput {
        let mut input = self.last;
        input.read_error = None;
        match self.io.link.read_counts() {
            Ok(v) => input.link_encoder = v,
            Err(_) => input.read_error = Some(Sensor::LinkEncoder),
        }
        match self.io.pot.read_counts() {
            Ok(v) => input.gear_pot = Some(v),
            Err(_) => input.read_error = Some(Sensor::GearPot),
        }
        match self.io.current.read_raw() {
            Ok(v) => input.current_adc = v,
            Err(_) => input.read_error = Some(Sensor::CurrentAdc),
        }
        self.last = input;
        input
    }

    /// Puts the servo's demand on the H-bridge; a driver error turns the bridge off.
    fn drive(&mut self, demand: BridgeDemand) {
        let result = match demand {
            BridgeDemand::Off if self.io.bridge.state() == BridgeState::Disabled => Ok(()),
            BridgeDemand::Off => self.io.bridge.disable(),
            BridgeDemand::Drive(duty) => {
                self.io.bridge.enable();
                self.io.bridge.drive(duty)
            }
        };
        if result.is_err() {
            self.bridge_errors = self.bridge_errors.saturating_add(1);
            let _ = self.io.bridge.disable();
        }
    }

    /// Runs one 1 ms control period of `actuator`'s servo. `entry` is the SysTick value
    /// when the interrupt handler started.
    #[inline(never)]
    /// A telemetry sample, when due, goes into `telemetry` (a full queue drops and counts
    /// it).
    pub fn tick(
        &mut self,
        entry: u32,
        actuator: &mut Actuator,
        telemetry: &mut Producer<'_, Sample>,
    ) -> TickResult {
        let plan = self.world.begin_tick(&mut self.io, &mut actuator.servo);
        let t1 = SYST::get_current();
        let input = self.read_inputs();
        let out = actuator.servo.tick(&input);
        self.drive(out.bridge);
        let t2 = SYST::get_current();
        let sampled = actuator.publish_tick(&input, &out, telemetry);
        if plan.overrun {
            busy_wait_past_deadline();
        }
        // SysTick pending again while we still run: the next period has already begun.
        let overran = SCB::is_pendst_pending();
        let busy_counts = timing::systick_elapsed(entry, SYST::get_current(), board::SYSCLK_HZ);
        let late = if overran {
            let f = actuator.servo.deadline_missed(busy_counts);
            if f.is_some() {
                self.drive(BridgeDemand::Off);
            }
            f
        } else {
            None
        };
        self.world.end_tick(&actuator.servo, &out, late, &self.io);

        let world = timing::systick_elapsed(entry, t1, board::SYSCLK_HZ);
        let step = timing::systick_elapsed(t1, t2, board::SYSCLK_HZ);
        let s = &mut self.stats;
        s.ticks = s.ticks.wrapping_add(1);
        s.step_sum = s.step_sum.wrapping_add(u64::from(step));
        s.step_max = s.step_max.max(step);
        s.world_sum = s.world_sum.wrapping_add(u64::from(world));
        s.world_max = s.world_max.max(world);
        TickResult {
            fault: out.new_fault.or(late),
            overran,
            busy_counts,
            sampled,
        }
    }
}

/// Fault injection: spins until the next SysTick period has begun and half of it has
/// passed, so this period takes 1.5 periods.
fn busy_wait_past_deadline() {
    while !SCB::is_pendst_pending() {
        cortex_m::asm::nop();
    }
    let half = SYST::get_reload() / 2;
    while SYST::get_current() > half {
        cortex_m::asm::nop();
    }
}
