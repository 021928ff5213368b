//! The messages: requests (host → device), replies and telemetry (device → host).
//!
//! Variant order is the wire format (postcard encodes the variant index): append new
//! variants at the end and bump [`crate::VERSION`] for anything else.

use serde::{Deserialize, Serialize};

use crate::{
    CLUTCH_MAX_UM, CLUTCH_MIN_UM, CLUTCH_TOLERANCE_MAX_UM, CURRENT_LIMIT_MAX_MA,
    IMPEDANCE_DAMPING_MAX_UNMS_PER_RAD, IMPEDANCE_STIFFNESS_MIN_MNM_PER_RAD,
    IMPEDANCE_TORQUE_MAX_UNM, KD_MAX, KI_MAX, KP_MAX, MOTOR_TORQUE_LIMIT_MAX_UNM,
    MOVE_DURATION_MAX_MS, MOVE_DURATION_MIN_MS, SINE_AMPLITUDE_MAX_URAD, SINE_FREQUENCY_MAX_MHZ,
    SINE_FREQUENCY_MIN_MHZ, STIFFNESS_MIN_MNM_PER_RAD, TARGET_MAX_URAD, TELEMETRY_RATE_MAX_HZ,
    TELEMETRY_RATE_MIN_HZ,
};

/// A request from the host. Each one is answered by exactly one [`Reply`] with the same
/// `seq`: [`Reply::Ok`], [`Reply::Error`], or the data asked for.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Request {
    /// Liveness check. Reply: [`Reply::Ok`]. Touches nothing.
    Ping,
    /// Reply: [`Reply::Status`].
    GetStatus,
    /// Enable the motor (hold the current position). Refused with
    /// [`ErrorCode::NotAllowed`] while a fault is latched.
    Enable,
    /// Disable the motor (bridge off). Always allowed.
    Disable,
    /// Clear the latched faults (the motor stays disabled). Reply: [`Reply::Ok`], or
    /// [`Reply::FaultPersists`] (nothing cleared) while the condition of a fault still
    /// holds, e.g. the link is still outside the position window.
    ClearFault,
    /// The clutch now sits at active length `length_um` (the user moved it): reconfigure
    /// the controller for it.
    SetClutchLength {
        /// Active beam length L, µm, in [`CLUTCH_MIN_UM`]..=[`CLUTCH_MAX_UM`].
        length_um: u32,
    },
    /// Configure the controller for joint stiffness k. Reply: [`Reply::ClutchToSet`] with
    /// the clutch length L(k) of the model's inverse, which the user then sets by hand.
    SetStiffness {
        /// Joint stiffness k, mN·m/rad, ≥ [`STIFFNESS_MIN_MNM_PER_RAD`] (> 0). The paper
        /// preset spans 57 300 (L = 5 mm) to 7 167 500 (L = 1 mm).
        stiffness_mnm_per_rad: u32,
    },
    /// Minimum-jerk move of the link to an absolute angle.
    Move {
        /// Target link angle, µrad, |·| ≤ [`TARGET_MAX_URAD`] (2π rad).
        target_urad: i32,
        /// Duration, ms, in [`MOVE_DURATION_MIN_MS`]..=[`MOVE_DURATION_MAX_MS`] (1 ms–60 s).
        /// The board runs the move for longer where the current, voltage or beam limits
        /// do not allow it that fast (docs/design.md §11, "Moves within the limits").
        duration_ms: u32,
    },
    /// Step of the reference to an absolute link angle.
    Step {
        /// Target link angle, µrad, |·| ≤ [`TARGET_MAX_URAD`] (2π rad).
        target_urad: i32,
    },
    /// Sine reference about the link angle at the time of the command, until the next
    /// motion command or [`Request::Hold`].
    Sine {
        /// Amplitude, µrad, ≤ [`SINE_AMPLITUDE_MAX_URAD`] (1 rad).
        amplitude_urad: u32,
        /// Frequency, mHz, in [`SINE_FREQUENCY_MIN_MHZ`]..=[`SINE_FREQUENCY_MAX_MHZ`]
        /// (0.01–20 Hz).
        frequency_mhz: u32,
    },
    /// Stop any motion and hold the current reference.
    Hold,
    /// Override the automatic gain schedule with explicit PID gains.
    SetGains(Gains),
    /// Return to the automatic (stiffness-scheduled) gains.
    AutoGains,
    /// Set the live limits and the position limit.
    SetLimits(Limits),
    /// Stream [`Reply::Telemetry`] frames.
    StreamTelemetry {
        /// Samples per second: 0 = off, else [`TELEMETRY_RATE_MIN_HZ`]..=
        /// [`TELEMETRY_RATE_MAX_HZ`] (10–500 Hz).
        rate_hz: u16,
    },
    /// Arms the command timeout (the first one) and restarts it. Once armed, every
    /// well-formed request within its ranges restarts it too (link activity), so other traffic of the same
    /// host never starves it. Reply: [`Reply::Ok`].
    Heartbeat,
    /// Ends the heartbeat session: the command timeout is off until the next
    /// [`Request::Heartbeat`] (a session that armed it sends this when it ends; a latched
    /// `command-timeout` disarms it too). Reply: [`Reply::Ok`].
    DisarmHeartbeat,
    /// Reply: [`Reply::Limits`], the live limits and the position window in force.
    GetLimits,
    /// Reply: [`Reply::Sensors`], the raw readings of the last control tick (any state);
    /// [`ErrorCode::Busy`] before the first tick (no readings yet: ask again).
    GetSensors,
    /// Drive the motor open-loop at `duty_permille` for `duration_ms`, to check the motor's
    /// direction and the sensors before the loop is closed. Only while disabled (else
    /// [`ErrorCode::NotAllowed`]); ends by itself, on [`Request::Disable`], on enable and
    /// when a fault latches (the supervisor keeps checking). Reply: [`Reply::Ok`].
    Nudge {
        /// Duty, ‰ of the supply, 1 ≤ |·| ≤ [`crate::NUDGE_DUTY_MAX_PERMILLE`]; the sign is
        /// the direction (positive: the direction pin high).
        duty_permille: i16,
        /// How long, ms, 1..=[`crate::NUDGE_DURATION_MAX_MS`].
        duration_ms: u16,
    },
    /// Write the running configuration to the settings store (with the stored calibration
    /// and bus settings), atomically. Refused with [`ErrorCode::NotAllowed`] while the motor
    /// is enabled (programming the flash stalls the control loop on the real board);
    /// [`ErrorCode::Storage`] if the flash fails or the device has no store.
    Save,
    /// Re-read the settings store and apply what is stored and valid (defaults for the
    /// rest). [`ErrorCode::Storage`] if the device has no store.
    Load,
    /// Forget every stored record and the fault log, and go back to the defaults. Refused
    /// with [`ErrorCode::NotAllowed`] while the motor is enabled.
    FactoryReset,
    /// One entry of the stored fault log. Reply: [`Reply::FaultsLog`].
    FaultsLog {
        /// Which entry, 0 = the most recent; beyond the log's length the reply has none.
        index: u8,
    },
    /// Hold the link at `target_urad` as a spring-damper: virtual stiffness, virtual
    /// damping and a feed-forward torque (the link first moves to the target, then the
    /// coupling torque follows k_v·(θ_t − θ) − d_v·θ̇ + τ_ff), until the next motion
    /// command or [`Request::Hold`]. The device refuses a stiffness above the beams' at
    /// the clutch setting with [`ErrorCode::OutOfRange`].
    Impedance {
        /// Target link angle θ_t, µrad, |·| ≤ [`TARGET_MAX_URAD`].
        target_urad: i32,
        /// Virtual stiffness k_v, mN·m/rad, ≥ [`IMPEDANCE_STIFFNESS_MIN_MNM_PER_RAD`] and
        /// at most the joint stiffness at the clutch setting (the device's check).
        stiffness_mnm_per_rad: u32,
        /// Virtual damping d_v, µN·m·s/rad, ≤ [`IMPEDANCE_DAMPING_MAX_UNMS_PER_RAD`].
        damping_unms_per_rad: u32,
        /// Feed-forward torque τ_ff, µN·m, |·| ≤ [`IMPEDANCE_TORQUE_MAX_UNM`].
        torque_unm: i32,
    },
    /// Change the Dynamixel bus settings (protocol, ID, line rate; `vsa bus`). They take
    /// effect after the reply and are stored (once the motor is off: programming the flash
    /// stalls the control loop). Reply: [`Reply::Ok`]; [`ErrorCode::OutOfRange`] for
    /// settings the device's control table or UART cannot take, [`ErrorCode::NotAllowed`]
    /// on a device without a bus, [`ErrorCode::Storage`] if they could not be stored (in
    /// force until the next boot all the same).
    SetBus(crate::bus::BusChange),
    /// Start (`start: true`) the calibration sequence of a real build (docs/calibration.md)
    /// from the disabled state, or stop it (`false`: the motor off). Refused with
    /// [`ErrorCode::NotAllowed`] unless disabled with no fault latched; progress in
    /// [`Status::calibration`], the result by [`Request::GetCalibration`]. Reply:
    /// [`Reply::Ok`].
    Calibrate {
        /// Start (`true`) or stop (`false`).
        start: bool,
    },
    /// Reply: [`Reply::Calibration`].
    GetCalibration,
}

