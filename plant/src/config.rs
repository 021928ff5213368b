//! Configuration of the simulated actuator: plain `f32` parameters in SI units.
//!
//! The coupling parameters (stiffness, free play, hysteresis coefficient, stress per
//! torque) are **derived by the caller** from the beam model (the `model` crate, `docs/design.md`
//! §2) for the chosen geometry and clutch length; this crate does not compute them. The
//! defaults are the paper preset (`docs/design.md` §2.2) at L = 3 mm, for convenience.

/// Full-scale PWM duty in permille: `step_tick(±DUTY_FULL_SCALE)` applies ±supply voltage.
pub const DUTY_FULL_SCALE: i16 = 1000;

/// Control period simulated by one [`crate::Plant::step_tick`]: 1 ms (1 kHz loop).
pub const TICK_S: f32 = 1.0e-3;

/// Upper bound of the number of integration substeps per tick (after adaptation to k).
pub const MAX_SUBSTEPS: u16 = 400;

/// DC motor, gearbox and H-bridge, all referred to the **output** of the 254:1 gearbox
/// (gear efficiency folded into the constants, `docs/design.md` §3).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MotorConfig {
    /// H-bridge supply voltage, V. Default 12 V.
    pub supply_voltage_v: f32,
    /// Armature resistance, Ω. Default 8 Ω.
    pub resistance_ohm: f32,
    /// Torque constant at the output, N·m/A. Default 1.0.
    pub torque_constant_nm_per_a: f32,
    /// Back-EMF constant at the output, V·s/rad. Default 1.94 (no-load speed 12/1.94 =
    /// 6.19 rad/s = 59 rpm).
    pub back_emf_v_s_per_rad: f32,
    /// Rotor + gear train inertia reflected at the output, kg·m². Default 3.2e-3.
    pub inertia_kg_m2: f32,
    /// Viscous friction of the gear train at the output, N·m·s/rad. Default 1e-3 (0.4 % of
    /// the back-EMF damping k_t·k_e/R = 0.2425).
    pub viscous_nm_s_per_rad: f32,
    /// Coulomb (dry) friction of the gear train at the output, N·m; also the breakaway
    /// (stiction) level. Default 0.01 N·m (0.7 % of the stall torque).
    pub coulomb_nm: f32,
    /// Wiring of the motor leads to the bridge: +1, or −1 when swapped (a positive duty
    /// then turns the gear negative; the bridge's current sense reads the bridge current,
    /// −1 × the motor's). Default +1.
    pub polarity: f32,
}

impl Default for MotorConfig {
    fn default() -> Self {
        Self {
            supply_voltage_v: 12.0,
            resistance_ohm: 8.0,
            torque_constant_nm_per_a: 1.0,
            back_emf_v_s_per_rad: 1.94,
            inertia_kg_m2: 3.2e-3,
            viscous_nm_s_per_rad: 1.0e-3,
            coulomb_nm: 0.01,
            polarity: 1.0,
        }
    }
}

/// The four-beam elastic coupling between output gear and output shaft (link).
///
/// Torque on the link as a function of the deflection φ = θ_gear − θ_link:
/// effective deflection φ_e = sign(φ)·max(|φ| − φ_b, 0) (free-play dead zone), then the
/// hysteresis band of `docs/design.md` §2.1, τ = k·φ_e·(1 ± c·|φ_e|) with c = (6/5)·μ·R/L
/// (because δ = R·φ_e), `+` while loading, `−` while unloading. See [`crate::Coupling`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CouplingConfig {
    /// Joint stiffness k, N·m/rad (Euler–Bernoulli or Timoshenko, caller's choice). Default
    /// 265.5 (paper preset, L = 3 mm). 0 disconnects gear and link.
    pub stiffness_nm_per_rad: f32,
    /// Output free play φ_b (half-width of the dead zone), rad. Default 5.128e-3
    /// (c = θ_max·t_c = 0.04 mm, φ_b = c/R with R = 7.8 mm).
    pub free_play_rad: f32,
    /// Hysteresis coefficient c = (6/5)·μ·R/L, 1/rad. Default 1.248 (μ = 0.4, R = 7.8 mm,
    /// L = 3 mm). 0 disables hysteresis (pure spring with dead zone).
    pub hysteresis_per_rad: f32,
    /// Slope of the torque between the two branches after a reversal, as a multiple of k
    /// (the contact sticks until the torque reaches the other branch). Large values
    /// approach an instantaneous branch switch; it must stay ≥ 1 and it raises the
    /// substep count (see [`PlantConfig::effective_substeps`]). Default 10.
    pub stick_stiffness_ratio: f32,
    /// Beam root stress per N·m of joint torque, Pa/(N·m): σ = τ·L·r/(n·R·I). Default
    /// 9.794e8 (paper preset, L = 3 mm: 1959 MPa at 2 N·m).
    pub stress_per_torque_pa_per_nm: f32,
}

