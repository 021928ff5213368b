//! Link-angle reference generator: hold, raw step, minimum-jerk move, sine.
//!
//! The generator owns the reference state (position r, velocity ṙ, acceleration r̈) and
//! advances it once per 1 ms tick. A new command starts from the *current reference
//! state*, so changing the target mid-move is smooth: a move is the quintic that joins
//! (r, ṙ, r̈) now to (target, 0, 0) after T seconds (the minimum-jerk polynomial with free
//! initial conditions). From rest it is the classic min-jerk profile
//! r(τ) = r₀ + h·(10τ³ − 15τ⁴ + 6τ⁵), τ = t/T, peak velocity 1.875·h/T, peak acceleration
//! 5.77·h/T².
//!
//! Quintic coefficients (τ ∈ [0, 1], h = target − r₀, c₁ = ṙ₀·T, c₂ = r̈₀·T²/2):
//! c₃ = 10h − 6c₁ − 3c₂, c₄ = −15h + 8c₁ + 3c₂, c₅ = 6h − 3c₁ − c₂
//! (so r(1) = target, ṙ(1) = r̈(1) = 0). They, and the velocity and acceleration
//! polynomials divided by T and T², are computed when the command is given (divisions
//! allowed); per tick the generator evaluates three Horner chains (12 multiplies of
//! I32F32 values through a 64×64→128-bit product).
//!
//! A raw step runs the profile of [`super::dash`]; from rest at a soft setting its
//! reference goes through the ZV shaper of [`super::shaper`] and ends Δ ticks later.
//!
//! The sine r = r_c + A·sin(ωt) (r_c the reference position when the command is given)
//! uses a u32 phase accumulator (2³² per turn) and the integer sine of
//! [`super::sine`]; ṙ = A·ω·cos(ωt), r̈ = −A·ω²·sin(ωt).
//!
//! Formats: r in rad I32F32 bits (`i64`, the model's [`Angle`]); ṙ in rad/s and r̈ in
//! rad/s² as Q16 `i32` (±32 768, resolution 1.5e-5).

use fixed::types::I64F64;

use super::dash::Dash;
use super::error::ControlError;
use super::gain::{q32_to_q16, sat_i32, Gain, Q16_ONE};
use super::schedule::Schedule;
use super::shaper::Shaper;
use super::sine::{cos_q30, sin_q30};
use crate::units::{Angle, Frequency};

/// Largest |target| or |amplitude| accepted, rad (keeps every Q16 error in range).
pub const MAX_ANGLE_RAD: i32 = 10_000;
/// Shortest move, ms.
pub const MIN_MOVE_MS: u32 = 10;
/// Longest move, ms (10 minutes).
pub const MAX_MOVE_MS: u32 = 600_000;
/// Highest sine frequency, rad/s (50 Hz; the loop runs at 1 kHz).
pub const MAX_SINE_RAD_S: i32 = 315;

/// What the link should do.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Command {
    /// Hold the current reference position (velocity and acceleration drop to 0).
    Hold,
    /// Raw step to `target` (absolute link angle) as fast as the actuator allows: through
    /// `Trajectory::step` a profile planned from the limits ([`super::dash`]); through
    /// [`Trajectory::command`] alone the reference jumps.
    Step {
        /// Absolute link angle, rad.
        target: Angle,
    },
    /// Minimum-jerk move from the current reference state to `target` in `duration_ms`.
    Move {
        /// Absolute link angle, rad.
        target: Angle,
        /// Duration, ms, in [`MIN_MOVE_MS`, `MAX_MOVE_MS`].
        duration_ms: u32,
    },
    /// Sine about the current reference position, starting at phase 0.
    Sine {
        /// Amplitude A, rad (> 0).
        amplitude: Angle,
        /// Angular frequency ω, rad/s, in (0, [`MAX_SINE_RAD_S`]].
        frequency: Frequency,
    },
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Mode {
    Hold,
    Quintic {
        /// Start position r₀ (Q32 rad).
        p0: i64,
        /// Target (Q32 rad).
        target: i64,
        /// c₁..c₅ (Q32 rad).
        c: [i64; 5],
        /// Velocity polynomial coefficients i·cᵢ/T (Q32 rad/s).
        dv: [i64; 5],
        /// Acceleration polynomial coefficients i(i−1)·cᵢ/T² (Q32 rad/s²).
        da: [i64; 4],
        /// τ (Q32), its increment per tick, and the ticks left.
        tau: i64,
        dtau: i64,
        left: u32,
    },
    Sine {
        center: i64,
        /// A (Q16 rad), A·ω (Q16 rad/s), A·ω² (Q16 rad/s²).
        amp: i32,
        vel_amp: i32,
        acc_amp: i32,
        phase: u32,
        dphase: u32,
    },
    Dash(Dash),
    /// A shaped raw step whose profile has landed: the shaper's last Δ ticks.
    Tail {
        target: i64,
        left: u8,
        up: bool,
        dt: Gain,
    },
}

