//! A minimum-jerk move's velocity feed-forward for the actuator it meets (docs/design.md
//! §11, "The velocity feed-forward for the actuator a move meets").
//!
//! The velocity feed-forward (1000/V̂_s)·k̂_e·ṙ uses the configured supply and back-EMF
//! constant; a sagging supply or a different motor needs (V̂_s/V_s)·(k_e/k̂_e) of it, and the
//! PID supplies the rest only once the link lags. The back-EMF observer reads the gear
//! velocity through the same constants, ω̂ = (V̂_s·d/1000 − R̂·i)/k̂_e; with the true
//! V_s·d/1000 = R·i + k_e·ω,
//!
//! ```text
//! ω̂ = s·ω + c·i,   s = (V̂_s/V_s)·(k_e/k̂_e),   c = ((V̂_s/V_s)·R − R̂)/k̂_e
//! ```
//!
//! so s, the factor the velocity feed-forward is short by, is the observer's scale against
//! a true velocity, and c the bias a resistance error adds under current. While a loaded
//! move runs, the controller hands this tracker each tick's ω̂, current and gear position
//! (the link encoder plus the deflection the feed-forward planned: the gear's travel). Over
//! windows of `WINDOW` ticks it sums O = Σω̂, I = Σi and takes D = 1000·Δθ_g (rad/s·ticks,
//! like O), and fits O = s·D + c·I by least squares over the windows so far. Once the gear
//! has travelled `MIN_TRAVEL` and `MIN_WINDOWS` windows are in, the velocity feed-forward
//! is scaled by s, clamped to [`SCALE_MIN`, `SCALE_MAX`]. It runs after the control step
//! (`Controller::track_speed`, the service's per-tick work): per tick two adds, per window
//! five 32×32→64-bit products and a 2×2 solve with one 32-bit division.
//!
//! A loaded raw step runs the same fit after `RAW_MIN_TRAVEL` for its damping instead: where
//! s < 1 the derivative's filtered gear speed is led to ω̂/s after each tick
//! ([`SpeedScale::lead`]; docs/design.md §11, "The damping for the motor a raw step meets").
//!
//! Formats: ω̂ Q16 rad/s, i Q16 A, angles I32F32 rad bits, the scale Q16.

use super::gain::{q32_to_q16, sat_i32, Gain, Q16_ONE};

/// Ticks per window: the encoder's count (1.5 mrad) is then at most a few per cent of a
/// window's travel at the speeds of a move.
pub const WINDOW: u8 = 8;
/// Windows before the fit is used.
pub const MIN_WINDOWS: u16 = 4;
/// Gear travel before the fit is used, rad (I32F32 bits of 0.1 rad): the current-sense
/// offset's bias (±20 counts: 80 mrad/s) is then a small part of the travel.
pub const MIN_TRAVEL: i64 = 429_496_730;
/// Gear travel before a raw step's fit is used (I32F32 bits of 0.2 rad): a raw step's gear
/// crosses the free play as it starts, off the deflection the feed-forward planned, and
/// over 0.1 rad the fit read nominal motors at 0.89–0.93 (docs/design.md §11, "The damping
/// for the motor a raw step meets").
pub const RAW_MIN_TRAVEL: i64 = 2 * MIN_TRAVEL;
/// The fit's range, Q16: V̂_s/V_s over 12/12.6…12/10.5 times k_e/k̂_e over 0.9…1.1 (the
/// acceptance ranges, docs/design.md §9) with a margin.
pub const SCALE_MIN: i32 = 55_706; // 0.85
/// See [`SCALE_MIN`].
pub const SCALE_MAX: i32 = 81_920; // 1.25
/// Per-window values are shifted right by this before the products (|D|, |O| < 2²⁴ for
/// 20 rad/s, 2¹⁴ after it), so each product is at most 2²⁸.
const VALUE_SHIFT: u32 = 10;
/// When a sum passes this, all five are halved (the older windows then weigh half as
/// much): they stay within `i32`, so the fit's products are single 32×32→64-bit multiplies.
const SUM_LIMIT: i32 = 1 << 30;

