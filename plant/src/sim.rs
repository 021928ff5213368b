//! The simulated actuator: motor + gear, beam coupling, link + load, sensors.

use crate::config::{CouplingConfig, PlantConfig, DUTY_FULL_SCALE, TICK_S};
use crate::coupling::{Branch, Coupling};
use crate::sensors::{
    adc_counts, encoder_counts, pot_counts, supply_counts, SensorFaults, SensorReadings, XorShift32,
};

/// What the H-bridge does during one tick.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BridgeCommand {
    /// Drive with a signed duty in permille, saturated to ±[`DUTY_FULL_SCALE`]: the motor
    /// sees the average voltage duty/1000 · V_supply (synchronous rectification, so the
    /// current may reverse and regenerate).
    Drive(i16),
    /// All switches open: no current, unless the back-EMF exceeds the supply and the
    /// freewheel diodes conduct.
    Coast,
    /// Terminals shorted (V = 0): dynamic braking, i = −k_e·ω/R.
    Brake,
}

/// The true internal state, for tests and plots (not visible to the firmware).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrueState {
    /// Completed ticks since construction (wraps after 2³² ticks, 49.7 days).
    pub tick: u32,
    /// Output-gear angle θ_gear, rad (f64 so that slow motion is not lost at large angles).
    pub gear_angle_rad: f64,
    /// Output-gear velocity, rad/s.
    pub gear_velocity_rad_s: f32,
    /// Link (output shaft) angle θ_link, rad, not wrapped.
    pub link_angle_rad: f64,
    /// Link velocity, rad/s.
    pub link_velocity_rad_s: f32,
    /// Deflection φ = θ_gear − θ_link, rad (integrated on its own for precision).
    pub deflection_rad: f32,
    /// Deflection beyond the free play, φ_e, rad.
    pub effective_deflection_rad: f32,
    /// Coupling (spring) torque on the link, N·m.
    pub spring_torque_nm: f32,
    /// Hysteresis branch of the coupling.
    pub branch: Branch,
    /// Motor current, A (positive drives the gear positive).
    pub motor_current_a: f32,
    /// Motor torque at the output, N·m.
    pub motor_torque_nm: f32,
    /// External load torque on the link (constant + gravity + profile + external), N·m.
    pub load_torque_nm: f32,
    /// Beam root bending stress, Pa, signed like the torque (σ = τ·stress-per-torque).
    pub beam_stress_pa: f32,
}

/// Mechanical energy, J.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Energy {
    /// ½·J_gear·ω_gear² + ½·J_link·ω_link².
    pub kinetic_j: f32,
    /// ½·k·φ_e² (the conservative part of the coupling).
    pub elastic_j: f32,
    /// Gravity potential m·g·d·(1 − cos(θ_link − θ_down)).
    pub gravity_j: f32,
}

impl Energy {
    /// Sum of the three terms, J.
    pub fn total_j(&self) -> f32 {
        self.kinetic_j + self.elastic_j + self.gravity_j
    }
}

/// Velocity-update constants for one kick of length h.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Kick {
    /// h / J_gear
    gain_g: f32,
    /// h · τ_coulomb / J_gear (largest velocity change dry friction can remove)
    fric_g: f32,
    /// h / J_link
    gain_l: f32,
    /// h · τ_coulomb_link / J_link (0: no dry friction on the link)
    fric_l: f32,
}

/// Derived constants, recomputed when the configuration changes (divisions live here).
#[derive(Clone, Copy, Debug, PartialEq)]
struct Derived {
    substeps: u16,
    dt: f32,
    full: Kick,
    half: Kick,
    inv_r: f32,
    volts_per_permille: f32,
}

/// Velocity change per N·m and the Coulomb friction's velocity change over a time `h`, for
/// one inertia `j` (both zero when `j` ≤ 0).
fn side_kick(h: f32, j: f32, coulomb_nm: f32) -> (f32, f32) {
    if j > 0.0 {
        let cf = if coulomb_nm > 0.0 { coulomb_nm } else { 0.0 };
        (h / j, h * cf / j)
    } else {
        (0.0, 0.0)
    }
}

