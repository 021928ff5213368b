//! The records: what each holds, in which unit, its schema version, its range checks, and
//! how its stored bytes become a value again (or a [`Rejection`] saying why not).
//!
//! A stored record is `[version: u8] ++ postcard(fields)`. postcard is not self-describing,
//! so the version byte is read first and picks the layout; a version this firmware has no
//! layout for is rejected, never decoded as the current one.

use dynamixel::{Field, Protocol};
use model::calibration::pot_error::{MAX_ERROR_CENTI, POT_ERROR_BINS};
use protocol::{FaultRecord, Gains, Limits, Request, CLUTCH_MAX_UM, CLUTCH_MIN_UM};
use serde::{de::DeserializeOwned, Deserialize, Serialize};

/// Why a stored record was not applied (the defaults are used instead).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum Rejection {
    /// The bytes do not decode as the layout of their version.
    Undecodable,
    /// Written with a schema version this firmware has no layout or migration for.
    UnknownVersion {
        /// The version found in flash.
        found: u8,
        /// The version this firmware writes.
        current: u8,
    },
    /// Decoded, but a field fails the checks (the same as over the wire): which and why.
    Invalid(&'static str),
    /// The flash could not be read.
    Flash(crate::FlashFault),
}

impl core::fmt::Display for Rejection {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Rejection::Undecodable => f.write_str("does not decode"),
            Rejection::UnknownVersion { found, current } => {
                write!(
                    f,
                    "schema version {found} unknown (this firmware: {current})"
                )
            }
            Rejection::Invalid(why) => f.write_str(why),
            Rejection::Flash(e) => write!(f, "flash: {e}"),
        }
    }
}

/// A record of the set: a name for the boot log, a schema version, and the decoding of
/// every version this firmware knows.
///
/// When a layout changes: keep the old struct (e.g. `ConfigV1`), bump [`Record::VERSION`],
/// and make [`Record::migrate`] decode the old layout and convert it, checked like any
/// other value afterwards. The calibration and the configuration are at version 2
/// (version 1 migrates), the bus settings at version 2 (version 1 is rejected), the fault
/// entries at version 1.
pub trait Record: Serialize + DeserializeOwned {
    /// Name in the boot log and in errors.
    const NAME: &'static str;
    /// Schema version this firmware writes.
    const VERSION: u8;

    /// Decodes a body written with an older or unknown `version`.
    ///
    /// # Errors
    /// [`Rejection::UnknownVersion`] unless a migration exists for `version`.
    fn migrate(version: u8, _body: &[u8]) -> Result<Self, Rejection> {
        Err(Rejection::UnknownVersion {
            found: version,
            current: Self::VERSION,
        })
    }

    /// The range checks of the fields that do not need the device (see the type's docs).
    ///
    /// # Errors
    /// The first failing check, as a short phrase for the log.
    fn check(&self) -> Result<(), &'static str>;
}

/// Encodes `record` as `[version] ++ postcard` into `buf`; the bytes written.
pub(crate) fn encode<R: Record>(record: &R, buf: &mut [u8]) -> Result<usize, postcard::Error> {
    let (head, body) = buf
        .split_first_mut()
        .ok_or(postcard::Error::SerializeBufferFull)?;
    *head = R::VERSION;
    Ok(1 + postcard::to_slice(record, body)?.len())
}

/// Decodes stored bytes: the current version directly, any other through
/// [`Record::migrate`]. Trailing bytes make it [`Rejection::Undecodable`].
pub(crate) fn decode<R: Record>(bytes: &[u8]) -> Result<R, Rejection> {
    let (&version, body) = bytes.split_first().ok_or(Rejection::Undecodable)?;
    if version != R::VERSION {
        return R::migrate(version, body);
    }
    whole(body)
}

/// `body` as one `T` with nothing after it.
fn whole<T: DeserializeOwned>(body: &[u8]) -> Result<T, Rejection> {
    match postcard::take_from_bytes::<T>(body) {
        Ok((value, [])) => Ok(value),
        _ => Err(Rejection::Undecodable),
    }
}

/// For a [`Record::migrate`] that knows version 1 only: `body` decoded as version 1's
/// layout `T`, or why not.
fn version_1<R: Record, T: DeserializeOwned>(version: u8, body: &[u8]) -> Result<T, Rejection> {
    if version != 1 {
        return Err(Rejection::UnknownVersion {
            found: version,
            current: R::VERSION,
        });
    }
    whole(body)
}