/// The reference generator (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Trajectory {
    mode: Mode,
    pos: i64,
    vel: i32,
    acc: i32,
    /// A raw step's unshaped profile position (I32F32 rad bits), and its shaper.
    raw: i64,
    shaper: Shaper,
}

/// One tick of reference.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Reference {
    /// r, rad (I32F32).
    pub position: Angle,
    /// ṙ, rad/s, Q16 bits.
    pub velocity_q16: i32,
    /// r̈, rad/s², Q16 bits.
    pub acceleration_q16: i32,
}

impl Reference {
    /// The reference stands still (no speed, no acceleration): a hold, or a step's target
    /// reached.
    #[inline]
    #[must_use]
    pub const fn stationary(&self) -> bool {
        self.velocity_q16 == 0 && self.acceleration_q16 == 0
    }
}

/// `(a·b) >> 32` (rounded toward −∞), saturated to `i64`: the Q32 product.
///
/// The Horner chains multiply by τ ∈ [0, 1] (Q32, so `b` < 2³² but for the last ticks of
/// very long moves): then `b` is one 32-bit word and the product is
/// `a_hi·b + ((a_lo·b) >> 32)` exactly (`a = a_hi·2³² + a_lo`, `a_lo` unsigned), two
/// 32×32→64 multiplies instead of a 128-bit product on a 32-bit core. Same result as the
/// 128-bit path, bit for bit.
#[inline]
fn mul_q32(a: i64, b: i64) -> i64 {
    if let Ok(t) = u32::try_from(b) {
        let hi = (a >> 32) * i64::from(t); // |a_hi·t| < 2⁶³
        let lo = ((a as u32 as u64 * u64::from(t)) >> 32) as i64; // < 2³²
                                                                  // lo ≥ 0, so only an upward overflow is possible.
        return hi.checked_add(lo).unwrap_or(i64::MAX);
    }
    mul_q32_wide(a, b)
}

/// [`mul_q32`] for any `b`, through the 128-bit product.
#[inline(never)]
fn mul_q32_wide(a: i64, b: i64) -> i64 {
    let p = (i128::from(a) * i128::from(b)) >> 32;
    if p > i128::from(i64::MAX) {
        i64::MAX
    } else if p < i128::from(i64::MIN) {
        i64::MIN
    } else {
        p as i64
    }
}

/// [`mul_q32`] for `t` < 2³² (τ in a move's Horner chains): a_hi·t lies in
/// (−2⁶³, 2⁶³ − 2³²) and the low part in [0, 2³²), so their sum cannot overflow and needs
/// no check. The same result as [`mul_q32`], bit for bit.
#[inline]
fn mul_q32_bounded(a: i64, t: u32) -> i64 {
    i64::from((a >> 32) as i32) * i64::from(t) + ((a as u32 as u64 * u64::from(t)) >> 32) as i64
}

