//! What the controller is configured with: the clutch setting, the link inertia, the motor,
//! the live limits, gain overrides and the sensor calibration. [`super::Schedule::new`]
//! validates a [`Config`] and derives the per-tick constants from it.

use fixed::types::I32F32;

use super::error::ControlError;
use crate::beam::BeamModel;
use crate::design::Design;
use crate::units::{Frequency, Inertia, Length, Ratio, Stiffness, Torque};

/// Which clutch setting to run at.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ClutchSetting {
    /// Active beam length L, mm, in the adjustable range [t_c, l].
    Length(Length),
    /// Wanted joint stiffness k, N·m/rad: L = L(k) of the beam model.
    Stiffness(Stiffness),
}

/// Motor and gearbox, all referred to the gearbox output (AX-12A class defaults,
/// docs/design.md §3). Units in the field docs; every field is I32F32 unless stated.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MotorParams {
    /// H-bridge supply, V, in [1, 100]. Duty ±1000 ‰ applies ±supply.
    pub supply_v: I32F32,
    /// Armature resistance, Ω, in [0.1, 1000].
    pub resistance_ohm: I32F32,
    /// Torque constant at the output, N·m/A, in [0.01, 100].
    pub torque_constant: I32F32,
    /// Back-EMF constant at the output, V·s/rad, in [0.01, 100].
    pub back_emf: I32F32,
    /// Rotor + gear train inertia at the output, kg·mm², in [1, 10⁶].
    pub rotor_inertia: Inertia,
    /// Viscous friction of the gear train at the output, N·m·s/rad, in [0, 10].
    pub viscous: I32F32,
    /// Coulomb (dry) friction of the gear train at the output, N·m, in [0, 1].
    pub coulomb: I32F32,
}

impl MotorParams {
    /// AX-12A class: 12 V, 8 Ω, k_t = 1.0 N·m/A, k_e = 1.94 V·s/rad, J_rotor = 3.2e-3
    /// kg·m² (3200 kg·mm²), viscous 1e-3 N·m·s/rad.
    pub const AX12A: MotorParams = MotorParams {
        supply_v: I32F32::lit("12"),
        resistance_ohm: I32F32::lit("8"),
        torque_constant: I32F32::lit("1"),
        back_emf: I32F32::lit("1.94"),
        rotor_inertia: Inertia::from_int(3200),
        viscous: I32F32::lit("0.001"),
        coulomb: I32F32::lit("0.01"),
    };
}

/// Live limits (clamps, not faults).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Limits {
    /// Fraction of the beams' stress-limited capacity τ_cap(L) the coupling torque may
    /// use, in (0, 1]. Default 0.85.
    pub torque_margin: Ratio,
    /// Motor current limit, A, in (0, 10]. Default 1.5 A (stall current at 12 V).
    pub max_current_a: I32F32,
    /// Motor torque limit at the output, N·m, > 0. Default 1.5 N·m (stall torque).
    pub max_motor_torque: Torque,
    /// Largest |duty|, ‰, in 1..=1000. Default 1000.
    pub max_duty: i16,
    /// How much longer than configured the hand-set clutch may actually be, mm, in
    /// [0, 5]. The beams' capacity at L + this (τ_cap ∝ 1/L, eq. 2) is the one the torque
    /// limit above and the supervisor's overload check use (the latter until the clutch
    /// monitor, if on, confirms the stiffness; docs/calibration.md, "The clutch
    /// monitor"). Default 0 (τ_cap(L) as configured); a board takes 1 mm until a
    /// calibration confirms the clutch (`service::clutch_confirmation`).
    pub clutch_tolerance: Length,
}

impl Limits {
    /// The defaults above.
    pub const DEFAULT: Limits = Limits {
        torque_margin: Ratio::from_fixed(I32F32::lit("0.85")),
        max_current_a: I32F32::lit("1.5"),
        max_motor_torque: Torque::from_fixed(I32F32::lit("1.5")),
        max_duty: 1000,
        clutch_tolerance: Length::from_int(0),
    };
}

impl Default for Limits {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// PID gains in the controller's units (duty ‰ out, link angle in).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PidGains {
    /// Proportional, ‰/rad, in [0, 10⁶].
    pub kp: I32F32,
    /// Integral, ‰/(rad·s), in [0, 10⁷].
    pub ki: I32F32,
    /// Derivative (on the filtered link velocity), ‰·s/rad, in [0, 10⁴].
    pub kd: I32F32,
}

/// Overrides of the automatic gain schedule.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct GainOverride {
    /// Closed-loop bandwidth ω_c, rad/s, in (0, 500]; `None`: scheduled from k and J.
    pub bandwidth: Option<Frequency>,
    /// Explicit PID gains; `None`: from the pole placement at ω_c.
    pub gains: Option<PidGains>,
}

/// Sensor calibration.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SensorCal {
    /// Gear potentiometer reading at gear angle 0, counts, 0..=1023. Default 512.
    pub pot_center: u16,
    /// Link encoder reading at link angle 0, counts, 0..=4095. Default 0.
    pub encoder_zero: u16,
    /// 1-σ uncertainty of the current-based torque estimate (gear friction, inertia and
    /// gear-efficiency model error), N·m, > 0. Default 0.02 N·m. Sets the blend with the
    /// deflection-based estimate.
    pub current_torque_sigma: Torque,
}

impl SensorCal {
    /// The defaults above.
    pub const DEFAULT: SensorCal = SensorCal {
        pot_center: 512,
        encoder_zero: 0,
        current_torque_sigma: Torque::from_fixed(I32F32::lit("0.02")),
    };
}

impl Default for SensorCal {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// Everything the controller needs to know about the actuator and the task. (Not
/// `defmt::Format`: log the fields you need, as raw bits.)
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Config {
    /// The clutch setting.
    pub clutch: ClutchSetting,
    /// Beam theory for k(L) and L(k).
    pub beam_model: BeamModel,
    /// Link inertia about the output axis, kg·mm² (1e-3 kg·m² = 1000).
    pub link_inertia: Inertia,
    /// Motor and gearbox.
    pub motor: MotorParams,
    /// Live limits.
    pub limits: Limits,
    /// Gain schedule overrides.
    pub gains: GainOverride,
    /// Sensor calibration.
    pub sensors: SensorCal,
}

impl Config {
    /// Paper preset at clutch length `len`: E–B beams, J_link = 1e-3 kg·m², AX-12A motor,
    /// default limits, scheduled gains.
    #[must_use]
    pub const fn paper(len: Length) -> Config {
        Config {
            clutch: ClutchSetting::Length(len),
            beam_model: BeamModel::EulerBernoulli,
            link_inertia: Inertia::from_int(1000),
            motor: MotorParams::AX12A,
            limits: Limits::DEFAULT,
            gains: GainOverride {
                bandwidth: None,
                gains: None,
            },
            sensors: SensorCal::DEFAULT,
        }
    }

    /// The clutch length the setting asks for on `design`: L itself, or L(k) of the beam
    /// model for a stiffness (not checked against the adjustable range).
    ///
    /// # Errors
    /// As the beam model's L(k) for a stiffness it cannot invert.
    pub fn clutch_length(&self, design: &Design) -> Result<Length, ControlError> {
        Ok(match self.clutch {
            ClutchSetting::Length(l) => l,
            ClutchSetting::Stiffness(k) => self.beam_model.clutch_length(design, k)?,
        })
    }
}
