//! An independent f64 reference ("oracle") of the beam mechanics in `docs/design.md` §2.
//!
//! Written straight from the formulas in `docs/design.md` §2, §2.1 and §2.2, in plain `f64` and
//! SI units throughout: metres, pascals, newtons, newton-metres, radians, kilogram square
//! metres, joules. It deliberately does not use the fixed-point `model` crate: tests compare
//! the two, so they must not share code.
//!
//! Naming: `l_act` is the active (clutch) length L of the beams; `self.l` is the total usable
//! beam length l. The paper writes x for the clutch position, which is the same as L.

use core::f64::consts::PI;
use core::fmt;

/// A quantity was asked for outside the range where its formula holds.
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub enum DomainError {
    /// The argument `value` lies outside `[min, max]` for the quantity `what`.
    OutOfRange {
        /// Which quantity was asked for.
        what: &'static str,
        /// The offending argument (SI units).
        value: f64,
        /// Smallest allowed argument (SI units).
        min: f64,
        /// Largest allowed argument (SI units).
        max: f64,
    },
}

impl fmt::Display for DomainError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            DomainError::OutOfRange {
                what,
                value,
                min,
                max,
            } => write!(f, "{what}: argument {value} outside [{min}, {max}]"),
        }
    }
}

impl std::error::Error for DomainError {}

/// Beam geometry and material of one actuator design (`docs/design.md` §2, symbols paragraph).
/// All fields in SI units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Design {
    /// Number of beams n (4 in the paper).
    pub n: u32,
    /// Beam radius r \[m\].
    pub r: f64,
    /// Pitch radius R, gear centre to beam centre \[m\].
    pub pitch_r: f64,
    /// Young's modulus E \[Pa\].
    pub e: f64,
    /// Shear modulus G \[Pa\].
    pub g: f64,
    /// Allowed bending stress σ_allow \[Pa\].
    pub sigma_allow: f64,
    /// Total usable beam length l \[m\].
    pub l: f64,
    /// Clutch plate thickness t_c \[m\].
    pub t_c: f64,
    /// Kinetic friction coefficient μ between beam and clutch slot \[-\].
    pub mu: f64,
}

impl Design {
    /// The reference design, `docs/design.md` §2.2 ("paper preset"): n = 4, r = 0.5 mm,
    /// R = 7.8 mm, E = 200 GPa, G = 80 GPa, σ_allow = 1.5 GPa, l = 8 mm, t_c = 1 mm, μ = 0.4.
    pub fn paper() -> Self {
        Design {
            n: 4,
            r: 0.5e-3,
            pitch_r: 7.8e-3,
            e: 200e9,
            g: 80e9,
            sigma_allow: 1.5e9,
            l: 8e-3,
            t_c: 1e-3,
            mu: 0.4,
        }
    }

    /// Number of beams as `f64`.
    fn nf(&self) -> f64 {
        f64::from(self.n)
    }

    /// Second moment of area of one beam, I = π·r⁴/4 \[m⁴\] (`docs/design.md` §2 table, row "–
    /// second moment of area").
    pub fn second_moment(&self) -> f64 {
        PI * self.r.powi(4) / 4.0
    }

    /// Cross-section area of one beam, A = π·r² \[m²\] (`docs/design.md` §2 table, row 4T).
    pub fn area(&self) -> f64 {
        PI * self.r * self.r
    }

    /// Poisson's ratio from E and G, ν = E/(2G) − 1 \[-\] (`docs/design.md` §2 table, row 4T).
    pub fn poisson(&self) -> f64 {
        self.e / (2.0 * self.g) - 1.0
    }

    /// Timoshenko shear coefficient of a circular section, κ = 6(1+ν)/(7+6ν) \[-\]
    /// (`docs/design.md` §2 table, row 4T).
    pub fn shear_coefficient(&self) -> f64 {
        let nu = self.poisson();
        6.0 * (1.0 + nu) / (7.0 + 6.0 * nu)
    }

