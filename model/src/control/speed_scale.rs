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
//! Formats: ω̂ Q16 rad/s, i Q16 A, angles I32F32 rad bits, the scale Q16.

use super::gain::{q32_to_q16, Q16_ONE};

/// Ticks per window: the encoder's count (1.5 mrad) is then at most a few per cent of a
/// window's travel at the speeds of a move.
pub const WINDOW: u8 = 8;
/// Windows before the fit is used.
pub const MIN_WINDOWS: u16 = 4;
/// Gear travel before the fit is used, rad (I32F32 bits of 0.1 rad): the current-sense
/// offset's bias (±20 counts: 80 mrad/s) is then a small part of the travel.
pub const MIN_TRAVEL: i64 = 429_496_730;
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

/// A move's window sums and the velocity feed-forward scale they give.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SpeedScale {
    /// Counting (a loaded move whose reference still moves).
    on: bool,
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
}

impl SpeedScale {
    /// No move: the scale is 1 and nothing is counted.
    pub const NEW: Self = Self {
        on: false,
        ticks: 0,
        obs: 0,
        cur: 0,
        start: 0,
        origin: 0,
        windows: 0,
        sums: [0; 5],
        scale: Q16_ONE,
    };

    /// A move starting with the gear at `gear` (I32F32 rad); `loaded`: the link is held
    /// under load (a floating link's gear crosses the free play, which no model of the
    /// deflection shows). Counting starts afresh.
    #[must_use]
    pub const fn start(gear: i64, loaded: bool) -> Self {
        Self {
            on: loaded,
            start: gear,
            origin: gear,
            ..Self::NEW
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
        self.on = false;
    }

    /// One tick of the move: ω̂ (Q16 rad/s), the current (Q16 A) and the gear position
    /// (I32F32 rad).
    pub fn take(&mut self, w_gear: i32, current: i32, gear: i64) {
        if self.on {
            self.count(w_gear, current, gear);
        }
    }

    /// [`SpeedScale::take`] within a move.
    fn count(&mut self, w_gear: i32, current: i32, gear: i64) {
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
        if self.windows >= MIN_WINDOWS && gear.saturating_sub(self.origin).abs() > MIN_TRAVEL {
            if let Some(s) = self.fit() {
                self.scale = s.clamp(SCALE_MIN, SCALE_MAX);
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
        let mut t = SpeedScale::start(0, true);
        let mut gear = 0.0f64; // rad
        for k in 0..300 {
            // A move's speed and a current that is not proportional to it.
            let tau = f64::from(k) / 300.0;
            let w = 3.0 * (core::f64::consts::PI * tau).sin();
            let i = 0.3 * (2.0 * core::f64::consts::PI * tau).cos() + 0.1;
            gear += w / 1000.0;
            let obs = s * w + c * i;
            t.take(
                (obs * 65536.0) as i32,
                (i * 65536.0) as i32,
                (gear * 4_294_967_296.0) as i64,
            );
        }
        f64::from(t.scale) / 65536.0
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
            t.take(65536 * 3, 65536 / 4, i64::from(k) << 28);
        }
        assert_eq!(t.apply(1000 << 16), 1000 << 16);
        let mut t = SpeedScale::start(0, true);
        t.stop();
        t.take(65536 * 3, 0, 1 << 40);
        assert_eq!(
            t,
            SpeedScale {
                on: false,
                ..SpeedScale::start(0, true)
            }
        );
    }
}