/// Whether Σ|kᵢ| < 2⁶²: a Horner chain over these coefficients in τ ∈ [0, 1) then stays
/// within 2⁶² + 5 at every step (each step's product is at most the running value in
/// magnitude, plus one for the rounding), so its adds need no saturation. A move whose
/// coefficients do not pass asks for angles, speeds or accelerations of 2³⁰ and more (in
/// rad, rad/s, rad/s²): it is refused.
fn bounded(k: &[i64]) -> bool {
    k.iter()
        .try_fold(0i64, |s, &x| s.checked_add(x.checked_abs()?))
        .is_some_and(|s| s < 1 << 62)
}

fn fx(v: i64) -> I64F64 {
    I64F64::from_bits(i128::from(v) << 32)
}

fn to_q32(v: I64F64) -> Result<i64, ControlError> {
    i64::try_from(v.to_bits() >> 32).map_err(|_| ControlError::TrajectoryOutOfRange)
}

fn check_angle(a: Angle) -> Result<(), ControlError> {
    if a.saturating_abs() > Angle::from_int(MAX_ANGLE_RAD) {
        Err(ControlError::TrajectoryOutOfRange)
    } else {
        Ok(())
    }
}

impl Default for Trajectory {
    fn default() -> Self {
        Self::new(Angle::ZERO)
    }
}

impl Trajectory {
    /// Holding at `position`.
    #[must_use]
    pub const fn new(position: Angle) -> Self {
        Self {
            mode: Mode::Hold,
            pos: position.to_bits(),
            vel: 0,
            acc: 0,
            raw: position.to_bits(),
            shaper: Shaper::OFF,
        }
    }

    /// The reference of the last tick.
    #[must_use]
    pub const fn reference(&self) -> Reference {
        Reference {
            position: Angle::from_bits(self.pos),
            velocity_q16: self.vel,
            acceleration_q16: self.acc,
        }
    }

    /// The final target of the current command (the centre for a sine).
    #[must_use]
    pub const fn target(&self) -> Angle {
        Angle::from_bits(match self.mode {
            Mode::Hold => self.pos,
            Mode::Quintic { target, .. } => target,
            Mode::Sine { center, .. } => center,
            Mode::Dash(d) => d.target(),
            Mode::Tail { target, .. } => target,
        })
    }

    /// The free-play impact speed's factor for the drive the running raw step met
    /// (`Dash::impact_q16`, Q16): 1 outside a raw step's profile.
    #[must_use]
    pub fn impact_q16(&self) -> i32 {
        if let Mode::Dash(d) = &self.mode {
            d.impact_q16()
        } else {
            Q16_ONE
        }
    }

    /// `true` while a sine runs.
    #[must_use]
    pub const fn is_sine(&self) -> bool {
        matches!(self.mode, Mode::Sine { .. })
    }

    /// A raw step's drive in this tick (`Dash::drive`): the output's acceleration part and
    /// the rigid model's r̈ feed-forward, ‰ Q16. No effect in the other modes.
    #[inline]
    pub(crate) fn drive(&mut self, actual: i32, model: i32) {
        if let Mode::Dash(d) = &mut self.mode {
            d.drive(actual, model);
        }
    }

    /// Holds at `target` (I32F32 rad bits), still: the end of a move or a shaped step.
    fn land(&mut self, target: i64) {
        self.pos = target;
        self.vel = 0;
        self.acc = 0;
        self.mode = Mode::Hold;
    }

    /// `true` while a raw step runs (its shaper's tail included).
    #[must_use]
    pub const fn is_dash(&self) -> bool {
        matches!(self.mode, Mode::Dash(_) | Mode::Tail { .. })
    }

    /// `true` while a move is under way or a sine runs.
    #[must_use]
    pub const fn is_moving(&self) -> bool {
        !matches!(self.mode, Mode::Hold)
    }