    /// Joint stiffness, Euler–Bernoulli: k(L) = n·3·E·I·R²/L³ \[N·m/rad\], L in m
    /// (`docs/design.md` §2 table, row 4; paper eq. 4). L = 0 gives +∞ (rigid).
    pub fn stiffness(&self, l_act: f64) -> f64 {
        self.nf() * 3.0 * self.e * self.second_moment() * self.pitch_r.powi(2) / l_act.powi(3)
    }

    /// Joint stiffness, shear-corrected (Timoshenko):
    /// k_T(L) = n·R² / (L³/(3EI) + L/(κ·G·A)) \[N·m/rad\], L in m (`docs/design.md` §2 table,
    /// row 4T).
    pub fn stiffness_timoshenko(&self, l_act: f64) -> f64 {
        let bending = l_act.powi(3) / (3.0 * self.e * self.second_moment());
        let shear = l_act / (self.shear_coefficient() * self.g * self.area());
        self.nf() * self.pitch_r.powi(2) / (bending + shear)
    }

    /// Joint rotation under output torque τ \[N·m\], θ = τ/k(L) \[rad\], Euler–Bernoulli
    /// (`docs/design.md` §2 table, rows 2,3 and 4).
    pub fn deflection(&self, tau: f64, l_act: f64) -> f64 {
        tau / self.stiffness(l_act)
    }

    /// Tip force on each beam for output torque τ \[N·m\], P = τ/(n·R) \[N\]
    /// (`docs/design.md` §2 table, row "per-beam force, root stress"; paper eq. 2).
    pub fn beam_force(&self, tau: f64) -> f64 {
        tau / (self.nf() * self.pitch_r)
    }

    /// Bending stress at the beam root for output torque τ \[N·m\] at active length L \[m\],
    /// σ = P·L·r/I \[Pa\] (`docs/design.md` §2 table, row "per-beam force, root stress").
    pub fn root_stress(&self, tau: f64, l_act: f64) -> f64 {
        self.beam_force(tau) * l_act * self.r / self.second_moment()
    }

    /// Stress-limited torque capacity, τ_cap(L) = n·R·σ_allow·I/(r·L) \[N·m\]
    /// (`docs/design.md` §2 table, row "stress-limited capacity").
    pub fn torque_capacity(&self, l_act: f64) -> f64 {
        self.nf() * self.pitch_r * self.sigma_allow * self.second_moment() / (self.r * l_act)
    }

    /// Stress-limited deflection capacity, θ_cap(L) = τ_cap(L)/k(L) \[rad\]
    /// (`docs/design.md` §2 table, row "stress-limited capacity").
    pub fn deflection_capacity(&self, l_act: f64) -> f64 {
        self.torque_capacity(l_act) / self.stiffness(l_act)
    }

    /// Inverse of the Euler–Bernoulli stiffness, L(k) = (n·3·E·I·R²/k)^(1/3) \[m\], k in
    /// N·m/rad (`docs/design.md` §2 table, row "– inverse"). Error unless k is finite and > 0.
    pub fn length_for_stiffness(&self, k: f64) -> Result<f64, DomainError> {
        check_stiffness(k)?;
        Ok((self.nf() * 3.0 * self.e * self.second_moment() * self.pitch_r.powi(2) / k).cbrt())
    }