/// PID gains, each in 10⁻³ of the controller's unit (duty ‰ out, link angle in rad), so
/// 1000 = 1 ‰/rad. Unsigned: gains are non-negative.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Gains {
    /// Proportional, 10⁻³ ‰/rad, ≤ [`KP_MAX`] (10⁶ ‰/rad).
    pub kp: u64,
    /// Integral, 10⁻³ ‰/(rad·s), ≤ [`KI_MAX`] (10⁷ ‰/(rad·s)).
    pub ki: u64,
    /// Derivative, 10⁻³ ‰·s/rad, ≤ [`KD_MAX`] (10⁴ ‰·s/rad).
    pub kd: u64,
}

/// Live limits (clamps) and the position limit (a latched fault when crossed).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Limits {
    /// Fraction of the beams' stress-limited capacity τ_cap(L) the coupling torque may
    /// use, ‰, 1..=1000.
    pub torque_margin_permille: u16,
    /// Motor current limit, mA, 1..=[`CURRENT_LIMIT_MAX_MA`].
    pub current_ma: u16,
    /// Motor torque limit at the output, µN·m, 1..=[`MOTOR_TORQUE_LIMIT_MAX_UNM`].
    pub motor_torque_unm: u32,
    /// Largest |PWM duty|, ‰, 1..=1000.
    pub duty_permille: u16,
    /// Lower position limit of the link, µrad, |·| ≤ [`TARGET_MAX_URAD`], < the upper one.
    pub position_min_urad: i32,
    /// Upper position limit of the link, µrad, |·| ≤ [`TARGET_MAX_URAD`].
    pub position_max_urad: i32,
    /// How much longer than configured the hand-set clutch may be, µm,
    /// 0..=[`CLUTCH_TOLERANCE_MAX_UM`]: the torque limit and the overload check use the
    /// beams' capacity at that length (`model::control::Limits::clutch_tolerance`).
    pub clutch_tolerance_um: u16,
}

