//! Friction hysteresis of the clutch (design.md §2.1, the paper's §2.3 made concrete).
//!
//! A cantilever's tip load foreshortens it by (3/5)·δ²/L, so the beam slides through the
//! clutch by du = (6/5)(δ/L)·dδ and kinetic friction μ·P over that slide dissipates
//! energy. Summed over n beams at radius R:
//!
//! τ = k·φ·(1 ± (6/5)·μ·δ/L), δ = R·|φ|, `+` while loading (|φ| growing), `−` while
//! unloading (|φ| shrinking).
//!
//! Conventions chosen here (the formula is silent on them):
//! * δ is the magnitude R·|φ|, so the loop is odd-symmetric: τ(−φ) = −τ(φ) on each branch.
//! * The unloading factor 1 − (6/5)·μ·δ/L is clamped at 0: beyond δ = (5/6)·L/μ (1.34 rad
//!   at L = 5 mm for the paper preset, far past the stress limit) the model no longer
//!   holds and the torque stays 0 rather than reversing.
//! * k is the setting's stiffness (E–B or Timoshenko, as chosen in [`Setting::new`]).
//! * Combined with the free play ([`crate::backlash`]): the beams only deflect once the
//!   slot touches them, so φ is first reduced by the dead zone, φ_e = sign(φ)·max(|φ| − φ_b, 0),
//!   and the branch formula is applied to φ_e (with δ = R·|φ_e|). Inside the dead zone the
//!   torque is 0 on both branches.
//!
//! [`Hysteresis`] is the small state machine around it: it keeps the last deflection and
//! the branch, and switches branch when the motion reverses (§2.1).

use crate::beam::{or_overflow, torque_from, Setting};
use crate::error::Result;
use crate::fixmath::SoftFloat;
use crate::units::{Angle, Torque};

/// Branch of the hysteresis loop.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Branch {
    /// |φ| growing: friction adds to the elastic torque, factor 1 + (6/5)·μ·δ/L.
    #[default]
    Loading,
    /// |φ| shrinking: friction subtracts, factor max(1 − (6/5)·μ·δ/L, 0).
    Unloading,
}

impl Setting {
    /// |τ| on `branch` for a beam deflection magnitude `d` (rad).
    fn branch_magnitude(&self, d: SoftFloat, branch: Branch) -> Option<SoftFloat> {
        let a = self.friction.mul(d)?; // §2.1: (6/5)·μ·δ/L
        let factor = match branch {
            Branch::Loading => SoftFloat::ONE.add(a)?,
            Branch::Unloading => SoftFloat::ONE.saturating_sub(a),
        };
        self.k.mul(d)?.mul(factor)
    }

    /// Torque on a hysteresis branch, τ = k·φ·(1 ± (6/5)·μ·R·|φ|/L), without free play
    /// (the paper's Fig. 4 loop).
    ///
    /// # Errors
    /// [`crate::Error::Overflow`] if |τ| ≥ 2³¹ N·m.
    pub fn branch_torque(&self, phi: Angle, branch: Branch) -> Result<Torque> {
        let (d, negative) = SoftFloat::from_bits(phi.to_bits(), 32);
        torque_from(or_overflow(self.branch_magnitude(d, branch))?, negative)
    }

    /// Coupling torque with free play and friction: the branch formula applied to the
    /// deflection beyond the dead zone, φ_e = sign(φ)·max(|φ| − φ_b, 0).
    ///
    /// # Errors
    /// [`crate::Error::Overflow`] if |τ| ≥ 2³¹ N·m.
    pub fn hysteretic_coupling_torque(&self, phi: Angle, branch: Branch) -> Result<Torque> {
        let (d, negative) = self.beyond_free_play(phi);
        torque_from(or_overflow(self.branch_magnitude(d, branch))?, negative)
    }
}

/// The hysteresis state machine: last deflection and current branch.
///
/// Direction rule, on the raw deflection φ: moving away from zero (|φ| grows, or φ crosses
/// zero) is loading, moving towards zero is unloading, no motion keeps the branch.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Hysteresis {
    last: Angle,
    branch: Branch,
    free_play: bool,
}

impl Default for Hysteresis {
    fn default() -> Self {
        Self::new()
    }
}

impl Hysteresis {
    /// At rest (φ = 0, loading), with the free-play dead zone (the coupling as built).
    #[must_use]
    pub const fn new() -> Self {
        Hysteresis {
            last: Angle::ZERO,
            branch: Branch::Loading,
            free_play: true,
        }
    }

    /// At rest, without the dead zone (the pure friction loop of the paper's Fig. 4).
    #[must_use]
    pub const fn without_free_play() -> Self {
        Hysteresis {
            last: Angle::ZERO,
            branch: Branch::Loading,
            free_play: false,
        }
    }

    /// The current branch.
    #[must_use]
    pub const fn branch(&self) -> Branch {
        self.branch
    }

    /// The last deflection seen.
    #[must_use]
    pub const fn last(&self) -> Angle {
        self.last
    }

    /// Back to rest (φ = 0, loading), keeping the free-play choice.
    pub fn reset(&mut self) {
        self.last = Angle::ZERO;
        self.branch = Branch::Loading;
    }

