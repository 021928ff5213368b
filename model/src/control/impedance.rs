//! Impedance command: hold a target angle θ_t with a virtual stiffness k_v (at most the
//! beams' k at the clutch setting), a virtual damping d_v and a feed-forward torque τ_ff,
//! as admittance over the position loop (docs/design.md §11, "Impedance command").
//!
//! The law asks the coupling torque on the link, τ_c, to follow the virtual spring-damper:
//! τ_c = k_v·(θ_t − θ) − d_v·θ̇ + τ_ff. Each tick it turns the controller's coupling-torque
//! estimate τ̂ into the link reference θ_r that satisfies it with θ = θ_r,
//!
//! > k_v·(θ_t − θ_r) − d_v·θ̇_r + τ_ff = τ̂                                  (eq. I1)
//!
//! discretised backward Euler (stable for every d_v ≥ 0, no division per tick):
//!
//! > θ_eq = θ_t + (τ_ff − τ̂)/k_v,  θ_r ← θ_r + β·(θ_eq − θ_r),  β = Δt/(T + Δt)
//!
//! so θ_r is θ_eq, the spring's equilibrium for the torque the beams carry, through a
//! first-order lag of time constant T = max(d_v/k_v, 4/ω_c, 8·J_l·ω_c/k_v): the virtual
//! dynamics are not made faster than the position loop (bandwidth ω_c) can follow, nor
//! the loop through the link's own inertial torque J_l·θ̈ in τ̂ stronger than 1/8. At rest
//! under an external torque τ the beams carry τ̂ = −τ and the link sits at
//! θ_t + (τ_ff + τ)/k_v: the deflection τ/k_v. The position loop holds θ = θ_r (given as
//! a stationary reference each tick), so the beams' limits, the supervisor and every clamp
//! of the controller stay in force. A new target is first reached by a minimum-jerk move
//! ([`Impedance::approach`]); the law starts when it ends. A k_v above the beams' k is
//! refused: faster than the loop the joint is its beams whatever the loop does.
//!
//! Formats: angles I32F32 rad bits (`i64`, the controller's reference), torques through
//! Q16 (±32 768 N·m, resolution 1.5e-5 N·m), 1/k_v and β as [`Gain`]s computed when the
//! command is given. Per tick: two multiplies, saturating.

use core::fmt;

use fixed::types::{I32F32, I64F64};

use super::gain::{q32_to_q16, Gain};
use super::schedule::{Schedule, TICKS_PER_S};
use super::trajectory::{Command, MAX_ANGLE_RAD, MAX_MOVE_MS};
use crate::sensors::ENCODER_HALF_COUNT_Q32;
use crate::units::{Angle, Inertia, Stiffness, Torque};

/// The reference's lag is at least `LAG_BANDWIDTH_RATIO`/ω_c (ω_c the position loop's
/// bandwidth): faster virtual dynamics than the loop can follow make the torque estimate's
/// free-play transients drive the reference into a limit cycle (docs/design.md §11,
/// "Impedance command").
pub const LAG_BANDWIDTH_RATIO: i32 = 4;
/// And at least `LAG_INERTIA_RATIO`·J_l·ω_c/k_v.
pub const LAG_INERTIA_RATIO: i32 = 8;
/// Duration of the approach move per rad of distance, ms (peak speed 1.9 rad/s, peak
/// acceleration 5.8/h rad/s² for a distance h: gentle enough for a link three times
/// heavier than configured).
pub const APPROACH_MS_PER_RAD: u32 = 1000;
/// Shortest approach move, ms.
pub const APPROACH_MIN_MS: u32 = 200;
/// One encoder count, rad Q32.
const ENCODER_COUNT_Q32: u128 = 2 * ENCODER_HALF_COUNT_Q32 as u128;
/// Softest virtual stiffness accepted, N·m/rad (1/k_v must fit its [`Gain`]; 0.1 N·m/rad
/// turns 0.1 N·m into 1 rad).
pub const MIN_STIFFNESS_NM_PER_RAD: I32F32 = I32F32::lit("0.1");
/// Largest virtual damping accepted, N·m·s/rad (d_v/k_v, the reference's time constant, up
/// to 1000 s at the softest k_v).
pub const MAX_DAMPING_NMS_PER_RAD: I32F32 = I32F32::lit("100");
/// Largest |τ_ff| accepted, N·m (far beyond any beam's capacity; the loop's torque limit
/// applies anyway).
pub const MAX_FEED_FORWARD_NM: i32 = 100;