/// What a [`SpeedScale`] counts. One byte: the tracker sits in every controller, and every
/// scenario of the emulated firmware keeps a controller per segment.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Counting {
    /// Nothing: no loaded command, or its reference stopped.
    Off,
    /// A loaded move's, for its velocity feed-forward.
    Move,
    /// A loaded raw step's, for its damping ([`SpeedScale::lead`]).
    Raw,
}

/// A move's window sums and the velocity feed-forward scale they give.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SpeedScale {
    /// What is counted, if anything (a loaded command whose reference still moves).
    counting: Counting,
    /// Ticks in the current window, and its sums of ω̂ and i (Q16·ticks).
    ticks: u8,
    obs: i32,
    cur: i32,
    /// Gear position at the window's start and at the move's start (I32F32 rad).
    start: i64,
    origin: i64,
    windows: u16,
    /// Σ D², Σ D·I, Σ I², Σ O·D, Σ O·I.
    sums: [i32; 5],
    /// The feed-forward scale, Q16.
    scale: i32,
    /// A raw step's (1/s − 1)·α/(1 − α) for s < 1, Q16 (0 without a fit or for s ≥ 1): see
    /// [`SpeedScale::lead`].
    lead: i32,
}

impl SpeedScale {
    /// No move: the scale is 1 and nothing is counted.
    pub const NEW: Self = Self {
        counting: Counting::Off,
        ticks: 0,
        obs: 0,
        cur: 0,
        start: 0,
        origin: 0,
        windows: 0,
        sums: [0; 5],
        scale: Q16_ONE,
        lead: 0,
    };

    /// A move starting with the gear at `gear` (I32F32 rad); `loaded`: the link is held
    /// under load (a floating link's gear crosses the free play, which no model of the
    /// deflection shows). Counting starts afresh.
    #[must_use]
    pub const fn start(gear: i64, loaded: bool) -> Self {
        Self::begin(
            gear,
            if loaded {
                Counting::Move
            } else {
                Counting::Off
            },
        )
    }

    /// A raw step starting with the gear at `gear`: the same fit, after
    /// [`RAW_MIN_TRAVEL`], for the observer's speed in the damping ([`SpeedScale::lead`]);
    /// the step's feed-forward stays its profile's ("Braking for the actuator the step
    /// met").
    #[must_use]
    pub const fn start_raw(gear: i64, loaded: bool) -> Self {
        Self::begin(gear, if loaded { Counting::Raw } else { Counting::Off })
    }

    /// Counting `counting` afresh from the gear at `gear`.
    const fn begin(gear: i64, counting: Counting) -> Self {
        Self {
            counting,
            start: gear,
            origin: gear,
            ..Self::NEW
        }
    }

    /// What the damping's filtered gear speed gets after a tick whose observer read `w`
    /// (Q16 rad/s), over a raw step's fit: the filter w_f += α·(ω̂ − w_f) then settles on
    /// the true speed ω̂/s, the next tick reading it, when (ω̂/s − ω̂)·α/(1 − α) is added
    /// after each tick (0 without a fit, and for a fit that reads the gear fast, s ≥ 1).
    #[must_use]
    pub fn lead(&self, w: i32) -> i32 {
        if self.lead == 0 {
            0
        } else {
            sat_i32((i64::from(w) * i64::from(self.lead)) >> 16)
        }
    }

    /// `x` (Q16) times the scale; `x` itself while the scale is 1.
    #[inline(always)]
    #[must_use]
    pub fn apply(&self, x: i32) -> i32 {
        super::gain::scale_q16(x, self.scale)
    }

    /// The reference stopped: counting ends, the scale stays for the rest of the command.
    pub fn stop(&mut self) {
        self.counting = Counting::Off;
    }

    /// One tick of the move: ω̂ (Q16 rad/s), the current (Q16 A), the gear position
    /// (I32F32 rad) and the damping filter's α (in (0, 1); read only on a raw step's
    /// fitted windows, so the ticks between pay nothing for it).
    pub fn take(&mut self, w_gear: i32, current: i32, gear: i64, alpha: Gain) {
        if self.counting != Counting::Off {
            self.count(w_gear, current, gear, alpha);
        }
    }

