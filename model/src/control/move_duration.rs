//! The shortest minimum-jerk move the actuator's limits allow (docs/design.md §11,
//! "Moves within the limits").
//!
//! A rest-to-rest minimum-jerk move over h in T peaks at |r̈| = (10/√3)·h/T² and
//! |ṙ| = (15/8)·h/T (module docs of [`super::trajectory`]). The rigid feed-forward asks
//! ff_acc·r̈ of the duty for the acceleration and ff_vel·ṙ for the speed; a commanded move
//! that would ask more than the limits give is stretched to the shortest T that keeps
//!
//! ```text
//! ff_acc·|r̈|_peak ≤ f_m·(u_i − |u_I|)   →   T ≥ √((10/√3)·h / a_max)
//! ff_vel·|ṙ|_peak ≤ f_v·(u_max − |u_I|)  →   T ≥ (15/8)·h / s_top
//! ```
//!
//! u_i the current limit and u_max the duty limit in duty terms, u_I the load the
//! integrator holds when the move is commanded (the worse of the two directions: a move
//! accelerates against the load or brakes against it), f_v = [`super::dash::VOLTAGE_FRACTION`]
//! (the raw step's top speed) and f_m = [`MOVE_CURRENT_FRACTION`]. Computed once per
//! command (one 128-bit division and an integer square root), never per tick. A move that
//! starts from a moving reference is bounded by the same rest-to-rest figures.

use fixed::types::I32F32;

use super::schedule::Schedule;
use super::trajectory::MAX_MOVE_MS;

/// Fraction of the current headroom (the current limit less the held load) a move's peak
/// acceleration may ask of the rigid feed-forward: a third, so that a link up to 3× the
/// configured inertia (the acceptance range of docs/design.md §9) still finds its peak
/// torque within the current limit. Measured on the acceptance grid (seeds 1 / 1000001,
/// design §11): ¼ and ½ of the headroom within two runs of it on the nominal actuators;
/// off-nominal overshoot violations 42 (¼), 46 (⅓), 50 (½), 53 (¾) of 250, settling 78,
/// 72, 73, 74.
pub const MOVE_CURRENT_FRACTION: I32F32 = I32F32::lit("0.3333333333");

/// (10/√3)·10⁶: the minimum-jerk peak acceleration factor, in ms² per s².
const PEAK_ACCEL_MS2: i128 = 5_773_503;
/// (15/8)·10³: the minimum-jerk peak speed factor, in ms per s.
const PEAK_SPEED_MS: i128 = 1_875;

/// The shortest duration, ms, of a minimum-jerk move from `from` to `target` (rad, I32F32
/// bits) with the integrator holding `hold_q16` (‰ Q16); 0 when the held load leaves no
/// headroom (the move then runs as commanded and the clamps decide). At most
/// [`MAX_MOVE_MS`].
#[must_use]
pub fn shortest_ms(sched: &Schedule, from: i64, target: i64, hold_q16: i32) -> u32 {
    // |h| < 2·10 000 rad (the trajectory's range) in Q32: below 2⁴⁶.
    let h = (i128::from(target) - i128::from(from)).abs();
    let hold = hold_q16.saturating_abs();
    let a_max = sched
        .move_accel_per_duty
        .apply(sched.i_lim_duty_q16.saturating_sub(hold)); // rad/s² Q16
    let top = sched
        .dash
        .top_per_duty
        .apply(sched.duty_lim_q16.saturating_sub(hold)); // rad/s Q16
    if a_max <= 0 || top <= 0 {
        return 0;
    }
    // h/a in s² is (h_q32/a_q16)·2⁻¹⁶; below 2⁴⁶·2²³ / 2¹⁶: no overflow.
    let t2_ms2 = h * PEAK_ACCEL_MS2 / (i128::from(a_max) << 16);
    let by_accel = i128::from(u64::try_from(t2_ms2).unwrap_or(u64::MAX).isqrt()) + 1;
    let by_speed = h * PEAK_SPEED_MS / (i128::from(top) << 16) + 1;
    u32::try_from(by_accel.max(by_speed).min(i128::from(MAX_MOVE_MS))).unwrap_or(MAX_MOVE_MS)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::control::Config;
    use crate::design::Design;
    use crate::units::Length;

    /// The paper preset at 2 mm with the default 1e-3 kg·m² link: the motor's 1.5 A binds
    /// (the beams allow 0.85·τ_cap = 1.96 N·m), so the oracle is the datasheet motor of
    /// design §3 alone, at the full 1000 ‰ duty limit.
    fn oracle_ms(h: f64, hold_nm: f64) -> f64 {
        let (kt, ke, r, bv, vs) = (1.0, 1.94, 8.0, 1e-3, 12.0);
        let j = 3.2e-3 + 1e-3;
        let i_lim = 1.5;
        // Headroom in current and in voltage the held load leaves.
        let a_max = (i_lim - hold_nm / kt) * kt / j / 3.0;
        let v_max = 0.85 * (vs - r * hold_nm / kt);
        let s_top = v_max / (ke + r * bv / kt);
        let by_accel = (10.0 / 3f64.sqrt() * h / a_max).sqrt();
        let by_speed = 15.0 / 8.0 * h / s_top;
        by_accel.max(by_speed) * 1e3
    }

    fn schedule() -> Schedule {
        Schedule::new(&Design::paper(), &Config::paper(Length::from_int(2))).unwrap()
    }

    fn rad(x: f64) -> i64 {
        (x * 4_294_967_296.0) as i64
    }

    #[test]
    fn matches_the_rigid_motor_oracle() {
        let s = schedule();
        for (h, hold_nm) in [
            (0.05, 0.0),
            (0.2, 0.0),
            (0.5, 0.0),
            (0.5, 0.3),
            (-0.6, -0.2),
        ] {
            // The held load as the integrator's duty: R/k_t·τ in V, ×1000/V_s.
            let hold_q16 = (hold_nm * 8.0 * 1000.0 / 12.0 * 65536.0) as i32;
            let got = f64::from(shortest_ms(&s, rad(0.1), rad(0.1 + h), hold_q16));
            let want = oracle_ms(f64::abs(h), f64::abs(hold_nm));
            assert!(
                (got - want).abs() <= 0.01 * want + 1.5,
                "h {h} hold {hold_nm}: {got} ms vs {want:.1} ms"
            );
        }
    }

    #[test]
    fn no_headroom_keeps_the_commanded_move() {
        let s = schedule();
        // A held load beyond the current limit.
        assert_eq!(shortest_ms(&s, 0, rad(0.5), i32::MAX), 0);
        // No distance: the ceiling's 1 ms.
        assert_eq!(shortest_ms(&s, rad(0.3), rad(0.3), 0), 1);
        // The longest distance stays within the trajectory's longest move.
        assert!(shortest_ms(&s, rad(-9_999.0), rad(9_999.0), 0) <= MAX_MOVE_MS);
    }
}