/// What an impedance command asks (see the module docs). (Not `defmt::Format`: the
/// damping is a plain I32F32; log the fields' bits.)
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ImpedanceCommand {
    /// Target link angle θ_t, absolute, rad, |·| ≤ [`MAX_ANGLE_RAD`].
    pub target: Angle,
    /// Virtual stiffness k_v, N·m/rad, in [[`MIN_STIFFNESS_NM_PER_RAD`], k(L)].
    pub stiffness: Stiffness,
    /// Virtual damping d_v, N·m·s/rad, in [0, [`MAX_DAMPING_NMS_PER_RAD`]].
    pub damping: I32F32,
    /// Feed-forward torque τ_ff, N·m, |·| ≤ [`MAX_FEED_FORWARD_NM`].
    pub torque: Torque,
}

/// Why an impedance command was refused (nothing changed).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum ImpedanceError {
    /// k_v is above the beams' stiffness at the current clutch setting: the joint cannot
    /// be made stiffer than its beams (set a shorter clutch length).
    StiffnessAbovePhysical,
    /// k_v is below [`MIN_STIFFNESS_NM_PER_RAD`].
    StiffnessOutOfRange,
    /// d_v is negative or above [`MAX_DAMPING_NMS_PER_RAD`].
    DampingOutOfRange,
    /// |τ_ff| is above [`MAX_FEED_FORWARD_NM`].
    TorqueOutOfRange,
    /// |θ_t| is above [`MAX_ANGLE_RAD`].
    TargetOutOfRange,
}

impl fmt::Display for ImpedanceError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            ImpedanceError::StiffnessAbovePhysical => {
                "virtual stiffness above the beams' stiffness at this clutch setting"
            }
            ImpedanceError::StiffnessOutOfRange => "virtual stiffness below 0.1 N·m/rad",
            ImpedanceError::DampingOutOfRange => "virtual damping outside [0, 100] N·m·s/rad",
            ImpedanceError::TorqueOutOfRange => "feed-forward torque beyond ±100 N·m",
            ImpedanceError::TargetOutOfRange => "target beyond ±10 000 rad",
        })
    }
}

impl core::error::Error for ImpedanceError {}

/// A running impedance command: the per-tick constants and the reference state.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Impedance {
    command: ImpedanceCommand,
    /// θ_t, rad Q32.
    target: i64,
    /// τ_ff, N·m Q16.
    torque_q16: i32,
    /// 1/k_v, rad per N·m (Q16 in, Q32 out).
    inv_k: Gain,
    /// β = Δt/(T + Δt), the lag's step per tick (Q16 in, Q32 out).
    beta: Gain,
    /// θ_r, rad Q32.
    reference: i64,
    /// The position loop is still moving the link to θ_t (the approach): the law starts
    /// when that move ends.
    approaching: bool,
}

impl Impedance {
    /// Checks `cmd` against the beams' stiffness of `schedule` (the clutch setting in use)
    /// and prepares it for the configured link inertia `link_inertia` (the reference's lag,
    /// see [`LAG_BANDWIDTH_RATIO`]). Configuration-time maths: divisions. The law starts
    /// after [`Impedance::approach`] has brought the link to θ_t.
    ///
    /// # Errors
    /// An [`ImpedanceError`] for a value outside its range.
    pub fn new(
        cmd: &ImpedanceCommand,
        schedule: &Schedule,
        link_inertia: Inertia,
    ) -> Result<Impedance, ImpedanceError> {
        if cmd.target.saturating_abs() > Angle::from_int(MAX_ANGLE_RAD) {
            return Err(ImpedanceError::TargetOutOfRange);
        }
        let k_v = cmd.stiffness.get();
        if k_v < I64F64::from_num(MIN_STIFFNESS_NM_PER_RAD) {
            return Err(ImpedanceError::StiffnessOutOfRange);
        }
        if k_v > schedule.stiffness().get() {
            return Err(ImpedanceError::StiffnessAbovePhysical);
        }
        if cmd.damping < I32F32::ZERO || cmd.damping > MAX_DAMPING_NMS_PER_RAD {
            return Err(ImpedanceError::DampingOutOfRange);
        }
        if cmd.torque.saturating_abs() > Torque::from_int(MAX_FEED_FORWARD_NM) {
            return Err(ImpedanceError::TorqueOutOfRange);
        }
        // k_v ≥ 0.1: 1/k_v ≤ 10 fits; k_v·Δt > 0, so β ∈ (0, 1].
        let inv_k = I64F64::ONE
            .checked_div(k_v)
            .and_then(Gain::new)
            .ok_or(ImpedanceError::StiffnessOutOfRange)?;
        // Time constant T = max(d_v/k_v, 4/ω_c, 8·J_l·ω_c/k_v) s; β = Δt/(T + Δt).
        let t_virtual = I64F64::from_num(cmd.damping)
            .checked_div(k_v)
            .ok_or(ImpedanceError::DampingOutOfRange)?;
        let t_loop = I64F64::from_num(LAG_BANDWIDTH_RATIO)
            .checked_div(I64F64::from_num(schedule.bandwidth().get()))
            .unwrap_or(I64F64::ZERO);
        // The outer loop's gain at ω_c, J·ω_c/(k_v·T), at most 1/`LAG_INERTIA_RATIO`.
        let j = I64F64::from_num(link_inertia.get()) / 1_000_000; // kg·m²
        let t_inertia = j
            .checked_mul(I64F64::from_num(schedule.bandwidth().get()))
            .and_then(|x| x.checked_mul_int(i128::from(LAG_INERTIA_RATIO)))
            .and_then(|x| x.checked_div(k_v))
            .unwrap_or(I64F64::ZERO);
        let dt = I64F64::ONE / i128::from(TICKS_PER_S);
        let beta = dt
            .checked_div(t_virtual.max(t_loop).max(t_inertia) + dt)
            .and_then(Gain::new)
            .ok_or(ImpedanceError::DampingOutOfRange)?;
        Ok(Impedance {
            command: *cmd,
            target: cmd.target.to_bits(),
            torque_q16: q32_to_q16(cmd.torque.to_bits()),
            inv_k,
            beta,
            reference: cmd.target.to_bits(),
            approaching: true,
        })
    }

