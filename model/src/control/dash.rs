//! The raw step's reference: as fast as the actuator allows, planned from its limits
//! (docs/design.md §11, "Raw steps").
//!
//! The time-optimal rest-to-rest move of the rigid actuator (§10) accelerates at the
//! current limit until the supply's voltage binds, runs along the voltage limit (the
//! speed approaches the no-load speed exponentially with the mechanical time constant
//! τ_m = J·R/(k_t·k_e)) and brakes at the current limit. The profile is that with margins:
//! the acceleration uses `CURRENT_FRACTION` of the current headroom, the top speed
//! `VOLTAGE_FRACTION` of the duty headroom, both what the load the integrator holds when
//! the step is commanded leaves, so that the feed-forward of the rigid model alone drives the
//! actuator along it and the PID keeps the rest of the current and voltage for its
//! corrections. In speed s along the step (rad/s), per tick:
//!
//! ```text
//! s ← s + min(a_acc, (s_top − s)/τ_m)·dt                 (accelerate)
//! brake once s² ≥ 2·a_brake·d, d the distance left, then  (one division per step)
//! s ← s − a·dt,  a = s²/(2·d)                            (lands on the target)
//! ```
//!
//! with a_acc = f_i·(u_i − σ·u_I)/ff_acc, a_brake = f_i·(u_i + σ·u_I)/ff_acc and
//! s_top = f_v·(u_max − σ·u_I)/ff_vel in duty terms (u_i the current limit, u_max the
//! duty limit, u_I the integrator, ff_acc and ff_vel the feed-forward gains, σ the step's
//! sign): the feed-forward duty ff_vel·s + ff_acc·a + u_I then leaves (1 − f_i) of the
//! current headroom and (1 − f_v) of the duty headroom to the PID. While the output was at
//! the duty limit in the step's direction (an actuator slower than configured), the speed
//! holds instead of growing: the reference runs no faster than the link follows.
//!
//! The braking deceleration is lowered by the square of the ratio of the drive the model
//! asked for to the drive the output needed while the step accelerated, once the target is
//! within three braking distances (`BRAKE_SCALE_MAX`): a heavier link or a weaker motor
//! brakes earlier. Squared because the ratio under-reads a heavier link: it lags on the
//! beams while the gear accelerates.
//!
//! A small step (shorter than `SMALL_STEP_FREE_PLAYS`·φ_b) under a held load asks, in the
//! phase the load helps, no more than `CONTACT_FRACTION` of the load's own acceleration of
//! the link, and no less than `CONTACT_FLOOR_PER_RAD` per rad of step: the beams stay on
//! one wall instead of letting the link cross the free play near the target. A small step
//! of a floating link plans its profile to φ_b/2 short of the target (`FLOATING_SHORT_SHIFT`)
//! and lands on the target: its link crosses the free play as the braking begins.
//!
//! Formats: speeds Q16 rad/s, accelerations Q16 rad/s², positions I32F32 rad bits.

use super::gain::{q32_to_q16, sat_i32, sqrt_ratio_q16, Gain, Q16_ONE};
use super::schedule::{Schedule, TICKS_PER_S};

/// Fraction of the current headroom (the current limit less the held load) the profile's
/// acceleration and braking use. Measured on the acceptance grid (seeds 1 / 1000001, 250 +
/// 250 cases; docs/design.md §11, "Raw steps"): larger fractions are faster but a heavy
/// link's coupling overshoots each torque step (0.6: 3 and 20 runs above σ_allow; 0.25:
/// 0 and 7), smaller ones lose raw steps to the time bound (0.2: 114 misses of 117).
pub const CURRENT_FRACTION: fixed::types::I32F32 = fixed::types::I32F32::lit("0.25");
/// Fraction of the duty headroom (the duty limit less the held load) the profile's top
/// speed uses (0.7 and 0.95 measured within a few runs of it on the grid).
pub const VOLTAGE_FRACTION: fixed::types::I32F32 = fixed::types::I32F32::lit("0.85");

/// The per-configuration constants of the profile (part of the schedule; the current and
/// duty limits and dt are the schedule's own).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct DashGains {
    /// `CURRENT_FRACTION`/ff_acc, rad/s² per ‰ of current headroom.
    pub(crate) accel_per_duty: Gain,
    /// `VOLTAGE_FRACTION`/ff_vel, rad/s per ‰ of duty headroom.
    pub(crate) top_per_duty: Gain,
    /// dt/τ_m = dt·ff_vel/ff_acc per tick (the voltage-limited approach to s_top).
    pub(crate) beta: Gain,
    /// `CONTACT_FRACTION`·(torque per ‰)/J_l: the link acceleration a fraction of the held
    /// load gives the configured link, rad/s² per ‰ of held duty.
    pub(crate) accel_per_held: Gain,
}