impl Default for CouplingConfig {
    fn default() -> Self {
        Self {
            stiffness_nm_per_rad: 265.5,
            free_play_rad: 5.128e-3,
            hysteresis_per_rad: 1.248,
            stick_stiffness_ratio: 10.0,
            stress_per_torque_pa_per_nm: 9.794e8,
        }
    }
}

impl CouplingConfig {
    /// A linear spring of stiffness `k` (N·m/rad): no free play, no hysteresis.
    pub fn linear(k_nm_per_rad: f32) -> Self {
        Self {
            stiffness_nm_per_rad: k_nm_per_rad,
            free_play_rad: 0.0,
            hysteresis_per_rad: 0.0,
            ..Self::default()
        }
    }
}

/// The output shaft (link) and what it carries.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LinkConfig {
    /// Link inertia about the output axis, kg·m². Default 1e-3 (100 g at 10 cm).
    pub inertia_kg_m2: f32,
    /// Viscous friction of the output bearing, N·m·s/rad. Default 2e-4.
    pub viscous_nm_s_per_rad: f32,
    /// Coulomb (dry) friction of the output bearing, N·m. Default 0.
    pub coulomb_nm: f32,
}

impl Default for LinkConfig {
    fn default() -> Self {
        Self {
            inertia_kg_m2: 1.0e-3,
            viscous_nm_s_per_rad: 2.0e-4,
            coulomb_nm: 0.0,
        }
    }
}

/// One step of a piecewise-constant external torque profile.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ProfileStep {
    /// First tick (counted from the plant's construction or last reset) at which the step
    /// applies.
    pub from_tick: u32,
    /// Torque on the link from that tick on, N·m.
    pub torque_nm: f32,
}

/// Capacity of a [`TorqueProfile`].
pub const PROFILE_STEPS: usize = 8;

/// Piecewise-constant external torque versus time, in a fixed-size array (no allocation,
/// no closures). Before the first step (or with `len == 0`) the torque is 0. Steps must be
/// sorted by `from_tick`; the last step whose `from_tick` ≤ the current tick applies.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TorqueProfile {
    /// The steps; only the first `len` are used.
    pub steps: [ProfileStep; PROFILE_STEPS],
    /// Number of valid steps (values above [`PROFILE_STEPS`] are treated as
    /// [`PROFILE_STEPS`]).
    pub len: u8,
}

impl TorqueProfile {
    /// Torque of the profile at `tick`, N·m.
    pub fn torque_at(&self, tick: u32) -> f32 {
        let mut torque = 0.0;
        for step in self.steps.iter().take(usize::from(self.len)) {
            if step.from_tick <= tick {
                torque = step.torque_nm;
            }
        }
        torque
    }
}

/// External load on the link. All terms add up; the default is no load.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LoadConfig {
    /// Constant torque on the link, N·m.
    pub constant_nm: f32,
    /// Gravity arm m·g·d, N·m (0 = no gravity). The gravity torque on the link is
    /// −m·g·d·sin(θ_link − θ_down): a pendulum hanging at `gravity_down_rad`.
    pub gravity_mgd_nm: f32,
    /// Link angle at which the gravity arm hangs straight down, rad.
    pub gravity_down_rad: f32,
    /// Piecewise-constant torque profile versus tick, N·m.
    pub profile: TorqueProfile,
}

/// Sensors as the control board sees them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SensorConfig {
    /// Potentiometer count at gear angle 0 (the pot reads 0..=1023 over 300°). Default 512.
    pub pot_center_counts: f32,
    /// Magnetic encoder count at link angle 0 (mounting offset), 0..=4095. Default 0.
    pub encoder_zero_counts: u16,
    /// Current-sense offset error, ADC counts (added to the mid-scale 2048). Default 0.
    pub current_offset_counts: f32,
    /// Current-sense gain error: the ADC reads `current_gain`·i (1024 counts/A nominal).
    /// Default 1.
    pub current_gain: f32,
    /// Standard deviation of the current-sense noise, ADC counts (approximately Gaussian,
    /// sum of four uniforms). Default 0 (noise off).
    pub current_noise_counts: f32,
    /// Seed of the xorshift32 noise generator (0 is replaced by a fixed non-zero value).
    pub noise_seed: u32,
    /// Link encoder counts per turn, 16..=16384 (an AS5047P's incremental output gives
    /// 4 000 at its factory 1 000 pulses per revolution). Default 4096.
    pub encoder_counts_per_turn: u16,
    /// Link encoder counting direction: +1, or −1 when it counts down as the link turns
    /// positive (magnet or chip mounted the other way, A/B swapped). Default +1.
    pub encoder_direction: f32,
    /// Pot direction: +1, or −1 when its end terminals are wired the other way. Default +1.
    pub pot_direction: f32,
    /// Pot gain error (reading = gain · the nominal 1024/300° slope). Default 1.
    pub pot_gain: f32,
    /// Amplitude of the pot's integral non-linearity, counts: A·sin(2π·c/1024) is added
    /// at ideal count c (a smooth bow over the track). Default 0.
    pub pot_nonlinearity_counts: f32,
    /// Standard deviation of the pot noise, counts (same generator as the current noise,
    /// drawn after it; no draw when 0). Default 0.
    pub pot_noise_counts: f32,
    /// Supply sense gain error: the ADC reads `supply_sense_gain`·V_s (5 mV a count
    /// nominal; the divider's resistors and the ADC reference). Default 1.
    pub supply_sense_gain: f32,
}

