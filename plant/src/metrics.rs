//! The step-response figures, defined once for every tool that reports them: the host
//! harness and `vsa simulate`, the scenarios (step sweep), the service test and the
//! end-to-end test of the emulated board.
//!
//! **Clock.** t = 0 when the command is given: the boundary before the first control tick
//! that runs with it. A sample taken at the end of the n-th tick from then is at
//! t = n ms. (A board's telemetry sample of tick τ, for a command handled when the servo
//! had run T ticks, is at t = τ − T ms.)
//!
//! **Figures** of a step from `start` (the link angle when the command is given) to
//! `target`, h = target − start, with a band (±1 encoder count on the true angle; ±1.5
//! counts on a measured angle, which is the centre of its count):
//!
//! * overshoot: the largest excursion beyond the target in the direction of the step,
//!   % of |h|; 0 if it never passes the target or if |h| is below the band;
//! * rise time: from 10 % to 90 % of h (first crossing of each), `None` if never reached;
//! * settling time: t of the last sample outside the band (0 if none was); `None` if the
//!   last sample recorded is outside;
//! * steady-state error: the largest |angle − target| from `steady_from_s` on;
//! * span at rest ([`Span`]): max − min of a value (encoder count, duty) over that window.
//!
//! Samples at t ≤ 0 (before the command) count only for the steady window.
//!
//! A host that records a board's telemetry does not see the tick at which the board took
//! its command; [`move_command_tick`] recovers it from the recorded reference.

use model::control::{Command, Trajectory};
use model::Angle;

/// Streams the step-response figures of one command.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StepResponse {
    start: f64,
    target: f64,
    band: f64,
    steady_from_s: f64,
    max_excess: f64,
    t10: Option<f64>,
    t90: Option<f64>,
    last_outside_s: Option<f64>,
    latest_outside: bool,
    steady_error: f64,
}

/// What a [`StepResponse`] measured.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct StepFigures {
    /// Overshoot beyond the target, % of the commanded change.
    pub overshoot_pct: f64,
    /// 10 %→90 % rise time, s.
    pub rise_time_s: Option<f64>,
    /// Time from the command until the angle stays within the band, s.
    pub settling_time_s: Option<f64>,
    /// Largest |angle − target| in the steady window, in the unit of the angles.
    pub steady_state_error: f64,
}

impl StepResponse {
    /// A step from `start` to `target` (any one angle unit), settling band ±`band`, steady
    /// window from `steady_from_s` after the command.
    #[must_use]
    pub const fn new(start: f64, target: f64, band: f64, steady_from_s: f64) -> StepResponse {
        StepResponse {
            start,
            target,
            band,
            steady_from_s,
            max_excess: 0.0,
            t10: None,
            t90: None,
            last_outside_s: None,
            latest_outside: false,
            steady_error: 0.0,
        }
    }

    /// Records the angle `angle` at `t_s` seconds after the command (samples in time
    /// order).
    pub fn record(&mut self, t_s: f64, angle: f64) {
        let err = angle - self.target;
        if t_s > 0.0 {
            let outside = err.abs() > self.band;
            if outside {
                self.last_outside_s = Some(t_s);
            }
            self.latest_outside = outside;
            let h = self.target - self.start;
            if h != 0.0 {
                let frac = (angle - self.start) / h;
                if self.t10.is_none() && frac >= 0.1 {
                    self.t10 = Some(t_s);
                }
                if self.t90.is_none() && frac >= 0.9 {
                    self.t90 = Some(t_s);
                }
                self.max_excess = self.max_excess.max(err * h.signum());
            }
        }
        if t_s >= self.steady_from_s {
            self.steady_error = self.steady_error.max(err.abs());
        }
    }

    /// The target the figures are taken against.
    #[must_use]
    pub const fn target(&self) -> f64 {
        self.target
    }

    /// Start of the steady window, s after the command.
    #[must_use]
    pub const fn steady_from_s(&self) -> f64 {
        self.steady_from_s
    }

    /// Whether `t_s` lies in the steady window.
    #[must_use]
    pub fn in_steady_window(&self, t_s: f64) -> bool {
        t_s >= self.steady_from_s
    }

