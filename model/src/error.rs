//! The crate's error type: every function is total and reports what went wrong instead of
//! panicking or wrapping.

use core::fmt;

/// Why a design was rejected or a computation has no result.
///
/// Fieldless so that it is cheap to return, compare and log from the 1 kHz task.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum Error {
    /// Beam count n outside `1..=16`.
    BeamCountOutOfRange,
    /// Beam radius r outside [0.05, 5] mm.
    BeamRadiusOutOfRange,
    /// Pitch radius R outside [1, 100] mm, or not larger than the beam radius r.
    PitchRadiusOutOfRange,
    /// Young's modulus E outside [1, 1000] GPa.
    YoungsModulusOutOfRange,
    /// Shear modulus G outside [1, 1000] GPa.
    ShearModulusOutOfRange,
    /// Poisson's ratio ν = E/(2G) − 1 above 0.5 (G < E/3): not an isotropic solid.
    PoissonRatioNonPhysical,
    /// Allowable stress σ_allow outside [1, 10 000] MPa.
    AllowableStressOutOfRange,
    /// Total beam length l outside [0.1, 100] mm.
    BeamLengthOutOfRange,
    /// Clutch plate thickness t_c outside [0.01 mm, l).
    ClutchThicknessOutOfRange,
    /// Friction coefficient μ outside [0, 2].
    FrictionOutOfRange,
    /// Clutch (active) length L outside (0, l].
    ClutchLengthOutOfRange,
    /// Clutch position x outside [t_c, l] for the beam-tilt backlash (paper eq. 7).
    BacklashPositionOutOfRange,
    /// A stiffness that must be positive is zero or negative.
    StiffnessNotPositive,
    /// The wanted stiffness is below k(l): it would need a clutch length beyond l.
    StiffnessTooLow,
    /// The wanted stiffness needs a clutch length that rounds to 0 (below 1.2e-10 mm).
    StiffnessTooHigh,
    /// A link inertia that must be positive is zero or negative.
    InertiaNotPositive,
    /// A frequency that must be positive is zero or negative.
    FrequencyNotPositive,
    /// The result, or a value on the way to it, does not fit its fixed-point format.
    Overflow,
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Error::BeamCountOutOfRange => "beam count outside 1..=16",
            Error::BeamRadiusOutOfRange => "beam radius outside [0.05, 5] mm",
            Error::PitchRadiusOutOfRange => {
                "pitch radius outside [1, 100] mm or not larger than the beam radius"
            }
            Error::YoungsModulusOutOfRange => "Young's modulus outside [1, 1000] GPa",
            Error::ShearModulusOutOfRange => "shear modulus outside [1, 1000] GPa",
            Error::PoissonRatioNonPhysical => {
                "shear modulus below E/3: Poisson's ratio above 0.5 is non-physical"
            }
            Error::AllowableStressOutOfRange => "allowable stress outside [1, 10000] MPa",
            Error::BeamLengthOutOfRange => "beam length outside [0.1, 100] mm",
            Error::ClutchThicknessOutOfRange => "clutch thickness outside [0.01 mm, beam length)",
            Error::FrictionOutOfRange => "friction coefficient outside [0, 2]",
            Error::ClutchLengthOutOfRange => "clutch length outside (0, beam length]",
            Error::BacklashPositionOutOfRange => {
                "clutch position outside [clutch thickness, beam length]"
            }
            Error::StiffnessNotPositive => "stiffness must be positive",
            Error::StiffnessTooLow => "stiffness below the softest setting (L > l)",
            Error::StiffnessTooHigh => "stiffness needs a clutch length below resolution",
            Error::InertiaNotPositive => "inertia must be positive",
            Error::FrequencyNotPositive => "frequency must be positive",
            Error::Overflow => "result out of range of its fixed-point format",
        })
    }
}

impl core::error::Error for Error {}

/// Result with the crate's [`Error`].
pub type Result<T> = core::result::Result<T, Error>;
