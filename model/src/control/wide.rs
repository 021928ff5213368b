//! Checked I64F64 arithmetic for the configuration-time derivations of
//! [`super::Schedule`]: every operation fails with [`ControlError::Overflow`] instead of
//! wrapping, and the results are rounded into their per-tick formats.

use fixed::types::{I32F32, I64F64};

use super::error::ControlError;
use super::gain::Gain;

/// An I32F32 configuration value widened to I64F64 (exact).
pub(crate) fn wide(v: I32F32) -> I64F64 {
    I64F64::from_num(v)
}

pub(crate) fn mul(a: I64F64, b: I64F64) -> Result<I64F64, ControlError> {
    a.checked_mul(b).ok_or(ControlError::Overflow)
}

pub(crate) fn div(a: I64F64, b: I64F64) -> Result<I64F64, ControlError> {
    a.checked_div(b).ok_or(ControlError::Overflow)
}

pub(crate) fn add(a: I64F64, b: I64F64) -> Result<I64F64, ControlError> {
    a.checked_add(b).ok_or(ControlError::Overflow)
}

pub(crate) fn sub(a: I64F64, b: I64F64) -> Result<I64F64, ControlError> {
    a.checked_sub(b).ok_or(ControlError::Overflow)
}

/// `v` as Q32 (I32F32 bits), rounded toward −∞.
pub(crate) fn to_q32(v: I64F64) -> Result<i64, ControlError> {
    i64::try_from(v.to_bits() >> 32).map_err(|_| ControlError::Overflow)
}

/// `v` as Q16 (I16F16 bits), rounded toward −∞.
pub(crate) fn to_q16(v: I64F64) -> Result<i32, ControlError> {
    i32::try_from(v.to_bits() >> 48).map_err(|_| ControlError::Overflow)
}

/// `v` as a per-tick [`Gain`].
pub(crate) fn to_gain(v: I64F64) -> Result<Gain, ControlError> {
    Gain::new(v).ok_or(ControlError::Overflow)
}
