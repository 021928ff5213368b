//! Catching a floating link at its target (docs/design.md §11, "Catching the floating
//! link").
//!
//! Without a load the link floats in the free play ±φ_b, and a still gear only bounces it
//! from wall to wall (each bounce keeps 0.65 of its speed or more, a heavy link's nearly
//! all). A wall that retreats at κ·v as a link moving at v meets it takes the link's speed
//! instead. So at rest, once the link is seen to bounce, the gear's walls are located from
//! the link's reversals and, when the encoder's edges show the link flying towards the
//! target, the gear's front wall is sent to arrive at the target, moving at κ·v, when the
//! link does, so that the link stops there.
//!
//! Everything is read from the link encoder's edges and the back-EMF observer, in encoder
//! counts: positions in counts Q16 relative to the target, speeds in counts per tick Q16.

use super::controller::COUNT_PER_TICK_Q16;
use super::creep::CREEP_STILL_INTERVALS;
use super::gain::{q16_to_q32, q32_to_q16, Gain, Q16_ONE};
use super::schedule::Schedule;
use crate::sensors::ENCODER_HALF_COUNT_Q32;

/// Wall speed at contact per link speed, κ, Q16 (0.4): 0.37 … 0.43 stopped as many links
/// on the grid; 0.3 and 0.5 about 60 % as many (docs/design.md §11).
pub const CATCH_KAPPA_Q16: i32 = 26_214;
/// At most this many catches per rest: a link that two catches did not stop is left to
/// the rest hold (more catches swung the duty in the rest without stopping more links).
pub const CATCH_MAX: u8 = 2;
/// The gear's position loop towards its planned wall, per tick (40 /s · 1 ms), Q16.
const LAMBDA_Q16: i64 = 2_621;
/// Depth of a reversal beyond the last edge, per (interval × speed): e/(1 + e) with the
/// still gear's restitution e ≈ 0.65, Q16.
const DEPTH_Q16: i64 = 25_821;
/// A catch is planned only for a target at least this far ahead (0.3 count, Q16) …
const MIN_AHEAD_Q16: i32 = 19_661;
/// … and at least this many ticks away: time for the gear to get there.
const MIN_TICKS: i32 = 40;
/// The contact shows as the gear pushed beyond 1.3 times its speed plus this margin
/// (0.004 rad/s in counts per tick, Q16).
const CONTACT_MARGIN_Q16: i32 = 171;
/// The catch goes on this many ticks after its contact shows (40 ms): a heavy link's
/// contact lasts some 20 ms, and a gear left to the damper two ticks into it stopped under
/// the link and gave it back most of its speed (docs/design.md §11).
const CONTACT_TICKS: u32 = 40;

/// Ticks in a row, from the rest hold's start, that its conditions must hold before the
/// catch takes the output (60 ms after the hold's 20: an earlier hand-over came while a
/// lightly loaded link settled, and delayed it; docs/design.md §11).
pub const CATCH_TICKS: u16 = 60;
/// Under the catch's damper, a gear that moves faster than this for `CATCH_LOAD_TICKS` is
/// pushed by a load: the output goes back to the loop with its integrator (10 mrad/s,
/// rad/s Q16).
pub const CATCH_LOAD_SPEED_Q16: i32 = 655;
/// See [`CATCH_LOAD_SPEED_Q16`].
pub const CATCH_LOAD_TICKS: u16 = 30;
/// A link that has not changed count for this many ticks (and four times the interval
/// between its last two changes) while more than a count off, within the rest zone, is
/// handed back to the loop (150 ms); the hand-over waits for a count change within as
/// many.
pub const CATCH_STILL_TICKS: u32 = 150;
/// One encoder count, rad Q16.
const COUNT_RAD_Q16: i32 = (ENCODER_HALF_COUNT_Q32 >> 15) as i32;
/// rad/s → encoder counts per tick, Q16 (0.6519): the inverse of `COUNT_PER_TICK_Q16`.
const COUNTS_PER_TICK_PER_RAD_S_Q16: i64 = (1i64 << 32) / COUNT_PER_TICK_Q16 as i64;
/// rad → encoder counts, Q16 (651.9): 1000 ticks a second.
const COUNTS_PER_RAD_Q16: i64 = COUNTS_PER_TICK_PER_RAD_S_Q16 * 1000;