fn kick(h: f32, cfg: &PlantConfig) -> Kick {
    let (gain_g, fric_g) = side_kick(h, cfg.motor.inertia_kg_m2, cfg.motor.coulomb_nm);
    let (gain_l, fric_l) = side_kick(h, cfg.link.inertia_kg_m2, cfg.link.coulomb_nm);
    Kick {
        gain_g,
        fric_g,
        gain_l,
        fric_l,
    }
}

fn derive(cfg: &PlantConfig) -> Derived {
    let substeps = cfg.effective_substeps();
    let dt = TICK_S / f32::from(substeps);
    Derived {
        substeps,
        dt,
        full: kick(dt, cfg),
        half: kick(0.5 * dt, cfg),
        inv_r: if cfg.motor.resistance_ohm > 0.0 {
            1.0 / cfg.motor.resistance_ohm
        } else {
            0.0
        },
        volts_per_permille: cfg.motor.supply_voltage_v / f32::from(DUTY_FULL_SCALE),
    }
}

/// Apply dry friction as a velocity projection: remove up to `f` of speed, never reverse.
/// This is the implicit (stick-capable) treatment of Coulomb friction: a body at rest stays
/// at rest while the other torques stay below the friction level.
#[inline]
fn dry_friction(w: f32, f: f32) -> f32 {
    if w > f {
        w - f
    } else if w < -f {
        w + f
    } else {
        0.0
    }
}

/// sin(base + x) from sin(base), cos(base) and short series of x (basic operations only);
/// libm for |x| > 0.1 rad.
#[inline]
fn sin_shifted(sin0: f32, cos0: f32, base: f32, x: f32) -> f32 {
    if !(-0.1..=0.1).contains(&x) {
        return libm::sinf(base + x);
    }
    let x2 = x * x;
    let c = 1.0 - x2 * (0.5 - x2 * (1.0 / 24.0));
    let s = x * (1.0 - x2 * (1.0 / 6.0 - x2 * (1.0 / 120.0)));
    sin0 * c + cos0 * s
}

/// The simulated actuator. See the crate documentation for the model and the integrator.
#[derive(Clone, Debug, PartialEq)]
pub struct Plant {
    cfg: PlantConfig,
    d: Derived,
    // --- state ---
    theta_g: f64,
    theta_l: f64,
    phi: f32,
    omega_g: f32,
    omega_l: f32,
    coupling: Coupling,
    gravity_nm: f32,
    command: BridgeCommand,
    current_a: f32,
    external_nm: f32,
    tick: u32,
    spring_work_j: f64,
    rng: XorShift32,
    readings: SensorReadings,
    faults: SensorFaults,
}

impl Plant {
    /// A plant at rest at θ_gear = θ_link = the power-up angle (0 by default), bridge
    /// coasting; the sensors are sampled once.
    pub fn new(cfg: PlantConfig) -> Self {
        let mut p = Self {
            cfg,
            d: derive(&cfg),
            theta_g: 0.0,
            theta_l: 0.0,
            phi: 0.0,
            omega_g: 0.0,
            omega_l: 0.0,
            coupling: Coupling::new(&cfg.coupling),
            gravity_nm: 0.0,
            command: BridgeCommand::Coast,
            current_a: 0.0,
            external_nm: 0.0,
            tick: 0,
            spring_work_j: 0.0,
            rng: XorShift32::new(cfg.sensors.noise_seed),
            readings: SensorReadings::default(),
            faults: SensorFaults::default(),
        };
        let a = f64::from(cfg.power_up_angle_rad);
        p.set_state(a, 0.0, a, 0.0);
        p
    }

    /// The configuration.
    pub fn config(&self) -> &PlantConfig {
        &self.cfg
    }

    /// Substeps per tick in use (see [`PlantConfig::effective_substeps`]).
    pub fn substeps(&self) -> u16 {
        self.d.substeps
    }

    /// Put the mechanism in a given state: angles in rad, velocities in rad/s. The coupling
    /// history is reset (torque at the elastic value k·φ_e); locked sides keep velocity 0.
    /// The sensors are sampled again.
    pub fn set_state(
        &mut self,
        gear_angle_rad: f64,
        gear_velocity_rad_s: f32,
        link_angle_rad: f64,
        link_velocity_rad_s: f32,
    ) {
        self.theta_g = gear_angle_rad;
        self.theta_l = link_angle_rad;
        self.phi = (gear_angle_rad - link_angle_rad) as f32;
        self.omega_g = if self.cfg.gear_locked {
            0.0
        } else {
            gear_velocity_rad_s
        };
        self.omega_l = if self.cfg.link_locked {
            0.0
        } else {
            link_velocity_rad_s
        };
        self.coupling.reset(self.phi);
        self.gravity_nm = self.gravity_now();
        self.current_a = self.motor_current(self.omega_g, 0.0);
        self.sample_sensors();
    }

