//! The creep at rest: a link that came to rest more than a count off its target, with no
//! load to press it against a wall of the free play, is pushed there by the gear at a
//! crawl (docs/design.md §11, "The creep at rest"). The rest hold keeps the gear still
//! wherever the link stopped in the free play; with dry friction in the output bearing
//! that is anywhere within ±φ_b of the target. The f32 port uses the same rule.
//!
//! Whether the link has stopped is read from the link encoder alone: no count change for
//! `CREEP_STILL_TICKS` and for `CREEP_STILL_INTERVALS` times the interval between its
//! last two changes. A link that slows to a stop (friction) passes; one that drifts at a
//! constant speed through the free play (no friction) does not, unless a bounce off the
//! still gear has just changed its pace.
//!
//! The same still count times the push of a link that a load presses on a wall while it
//! stands off its target's count ([`Creep::press`], docs/design.md §11, "A light load one
//! count off").

use fixed::types::I32F32;

use super::gain::Gain;
use crate::sensors::ENCODER_HALF_COUNT_Q32;

/// Gear speed of the push, rad/s: an encoder count in 77 ms. A link without friction
/// leaves the push at this speed; 0.04 brought as many links with bearing friction within
/// a count but swung the duty more at rest (docs/design.md §11, "The creep at rest").
pub const CREEP_SPEED: I32F32 = I32F32::lit("0.02");
/// Ticks without a count change before a push may start (64 ms).
pub const CREEP_STILL_TICKS: u16 = 64;
/// … and at least this many times the interval between the last two count changes.
pub const CREEP_STILL_INTERVALS: u16 = 4;
/// Growth of the push's extra drive while the link does not move, ‰ Q16 per tick
/// (1000/2¹⁶ ‰, about 15 ‰ per second): the gear's and the bearing's friction are not
/// known, so the drive rises until the link moves.
pub const CREEP_BOOST_PER_TICK_Q16: i32 = 1000;
/// Ceiling of that extra drive, ‰: the push stays below the rest's 20 ‰ duty span on the
/// off-nominal grids (with 12 ‰, 64 of their runs over six seeds were above it, against
/// 54).
pub const CREEP_BOOST_MAX_PERMILLE: i32 = 8;

/// Ticks without a count change before a link that a load presses on a wall, off its
/// target's count, gets the configured Coulomb friction's duty towards the target (32 ms;
/// 16 swung the duty at rest more and latched more faults, 48 settled fewer runs,
/// docs/design.md §11, "A light load one count off").
pub const PRESS_STILL_TICKS: u16 = 32;
/// While it presses, the hold's integrator winds a 2^−`PRESS_WIND_SHIFT` part of the
/// press's duty more each tick, towards the target (the friction's duty in 32 ticks).
/// The gear's true friction may be three times the configured one (docs/design.md §9),
/// and a hold under a load sits anywhere within ±f of the load: breaking away towards
/// the target may take 2·f more than it, which K_i·e alone wound in hundreds of ms. Wound
/// into the integrator, not added to the press: once the link is in its count the
/// position term and the press drop out, and what the integrator keeps holds the gear
/// there (docs/design.md §11, "The press wound into the hold").
pub const PRESS_WIND_SHIFT: u32 = 5;

/// `CREEP_SPEED` in rad/s Q16.
pub(crate) const CREEP_SPEED_Q16: i32 = (CREEP_SPEED.to_bits() >> 16) as i32;
/// A count crossed within this many ticks while pushing: the link moves at twice the
/// push's speed or faster (thrown, not pushed), and the push stops.
const KICK_TICKS: u16 = (2 * ENCODER_HALF_COUNT_Q32 / (2 * CREEP_SPEED.to_bits() / 1000)) as u16;

const _: () = assert!(KICK_TICKS == 38);

/// The creep's state: the link's stillness and the push.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Creep {
    /// Ticks since the link's count last changed (saturating).
    still: u16,
    /// Ticks between its last two changes (saturating).
    interval: u16,
    /// Direction of the push, ±1, or 0 for none.
    dir: i8,
    /// Extra drive of the push, ‰ Q16, 0…`CREEP_BOOST_MAX_PERMILLE`.
    boost_q16: i32,
    /// A push happened since the reference last moved.
    pushed: bool,
}

