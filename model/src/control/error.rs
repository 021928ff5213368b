//! Why the controller rejected a configuration or a command.

use core::fmt;

use crate::error::Error;

/// Why a configuration or a command was rejected. The running configuration (or
/// trajectory) is left untouched.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum ControlError {
    /// The beam model rejected the clutch length or the wanted stiffness.
    Beam(Error),
    /// The clutch length is outside the adjustable range [t_c, l] of the design.
    ClutchOutOfRange,
    /// The stiffness is above [`MAX_STIFFNESS`](super::MAX_STIFFNESS) (outside the controller's formats).
    StiffnessOutOfRange,
    /// Link inertia outside [[`MIN_INERTIA`](super::MIN_INERTIA), [`MAX_INERTIA`](super::MAX_INERTIA)] kg·mm².
    InertiaOutOfRange,
    /// A motor parameter is outside its documented range (see [`MotorParams`](super::MotorParams)).
    MotorOutOfRange,
    /// A limit is outside its documented range (see [`Limits`](super::Limits)).
    LimitOutOfRange,
    /// A gain override or the bandwidth is outside its range (see [`GainOverride`](super::GainOverride)).
    GainOutOfRange,
    /// A sensor calibration value is outside the sensor's range.
    SensorOutOfRange,
    /// A trajectory command is outside its range (see [`super::trajectory`]).
    TrajectoryOutOfRange,
    /// A derived constant does not fit its per-tick format.
    Overflow,
}

impl fmt::Display for ControlError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ControlError::Beam(e) => write!(f, "beam model: {e}"),
            ControlError::ClutchOutOfRange => {
                f.write_str("clutch length outside the adjustable range [t_c, l]")
            }
            ControlError::StiffnessOutOfRange => {
                f.write_str("stiffness above the controller's range (1e6 N·m/rad)")
            }
            ControlError::InertiaOutOfRange => {
                f.write_str("link inertia outside [1, 1e6] kg·mm² (1e-6 … 1 kg·m²)")
            }
            ControlError::MotorOutOfRange => f.write_str("motor parameter out of range"),
            ControlError::LimitOutOfRange => f.write_str("limit out of range"),
            ControlError::GainOutOfRange => f.write_str("gain or bandwidth out of range"),
            ControlError::SensorOutOfRange => f.write_str("sensor calibration out of range"),
            ControlError::TrajectoryOutOfRange => f.write_str("trajectory command out of range"),
            ControlError::Overflow => f.write_str("derived constant out of its fixed-point range"),
        }
    }
}

impl core::error::Error for ControlError {}

impl From<Error> for ControlError {
    fn from(e: Error) -> Self {
        ControlError::Beam(e)
    }
}
