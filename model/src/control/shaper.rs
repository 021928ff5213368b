//! A raw step's reference at soft settings, through a zero-vibration (ZV) input shaper
//! (docs/design.md §11, "Raw steps at soft settings: the shaper").
//!
//! Where the beams set the loop's bandwidth (ω_a = √(k/J_l) below `BW_RATIO`·`BW_MAX`,
//! so ω_c = ω_a/5), the loop cannot damp the link ringing on the beams, and each torque
//! step of the raw step's profile ([`super::dash`]) sets it ringing at about ω_a. The
//! shaper splits every change of the profile into two halves π/ω_a apart,
//!
//! ```text
//! r_s(t) = ½·r(t) + ½·r(t − Δ),   Δ = round(π/ω_a / dt) ticks   (the same for ṙ and r̈)
//! ```
//!
//! so the ringing the second half starts cancels the first half's at ω_a, for the link the
//! controller is configured with; at the step's end the reference takes Δ ticks more. The
//! profile runs unshaped (its own position, its drive and braking rules), and the shaper
//! keeps its last `SHAPER_LEN` ticks. Per tick: one sample stored, one read, three
//! halvings and adds.
//!
//! Formats: positions I32F32 rad bits, stored as Q24 offsets from the step's start (a
//! step of up to 128 rad; 6e-8 rad resolution for the delayed half); ṙ and r̈ Q16.

use super::gain::sat_i32;

/// Ticks of profile the shaper keeps: the longest delay is `SHAPER_LEN` − 1 ticks, a
/// link ringing at 50 rad/s or faster (the acceptance range, docs/design.md §9, reaches
/// 53 rad/s: L = 8 mm with J_l = 5e-3 kg·m²); a slower one is shaped for 50 rad/s.
pub const SHAPER_LEN: usize = 64;
/// Bits dropped from a position offset when it is stored (Q32 → Q24).
const OFFSET_SHIFT: u32 = 8;

/// One stored tick of the unshaped profile.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct Sample {
    /// Position less the step's start, rad Q24.
    offset: i32,
    /// ṙ, rad/s Q16.
    velocity: i32,
    /// r̈, rad/s² Q16.
    acceleration: i32,
}

/// The shaper's state: its delay, the stored ticks and where the step started.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shaper {
    /// Δ in ticks, 1…`SHAPER_LEN` − 1; 0 when the reference is not shaped.
    delay: u8,
    /// Index of the newest sample.
    head: u8,
    /// The step's start, rad I32F32 bits.
    origin: i64,
    samples: [Sample; SHAPER_LEN],
}

impl Shaper {
    /// Off: the reference passes unshaped.
    pub const OFF: Shaper = Shaper {
        delay: 0,
        head: 0,
        origin: 0,
        samples: [Sample {
            offset: 0,
            velocity: 0,
            acceleration: 0,
        }; SHAPER_LEN],
    };

    /// A shaper of `delay` ticks for a step from rest at `origin` (I32F32 rad bits): its
    /// past is that rest. `delay` 0 (or none that fits) leaves it off.
    #[must_use]
    pub fn start(delay: u8, origin: i64) -> Shaper {
        if delay == 0 || usize::from(delay) >= SHAPER_LEN {
            return Shaper::OFF;
        }
        Shaper {
            delay,
            origin,
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

    /// Stores this tick of the profile and returns the shaped reference: the halves of
    /// this tick and of the one Δ ticks ago.
    #[inline]
    pub fn shape(&mut self, position: i64, velocity: i32, acceleration: i32) -> (i64, i32, i32) {
        let mask = SHAPER_LEN - 1;
        let head = (usize::from(self.head) + 1) & mask;
        self.head = head as u8;
        self.samples[head] = Sample {
            offset: sat_i32(position.saturating_sub(self.origin) >> OFFSET_SHIFT),
            velocity,
            acceleration,
        };
        let old = self.samples[(head + SHAPER_LEN - usize::from(self.delay)) & mask];
        let old_position = self
            .origin
            .saturating_add(i64::from(old.offset) << OFFSET_SHIFT);
        (
            (position >> 1).saturating_add(old_position >> 1),
            (velocity >> 1).saturating_add(old.velocity >> 1),
            (acceleration >> 1).saturating_add(old.acceleration >> 1),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const ONE: i64 = 1 << 32;

    #[test]
    fn a_jump_becomes_two_halves_delay_apart() {
        // The ZV shaper's impulse response: a jump of the profile from 0 to 1 rad shows
        // half of it at once and the rest Δ ticks later.
        let mut s = Shaper::start(5, 0);
        let out: Vec<i64> = (0..8).map(|_| s.shape(ONE, 0, 0).0).collect();
        assert_eq!(
            out,
            [ONE / 2, ONE / 2, ONE / 2, ONE / 2, ONE / 2, ONE, ONE, ONE]
        );
    }

    #[test]
    fn shaped_is_the_mean_of_now_and_delay_ago() {
        // Oracle: the sequence itself, averaged by hand with its own copy Δ = 3 ticks
        // older (the past before the start is the rest at the origin).
        let origin = 7 * ONE;
        let seq: Vec<(i64, i32, i32)> = (1..=20i64)
            .map(|k| {
                (
                    origin + k * k * (ONE / 1000),
                    (k * 131) as i32,
                    (1000 - k * 77) as i32,
                )
            })
            .collect();
        let mut s = Shaper::start(3, origin);
        for (k, &(p, v, a)) in seq.iter().enumerate() {
            let (op, ov, oa) = if k >= 3 { seq[k - 3] } else { (origin, 0, 0) };
            let (sp, sv, sa) = s.shape(p, v, a);
            // The stored position loses its 8 low bits (Q24): within 2⁸ LSB of the mean.
            assert!((sp - (p / 2 + op / 2)).abs() <= 1 << 8, "tick {k}");
            assert_eq!(sv, v.div_euclid(2) + ov.div_euclid(2), "tick {k}");
            assert_eq!(sa, a.div_euclid(2) + oa.div_euclid(2), "tick {k}");
        }
    }

    #[test]
    fn off_and_out_of_range_delays_stay_off() {
        assert!(!Shaper::start(0, ONE).on());
        assert!(!Shaper::start(SHAPER_LEN as u8, ONE).on());
        assert!(Shaper::start(SHAPER_LEN as u8 - 1, ONE).on());
    }

    #[test]
    fn the_longest_delay_reads_the_oldest_sample() {
        let d = SHAPER_LEN as u8 - 1;
        let mut s = Shaper::start(d, 0);
        for _ in 0..d {
            assert_eq!(s.shape(ONE, 0, 0).0, ONE / 2);
        }
        assert_eq!(s.shape(ONE, 0, 0).0, ONE);
    }
}