    /// Inverse of the Timoshenko stiffness: the L \[m\] with k_T(L) = k, k in N·m/rad
    /// (`docs/design.md` §2 table, row 4T). k_T is strictly decreasing in L from +∞ to 0, so the
    /// root is unique; it is found by bisection to 1e-15 relative (or until the bracket
    /// cannot shrink further in f64). Error unless k is finite and > 0.
    pub fn length_for_stiffness_timoshenko(&self, k: f64) -> Result<f64, DomainError> {
        check_stiffness(k)?;
        // k_T(L) <= k(L) for every L, so at the E–B length k_T is at most k: an upper bound.
        let mut hi = self.length_for_stiffness(k)?;
        let mut lo = hi;
        while self.stiffness_timoshenko(lo) < k {
            lo *= 0.5;
        }
        // Invariant: k_T(lo) >= k >= k_T(hi).
        for _ in 0..200 {
            if hi - lo <= 1e-15 * hi {
                break;
            }
            let mid = 0.5 * (lo + hi);
            if mid <= lo || mid >= hi {
                break;
            }
            if self.stiffness_timoshenko(mid) >= k {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        Ok(0.5 * (lo + hi))
    }

    /// Largest elastic tip deflection of the full beam, δ_max = σ_allow·l²/(3·E·r) \[m\]
    /// (`docs/design.md` §2 table, row 5, default δ_max).
    pub fn delta_max(&self) -> f64 {
        self.sigma_allow * self.l * self.l / (3.0 * self.e * self.r)
    }

    /// Beam bending capacity (tilt), θ_max = δ_max/l \[rad\] (`docs/design.md` §2 table, row 5;
    /// paper eq. 5, linearised).
    pub fn theta_max(&self) -> f64 {
        self.delta_max() / self.l
    }

    /// Slot clearance, c = θ_max·t_c \[m\] (`docs/design.md` §2 table, row 6; paper eq. 6).
    pub fn slot_clearance(&self) -> f64 {
        self.theta_max() * self.t_c
    }

    /// Slot radius, r_slot = r + c \[m\], r the beam radius (`docs/design.md` §2 table, row 6;
    /// the paper's "R_c = R + θ_max t_c" with R meaning the beam radius).
    pub fn slot_radius(&self) -> f64 {
        self.r + self.slot_clearance()
    }

    /// Backlash from beam tilt at clutch position x \[m\], θ_b = θ_max·t_c/x \[rad\], defined
    /// for t_c ≤ x ≤ l (`docs/design.md` §2 table, row 7; paper eq. 7). Outside: domain error.
    pub fn backlash_tilt(&self, x: f64) -> Result<f64, DomainError> {
        // Written as a negated "inside" test so that NaN is rejected too.
        if !(x >= self.t_c && x <= self.l) {
            return Err(DomainError::OutOfRange {
                what: "beam-tilt backlash: clutch position x",
                value: x,
                min: self.t_c,
                max: self.l,
            });
        }
        Ok(self.theta_max() * self.t_c / x)
    }

    /// Output free play, φ_b = c/R \[rad\]: the output rotation before the slot touches the
    /// beam (`docs/design.md` §2 table, row "output free play").
    pub fn free_play(&self) -> f64 {
        self.slot_clearance() / self.pitch_r
    }

    /// Loading branch of the friction hysteresis, τ = k·φ·(1 + (6/5)·μ·δ/L) with δ = R·φ
    /// \[N·m\], φ in rad, L in m (`docs/design.md` §2 table, row "friction hysteresis", and §2.1).
    /// "Loading" means |φ| growing. For φ < 0 the branch is mirrored (δ enters by its
    /// magnitude, friction opposes the motion), so the torque is odd in φ.
    pub fn torque_loading(&self, phi: f64, l_act: f64) -> f64 {
        self.stiffness(l_act) * phi * (1.0 + self.friction_factor(phi, l_act))
    }

    /// Unloading branch of the friction hysteresis, τ = k·φ·(1 − (6/5)·μ·δ/L) with δ = R·φ
    /// \[N·m\] (`docs/design.md` §2 table, row "friction hysteresis", and §2.1). "Unloading" means
    /// |φ| shrinking; mirrored for φ < 0 as in [`Design::torque_loading`].
    pub fn torque_unloading(&self, phi: f64, l_act: f64) -> f64 {
        self.stiffness(l_act) * phi * (1.0 - self.friction_factor(phi, l_act))
    }

    /// (6/5)·μ·|δ|/L with δ = R·φ \[-\] (`docs/design.md` §2.1).
    fn friction_factor(&self, phi: f64, l_act: f64) -> f64 {
        1.2 * self.mu * (self.pitch_r * phi).abs() / l_act
    }

    /// Energy dissipated by one full loop 0 → φ_max → 0 \[J\]: ∫₀^φmax (τ_load − τ_unload) dφ
    /// = k·(12/5)·μ·R·φ_max³/(3·L), the closed form of the §2.1 branches (`docs/design.md` §2.1).
    pub fn hysteresis_loop_energy(&self, phi_max: f64, l_act: f64) -> f64 {
        let phi = phi_max.abs();
        self.stiffness(l_act) * 2.4 * self.mu * self.pitch_r * phi.powi(3) / (3.0 * l_act)
    }

    /// The friction hysteresis as an equivalent viscous damper between gear and link
    /// \[N·m·s/rad\], for a deflection (beyond the free play) φ₀ + Δ·sin(ωt) that stays on
    /// one side (|φ₀| ≥ Δ): the describing function's b = W/(π·ω·Δ²), where
    /// W = ∫ (τ_load − τ_unload) dφ over φ₀ − Δ … φ₀ + Δ is the energy one cycle dissipates
    /// between the two branches (the difference of two [`Design::hysteresis_loop_energy`]
    /// integrals from 0) and π·ω·b·Δ² a damper's.
    pub fn hysteresis_damping(&self, phi0: f64, delta: f64, omega: f64, l_act: f64) -> f64 {
        let (phi0, delta) = (phi0.abs(), delta.abs());
        if delta == 0.0 || omega == 0.0 {
            return 0.0;
        }
        let w = self.hysteresis_loop_energy(phi0 + delta, l_act)
            - self.hysteresis_loop_energy(phi0 - delta, l_act);
        w / (PI * omega * delta * delta)
    }

    /// Elastic coupling torque with the output free play as a dead zone \[N·m\]: 0 for
    /// |φ| ≤ φ_b, k(L)·(|φ| − φ_b)·sign(φ) beyond (`docs/design.md` §2 table, row "output free
    /// play").
    pub fn coupling_torque(&self, phi: f64, l_act: f64) -> f64 {
        let phi_b = self.free_play();
        if phi.abs() <= phi_b {
            0.0
        } else {
            self.stiffness(l_act) * (phi.abs() - phi_b) * phi.signum()
        }
    }
}

/// Stiffness arguments of the inverses must be finite and positive.
fn check_stiffness(k: f64) -> Result<(), DomainError> {
    if k.is_finite() && k > 0.0 {
        Ok(())
    } else {
        Err(DomainError::OutOfRange {
            what: "inverse stiffness: k",
            value: k,
            min: f64::MIN_POSITIVE,
            max: f64::MAX,
        })
    }
}

/// Natural frequency of the link on the coupling, ω_n = √(k/J) \[rad/s\], k in N·m/rad,
/// J in kg·m² (`docs/design.md` §2 table, row "natural frequency").
pub fn natural_frequency(k: f64, j: f64) -> f64 {
    (k / j).sqrt()
}

/// Stiffness that puts the natural frequency at ω: k = J·ω² \[N·m/rad\], J in kg·m², ω in
/// rad/s (`docs/design.md` §2 table, row "natural frequency", energy-optimal setting).
pub fn stiffness_for_frequency(j: f64, omega: f64) -> f64 {
    j * omega * omega
}

/// Direction of motion of the output deflection φ.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Direction {
    /// φ increasing.
    Increasing,
    /// φ decreasing.
    Decreasing,
}

/// Follows a sequence of deflections φ and returns the friction-hysteresis torque, picking
/// the branch from the direction of motion (`docs/design.md` §2.1: "A reversal switches branch
/// (keep the direction as state)").
///
/// Loading (|φ| growing, i.e. moving away from 0) uses [`Design::torque_loading`], unloading
/// uses [`Design::torque_unloading`]. Equivalently τ = k·φ + sign(φ̇)·k·(6/5)·μ·R·φ²/L. A
/// step with no change keeps the last direction; before the first motion the torque is the
/// elastic k·φ.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HysteresisFollower {
    design: Design,
    l_act: f64,
    last_phi: Option<f64>,
    direction: Option<Direction>,
}