    /// The position command that takes the link from the reference `start` to θ_t before
    /// the law starts: a minimum-jerk move of [`APPROACH_MS_PER_RAD`] ms per rad, at least
    /// [`APPROACH_MIN_MS`] (a spring stretched by |θ_t − θ| at once would ask the loop for a
    /// raw step with the reference moving on; the move's feed-forward follows it cleanly),
    /// or a step within one encoder count.
    #[must_use]
    pub fn approach(&self, start: Angle) -> Command {
        let target = Angle::from_bits(self.target);
        let h = i128::from(self.target.saturating_sub(start.to_bits())).unsigned_abs();
        if h <= ENCODER_COUNT_Q32 {
            return Command::Step { target };
        }
        // ms = |h|·APPROACH_MS_PER_RAD, |h| in Q32 rad.
        let ms = (h.saturating_mul(u128::from(APPROACH_MS_PER_RAD)) >> 32)
            .clamp(u128::from(APPROACH_MIN_MS), u128::from(MAX_MOVE_MS));
        Command::Move {
            target,
            duration_ms: u32::try_from(ms).unwrap_or(MAX_MOVE_MS),
        }
    }

    /// The command being carried out.
    #[must_use]
    pub const fn command(&self) -> &ImpedanceCommand {
        &self.command
    }

    /// Whether the approach move to θ_t is still under way (the law waits).
    #[must_use]
    pub const fn approaching(&self) -> bool {
        self.approaching
    }

    /// θ_r, the link reference for the position loop in this tick.
    #[must_use]
    pub const fn reference(&self) -> Angle {
        Angle::from_bits(self.reference)
    }

    /// One tick of eq. I1 with the coupling-torque estimate `torque` of the tick just run:
    /// the reference for the next tick. Total, saturating, within ±[`MAX_ANGLE_RAD`].
    /// While the approach runs (`moving`: the position loop's trajectory is still under
    /// way) it waits and returns θ_t.
    pub fn advance(&mut self, torque: Torque, moving: bool) -> Angle {
        if self.approaching {
            if moving {
                return self.reference();
            }
            self.approaching = false;
        }
        let tau = q32_to_q16(torque.to_bits());
        // θ_eq = θ_t + (τ_ff − τ̂)/k_v (eq. I1 at rest)
        let offset = self.inv_k.apply_wide(self.torque_q16.saturating_sub(tau));
        let eq = self.target.saturating_add(offset);
        // θ_r ← θ_r + β·(θ_eq − θ_r) (eq. I1, backward Euler)
        let step = self
            .beta
            .apply_wide(q32_to_q16(eq.saturating_sub(self.reference)));
        self.reference = clamp_angle(self.reference.saturating_add(step));
        self.reference()
    }
}