    /// Change the coupling (the clutch moved): new k, free play, hysteresis, stress factor.
    /// The deflection is kept, the hysteresis history is reset, the substep count is
    /// recomputed.
    pub fn set_coupling(&mut self, coupling: CouplingConfig) {
        self.cfg.coupling = coupling;
        self.d = derive(&self.cfg);
        self.coupling = Coupling::new(&coupling);
        self.coupling.reset(self.phi);
    }

    /// The armature's resistance from now on, Ω (the copper warmed or cooled).
    pub fn set_resistance(&mut self, ohm: f32) {
        self.cfg.motor.resistance_ohm = ohm;
        self.d = derive(&self.cfg);
    }

    /// The bridge supply from now on, V (a battery discharging, another bench supply).
    pub fn set_supply(&mut self, volts: f32) {
        self.cfg.motor.supply_voltage_v = volts;
        self.d = derive(&self.cfg);
    }

    /// External torque on the link, N·m, held until changed (adds to the configured load).
    /// The closure-free way to apply an arbitrary profile: set it before each tick.
    pub fn set_external_torque(&mut self, torque_nm: f32) {
        self.external_nm = torque_nm;
    }

    /// Fault hooks of the sensors (take effect at the next sampling, i.e. the next tick).
    pub fn faults_mut(&mut self) -> &mut SensorFaults {
        &mut self.faults
    }

    /// Sensor readings sampled at the end of the last tick.
    pub fn readings(&self) -> SensorReadings {
        self.readings
    }

    /// Work done on the coupling since construction, ∫τ dφ, J (trapezoidal per substep).
    /// Over a closed deflection cycle it is the energy dissipated by the hysteresis.
    pub fn spring_work_j(&self) -> f64 {
        self.spring_work_j
    }

    /// Advance one 1 ms control period driving the H-bridge with `duty` permille
    /// (saturated to ±1000). Returns the sensor readings at the end of the tick.
    pub fn step_tick(&mut self, duty: i16) -> SensorReadings {
        self.step_tick_cmd(BridgeCommand::Drive(duty))
    }

    /// θ_link − θ_down reduced to (−2π, 2π) in f64, then rounded to f32.
    fn gravity_base(&self) -> f32 {
        libm::fmod(
            self.theta_l - f64::from(self.cfg.load.gravity_down_rad),
            2.0 * core::f64::consts::PI,
        ) as f32
    }

    /// Gravity torque on the link at the current angle, N·m.
    fn gravity_now(&self) -> f32 {
        let mgd = self.cfg.load.gravity_mgd_nm;
        if mgd == 0.0 {
            0.0
        } else {
            -mgd * libm::sinf(self.gravity_base())
        }
    }

    /// Motor current (A) at gear velocity `w` under the current command; `volts` is the
    /// drive voltage for [`BridgeCommand::Drive`].
    #[inline]
    fn motor_current(&self, w: f32, volts: f32) -> f32 {
        let m = &self.cfg.motor;
        let emf = m.back_emf_v_s_per_rad * w;
        match self.command {
            BridgeCommand::Drive(_) => (volts - emf) * self.d.inv_r,
            BridgeCommand::Brake => -emf * self.d.inv_r,
            BridgeCommand::Coast => {
                let vs = m.supply_voltage_v;
                if emf > vs {
                    (vs - emf) * self.d.inv_r
                } else if emf < -vs {
                    (-vs - emf) * self.d.inv_r
                } else {
                    0.0
                }
            }
        }
    }

    fn drive_volts(&self) -> f32 {
        match self.command {
            BridgeCommand::Drive(duty) => {
                let duty = duty.clamp(-DUTY_FULL_SCALE, DUTY_FULL_SCALE);
                // Swapped motor leads: the motor sees the bridge's voltage reversed.
                f32::from(duty) * self.d.volts_per_permille * self.cfg.motor.polarity
            }
            _ => 0.0,
        }
    }