    /// [`SpeedScale::take`] within a move.
    fn count(&mut self, w_gear: i32, current: i32, gear: i64, alpha: Gain) {
        self.obs = self.obs.saturating_add(w_gear);
        self.cur = self.cur.saturating_add(current);
        self.ticks += 1;
        if self.ticks < WINDOW {
            return;
        }
        // D = 1000·Δθ_g: rad/s·ticks at dt = 1 ms, like O.
        let d = q32_to_q16(gear.saturating_sub(self.start)).saturating_mul(1000) >> VALUE_SHIFT;
        let (o, i) = (self.obs >> VALUE_SHIFT, self.cur >> VALUE_SHIFT);
        // Clamped to the range the products are sized for.
        let lim = 1 << 14;
        let (d, o, i) = (d.clamp(-lim, lim), o.clamp(-lim, lim), i.clamp(-lim, lim));
        self.ticks = 0;
        self.obs = 0;
        self.cur = 0;
        self.start = gear;
        self.windows = self.windows.saturating_add(1);
        // |d|, |o|, |i| ≤ 2¹⁴ (20 rad/s, 2 A): each product ≤ 2²⁸, each sum ≤ 2³⁰ + 2²⁸.
        for (s, p) in self
            .sums
            .iter_mut()
            .zip([d * d, d * i, i * i, o * d, o * i])
        {
            *s += p;
        }
        if self.sums.iter().any(|s| s.abs() > SUM_LIMIT) {
            for s in &mut self.sums {
                *s >>= 1;
            }
        }
        let raw = self.counting == Counting::Raw;
        let travel = if raw { RAW_MIN_TRAVEL } else { MIN_TRAVEL };
        if self.windows >= MIN_WINDOWS && gear.saturating_sub(self.origin).abs() > travel {
            if let Some(s) = self.fit() {
                let s = s.clamp(SCALE_MIN, SCALE_MAX);
                if raw {
                    // 2³²/s as 2³¹/(s/2) (s/2 ≥ 27 853), and α/(1 − α) (α < 1, so α·2¹⁶
                    // fits): two 32-bit divisions a window. Only for a slow read (s < 1): a
                    // fast one damps more than configured, the safe side, and taking it back
                    // put a heavy link's raw step above σ_allow (design §11, "The damping
                    // for the motor a raw step meets").
                    let inv = ((1u32 << 31) / (s as u32 >> 1)) as i32;
                    let a = alpha.apply(Q16_ONE).clamp(0, Q16_ONE - 1) as u32;
                    let ratio = i64::from((a << 16) / ((Q16_ONE as u32) - a));
                    self.lead = sat_i32((i64::from((inv - Q16_ONE).max(0)) * ratio) >> 16);
                } else {
                    self.scale = s;
                }
            }
        }
    }