/// A small step's phase that its load helps asks at most this fraction of the load's own
/// acceleration of the configured link, τ_L/J_l: the beams then stay pressed on one wall
/// for links up to 1/0.2 = 5 times the configured one as the held duty reads their load:
/// a link 3× heavier on a motor with R ×1.4 and k_t ×0.9 (the acceptance ranges,
/// docs/design.md §9) is 3·1.4/0.9 = 4.7×. Measured on the acceptance grid (30 seeds,
/// docs/design.md §11, "Small raw steps"): 0.35 (2.9×) left 66 more off-nominal
/// overshoots, 0.5 and 1.0 more still.
pub const CONTACT_FRACTION: fixed::types::I32F32 = fixed::types::I32F32::lit("0.2");
/// Steps shorter than this many free plays φ_b are small: one crossing of the free play,
/// 2·φ_b, is then more than 5 % of the step.
pub const SMALL_STEP_FREE_PLAYS: i32 = 40;
/// The least acceleration of that phase per rad of step, 1/s²: it takes at most √(2/70) =
/// 0.17 s, whatever the load.
pub const CONTACT_FLOOR_PER_RAD: i32 = 70;
/// A small step of a floating link (the integrator holding less than half
/// `FLOAT_LOAD_NM`) plans its profile to φ_b/2^this short of the target and lands on the
/// target: when the braking begins the link, pushed until then, flies on across the free
/// play to the gear's braking wall. Half the free play, measured on the acceptance grid
/// (90 seeds, docs/design.md §11, "Small raw steps of a floating link"): nominal overshoot
/// violations 939 → 853 / 757 / 755 / 830 for a quarter, half, three quarters and the whole
/// of φ_b.
pub const FLOATING_SHORT_SHIFT: u32 = 1;
/// The most the braking deceleration is lowered for an actuator that needed more drive to
/// accelerate than the model: ×1/3, a link three times the configured one (docs/design.md
/// §11, "Braking for the actuator the step met").
pub const BRAKE_SCALE_MAX: i32 = 3;
/// The braking is scaled only where the acceleration took more than this share of the
/// model's drive, per cent: a nominal actuator's output also carries the gear friction's and
/// the deflection's feed-forward and the PID's part, and a 0.5 rad step at L = 3 mm kept
/// its 152 ms (without the margin 156 ms, docs/design.md §11).
pub const DRIVE_MARGIN_PERCENT: i64 = 125;

/// `num / den` for Q32 `num` ≥ 0 and Q16 `den` > 0, as Q16 (rounded down, saturating; 0 for
/// `den` ≤ 0), through a 32-bit division (one `UDIV` on Cortex-M3/M4, where a 64-bit
/// division is a library call of a few hundred instructions): `num` is shifted right until
/// it fits 32 bits and the quotient shifted back. For the braking deceleration
/// a = s²/(2·d) ≈ a_brake ≥ 2⁻¹⁰ rad/s² the quotient keeps at least 12 significant bits
/// for steps up to 2¹⁰ rad at 2⁷ rad/s.
fn div_q32_by_q16(num: i64, den: i32) -> i32 {
    let (Ok(n), Ok(d)) = (u64::try_from(num), u32::try_from(den)) else {
        return 0;
    };
    if d == 0 {
        return 0;
    }
    let k = 32u32.saturating_sub(n.leading_zeros());
    let q = ((n >> k) as u32) / d; // n >> k < 2³²
    sat_i32(i64::from(q) << k)
}

/// A planned step, advanced once per tick.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Dash {
    target: i64,
    /// Where the profile brakes to (I32F32 rad bits): the target, or short of it by
    /// φ_b/2 for a floating link's small step (`FLOATING_SHORT_SHIFT`).
    aim: i64,
    /// +1 or −1: the step's direction.
    sign: i32,
    /// Speed along the step, rad/s Q16 (negative while a reversed start is undone).
    speed: i32,
    accel: i32,
    brake: i32,
    top: i32,
    beta: Gain,
    dt: Gain,
    /// The braking deceleration once braking started (0 before), rad/s² Q16.
    braking: i32,
    /// Σ over the accelerating ticks of the output's acceleration part (duty less the
    /// velocity feed-forward and the integrator), and of the rigid model's r̈ feed-forward,
    /// both in the step's direction, ‰ Q16.
    drive_actual: i64,
    drive_model: i64,
    /// The braking deceleration scaled by the square of their ratio, fixed once the target
    /// is within three braking distances (0 before), rad/s² Q16.
    brake_scaled: i32,
}