    /// Advance one 1 ms control period with an explicit H-bridge command. Returns the sensor
    /// readings at the end of the tick.
    ///
    /// Integrator: Störmer–Verlet (kick–drift–kick leapfrog) over `substeps()` substeps:
    /// half kick, then per substep a drift, one coupling/gravity evaluation and a kick
    /// (full, the last one half), so velocities and positions are synchronous at tick
    /// boundaries. Velocity-dependent torques (back-EMF, viscous) use the velocity at the
    /// start of each kick; dry friction is a velocity projection (stick-capable).
    pub fn step_tick_cmd(&mut self, command: BridgeCommand) -> SensorReadings {
        self.command = command;
        let volts = self.drive_volts();
        let load_const = self.cfg.load.constant_nm
            + self.cfg.load.profile.torque_at(self.tick)
            + self.external_nm;
        let kt = self.cfg.motor.torque_constant_nm_per_a;
        let bg = self.cfg.motor.viscous_nm_s_per_rad;
        let bl = self.cfg.link.viscous_nm_s_per_rad;
        let gear_free = !self.cfg.gear_locked;
        let link_free = !self.cfg.link_locked;
        let n = self.d.substeps;
        let dt = self.d.dt;
        // Drive and brake: gear torque = a − b·ω − τ_c (motor + viscous folded together).
        // Coast is piecewise (freewheel diodes) and takes the general path.
        let coast = matches!(command, BridgeCommand::Coast);
        let b_emf = kt * self.cfg.motor.back_emf_v_s_per_rad * self.d.inv_r;
        let a_motor = kt * volts * self.d.inv_r;
        let b_gear = b_emf + bg;
        // Gravity: sin/cos of the link angle once per tick (libm), then per substep the
        // angle-addition formula with short Taylor series of the within-tick displacement
        // (error < 1e-9 for |dl| ≤ 0.1 rad; beyond, libm::sinf).
        let mgd = self.cfg.load.gravity_mgd_nm;
        let gravity_on = mgd != 0.0;
        let (sin0, cos0, base) = if gravity_on {
            let base = self.gravity_base();
            let (s0, c0) = libm::sincosf(base);
            (s0, c0, base)
        } else {
            (0.0, 0.0, 0.0)
        };

        let mut wg = self.omega_g;
        let mut wl = self.omega_l;
        let mut tau_c = self.coupling.torque();
        let mut tau_g = self.gravity_nm;
        let phi0 = self.phi;
        let mut phi = phi0;
        let mut dg = 0.0f32;
        let mut dl = 0.0f32;
        let mut work = 0.0f32;

        let mut k = self.d.half;
        let mut s: u16 = 0;
        loop {
            // Kick.
            if gear_free {
                let tau_m = if coast {
                    kt * self.motor_current(wg, volts) - bg * wg
                } else {
                    a_motor - b_gear * wg
                };
                wg += k.gain_g * (tau_m - tau_c);
                wg = dry_friction(wg, k.fric_g);
            }
            if link_free {
                wl += k.gain_l * (tau_c + tau_g + load_const - bl * wl);
                wl = dry_friction(wl, k.fric_l);
            }
            if s == n {
                break;
            }
            // Drift.
            dg += dt * wg;
            dl += dt * wl;
            let phi_new = phi0 + (dg - dl);
            // Forces at the new positions.
            let tau_new = self.coupling.update(phi_new);
            work += (tau_c + tau_new) * (phi_new - phi);
            tau_c = tau_new;
            phi = phi_new;
            if gravity_on {
                tau_g = -mgd * sin_shifted(sin0, cos0, base, dl);
            }
            s += 1;
            k = if s == n { self.d.half } else { self.d.full };
        }

        self.omega_g = wg;
        self.omega_l = wl;
        self.theta_g += f64::from(dg);
        self.theta_l += f64::from(dl);
        self.phi = phi;
        self.gravity_nm = tau_g;
        self.current_a = self.motor_current(wg, volts);
        self.spring_work_j += 0.5 * f64::from(work);
        self.tick = self.tick.wrapping_add(1);
        self.sample_sensors();
        self.readings
    }

    /// Samples the sensors again at the present state (fresh noise) without advancing the
    /// dynamics: the readings of an actuator held still while its board boots.
    pub fn resample(&mut self) -> SensorReadings {
        self.sample_sensors();
        self.readings
    }