impl Creep {
    /// No push, the link taken to have just moved.
    pub const NEW: Creep = Creep {
        still: 0,
        interval: 0,
        dir: 0,
        boost_q16: 0,
        pushed: false,
    };

    /// Whether a push happened since the reference last moved: the link may then have
    /// left it at the push's speed, and the rest hold's zone is twice as wide, so that the
    /// loop does not throw a link that drifts between the still gear's walls.
    #[must_use]
    pub const fn pushed(&self) -> bool {
        self.pushed
    }

    /// Ticks since the link's count last changed (saturating).
    #[must_use]
    pub const fn still(&self) -> u16 {
        self.still
    }

    /// The extra drive of the push, ‰ Q16 (0 without a push).
    #[must_use]
    pub const fn boost_q16(&self) -> i32 {
        self.boost_q16
    }

    /// One tick of a stationary reference, as [`Creep::update`], with the push's gear
    /// velocity reference (rad/s Q16, for the gear hold) and duty (‰ Q16): the velocity
    /// feed-forward `ff_vel` of ±`CREEP_SPEED` plus the configured Coulomb friction's duty
    /// `coulomb_duty_q16` and the extra drive; without a push, the duty of
    /// [`Creep::press`] for a link pressed on a wall off its count (`pressed_off`). Out of
    /// line: on the move's ticks, the control step's most expensive, it costs a branch.
    #[allow(clippy::too_many_arguments)]
    #[inline(never)]
    pub fn step(
        &mut self,
        delta: i32,
        resting: bool,
        in_count: bool,
        pressed_off: bool,
        e_q32: i64,
        ff_vel: Gain,
        coulomb_duty_q16: i32,
    ) -> (i32, i32) {
        let positive = e_q32 > 0;
        let beyond = e_q32.saturating_abs() > 2 * ENCODER_HALF_COUNT_Q32;
        let dir = self.update(delta, resting, in_count, positive, beyond);
        if dir == 0 {
            return (
                0,
                coulomb_duty_q16 * i32::from(self.press(pressed_off, positive)),
            );
        }
        let w = CREEP_SPEED_Q16 * i32::from(dir);
        let f = coulomb_duty_q16 + self.boost_q16;
        (
            w,
            ff_vel.apply(w).saturating_add(if dir > 0 { f } else { -f }),
        )
    }

    /// The push of a link that a load presses on a wall of the free play while it stands
    /// off its target's count (`pressed_off`, after this tick's [`Creep::update`]): the
    /// direction of the error (`positive`: r − θ_l > 0) once the link's count has not
    /// changed for `PRESS_STILL_TICKS`, else 0. A count's error asks little of the
    /// position term (a quarter of it for a load below `FLOAT_LOAD_NM`, whose loop is
    /// soft near the target) against the gear's dry friction, and the integrator took
    /// hundreds of ms to wind past it; the configured friction's duty ends that wait
    /// (docs/design.md §11, "A light load one count off"). It stops with the first count
    /// change and restarts after as many still ticks.
    #[must_use]
    pub const fn press(&self, pressed_off: bool, positive: bool) -> i8 {
        if !pressed_off || self.still < PRESS_STILL_TICKS {
            0
        } else if positive {
            1
        } else {
            -1
        }
    }

    /// What the press winds into the hold's integrator this tick, ‰ Q32: a
    /// 2^−`PRESS_WIND_SHIFT` part of its duty (`coulomb_duty_q16`, ‰ Q16) while it presses
    /// a loaded link that stands more than a count off its target (`pressed_beyond`: as
    /// `pressed_off` of [`Creep::press`], the integrator above `FLOAT_LOAD_NM`), else 0. A
    /// link in the neighbouring count is within the settling band, and a wound press threw
    /// it past the target.
    #[must_use]
    pub fn wind(&self, pressed_beyond: bool, positive: bool, coulomb_duty_q16: i32) -> i64 {
        i64::from(coulomb_duty_q16.saturating_mul(i32::from(self.press(pressed_beyond, positive))))
            << (16 - PRESS_WIND_SHIFT)
    }

