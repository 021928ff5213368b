//! Simulated actuator standing in for the real servo (see `design.md` §3).
//!
//! A DC motor behind a 254:1 gearbox (all constants referred to the output) drives the
//! output gear through an H-bridge ([`BridgeCommand`]: signed duty in permille, coast,
//! brake). The gear is joined to the link (output shaft) by the four-beam coupling
//! ([`Coupling`]: free-play dead zone, stiffness k, friction hysteresis). The link carries
//! a configurable load ([`LoadConfig`]: constant, gravity arm, piecewise-constant profile,
//! and a per-tick external torque). The board sees the gear potentiometer, the link
//! magnetic encoder and the current ADC ([`SensorReadings`]), with deterministic noise and
//! fault hooks.
//!
//! Motor model: armature inductance neglected, the current is algebraic,
//! i = (V − k_e·ω_gear)/R, torque k_t·i on the gear, minus viscous and Coulomb friction.
//!
//! # Numerics and bit-identity
//!
//! Everything is `f32` using only IEEE basic operations (+ − × ÷ √) plus the `libm` crate
//! (sinf for gravity, floor/fmod/cos at sampling time), never `std` float methods, so a run
//! is bit-identical on x86, the Cortex-M4F and the soft-float Cortex-M3. The absolute
//! angles are accumulated in `f64` once per tick (so slow motion at large angles is not
//! rounded away); within a tick the displacements and the deflection are `f32`.
//!
//! The integrator is Störmer–Verlet (kick–drift–kick), symplectic and second order: with
//! the default 20 substeps per 1 ms tick (dt = 50 µs) the stiffest paper setting (L = 1 mm,
//! k = 7167.5 N·m/rad, gear + link mode ω = 3070 rad/s) runs at ω·dt = 0.15. The substep
//! count is raised automatically for stiffer couplings
//! ([`PlantConfig::effective_substeps`]). Per substep: one coupling evaluation (no libm),
//! one kick and one drift, about 35 float operations; a gravity load adds a dozen more
//! (sin/cos once per tick through libm, angle addition with short series per substep).
//!
//! Measured cost of one tick at the default 20 substeps (release, QEMU `-icount shift=3`,
//! SysTick at the core clock): about 42 000 cycles on the soft-float Cortex-M3 (netduino2,
//! 120 MHz, 0.35 ms of each 1 ms) and 4 700 on the Cortex-M4F (netduinoplus2, 168 MHz); with
//! a gravity load 61 000 and 8 200. At soft settings the M3 can run with fewer substeps
//! (e.g. `substeps: 5` at L ≥ 3 mm); the plant never goes below the stable count. The same
//! scenario gives the same [`Plant::digest`] on x86, the emulated M3 and the emulated M4F.
//!
//! The coupling parameters are plain `f32` that the caller derives from the beam model
//! (`model` crate, `design.md` §2) for its geometry and clutch length; [`harness`] does
//! that and closes the loop with the `model` crate's controller (metrics streamed, no
//! allocation); [`metrics`] defines the step-response figures every tool reports.
#![cfg_attr(not(test), no_std)]
#![forbid(unsafe_code)]
#![deny(missing_docs)]

mod config;
mod coupling;
pub mod harness;
pub mod metrics;
pub mod scenario;
mod sensors;
pub mod served;
mod sim;

pub use config::{
    CouplingConfig, LinkConfig, LoadConfig, MotorConfig, PlantConfig, ProfileStep, SensorConfig,
    TorqueProfile, DEFAULT_SUBSTEPS, DUTY_FULL_SCALE, MAX_OMEGA_DT, MAX_OMEGA_DT_STICK,
    MAX_SUBSTEPS, PROFILE_STEPS, TICK_S,
};
pub use coupling::{Branch, Coupling};
pub use sensors::{
    SensorFault, SensorFaults, SensorReadings, XorShift32, ENCODER_COUNT_RAD, POT_COUNTS_PER_RAD,
};
pub use sim::{BridgeCommand, Energy, Plant, TrueState};
