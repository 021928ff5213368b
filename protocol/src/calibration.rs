//! The calibration messages: start or stop the calibration sequence of a real build
//! ([`Request::Calibrate`]), its progress (in [`crate::Status`] and in the report) and its
//! result ([`Request::GetCalibration`] → [`Reply::Calibration`]). The sequence itself is the
//! device's (docs/calibration.md); the result has the settings store's record format
//! ([`Calibration`], stored as it is sent).

use serde::{Deserialize, Serialize};

use crate::msg::{ErrorCode, Reply, Request};

/// Where the calibration sequence is (part of [`crate::Status`] and of the report).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum CalibrationProgress {
    /// Not run since boot.
    #[default]
    Idle,
    /// Running (the motor is driven by the sequence, the servo disabled).
    Running {
        /// Phase, 1-based (1 rest, 2 nudge, 3 moves, 4 last move, 5 done).
        phase: u8,
        /// Percent of the whole sequence, 0..=99.
        percent: u8,
    },
    /// The last run succeeded: its result is in force and stored.
    Done,
    /// The last run stopped with the motor off: the failure's code (the device's list of
    /// failures, `model::calibration::sequence::Failure::code`: name and message).
    Failed {
        /// Failure code.
        failure: u8,
    },
}

/// The calibration of a real build (the result of the calibration sequence) in integer
/// units, as the settings store keeps it (`store::Calibration`, whose checks it must pass).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Calibration {
    /// Motor polarity, ±1 (−1: the bridge's sense is reversed in software).
    pub motor_polarity: i8,
    /// Link encoder direction, ±1.
    pub encoder_direction: i8,
    /// Gear potentiometer direction, ±1.
    pub pot_direction: i8,
    /// Current-sense offset from mid-scale, ADC counts.
    pub current_offset_counts: i16,
    /// Pot-to-encoder alignment offset, pot counts (its electrical centre is the zero).
    pub pot_offset_counts: i16,
    /// Motor winding resistance as the current sense sees it, mΩ, > 0.
    pub resistance_mohm: u32,
    /// Back-EMF constant at the output, µV·s/rad, > 0.
    pub back_emf_uv_s_per_rad: u32,
    /// Gear friction torque at the output, µN·m.
    pub gear_friction_unm: u32,
    /// Link inertia, kg·mm² (1e-3 kg·m² = 1000).
    pub link_inertia_kg_mm2: u32,
    /// Identified joint stiffness, mN·m/rad; `None` where the sensors cannot resolve it.
    pub stiffness_mnm_per_rad: Option<u32>,
    /// Clutch length from that stiffness, µm; `None` where the stiffness is not resolved.
    pub clutch_length_um: Option<u32>,
    /// Relative 1-σ uncertainty of the stiffness, ‰, ≤ 1000.
    pub stiffness_uncertainty_permille: u16,
}

/// Reply to [`Request::GetCalibration`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CalibrationReport {
    /// Where the sequence is.
    pub progress: CalibrationProgress,
    /// The calibration in force (the last successful run's, or the stored one), if any.
    pub calibration: Option<Calibration>,
    /// The armature resistance the controller works with instead of the calibration's, ‰
    /// of the calibration's: what a held link under load showed since (the motor warmed or
    /// cooled, docs/design.md §11, "Tracking a warm motor's resistance"); `None` while the
    /// calibration's is in force. A ratio, not mΩ, so that the report fits the largest
    /// reply. Not stored: the next boot starts from the calibration's.
    pub tracked_resistance_permille: Option<u16>,
}

/// What the handler asks of the device for the calibration requests (part of
/// [`crate::Device`]; refused with [`ErrorCode::NotAllowed`] by a device without them).
pub(crate) fn dispatch<D: crate::Device + ?Sized>(
    req: Request,
    dev: &mut D,
) -> Result<Reply, ErrorCode> {
    match req {
        Request::Calibrate { start } => dev.calibrate(start).map(|()| Reply::Ok),
        Request::GetCalibration => dev.calibration().map(Reply::Calibration),
        _ => Err(ErrorCode::UnknownMessage),
    }
}