/// What the control step knows of the rest this tick.
#[derive(Clone, Copy, Debug)]
pub struct Rest {
    /// |integrator|, ‰ Q16.
    pub load_abs: i32,
    /// |r − θ_l|, rad Q16.
    pub e_abs: i32,
    /// r − θ_l, rad Q32.
    pub e_q32: i64,
    /// Coupling torque estimate, N·m Q16.
    pub tau: i32,
    /// Link encoder count change this tick.
    pub delta: i32,
    /// Observer gear speed, rad/s Q16.
    pub w_gear: i32,
    /// The loop hunts at rest (`control::hunt`).
    pub hunting: bool,
    /// Ticks since the link's count last changed (saturating).
    pub still: u16,
}

/// The hand-over between the loop and the catch.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CatchHold {
    catch: Catch,
    /// Ticks the conditions have held.
    ticks: u16,
    /// The catch has the output; the integrator it set aside, ‰ Q16 (the catch takes it
    /// with less than `REST_LOAD_NM` held).
    active: bool,
    integ: i32,
    /// Ticks the gear has moved under the damper.
    push: u16,
    /// A load showed: no catch until the next command.
    blocked: bool,
}

impl CatchHold {
    /// The loop has the output.
    pub const NEW: CatchHold = CatchHold {
        catch: Catch::NEW,
        ticks: 0,
        active: false,
        integ: 0,
        push: 0,
        blocked: false,
    };

    /// The output (‰ Q16) while the catch has it, `None` while the loop has it; called
    /// while the reference stands still, `resting` once the rest hold has begun (the
    /// controller starts the hand-over afresh with every command). It takes the output
    /// once the rest hold's conditions, with the gear still and the link's count changed
    /// within [`CATCH_STILL_TICKS`] (a link that a light load holds on a wall has nothing
    /// to catch), have held for [`CATCH_TICKS`] more: the integrator is set aside and
    /// cleared, and the gear is a damper (duty 0: the back-EMF) except while a catch runs,
    /// when it follows the catch's speed (velocity feed-forward `ff_vel`, the configured
    /// Coulomb friction, K_d). A gear that keeps moving under the damper is pushed by a
    /// load, and a link that stands still more than a count off is the loop's to push: the
    /// loop gets the output back with its integrator until the next command. When the
    /// conditions lapse (the link beyond three rest zones, a hunt, a torque), the loop gets
    /// it back with its integrator too, and the hand-over starts again.
    /// Before the rest hold, a test of two flags here; the rest is out of line.
    #[inline]
    pub fn output(
        &mut self,
        s: &Schedule,
        integ: &mut i64,
        ff_vel: Gain,
        resting: bool,
        r: Rest,
    ) -> Option<i32> {
        if self.ticks == 0 && !resting {
            return None;
        }
        self.take(s, integ, ff_vel, r)
    }