    /// s = (ΣOD·ΣI² − ΣOI·ΣDI)/(ΣD²·ΣI² − ΣDI²), Q16, where the determinant is at least
    /// 1/16 of ΣD²·ΣI² (travel and current not too alike to tell apart); `None` otherwise.
    /// The sums are `i32`, so each product is one 32×32→64-bit multiply (below 2⁶²); the
    /// quotient is one 32-bit division of 16-bit operands.
    fn fit(&self) -> Option<i32> {
        let w = |x: i32| i64::from(x);
        let [dd, di, ii, od, oi] = self.sums.map(w);
        let det = dd * ii - di * di;
        if det <= 0 || det < (dd * ii) >> 4 {
            return None;
        }
        let num = od * ii - oi * di;
        if num <= 0 {
            return Some(SCALE_MIN);
        }
        // det to 15 bits; the quotient in Q15 (num/det < 2 after the check).
        let k = (64 - det.leading_zeros()).saturating_sub(15);
        let (n, d) = (num >> k, det >> k);
        if n >= 2 * d {
            return Some(SCALE_MAX);
        }
        let q = ((n as u32) << 15) / (d as u32).max(1); // n < 2¹⁶: no overflow
        Some((q << 1) as i32)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Feeds windows of a gear moving at a speed profile with the observer reading
    /// s·ω + c·i; the fit finds s. Oracle: the s and c the readings were built with.
    fn fitted(s: f64, c: f64) -> f64 {
        fitted_at(s, c, 3.0)
    }

    /// The move's scale after [`fed`] at peak speed `peak`, as a factor.
    fn fitted_at(s: f64, c: f64, peak: f64) -> f64 {
        f64::from(fed(SpeedScale::start(0, true), s, c, peak).scale) / 65536.0
    }

    /// The tracker `t` after a move of peak speed `peak` rad/s (travel 0.19·peak rad) read
    /// as s·ω + c·i.
    fn fed(mut t: SpeedScale, s: f64, c: f64, peak: f64) -> SpeedScale {
        let mut gear = 0.0f64; // rad
        for k in 0..300 {
            // A move's speed and a current that is not proportional to it.
            let tau = f64::from(k) / 300.0;
            let w = peak * (core::f64::consts::PI * tau).sin();
            let i = 0.3 * (2.0 * core::f64::consts::PI * tau).cos() + 0.1;
            gear += w / 1000.0;
            let obs = s * w + c * i;
            t.take(
                (obs * 65536.0) as i32,
                (i * 65536.0) as i32,
                (gear * 4_294_967_296.0) as i64,
                alpha(),
            );
        }
        t
    }

    /// The damping filter's α in the tests (0.2).
    fn alpha() -> Gain {
        Gain::new(fixed::types::I64F64::from_num(0.2)).expect("0.2 is a gain")
    }

    /// What the control step reads from its filter, w_f + α·(ω̂ − w_f) (f64, as the step's
    /// filter), after `ticks` ticks of a steady observer read `w` rad/s with the tracker's
    /// lead added after each.
    fn damped(t: &SpeedScale, w: f64, ticks: u32) -> f64 {
        let a = f64::from(alpha().apply(Q16_ONE)) / 65536.0;
        let (mut wf, mut read) = (0.0, 0.0);
        for _ in 0..ticks {
            wf += a * (w - wf);
            read = wf;
            wf += f64::from(t.lead((w * 65536.0) as i32)) / 65536.0;
        }
        read
    }

    #[test]
    fn a_raw_steps_fit_leads_the_damping_to_the_gear_speed_and_leaves_the_feed_forward_alone() {
        // Oracle: the observer read s·ω, so the damping should read ω = ω̂/s where s < 1,
        // and ω̂ itself where s ≥ 1; the feed-forward stays as it is.
        for (s, due) in [(0.9, 2.0 / 0.9), (0.95, 2.0 / 0.95), (1.0, 2.0), (1.1, 2.0)] {
            let t = fed(SpeedScale::start_raw(0, true), s, 0.3, 3.0);
            assert_eq!(t.apply(1000 << 16), 1000 << 16);
            let w = damped(&t, 2.0, 200);
            assert!((w - due).abs() < 0.02, "s {s}: {w}");
        }
        // 0.19 rad of travel is below the raw step's 0.2: no fit yet; a move's uses it.
        let t = fed(SpeedScale::start_raw(0, true), 0.9, 0.0, 1.0);
        assert_eq!(t.lead(2 << 16), 0);
        assert!((fitted_at(0.9, 0.0, 1.0) - 0.9).abs() < 0.01);
    }

    #[test]
    fn the_fit_finds_the_observer_scale_under_a_resistance_bias() {
        for (s, c) in [(1.0, 0.0), (1.1, 0.0), (0.9, 0.5), (1.14, -0.8), (1.0, 1.0)] {
            let got = fitted(s, c);
            assert!((got - s).abs() < 0.01, "s {s}, c {c}: {got}");
        }
        // Outside the range: clamped.
        assert!((fitted(1.6, 0.0) - 1.25).abs() < 1e-4);
        assert!((fitted(0.5, 0.0) - 0.85).abs() < 1e-4);
    }

    #[test]
    fn a_floating_link_or_no_move_leaves_the_feed_forward_alone() {
        let mut t = SpeedScale::start(0, false);
        for k in 0..100 {
            t.take(65536 * 3, 65536 / 4, i64::from(k) << 28, alpha());
        }
        assert_eq!(t.apply(1000 << 16), 1000 << 16);
        let mut t = SpeedScale::start(0, true);
        t.stop();
        t.take(65536 * 3, 0, 1 << 40, alpha());
        assert_eq!(
            t,
            SpeedScale {
                counting: Counting::Off,
                ..SpeedScale::start(0, true)
            }
        );
    }
}