    /// The figures so far.
    #[must_use]
    pub fn figures(&self) -> StepFigures {
        let h = (self.target - self.start).abs();
        StepFigures {
            overshoot_pct: if h >= self.band {
                100.0 * self.max_excess / h
            } else {
                0.0
            },
            rise_time_s: match (self.t10, self.t90) {
                (Some(a), Some(b)) => Some(b - a),
                _ => None,
            },
            settling_time_s: match self.last_outside_s {
                _ if self.latest_outside => None,
                None => Some(0.0),
                Some(t) => Some(t),
            },
            steady_state_error: self.steady_error,
        }
    }
}

/// Smallest and largest of a value over a window (the span at rest).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Span {
    min: i32,
    max: i32,
}

impl Default for Span {
    fn default() -> Self {
        Self::new()
    }
}

impl Span {
    /// No value yet (span 0).
    #[must_use]
    pub const fn new() -> Span {
        Span {
            min: i32::MAX,
            max: i32::MIN,
        }
    }

    /// Adds `v`.
    pub fn add(&mut self, v: i32) {
        self.min = self.min.min(v);
        self.max = self.max.max(v);
    }

    /// max − min (0 if empty or one value).
    #[must_use]
    pub fn width(&self) -> i32 {
        self.max.saturating_sub(self.min).max(0)
    }
}