/// One tick of the profile: position (I32F32 bits), velocity and acceleration (Q16), and
/// whether the target is reached (the reference then holds).
pub(crate) struct DashTick {
    pub(crate) position: i64,
    pub(crate) velocity_q16: i32,
    pub(crate) acceleration_q16: i32,
    /// The change of speed along the step in this tick, Q16 (0 at the landing).
    pub(crate) change_q16: i32,
    pub(crate) done: bool,
}

/// The distance a tick covers from speed `s` to `next` along the step (trapezoidal rule),
/// I32F32 rad bits: the profile's own position rule, which the shaper replays.
#[inline]
pub(crate) fn travel(dt: Gain, s: i32, next: i32) -> i64 {
    dt.apply_wide(s.saturating_add(next)) >> 1
}

impl Dash {
    /// Plans a step from `position` moving at `velocity_q16` to `target`, with the
    /// integrator holding `hold_q16` (‰ Q16). `None` when the limits leave no
    /// acceleration or braking (a load beyond the current limit): the reference then jumps.
    #[must_use]
    pub(crate) fn plan(
        sched: &Schedule,
        position: i64,
        velocity_q16: i32,
        target: i64,
        hold_q16: i32,
    ) -> Option<Dash> {
        let sign = if target >= position { 1 } else { -1 };
        let hold = hold_q16.saturating_mul(sign);
        // The headroom the held load leaves, in each direction.
        let g = &sched.dash;
        let current = sched.i_lim_duty_q16;
        let accel = g.accel_per_duty.apply(current.saturating_sub(hold));
        let brake = g.accel_per_duty.apply(current.saturating_add(hold));
        let top = g
            .top_per_duty
            .apply(sched.duty_lim_q16.saturating_sub(hold));
        if accel <= 0 || brake <= 0 || top <= 0 {
            return None;
        }
        // A small step under a held load keeps the beams on the wall the load presses them
        // against: where the load helps (braking when it pulls against the step,
        // accelerating when it pulls along), the link follows the gear only as fast as the
        // load alone moves it, τ_L/J_l; asked for more, it leaves that wall, crosses the
        // free play and is caught on the other one, a count or more past the target.
        let h = q32_to_q16(target.saturating_sub(position)).saturating_abs();
        let small = h < sched.free_play_q16.saturating_mul(SMALL_STEP_FREE_PLAYS);
        let floating = hold.saturating_abs() < sched.float_load_q16 / 2;
        let (accel, brake) = if small && !floating {
            let lim = g
                .accel_per_held
                .apply(hold.saturating_abs())
                .max(h.saturating_mul(CONTACT_FLOOR_PER_RAD));
            if hold > 0 {
                (accel, brake.min(lim))
            } else {
                (accel.min(lim), brake)
            }
        } else {
            (accel, brake)
        };
        // A floating link's small step aims short: the free play it crosses as the braking
        // begins carries it the rest (φ_b/2 in Q32, at most half the step).
        let short = if small && floating {
            (i64::from(sched.free_play_q16) << (16 - FLOATING_SHORT_SHIFT)).min(i64::from(h) << 15)
        } else {
            0
        };
        Some(Dash {
            target,
            aim: if sign > 0 {
                target - short
            } else {
                target + short
            },
            sign,
            speed: velocity_q16.saturating_mul(sign),
            accel,
            brake,
            top,
            beta: g.beta,
            dt: sched.dt,
            braking: 0,
            drive_actual: 0,
            drive_model: 0,
            brake_scaled: 0,
        })
    }

    /// Takes this tick's drive: `actual` the output's acceleration part, `model` the rigid
    /// model's r̈ feed-forward (‰ Q16). Counted while the profile accelerates, until the
    /// braking deceleration is fixed (|Σ| < 2⁴⁷ for steps of up to 2¹⁵ ticks).
    #[inline]
    pub(crate) fn drive(&mut self, actual: i32, model: i32) {
        if self.brake_scaled == 0 && model.saturating_mul(self.sign) > 0 {
            self.drive_actual += i64::from(actual.saturating_mul(self.sign));
            self.drive_model += i64::from(model.saturating_mul(self.sign));
        }
    }