/// How the clutch was configured: the protocol's two requests for it, in their units.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Clutch {
    /// [`Request::SetClutchLength`]: active beam length L, µm, in
    /// [`CLUTCH_MIN_UM`]..=[`CLUTCH_MAX_UM`].
    LengthUm(u32),
    /// [`Request::SetStiffness`]: joint stiffness k, mN·m/rad (L(k) is recomputed at boot).
    StiffnessMnmPerRad(u32),
}

/// The active configuration: what the host set over the protocol, in the protocol's units.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Config {
    /// Clutch length or stiffness.
    pub clutch: Clutch,
    /// Link inertia about the output axis, kg·mm² (the controller's unit: 1000 =
    /// 1e-3 kg·m²), in [`model::control::MIN_INERTIA`]..=
    /// [`model::control::MAX_INERTIA`].
    pub link_inertia_kg_mm2: u32,
    /// PID gains ([`Request::SetGains`]); `None` = the automatic schedule
    /// ([`Request::AutoGains`]).
    pub gains: Option<Gains>,
    /// Live limits and the position window ([`Request::SetLimits`]).
    pub limits: Limits,
    /// Heartbeat (command) timeout, ms, ≥ 1 (the supervisor's `command_timeout_ms`).
    pub command_timeout_ms: u32,
}

/// [`Config`] as version 1 stored it: [`Limits`] without the clutch tolerance.
#[derive(Deserialize)]
struct ConfigV1 {
    clutch: Clutch,
    link_inertia_kg_mm2: u32,
    gains: Option<Gains>,
    limits: LimitsV1,
    command_timeout_ms: u32,
}

/// [`Limits`] before the clutch tolerance.
#[derive(Deserialize)]
struct LimitsV1 {
    torque_margin_permille: u16,
    current_ma: u16,
    motor_torque_unm: u32,
    duty_permille: u16,
    position_min_urad: i32,
    position_max_urad: i32,
}

impl Record for Config {
    const NAME: &'static str = "config";
    const VERSION: u8 = 2;

    /// Version 1 lacked the clutch tolerance: none (0 µm, the default).
    fn migrate(version: u8, body: &[u8]) -> Result<Self, Rejection> {
        let v1: ConfigV1 = version_1::<Self, _>(version, body)?;
        let l = v1.limits;
        Ok(Config {
            clutch: v1.clutch,
            link_inertia_kg_mm2: v1.link_inertia_kg_mm2,
            gains: v1.gains,
            limits: Limits {
                torque_margin_permille: l.torque_margin_permille,
                current_ma: l.current_ma,
                motor_torque_unm: l.motor_torque_unm,
                duty_permille: l.duty_permille,
                position_min_urad: l.position_min_urad,
                position_max_urad: l.position_max_urad,
                clutch_tolerance_um: 0,
            },
            command_timeout_ms: v1.command_timeout_ms,
        })
    }

    /// The checks of [`Request::validate`] on the equivalent requests, the controller's
    /// inertia range and the supervisor's timeout ≥ 1. Whether the design reaches the
    /// clutch length or stiffness is the device's check (the firmware's validator).
    fn check(&self) -> Result<(), &'static str> {
        let clutch = match self.clutch {
            Clutch::LengthUm(length_um) => Request::SetClutchLength { length_um },
            Clutch::StiffnessMnmPerRad(stiffness_mnm_per_rad) => Request::SetStiffness {
                stiffness_mnm_per_rad,
            },
        };
        if clutch.validate().is_err() {
            return Err("clutch length or stiffness out of range");
        }
        let inertia = model::control::MIN_INERTIA..=model::control::MAX_INERTIA;
        if !i32::try_from(self.link_inertia_kg_mm2).is_ok_and(|j| inertia.contains(&j)) {
            return Err("link inertia outside 1..=1000000 kg·mm²");
        }
        if self.gains.is_some_and(|g| !g.is_valid()) {
            return Err("gain above its bound");
        }
        if !self.limits.is_valid() {
            return Err("limits out of range or position window empty");
        }
        if self.command_timeout_ms == 0 {
            return Err("command timeout 0 ms");
        }
        Ok(())
    }
}