impl Limits {
    /// Defaults of the controller and the supervisor: margin 850 ‰, 1.5 A, 1.5 N·m (AX-12A
    /// stall), full duty, position window ±2.5 rad, no clutch tolerance.
    pub const DEFAULT: Limits = Limits {
        torque_margin_permille: 850,
        current_ma: 1_500,
        motor_torque_unm: 1_500_000,
        duty_permille: 1_000,
        position_min_urad: -2_500_000,
        position_max_urad: 2_500_000,
        clutch_tolerance_um: 0,
    };
}

impl Default for Limits {
    fn default() -> Self {
        Self::DEFAULT
    }
}

fn target_ok(target_urad: i32) -> bool {
    target_urad.unsigned_abs() <= TARGET_MAX_URAD
}

impl Gains {
    /// Whether every gain is within its bound.
    #[must_use]
    pub const fn is_valid(&self) -> bool {
        self.kp <= KP_MAX && self.ki <= KI_MAX && self.kd <= KD_MAX
    }
}

impl Limits {
    /// Whether every field is within its range and min < max.
    #[must_use]
    pub fn is_valid(&self) -> bool {
        (1..=1000).contains(&self.torque_margin_permille)
            && (1..=CURRENT_LIMIT_MAX_MA).contains(&self.current_ma)
            && (1..=MOTOR_TORQUE_LIMIT_MAX_UNM).contains(&self.motor_torque_unm)
            && (1..=1000).contains(&self.duty_permille)
            && target_ok(self.position_min_urad)
            && target_ok(self.position_max_urad)
            && self.position_min_urad < self.position_max_urad
            && self.clutch_tolerance_um <= CLUTCH_TOLERANCE_MAX_UM
    }
}