    /// Starts `cmd` from the current reference state. Configuration-time maths (divisions).
    ///
    /// # Errors
    /// [`ControlError::TrajectoryOutOfRange`] for a target or amplitude beyond
    /// ±[`MAX_ANGLE_RAD`], a duration outside [[`MIN_MOVE_MS`], [`MAX_MOVE_MS`]], a sine
    /// frequency outside (0, [`MAX_SINE_RAD_S`]] or an amplitude ≤ 0, or coefficients
    /// that do not fit their formats (e.g. a 10 ms move over 10 000 rad). The running
    /// trajectory is untouched on error.
    pub fn command(&mut self, cmd: Command) -> Result<(), ControlError> {
        let mode = match cmd {
            Command::Hold => {
                self.mode = Mode::Hold;
                self.vel = 0;
                self.acc = 0;
                return Ok(());
            }
            Command::Step { target } => {
                check_angle(target)?;
                self.mode = Mode::Hold;
                self.pos = target.to_bits();
                self.vel = 0;
                self.acc = 0;
                return Ok(());
            }
            Command::Move {
                target,
                duration_ms,
            } => {
                check_angle(target)?;
                if !(MIN_MOVE_MS..=MAX_MOVE_MS).contains(&duration_ms) {
                    return Err(ControlError::TrajectoryOutOfRange);
                }
                self.quintic(target, duration_ms)?
            }
            Command::Sine {
                amplitude,
                frequency,
            } => {
                check_angle(amplitude)?;
                if amplitude.to_bits() <= 0
                    || frequency.to_bits() <= 0
                    || frequency > Frequency::from_int(MAX_SINE_RAD_S)
                {
                    return Err(ControlError::TrajectoryOutOfRange);
                }
                let a = fx(amplitude.to_bits());
                let w = fx(frequency.to_bits());
                let out_of_range = ControlError::TrajectoryOutOfRange;
                let va = a.checked_mul(w).ok_or(out_of_range)?;
                let aa = va.checked_mul(w).ok_or(out_of_range)?;
                let q16 = |v: I64F64| -> Result<i32, ControlError> {
                    i32::try_from(v.to_bits() >> 48).map_err(|_| out_of_range)
                };
                // Phase increment per 1 ms tick: ω/(2π)·10⁻³ turns = ω/(2π)·10⁻³·2³².
                let turns = w
                    .checked_div(I64F64::TAU)
                    .and_then(|f| f.checked_mul_int(1 << 32))
                    .and_then(|f| f.checked_div_int(1000))
                    .ok_or(out_of_range)?;
                let dphase =
                    u32::try_from(turns.round().to_bits() >> 64).map_err(|_| out_of_range)?;
                Mode::Sine {
                    center: self.pos,
                    amp: q16(a)?,
                    vel_amp: q16(va)?,
                    acc_amp: q16(aa)?,
                    phase: 0,
                    dphase,
                }
            }
        };
        self.mode = mode;
        Ok(())
    }

    /// Starts a raw step to `target` along the profile of [`super::dash`], planned with
    /// the schedule `sched` and the duty the integrator holds (‰ Q16); where the limits
    /// leave no acceleration the reference jumps ([`Trajectory::command`]).
    ///
    /// # Errors
    /// As [`Trajectory::command`] for a target beyond ±[`MAX_ANGLE_RAD`].
    pub(crate) fn step(
        &mut self,
        target: Angle,
        sched: &Schedule,
        hold_q16: i32,
    ) -> Result<(), ControlError> {
        check_angle(target)?;
        match Dash::plan(sched, self.pos, self.vel, target.to_bits(), hold_q16) {
            Some(d) => {
                self.mode = Mode::Dash(d);
                self.raw = self.pos;
                // From rest at a soft setting the reference goes through the shaper.
                self.shaper = if self.vel == 0 && self.acc == 0 {
                    Shaper::start(sched.shaper_ticks, self.pos, d.max_change_q16())
                } else {
                    Shaper::OFF
                };
                Ok(())
            }
            None => self.command(Command::Step { target }),
        }
    }

