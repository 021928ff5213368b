//! A raw step's reference at soft settings, through a zero-vibration (ZV) input shaper
//! (docs/design.md §11, "Raw steps at soft settings: the shaper").
//!
//! Where the beams set the loop's bandwidth (ω_a = √(k/J_l) below `BW_RATIO`·`BW_MAX`,
//! so ω_c = ω_a/5), the loop cannot damp the link ringing on the beams, and each torque
//! step of the raw step's profile ([`super::dash`]) sets it ringing at about ω_a. Where,
//! too, half a ringing period is longer than the motor's mechanical time constant (a
//! faster ringing the motor's own lag smooths out), the shaper splits every change of the
//! profile into two halves π/ω_a apart (the delay: `Schedule`'s `shaper_ticks`),
//!
//! ```text
//! r_s(t) = ½·r(t) + ½·r(t − Δ),   Δ = round(π/ω_a / dt) ticks   (the same for ṙ and r̈)
//! ```
//!
//! so the ringing the second half starts cancels the first half's at ω_a, for the link the
//! controller is configured with; at the step's end the reference takes Δ ticks more. The
//! profile runs unshaped (its own position, its drive and braking rules). The delayed half
//! is the profile replayed: the shaper keeps the profile's change of speed along the step
//! in each of its last `SHAPER_LEN` ticks (an `i16`, Q16 rad/s: the controller's state is
//! copied whole while a board starts, a prepared configuration per scenario segment) and
//! integrates them Δ ticks late with the profile's own rule (`dash::travel`), so the
//! delayed half is the profile itself, bit for bit. Per tick: one change stored, one read,
//! one travel, three halvings and adds.
//!
//! Formats: positions I32F32 rad bits; ṙ, r̈ and the speed along the step Q16.

use super::dash;
use super::gain::Gain;
use super::schedule::TICKS_PER_S;
use super::trajectory::Reference;
use crate::units::Angle;

/// Ticks of profile the shaper keeps: the longest delay is `SHAPER_LEN` − 1 ticks, a
/// link ringing at 50 rad/s or faster (the acceptance range, docs/design.md §9, reaches
/// 53 rad/s: L = 8 mm with J_l = 5e-3 kg·m²); a slower one is shaped for 50 rad/s.
pub const SHAPER_LEN: usize = 64;
/// The stored change that marks the profile's landing on its target.
const LANDED: i16 = i16::MIN;
/// The largest change of speed a tick may store: a profile that changes its speed faster
/// (over 0.5 rad/s per tick) is not shaped.
pub const MAX_CHANGE_Q16: i32 = i16::MAX as i32;

/// The shaper's state: its delay, the stored changes and the delayed half's replay.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shaper {
    /// Δ in ticks, 1…`SHAPER_LEN` − 1; 0 when the reference is not shaped.
    delay: u8,
    /// Index of the newest change.
    head: u8,
    /// The delayed profile: its position (I32F32 rad bits) and speed along the step (Q16).
    position: i64,
    speed: i32,
    /// Change of speed along the step in each stored tick, Q16 (`LANDED` at the landing).
    changes: [i16; SHAPER_LEN],
}

impl Shaper {
    /// Off: the reference passes unshaped.
    pub const OFF: Shaper = Shaper {
        delay: 0,
        head: 0,
        position: 0,
        speed: 0,
        changes: [0; SHAPER_LEN],
    };

    /// A shaper of `delay` ticks for a step from rest at `origin` (I32F32 rad bits): its
    /// past is that rest. `delay` 0, one that does not fit, or a profile that may change
    /// its speed by more than `MAX_CHANGE_Q16` in a tick (`max_change_q16`) leave it off.
    #[must_use]
    pub fn start(delay: u8, origin: i64, max_change_q16: i32) -> Shaper {
        if delay == 0 || usize::from(delay) >= SHAPER_LEN || max_change_q16 > MAX_CHANGE_Q16 {
            return Shaper::OFF;
        }
        Shaper {
            delay,
            position: origin,
            ..Shaper::OFF
        }
    }

    /// Whether the reference is shaped.
    #[inline]
    #[must_use]
    pub const fn on(&self) -> bool {
        self.delay != 0
    }

    /// The delay Δ, ticks (0 when off).
    #[must_use]
    pub const fn delay(&self) -> u8 {
        self.delay
    }