    #[inline(never)]
    fn take(&mut self, s: &Schedule, integ: &mut i64, ff_vel: Gain, r: Rest) -> Option<i32> {
        let eligible = r.load_abs < s.rest_load_q16
            && !r.hunting
            && !self.blocked
            && (self.active
                || (r.w_gear.saturating_abs() < CATCH_LOAD_SPEED_Q16
                    && u32::from(r.still) < CATCH_STILL_TICKS))
            // Out to three rest zones once it has the output: a link that drifted further
            // off under the catch met the loop's full kick (docs/design.md §11).
            && r.e_abs <= if self.active { 3 } else { 2 } * s.rest_zone_q16
            && r.tau.saturating_abs() < s.rest_torque_q16;
        self.ticks = if eligible {
            self.ticks.saturating_add(1)
        } else {
            0
        };
        if self.ticks < CATCH_TICKS {
            if self.active {
                // Without its hold the loop met a link drifting off the zone with a kick
                // that took the beams past σ_allow (docs/design.md §11).
                *integ = q16_to_q32(self.integ);
                self.active = false;
            }
            return None;
        }
        if !self.active {
            self.active = true;
            self.catch = Catch::NEW;
            self.integ = q32_to_q16(*integ);
            self.push = 0;
            *integ = 0;
        }
        // |ω| < 2³¹ (rad/s Q16) times 0.65·2¹⁶: within i64.
        let w_counts = ((i64::from(r.w_gear) * COUNTS_PER_TICK_PER_RAD_S_Q16) >> 16) as i32;
        // The target less the link's count centre, and the free play 2·φ_b, in counts Q16:
        // rad Q16 × counts per rad (the zone bounds the first, the schedule the second).
        let target = ((r.e_q32 >> 16) * COUNTS_PER_RAD_Q16) >> 16;
        let gap = (i64::from(s.free_play_q16) * 2 * COUNTS_PER_RAD_Q16) >> 16;
        let w = self
            .catch
            .step(r.delta, target as i32, w_counts, gap as i32);
        // A link that stands still more than a count off, within the rest zone, is the
        // loop's to push (the creep, a light load's hold): it gets the output back with its
        // integrator. Beyond the zone the loop is not at rest and would throw it.
        if w == 0 && self.catch.still() && r.e_abs > COUNT_RAD_Q16 && r.e_abs <= s.rest_zone_q16 {
            return self.give_back(integ);
        }
        if w == 0 {
            self.push = if r.w_gear.saturating_abs() > CATCH_LOAD_SPEED_Q16 {
                self.push.saturating_add(1)
            } else {
                0
            };
            if self.push > CATCH_LOAD_TICKS {
                return self.give_back(integ);
            }
            return Some(0);
        }
        // counts per tick → rad/s, Q16.
        let w_rad = ((i64::from(w) * i64::from(COUNT_PER_TICK_Q16)) >> 16) as i32;
        let friction = if w > 0 {
            s.coulomb_duty_q16
        } else {
            -s.coulomb_duty_q16
        };
        Some(
            ff_vel
                .apply(w_rad)
                .saturating_add(friction)
                .saturating_add(s.kd.apply(w_rad.saturating_sub(r.w_gear))),
        )
    }

    /// The catch has the output.
    #[must_use]
    pub const fn active(&self) -> bool {
        self.active
    }

    /// The loop gets the output back with the integrator set aside, until the next
    /// command.
    fn give_back(&mut self, integ: &mut i64) -> Option<i32> {
        *integ = q16_to_q32(self.integ);
        self.blocked = true;
        self.active = false;
        None
    }
}

/// The catch's state during one rest.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Catch {
    /// Ticks since the rest began.
    tick: u32,
    /// Gear displacement since then, counts Q16 (the observer integrated).
    gear: i32,
    /// Direction of the link's last count change, ±1 (0 none yet).
    dir: i8,
    /// Tick of the last count change.
    last_edge: u32,
    /// Ticks between the last two count changes of the current flight.
    interval: u32,
    /// Speed of the current flight, counts per tick Q16 (0: not measured yet).
    speed: i32,
    /// Count changes since the last reversal.
    edges: u8,
    /// The lower wall at zero gear displacement, counts Q16 (valid once `known`).
    wall_lo: i32,
    known: bool,
    /// Planned gear displacement, counts Q16, and the wall's speed at contact.
    goal: i32,
    wall_speed: i32,
    /// Direction of the catch under way (0: none).
    plan: i8,
    /// A catch ended: no new one until the link is seen flying again.
    settled: bool,
    /// Planned length and last tick of the catch, and whether the contact showed.
    length: u32,
    end: u32,
    contact: bool,
    /// Catches this rest.
    catches: u8,
}