impl Request {
    /// Checks every field against its documented range.
    ///
    /// # Errors
    /// [`ErrorCode::OutOfRange`] when a field is outside its range.
    pub fn validate(&self) -> Result<(), ErrorCode> {
        let ok = match *self {
            Request::Ping
            | Request::GetStatus
            | Request::Enable
            | Request::Disable
            | Request::ClearFault
            | Request::Hold
            | Request::AutoGains
            | Request::Heartbeat
            | Request::DisarmHeartbeat
            | Request::GetLimits
            | Request::Save
            | Request::Load
            | Request::FactoryReset
            | Request::FaultsLog { .. }
            | Request::Calibrate { .. }
            | Request::GetCalibration => true,
            Request::SetClutchLength { length_um } => {
                (CLUTCH_MIN_UM..=CLUTCH_MAX_UM).contains(&length_um)
            }
            Request::SetStiffness {
                stiffness_mnm_per_rad,
            } => stiffness_mnm_per_rad >= STIFFNESS_MIN_MNM_PER_RAD,
            Request::Move {
                target_urad,
                duration_ms,
            } => {
                target_ok(target_urad)
                    && (MOVE_DURATION_MIN_MS..=MOVE_DURATION_MAX_MS).contains(&duration_ms)
            }
            Request::Step { target_urad } => target_ok(target_urad),
            Request::Sine {
                amplitude_urad,
                frequency_mhz,
            } => {
                amplitude_urad <= SINE_AMPLITUDE_MAX_URAD
                    && (SINE_FREQUENCY_MIN_MHZ..=SINE_FREQUENCY_MAX_MHZ).contains(&frequency_mhz)
            }
            Request::SetGains(g) => g.is_valid(),
            Request::SetLimits(l) => l.is_valid(),
            Request::StreamTelemetry { rate_hz } => {
                rate_hz == 0 || (TELEMETRY_RATE_MIN_HZ..=TELEMETRY_RATE_MAX_HZ).contains(&rate_hz)
            }
            Request::GetSensors => true,
            Request::Nudge {
                duty_permille,
                duration_ms,
            } => crate::sensors::nudge_ok(duty_permille, duration_ms),
            Request::Impedance {
                target_urad,
                stiffness_mnm_per_rad,
                damping_unms_per_rad,
                torque_unm,
            } => {
                target_ok(target_urad)
                    && stiffness_mnm_per_rad >= IMPEDANCE_STIFFNESS_MIN_MNM_PER_RAD
                    && damping_unms_per_rad <= IMPEDANCE_DAMPING_MAX_UNMS_PER_RAD
                    && torque_unm.unsigned_abs() <= IMPEDANCE_TORQUE_MAX_UNM
            }
            Request::SetBus(change) => change.is_valid(),
        };
        if ok {
            Ok(())
        } else {
            Err(ErrorCode::OutOfRange)
        }
    }
}