    /// The braking deceleration for the actuator the acceleration met:
    /// a_brake·(Σmodel/Σactual)² where the output needed more than `DRIVE_MARGIN_PERCENT` of
    /// what the model asked (a heavier link, a warm motor, a sagging supply), not below
    /// a_brake/3; a_brake as planned otherwise (the gear friction and the deflection's
    /// feed-forward are in the output's part, and a nominal actuator's ratio stays within the
    /// margin). The square, measured on the acceptance grid (docs/design.md §11, "The ratio
    /// squared"): a heavier link lags on the beams while the gear accelerates, and the ratio
    /// under-reads it. One 32-bit division, once a step.
    fn brake_for_drive(&self) -> i32 {
        let (a, m) = (self.drive_actual, self.drive_model);
        if m <= 0 || a.saturating_mul(100) <= m.saturating_mul(DRIVE_MARGIN_PERCENT) {
            return self.brake;
        }
        // Both to 15 bits (0 < m < a, so 2¹⁴ ≤ den < 2¹⁵ or den = a ≥ 1), the ratio in Q16
        // (≤ 1).
        let sh = (64 - a.leading_zeros()).saturating_sub(15);
        let den = (a >> sh) as i32;
        let ratio = i64::from((((m >> sh) as i32) << 16) / den);
        let ratio = ((ratio * ratio) >> 16) as i32; // ≤ 1 in Q16
        let ratio = ratio.max(Q16_ONE / BRAKE_SCALE_MAX);
        ((i64::from(self.brake) * i64::from(ratio)) >> 16) as i32
    }

    /// The free-play impact speed's factor for the drive the step met: √(a_brake'/a_brake),
    /// the square root of the scale its braking got (Q16; 1 until the braking is fixed), so
    /// the drive ratio itself: an impact's torque is v·√(k·J), so a link g times as heavy
    /// takes the same torque at 1/√g of the speed, and the braking's scale stands for 1/g.
    /// One 32-bit division; called out of line, where the impact limit is reached.
    #[must_use]
    pub(crate) fn impact_q16(&self) -> i32 {
        if self.brake_scaled == 0 || self.brake_scaled >= self.brake {
            return Q16_ONE;
        }
        sqrt_ratio_q16(div_q32_by_q16(
            i64::from(self.brake_scaled) << 16,
            self.brake,
        ))
    }

    /// The step's target.
    #[must_use]
    pub(crate) const fn target(&self) -> i64 {
        self.target
    }

    /// Whether the step goes up (+).
    pub(crate) const fn up(&self) -> bool {
        self.sign > 0
    }

    /// The tick, as the profile integrates it.
    pub(crate) const fn dt(&self) -> Gain {
        self.dt
    }

    /// Twice the largest change of speed the plan asks in a tick, Q16 (the braking that
    /// lands on the target can exceed the planned deceleration a little).
    pub(crate) fn max_change_q16(&self) -> i32 {
        self.dt.apply(self.accel.max(self.brake)).saturating_mul(2)
    }