/// Clamps a Q32 angle to ±[`MAX_ANGLE_RAD`] (what the position loop accepts).
fn clamp_angle(bits: i64) -> i64 {
    let lim = i64::from(MAX_ANGLE_RAD) << 32;
    bits.clamp(-lim, lim)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::control::Config;
    use crate::{Design, Length};

    const J: Inertia = Inertia::from_int(1000);

    fn schedule(l: i32) -> Schedule {
        Schedule::new(&Design::paper(), &Config::paper(Length::from_int(l))).unwrap()
    }

    fn cmd(k: i64, d_milli: i32, ff_milli: i32) -> ImpedanceCommand {
        ImpedanceCommand {
            target: Angle::from_micro(300_000).unwrap(),
            stiffness: Stiffness::from_int(k),
            damping: I32F32::from_num(d_milli) / 1000,
            torque: Torque::from_micro(i64::from(ff_milli) * 1000).unwrap(),
        }
    }

    #[test]
    fn refuses_a_stiffness_above_the_beams_and_values_out_of_range() {
        let s = schedule(5); // k(5 mm) = 57.3 N·m/rad
        assert!(Impedance::new(&cmd(57, 200, 0), &s, J).is_ok());
        assert_eq!(
            Impedance::new(&cmd(58, 200, 0), &s, J),
            Err(ImpedanceError::StiffnessAbovePhysical)
        );
        assert_eq!(
            Impedance::new(&cmd(0, 200, 0), &s, J),
            Err(ImpedanceError::StiffnessOutOfRange)
        );
        assert_eq!(
            Impedance::new(&cmd(20, -1, 0), &s, J),
            Err(ImpedanceError::DampingOutOfRange)
        );
        assert_eq!(
            Impedance::new(&cmd(20, 100_001, 0), &s, J),
            Err(ImpedanceError::DampingOutOfRange)
        );
        assert_eq!(
            Impedance::new(&cmd(20, 0, 100_001), &s, J),
            Err(ImpedanceError::TorqueOutOfRange)
        );
        let mut far = cmd(20, 0, 0);
        far.target = Angle::from_int(MAX_ANGLE_RAD + 1);
        assert_eq!(
            Impedance::new(&far, &s, J),
            Err(ImpedanceError::TargetOutOfRange)
        );
        // The stiffest setting takes what the softer one refused.
        assert!(Impedance::new(&cmd(58, 200, 0), &schedule(3), J).is_ok());
    }

    #[test]
    fn the_reference_lags_to_the_equilibrium_of_the_torque() {
        // k_v = 20 N·m/rad, d_v = 0.2 N·m·s/rad, τ_ff = 0.1 N·m, τ̂ = −0.2 N·m (an external
        // +0.2 N·m): θ_eq = 0.3 + 0.3/20 = 0.315 rad. Time constant: the largest of
        // d_v/k_v = 10 ms, 4/ω_c and 8·J·ω_c/k_v.
        let s = schedule(3);
        let mut imp = Impedance::new(&cmd(20, 200, 100), &s, J).unwrap();
        let tau = Torque::from_micro(-200_000).unwrap();
        // The approach: θ_t while the move runs.
        for _ in 0..3 {
            assert_eq!(imp.advance(tau, true), Angle::from_micro(300_000).unwrap());
        }
        let w_c = s.bandwidth().get().to_num::<f64>();
        let t = (0.2 / 20.0f64).max(4.0 / w_c).max(8.0 * 1e-3 * w_c / 20.0);
        let beta = 1e-3 / (t + 1e-3);
        let mut want = 0.3f64;
        for _ in 0..2000 {
            let got = imp.advance(tau, false).get().to_num::<f64>();
            want += beta * (0.315 - want);
            assert!((got - want).abs() < 2e-5, "{got} vs {want}");
        }
        assert!((imp.reference().get().to_num::<f64>() - 0.315).abs() < 2e-5);
    }

    #[test]
    fn the_approach_is_a_move_of_a_second_per_radian() {
        let imp = Impedance::new(&cmd(20, 200, 0), &schedule(3), J).unwrap();
        let target = Angle::from_micro(300_000).unwrap();
        assert_eq!(
            imp.approach(Angle::from_micro(-500_000).unwrap()),
            Command::Move {
                target,
                duration_ms: 800
            }
        );
        assert_eq!(
            imp.approach(Angle::ZERO),
            Command::Move {
                target,
                duration_ms: 300
            }
        );
        assert_eq!(
            imp.approach(Angle::from_micro(250_000).unwrap()),
            Command::Move {
                target,
                duration_ms: APPROACH_MIN_MS
            }
        );
        assert_eq!(
            imp.approach(Angle::from_micro(299_000).unwrap()),
            Command::Step { target }
        );
    }

    #[test]
    fn advance_is_total() {
        let mut imp = Impedance::new(&cmd(1, 0, 0), &schedule(8), J).unwrap();
        for t in [Torque::MAX, Torque::MIN, Torque::ZERO, Torque::from_int(-5)] {
            let r = imp.advance(t, false);
            assert!(r.saturating_abs() <= Angle::from_int(MAX_ANGLE_RAD));
        }
    }
}