/// The board's tick count when it took a `Command::Move` from `start_urad` to
/// `target_urad` in `duration_ms`, from telemetry samples `(tick, reference µrad)`
/// recorded around the move: the count T for which the controller's own trajectory,
/// advanced τ − T ticks, best matches every sample's reference (least sum of |error|).
/// A sample of tick τ is then at t = (τ − T) ms. `None` without a sample in the move or
/// for a start or target out of range.
#[must_use]
pub fn move_command_tick(
    start_urad: i32,
    target_urad: i32,
    duration_ms: u32,
    samples: &[(u32, i32)],
) -> Option<u32> {
    let start = Angle::from_micro(i64::from(start_urad)).ok()?;
    let target = Angle::from_micro(i64::from(target_urad)).ok()?;
    let mut traj = Trajectory::new(start);
    traj.command(Command::Move {
        target,
        duration_ms,
    })
    .ok()?;
    let to_urad = |a: Angle| a.to_bits() as f64 * 1e6 / 4_294_967_296.0;
    let r0 = to_urad(start);
    // The move shows first in a sample whose reference left the start (by > 1 µrad).
    let first_moved = samples
        .iter()
        .find(|&&(_, r)| (f64::from(r) - r0).abs() > 1.0)?
        .0;
    // Sum of |reference − sample| if the command was taken at count `t` (samples in tick
    // order; the reference after n ticks is the trajectory advanced n times).
    let cost = |t: i64| -> f64 {
        let mut traj = traj;
        let (mut n, mut r) = (0i64, r0);
        samples
            .iter()
            .map(|&(tau, sample)| {
                while n < i64::from(tau) - t {
                    r = to_urad(traj.advance().position);
                    n += 1;
                }
                (r - f64::from(sample)).abs()
            })
            .sum()
    };
    let lo = (i64::from(first_moved) - i64::from(duration_ms) - 2).max(0);
    let mut best: Option<(f64, i64)> = None;
    for t in lo..=i64::from(first_moved) {
        let c = cost(t);
        if best.is_none_or(|(b, _)| c < b) {
            best = Some((c, t));
        }
    }
    best.and_then(|(_, t)| u32::try_from(t).ok())
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: f64 = 1e-3;

    /// A trace given as angles at t = 1, 2, … ms.
    fn run(start: f64, target: f64, band: f64, steady_from_s: f64, trace: &[f64]) -> StepFigures {
        let mut s = StepResponse::new(start, target, band, steady_from_s);
        for (i, &a) in trace.iter().enumerate() {
            s.record((i + 1) as f64 * MS, a);
        }
        s.figures()
    }

    #[test]
    fn a_hand_computed_step() {
        // 0 → 10, band 0.5. 10 % (1.0) first reached at 2 ms, 90 % (9.0) at 4 ms; peak 11
        // (10 % over); last sample outside ±0.5 is 10.6 at 6 ms; steady window from 5 ms:
        // errors 1.0 (11 at 5 ms), 0.6, 0.2, 0.1 → 1.0.
        let f = run(
            0.0,
            10.0,
            0.5,
            5.0 * MS,
            &[0.5, 2.0, 6.0, 9.5, 11.0, 10.6, 9.8, 10.1],
        );
        assert!((f.overshoot_pct - 10.0).abs() < 1e-12, "{f:?}");
        assert!((f.rise_time_s.unwrap() - 2.0 * MS).abs() < 1e-15);
        assert!((f.settling_time_s.unwrap() - 6.0 * MS).abs() < 1e-15);
        assert!((f.steady_state_error - 1.0).abs() < 1e-12);
    }

    #[test]
    fn a_negative_step_without_overshoot() {
        // 0 → −4, band 0.5: passes −0.4 (10 %) at 1 ms, −3.6 (90 %) at 4 ms (−3.7), never
        // beyond −4; outside the band last at 3 ms (−3.4); steady from 0: the first
        // sample's error 3.5 is the largest.
        let f = run(0.0, -4.0, 0.5, 0.0, &[-0.5, -2.0, -3.4, -3.7, -4.0, -3.9]);
        assert_eq!(f.overshoot_pct, 0.0);
        assert!((f.rise_time_s.unwrap() - 3.0 * MS).abs() < 1e-15);
        assert!((f.settling_time_s.unwrap() - 3.0 * MS).abs() < 1e-15);
        assert!((f.steady_state_error - 3.5).abs() < 1e-12);
    }

    #[test]
    fn not_settled_at_the_end_and_small_steps() {
        // Ends outside the band: no settling time; never reaches 90 %: no rise time.
        let f = run(0.0, 10.0, 0.5, 0.0, &[1.0, 3.0, 5.0]);
        assert_eq!(f.settling_time_s, None);
        assert_eq!(f.rise_time_s, None);
        // A change smaller than the band has no overshoot figure; inside throughout: 0 s.
        let f = run(0.0, 0.2, 0.5, 0.0, &[0.1, 0.4, 0.2]);
        assert_eq!(f.overshoot_pct, 0.0);
        assert_eq!(f.settling_time_s, Some(0.0));
    }

    #[test]
    fn samples_before_the_command_count_only_for_the_steady_window() {
        let mut s = StepResponse::new(0.0, 1.0, 0.1, -2.0 * MS);
        s.record(-MS, 5.0); // before the command: far beyond the target
        s.record(0.0, 5.0);
        s.record(1.0 * MS, 1.0);
        let f = s.figures();
        assert_eq!(f.overshoot_pct, 0.0);
        assert_eq!(f.settling_time_s, Some(0.0));
        assert!((f.steady_state_error - 4.0).abs() < 1e-12);
        assert!(!s.in_steady_window(-3.0 * MS) && s.in_steady_window(-2.0 * MS));
    }

    #[test]
    fn the_command_tick_of_a_recorded_move() {
        // A move taken when the board had run 1000 ticks, sampled every 2nd tick from 950,
        // references rounded to µrad as the telemetry does.
        let mut traj = Trajectory::new(Angle::from_micro(-20_000).unwrap());
        traj.command(Command::Move {
            target: Angle::from_micro(500_000).unwrap(),
            duration_ms: 300,
        })
        .unwrap();
        let mut samples = std::vec::Vec::new();
        for tick in 950..1500u32 {
            let r = if tick > 1000 {
                traj.advance().position.to_bits()
            } else {
                Angle::from_micro(-20_000).unwrap().to_bits()
            };
            if tick % 2 == 1 {
                let urad = (r as f64 * 1e6 / 4_294_967_296.0).round() as i32;
                samples.push((tick, urad));
            }
        }
        assert_eq!(
            move_command_tick(-20_000, 500_000, 300, &samples),
            Some(1000)
        );
        // Nothing moved: no answer.
        assert_eq!(
            move_command_tick(-20_000, 500_000, 300, &samples[..20]),
            None
        );
    }

    #[test]
    fn span() {
        let mut s = Span::new();
        assert_eq!(s.width(), 0);
        s.add(7);
        assert_eq!(s.width(), 0);
        s.add(3);
        s.add(5);
        assert_eq!(s.width(), 4);
    }
}