    fn quintic(&self, target: Angle, duration_ms: u32) -> Result<Mode, ControlError> {
        let ov = ControlError::TrajectoryOutOfRange;
        let t = I64F64::from_num(duration_ms) / 1000; // s, exact enough (I64F64)
        let p0 = fx(self.pos);
        let v0 = I64F64::from_bits(i128::from(self.vel) << 48);
        let a0 = I64F64::from_bits(i128::from(self.acc) << 48);
        let h = fx(target.to_bits()).checked_sub(p0).ok_or(ov)?;
        let c1 = v0.checked_mul(t).ok_or(ov)?;
        let c2 = a0.checked_mul(t).and_then(|x| x.checked_mul(t)).ok_or(ov)? / 2;
        let lin = |kh: i32, k1: i32, k2: i32| -> Option<I64F64> {
            h.checked_mul_int(i128::from(kh))?
                .checked_add(c1.checked_mul_int(i128::from(k1))?)?
                .checked_add(c2.checked_mul_int(i128::from(k2))?)
        };
        let c3 = lin(10, -6, -3).ok_or(ov)?;
        let c4 = lin(-15, 8, 3).ok_or(ov)?;
        let c5 = lin(6, -3, -1).ok_or(ov)?;
        let c = [c1, c2, c3, c4, c5];
        let mut cq = [0i64; 5];
        let mut dv = [0i64; 5];
        let mut da = [0i64; 4];
        let t2 = t.checked_mul(t).ok_or(ov)?;
        for (i, ci) in c.iter().enumerate() {
            let n = i as i128 + 1; // power of τ
            cq[i] = to_q32(*ci)?;
            dv[i] = to_q32(
                ci.checked_mul_int(n)
                    .and_then(|x| x.checked_div(t))
                    .ok_or(ov)?,
            )?;
            if i >= 1 {
                da[i - 1] = to_q32(
                    ci.checked_mul_int(n * (n - 1))
                        .and_then(|x| x.checked_div(t2))
                        .ok_or(ov)?,
                )?;
            }
        }
        if !(bounded(&cq) && bounded(&dv) && bounded(&da)) {
            return Err(ov);
        }
        // Velocity and acceleration must fit Q16 (below 30 000) over the whole move:
        // sampled at 65 points of τ (command time; the profiles are smooth quintics whose
        // peaks the samples miss by < 0.1 %, well inside the margin to 32 768).
        let limit = 30_000i64 << 32;
        let mut k = 0i64;
        while k <= 64 {
            let t = k << 26; // τ = k/64 in Q32
            let horner = |c: &[i64]| {
                c.iter()
                    .rev()
                    .fold(0i64, |a, &ci| mul_q32(a, t).saturating_add(ci))
            };
            if horner(&dv).saturating_abs() > limit || horner(&da).saturating_abs() > limit {
                return Err(ov);
            }
            k += 1;
        }
        Ok(Mode::Quintic {
            p0: self.pos,
            target: target.to_bits(),
            c: cq,
            dv,
            da,
            tau: 0,
            dtau: ((1i64 << 32) + i64::from(duration_ms / 2)) / i64::from(duration_ms),
            left: duration_ms,
        })
    }

    /// Advances one tick and returns the new reference.
    pub fn advance(&mut self) -> Reference {
        self.advance_limited(0)
    }