    /// One tick of a stationary reference (a moving one resets the state to
    /// [`Creep::NEW`]): the link encoder's count change, whether the rest hold holds,
    /// whether the link is in the reference's count, and of the error r − θ_l to the
    /// count's centre whether it is positive and more than a count. Returns the push's
    /// direction (±1, 0 for none): towards the target from more than a count off, until
    /// the link is in the target's count, moves away from it, or is thrown.
    pub fn update(
        &mut self,
        delta: i32,
        resting: bool,
        in_count: bool,
        positive: bool,
        beyond: bool,
    ) -> i8 {
        if delta == 0 {
            self.still = self.still.saturating_add(1);
        } else {
            self.interval = self.still.saturating_add(1);
            self.still = 0;
        }
        self.pushed |= self.dir != 0;
        if !resting || in_count {
            self.dir = 0;
        } else if self.dir == 0 {
            let quiet = CREEP_STILL_TICKS.max(self.interval.saturating_mul(CREEP_STILL_INTERVALS));
            if self.still >= quiet && beyond {
                self.dir = if positive { 1 } else { -1 };
            }
        } else if (delta != 0 && self.interval <= KICK_TICKS) || positive != (self.dir > 0) {
            self.dir = 0;
        }
        if self.dir == 0 {
            self.boost_q16 = 0;
        } else if delta == 0 {
            self.boost_q16 =
                (self.boost_q16 + CREEP_BOOST_PER_TICK_Q16).min(CREEP_BOOST_MAX_PERMILLE << 16);
        }
        self.dir
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const COUNT: i64 = 2 * ENCODER_HALF_COUNT_Q32;

    /// `update` with the error r − θ_l, rad Q32.
    fn tick(c: &mut Creep, delta: i32, resting: bool, in_count: bool, e: i64) -> i8 {
        c.update(delta, resting, in_count, e > 0, e.abs() > COUNT)
    }

    /// `n` resting ticks without a count change at error `e`; the last direction.
    fn quiet(c: &mut Creep, n: usize, e: i64) -> i8 {
        (0..n).fold(0, |_, _| tick(c, 0, true, false, e))
    }

    #[test]
    fn a_pressed_link_off_its_count_gets_the_friction_duty_once_still() {
        let mut c = Creep::NEW;
        // Not resting (a load holds the link): the creep itself never pushes.
        for _ in 1..PRESS_STILL_TICKS {
            assert_eq!(tick(&mut c, 0, false, false, -COUNT), 0);
        }
        assert_eq!(c.press(true, false), 0);
        assert_eq!(tick(&mut c, 0, false, false, -COUNT), 0);
        assert_eq!((c.press(true, false), c.press(true, true)), (-1, 1));
        assert_eq!(c.press(false, true), 0);
        // Through `step`: no gear velocity reference, the friction's duty towards the
        // target; none for a link that is not pressed.
        let ff = Gain::from_int(1).expect("gain");
        assert_eq!(
            c.step(0, false, false, true, -COUNT, ff, 7 << 16),
            (0, -7 << 16)
        );
        assert_eq!(c.step(0, false, false, false, -COUNT, ff, 7 << 16), (0, 0));
        // A count change: the wait starts again.
        assert_eq!(c.step(1, false, false, true, -COUNT, ff, 7 << 16), (0, 0));
        assert_eq!(c.press(true, false), 0);
    }

    #[test]
    fn the_press_is_wound_into_the_hold_once_the_link_stands() {
        let mut c = Creep::NEW;
        // 16 ‰ of friction: half a ‰ a tick (2⁻⁵) in Q32, towards the target, once the
        // press is on; nothing before, nor for a link that is not pressed beyond a count.
        let half_permille_q32 = 1_i64 << 31;
        for _ in 1..PRESS_STILL_TICKS {
            tick(&mut c, 0, false, false, 2 * COUNT);
            assert_eq!(c.wind(true, true, 16 << 16), 0);
        }
        tick(&mut c, 0, false, false, 2 * COUNT);
        assert_eq!(c.wind(true, true, 16 << 16), half_permille_q32);
        assert_eq!(c.wind(true, false, 16 << 16), -half_permille_q32);
        assert_eq!(c.wind(false, true, 16 << 16), 0);
        // A count change: the wait starts again.
        tick(&mut c, 1, false, false, 2 * COUNT);
        assert_eq!(c.wind(true, true, 16 << 16), 0);
    }

    #[test]
    fn a_still_link_more_than_a_count_off_is_pushed_towards_the_target() {
        let mut c = Creep::NEW;
        // 63 quiet ticks: not yet; the 64th starts the push.
        assert_eq!(quiet(&mut c, 63, 3 * COUNT), 0);
        assert_eq!(tick(&mut c, 0, true, false, 3 * COUNT), 1);
        assert!(!c.pushed());
        // The drive grows while the link does not move, up to its ceiling.
        assert_eq!(c.boost_q16(), CREEP_BOOST_PER_TICK_Q16);
        quiet(&mut c, 1000, 3 * COUNT);
        assert_eq!(c.boost_q16(), CREEP_BOOST_MAX_PERMILLE << 16);
        assert!(c.pushed());
        // Pushed: the link moves a count after a long quiet and the push goes on, with
        // the drive it has; a count in one tick more is a thrown link, and it stops.
        assert_eq!(tick(&mut c, 1, true, false, 2 * COUNT), 1);
        assert_eq!(c.boost_q16(), CREEP_BOOST_MAX_PERMILLE << 16);
        assert_eq!(tick(&mut c, 1, true, false, 2 * COUNT), 0, "thrown");
        assert_eq!(c.boost_q16(), 0);
        // The other way round for a negative error; in the count it stops.
        let mut c = Creep::NEW;
        assert_eq!(quiet(&mut c, 64, -2 * COUNT), -1);
        assert_eq!(tick(&mut c, 1, true, true, 0), 0);
        assert!(c.pushed());
    }

    #[test]
    fn no_push_within_a_count_or_without_the_rest_hold() {
        let mut c = Creep::NEW;
        assert_eq!(
            quiet(&mut c, 500, COUNT),
            0,
            "one count off: within the limit"
        );
        let mut c = Creep::NEW;
        for _ in 0..500 {
            assert_eq!(tick(&mut c, 0, false, false, 3 * COUNT), 0, "no rest hold");
        }
        // Out of the rest hold the push stops, and the zone stays widened.
        let mut c = Creep::NEW;
        quiet(&mut c, 70, 3 * COUNT);
        assert_eq!(tick(&mut c, 0, false, false, 3 * COUNT), 0);
        assert!(c.pushed());
    }

    #[test]
    fn a_drifting_link_is_not_taken_for_a_still_one() {
        let mut c = Creep::NEW;
        // A count every 30 ticks: the quiet time needed is max(64, 4·30) = 120 ticks.
        for _ in 0..10 {
            quiet(&mut c, 29, 3 * COUNT);
            assert_eq!(tick(&mut c, 1, true, false, 3 * COUNT), 0);
        }
        assert_eq!(quiet(&mut c, 119, 3 * COUNT), 0);
        assert_eq!(
            tick(&mut c, 0, true, false, 3 * COUNT),
            1,
            "120 quiet ticks"
        );
    }

    #[test]
    fn the_kick_threshold_is_a_count_at_twice_the_push_speed() {
        // Independent: 2π/4096 rad over 2·0.02 rad/s, in 1 ms ticks.
        let ticks = (2.0 * core::f64::consts::PI / 4096.0) / (2.0 * 0.02) * 1000.0;
        assert_eq!(f64::from(KICK_TICKS), ticks.floor());
        assert_eq!(CREEP_SPEED_Q16, (0.02f64 * 65536.0) as i32);
    }
}
