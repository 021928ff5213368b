//! Feed-forward of a sine reference through the two-mass inverse (docs/design.md §11,
//! step 6).
//!
//! For any reference the controller feeds forward the rigid body's inverse,
//! u_ff = (1000/V_s)·[(k_e + R·b_v/k_t)·ṙ + (R/k_t)·(J_g + J_l)·r̈] (`Schedule::ff_vel`,
//! `ff_acc`), and the back-EMF of the deflection change the beams need,
//! u_defl = (1000/V_s)·k_e·Δφ_ref/dt with φ_ref = J_l·r̈/k + … (step 7). The gear's own
//! inertia and friction for that deflection are missing; for a slow or stiff motion they
//! are small, but at the coupling resonance the rigid inverse asks for the whole
//! (J_g + J_l)·A·ω² where the two-mass system needs no motor torque at all.
//!
//! For a sine r = c + A·sin(ωt) the missing part is known in advance: the deflection
//! φ = J_l·r̈/k = −(J_l·ω²/k)·(r − c) moves with the reference, so the gear follows
//! θ_g = r + φ with θ̇_g = g·ṙ and θ̈_g = g·r̈, g = 1 − J_l·ω²/k. The motor torque
//! T_m = J_g·θ̈_g + b_v·θ̇_g + J_l·r̈ (+ the load the integrator holds) differs from the
//! rigid one by (g − 1)·(J_g·r̈ + b_v·ṙ). So, with c_ω = J_l·ω²/k,
//!
//! ```text
//! K_v = ff_vel − c_ω·(1000/V_s)·R·b_v/k_t,   K_a = ff_acc − c_ω·(1000/V_s)·R·J_g/k_t
//! ```
//!
//! replace the rigid gains while the sine runs: no per-tick cost, the same two multiplies.
//! At the coupling resonance ω² = k·(1/J_g + 1/J_l), J_g·g + J_l = 0 and K_a = 0: the motor
//! supplies only the losses. Computed when the sine is commanded and when the configuration
//! changes (divisions in I64F64, `super::wide`); any other command uses the rigid gains.

use fixed::types::I64F64;

use super::config::Config;
use super::error::ControlError;
use super::gain::Gain;
use super::schedule::Schedule;
use super::trajectory::Command;
use super::wide::{div, mul, sub, to_gain, wide};
use crate::units::Frequency;

/// The feed-forward gains on ṙ and r̈ in use, and the sine frequency they were made for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FeedForward {
    /// ‰ per rad/s of ṙ.
    pub(crate) vel: Gain,
    /// ‰ per rad/s² of r̈.
    pub(crate) acc: Gain,
    /// ω of the running sine, `None` for any other reference.
    omega: Option<Frequency>,
}

impl FeedForward {
    /// The rigid body's inverse (every reference but a sine).
    #[must_use]
    pub(crate) const fn rigid(s: &Schedule) -> FeedForward {
        FeedForward {
            vel: s.ff_vel,
            acc: s.ff_acc,
            omega: None,
        }
    }

    /// The gains for `cmd`: the two-mass inverse for a sine, else the rigid one.
    ///
    /// # Errors
    /// [`ControlError::TrajectoryOutOfRange`] if a sine's gains do not fit their format.
    pub(crate) fn for_command(
        s: &Schedule,
        cfg: &Config,
        cmd: &Command,
    ) -> Result<FeedForward, ControlError> {
        match *cmd {
            Command::Sine { frequency, .. } => {
                sine(s, cfg, frequency).map_err(|_| ControlError::TrajectoryOutOfRange)
            }
            _ => Ok(FeedForward::rigid(s)),
        }
    }

    /// The same reference under a new schedule and configuration.
    ///
    /// # Errors
    /// [`ControlError::Overflow`] if a sine's gains do not fit their format.
    pub(crate) fn reconfigure(&self, s: &Schedule, cfg: &Config) -> Result<Self, ControlError> {
        match self.omega {
            Some(w) => sine(s, cfg, w),
            None => Ok(FeedForward::rigid(s)),
        }
    }

    /// The gain on ṙ, ‰ per rad/s.
    #[must_use]
    pub fn velocity_gain(&self) -> I64F64 {
        self.vel.value()
    }

    /// The gain on r̈, ‰ per rad/s².
    #[must_use]
    pub fn acceleration_gain(&self) -> I64F64 {
        self.acc.value()
    }
}