impl Default for SensorConfig {
    fn default() -> Self {
        Self {
            pot_center_counts: 512.0,
            encoder_zero_counts: 0,
            current_offset_counts: 0.0,
            current_gain: 1.0,
            current_noise_counts: 0.0,
            noise_seed: 0x2545_F491,
            encoder_counts_per_turn: model::sensors::ENCODER_COUNTS,
            encoder_direction: 1.0,
            pot_direction: 1.0,
            pot_gain: 1.0,
            pot_nonlinearity_counts: 0.0,
            pot_noise_counts: 0.0,
            supply_sense_gain: 1.0,
        }
    }
}

/// Complete configuration of the simulated actuator.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PlantConfig {
    /// Motor, gearbox and H-bridge.
    pub motor: MotorConfig,
    /// Beam coupling between gear and link.
    pub coupling: CouplingConfig,
    /// Link inertia and bearing friction.
    pub link: LinkConfig,
    /// External load on the link.
    pub load: LoadConfig,
    /// Sensors.
    pub sensors: SensorConfig,
    /// Requested integration substeps per 1 ms tick; 0 means the default of 20. The plant
    /// raises it if the coupling needs more for stability
    /// ([`PlantConfig::effective_substeps`]).
    pub substeps: u16,
    /// Hold the output gear fixed (test fixture; the motor sees a stall).
    pub gear_locked: bool,
    /// Hold the link fixed (test fixture, e.g. a stiffness identification load test).
    pub link_locked: bool,
    /// Clutch length the coupling was derived for, m (0: not known). An override of it
    /// (`clutch`) makes [`crate::harness::plant_for`] derive the coupling again at the
    /// new length: the clutch as it actually is, whatever the controller was told.
    pub clutch_length_m: f32,
    /// Link (and gear) angle at power-up, rad. The link encoder is incremental: it reads
    /// `encoder_zero_counts` at power-up wherever the link is. Default 0.
    pub power_up_angle_rad: f32,
}

/// Default number of substeps per tick (50 µs at 1 kHz).
pub const DEFAULT_SUBSTEPS: u16 = 20;

/// Largest ω·dt allowed for the coupling mode at stiffness k (accuracy: the Störmer–Verlet
/// frequency error is ≈ (ω·dt)²/24 = 0.4 %, the energy ripple ≈ (ω·dt)²/4).
pub const MAX_OMEGA_DT: f32 = 0.3;

/// Largest ω·dt allowed for the stiffer stick transition of the hysteresis (stability only:
/// Störmer–Verlet is stable below 2).
pub const MAX_OMEGA_DT_STICK: f32 = 1.0;

impl PlantConfig {
    /// Substeps per tick actually used: `max(substeps (or 20), n_min)`, at most
    /// [`MAX_SUBSTEPS`], where n_min keeps ω·dt ≤ [`MAX_OMEGA_DT`] for the coupling mode
    /// ω² = k·(1/J_gear + 1/J_link) (a locked side drops its term) and ω·dt ≤
    /// [`MAX_OMEGA_DT_STICK`] for the stick slope (`stick_stiffness_ratio`·k) when
    /// hysteresis is on. Computed once at configuration time (uses a square root).
    pub fn effective_substeps(&self) -> u16 {
        let requested = if self.substeps == 0 {
            DEFAULT_SUBSTEPS
        } else {
            self.substeps
        };
        let mut inv_j = 0.0;
        if !self.gear_locked && self.motor.inertia_kg_m2 > 0.0 {
            inv_j += 1.0 / self.motor.inertia_kg_m2;
        }
        if !self.link_locked && self.link.inertia_kg_m2 > 0.0 {
            inv_j += 1.0 / self.link.inertia_kg_m2;
        }
        let k = self.coupling.stiffness_nm_per_rad;
        let mut needed = 1.0f32;
        if k > 0.0 && inv_j > 0.0 {
            let omega = libm::sqrtf(k * inv_j);
            needed = omega * TICK_S / MAX_OMEGA_DT;
            if self.coupling.hysteresis_per_rad > 0.0 && self.coupling.stick_stiffness_ratio > 1.0 {
                let omega_s = libm::sqrtf(self.coupling.stick_stiffness_ratio * k * inv_j);
                let n_s = omega_s * TICK_S / MAX_OMEGA_DT_STICK;
                if n_s > needed {
                    needed = n_s;
                }
            }
        }
        // `as` saturates (NaN → 0), so this cannot panic or wrap.
        let needed = libm::ceilf(needed) as u32;
        let n = if u32::from(requested) > needed {
            u32::from(requested)
        } else {
            needed
        };
        n.clamp(1, u32::from(MAX_SUBSTEPS)) as u16
    }
}