impl Catch {
    /// A rest that has just begun.
    pub const NEW: Catch = Catch {
        tick: 0,
        gear: 0,
        dir: 0,
        last_edge: 0,
        interval: 0,
        speed: 0,
        edges: 0,
        wall_lo: 0,
        known: false,
        goal: 0,
        wall_speed: 0,
        plan: 0,
        settled: false,
        length: 0,
        end: 0,
        contact: false,
        catches: 0,
    };

    /// One tick of a rest. `delta`: the link encoder's count change; `target`: the target
    /// less the link's count centre, counts Q16; `w_gear`: the observer's gear speed in
    /// counts per tick Q16; `gap`: the free play 2·φ_b in counts Q16. Returns the gear's
    /// speed reference, counts per tick Q16 (0: no catch under way).
    #[inline(never)]
    pub fn step(&mut self, delta: i32, target: i32, w_gear: i32, gap: i32) -> i32 {
        self.tick = self.tick.wrapping_add(1);
        self.gear = self.gear.saturating_add(w_gear);
        if delta != 0 {
            self.edge(delta, target, gap);
        }
        if self.plan != 0 {
            self.watch(w_gear);
        }
        if self.plan == 0 {
            return 0;
        }
        self.goal = self.goal.saturating_add(self.wall_speed);
        let pull = ((i64::from(self.goal) - i64::from(self.gear)) * LAMBDA_Q16) >> 16;
        let w = i64::from(self.wall_speed) + pull;
        // Never faster than the link its way (the rear wall would hit it), at most twice
        // its speed back.
        // In 32 bits (speed ≤ Q16_ONE, a count a tick): an i64 division is a library call
        // on the M3, a hundred instructions a tick while a catch runs.
        let ahead = i64::from(self.speed * 9 / 10);
        let back = 2 * i64::from(self.speed);
        let w = if self.plan > 0 {
            w.clamp(-back, ahead)
        } else {
            w.clamp(-ahead, back)
        };
        w as i32 // |w| ≤ 2·speed ≤ 2·Q16_ONE
    }

    /// A count change: a reversal locates a wall, two changes the same way time a flight,
    /// and a flight towards the target plans a catch.
    fn edge(&mut self, delta: i32, target: i32, gap: i32) {
        let d: i8 = if delta > 0 { 1 } else { -1 };
        // The boundary crossed, relative to the target: from below it is the count's lower
        // edge, from above its upper one (the count centre is `target` below the target).
        let half = Q16_ONE / 2;
        let boundary = if d > 0 { -half } else { half }.saturating_sub(target);
        let since = self.tick.wrapping_sub(self.last_edge).max(1);
        if self.dir != 0 && d != self.dir {
            // Reversed inside the count beyond the last boundary: at a wall.
            let vin = if self.speed > 0 {
                i64::from(self.speed)
            } else {
                i64::from(Q16_ONE as u32 / since)
            };
            let depth = ((i64::from(since) * vin * DEPTH_Q16) >> 16).clamp(0, i64::from(Q16_ONE));
            let wall = boundary.saturating_add(i32::from(self.dir) * depth as i32);
            self.wall_lo = if self.dir > 0 {
                wall.saturating_sub(gap).saturating_sub(self.gear)
            } else {
                wall.saturating_sub(self.gear)
            };
            self.known = true;
            self.edges = 1;
            self.speed = 0;
            self.plan = 0;
            self.settled = false;
        } else {
            self.edges = self.edges.saturating_add(1);
            if self.edges >= 2 {
                self.settled = false;
                self.interval = since;
                self.speed = Q16_ONE / i32::try_from(since).unwrap_or(i32::MAX);
            }
        }
        self.dir = d;
        self.last_edge = self.tick;
        if !self.known || self.speed == 0 || self.plan != 0 || self.settled {
            return;
        }
        if self.catches >= CATCH_MAX {
            return;
        }
        let front = if d > 0 {
            self.wall_lo.saturating_add(gap)
        } else {
            self.wall_lo
        }
        .saturating_add(self.gear);
        let ahead = boundary.saturating_neg().saturating_mul(i32::from(d));
        if ahead <= MIN_AHEAD_Q16 {
            return;
        }
        let ticks = ahead / self.speed;
        if ticks <= MIN_TICKS {
            return;
        }
        // The front wall at the target when the link gets there, moving at κ·v: it is
        // κ·v·ticks short of the target now, and its goal moves with it.
        let w = ((i64::from(self.speed) * i64::from(CATCH_KAPPA_Q16)) >> 16) as i32 * i32::from(d);
        self.wall_speed = w;
        self.goal = self
            .gear
            .saturating_sub(w.saturating_mul(ticks))
            .saturating_sub(front);
        self.plan = d;
        self.catches += 1;
        self.length = (ticks as u32) * 5 / 4;
        self.end = self.tick.wrapping_add(self.length + 10);
        self.contact = false;
    }