/// The calibration of a real build (the result of the calibration sequence), in integer
/// units of the protocol's kind.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Calibration {
    /// What the host link reports ([`protocol::Calibration`]: signs, offsets, the motor
    /// and link parameters, the stiffness); the fields below stay on the board. Postcard
    /// writes a nested struct as its fields in order: the stored layout is version 1's
    /// fields followed by version 2's, so a change of `protocol::Calibration` is a new
    /// version of this record.
    pub wire: protocol::Calibration,
    /// Link encoder counts per turn, 16..=16384 (the timer's count per turn: 4 per pulse
    /// of an incremental output, e.g. 4000 for an AS5047P's factory 1000 pulses).
    pub encoder_counts_per_turn: u16,
    /// Pot slope relative to the nominal 1024 counts per 300°, ppm, in
    /// [`GAIN_MIN_PPM`]..=[`GAIN_MAX_PPM`].
    pub pot_gain_ppm: u32,
    /// Current-sense slope relative to the nominal 1024 counts/A, ppm, in
    /// [`GAIN_MIN_PPM`]..=[`GAIN_MAX_PPM`].
    pub current_gain_ppm: u32,
    /// The pot's measured error bound per sixteenth of its track
    /// (`model::calibration::pot_error`), pot counts × 100, each ≤ 5000; `None`: not
    /// measured (the supervisor's fixed pot tolerance applies).
    pub pot_error_centi: Option<[u16; POT_ERROR_BINS]>,
}

/// Lowest pot or current-sense gain, ppm (0.5).
pub const GAIN_MIN_PPM: u32 = 500_000;
/// Highest pot or current-sense gain, ppm (2).
pub const GAIN_MAX_PPM: u32 = 2_000_000;
/// One, ppm: the gain of a nominal sensor.
pub const GAIN_ONE_PPM: u32 = 1_000_000;

/// Largest |current-sense offset|, ADC counts: half the 12-bit scale.
pub const CURRENT_OFFSET_MAX: i16 = model::sensors::ADC_MID as i16;
/// Largest |pot offset|, pot counts: half the pot's 1024 counts.
pub const POT_OFFSET_MAX: i16 = (model::sensors::POT_COUNTS / 2) as i16;

impl Record for Calibration {
    const NAME: &'static str = "calibration";
    const VERSION: u8 = 2;

    /// Version 1 lacked the encoder's counts per turn, the gains and the pot's error
    /// table: those of the nominal build (4096 counts, unit gains, no table).
    fn migrate(version: u8, body: &[u8]) -> Result<Self, Rejection> {
        // Version 1 wrote exactly the host link's fields.
        let v1: protocol::Calibration = version_1::<Self, _>(version, body)?;
        Ok(Calibration {
            wire: v1,
            encoder_counts_per_turn: model::sensors::ENCODER_COUNTS,
            pot_gain_ppm: GAIN_ONE_PPM,
            current_gain_ppm: GAIN_ONE_PPM,
            pot_error_centi: None,
        })
    }

    fn check(&self) -> Result<(), &'static str> {
        let sign = |s: i8| s == 1 || s == -1;
        if !(sign(self.wire.motor_polarity)
            && sign(self.wire.encoder_direction)
            && sign(self.wire.pot_direction))
        {
            return Err("polarity or direction not ±1");
        }
        if self.wire.current_offset_counts.unsigned_abs() > CURRENT_OFFSET_MAX.unsigned_abs()
            || self.wire.pot_offset_counts.unsigned_abs() > POT_OFFSET_MAX.unsigned_abs()
        {
            return Err("sensor offset beyond half scale");
        }
        if self.wire.resistance_mohm == 0 || self.wire.back_emf_uv_s_per_rad == 0 {
            return Err("resistance or back-EMF constant 0");
        }
        let inertia = model::control::MIN_INERTIA..=model::control::MAX_INERTIA;
        if !i32::try_from(self.wire.link_inertia_kg_mm2).is_ok_and(|j| inertia.contains(&j)) {
            return Err("link inertia outside 1..=1000000 kg·mm²");
        }
        if self.wire.stiffness_mnm_per_rad == Some(0) {
            return Err("stiffness 0");
        }
        if self
            .wire
            .clutch_length_um
            .is_some_and(|l| !(CLUTCH_MIN_UM..=CLUTCH_MAX_UM).contains(&l))
        {
            return Err("clutch length out of range");
        }
        if self.wire.stiffness_uncertainty_permille > 1000 {
            return Err("stiffness uncertainty above 1000 ‰");
        }
        if !(16..=16384).contains(&self.encoder_counts_per_turn) {
            return Err("encoder counts per turn outside 16..=16384");
        }
        let gains = GAIN_MIN_PPM..=GAIN_MAX_PPM;
        if !gains.contains(&self.pot_gain_ppm) || !gains.contains(&self.current_gain_ppm) {
            return Err("pot or current gain outside 0.5..=2");
        }
        if self
            .pot_error_centi
            .is_some_and(|t| t.iter().any(|&e| e > MAX_ERROR_CENTI))
        {
            return Err("pot error above 50 counts");
        }
        Ok(())
    }
}

