//! The clutch monitor (docs/design.md §7, docs/calibration.md): the clutch is slid by
//! hand, and a clutch longer than configured makes the beams softer *and* weaker
//! (k ∝ 1/L³, τ_cap ∝ 1/L, eqs. 1–4) than the supervisor believes. Every tick, called by
//! the supervisor:
//!
//! * an online estimate of the joint compliance 1/k from the measured deflection
//!   φ (pot − encoder, beyond the free play on the torque's side) and the motor-side
//!   torque τ = k_t·i − J_g·ω̇_g − b_v·ω_g (the controller's `Output::motor_torque_q16`,
//!   ω̇_g through its derivative filter): least squares of φ on τ with exponential
//!   forgetting (recursive least squares of one parameter, forgetting factor
//!   λ = 1 − 2⁻⁸, a time constant of 256 ticks), kept as the two weighted sums Σλⁿτφ and
//!   Σλⁿτ² so that the per-tick work is multiplies and shifts, no division. Regressing φ on τ (not τ on φ)
//!   leaves the pot's coarse quantisation in the residual instead of biasing the slope.
//! * the capacity the overload check uses: until the estimate confirms the configured
//!   stiffness, the weakest one the clutch tolerance allows, τ_cap(L)·L/(L + ΔL);
//!   confirmed (the compliance's upper bound within [`CONFIRM_RATIO`] of the configured
//!   one), τ_cap(L)·[`CONFIRM_RATIO`]^(−1/3) (the longest clutch that compliance
//!   allows);
//! * [`FaultCode::ClutchMismatch`](crate::supervisor::FaultCode::ClutchMismatch) when the
//!   compliance's lower bound (the pot's half-count quantisation taken against the
//!   estimate, a third sum Σλⁿ|τ|) stays above [`MISMATCH_RATIO`] × the configured one
//!   (k below 80 %: the clutch about 8 % longer than configured) for 64 consecutive ticks.
//!   A fixed ratio, not the tolerance's ((L + ΔL)/L)³ (1.40 at 5 mm with 0.6 mm): the
//!   lower bound is conservative, and at 1.40 it let a clutch 1 mm long at 5 mm (1.73×)
//!   through in three of four motions (docs/calibration.md).
//!
//! Evidence: a decision needs Σλⁿτ² ≥ (τ_ev)²·256, τ_ev the torque that deflects the
//! configured beams by one pot count: the torque must have been large enough, for about
//! the forgetting time, to move the pot. With a 0.29° pot that is the case at the soft
//! settings only (L ≳ 4 mm on the paper's beams, docs/calibration.md); elsewhere the
//! monitor stays undecided and the weak capacity stays in force.

use crate::control::{Output, Schedule};
use crate::sensors::POT_COUNT_Q32;

/// Compliance ratio (estimated / configured) above which the clutch is declared longer
/// than configured, Q16: 1.25 (k below 80 %).
pub const MISMATCH_RATIO: i64 = 5 << 14;
/// Compliance ratio below which the configured stiffness is confirmed, Q16: 1.1.
pub const CONFIRM_RATIO: i64 = 72_090;
/// Forgetting shift: λ = 1 − 2⁻⁸.
const FORGET: u32 = 8;
/// Low-pass shift of φ and τ before the regression (α = 1/16).
const SMOOTH: u32 = 4;
/// Bounds of the regression's samples: |τ| ≤ 4 N·m (Q12: 2¹⁴), |φ_e| ≤ 0.125 rad (Q16:
/// 2¹³). With them |τ·φ| < 2²⁷ and τ² ≤ 2²⁸ fit an i32, the sums stay below 2³⁶
/// (2⁸ samples' worth), s_tp·2²⁴ below 2⁶⁰ and a threshold (≤ 1.25 × [`COMPLIANCE_MAX_28`])
/// times s_tt below 1.25·2⁶²: plain i64 arithmetic, no overflow (the clamps make the
/// bounds hold).
const TAU_MAX_Q12: i32 = 1 << 14;
const PHI_MAX_Q16: i32 = 1 << 13;
/// Consecutive ticks the estimate must stay beyond the mismatch ratio (a violent
/// transient, e.g. a raw step's impacts, is not evidence).
const MISMATCH_TICKS: u16 = 64;
/// The largest configured compliance the decisions' i64 products hold (above), rad per
/// N·m × 2²⁸: 2²⁶, k ≥ 4 N·m/rad (the paper's beams at 8 mm: 14 N·m/rad). Softer beams
/// leave the monitor undecided (the weak capacity stays in force).
pub const COMPLIANCE_MAX_28: i64 = 1 << 26;