    fn sample_sensors(&mut self) {
        let s = &self.cfg.sensors;
        let noise = s.current_noise_counts * self.rng.next_gaussian();
        // The pot's noise is drawn only when configured, so the current noise's sequence
        // (and every digest of a run without pot noise) stays as it was.
        let pot_noise = if s.pot_noise_counts > 0.0 {
            s.pot_noise_counts * self.rng.next_gaussian()
        } else {
            0.0
        };
        let since_power_up = self.theta_l - f64::from(self.cfg.power_up_angle_rad);
        let raw = SensorReadings {
            gear_pot: pot_counts(self.theta_g, s, pot_noise),
            link_encoder: encoder_counts(since_power_up, s),
            // The sense sits in the bridge's output: it reads the bridge current, the
            // motor's times the lead polarity.
            current_adc: adc_counts(
                self.current_a * self.cfg.motor.polarity,
                s.current_gain,
                s.current_offset_counts,
                noise,
            ),
            supply_adc: supply_counts(self.cfg.motor.supply_voltage_v, s.supply_sense_gain),
        };
        self.readings = self.faults.apply(raw, self.readings);
    }

    /// The true state at the end of the last tick.
    pub fn state(&self) -> TrueState {
        let tau = self.coupling.torque();
        let load = self.cfg.load.constant_nm
            + self.cfg.load.profile.torque_at(self.tick.saturating_sub(1))
            + self.external_nm
            + self.gravity_nm;
        TrueState {
            tick: self.tick,
            gear_angle_rad: self.theta_g,
            gear_velocity_rad_s: self.omega_g,
            link_angle_rad: self.theta_l,
            link_velocity_rad_s: self.omega_l,
            deflection_rad: self.phi,
            effective_deflection_rad: self.coupling.last_effective_deflection(),
            spring_torque_nm: tau,
            branch: self.coupling.branch(),
            motor_current_a: self.current_a,
            motor_torque_nm: self.cfg.motor.torque_constant_nm_per_a * self.current_a,
            load_torque_nm: load,
            beam_stress_pa: tau * self.cfg.coupling.stress_per_torque_pa_per_nm,
        }
    }

    /// Mechanical energy at the end of the last tick (uses one `libm::cosf` if gravity is
    /// configured).
    pub fn energy(&self) -> Energy {
        let jg = if self.cfg.gear_locked {
            0.0
        } else {
            self.cfg.motor.inertia_kg_m2
        };
        let jl = if self.cfg.link_locked {
            0.0
        } else {
            self.cfg.link.inertia_kg_m2
        };
        let mgd = self.cfg.load.gravity_mgd_nm;
        let gravity_j = if mgd == 0.0 {
            0.0
        } else {
            mgd * (1.0 - libm::cosf(self.gravity_base()))
        };
        Energy {
            kinetic_j: 0.5 * (jg * self.omega_g * self.omega_g + jl * self.omega_l * self.omega_l),
            elastic_j: self.coupling.elastic_energy(),
            gravity_j,
        }
    }

    /// A 32-bit FNV-1a digest of the bit patterns of the whole state (angles, velocities,
    /// deflection, coupling torque, current, tick, noise state, readings): compare host and
    /// target runs of the same scenario for bit-identity.
    pub fn digest(&self) -> u32 {
        let mut h: u32 = 0x811C_9DC5;
        let mut mix = |word: u64| {
            for b in word.to_le_bytes() {
                h ^= u32::from(b);
                h = h.wrapping_mul(0x0100_0193);
            }
        };
        mix(self.theta_g.to_bits());
        mix(self.theta_l.to_bits());
        mix(u64::from(self.phi.to_bits()));
        mix(u64::from(self.omega_g.to_bits()));
        mix(u64::from(self.omega_l.to_bits()));
        mix(u64::from(self.coupling.torque().to_bits()));
        mix(u64::from(self.current_a.to_bits()));
        mix(self.spring_work_j.to_bits());
        mix(u64::from(self.tick));
        let mut rng = self.rng;
        mix(u64::from(rng.next_u32()));
        mix(u64::from(self.readings.gear_pot)
            | u64::from(self.readings.link_encoder) << 16
            | u64::from(self.readings.current_adc) << 32);
        h
    }
}
