//! The back-EMF observer's resistance, read from the duty jump a raw step or a probed
//! command starts with (docs/design.md §11, "The observer's resistance from a command's
//! first tick").
//!
//! The observer reads the gear velocity as ω̂ = d·w_d − n·w_n: d the applied duty (‰), n
//! the current sense's counts from its zero, w_d = V̂_s/(1000·k̂_e) and w_n =
//! R̂/(k̂_e·counts per A). A copper colder or warmer than configured makes w_n wrong, and
//! ω̂ then carries a bias (R − R̂)·i/k̂_e that follows the current: at 1 A, 0.8 rad/s for
//! R ×0.8, enough to hide a braking gear's closing speed from the free-play impact limit.
//!
//! A raw step from rest jumps the duty by Δd in one tick, and the current steps by Δn.
//! Before the jump the gear was held (its torque balanced), so within that tick its speed
//! changes only by what the added current accelerates it, Δω = k̂_t·Δi·dt/Ĵ_g (the gear
//! alone, crossing the free play). The observer agrees with that when
//!
//! ```text
//! Δd·w_d − Δn·w_n = Δω   ⇒   w_n = Δd·w_d/Δn − k̂_t·dt/(Ĵ_g·counts per A)
//! ```
//!
//! Both differences cancel the current sense's offset and the back-EMF before the jump;
//! the supply's and the current sense's gain errors are lumped into w_n as the observer
//! needs them. Measured on the 197 of the 255 raw steps of two off-nominal grid seeds
//! (1000101, 1000102) that gave one: 0.94…1.13 of the simulated motor's R/gain, the middle
//! 90 % within 0.97…1.03 (where the link is held in contact, some of the added torque
//! accelerates it as well).
//!
//! A minimum-jerk move starts with no jump of its own (and a raw step through the shaper
//! with half of one): from rest, its first tick adds a probe of [`PROBE_PERMILLE`] in its
//! direction and its second tick takes as much away, a doublet that leaves the gear about
//! 70 µrad further and with no speed of its own to keep. The second tick's duty does not
//! enter the estimate (its current is measured a tick later). The probe is added in the
//! control step ([`DutyJump::probe_step`]: two loads and two stores a tick).
//!
//! A chattering hold. On a motor warmer or colder than configured, a held load can make
//! the output alternate tick to tick between the loop's duty and the free-play impact
//! limit's, which the observer's bias (R − R̂)·i/k̂_e trips on every other tick (a hold
//! at R ×1.36 against 0.29 N·m: −559 / −45 ‰ for 400 ms, docs/design.md §11, "Runs that
//! ended far off"). While the reference stands, the link is still and the integrator holds
//! a load, two jumps of at least [`MIN_JUMP_PERMILLE`] of opposite signs in a row arm the
//! same estimate from the second: the gear is held by the load, and its speed changes
//! within the tick by what the jump's current gives it.
//!
//! The estimate runs after the control step (`Controller::track_speed`, the service's
//! per-tick work): per tick three stores and the count of ticks the reference has stood
//! ([`HELD_TICKS`]); on the step's second tick one 64-bit division.
//!
//! Formats: w_d, w_n and the correction in rad/s per ‰ or per count, Q32 (the schedule's).

use super::Command;
use crate::sensors::ADC_MID;
use crate::Angle;