/// Why a request was refused ([`Reply::Error`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum ErrorCode {
    /// The frame did not decode: bad COBS, too short, too long, or a body postcard rejects.
    BadFrame,
    /// The frame's CRC-32 did not match.
    BadCrc,
    /// The frame decoded but its message index is not a request this version knows.
    UnknownMessage,
    /// A field is outside its documented range ([`Request::validate`], or the device's
    /// own check, e.g. a stiffness whose clutch length is outside the design's range, or a
    /// motion target outside the position window in force, [`Request::GetLimits`]).
    OutOfRange,
    /// Not allowed in the current state (e.g. enable or move while a fault is latched).
    NotAllowed,
    /// The device cannot take the request now (e.g. reconfiguring during a motion).
    Busy,
    /// The frame's version is not [`crate::VERSION`].
    UnsupportedVersion,
    /// The settings store failed (a flash error), or the device has none.
    Storage,
}

impl core::fmt::Display for ErrorCode {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            ErrorCode::BadFrame => "bad frame",
            ErrorCode::BadCrc => "bad CRC",
            ErrorCode::UnknownMessage => "unknown message",
            ErrorCode::OutOfRange => "value out of range",
            ErrorCode::NotAllowed => "not allowed in this state",
            ErrorCode::Busy => "busy",
            ErrorCode::UnsupportedVersion => "unsupported protocol version",
            ErrorCode::Storage => "settings store failed or absent",
        })
    }
}

impl core::error::Error for ErrorCode {}

/// A message from the device.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Reply {
    /// The request was carried out.
    Ok,
    /// The request was refused (nothing changed), or the frame was bad.
    Error(ErrorCode),
    /// Reply to [`Request::GetStatus`].
    Status(Status),
    /// Reply to [`Request::SetStiffness`]: the controller is configured for the stiffness;
    /// set the clutch to this length.
    ClutchToSet {
        /// Active beam length L(k) from the model's inverse, µm.
        length_um: u32,
    },
    /// One telemetry sample, sent unsolicited while streaming. The frame's `seq` is a
    /// wrapping counter of the samples taken, dropped ones included, so a gap in `seq` is
    /// the number of samples the device dropped because the link was slow.
    Telemetry(TelemetrySample),
    /// Reply to [`Request::GetLimits`].
    Limits(Limits),
    /// Reply to [`Request::ClearFault`] when the condition of a latched fault still holds
    /// (nothing was cleared): the fault, its value now (unit per [`FaultCode`]) and the
    /// tick it was last seen at.
    FaultPersists(FaultRecord),
    /// Reply to [`Request::GetSensors`].
    Sensors(crate::RawSensors),
    /// Reply to [`Request::FaultsLog`]: how many faults the stored log holds, and the one
    /// asked for if it exists.
    FaultsLog {
        /// Entries in the log (at most 16).
        count: u8,
        /// The entry asked for.
        entry: Option<LoggedFault>,
    },
    /// Reply to [`Request::GetCalibration`].
    Calibration(crate::CalibrationReport),
}

/// A latched fault as the settings store's fault log keeps it (it survives resets).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LoggedFault {
    /// Number of the fault since the log was last cleared (factory reset).
    pub seq: u32,
    /// The fault; its `tick` is the uptime at which it latched, ms since that boot.
    pub fault: FaultRecord,
}

