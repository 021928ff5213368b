//! The bring-up messages: the raw sensor readings ([`Request::GetSensors`] →
//! [`Reply::Sensors`]) and the open-loop nudge ([`Request::Nudge`]), with which each sensor
//! and the motor's direction can be checked before the loop is closed (`vsa sensors`).

use serde::{Deserialize, Serialize};

use crate::msg::{ErrorCode, Reply, Request};

/// Largest |duty| of a nudge, ‰ of the supply (12 % of 12 V: 1.44 V on the motor).
pub const NUDGE_DUTY_MAX_PERMILLE: u16 = 120;

/// Longest nudge, ms.
pub const NUDGE_DURATION_MAX_MS: u16 = 1_000;

/// The raw readings of one control tick ([`Reply::Sensors`]), before any conversion: what
/// the drivers returned, so that wiring, direction and offsets can be checked by eye.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RawSensors {
    /// Control tick of the readings (1 kHz ticks since start: ms).
    pub tick: u32,
    /// Link encoder, counts (0..4096, relative to power-up).
    pub link_encoder: u16,
    /// Gear pot, counts (0..1024), if fitted.
    pub gear_pot: Option<u16>,
    /// Current ADC, raw 12-bit counts (mid-scale at 0 A for the expected sensor).
    pub current_adc: u16,
    /// Supply sense, raw 12-bit counts (5 mV of bridge supply a count), if the board has
    /// one and the read succeeded.
    pub supply_adc: Option<u16>,
    /// Open-loop duty applied in that tick by a nudge or the calibration sequence, ‰
    /// (0: none).
    pub nudge_duty_permille: i16,
}

/// Whether a nudge's fields are within their ranges: 1..=[`NUDGE_DUTY_MAX_PERMILLE`] ‰ in
/// magnitude, 1..=[`NUDGE_DURATION_MAX_MS`] ms.
#[must_use]
pub const fn nudge_ok(duty_permille: i16, duration_ms: u16) -> bool {
    let d = duty_permille.unsigned_abs();
    d != 0
        && d <= NUDGE_DUTY_MAX_PERMILLE
        && duration_ms != 0
        && duration_ms <= NUDGE_DURATION_MAX_MS
}

/// What the handler asks of the device for the bring-up requests (part of
/// [`crate::Device`]; both refused with [`ErrorCode::NotAllowed`] by a device without them).
pub(crate) fn dispatch<D: crate::Device + ?Sized>(
    req: Request,
    dev: &mut D,
) -> Result<Reply, ErrorCode> {
    match req {
        Request::GetSensors => dev.raw_sensors().map(Reply::Sensors),
        Request::Nudge {
            duty_permille,
            duration_ms,
        } => dev.nudge(duty_permille, duration_ms).map(|()| Reply::Ok),
        _ => Err(ErrorCode::UnknownMessage),
    }
}