/// Least duty jump, ‰, that gives an estimate: 100 ‰ is 1.2 V at 12 V, about 0.15 A
/// through 8 Ω. Measured on the off-nominal grid (seeds 1000101…1000130): 300, 200, 150,
/// 100 and 50 ‰ (with the least current step below alike) gave 1 432, 1 347, 1 312, 1 280
/// and 1 271 overshoot violations (1 493 without the estimate), the nominal grid unchanged.
pub const MIN_JUMP_PERMILLE: i32 = 100;
/// Least current step, counts (0.1 A): the sense's noise, 2 counts a sample, is then 3 %
/// of it.
pub const MIN_STEP_COUNTS: i32 = 100;
/// Largest |current| after the jump, counts: 90 % of the sense's half range (1 843 counts,
/// 1.8 A of its ±2 A).
pub const MAX_COUNTS: i32 = ADC_MID as i32 * 9 / 10;
/// Relative difference from the configured w_n, in thousandths, below which the
/// configured one stays: beyond the middle 90 % of the estimate's spread (±3 %, module
/// docs).
pub const TOLERANCE_PERMILLE: i64 = 50;
/// The estimate's range, in thousandths of the configured w_n: R ×0.8…×1.4 (copper from
/// cold to hot) times a current-sense gain of ±5 % (docs/design.md §9), with a margin.
/// Outside it, something else moved the current (a stalled or a bouncing gear).
pub const RANGE_PERMILLE: (i64, i64) = (700, 1600);
/// Duty a probed command from rest (a move, a loaded raw step through the shaper) adds to
/// its first tick and takes away on its second, ‰, in its direction: 150 ‰ is 1.8 V at
/// 12 V; through 11.2 Ω (R ×1.4) at 10.5 V and a sense 5 % low still 0.13 A, above
/// [`MIN_STEP_COUNTS`]. The gear gains k_t·Δi·dt/J_g ≈ 0.07 rad/s for a tick.
pub const PROBE_PERMILLE: i32 = 150;

/// Ticks the reference must have stood still, counted from the controller's start (on
/// enabling) or the last motion, before a command may read an estimate: the gear held,
/// its torque balanced. A move sent just after enabling, while the hold was still taking
/// up a load, read R from a gear the beams were accelerating (the emulated board's
/// power-up check, a 0.3 N·m load hung on at the first driven tick: in 17 runs the move
/// ended 0.4–3.6 counts off, twice beyond the check's 2; with the rule 16 of 16 at 0.43).
/// The grids' commands come after 500 ms of hold: their runs are the same with it.
pub const HELD_TICKS: u8 = 100;

/// The count of ticks the reference has stood still, `held`, after one more tick: one up
/// while it stands (at most [`HELD_TICKS`]), 0 once it moves. The rule for the controller
/// and the bench's f32 port.
#[must_use]
#[inline(always)]
pub fn held_after(held: u8, stationary: bool) -> u8 {
    if stationary {
        held.saturating_add(1).min(HELD_TICKS)
    } else {
        0
    }
}

/// The target of a command that probes its first tick, `None` for one that does not: a
/// move, and a raw step through the shaper (`shaped`) whose integrator holds a load
/// (`loaded`: the link on a wall). The rule for the controller and the bench's f32 port.
#[must_use]
pub fn probed_target(cmd: &Command, shaped: bool, loaded: bool) -> Option<Angle> {
    match *cmd {
        Command::Move { target, .. } => Some(target),
        Command::Step { target } if shaped && loaded => Some(target),
        _ => None,
    }
}

/// The jump's state across the command's first two ticks.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct DutyJump {
    /// Ticks until the estimate: 2 at the command, 0 when done or not armed.
    armed: u8,
    /// Ticks the reference has stood still (at most [`HELD_TICKS`]).
    held: u8,
    /// Duty of the tick before (‰) and current counts of the last tick.
    duty_prev: i32,
    counts_prev: i32,
    /// The duty jump under way, ‰ (set on the step's first tick).
    jump: i32,
    /// Duty the next control step adds, ‰ Q16, and the one after it: the probe on a
    /// probed command's first tick and its negative on the second, else 0.
    probe_q16: i32,
    probe_next_q16: i32,
}

impl DutyJump {
    /// Not armed.
    pub const NEW: DutyJump = DutyJump {
        armed: 0,
        held: 0,
        duty_prev: 0,
        counts_prev: 0,
        jump: 0,
        probe_q16: 0,
        probe_next_q16: 0,
    };

    /// A raw step was commanded: the next two ticks may give an estimate, if the reference
    /// stood still before it (`from_rest`), for [`HELD_TICKS`] at least (the gear held,
    /// its torque balanced).
    pub fn arm(&mut self, from_rest: bool) {
        self.armed = if from_rest && self.held >= HELD_TICKS {
            2
        } else {
            0
        };
        self.probe_q16 = 0;
        self.probe_next_q16 = 0;
    }