/// K_v and K_a of the module docs for a sine of ω (rad/s).
fn sine(s: &Schedule, cfg: &Config, omega: Frequency) -> Result<FeedForward, ControlError> {
    let m = &cfg.motor;
    let mega = I64F64::from_num(1_000_000);
    let j_gear = div(wide(m.rotor_inertia.get()), mega)?; // kg·mm² → kg·m²
    let j_link = div(wide(cfg.link_inertia.get()), mega)?;
    let w = wide(omega.get());
    // c_ω = J_l·ω²/k; (1000/V_s)·R/k_t, ‰ per N·m.
    let c = div(mul(mul(j_link, w)?, w)?, s.stiffness().get())?;
    let duty_per_nm = div(
        div(
            mul(I64F64::from_num(1000), wide(m.resistance_ohm))?,
            wide(m.supply_v),
        )?,
        wide(m.torque_constant),
    )?;
    let per_c = mul(c, duty_per_nm)?;
    Ok(FeedForward {
        vel: to_gain(sub(s.ff_vel.value(), mul(per_c, wide(m.viscous))?)?)?,
        acc: to_gain(sub(s.ff_acc.value(), mul(per_c, j_gear)?)?)?,
        omega: Some(omega),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::design::Design;
    use crate::units::{Angle, Inertia, Length};

    fn f(x: I64F64) -> f64 {
        x.to_num()
    }

    /// Against the two-mass inverse written out in f64: duty amplitude of the motor torque
    /// for a link that follows A·sin(ωt), J_g·g·r̈ + J_l·r̈ + b_v·g·ṙ plus the back-EMF.
    #[test]
    fn gains_are_the_two_mass_inverse() {
        let d = Design::paper();
        for (l, jl, hz) in [(5, 1000, 2.0), (8, 3200, 5.0), (3, 500, 20.0)] {
            let mut cfg = Config::paper(Length::from_int(l));
            cfg.link_inertia = Inertia::from_int(jl);
            let s = Schedule::new(&d, &cfg).unwrap();
            let w = Frequency::from_hz(fixed::types::I32F32::from_num(hz)).unwrap();
            let ff = FeedForward::for_command(
                &s,
                &cfg,
                &Command::Sine {
                    amplitude: Angle::from_int(1),
                    frequency: w,
                },
            )
            .unwrap();
            let k = f(s.stiffness().get());
            let (j_g, j_l, om) = (3.2e-3, f64::from(jl) * 1e-6, w.get().to_num::<f64>());
            let g = 1.0 - j_l * om * om / k;
            let dpv = 1000.0 / 12.0;
            let acc = dpv * 8.0 * (j_g * g + j_l);
            let vel = dpv * (8.0 * 1e-3 * g + 1.94);
            assert!((f(ff.acceleration_gain()) - acc).abs() < 1e-6 * acc.abs().max(1.0));
            assert!((f(ff.velocity_gain()) - vel).abs() < 1e-6 * vel);
            // Any other command: the rigid gains; reconfiguring keeps the sine's ω.
            let rigid = FeedForward::for_command(&s, &cfg, &Command::Hold).unwrap();
            assert_eq!(rigid, FeedForward::rigid(&s));
            let rig_acc = dpv * 8.0 * (j_g + j_l);
            assert!((f(rigid.acceleration_gain()) - rig_acc).abs() < 1e-6 * rig_acc);
            assert_eq!(ff.reconfigure(&s, &cfg).unwrap(), ff);
        }
    }

    #[test]
    fn no_motor_torque_for_the_motion_at_the_coupling_resonance() {
        let d = Design::paper();
        let mut cfg = Config::paper(Length::from_int(6));
        cfg.link_inertia = Inertia::from_int(3200);
        let s = Schedule::new(&d, &cfg).unwrap();
        let k = f(s.stiffness().get());
        let om = (k * 2.0 / 3.2e-3).sqrt();
        let w = Frequency::from_bits(fixed::types::I32F32::from_num(om).to_bits());
        let ff = sine(&s, &cfg, w).unwrap();
        // J_g·g + J_l = 0 up to the rounding of ω: |K_a| ≪ the rigid (1000/12)·8·6.4e-3.
        assert!(f(ff.acceleration_gain()).abs() < 1e-6, "{ff:?}");
    }
}
