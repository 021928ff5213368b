//! Fixed-point maths of the vsa variable-stiffness actuator (see `docs/design.md` §2).
//!
//! Four steel cantilever beams join a servo's output gear to its output shaft; a clutch
//! plate sliding along them sets the active length L and with it the joint stiffness
//! k = n·3·E·I·R²/L³ (paper eq. 4). This crate is the no_std, float-free model of that
//! coupling, shared by the firmware (1 kHz loop), the host tools and the tests:
//!
//! * [`units`]: one newtype per quantity, each with its unit and fixed-point format;
//! * [`design`]: the validated [`Design`] and its derived constants ([`Design::paper`]);
//! * [`stiffness`]: k(L), k_T(L) and their inverses L(k) (eq. 4, row 4T);
//! * [`stress`]: deflection, beam force, root stress and the stress-limited capacity;
//! * [`beam`]: the beam model and the precomputed per-setting [`Setting`] for the control
//!   loop;
//! * [`backlash`]: paper eqs. 5–7 and the free-play dead zone of the coupling;
//! * [`hysteresis`]: friction hysteresis branches and their state machine (§2.1);
//! * [`dynamics`]: natural frequency and the stiffness/clutch setting for a wanted one;
//! * [`material`]: beam materials (E, G, σ_allow, density, sources); [`sizing`]: a design's
//!   mass, stored energy and fit against goals (the explorer's numbers);
//! * [`fixmath`]: integer square and cube roots;
//! * [`sensors`]: the sensors' resolutions, their count-to-radian constants and the
//!   encoder wrap;
//! * [`control`]: the 1 kHz link-position controller, its trajectories and gain schedule;
//! * [`supervisor`]: the latched fault checks (docs/design.md §7); [`servo`]: the controller
//!   under the supervisor with the enable state machine, the firmware's per-tick decision;
//! * [`error`]: the [`Error`] every fallible function returns.
//!
//! Every function is total: inputs outside the documented domain and results that do not
//! fit their format are errors; nothing panics and nothing wraps. All arithmetic is
//! integer, so results are bit-identical on the host and on Cortex-M.
//!
//! Domain: the design parameters of [`DesignParams`] (n ∈ 1..=16, r ∈ [0.05, 5] mm,
//! R ∈ [1, 100] mm with R > r, E, G ∈ [1, 1000] GPa with G ≥ E/3, σ_allow ∈ [1, 10⁴] MPa,
//! l ∈ [0.1, 100] mm, t_c ∈ [0.01 mm, l), μ ∈ [0, 2]); clutch length L ∈ (0, l]; clutch
//! position x ∈ [t_c, l] for eq. 7; any representable torque, angle, inertia > 0,
//! frequency > 0, stiffness > 0.
//!
//! Accuracy: derived constants are kept as 64-bit-mantissa integers (relative error
//! ~1e-18 each) and every result is rounded once into its format, so results are within
//! ~1e-12 relative or 0.5 LSB of the exact value over the whole domain (a unit-test sweep
//! checks 1e-9 / 0.51 LSB against f64). Division by a configuration value happens only
//! when a [`Design`] or a [`Setting`] is built, or in functions that take L as an argument;
//! the per-tick [`Setting`] functions multiply by precomputed reciprocals.
#![cfg_attr(not(test), no_std)]
#![forbid(unsafe_code)]
#![deny(missing_docs)]

pub mod backlash;
pub mod beam;
pub mod calibration;
pub mod clutch_monitor;
pub mod control;
pub mod design;
pub mod dynamics;
pub mod error;
pub mod fixmath;
pub mod hysteresis;
pub mod material;
pub mod sensors;
pub mod servo;
pub mod sizing;
pub mod stiffness;
pub mod stress;
pub mod supervisor;
pub mod units;

pub use beam::{BeamModel, Setting};
pub use control::{
    Command, ControlError, Controller, Flags as ControlFlags, Measurements, Output as ControlOutput,
};
pub use design::{Design, DesignParams};
pub use dynamics::{natural_frequency, stiffness_for_frequency, Tuning};
pub use error::{Error, Result};
pub use hysteresis::{Branch, Hysteresis};
pub use units::{Angle, Force, Frequency, Inertia, Length, Ratio, Stiffness, Stress, Torque};

#[cfg(test)]
mod sweep;
#[cfg(test)]
mod test_rng;
