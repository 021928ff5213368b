//! The 1 kHz link-position controller: trajectories, a scheduled PID with feed-forward,
//! free-play compensation, a blended torque estimate and live torque/current limits, all
//! in integer fixed point (no floats, no allocation, no panics), bit-identical on the host
//! and on Cortex-M. The plant model, the per-tick structure and the derivation of every
//! formula are in `docs/design.md` §11; in short, per tick:
//!
//! 1. unwrap the link encoder (angle at the centre of the count) and read the current;
//! 2. gear velocity from the back-EMF observer ω_g = (V − R·i)/k_e (no differentiation;
//!    its R read from a raw step's or a move's first duty jump after the tick,
//!    [`duty_jump`]);
//! 3. coupling torque: current-based (current and gear velocity through the derivative
//!    filter, so that the observer's jump on a duty step is no torque), blended with the
//!    pot's deflection-based estimate by inverse variance;
//! 4. reference r, ṙ, r̈ from [`trajectory`] (a raw step along the near-time-optimal
//!    profile of [`dash`], at soft settings through the ZV shaper of [`shaper`]; a move no
//!    shorter than the limits allow, [`move_duration`]);
//!    a move's r̈ feed-forward scaled for the actuator it meets ([`move_drive`]), and its
//!    ṙ feed-forward for the observer's scale against the gear's travel ([`speed_scale`],
//!    fitted after each tick by `Controller::track_speed`);
//! 5. error e = r − θ_l, zero while r lies in the measured encoder count;
//! 6. feed-forward of the rigid inverse model (the two-mass inverse for a sine,
//!    [`sine_feedforward`]), plus the free-play and compliance
//!    compensation (a dead-zone inverse on the gear side, the beams' hysteresis band) and,
//!    for a moving reference and a loaded link, the gear's Coulomb friction;
//! 7. PID with the derivative on the filtered gear velocity (over a loaded raw step, read
//!    for the motor's back-EMF constant by [`speed_scale`]); integral separation, and a
//!    gear hold inside the target count of a stationary reference (dead band: the
//!    observer's bias bound for a current-sense offset and a warm motor's resistance).
//!    While the link floats in the free play (little load held), P and I act on the gear's
//!    error against a gear-angle estimate (the observer integrated, pulled towards the
//!    link below ω_c/3), so that the link's rattle in the gap does not drive the motor,
//!    and near the target or in motion the loop runs at ω_c/2; at rest without load a
//!    still link more than a count off the target is pushed there at a crawl ([`creep`]),
//!    and a link bouncing in the free play is caught at the target by the gear's wall
//!    moving ahead of it ([`catch`], which then has the output instead of steps 6–9's
//!    terms; the window of step 9 stays);
//! 8. braking governor for stationary references (ω_g² > 2·a_b·|e|);
//! 9. clamps: current window about the back-EMF, beam-derived torque limit, duty limit,
//!    with anti-windup.
//!
//! The gains come from pole placement of (s + ω_c)³ on the rigid model, ω_c =
//! min(60 rad/s, ω_a/5), ω_a = √(k/J_l), computed in [`Schedule::new`] when the
//! configuration changes, never per tick.
//!
//! Formats: per-tick signals are Q16 `i32` (duty ‰, rad, rad/s, rad/s², A, N·m; range
//! ±32 768, resolution 1.5e-5), absolute angles and the integrator I32F32 `i64`; constants
//! are [`Gain`]s. Every operation saturates.

pub mod catch;
pub mod config;
pub mod controller;
pub mod creep;
pub mod dash;
pub mod duty_jump;
pub mod error;
pub mod gain;
pub mod hunt;
pub mod impedance;
pub mod move_drive;
pub mod move_duration;
pub mod rest_resistance;
pub mod schedule;
pub mod shaper;
pub mod sine;
pub mod sine_feedforward;
pub mod speed_scale;
pub mod supply_window;
pub mod trajectory;
pub mod validate;
mod wide;

pub use config::{ClutchSetting, Config, GainOverride, Limits, MotorParams, PidGains, SensorCal};
pub use controller::{Controller, Flags, Measurements, Output};
pub use error::ControlError;
pub use gain::Gain;
pub use impedance::{Impedance, ImpedanceCommand, ImpedanceError};
pub use schedule::{
    Schedule, BRAKE_FRACTION, BW_MAX, BW_RATIO, CONTACT_TORQUE_NM, DERIV_FILTER_N,
    FREE_PLAY_SWITCH_NM,
};
pub use trajectory::{Command, Reference, Trajectory};
pub use validate::{MAX_CLUTCH_TOLERANCE_MM, MAX_INERTIA, MAX_STIFFNESS, MIN_INERTIA};
// The bench's float port imports it from here.
pub use crate::sensors::encoder_delta;
