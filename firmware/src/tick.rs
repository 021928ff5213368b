//! One period of the 1 kHz control tick: the board's hooks first (on the emulated boards
//! the simulated actuator advances; on the real board the watchdog is fed), then the control
//! step: sensors (through the driver traits, `drivers::tick_io`) → the sensor-correction
//! layer and the servo (controller + supervisor; `service::Actuator::tick`,
//! `model::calibration::pipeline`) → H-bridge driver, then the missed-deadline check.
//!
//! The control step (sensor reads, `Servo::tick`, the bridge writes) is timed on its own,
//! separately from the hooks' part (the plant on the emulated boards), in SysTick counts;
//! under QEMU icount these convert to instructions (see [`StepStats`]).

use crate::board::{self, Hooks, Io, TickHooks};
use crate::timing;
use cortex_m::peripheral::{SCB, SYST};
use heapless::spsc::Producer;
use model::servo::BridgeDemand;
use model::supervisor::Fault;
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
    /// Sum of the board hooks' part (the plant on the emulated boards).
    pub hooks_sum: u64,
    /// Largest hooks' part.
    pub hooks_max: u32,
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

/// The per-tick state: the board's I/O and hooks (the servo is in the [`Actuator`] shared
/// with the link task).
pub struct ControlLoop {
    io: Io,
    hooks: Hooks,
    stats: StepStats,
}

impl ControlLoop {
    /// A loop over `io`, with the board's `hooks` around each step.
    pub fn new(io: Io, hooks: Hooks) -> Self {
        Self {
            io,
            hooks,
            stats: StepStats::default(),
        }
    }

    /// The cost accounting so far.
    pub fn stats(&self) -> StepStats {
        self.stats
    }

    /// The board's hooks (their events are for the log).
    pub fn hooks_mut(&mut self) -> &mut Hooks {
        &mut self.hooks
    }

    /// Runs one 1 ms control period of `actuator`'s servo. `entry` is the SysTick value
    /// when the interrupt handler started. A telemetry sample, when due, goes into
    /// `telemetry` (a full queue drops and counts it).
    #[inline(never)]
    pub fn tick(
        &mut self,
        entry: u32,
        actuator: &mut Actuator,
        telemetry: &mut Producer<'_, Sample>,
    ) -> TickResult {
        let plan = self.hooks.before_step(&mut self.io, &mut actuator.servo);
        let t1 = SYST::get_current();
        let raw = self.io.read_inputs();
        let (out, demand) = actuator.control(&raw);
        self.io.drive(demand);
        let t2 = SYST::get_current();
        let input = *actuator.pipeline.input();
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
                self.io.drive(BridgeDemand::Off);
            }
            f
        } else {
            None
        };
        self.hooks.after_step(&actuator.servo, &out, late, &self.io);

        let hooks = timing::systick_elapsed(entry, t1, board::SYSCLK_HZ);
        let step = timing::systick_elapsed(t1, t2, board::SYSCLK_HZ);
        let s = &mut self.stats;
        s.ticks = s.ticks.wrapping_add(1);
        s.step_sum = s.step_sum.wrapping_add(u64::from(step));
        s.step_max = s.step_max.max(step);
        s.hooks_sum = s.hooks_sum.wrapping_add(u64::from(hooks));
        s.hooks_max = s.hooks_max.max(hooks);
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