    /// [`Trajectory::advance`], told that the drive was at a limit on the last tick in the
    /// direction `limited` (+1, −1, or 0 for none): a raw step's profile then gains no
    /// speed that way.
    pub(crate) fn advance_limited(&mut self, limited: i32) -> Reference {
        match &mut self.mode {
            Mode::Hold => {}
            Mode::Quintic {
                p0,
                target,
                c,
                dv,
                da,
                tau,
                dtau,
                left,
            } => {
                *left = left.saturating_sub(1);
                if *left == 0 {
                    let target = *target;
                    self.land(target);
                } else {
                    *tau = tau.saturating_add(*dtau);
                    let t = *tau;
                    let (pc, pv, pa) = if let Ok(t32) = u32::try_from(t) {
                        // τ < 1 and the coefficients bounded at planning (`bounded`):
                        // plain adds.
                        let horner = |k: &[i64]| {
                            k.iter()
                                .rev()
                                .fold(0i64, |acc, &ki| mul_q32_bounded(acc, t32) + ki)
                        };
                        (mul_q32_bounded(horner(c), t32), horner(dv), horner(da))
                    } else {
                        let horner = |k: &[i64]| {
                            k.iter()
                                .rev()
                                .fold(0i64, |acc, &ki| mul_q32(acc, t).saturating_add(ki))
                        };
                        (mul_q32(horner(c), t), horner(dv), horner(da))
                    };
                    self.pos = p0.saturating_add(pc);
                    self.vel = q32_to_q16(pv);
                    self.acc = q32_to_q16(pa);
                }
            }
            Mode::Sine {
                center,
                amp,
                vel_amp,
                acc_amp,
                phase,
                dphase,
            } => {
                *phase = phase.wrapping_add(*dphase);
                let s = i64::from(sin_q30(*phase));
                let co = i64::from(cos_q30(*phase));
                // Q16·Q30 >> 30 = Q16; position back to Q32.
                let off = sat_i32((i64::from(*amp) * s) >> 30);
                self.pos = center.saturating_add(i64::from(off) << 16);
                self.vel = sat_i32((i64::from(*vel_amp) * co) >> 30);
                self.acc = sat_i32(-((i64::from(*acc_amp) * s) >> 30));
            }
            Mode::Dash(d) => {
                let t = d.advance(self.raw, limited);
                self.raw = t.position;
                if self.shaper.on() {
                    let now = Reference {
                        position: Angle::from_bits(t.position),
                        velocity_q16: t.velocity_q16,
                        acceleration_q16: t.acceleration_q16,
                    };
                    let r =
                        self.shaper
                            .shape(&now, t.change_q16, t.done, d.up(), d.dt(), d.target());
                    (self.pos, self.vel, self.acc) =
                        (r.position.to_bits(), r.velocity_q16, r.acceleration_q16);
                    if t.done {
                        self.mode = Mode::Tail {
                            target: t.position,
                            left: self.shaper.delay(),
                            up: d.up(),
                            dt: d.dt(),
                        };
                    }
                } else {
                    self.pos = t.position;
                    self.vel = t.velocity_q16;
                    self.acc = t.acceleration_q16;
                    if t.done {
                        self.mode = Mode::Hold;
                    }
                }
            }
            Mode::Tail {
                target,
                left,
                up,
                dt,
            } => {
                *left = left.saturating_sub(1);
                if *left == 0 {
                    // The delayed half has landed too: exactly on the target.
                    let target = *target;
                    self.land(target);
                } else {
                    let now = Reference {
                        position: Angle::from_bits(*target),
                        velocity_q16: 0,
                        acceleration_q16: 0,
                    };
                    let r = self.shaper.shape(&now, 0, true, *up, *dt, *target);
                    (self.pos, self.vel, self.acc) =
                        (r.position.to_bits(), r.velocity_q16, r.acceleration_q16);
                }
            }
        }
        self.reference()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use fixed::types::I32F32;

    fn rad(a: Angle) -> f64 {
        a.get().to_num::<f64>()
    }

    fn q16(v: i32) -> f64 {
        f64::from(v) / 65536.0
    }

    /// A raw step at a soft setting: its reference is the unshaped profile averaged by hand
    /// with itself Δ ticks older (the rest before the step), it ends Δ ticks after the
    /// unshaped one, exactly on the target. Without the shaper (Δ = 0) the two are one.
    #[test]
    fn a_shaped_raw_step_is_the_profile_averaged_with_itself_delay_ago() {
        let cfg = crate::control::Config::paper(crate::units::Length::from_int(7));
        let mut sched = Schedule::new(&crate::design::Design::paper(), &cfg).unwrap();
        let delay = usize::from(sched.shaper_ticks);
        assert!(delay > 10, "shaped at 7 mm: Δ = {delay}");
        let target = Angle::from_fixed(I32F32::lit("0.4"));
        let run = |s: &Schedule| {
            let mut t = Trajectory::new(Angle::from_fixed(I32F32::lit("0.1")));
            t.step(target, s, 0).unwrap();
            let mut out = vec![t.reference()];
            while t.is_dash() {
                out.push(t.advance());
            }
            out
        };
        let shaped = run(&sched);
        sched.shaper_ticks = 0;
        let raw = run(&sched);
        assert_eq!(shaped.len(), raw.len() + delay, "Δ ticks longer");
        let rest = raw[0];
        let at = |k: usize| {
            if k < raw.len() {
                raw[k]
            } else {
                *raw.last().unwrap()
            }
        };
        for (k, got) in shaped.iter().enumerate().take(shaped.len() - 1).skip(1) {
            let now = at(k);
            let old = if k > delay { at(k - delay) } else { rest };
            let half = |a: i64, b: i64| a.div_euclid(2) + b.div_euclid(2);
            let mean = half(now.position.to_bits(), old.position.to_bits());
            assert_eq!(got.position.to_bits(), mean, "tick {k}");
            let half = |a: i32, b: i32| a.div_euclid(2) + b.div_euclid(2);
            assert_eq!(got.velocity_q16, half(now.velocity_q16, old.velocity_q16));
            assert_eq!(
                got.acceleration_q16,
                half(now.acceleration_q16, old.acceleration_q16)
            );
        }
        let last = *shaped.last().unwrap();
        assert_eq!(last.position, target);
        assert!(last.stationary());
    }

    #[test]
    fn mul_q32_fast_path_is_the_128_bit_product() {
        let edges = [
            0i64,
            1,
            -1,
            i64::MAX,
            i64::MIN,
            i64::MAX - 1,
            i64::MIN + 1,
            1 << 32,
            -(1 << 32),
            (1 << 32) - 1,
            u32::MAX as i64,
            1 << 31,
            -(1 << 31),
        ];
        let mut draw = crate::test_rng::xorshift(0x9E37_79B9_7F4A_7C15);
        let mut next = || draw() as i64;
        let mut cases = Vec::new();
        for &a in &edges {
            for &b in &edges {
                cases.push((a, b));
            }
        }
        for _ in 0..200_000 {
            let (a, b) = (next(), next());
            cases.push((a, b));
            cases.push((a, b & 0xFFFF_FFFF));
            cases.push((a >> (b as u64 % 64), (b as u64 % (1 << 33)) as i64));
        }
        for (a, b) in cases {
            assert_eq!(mul_q32(a, b), mul_q32_wide(a, b), "{a} × {b}");
        }
    }

    /// A Horner chain over coefficients that pass `bounded`, in τ < 1, is the same with
    /// the unchecked product and plain adds as with the 128-bit product and saturating
    /// adds, bit for bit; coefficients whose magnitudes sum to 2⁶² do not pass.
    #[test]
    fn bounded_horner_is_the_saturating_one() {
        let mut next = crate::test_rng::xorshift(0x2545_F491_4F6C_DD1D);
        for _ in 0..100_000 {
            let n = 4 + (next() % 2) as usize;
            let k: Vec<i64> = (0..n)
                .map(|_| (next() as i64) >> (4 + next() % 59)) // |k| < 2⁵⁹: Σ < 2⁶²
                .collect();
            assert!(bounded(&k), "{k:?}");
            let t = next() & 0xFFFF_FFFF;
            let wide = k
                .iter()
                .rev()
                .fold(0i64, |a, &ki| mul_q32_wide(a, t as i64).saturating_add(ki));
            let fast = k
                .iter()
                .rev()
                .fold(0i64, |a, &ki| mul_q32_bounded(a, t as u32) + ki);
            assert_eq!(fast, wide, "{k:?} at τ = {t}");
        }
        assert!(!bounded(&[1 << 61, 1 << 61]));
        assert!(!bounded(&[(1 << 62) - 1, -1]));
        assert!(!bounded(&[i64::MIN]));
        assert!(bounded(&[(1 << 61) - 1, 1 << 61]));
    }

    #[test]
    fn min_jerk_from_rest_matches_formula() {
        let mut t = Trajectory::new(Angle::ZERO);
        t.command(Command::Move {
            target: Angle::from_fixed(I32F32::lit("0.5")),
            duration_ms: 200,
        })
        .unwrap();
        let mut peak_v = 0.0f64;
        let mut peak_a = 0.0f64;
        for k in 1..=200 {
            let r = t.advance();
            let tau = f64::from(k) / 200.0;
            let want = 0.5 * (10.0 * tau.powi(3) - 15.0 * tau.powi(4) + 6.0 * tau.powi(5));
            assert!((rad(r.position) - want).abs() < 1e-6, "{k}");
            let wv = 0.5 / 0.2 * 30.0 * tau.powi(2) * (1.0 - tau).powi(2);
            assert!((q16(r.velocity_q16) - wv).abs() < 1e-3, "{k}");
            peak_v = peak_v.max(q16(r.velocity_q16));
            peak_a = peak_a.max(q16(r.acceleration_q16));
        }
        assert!((peak_v - 1.875 * 0.5 / 0.2).abs() < 0.01);
        assert!((peak_a - 5.7735 * 0.5 / 0.04).abs() < 0.2, "{peak_a}");
        let r = t.reference();
        assert_eq!(r.position, Angle::from_fixed(I32F32::lit("0.5")));
        assert!(!t.is_moving());
    }

    #[test]
    fn retarget_mid_move_is_smooth() {
        let mut t = Trajectory::new(Angle::ZERO);
        t.command(Command::Move {
            target: Angle::from_int(1),
            duration_ms: 300,
        })
        .unwrap();
        let mut last = t.reference();
        for _ in 0..120 {
            last = t.advance();
        }
        t.command(Command::Move {
            target: Angle::from_fixed(I32F32::lit("-0.2")),
            duration_ms: 300,
        })
        .unwrap();
        let next = t.advance();
        // One tick later: position moves by about v·dt, velocity and acceleration change
        // by at most a jerk-limited amount.
        let dv = q16(next.velocity_q16) - q16(last.velocity_q16);
        let dp = rad(next.position) - rad(last.position) - q16(last.velocity_q16) * 1e-3;
        assert!(dp.abs() < 1e-3, "{dp}");
        assert!(dv.abs() < 0.2, "{dv}");
        for _ in 0..299 {
            t.advance();
        }
        assert_eq!(
            t.reference().position,
            Angle::from_fixed(I32F32::lit("-0.2"))
        );
    }

    #[test]
    fn sine_tracks_formula() {
        let mut t = Trajectory::new(Angle::from_int(1));
        let w = Frequency::from_hz(I32F32::from_num(1)).unwrap();
        t.command(Command::Sine {
            amplitude: Angle::from_fixed(I32F32::lit("0.2")),
            frequency: w,
        })
        .unwrap();
        for k in 1..=2000 {
            let r = t.advance();
            let x = core::f64::consts::TAU * f64::from(k) * 1e-3;
            assert!(
                (rad(r.position) - (1.0 + 0.2 * x.sin())).abs() < 5e-5,
                "{k}"
            );
            let wv = 0.2 * core::f64::consts::TAU * x.cos();
            assert!((q16(r.velocity_q16) - wv).abs() < 1e-3, "{k}");
        }
    }

    #[test]
    fn rejects_bad_commands_and_keeps_state() {
        let mut t = Trajectory::new(Angle::ZERO);
        t.command(Command::Move {
            target: Angle::from_int(1),
            duration_ms: 100,
        })
        .unwrap();
        t.advance();
        let before = t;
        for bad in [
            Command::Move {
                target: Angle::from_int(1),
                duration_ms: 5,
            },
            Command::Step {
                target: Angle::from_int(20_000),
            },
            Command::Sine {
                amplitude: Angle::ZERO,
                frequency: Frequency::from_int(1),
            },
            Command::Sine {
                amplitude: Angle::from_int(1),
                frequency: Frequency::from_int(1000),
            },
            Command::Move {
                target: Angle::from_int(9_999),
                duration_ms: 10,
            },
        ] {
            assert_eq!(t.command(bad), Err(ControlError::TrajectoryOutOfRange));
            assert_eq!(t, before);
        }
    }
}