/// Identity and settings on a Dynamixel bus, as the EEPROM area of the control table keeps
/// them (the baud rate in bit/s rather than the register's protocol-dependent code). Ranges
/// and defaults are the control table's ([`dynamixel::table`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct BusSettings {
    /// Bus ID (AX table: 0..=253; X table: 0..=252).
    pub id: u8,
    /// Baud rate, bit/s: one the protocol's Baud Rate register can select
    /// (2 000 000 / (v + 1) for protocol 1, [`dynamixel::table::X_BAUD_BPS`] for 2).
    pub baud_bps: u32,
    /// Dynamixel protocol version, 1 or 2.
    pub protocol_version: u8,
    /// Return delay, units of 2 µs (250 = 500 µs).
    pub return_delay_2us: u8,
    /// Status return level, 0 (ping only), 1 (ping and read), 2 (all).
    pub status_return_level: u8,
    /// Clockwise angle limit, AX position units (0..=1023 over 300°, 0.29° each).
    pub cw_angle_limit: u16,
    /// Counter-clockwise angle limit, AX position units, ≥ the clockwise one (both 0:
    /// wheel mode).
    pub ccw_angle_limit: u16,
    /// The rest of the EEPROM area, in the registers' own units (AX table, and the X
    /// table for the position and velocity limits).
    pub limits: BusLimits,
}

/// The EEPROM-area registers that limit and alarm, stored with the bus settings. Each is
/// checked against its register's range (the AX-12A's where both tables have it: the
/// register is one whichever protocol wrote it).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct BusLimits {
    /// Max Torque (AX 14), 0–1023 (0.1 % of the torque capacity).
    pub max_torque: u16,
    /// Temperature Limit (AX 11 / X 31), °C.
    pub temperature_limit: u8,
    /// Min Voltage Limit (AX 12 / X 34), 0.1 V.
    pub min_voltage_limit: u8,
    /// Max Voltage Limit (AX 13 / X 32), 0.1 V.
    pub max_voltage_limit: u8,
    /// Alarm LED (AX 17), error-bit mask.
    pub alarm_led: u8,
    /// Shutdown (AX 18 / X 63), error-bit mask.
    pub shutdown: u8,
    /// Velocity Limit (X 44), 0.229 rpm.
    pub velocity_limit: u16,
    /// Min Position Limit (X 52), X position units (4096 per turn).
    pub min_position_limit: u16,
    /// Max Position Limit (X 48), X position units.
    pub max_position_limit: u16,
}

impl BusLimits {
    /// Each register's field, and its value here (the one list the defaults, the check
    /// and the bus device's conversions go through).
    #[must_use]
    pub fn fields(&self) -> [(Field, i32); 9] {
        [
            (Field::MaxTorque, i32::from(self.max_torque)),
            (Field::TemperatureLimit, i32::from(self.temperature_limit)),
            (Field::MinVoltageLimit, i32::from(self.min_voltage_limit)),
            (Field::MaxVoltageLimit, i32::from(self.max_voltage_limit)),
            (Field::AlarmLed, i32::from(self.alarm_led)),
            (Field::Shutdown, i32::from(self.shutdown)),
            (Field::VelocityLimit, i32::from(self.velocity_limit)),
            (Field::MinPositionLimit, i32::from(self.min_position_limit)),
            (Field::MaxPositionLimit, i32::from(self.max_position_limit)),
        ]
    }