/// What the monitor concluded so far.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ClutchState {
    /// Not enough evidence: the weak capacity applies.
    Unknown,
    /// The configured stiffness is confirmed.
    Confirmed,
    /// Softer than configured beyond the tolerance.
    Mismatch,
}

/// Constants derived from the schedule (configuration time).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ClutchLimits {
    /// Configured compliance 1/k, rad per N·m × 2²⁸ (the regression's φ Q16 over τ Q12,
    /// × 2²⁴), at most [`COMPLIANCE_MAX_28`].
    compliance_28: i64,
    /// `MISMATCH_RATIO` and `CONFIRM_RATIO` × `compliance_28`.
    mismatch_28: i64,
    confirm_28: i64,
    /// Free play φ_b, rad Q16.
    free_play_q16: i32,
    /// Half a pot count, rad Q16: the pot's quantisation error bound.
    half_count_q16: i64,
    /// |τ| below which the beams may be anywhere in the free play, N·m Q16.
    contact_q16: i32,
    /// Least Σλⁿτ² for a decision, N·m² Q24.
    evidence: i64,
    /// Capacity while undecided and once confirmed, I32F32 N·m.
    cap_weak: i64,
    cap_confirmed: i64,
}

impl ClutchLimits {
    /// For the schedule `sched`: τ_cap and k at the configured L, and the clutch
    /// tolerance (the clutch may be that much longer than configured).
    #[must_use]
    pub fn new(sched: &Schedule) -> ClutchLimits {
        let setting = sched.setting();
        let cap = setting.torque_capacity().to_bits();
        let tol = sched.clutch_tolerance().to_bits().max(0);
        // 1.1^(−1/3) = 0.96873, Q16 63486.
        let cap_confirmed = if tol == 0 {
            cap
        } else {
            ((i128::from(cap) * 63_486) >> 16) as i64
        };
        // k is I64F64 N·m/rad: 1/k × 2²⁸ = 2⁹²/k_bits.
        let k_bits = sched.stiffness().to_bits().max(1);
        let exact_28 = (1i128 << 92) / k_bits;
        let compliance_28 = exact_28.clamp(1, i128::from(COMPLIANCE_MAX_28)) as i64;
        // τ_ev (Q12) = one pot count / c = POT_COUNT_Q32·2⁸ / c₂₈; evidence τ_ev²·2^FORGET
        // (more than the sums can reach where the compliance is beyond the bound: the
        // clamped one would read those beams as soft).
        let tau_ev = (i128::from(POT_COUNT_Q32) << 8) / i128::from(compliance_28);
        let evidence = if exact_28 > i128::from(COMPLIANCE_MAX_28) {
            i64::MAX
        } else {
            (tau_ev * tau_ev * (1 << FORGET)).min(1 << 40) as i64
        };
        ClutchLimits {
            compliance_28,
            mismatch_28: (compliance_28 * MISMATCH_RATIO) >> 16,
            confirm_28: (compliance_28 * CONFIRM_RATIO) >> 16,
            free_play_q16: (sched.free_play().to_bits() >> 16) as i32,
            half_count_q16: POT_COUNT_Q32 >> 17,
            contact_q16: sched.contact_torque_q16.max(1 << 11),
            evidence,
            // τ_cap(L) itself without a tolerance.
            cap_weak: sched.weak_capacity().to_bits(),
            cap_confirmed,
        }
    }
}

/// The monitor's state.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ClutchMonitor {
    state: ClutchState,
    phi_f: i32,
    tau_f: i32,
    /// Σλⁿτ² (N·m² Q24) and Σλⁿτφ (N·m·rad Q28).
    s_tt: i64,
    s_tp: i64,
    /// Σλⁿ|τ| (N·m Q12): bounds what the pot's quantisation can add to Σλⁿτφ.
    s_ta: i64,
    /// Consecutive ticks beyond the mismatch ratio.
    beyond: u16,
    /// The estimate when the mismatch was found, ‰ of the configured compliance (the
    /// fault's value, computed once).
    mismatch_permille: i32,
}

impl Default for ClutchMonitor {
    fn default() -> Self {
        Self::new()
    }
}

impl ClutchMonitor {
    /// Undecided, no history.
    #[must_use]
    pub const fn new() -> ClutchMonitor {
        ClutchMonitor {
            state: ClutchState::Unknown,
            phi_f: 0,
            tau_f: 0,
            s_tt: 0,
            s_tp: 0,
            s_ta: 0,
            beyond: 0,
            mismatch_permille: 0,
        }
    }

    /// The conclusion so far.
    #[must_use]
    pub const fn state(&self) -> ClutchState {
        self.state
    }