/// Operating state.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum State {
    /// Motor off, no fault latched.
    #[default]
    Disabled,
    /// Motor on, position loop running.
    Enabled,
    /// A fault is latched: motor off until [`Request::ClearFault`].
    Faulted,
}

pub use fault::{FaultCode, FaultSet};

/// The first fault latched since the last clear.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FaultRecord {
    /// Which fault.
    pub code: FaultCode,
    /// The offending value, in the unit documented on the [`FaultCode`].
    pub value: i32,
    /// Control tick at which it latched (1 kHz ticks since start: ms).
    pub tick: u32,
}

/// Live limits active (clamps, not faults), one bit each.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LimitFlags(pub u8);

impl LimitFlags {
    /// No limit active.
    pub const NONE: LimitFlags = LimitFlags(0);
    /// The coupling torque is limited to margin·τ_cap(L).
    pub const TORQUE: u8 = 1 << 0;
    /// The motor current (or motor torque) limit clamps the output.
    pub const CURRENT: u8 = 1 << 1;
    /// The duty is clamped at its limit.
    pub const DUTY: u8 = 1 << 2;

    /// Whether any of the bits in `mask` is set.
    #[must_use]
    pub const fn any(self, mask: u8) -> bool {
        self.0 & mask != 0
    }
}

/// Reply to [`Request::GetStatus`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Status {
    /// Operating state.
    pub state: State,
    /// Latched faults.
    pub faults: FaultSet,
    /// The first fault latched since the last clear, if any.
    pub first_fault: Option<FaultRecord>,
    /// Live limits active in the last tick.
    pub limits: LimitFlags,
    /// Configured clutch length, µm.
    pub clutch_length_um: u32,
    /// Configured joint stiffness k(L), mN·m/rad.
    pub stiffness_mnm_per_rad: u32,
    /// How much longer than configured the clutch is taken to be, µm: the configured
    /// tolerance ([`Limits::clutch_tolerance_um`]), or more until a calibration has
    /// confirmed the clutch (docs/calibration.md, "Until the clutch is confirmed").
    pub clutch_tolerance_um: u16,
    /// Control tick (1 kHz ticks since start: ms).
    pub tick: u32,
    /// A motion (move, step transient, sine) is running.
    pub moving: bool,
    /// Telemetry rate, Hz (0 = off).
    pub telemetry_rate_hz: u16,
    /// Telemetry samples dropped because the link was slow, since boot.
    pub telemetry_dropped: u32,
    /// Protocol errors since boot ([`crate::ErrorCounters::total`]); filled in by the
    /// [`crate::Handler`], whatever the device reports.
    pub protocol_errors: u32,
    /// The running configuration differs from the one in the settings store (or, with
    /// nothing stored, from the defaults): `save` would change what the next boot loads.
    /// `false` on a device without a store.
    pub differs_from_stored: bool,
    /// Where the calibration sequence is ([`Request::Calibrate`]).
    pub calibration: crate::CalibrationProgress,
}

/// One telemetry sample (taken at a control tick).
///
/// Encoded size: at most 35 bytes ([`crate::MAX_TELEMETRY_BODY`] − 1); 20–28 bytes for
/// typical values.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TelemetrySample {
    /// Control tick (1 kHz ticks since start: ms).
    pub tick: u32,
    /// Link-angle reference of the controller, µrad.
    pub reference_urad: i32,
    /// Measured link angle (output shaft), µrad, unwrapped.
    pub link_angle_urad: i32,
    /// Measured gear angle (output gear, before the beams), µrad.
    pub gear_angle_urad: i32,
    /// Motor current, mA.
    pub current_ma: i16,
    /// Estimated coupling torque on the link, µN·m.
    pub torque_unm: i32,
    /// PWM duty applied, ‰ (±1000 = ± the supply).
    pub duty_permille: i16,
    /// Latched faults.
    pub faults: FaultSet,
    /// Live limits active.
    pub limits: LimitFlags,
}
