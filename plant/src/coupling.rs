//! The four-beam coupling: free play, linear beam stiffness and friction hysteresis.

use crate::config::CouplingConfig;

/// Which part of the hysteresis band the coupling torque is on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Branch {
    /// Inside the free play (φ_e = 0, torque 0).
    DeadZone,
    /// Loading branch τ = k·φ_e·(1 + c·|φ_e|) (|φ_e| growing, friction resists).
    Loading,
    /// Unloading branch τ = k·φ_e·(1 − c·|φ_e|) (|φ_e| shrinking).
    Unloading,
    /// Between the branches after a reversal (the beam contact sticks), or no hysteresis.
    Elastic,
}

/// Coupling torque as a function of the deflection history.
///
/// Model (`docs/design.md` §2, §2.1): φ_e = sign(φ)·max(|φ| − φ_b, 0); the torque lies in the band
/// between the unloading branch k·φ_e·(1 − c·|φ_e|) and the loading branch
/// k·φ_e·(1 + c·|φ_e|), c = (6/5)·μ·R/L. The branch is kept as state in the torque itself
/// (a Prandtl / elastic–plastic operator): each update moves the torque by
/// k_s·Δφ_e (k_s = `stick_stiffness_ratio`·k) and clamps it into the band. While |φ_e|
/// grows the torque rides the loading branch, after a reversal it leaves it along the steep
/// slope k_s (the contact sticks) until it reaches the unloading branch: the "reversal
/// switches branch" of §2.1, over a deflection span of about 2·c·φ_e²/ratio instead of
/// instantly, which keeps the torque continuous in φ (no chatter, explicit integration
/// stays stable). Without hysteresis (c = 0) the torque is exactly k·φ_e.
///
/// Sign convention: positive torque acts on the link in the positive direction (and on the
/// gear in the negative one) when θ_gear > θ_link.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Coupling {
    k: f32,
    free_play: f32,
    c: f32,
    k_stick: f32,
    phi_e: f32,
    torque: f32,
    branch: Branch,
}

#[inline]
fn abs(x: f32) -> f32 {
    if x < 0.0 {
        -x
    } else {
        x
    }
}

impl Coupling {
    /// A coupling at rest (zero deflection, zero torque).
    pub fn new(cfg: &CouplingConfig) -> Self {
        let k = if cfg.stiffness_nm_per_rad > 0.0 {
            cfg.stiffness_nm_per_rad
        } else {
            0.0
        };
        let ratio = if cfg.stick_stiffness_ratio > 1.0 {
            cfg.stick_stiffness_ratio
        } else {
            1.0
        };
        Self {
            k,
            free_play: if cfg.free_play_rad > 0.0 {
                cfg.free_play_rad
            } else {
                0.0
            },
            c: if cfg.hysteresis_per_rad > 0.0 {
                cfg.hysteresis_per_rad
            } else {
                0.0
            },
            k_stick: ratio * k,
            phi_e: 0.0,
            torque: 0.0,
            branch: Branch::DeadZone,
        }
    }

    /// Effective deflection after the free play, rad.
    #[inline]
    pub fn effective_deflection(&self, phi: f32) -> f32 {
        let mag = abs(phi) - self.free_play;
        if mag > 0.0 {
            if phi < 0.0 {
                -mag
            } else {
                mag
            }
        } else {
            0.0
        }
    }

    /// Forget the history: put the torque at the elastic value k·φ_e (middle of the band).
    pub fn reset(&mut self, phi: f32) {
        self.phi_e = self.effective_deflection(phi);
        self.torque = self.k * self.phi_e;
        self.branch = if self.phi_e == 0.0 {
            Branch::DeadZone
        } else {
            Branch::Elastic
        };
    }

    /// Advance to deflection `phi` (rad, θ_gear − θ_link) and return the coupling torque,
    /// N·m. A handful of float operations, no libm.
    #[inline]
    pub fn update(&mut self, phi: f32) -> f32 {
        let phi_e = self.effective_deflection(phi);
        let elastic = self.k * phi_e;
        if self.c == 0.0 || phi_e == 0.0 {
            self.branch = if phi_e == 0.0 {
                Branch::DeadZone
            } else {
                Branch::Elastic
            };
            self.phi_e = phi_e;
            self.torque = elastic;
            return elastic;
        }
        let mut rel = self.c * abs(phi_e);
        if rel > 1.0 {
            rel = 1.0;
        }
        let half_width = abs(elastic) * rel;
        let lo = elastic - half_width;
        let hi = elastic + half_width;
        let trial = self.torque + self.k_stick * (phi_e - self.phi_e);
        let (torque, branch) = if trial >= hi {
            (
                hi,
                if phi_e > 0.0 {
                    Branch::Loading
                } else {
                    Branch::Unloading
                },
            )
        } else if trial <= lo {
            (
                lo,
                if phi_e > 0.0 {
                    Branch::Unloading
                } else {
                    Branch::Loading
                },
            )
        } else {
            (trial, Branch::Elastic)
        };
        self.phi_e = phi_e;
        self.torque = torque;
        self.branch = branch;
        torque
    }

    /// Torque at the last update, N·m.
    #[inline]
    pub fn torque(&self) -> f32 {
        self.torque
    }

    /// Branch at the last update.
    pub fn branch(&self) -> Branch {
        self.branch
    }

    /// Effective deflection at the last update, rad.
    pub fn last_effective_deflection(&self) -> f32 {
        self.phi_e
    }

    /// Conservative (elastic) energy ½·k·φ_e² at the last update, J. The hysteresis part of
    /// the torque is friction and stores nothing.
    pub fn elastic_energy(&self) -> f32 {
        0.5 * self.k * self.phi_e * self.phi_e
    }
}