    /// The estimated compliance relative to the configured one, Q16 (`None` without
    /// enough evidence). Divides: for reports, not the per-tick path.
    #[must_use]
    pub fn ratio_q16(&self, lim: &ClutchLimits) -> Option<i64> {
        (self.s_tt >= lim.evidence && self.s_tt > 0).then(|| {
            let num = i128::from(self.s_tp) << 40;
            (num / (i128::from(self.s_tt) * i128::from(lim.compliance_28))) as i64
        })
    }

    /// The estimate when the mismatch was found, ‰ of the configured compliance (0 before).
    #[must_use]
    pub const fn mismatch_permille(&self) -> i32 {
        self.mismatch_permille
    }

    /// The estimate relative to the configured compliance, ‰: two i64 divisions, for the
    /// one tick a mismatch is found (`ratio_q16` divides in i128).
    fn permille(&self, lim: &ClutchLimits) -> i32 {
        // s_tp·2²⁴ < 2⁶⁰ (the bounds at `TAU_MAX_Q12`); the estimate c·2²⁸.
        let est_28 = (self.s_tp << 24).checked_div(self.s_tt).unwrap_or(0);
        let permille = est_28
            .saturating_mul(1000)
            .checked_div(lim.compliance_28)
            .unwrap_or(0);
        permille.clamp(0, i64::from(i32::MAX)) as i32
    }

    /// The capacity (I32F32 N·m) the overload check uses now.
    #[must_use]
    pub const fn capacity(&self, lim: &ClutchLimits) -> i64 {
        match self.state {
            ClutchState::Confirmed => lim.cap_confirmed,
            _ => lim.cap_weak,
        }
    }

    /// One tick: `phi_q32` the measured deflection θ_g − θ_l (rad, I32F32), `out` the
    /// controller's output (its motor-side torque). Returns true while the mismatch holds
    /// (from the tick it is found until the monitor is reset).
    #[inline(always)]
    pub fn update(&mut self, phi_q32: i64, out: &Output, lim: &ClutchLimits) -> bool {
        if self.state == ClutchState::Mismatch {
            // A condition: it holds until the monitor is reset (a new configuration).
            return true;
        }
        let tau = out.motor_torque_q16;
        let phi = (phi_q32 >> 16).clamp(-(1 << 20), 1 << 20) as i32;
        self.tau_f = self
            .tau_f
            .saturating_add(tau.saturating_sub(self.tau_f) >> SMOOTH);
        self.phi_f = self
            .phi_f
            .saturating_add(phi.saturating_sub(self.phi_f) >> SMOOTH);
        if self.tau_f.saturating_abs() < lim.contact_q16 {
            return false;
        }
        // Deflection beyond the free play on the torque's side (eq. 5's dead zone).
        let phi_e = if self.tau_f > 0 {
            self.phi_f.saturating_sub(lim.free_play_q16)
        } else {
            self.phi_f.saturating_add(lim.free_play_q16)
        };
        let t = (self.tau_f >> 4).clamp(-TAU_MAX_Q12, TAU_MAX_Q12);
        let p = phi_e.clamp(-PHI_MAX_Q16, PHI_MAX_Q16);
        self.s_tt = self.s_tt - (self.s_tt >> FORGET) + i64::from(t * t);
        self.s_tp = self.s_tp - (self.s_tp >> FORGET) + i64::from(t * p);
        self.s_ta = self.s_ta - (self.s_ta >> FORGET) + i64::from(t.abs());
        if self.s_tt < lim.evidence {
            return false;
        }
        // c = s_tp/s_tt against r·c_cfg without dividing (bounds at `TAU_MAX_Q12`).
        // A mismatch only on the estimate's lower bound, a confirmation only on its upper
        // one: each φ may be off by half a pot count (|e| ≤ q), so Σλⁿτφ by at most
        // q·Σλⁿ|τ|. A still hold whose deflection sits between two counts otherwise reads
        // up to q/φ too soft (or too stiff).
        let q = lim.half_count_q16 * self.s_ta;
        let low = self.s_tp.saturating_sub(q) << 24;
        if low > lim.mismatch_28 * self.s_tt {
            self.beyond = self.beyond.saturating_add(1);
            if self.beyond >= MISMATCH_TICKS {
                self.state = ClutchState::Mismatch;
                self.mismatch_permille = self.permille(lim);
                return true;
            }
            return false;
        }
        self.beyond = 0;
        let high = self.s_tp.saturating_add(q) << 24;
        if self.state == ClutchState::Unknown && high <= lim.confirm_28 * self.s_tt {
            self.state = ClutchState::Confirmed;
        }
        false
    }
}