impl HysteresisFollower {
    /// A follower at active length `l_act` \[m\], with no history.
    pub fn new(design: Design, l_act: f64) -> Self {
        HysteresisFollower {
            design,
            l_act,
            last_phi: None,
            direction: None,
        }
    }

    /// The current direction of motion (None before the first motion).
    pub fn direction(&self) -> Option<Direction> {
        self.direction
    }

    /// Moves to deflection `phi` \[rad\] and returns the torque \[N·m\].
    pub fn step(&mut self, phi: f64) -> f64 {
        if let Some(last) = self.last_phi {
            if phi > last {
                self.direction = Some(Direction::Increasing);
            } else if phi < last {
                self.direction = Some(Direction::Decreasing);
            }
        }
        self.last_phi = Some(phi);
        let d = &self.design;
        match self.direction {
            None => d.stiffness(self.l_act) * phi,
            Some(dir) => {
                let moving_away = match dir {
                    Direction::Increasing => phi >= 0.0,
                    Direction::Decreasing => phi <= 0.0,
                };
                if moving_away {
                    d.torque_loading(phi, self.l_act)
                } else {
                    d.torque_unloading(phi, self.l_act)
                }
            }
        }
    }
}

// ---------------------------------------------------------------------------------------
// Sizing against goals (docs/design.md §10) and the linear two-mass actuator model, for the
// designer's tools (`vsa explore`, `vsa advise`).