    /// Stores this tick's change of speed along the step (`change_q16`, or the landing
    /// when `landed`), advances the delayed profile (direction `up`, tick `dt`, landing on
    /// `target`) and returns the shaped reference: the halves of this tick's `now` and of
    /// the delayed profile.
    #[inline]
    pub(crate) fn shape(
        &mut self,
        now: &Reference,
        change_q16: i32,
        landed: bool,
        up: bool,
        dt: Gain,
        target: i64,
    ) -> Reference {
        let mask = SHAPER_LEN - 1;
        let head = (usize::from(self.head) + 1) & mask;
        self.head = head as u8;
        // `start` bounds the profile's change: it fits (saturated all the same).
        self.changes[head] = if landed {
            LANDED
        } else {
            change_q16.clamp(-MAX_CHANGE_Q16, MAX_CHANGE_Q16) as i16
        };
        let old = self.changes[(head + SHAPER_LEN - usize::from(self.delay)) & mask];
        let (velocity, acceleration) = if old == LANDED {
            self.position = target;
            self.speed = 0;
            (0, 0)
        } else {
            let next = self.speed.saturating_add(i32::from(old));
            let travel = dash::travel(dt, self.speed, next);
            self.speed = next;
            let a = i32::from(old) * TICKS_PER_S;
            if up {
                self.position = self.position.saturating_add(travel);
                (next, a)
            } else {
                self.position = self.position.saturating_sub(travel);
                (next.saturating_neg(), -a)
            }
        };
        Reference {
            position: Angle::from_bits(
                (now.position.to_bits() >> 1).saturating_add(self.position >> 1),
            ),
            velocity_q16: (now.velocity_q16 >> 1).saturating_add(velocity >> 1),
            acceleration_q16: (now.acceleration_q16 >> 1).saturating_add(acceleration >> 1),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const ONE: i64 = 1 << 32;

    /// dt = 1 ms as the schedule builds it.
    fn dt() -> Gain {
        Gain::new(fixed::types::I64F64::ONE / 1000).unwrap()
    }

    /// A reference at `position` (I32F32 rad bits).
    fn at(position: i64, velocity_q16: i32, acceleration_q16: i32) -> Reference {
        Reference {
            position: Angle::from_bits(position),
            velocity_q16,
            acceleration_q16,
        }
    }

    /// A made-up profile along +: speeds (Q16) tick by tick from rest, landing at the end.
    fn profile(speeds: &[i32], origin: i64, target: i64) -> Vec<(Reference, i32, bool)> {
        let mut out = Vec::new();
        let (mut p, mut s) = (origin, 0);
        for &n in speeds {
            p += dash::travel(dt(), s, n);
            out.push((at(p, n, (n - s) * 1000), n - s, false));
            s = n;
        }
        out.push((at(target, 0, 0), 0, true));
        out
    }

    #[test]
    fn the_shaped_reference_is_the_mean_of_now_and_delay_ago() {
        // Oracle: the profile itself, averaged by hand with its own copy Δ = 4 ticks older
        // (the rest at the origin before the start).
        let origin = 3 * ONE;
        let speeds: Vec<i32> = (1..=12)
            .map(|k| 6000 * k.min(6))
            .chain([20_000, 9_000, 1_000])
            .collect();
        let seq = profile(&speeds, origin, 4 * ONE);
        let delay = 4;
        let mut s = Shaper::start(delay as u8, origin, 6000);
        let rest = at(origin, 0, 0);
        for (k, (now, change, landed)) in seq.iter().enumerate() {
            let old = if k >= delay { &seq[k - delay].0 } else { &rest };
            let got = s.shape(now, *change, *landed, true, dt(), 4 * ONE);
            let half = |a: i64, b: i64| a.div_euclid(2) + b.div_euclid(2);
            assert_eq!(
                got.position.to_bits(),
                half(now.position.to_bits(), old.position.to_bits()),
                "tick {k}"
            );
            assert_eq!(
                i64::from(got.velocity_q16),
                half(now.velocity_q16.into(), old.velocity_q16.into()),
                "tick {k}"
            );
            assert_eq!(
                i64::from(got.acceleration_q16),
                half(now.acceleration_q16.into(), old.acceleration_q16.into()),
                "tick {k}"
            );
        }
    }

    #[test]
    fn a_landing_shows_in_the_delayed_half_delay_ticks_later() {
        let mut s = Shaper::start(3, 0, 100);
        let landed = at(ONE, 0, 0);
        let got: Vec<i64> = (0..5)
            .map(|_| {
                s.shape(&landed, 0, true, true, dt(), ONE)
                    .position
                    .to_bits()
            })
            .collect();
        // The landing stored at the first tick is read at the fourth.
        assert_eq!(got, [ONE / 2, ONE / 2, ONE / 2, ONE, ONE]);
    }

    #[test]
    fn off_out_of_range_and_too_steep_profiles_stay_off() {
        assert!(!Shaper::start(0, ONE, 0).on());
        assert!(!Shaper::start(SHAPER_LEN as u8, ONE, 0).on());
        assert!(!Shaper::start(5, ONE, MAX_CHANGE_Q16 + 1).on());
        assert!(Shaper::start(SHAPER_LEN as u8 - 1, ONE, MAX_CHANGE_Q16).on());
    }
}