    /// Ticks since the link's count last changed.
    #[must_use]
    pub const fn quiet(&self) -> u32 {
        self.tick.wrapping_sub(self.last_edge)
    }

    /// The link stands still: its count has not changed for [`CATCH_STILL_TICKS`] nor for
    /// the creep's `CREEP_STILL_INTERVALS` times the interval between its last two changes
    /// (a slow drift is no stop; the creep's own rule, with the catch's wait).
    #[must_use]
    pub fn still(&self) -> bool {
        let intervals = self
            .interval
            .saturating_mul(u32::from(CREEP_STILL_INTERVALS));
        self.quiet() > CATCH_STILL_TICKS.max(intervals)
    }

    /// The catch under way: it ends [`CONTACT_TICKS`] after the contact shows in the
    /// observer (the link pushes the gear beyond its speed), when the link has stopped (no
    /// count change for three intervals), or a quarter late.
    fn watch(&mut self, w_gear: i32) {
        if !self.contact {
            let early = self.end.wrapping_sub(self.length / 2 + 10);
            let pushed = w_gear.saturating_mul(i32::from(self.plan));
            let bound =
                self.wall_speed.saturating_abs().saturating_mul(13) / 10 + CONTACT_MARGIN_Q16;
            if self.tick >= early && pushed > bound {
                self.contact = true;
                self.end = self.tick.wrapping_add(CONTACT_TICKS);
            }
        }
        let quiet = self.tick.wrapping_sub(self.last_edge);
        if quiet > 3 * self.interval + 10 || self.tick >= self.end {
            self.plan = 0;
            self.settled = true;
            self.edges = 0;
            self.speed = 0;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const COUNT: i32 = Q16_ONE;
    /// The free play of the paper preset, 2·5.128 mrad, in counts Q16 (6.686 counts).
    const GAP: i32 = 438_170;

    /// `n` ticks of a still link and a still gear.
    fn wait(c: &mut Catch, n: u32, target: i32) -> i32 {
        let mut w = 0;
        for _ in 0..n {
            w = c.step(0, target, 0, GAP);
        }
        w
    }

    #[test]
    fn a_still_link_is_left_alone() {
        let mut c = Catch::NEW;
        assert_eq!(wait(&mut c, 500, COUNT / 4), 0);
        assert!(!c.known);
    }

    /// A link flying up at one count per 20 ticks, 2.5 counts above its target, bounces
    /// off the gear's upper wall and comes back down at one count per 25 ticks: the wall is
    /// placed from the reversal, and the flight towards the target plans a catch whose
    /// front (lower) wall reaches the target, moving down at κ·v, when the link does.
    /// Expected values computed here from the geometry, in floating point.
    #[test]
    fn a_bounce_locates_the_walls_and_a_flight_towards_the_target_is_caught() {
        let q = f64::from(COUNT);
        let mut c = Catch::NEW;
        // `target`: the target less the link's count centre (counts Q16).
        let mut target = -5 * COUNT / 2;
        wait(&mut c, 19, target);
        target -= COUNT;
        c.step(1, target, 0, GAP); // up across 3 counts above the target
        wait(&mut c, 19, target);
        target -= COUNT;
        c.step(1, target, 0, GAP); // up across 4 counts
        assert_eq!(c.speed, COUNT / 20);
        // Reverses inside the count and comes back down across 4 counts, 10 ticks later.
        wait(&mut c, 9, target);
        target += COUNT;
        c.step(-1, target, 0, GAP);
        assert!(c.known);
        // Upper wall: 4 counts + 10 ticks × 1/20 count per tick × e/(1 + e), e = 0.65.
        let wall_hi = 4.0 + 10.0 / 20.0 * 0.65 / 1.65;
        let got = f64::from(c.wall_lo + GAP) / q;
        assert!((got - wall_hi).abs() < 1e-3, "{got} vs {wall_hi}");
        // Down across 3 counts 25 ticks later: 1/25 count per tick, 75 ticks from the target.
        wait(&mut c, 24, target);
        target += COUNT;
        let w = c.step(-1, target, 0, GAP);
        assert_eq!(c.speed, COUNT / 25);
        assert_eq!(c.plan, -1);
        let v = 1.0 / 25.0;
        let wall_speed = -0.4 * v;
        assert!((f64::from(c.wall_speed) / q - wall_speed).abs() < 1e-4);
        // The lower wall, now at wall_hi − 6.686 counts, must be at the target less
        // κ·v·75 ticks (moving down at κ·v it gets there with the link): the gear goes up
        // by the difference, first at the clamp of twice the link's speed.
        let lower = wall_hi - f64::from(GAP) / q;
        let goal = -wall_speed * 75.0 - lower;
        let got = f64::from(c.goal - c.wall_speed) / q;
        assert!((got - goal).abs() < 2e-3, "{got} vs {goal}");
        assert_eq!(
            w,
            2 * c.speed,
            "clamped at twice the link's speed towards it"
        );
        // Fed its own speed (a perfect servo), the gear's lower wall is at the target when
        // the link gets there, 75 ticks on, moving down.
        let mut w = w;
        for _ in 0..74 {
            w = c.step(0, target, w, GAP);
        }
        // Within the target's count (the position loop's lag leaves 0.2 count).
        let wall = f64::from(c.gear) / q + lower;
        assert!(wall.abs() < 0.5, "the wall {wall} counts from the target");
        assert!(w < 0, "{w}");
    }

    #[test]
    fn a_catch_ends_when_the_gear_is_pushed() {
        let mut c = Catch::NEW;
        c.known = true;
        c.plan = 1;
        c.speed = COUNT / 20;
        c.interval = 20;
        c.wall_speed = COUNT / 50;
        c.length = 100;
        c.end = 110;
        c.tick = 60;
        c.last_edge = 60;
        // Below 1.3 × the wall's speed: not a contact.
        c.step(0, 0, COUNT / 50 * 12 / 10, GAP);
        assert_eq!(c.plan, 1);
        // Pushed to twice the wall's speed: the contact, and the catch ends `CONTACT_TICKS`
        // later (before the link's three intervals of quiet would end it, at tick 131).
        c.step(0, 0, COUNT / 25, GAP);
        assert!(c.contact);
        for _ in 1..CONTACT_TICKS {
            c.step(0, 0, 0, GAP);
            assert_eq!(c.plan, 1);
        }
        c.step(0, 0, 0, GAP);
        assert_eq!(c.plan, 0);
        assert!(c.settled);
    }

    #[test]
    fn no_more_than_two_catches_a_rest() {
        let mut c = Catch::NEW;
        c.catches = CATCH_MAX;
        c.known = true;
        c.dir = -1;
        c.edges = 1;
        c.speed = COUNT / 25;
        c.last_edge = 0;
        c.tick = 25;
        c.step(-1, -4 * COUNT, 0, GAP);
        assert_eq!(c.plan, 0);
    }

    /// The paper preset's schedule at L = 3 mm.
    fn schedule() -> Schedule {
        use crate::control::Config;
        use crate::{Design, Length};
        Schedule::new(&Design::paper(), &Config::paper(Length::from_int(3))).unwrap()
    }

    /// A still link at its target, the gear still, with `load` (‰ Q16) in the integrator.
    fn at_rest(load: i32) -> Rest {
        Rest {
            load_abs: load.abs(),
            e_abs: 0,
            e_q32: 0,
            tau: 0,
            delta: 0,
            w_gear: 0,
            hunting: false,
            still: 0,
        }
    }

    /// 10 ‰ in the integrator, I32F32 bits.
    const INTEG: i64 = 10 << 32;

    /// A hand-over with `INTEG` held: [`CATCH_TICKS`] ticks of a still link at its target.
    fn handed_over(s: &Schedule) -> (CatchHold, i64) {
        let (mut h, mut integ) = (CatchHold::NEW, INTEG);
        for _ in 0..CATCH_TICKS {
            h.output(s, &mut integ, s.kd, true, at_rest(0));
        }
        (h, integ)
    }

    #[test]
    fn the_catch_takes_the_output_after_catch_ticks_of_the_rest_hold() {
        let s = schedule();
        let (mut h, mut integ) = (CatchHold::NEW, INTEG);
        // Half of `REST_LOAD_NM`: an unloaded move's leftover in the integrator.
        let load = s.rest_load_q16 / 2;
        // Before the rest hold has begun nothing counts.
        for _ in 0..100 {
            assert_eq!(h.output(&s, &mut integ, s.kd, false, at_rest(load)), None);
        }
        for _ in 1..CATCH_TICKS {
            assert_eq!(h.output(&s, &mut integ, s.kd, true, at_rest(load)), None);
            assert_eq!(integ, INTEG);
        }
        // The damper: duty 0, the integrator set aside.
        assert_eq!(h.output(&s, &mut integ, s.kd, true, at_rest(load)), Some(0));
        assert_eq!(integ, 0);
        assert_eq!(q16_to_q32(h.integ), INTEG);
    }

    #[test]
    fn a_held_load_or_a_moving_gear_keeps_the_output_with_the_loop() {
        let s = schedule();
        let mut integ = INTEG;
        // `REST_LOAD_NM` and more in the integrator.
        let mut h = CatchHold::NEW;
        for _ in 0..500 {
            let r = at_rest(s.rest_load_q16);
            assert_eq!(h.output(&s, &mut integ, s.kd, true, r), None);
        }
        // A link whose count has not changed for `CATCH_STILL_TICKS`: pressed on a wall.
        let mut h = CatchHold::NEW;
        for _ in 0..500 {
            let r = Rest {
                still: CATCH_STILL_TICKS as u16,
                ..at_rest(0)
            };
            assert_eq!(h.output(&s, &mut integ, s.kd, true, r), None);
        }
        // The gear moving at the load speed when the hand-over would come.
        let mut h = CatchHold::NEW;
        for _ in 0..500 {
            let r = Rest {
                w_gear: CATCH_LOAD_SPEED_Q16,
                ..at_rest(0)
            };
            assert_eq!(h.output(&s, &mut integ, s.kd, true, r), None);
        }
        assert_eq!(integ, INTEG);
    }

    #[test]
    fn a_gear_pushed_under_the_damper_gives_the_loop_back_its_integrator() {
        let s = schedule();
        let (mut h, mut integ) = handed_over(&s);
        assert_eq!(integ, 0);
        // The gear moves faster than the load speed under the damper, the link with it.
        let pushed = Rest {
            w_gear: 2 * CATCH_LOAD_SPEED_Q16,
            ..at_rest(0)
        };
        for _ in 0..CATCH_LOAD_TICKS {
            assert_eq!(h.output(&s, &mut integ, s.kd, true, pushed), Some(0));
        }
        assert_eq!(h.output(&s, &mut integ, s.kd, true, pushed), None);
        assert_eq!(integ, INTEG);
        // No catch again until the next command (which starts a new `CatchHold`).
        for _ in 0..500 {
            assert_eq!(h.output(&s, &mut integ, s.kd, true, at_rest(0)), None);
        }
        assert_eq!(integ, INTEG);
    }

    #[test]
    fn a_still_link_more_than_a_count_off_goes_back_to_the_loop() {
        let s = schedule();
        let (mut h, mut integ) = (CatchHold::NEW, INTEG);
        // 1.5 counts off the target, inside the zone, still.
        let off = Rest {
            e_abs: 3 * COUNT_RAD_Q16 / 2,
            e_q32: i64::from(3 * COUNT_RAD_Q16 / 2) << 16,
            ..at_rest(0)
        };
        for _ in 0..CATCH_TICKS {
            h.output(&s, &mut integ, s.kd, true, off);
        }
        assert_eq!(integ, 0);
        let mut ticks = 0;
        while h.output(&s, &mut integ, s.kd, true, off).is_some() {
            ticks += 1;
            assert!(ticks < 1000, "never handed back");
        }
        // The catch had the output for `CATCH_STILL_TICKS` ticks, the one that took it
        // included, and gives it back on the next.
        assert_eq!(ticks + 1, CATCH_STILL_TICKS);
        assert_eq!(integ, INTEG);
    }

    #[test]
    fn conditions_that_lapse_give_the_loop_back_its_integrator() {
        let s = schedule();
        let (mut h, mut integ) = handed_over(&s);
        assert_eq!(integ, 0);
        // Beyond twice the rest zone, within three: the catch keeps the output.
        let off = Rest {
            e_abs: 3 * s.rest_zone_q16,
            ..at_rest(0)
        };
        assert_eq!(h.output(&s, &mut integ, s.kd, true, off), Some(0));
        // The link drifts beyond three: the loop, with its hold.
        let far = Rest {
            e_abs: 3 * s.rest_zone_q16 + 1,
            ..at_rest(0)
        };
        assert_eq!(h.output(&s, &mut integ, s.kd, true, far), None);
        assert_eq!(integ, INTEG);
        // Not blocked: back within the zone, the hand-over starts again.
        for _ in 1..CATCH_TICKS {
            assert_eq!(h.output(&s, &mut integ, s.kd, true, at_rest(0)), None);
        }
        assert_eq!(h.output(&s, &mut integ, s.kd, true, at_rest(0)), Some(0));
        assert_eq!(integ, 0);
    }

    #[test]
    fn a_still_link_beyond_the_rest_zone_stays_with_the_catch() {
        let s = schedule();
        let (mut h, mut integ) = handed_over(&s);
        let off = Rest {
            e_abs: s.rest_zone_q16 + 1,
            e_q32: i64::from(s.rest_zone_q16 + 1) << 16,
            ..at_rest(0)
        };
        for _ in 0..4 * CATCH_STILL_TICKS {
            assert_eq!(h.output(&s, &mut integ, s.kd, true, off), Some(0));
        }
        assert_eq!(integ, 0);
    }

    /// A link drifting one count per 100 ticks is not still after `CATCH_STILL_TICKS`
    /// without a count change, only after four of its intervals.
    #[test]
    fn a_slow_drift_is_not_a_stop() {
        let mut c = Catch::NEW;
        let mut target = 0;
        for _ in 0..3 {
            wait(&mut c, 99, target);
            target -= COUNT;
            c.step(1, target, 0, GAP);
        }
        assert_eq!(c.interval, 100);
        wait(&mut c, CATCH_STILL_TICKS + 1, target);
        assert!(!c.still());
        wait(&mut c, 400 - CATCH_STILL_TICKS - 1, target);
        assert!(!c.still());
        wait(&mut c, 1, target);
        assert!(c.still());
    }
}