impl Design {
    /// Stress-limited deflection in closed form, θ_cap = σ_allow·L²/(3·E·r·R) \[rad\]
    /// (`docs/design.md` §10; independent of n). Equal to [`Design::deflection_capacity`].
    pub fn deflection_capacity_closed_form(&self, l_act: f64) -> f64 {
        self.sigma_allow * l_act * l_act / (3.0 * self.e * self.r * self.pitch_r)
    }

    /// Elastic energy stored at the stress limit, n·σ_allow²·π·r²·L/(24·E) \[J\]
    /// (`docs/design.md` §10: ½·τ_cap·θ_cap, ∝ σ²/E × active volume).
    pub fn energy_at_capacity(&self, l_act: f64) -> f64 {
        self.nf() * self.sigma_allow.powi(2) * PI * self.r * self.r * l_act / (24.0 * self.e)
    }

    /// Mass of the n beams of whole length `l_total` \[m\] at density `rho` \[kg/m³\],
    /// n·π·r²·l_total·ρ \[kg\].
    pub fn beam_mass(&self, l_total: f64, rho: f64) -> f64 {
        self.nf() * PI * self.r * self.r * l_total * rho
    }

    /// Volume of the cylinder the beam ring and its slots sweep, π·(R + r_slot)²·l_total
    /// \[m³\].
    pub fn envelope_volume(&self, l_total: f64) -> f64 {
        let outer = self.pitch_r + self.slot_radius();
        PI * outer * outer * l_total
    }

    /// The clutch slots fit: R > r_slot and, for n ≥ 2, neighbouring slots do not overlap,
    /// 2·R·sin(π/n) ≥ 2·r_slot.
    pub fn slots_fit(&self) -> bool {
        let rs = self.slot_radius();
        self.pitch_r > rs && (self.n < 2 || self.pitch_r * (PI / self.nf()).sin() >= rs)
    }
}

/// The shortest active length with which any number of beams of a material (E, σ_allow)
/// can give capacity `torque` and safe deflection `theta` at once, whatever r and R
/// (beams packed around the axis, n → ∞):
/// τ_cap ≥ T needs n·r²·L ≥ 12·T·E·θ/(π·σ²) (with the largest R that θ_cap ≥ θ allows),
/// and beams side by side need n·r² ≤ π·σ·L²/(3·E·θ), so L³ ≥ 36·T·E²·θ²/(π²·σ³) \[m\].
pub fn min_active_length(torque: f64, theta: f64, e: f64, sigma_allow: f64) -> f64 {
    (36.0 * torque * e * e * theta * theta / (PI * PI * sigma_allow.powi(3))).cbrt()
}