    /// Records the deflection `phi` and returns the branch it puts the loop on.
    pub fn update(&mut self, phi: Angle) -> Branch {
        let (now, before) = (phi.to_bits(), self.last.to_bits());
        if now != before {
            let crossed = (now < 0 && before > 0) || (now > 0 && before < 0) || before == 0;
            self.branch = if crossed || now.unsigned_abs() > before.unsigned_abs() {
                Branch::Loading
            } else {
                Branch::Unloading
            };
            self.last = phi;
        }
        self.branch
    }

    /// One step: updates the branch with `phi`, then returns the coupling torque on it
    /// (with or without free play, see [`Hysteresis::new`]). The state is updated even if
    /// the torque overflows.
    ///
    /// # Errors
    /// [`crate::Error::Overflow`] if |τ| ≥ 2³¹ N·m.
    pub fn step(&mut self, setting: &Setting, phi: Angle) -> Result<Torque> {
        let branch = self.update(phi);
        if self.free_play {
            setting.hysteretic_coupling_torque(phi, branch)
        } else {
            setting.branch_torque(phi, branch)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::beam::BeamModel;
    use crate::design::Design;
    use crate::units::Length;
    use fixed::types::I32F32;

    fn setting(l: i32) -> Setting {
        Setting::new(
            &Design::paper(),
            Length::from_int(l),
            BeamModel::EulerBernoulli,
        )
        .unwrap()
    }

    fn a(v: &str) -> Angle {
        Angle::from_fixed(I32F32::lit(v))
    }

    fn t(v: Torque) -> f64 {
        v.get().to_num::<f64>()
    }

    #[test]
    fn branches_match_formula() {
        let s = setting(4);
        let k = s.stiffness().get().to_num::<f64>();
        let r = I32F32::lit("7.8").to_num::<f64>();
        let mu = I32F32::lit("0.4").to_num::<f64>();
        for phi in ["0.001", "0.02", "-0.02", "0.3"] {
            let p = I32F32::lit(phi).to_num::<f64>();
            let c = 1.2 * mu * r * p.abs() / 4.0;
            let up = t(s.branch_torque(a(phi), Branch::Loading).unwrap());
            let down = t(s.branch_torque(a(phi), Branch::Unloading).unwrap());
            assert!(((up - k * p * (1.0 + c)) / up).abs() < 1e-8, "{phi}");
            assert!(((down - k * p * (1.0 - c)) / down).abs() < 1e-8, "{phi}");
            assert!(up.abs() > down.abs());
        }
        assert_eq!(
            s.branch_torque(Angle::ZERO, Branch::Loading),
            Ok(Torque::ZERO)
        );
        // Unloading factor clamps at 0 beyond δ = (5/6)·L/μ.
        assert_eq!(s.branch_torque(a("2"), Branch::Unloading), Ok(Torque::ZERO));
        // Overflow at Angle::MAX/MIN: host-tests/tests/bad_input.rs, for both beam models.
    }

    #[test]
    fn state_machine_switches_on_reversal() {
        let s = setting(5);
        let mut h = Hysteresis::without_free_play();
        assert_eq!(h.branch(), Branch::Loading);
        let up = h.step(&s, a("0.02")).unwrap();
        assert_eq!(h.branch(), Branch::Loading);
        assert_eq!(up, s.branch_torque(a("0.02"), Branch::Loading).unwrap());
        h.step(&s, a("0.03")).unwrap();
        assert_eq!(h.branch(), Branch::Loading);
        // Reversal: back towards zero.
        let down = h.step(&s, a("0.02")).unwrap();
        assert_eq!(h.branch(), Branch::Unloading);
        assert!(t(down) < t(up));
        // No motion keeps the branch.
        h.step(&s, a("0.02")).unwrap();
        assert_eq!(h.branch(), Branch::Unloading);
        // Crossing zero is loading on the other side.
        let neg = h.step(&s, a("-0.01")).unwrap();
        assert_eq!(h.branch(), Branch::Loading);
        assert!(t(neg) < 0.0);
        h.step(&s, a("-0.005")).unwrap();
        assert_eq!(h.branch(), Branch::Unloading);
        assert_eq!(h.last(), a("-0.005"));
        h.reset();
        assert_eq!((h.branch(), h.last()), (Branch::Loading, Angle::ZERO));
        // Loop is odd-symmetric.
        let p = s.branch_torque(a("0.05"), Branch::Unloading).unwrap();
        let m = s.branch_torque(a("-0.05"), Branch::Unloading).unwrap();
        assert_eq!(p.checked_neg(), Some(m));
    }

    #[test]
    fn free_play_then_friction() {
        let s = setting(5);
        let mut h = Hysteresis::default();
        let pb = s.free_play();
        assert_eq!(h.step(&s, pb), Ok(Torque::ZERO));
        let phi = a("0.05");
        let tau = h.step(&s, phi).unwrap();
        let beyond = phi.checked_sub(pb).unwrap();
        let want = t(s.branch_torque(beyond, Branch::Loading).unwrap());
        // `want` used the rounded φ − φ_b.
        assert!(((t(tau) - want) / want).abs() <= 1e-8, "{tau} {want}");
        // Back into the dead zone: unloading, zero torque.
        assert_eq!(h.step(&s, Angle::ZERO), Ok(Torque::ZERO));
        assert_eq!(h.branch(), Branch::Unloading);
    }
}
