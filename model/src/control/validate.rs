//! The ranges a [`Config`] must lie in, checked before anything is derived from it.

use fixed::types::I32F32;

use super::config::Config;
use super::error::ControlError;
use crate::beam::Setting;
use crate::design::Design;
use crate::sensors::{ENCODER_COUNTS, POT_COUNTS};
use crate::units::{Frequency, Stiffness};

/// Stiffest setting the controller accepts, N·m/rad.
pub const MAX_STIFFNESS: i64 = 1_000_000;
/// Smallest link inertia, kg·mm² (1e-6 kg·m²).
pub const MIN_INERTIA: i32 = 1;
/// Largest link inertia, kg·mm² (1 kg·m²).
pub const MAX_INERTIA: i32 = 1_000_000;
/// Largest clutch tolerance, mm.
pub const MAX_CLUTCH_TOLERANCE_MM: i32 = 5;

fn in_range(v: I32F32, lo: I32F32, hi: I32F32) -> bool {
    v >= lo && v <= hi
}

/// Checks every field of `cfg` against its documented range and returns the clutch
/// setting it asks for on `design`.
///
/// # Errors
/// The first field out of range, in the order motor, limits, inertia, sensors, gains,
/// clutch, stiffness.
pub(crate) fn validate(design: &Design, cfg: &Config) -> Result<Setting, ControlError> {
    use ControlError as E;
    let m = &cfg.motor;
    let one = I32F32::ONE;
    if !(in_range(m.supply_v, one, I32F32::from_num(100))
        && in_range(
            m.resistance_ohm,
            const { I32F32::lit("0.1") },
            I32F32::from_num(1000),
        )
        && in_range(
            m.torque_constant,
            const { I32F32::lit("0.01") },
            I32F32::from_num(100),
        )
        && in_range(
            m.back_emf,
            const { I32F32::lit("0.01") },
            I32F32::from_num(100),
        )
        && in_range(m.rotor_inertia.get(), one, I32F32::from_num(1_000_000))
        && in_range(m.viscous, I32F32::ZERO, I32F32::from_num(10))
        && in_range(m.coulomb, I32F32::ZERO, I32F32::ONE))
    {
        return Err(E::MotorOutOfRange);
    }
    let lim = &cfg.limits;
    if !(in_range(lim.torque_margin.get(), I32F32::DELTA, one)
        && in_range(lim.max_current_a, I32F32::DELTA, I32F32::from_num(10))
        && lim.max_motor_torque.to_bits() > 0
        && (1..=1000).contains(&lim.max_duty)
        && in_range(
            lim.clutch_tolerance.get(),
            I32F32::ZERO,
            I32F32::from_num(MAX_CLUTCH_TOLERANCE_MM),
        ))
    {
        return Err(E::LimitOutOfRange);
    }
    if !in_range(
        cfg.link_inertia.get(),
        I32F32::from_num(MIN_INERTIA),
        I32F32::from_num(MAX_INERTIA),
    ) {
        return Err(E::InertiaOutOfRange);
    }
    let s = &cfg.sensors;
    if s.pot_center >= POT_COUNTS
        || s.encoder_zero >= ENCODER_COUNTS
        || s.current_torque_sigma.to_bits() <= 0
    {
        return Err(E::SensorOutOfRange);
    }
    if let Some(bw) = cfg.gains.bandwidth {
        if bw.to_bits() <= 0 || bw > Frequency::from_int(500) {
            return Err(E::GainOutOfRange);
        }
    }
    if let Some(g) = cfg.gains.gains {
        if !(in_range(g.kp, I32F32::ZERO, I32F32::from_num(1_000_000))
            && in_range(g.ki, I32F32::ZERO, I32F32::from_num(10_000_000))
            && in_range(g.kd, I32F32::ZERO, I32F32::from_num(10_000)))
        {
            return Err(E::GainOutOfRange);
        }
    }
    let len = cfg.clutch_length(design)?;
    let (l_min, l_max) = design.adjustable_range();
    if len < l_min || len > l_max {
        return Err(E::ClutchOutOfRange);
    }
    let setting = Setting::new(design, len, cfg.beam_model)?;
    if setting.stiffness() > Stiffness::from_int(MAX_STIFFNESS) {
        return Err(E::StiffnessOutOfRange);
    }
    Ok(setting)
}