/// The actuator as a linear two-mass system: gear (motor and gearbox at the output) J_g
/// with viscous friction b_g, driven by the motor torque k_t·i; beams k with a damper b_c
/// in parallel (the beams' friction hysteresis, linearised by
/// [`Design::hysteresis_damping`], or 0); link J_l with viscous friction b_l and a constant
/// load; i = (V − k_e·ω_g)/R (no inductance, `docs/design.md` §3).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TwoMass {
    /// Gear-side inertia at the output \[kg·m²\].
    pub j_gear: f64,
    /// Link inertia \[kg·m²\].
    pub j_link: f64,
    /// Coupling stiffness \[N·m/rad\].
    pub k: f64,
    /// Coupling damping in parallel with the beams \[N·m·s/rad\].
    pub b_coupling: f64,
    /// Gear viscous friction \[N·m·s/rad\].
    pub b_gear: f64,
    /// Link viscous friction \[N·m·s/rad\].
    pub b_link: f64,
    /// Armature resistance \[Ω\].
    pub resistance: f64,
    /// Torque constant at the output \[N·m/A\].
    pub k_t: f64,
    /// Back-EMF constant at the output \[V·s/rad\].
    pub k_e: f64,
    /// Constant load on the link \[N·m\].
    pub load: f64,
}

impl TwoMass {
    /// The free coupling mode (motor torque zero): ω = √(k·(1/J_g + 1/J_l)) \[rad/s\].
    pub fn natural_frequency(&self) -> f64 {
        (self.k * (1.0 / self.j_gear + 1.0 / self.j_link)).sqrt()
    }

    /// Gear amplitude over link amplitude and the motor torque amplitude \[N·m\] when the
    /// link follows A·sin(ωt) exactly (complex amplitudes, the link's as the reference):
    /// (k + jω·b_c)·(Θ_g − Θ_l) = (−J_l·ω² + jω·b_l)·Θ_l,
    /// T_m = (−J_g·ω² + jω·b_g)·Θ_g + (k + jω·b_c)·(Θ_g − Θ_l).
    fn phasors(&self, amplitude: f64, omega: f64) -> ((f64, f64), (f64, f64)) {
        // (k + jω·b_c)·(Θ_g − Θ_l)/Θ_l
        let spring = (-self.j_link * omega * omega, omega * self.b_link);
        // (Θ_g − Θ_l)/Θ_l = spring/(k + jω·b_c)
        let (cr, ci) = (self.k, omega * self.b_coupling);
        let den = cr * cr + ci * ci;
        let rel = (
            (spring.0 * cr + spring.1 * ci) / den,
            (spring.1 * cr - spring.0 * ci) / den,
        );
        let theta_g = (amplitude * (1.0 + rel.0), amplitude * rel.1);
        let gear = (-self.j_gear * omega * omega, omega * self.b_gear);
        let torque = (
            gear.0 * theta_g.0 - gear.1 * theta_g.1 + amplitude * spring.0,
            gear.0 * theta_g.1 + gear.1 * theta_g.0 + amplitude * spring.1,
        );
        (theta_g, torque)
    }

    /// Electrical energy per cycle ∮V·i dt \[J\] when the link follows A·sin(ωt):
    /// R·(i₀² + |I|²/2)·T + k_e·Re(jω·Θ_g·conj(I))/2·T, i₀ = load/k_t the holding current.
    pub fn energy_per_cycle(&self, amplitude: f64, omega: f64) -> f64 {
        let (theta_g, torque) = self.phasors(amplitude, omega);
        let period = 2.0 * PI / omega;
        let i = (torque.0 / self.k_t, torque.1 / self.k_t);
        let i0 = self.load / self.k_t;
        let copper = self.resistance * (i0 * i0 + (i.0 * i.0 + i.1 * i.1) / 2.0) * period;
        // jω·Θ_g = (−ω·Θ_g.im, ω·Θ_g.re); Re(a·conj(b)) = a.re·b.re + a.im·b.im.
        let emf = self.k_e * (-omega * theta_g.1 * i.0 + omega * theta_g.0 * i.1) / 2.0 * period;
        copper + emf
    }

    /// Gear amplitude \[rad\] when the link follows A·sin(ωt).
    pub fn gear_amplitude(&self, amplitude: f64, omega: f64) -> f64 {
        let (g, _) = self.phasors(amplitude, omega);
        g.0.hypot(g.1)
    }

    /// Amplitude of the beams' deflection Θ_g − Θ_l \[rad\] when the link follows
    /// A·sin(ωt).
    pub fn deflection_amplitude(&self, amplitude: f64, omega: f64) -> f64 {
        let (g, _) = self.phasors(amplitude, omega);
        (g.0 - amplitude).hypot(g.1)
    }
}