    /// The limits from `value`, each field's value (out-of-range values saturate, and
    /// then fail [`Record::check`]).
    #[must_use]
    pub fn from_fields(value: impl Fn(Field) -> i32) -> BusLimits {
        let byte = |f| u8::try_from(value(f)).unwrap_or(u8::MAX);
        let word = |f| u16::try_from(value(f)).unwrap_or(u16::MAX);
        BusLimits {
            max_torque: word(Field::MaxTorque),
            temperature_limit: byte(Field::TemperatureLimit),
            min_voltage_limit: byte(Field::MinVoltageLimit),
            max_voltage_limit: byte(Field::MaxVoltageLimit),
            alarm_led: byte(Field::AlarmLed),
            shutdown: byte(Field::Shutdown),
            velocity_limit: word(Field::VelocityLimit),
            min_position_limit: word(Field::MinPositionLimit),
            max_position_limit: word(Field::MaxPositionLimit),
        }
    }

    /// The register of `field`: the AX-12A table's, else the X series'.
    fn register(field: Field) -> Option<dynamixel::Register> {
        Protocol::V1
            .table()
            .register(field)
            .or_else(|| Protocol::V2.table().register(field))
    }

    /// The tables' defaults.
    #[must_use]
    pub fn table_default() -> BusLimits {
        BusLimits::from_fields(|f| Self::register(f).and_then(|r| r.default).unwrap_or(0))
    }

    fn check(&self) -> Result<(), &'static str> {
        for (field, value) in self.fields() {
            if !Self::register(field).is_some_and(|r| (r.min..=r.max).contains(&value)) {
                return Err("a limit register outside its control table's range");
            }
        }
        if self.min_position_limit > self.max_position_limit {
            return Err("min position limit above the max position limit");
        }
        Ok(())
    }
}

/// The register of `field` in `protocol`'s table, else in the AX table (the angle limits
/// are kept in AX units whatever the protocol).
fn register(protocol: Protocol, field: Field) -> Option<dynamixel::Register> {
    protocol
        .table()
        .register(field)
        .or_else(|| Protocol::V1.table().register(field))
}

fn within(protocol: Protocol, field: Field, value: i32) -> bool {
    register(protocol, field).is_some_and(|r| (r.min..=r.max).contains(&value))
}

impl BusSettings {
    /// The AX-12A's factory settings (its control table's defaults: ID 1, 1 Mbit/s,
    /// protocol 1.0, return delay 250 = 500 µs, status return level 2, angle limits 0 and
    /// 1023).
    #[must_use]
    pub fn ax12a_default() -> BusSettings {
        let default = |f| {
            register(Protocol::V1, f)
                .and_then(|r| r.default)
                .unwrap_or(0)
        };
        let byte = |f| u8::try_from(default(f)).unwrap_or(0);
        BusSettings {
            id: byte(Field::Id),
            baud_bps: dynamixel::table::ax_baud_bps(byte(Field::BaudRate)),
            protocol_version: 1,
            return_delay_2us: byte(Field::ReturnDelayTime),
            status_return_level: byte(Field::StatusReturnLevel),
            cw_angle_limit: u16::try_from(default(Field::CwAngleLimit)).unwrap_or(0),
            ccw_angle_limit: u16::try_from(default(Field::CcwAngleLimit)).unwrap_or(0),
            limits: BusLimits::table_default(),
        }
    }
}

impl Record for BusSettings {
    const NAME: &'static str = "bus";
    const VERSION: u8 = 2;

    /// The control table's ranges for the protocol. Whether the UART makes the baud rate
    /// is the device's check.
    fn check(&self) -> Result<(), &'static str> {
        let protocol = Protocol::from_number(i32::from(self.protocol_version))
            .ok_or("Dynamixel protocol not 1 or 2")?;
        if !within(protocol, Field::Id, i32::from(self.id)) {
            return Err("bus ID outside the control table's range");
        }
        let baud_ok = match protocol {
            Protocol::V1 => register(protocol, Field::BaudRate).is_some_and(|r| {
                (r.min..=r.max).any(|v| {
                    u8::try_from(v).is_ok_and(|v| dynamixel::table::ax_baud_bps(v) == self.baud_bps)
                })
            }),
            Protocol::V2 => dynamixel::table::X_BAUD_BPS.contains(&self.baud_bps),
        };
        if !baud_ok {
            return Err("baud rate not one the protocol's register selects");
        }
        if !within(
            protocol,
            Field::ReturnDelayTime,
            i32::from(self.return_delay_2us),
        ) {
            return Err("return delay outside the control table's range");
        }
        if !within(
            protocol,
            Field::StatusReturnLevel,
            i32::from(self.status_return_level),
        ) {
            return Err("status return level above 2");
        }
        if !within(
            protocol,
            Field::CwAngleLimit,
            i32::from(self.cw_angle_limit),
        ) || !within(
            protocol,
            Field::CcwAngleLimit,
            i32::from(self.ccw_angle_limit),
        ) || self.cw_angle_limit > self.ccw_angle_limit
        {
            return Err("angle limits above 1023 or clockwise above counter-clockwise");
        }
        self.limits.check()
    }
}