    /// A probed command (a move, a loaded raw step through the shaper) towards positive
    /// angles if `up`: from rest, its first tick adds [`PROBE_PERMILLE`] for the jump to
    /// read, its second takes it away.
    pub fn arm_probe(&mut self, from_rest: bool, up: bool) {
        self.arm(from_rest);
        if self.armed == 2 {
            let p = PROBE_PERMILLE << 16;
            self.probe_q16 = if up { p } else { -p };
            self.probe_next_q16 = -self.probe_q16;
        }
    }

    /// Duty to add to this control step's output, ‰ Q16: ± the probe on a probed command's
    /// first two ticks, else 0. Called once a control step (two loads, two stores).
    #[inline(always)]
    pub fn probe_step(&mut self) -> i32 {
        let p = self.probe_q16;
        self.probe_q16 = self.probe_next_q16;
        self.probe_next_q16 = 0;
        p
    }

    /// After each control step: the duty it put out (‰), the current it measured (counts
    /// from the sense's zero), whether the reference stands (`stationary`) and whether a
    /// held load keeps the gear still under it (`quiet`: a still link, the integrator
    /// holding a load; a chattering hold then gives an estimate too). Returns the
    /// observer's w_n (rad/s per count, Q32) on the step's second tick: the estimate when
    /// it differs from `configured` by more than [`TOLERANCE_PERMILLE`] and lies in
    /// [`RANGE_PERMILLE`], else `configured`; `None` on every other tick. `w_d`: the
    /// schedule's w_d (rad/s per ‰, Q32); `w_step`: k̂_t·dt/(Ĵ_g·counts per A) (rad/s per
    /// count, Q32).
    #[allow(clippy::too_many_arguments)]
    pub fn take(
        &mut self,
        duty: i32,
        counts: i32,
        stationary: bool,
        quiet: bool,
        configured: i64,
        w_d: i64,
        w_step: i64,
    ) -> Option<i64> {
        let (duty_prev, counts_prev) = (self.duty_prev, self.counts_prev);
        self.duty_prev = duty;
        self.counts_prev = counts;
        self.held = held_after(self.held, stationary);
        match self.armed {
            2 => {
                // The step's first tick: its duty is the jump; the current was measured
                // under the duty before.
                self.jump = duty.saturating_sub(duty_prev);
                self.armed = if self.jump.saturating_abs() >= MIN_JUMP_PERMILLE {
                    1
                } else {
                    0
                };
                None
            }
            1 => {
                self.armed = 0;
                let w = estimate(
                    self.jump,
                    counts.saturating_sub(counts_prev),
                    counts,
                    configured,
                    w_d,
                    w_step,
                );
                self.jump = duty.saturating_sub(duty_prev);
                Some(w)
            }
            _ => {
                // A held load chattering tick to tick (two jumps of either sign in a row,
                // the gear held by the load between them): each jump is read like a
                // command's first tick (module docs, "A chattering hold").
                let jump = duty.saturating_sub(duty_prev);
                let chatter = (jump > 0) != (self.jump > 0)
                    && self.jump.saturating_abs() >= MIN_JUMP_PERMILLE
                    && jump.saturating_abs() >= MIN_JUMP_PERMILLE;
                if quiet && self.held >= HELD_TICKS && chatter {
                    self.armed = 1;
                }
                self.jump = jump;
                None
            }
        }
    }
}