    /// Advances one tick from `position`. Sign flips rather than products by the
    /// direction, and the 64-bit products only where a square needs them: this runs
    /// inside the control step's instruction budget.
    pub(crate) fn advance(&mut self, position: i64, limited: i32) -> DashTick {
        let s = self.speed;
        let up = self.sign > 0;
        let diff = self.aim.saturating_sub(position);
        let left = if up { diff } else { diff.saturating_neg() };
        let mut next = if self.braking == 0 && limited == self.sign && s > 0 {
            s // the drive is at its limit: no more speed than the actuator follows
        } else if self.braking == 0 {
            // The current limit or the voltage limit, whichever binds.
            let by_current = self.dt.apply(self.accel);
            let by_voltage = self.beta.apply(self.top.saturating_sub(s));
            s.saturating_add(by_current.min(by_voltage))
        } else {
            s.saturating_sub(self.dt.apply(self.braking))
        };
        // Distance covered in this tick (trapezoidal rule), Q32 rad.
        let mut travel = self::travel(self.dt, s, next);
        if self.braking == 0 && next > 0 && s > 0 {
            // Accelerating this tick would leave less than the braking distance,
            // s² ≥ 2·a_brake·d: brake from now on, at the deceleration that lands on the
            // target, a = s²/(2·d) (once per step).
            let left_after = q32_to_q16(left.saturating_sub(travel)).max(0);
            // Q32, < 2⁶². The scaled deceleration is at least a_brake/3: until the target is
            // within that braking distance it cannot call for braking, and then it is fixed.
            let s2 = i64::from(next) * i64::from(next);
            if self.brake_scaled == 0
                && s2 >= 2 * i64::from(self.brake / BRAKE_SCALE_MAX) * i64::from(left_after)
            {
                self.brake_scaled = self.brake_for_drive().max(1);
            }
            if self.brake_scaled != 0
                && s2 >= 2 * i64::from(self.brake_scaled) * i64::from(left_after)
            {
                let s2 = i64::from(s) * i64::from(s);
                self.braking = div_q32_by_q16(s2, q32_to_q16(left).saturating_mul(2)).max(1);
                next = s.saturating_sub(self.dt.apply(self.braking));
                travel = self::travel(self.dt, s, next);
            }
        }
        if self.braking != 0 && (next <= 0 || left <= travel) {
            return DashTick {
                position: self.target,
                velocity_q16: 0,
                acceleration_q16: 0,
                change_q16: 0,
                done: true,
            };
        }
        self.speed = next;
        let dv = next.saturating_sub(s).saturating_mul(TICKS_PER_S); // rad/s² Q16
        let (position, velocity_q16, acceleration_q16) = if up {
            (position.saturating_add(travel), next, dv)
        } else {
            (
                position.saturating_sub(travel),
                next.saturating_neg(),
                dv.saturating_neg(),
            )
        };
        DashTick {
            position,
            velocity_q16,
            acceleration_q16,
            change_q16: next.saturating_sub(s),
            done: false,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::{div_q32_by_q16, Dash, Q16_ONE};
    use crate::control::{Config, Schedule};
    use crate::design::Design;
    use crate::units::Length;

    /// A small step's phase that the held load helps is planned at 0.2 of the load's
    /// acceleration of the configured link (not below 70 rad/s² per rad); the other phase,
    /// and a large step, keep the current-limited plan. Oracle: the motor's datasheet
    /// values in f64, τ_L = held‰/1000·V_s·k_t/R.
    #[test]
    fn a_small_step_asks_no_more_than_the_held_load_gives_the_link() {
        let cfg = Config::paper(Length::from_int(3));
        let sched = Schedule::new(&Design::paper(), &cfg).unwrap();
        let m = cfg.motor;
        let (v, r, kt) = (
            m.supply_v.to_num::<f64>(),
            m.resistance_ohm.to_num::<f64>(),
            m.torque_constant.to_num::<f64>(),
        );
        let j_l = cfg.link_inertia.get().to_num::<f64>() * 1e-6;
        let q16 = |x: i32| f64::from(x) / 65536.0;
        let plan = |h: f64, held: f64| {
            Dash::plan(
                &sched,
                0,
                0,
                (h * 2f64.powi(32)) as i64,
                (held * 65536.0) as i32,
            )
            .unwrap()
        };
        let free = plan(0.1, 0.0);
        for held in [60.0, 120.0] {
            let tau = held / 1000.0 * v * kt / r;
            let want = (0.2 * tau / j_l).max(70.0 * 0.1);
            // The load pulls against the step: braking is the phase it helps.
            let against = plan(0.1, held);
            assert!(
                (q16(against.brake) - want).abs() < 1e-3 * want,
                "{held}: {}",
                q16(against.brake)
            );
            assert!(q16(against.accel) < q16(free.accel));
            // The load pulls along the step (the integrator holds against it): accelerating.
            let along = plan(-0.1, held);
            assert!(
                (q16(along.accel) - want).abs() < 1e-3 * want,
                "{held}: {}",
                q16(along.accel)
            );
            assert!(q16(along.brake) < q16(free.brake));
            // A large step keeps the current-limited plan.
            assert!(q16(plan(0.3, held).brake) > 1.2 * q16(against.brake));
            assert!(q16(plan(-0.3, held).accel) > 1.2 * q16(along.accel));
        }
    }

    /// A floating link's small step (nothing held) brakes to φ_b/2 short of its target and
    /// lands on the target; a held load's small step, and a floating link's step longer
    /// than 40·φ_b, brake to the target. Oracle: φ_b = c/R of the paper preset in f64
    /// (docs/design.md §2.2: c = t_c·θ_max, θ_max = σ_allow·l/(3·E·r), eqs. 5–6).
    #[test]
    fn a_floating_links_small_step_brakes_short_of_its_target() {
        let cfg = Config::paper(Length::from_int(3));
        let sched = Schedule::new(&Design::paper(), &cfg).unwrap();
        let theta_max = 1.5e9 * 8e-3 / (3.0 * 200e9 * 0.5e-3);
        let phi_b = 1e-3 * theta_max / 7.8e-3;
        let configured = sched.free_play().get().to_num::<f64>();
        assert!(
            (configured / phi_b - 1.0).abs() < 1e-3,
            "φ_b {configured} vs {phi_b}"
        );
        let q32 = 2f64.powi(32);
        // The farthest the profile gets before it lands, and where it lands (rad).
        let run = |h: f64, held: f64| {
            let target = (h * q32) as i64;
            let mut d = Dash::plan(&sched, 0, 0, target, (held * 65536.0) as i32).unwrap();
            let (mut position, mut far) = (0i64, 0f64);
            for _ in 0..10_000 {
                let t = d.advance(position, 0);
                position = t.position;
                if t.done {
                    assert_eq!(position, target, "{h} rad, {held} ‰: lands on the target");
                    return far;
                }
                far = far.max(position as f64 * h.signum() / q32);
            }
            panic!("{h} rad, {held} ‰: no landing");
        };
        for h in [0.05f64, -0.1, 0.15] {
            let short = h.abs() - run(h, 0.0);
            assert!(
                (short - phi_b / 2.0).abs() < 0.1 * phi_b,
                "{h} rad: {short} short"
            );
            // A held load: the contact rule's plan, braking to the target.
            assert!(
                h.abs() - run(h, 120.0 * h.signum()) < 0.1 * phi_b,
                "{h} rad held"
            );
        }
        assert!(0.3 - run(0.3, 0.0) < 0.1 * phi_b, "0.3 rad");
    }

    /// The braking deceleration is a_b·(Σmodel/Σactual)² of the drive handed in while the
    /// step accelerated (1.5 times the model's drive: 4/9 of the deceleration), never below
    /// a_b/3, and a_b where the output needed less than 1.25 times the model's; the impact
    /// speed's factor is the square root of that scale, 1 until the braking is fixed.
    #[test]
    fn braking_follows_the_drive_the_acceleration_took() {
        let cfg = Config::paper(Length::from_int(3));
        let sched = Schedule::new(&Design::paper(), &cfg).unwrap();
        for (factor, want) in [
            (1.5, 4.0 / 9.0),
            (1.6, 1.0 / 2.56),
            (2.0, 1.0 / 3.0),
            (5.0, 1.0 / 3.0),
            (1.2, 1.0),
            (0.5, 1.0),
        ] {
            let mut d = Dash::plan(&sched, 0, 0, 1i64 << 31, 0).unwrap();
            assert_eq!(d.impact_q16(), Q16_ONE);
            let mut position = 0;
            while d.braking == 0 {
                let t = d.advance(position, 0);
                position = t.position;
                let model = 20 << 16;
                d.drive((f64::from(model) * factor) as i32, model);
            }
            let got = f64::from(d.brake_scaled) / f64::from(d.brake);
            assert!((got - want).abs() < 1e-3, "×{factor}: {got}");
            let impact = f64::from(d.impact_q16()) / 65536.0;
            assert!(
                (impact / want.sqrt() - 1.0).abs() < 0.007,
                "×{factor}: {impact}"
            );
        }
    }

    #[test]
    fn the_narrow_division_matches_the_wide_one() {
        // Speeds 0.01 … 20 rad/s against distances 1e-4 … 5 rad: relative error < 2⁻¹².
        for s in [655i64, 6_554, 32_768, 327_680, 1_310_720] {
            for d in [7i32, 655, 6_554, 65_536, 327_680] {
                let num = s * s;
                let want = num / i64::from(d);
                let got = i64::from(div_q32_by_q16(num, d));
                let want = want.min(i64::from(i32::MAX));
                assert!(
                    (got - want).abs() <= (want >> 12).max(1),
                    "{s} {d}: {got} vs {want}"
                );
            }
        }
        assert_eq!(div_q32_by_q16(1 << 40, 0), 0);
        assert_eq!(div_q32_by_q16(-1, 5), 0);
    }
}