/// One entry of the fault log: a latched fault as the protocol reports it (code, value,
/// and `tick` = uptime in ms), numbered across boots.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FaultEntry {
    /// Number of the fault since the log was last cleared by a factory reset (wrapping
    /// never in practice: 2³² faults).
    pub seq: u32,
    /// The fault.
    pub fault: FaultRecord,
}

impl Record for FaultEntry {
    const NAME: &'static str = "faults";
    const VERSION: u8 = 1;

    /// Any code the protocol knows (checked while decoding) and any value are valid.
    fn check(&self) -> Result<(), &'static str> {
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_version_1_config_migrates_without_a_clutch_tolerance() {
        // The bytes version 1 wrote for the paper preset at 3 mm with the default limits
        // (the layout test of `store.rs` pinned them before the clutch tolerance).
        let v1 = [
            1, 0, 0xB8, 0x17, 0xE8, 0x07, 0, 0xD2, 0x06, 0xDC, 0x0B, 0xE0, 0xC6, 0x5B, 0xE8, 0x07,
            0xBF, 0x96, 0xB1, 0x02, 0xC0, 0x96, 0xB1, 0x02, 100,
        ];
        let c: Config = decode(&v1).unwrap();
        assert_eq!(c.clutch, Clutch::LengthUm(3_000));
        assert_eq!(c.link_inertia_kg_mm2, 1_000);
        assert_eq!(c.gains, None);
        assert_eq!(c.limits, Limits::DEFAULT);
        assert_eq!(c.limits.clutch_tolerance_um, 0);
        assert_eq!(c.command_timeout_ms, 100);
        // A cut version 1 body is undecodable, not a default.
        assert_eq!(decode::<Config>(&v1[..20]), Err(Rejection::Undecodable));
    }

    #[test]
    fn a_version_1_calibration_migrates_with_the_nominal_sensors() {
        // Version 1 wrote the host link's fields (`protocol::Calibration`), nothing more.
        let v1 = protocol::Calibration {
            motor_polarity: -1,
            encoder_direction: 1,
            pot_direction: -1,
            current_offset_counts: -12,
            pot_offset_counts: 7,
            resistance_mohm: 8_300,
            back_emf_uv_s_per_rad: 1_240_000,
            gear_friction_unm: 20_000,
            link_inertia_kg_mm2: 1_150,
            stiffness_mnm_per_rad: Some(265_000),
            clutch_length_um: Some(3_000),
            stiffness_uncertainty_permille: 40,
        };
        let mut bytes = [0u8; 64];
        bytes[0] = 1;
        let n = postcard::to_slice(&v1, &mut bytes[1..]).unwrap().len();
        let cal: Calibration = decode(&bytes[..1 + n]).unwrap();
        assert_eq!(
            (
                cal.wire.motor_polarity,
                cal.wire.pot_offset_counts,
                cal.wire.clutch_length_um
            ),
            (-1, 7, Some(3_000))
        );
        assert_eq!(cal.encoder_counts_per_turn, 4096);
        assert_eq!(
            (cal.pot_gain_ppm, cal.current_gain_ppm),
            (1_000_000, 1_000_000)
        );
        assert_eq!(cal.pot_error_centi, None);
        assert_eq!(cal.check(), Ok(()));
        // Version 2 round-trips; version 3 is unknown.
        let mut buf = [0u8; 128];
        let n = encode(&cal, &mut buf).unwrap();
        assert_eq!(buf[0], 2);
        assert_eq!(decode::<Calibration>(&buf[..n]), Ok(cal));
        buf[0] = 3;
        assert!(matches!(
            decode::<Calibration>(&buf[..n]),
            Err(Rejection::UnknownVersion {
                found: 3,
                current: 2
            })
        ));
    }
}