/// w_n from a duty jump `jump` (‰) and the current step `step` it gave (counts), the
/// current after it `counts`; `configured` when the step is too small, of the other sign,
/// out of the sense's range, or the estimate within the tolerance or out of range.
fn estimate(jump: i32, step: i32, counts: i32, configured: i64, w_d: i64, w_step: i64) -> i64 {
    if step.saturating_abs() < MIN_STEP_COUNTS
        || (step > 0) != (jump > 0)
        || counts.saturating_abs() > MAX_COUNTS
    {
        return configured;
    }
    // |jump| ≤ 2 000 and w_d < 2³⁶ (the schedule's bound): the product is below 2⁴⁷.
    let w = i64::from(jump) * w_d / i64::from(step) - w_step;
    let c = i128::from(configured);
    let (lo, hi) = RANGE_PERMILLE;
    let ratio = i128::from(w) * 1000;
    let within = (ratio - 1000 * c).abs() <= i128::from(TOLERANCE_PERMILLE) * c;
    if within || ratio < i128::from(lo) * c || ratio > i128::from(hi) * c {
        configured
    } else {
        w
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const Q32: f64 = 4_294_967_296.0;
    /// The configured motor (AX-12A class, docs/design.md §3): V_s, R, k_t, k_e, J_g.
    const VS: f64 = 12.0;
    const R: f64 = 8.0;
    const KT: f64 = 1.0;
    const KE: f64 = 1.94;
    const JG: f64 = 3.2e-3;
    const COUNTS_PER_A: f64 = 1024.0;

    /// The schedule's w_d, w_n and the step correction for the configured motor, Q32.
    fn configured() -> (i64, i64, i64) {
        let w_d = VS / (1000.0 * KE);
        let w_n = R / (KE * COUNTS_PER_A);
        let w_step = KT * 1e-3 / (JG * COUNTS_PER_A);
        (
            (w_d * Q32) as i64,
            (w_n * Q32) as i64,
            (w_step * Q32) as i64,
        )
    }

    /// A motor with resistance `r` and current-sense gain `gain` and offset `offset`
    /// (counts) holds `hold` N·m still, then its duty jumps from the holding duty to
    /// `jump` ‰ above it: the gear alone, Euler in 10 000 substeps of the tick, the current
    /// algebraic (V − k_e·ω)/R. Returns the duties and the sense's counts of the tick
    /// before and the tick after.
    fn jump(r: f64, gain: f64, offset: f64, hold: f64, jump: f64) -> ((i32, i32), (i32, i32)) {
        let i0 = hold / KT;
        let d0 = (1000.0 * r * i0 / VS).round();
        let d1 = d0 + jump;
        let v1 = d1 * VS / 1000.0;
        let (mut w, n) = (0.0f64, 10_000);
        let dt = 1e-3 / f64::from(n);
        for _ in 0..n {
            let i = (v1 - KE * w) / r;
            w += (KT * i - hold) / JG * dt;
        }
        let i1 = (v1 - KE * w) / r;
        let counts = |i: f64| (gain * COUNTS_PER_A * i + offset).round() as i32;
        ((d0 as i32, counts(i0)), (d1 as i32, counts(i1)))
    }

    /// A gear held at `(duty, counts)` under a stationary reference for [`HELD_TICKS`].
    fn held(j: &mut DutyJump, (duty, counts): (i32, i32)) {
        let (w_d, w_n, w_step) = configured();
        for _ in 0..HELD_TICKS {
            assert_eq!(j.take(duty, counts, true, false, w_n, w_d, w_step), None);
        }
    }

    /// A command's first two ticks after `before`: the duty jumps to `after`'s, its
    /// current a tick late. What `take` returns on each.
    fn step_ticks(j: &mut DutyJump, before: (i32, i32), after: (i32, i32)) -> [Option<i64>; 2] {
        let (w_d, w_n, w_step) = configured();
        [
            j.take(after.0, before.1, true, false, w_n, w_d, w_step),
            j.take(after.0, after.1, true, false, w_n, w_d, w_step),
        ]
    }

    /// The step's two ticks through a freshly armed [`DutyJump`].
    fn estimated(before: (i32, i32), after: (i32, i32)) -> Option<i64> {
        let (w_d, w_n, w_step) = configured();
        let mut j = DutyJump::NEW;
        held(&mut j, before);
        j.arm(true);
        // The step's first tick: its duty is the jump, its current the one before.
        let [first, w] = step_ticks(&mut j, before, after);
        assert_eq!(first, None);
        assert_eq!(
            j.take(after.0, after.1, true, false, w_n, w_d, w_step),
            None,
            "once"
        );
        w
    }

    #[test]
    fn a_cold_motor_is_read_from_the_jump_through_the_sense_errors() {
        // R ×0.8, the sense 3 % high and 15 counts off, 0.1 N·m held, 400 ‰ jump: the
        // observer needs R/(k_e·gain·counts per A).
        for (r, gain, offset, hold, dj) in [
            (6.4, 1.03, 15.0, 0.1, 400.0),
            (6.4, 0.95, -20.0, -0.2, -600.0),
            (11.2, 1.0, 5.0, 0.0, 350.0),
        ] {
            let (before, after) = jump(r, gain, offset, hold, dj);
            let w = estimated(before, after).expect("an estimate") as f64 / Q32;
            let truth = r / (KE * gain * COUNTS_PER_A);
            assert!(
                (w / truth - 1.0).abs() < 0.01,
                "R {r}, gain {gain}: {w:e} against {truth:e}"
            );
        }
    }

    /// A hold at `before` that chatters between it and `after` for six ticks, the
    /// current a tick late: the estimates it gives.
    fn chattered(before: (i32, i32), after: (i32, i32), quiet: bool) -> Vec<i64> {
        let (w_d, w_n, w_step) = configured();
        let mut j = DutyJump::NEW;
        held(&mut j, before);
        let mut out = Vec::new();
        let ticks = [after, before, after, before, after, before];
        let mut counts = before.1;
        for (duty, next_counts) in ticks {
            out.extend(j.take(duty, counts, true, quiet, w_n, w_d, w_step));
            counts = next_counts;
        }
        out
    }

    #[test]
    fn a_chattering_hold_is_read_from_its_jumps() {
        // R ×1.4 against 0.29 N·m, the sense 2 % high and 12 counts off, the duty
        // alternating 500 ‰ below the hold and back (a warm motor's hold between the loop
        // and the impact limit): every jump after the first reads R.
        let (before, after) = jump(11.2, 1.02, -12.0, 0.29, -500.0);
        let truth = 11.2 / (KE * 1.02 * COUNTS_PER_A);
        let w = chattered(before, after, true);
        assert_eq!(w.len(), 2, "{w:?}");
        for w in w {
            let w = w as f64 / Q32;
            assert!((w / truth - 1.0).abs() < 0.03, "{w:e} against {truth:e}");
        }
        // Not while the link moves or floats.
        assert!(chattered(before, after, false).is_empty());
        // Nor from jumps one way only (a load taken up, not a chatter).
        let (w_d, w_n, w_step) = configured();
        let mut j = DutyJump::NEW;
        held(&mut j, before);
        for k in 1..6 {
            let duty = before.0 - 150 * k;
            assert_eq!(j.take(duty, before.1, true, true, w_n, w_d, w_step), None);
        }
    }

    #[test]
    fn a_motor_as_configured_keeps_the_configured_observer() {
        let (_, w_n, _) = configured();
        for (offset, hold, dj) in [(0.0, 0.0, 400.0), (20.0, 0.3, -700.0), (-20.0, -0.1, 300.0)] {
            let (before, after) = jump(R, 1.0, offset, hold, dj);
            assert_eq!(estimated(before, after), Some(w_n));
            // 1.5 % warmer: still within the tolerance.
            let (before, after) = jump(R * 1.015, 1.0, offset, hold, dj);
            assert_eq!(estimated(before, after), Some(w_n));
        }
    }

    #[test]
    fn a_move_from_rest_is_read_from_its_probe_and_the_probe_taken_back() {
        let (w_d, w_n, w_step) = configured();
        let p = PROBE_PERMILLE << 16;
        for (up, r, hold) in [(true, 6.4, 0.1), (false, 6.8, -0.15), (false, 11.2, 0.2)] {
            let dj = if up { PROBE_PERMILLE } else { -PROBE_PERMILLE };
            let (before, after) = jump(r, 1.02, -12.0, hold, f64::from(dj));
            let mut j = DutyJump::NEW;
            assert_eq!(j.probe_step(), 0);
            held(&mut j, before);
            j.arm_probe(true, up);
            // First tick: the probe in its duty; second: taken away, the estimate read.
            assert_eq!(j.probe_step(), if up { p } else { -p });
            assert_eq!(
                j.take(after.0, before.1, true, false, w_n, w_d, w_step),
                None
            );
            assert_eq!(j.probe_step(), if up { -p } else { p });
            let w = j
                .take(before.0, after.1, true, false, w_n, w_d, w_step)
                .expect("an estimate");
            assert_eq!(j.probe_step(), 0);
            let truth = r / (KE * 1.02 * COUNTS_PER_A);
            let w = w as f64 / Q32;
            assert!(
                (w / truth - 1.0).abs() < 0.01,
                "R {r}: {w:e} against {truth:e}"
            );
        }
        // Not from rest: no probe; a raw step: none either.
        let mut j = DutyJump::NEW;
        held(&mut j, (0, 0));
        j.arm_probe(false, true);
        assert_eq!(j.probe_step(), 0);
        j.arm(true);
        assert_eq!(j.probe_step(), 0);
        // The probe is the step's own, whether or not the ticks after it are taken: ±P,
        // then nothing.
        let mut j = DutyJump::NEW;
        held(&mut j, (0, 0));
        j.arm_probe(true, false);
        assert_eq!([j.probe_step(), j.probe_step(), j.probe_step()], [-p, p, 0]);
        // A first tick whose duty fell although the probe pushed (the loop braking a
        // moving gear): no estimate.
        let mut j = DutyJump::NEW;
        held(&mut j, (-580, -1142));
        j.arm_probe(true, true);
        assert_eq!(j.take(-634, -1142, true, false, w_n, w_d, w_step), None);
        assert_eq!(j.take(-690, -1150, true, false, w_n, w_d, w_step), None);
    }

    #[test]
    fn moves_and_loaded_shaped_steps_probe_and_nothing_else() {
        let target = Angle::from_int(1);
        let mv = Command::Move {
            target,
            duration_ms: 200,
        };
        let step = Command::Step { target };
        for (shaped, loaded) in [(false, false), (false, true), (true, false), (true, true)] {
            assert_eq!(probed_target(&mv, shaped, loaded), Some(target));
            let want = (shaped && loaded).then_some(target);
            assert_eq!(probed_target(&step, shaped, loaded), want);
            assert_eq!(probed_target(&Command::Hold, shaped, loaded), None);
        }
    }

    #[test]
    fn small_jumps_moving_gears_and_implausible_steps_give_nothing() {
        let (w_d, w_n, w_step) = configured();
        // A jump below `MIN_JUMP_PERMILLE`: no estimate on the second tick.
        let (before, after) = jump(6.4, 1.0, 0.0, 0.0, 80.0);
        assert_eq!(estimated(before, after), None);
        // Armed from a moving reference: nothing.
        let (before, after) = jump(6.4, 1.0, 0.0, 0.0, 400.0);
        let mut j = DutyJump::NEW;
        held(&mut j, before);
        j.arm(false);
        assert_eq!(step_ticks(&mut j, before, after), [None, None]);
        // A reference that has not stood `HELD_TICKS` yet (just enabled, or just stopped):
        // neither an estimate nor a probe; held long enough, both.
        let mut j = DutyJump::NEW;
        held(&mut j, before);
        j.take(before.0, before.1, false, false, w_n, w_d, w_step);
        for _ in 1..HELD_TICKS {
            j.take(before.0, before.1, true, false, w_n, w_d, w_step);
        }
        j.arm_probe(true, true);
        assert_eq!(j.probe_step(), 0);
        assert_eq!(step_ticks(&mut j, before, after), [None, None]);
        held(&mut j, before);
        j.arm_probe(true, true);
        assert_eq!(j.probe_step(), PROBE_PERMILLE << 16);
        assert_eq!(
            j.take(after.0, before.1, true, false, w_n, w_d, w_step),
            None
        );
        assert!(j
            .take(after.0, after.1, true, false, w_n, w_d, w_step)
            .is_some());
        // A current step of the other sign than the jump, one too small, one beyond the
        // sense's range, an estimate out of range: the configured observer.
        assert_eq!(estimate(400, -300, 300, w_n, w_d, w_step), w_n);
        assert_eq!(estimate(400, 80, 80, w_n, w_d, w_step), w_n);
        assert_eq!(estimate(400, 500, 1900, w_n, w_d, w_step), w_n);
        // 400 ‰ over 1000 counts reads about half the configured R: out of range.
        assert_eq!(estimate(400, 1000, 1000, w_n, w_d, w_step), w_n);
    }
}
