//! The control tables, as data: every register's address, size, access, area, default,
//! accepted range and unit, defined once here and used by the device (validation, reads),
//! the backends (defaults) and the documentation.
//!
//! Registers name a protocol-independent [`Field`]; a field that means the same in both
//! tables (ID, return delay, torque enable, …) is one field at two addresses, so a backend
//! implements it once. Fields whose units differ (AX goal position in 0.29° counts, X goal
//! position in 0.088° pulses) are distinct.

use protocol::{CLUTCH_MAX_UM, CLUTCH_MIN_UM, STIFFNESS_MIN_MNM_PER_RAD};

/// Which protocol a table (and a device) speaks.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Protocol {
    /// Protocol 1.0, the AX-12A table.
    V1,
    /// Protocol 2.0, the X-series-style table.
    V2,
}

impl Protocol {
    /// The value of the Protocol Type register for this protocol (1 or 2).
    #[must_use]
    pub const fn number(self) -> i32 {
        match self {
            Protocol::V1 => 1,
            Protocol::V2 => 2,
        }
    }

    /// The protocol whose Protocol Type register value is `n`.
    #[must_use]
    pub const fn from_number(n: i32) -> Option<Protocol> {
        match n {
            1 => Some(Protocol::V1),
            2 => Some(Protocol::V2),
            _ => None,
        }
    }

    /// This protocol's control table.
    #[must_use]
    pub const fn table(self) -> &'static Table {
        match self {
            Protocol::V1 => &AX12A,
            Protocol::V2 => &X_SERIES,
        }
    }
}

/// Whether the bus may write a register.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Access {
    /// Read only.
    R,
    /// Read and write.
    RW,
}

/// Where a register lives.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Area {
    /// Persistent settings: subject to Lock (1.0) and to the torque-off rule (2.0).
    Eeprom,
    /// Volatile state, reset at power-on.
    Ram,
}

/// A logical register, as a backend sees it. Values are `i32` in the unit of the register
/// that names the field (see [`AX12A`], [`X_SERIES`], [`EXTRA`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
#[allow(missing_docs)] // each variant is documented by its registers' names and units below
pub enum Field {
    // Identity (answered by the device from the table, not the backend).
    ModelNumber,
    ModelInformation,
    FirmwareVersion,
    // Bus settings.
    Id,
    /// AX encoding: 2 000 000 / (v + 1) bps.
    BaudRate,
    /// X encoding: index into [`X_BAUD_BPS`].
    BaudRateX,
    ReturnDelayTime,
    StatusReturnLevel,
    BusProtocol,
    // Limits and alarms.
    CwAngleLimit,
    CcwAngleLimit,
    MinPositionLimit,
    MaxPositionLimit,
    VelocityLimit,
    TemperatureLimit,
    MinVoltageLimit,
    MaxVoltageLimit,
    MaxTorque,
    AlarmLed,
    Shutdown,
    OperatingMode,
    // Commands.
    TorqueEnable,
    Led,
    CwComplianceMargin,
    CcwComplianceMargin,
    CwComplianceSlope,
    CcwComplianceSlope,
    GoalPosition,
    GoalPositionX,
    MovingSpeed,
    GoalVelocity,
    ProfileAcceleration,
    ProfileVelocity,
    TorqueLimit,
    Punch,
    // State.
    PresentPosition,
    PresentPositionX,
    PresentSpeed,
    PresentVelocityX,
    PresentLoad,
    PresentLoadX,
    PresentVoltage,
    PresentTemperature,
    Registered,
    Moving,
    Lock,
    HardwareErrorStatus,
    // The actuator's own registers.
    ClutchLength,
    Stiffness,
    BeamCapacity,
    Faults,
    CalibrationState,
}

impl Field {
    /// Number of fields (for backends that store one value per field).
    pub const COUNT: usize = Field::CalibrationState as usize + 1;

    /// The field's index in `0..COUNT`.
    #[must_use]
    pub const fn index(self) -> usize {
        self as usize
    }
}

/// One register of a control table.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Register {
    /// First byte's address.
    pub address: u16,
    /// Size in bytes (1, 2 or 4), little-endian on the wire.
    pub size: u8,
    /// Whether the value is two's complement.
    pub signed: bool,
    /// The e-Manual's name.
    pub name: &'static str,
    /// The logical register.
    pub field: Field,
    /// Bus access.
    pub access: Access,
    /// EEPROM or RAM.
    pub area: Area,
    /// Factory default; `None` where the actuator's state decides (goal and present
    /// position, the clutch length configured at build time, …).
    pub default: Option<i32>,
    /// Smallest value a write may carry (for read-only registers: the documented range).
    pub min: i32,
    /// Largest value a write may carry.
    pub max: i32,
    /// Unit and encoding of the value.
    pub unit: &'static str,
}

impl Register {
    /// The value of the register from its `size` little-endian bytes; `None` when an
    /// unsigned 4-byte value does not fit in `i32` (no register accepts one).
    #[must_use]
    pub fn decode(&self, bytes: &[u8]) -> Option<i32> {
        let mut raw = [0u8; 4];
        let n = usize::from(self.size).min(4).min(bytes.len());
        raw[..n].copy_from_slice(&bytes[..n]);
        let u = u32::from_le_bytes(raw);
        if self.signed {
            let shift = 32 - 8 * u32::from(self.size.clamp(1, 4));
            // Sign-extend from `size` bytes.
            Some(((u << shift) as i32) >> shift)
        } else {
            i32::try_from(u).ok()
        }
    }

    /// Byte `i` (0 = least significant) of `value` as this register sends it.
    #[must_use]
    pub const fn byte(&self, value: i32, i: u16) -> u8 {
        (value as u32 >> (8 * (i as u32 & 3))) as u8
    }

    const fn at(self, base: u16) -> Register {
        Register {
            address: self.address + base,
            ..self
        }
    }
}

/// A control table: the protocol's registers, then the actuator's [`EXTRA`] registers at
/// `extra_base`.
#[derive(Debug)]
pub struct Table {
    /// The protocol this table is served in.
    pub protocol: Protocol,
    /// Product name of the model the table follows.
    pub model: &'static str,
    /// The protocol's registers, by address.
    pub main: &'static [Register],
    /// Address of the first extra register.
    pub extra_base: u16,
}

impl Table {
    /// The register that contains byte `address`, with its absolute address.
    #[must_use]
    pub fn containing(&self, address: u16) -> Option<Register> {
        let inside = |r: &Register| address >= r.address && address < r.address + u16::from(r.size);
        if let Some(r) = self.main.iter().find(|r| inside(r)) {
            return Some(*r);
        }
        let off = address.checked_sub(self.extra_base)?;
        EXTRA
            .iter()
            .find(|r| off >= r.address && off < r.address + u16::from(r.size))
            .map(|r| r.at(self.extra_base))
    }

    /// The register that holds `field`, with its absolute address.
    #[must_use]
    pub fn register(&self, field: Field) -> Option<Register> {
        self.registers().find(|r| r.field == field)
    }

    /// Every register, main table first, with absolute addresses.
    pub fn registers(&self) -> impl Iterator<Item = Register> + '_ {
        let base = self.extra_base;
        self.main
            .iter()
            .copied()
            .chain(EXTRA.iter().map(move |r| r.at(base)))
    }

    /// Whether `address` is inside the table's address span (a register or a reserved gap
    /// between two registers, which reads as 0).
    #[must_use]
    pub fn in_span(&self, address: u16) -> bool {
        let end = |rs: &[Register]| rs.last().map_or(0, |r| r.address + u16::from(r.size));
        address < end(self.main)
            || (address >= self.extra_base && address - self.extra_base < end(EXTRA))
    }
}

/// Bit rates of the X-series Baud Rate register values 0–7.
pub const X_BAUD_BPS: [u32; 8] = [
    9_600, 57_600, 115_200, 1_000_000, 2_000_000, 3_000_000, 4_000_000, 4_500_000,
];

/// Bit rate of AX Baud Rate register value `v`: 2 000 000 / (v + 1) bps.
#[must_use]
pub const fn ax_baud_bps(v: u8) -> u32 {
    2_000_000 / (v as u32 + 1)
}

/// Bit rate of a device's baud setting in `protocol`'s encoding (`None` for an X value
/// outside 0–7).
#[must_use]
pub fn baud_bps(protocol: Protocol, value: i32) -> Option<u32> {
    let v = u8::try_from(value).ok()?;
    match protocol {
        Protocol::V1 => Some(ax_baud_bps(v)),
        Protocol::V2 => X_BAUD_BPS.get(usize::from(v)).copied(),
    }
}

/// The value of `protocol`'s Baud Rate register that selects `bps` exactly, if any (the
/// inverse of [`baud_bps`]; the AX register's range is 1–254).
#[must_use]
pub fn baud_register(protocol: Protocol, bps: u32) -> Option<i32> {
    match protocol {
        Protocol::V1 => (1..=254u8).find(|&v| ax_baud_bps(v) == bps).map(i32::from),
        Protocol::V2 => X_BAUD_BPS
            .iter()
            .position(|&b| b == bps)
            .and_then(|i| i32::try_from(i).ok()),
    }
}

#[allow(clippy::too_many_arguments)] // one row of the table, in the e-Manual's column order
const fn reg(
    address: u16,
    size: u8,
    name: &'static str,
    field: Field,
    access: Access,
    area: Area,
    default: Option<i32>,
    min: i32,
    max: i32,
    unit: &'static str,
) -> Register {
    Register {
        address,
        size,
        signed: false,
        name,
        field,
        access,
        area,
        default,
        min,
        max,
        unit,
    }
}

const fn signed(r: Register) -> Register {
    Register { signed: true, ..r }
}

use Access::{R, RW};
use Area::{Eeprom as E, Ram as M};

/// Model number the AX-12A table answers with.
pub const AX12A_MODEL: i32 = 12;
/// Model number the X-series table answers with: the XL430-W250, whose addresses and units
/// the table follows, so that tools which pick the table by model number find ours.
pub const X_SERIES_MODEL: i32 = 1060;
/// Firmware version reported in both tables.
pub const FIRMWARE_VERSION: i32 = 1;
/// Address of the first extra register in the AX-12A table (right after Punch).
pub const AX12A_EXTRA_BASE: u16 = 50;
/// Address of the first extra register in the X-series table (past every XL430 address).
pub const X_SERIES_EXTRA_BASE: u16 = 1024;

/// The AX-12A control table (ROBOTIS e-Manual, AX-12A): EEPROM 0–18, RAM 24–49, then the
/// [`EXTRA`] registers from address 50.
#[rustfmt::skip]
pub static AX12A: Table = Table {
    protocol: Protocol::V1,
    model: "AX-12A",
    extra_base: AX12A_EXTRA_BASE,
    main: &[
        reg(0, 2, "Model Number", Field::ModelNumber, R, E, Some(AX12A_MODEL), 0, 65_535, "-"),
        reg(2, 1, "Firmware Version", Field::FirmwareVersion, R, E, Some(FIRMWARE_VERSION), 0, 255, "-"),
        reg(3, 1, "ID", Field::Id, RW, E, Some(1), 0, 253, "-"),
        reg(4, 1, "Baud Rate", Field::BaudRate, RW, E, Some(1), 1, 254, "2 000 000 / (v + 1) bps"),
        reg(5, 1, "Return Delay Time", Field::ReturnDelayTime, RW, E, Some(250), 0, 254, "2 µs"),
        reg(6, 2, "CW Angle Limit", Field::CwAngleLimit, RW, E, Some(0), 0, 1023, "0.293° (1024 over 300°)"),
        reg(8, 2, "CCW Angle Limit", Field::CcwAngleLimit, RW, E, Some(1023), 0, 1023, "0.293° (1024 over 300°)"),
        reg(11, 1, "Temperature Limit", Field::TemperatureLimit, RW, E, Some(70), 0, 100, "1 °C"),
        reg(12, 1, "Min Voltage Limit", Field::MinVoltageLimit, RW, E, Some(60), 50, 160, "0.1 V"),
        reg(13, 1, "Max Voltage Limit", Field::MaxVoltageLimit, RW, E, Some(140), 50, 160, "0.1 V"),
        reg(14, 2, "Max Torque", Field::MaxTorque, RW, E, Some(1023), 0, 1023, "0.1 % of the torque capacity"),
        reg(16, 1, "Status Return Level", Field::StatusReturnLevel, RW, E, Some(2), 0, 2, "0 ping, 1 + read, 2 all"),
        reg(17, 1, "Alarm LED", Field::AlarmLed, RW, E, Some(36), 0, 127, "error-bit mask"),
        reg(18, 1, "Shutdown", Field::Shutdown, RW, E, Some(36), 0, 127, "error-bit mask"),
        reg(24, 1, "Torque Enable", Field::TorqueEnable, RW, M, Some(0), 0, 1, "0 off, 1 on"),
        reg(25, 1, "LED", Field::Led, RW, M, Some(0), 0, 1, "0 off, 1 on"),
        reg(26, 1, "CW Compliance Margin", Field::CwComplianceMargin, RW, M, Some(1), 0, 255, "0.293°"),
        reg(27, 1, "CCW Compliance Margin", Field::CcwComplianceMargin, RW, M, Some(1), 0, 255, "0.293°"),
        reg(28, 1, "CW Compliance Slope", Field::CwComplianceSlope, RW, M, Some(32), 0, 254, "step 1–7 (2, 4, …, 128)"),
        reg(29, 1, "CCW Compliance Slope", Field::CcwComplianceSlope, RW, M, Some(32), 0, 254, "step 1–7 (2, 4, …, 128)"),
        reg(30, 2, "Goal Position", Field::GoalPosition, RW, M, None, 0, 1023, "0.293° (1024 over 300°)"),
        reg(32, 2, "Moving Speed", Field::MovingSpeed, RW, M, None, 0, 2047, "0.111 rpm, 0 = no limit"),
        reg(34, 2, "Torque Limit", Field::TorqueLimit, RW, M, None, 0, 1023, "0.1 % of the torque capacity"),
        reg(36, 2, "Present Position", Field::PresentPosition, R, M, None, 0, 1023, "0.293°"),
        reg(38, 2, "Present Speed", Field::PresentSpeed, R, M, None, 0, 2047, "0.111 rpm, bit 10 = CW"),
        reg(40, 2, "Present Load", Field::PresentLoad, R, M, None, 0, 2047, "0.1 %, bit 10 = CW"),
        reg(42, 1, "Present Voltage", Field::PresentVoltage, R, M, None, 0, 255, "0.1 V"),
        reg(43, 1, "Present Temperature", Field::PresentTemperature, R, M, None, 0, 255, "1 °C"),
        reg(44, 1, "Registered", Field::Registered, R, M, Some(0), 0, 1, "1 = REG_WRITE pending"),
        reg(46, 1, "Moving", Field::Moving, R, M, Some(0), 0, 1, "1 = moving"),
        reg(47, 1, "Lock", Field::Lock, RW, M, Some(0), 0, 1, "1 = EEPROM locked until power-off"),
        reg(48, 2, "Punch", Field::Punch, RW, M, Some(32), 32, 1023, "0.1 % of the torque capacity"),
    ],
};

/// The X-series-style control table served in Protocol 2.0: the XL430-W250's addresses,
/// sizes and units for the registers ROS 2 and `dynamixel-sdk` code uses, then the
/// [`EXTRA`] registers from address 1024. Defaults of settings shared with the AX-12A table
/// (temperature limit, Protocol Type) are the actuator's, not the XL430's.
#[rustfmt::skip]
pub static X_SERIES: Table = Table {
    protocol: Protocol::V2,
    model: "XL430-W250 (subset)",
    extra_base: X_SERIES_EXTRA_BASE,
    main: &[
        reg(0, 2, "Model Number", Field::ModelNumber, R, E, Some(X_SERIES_MODEL), 0, 65_535, "-"),
        reg(2, 4, "Model Information", Field::ModelInformation, R, E, Some(0), 0, 0, "-"),
        reg(6, 1, "Firmware Version", Field::FirmwareVersion, R, E, Some(FIRMWARE_VERSION), 0, 255, "-"),
        reg(7, 1, "ID", Field::Id, RW, E, Some(1), 0, 252, "-"),
        reg(8, 1, "Baud Rate", Field::BaudRateX, RW, E, Some(1), 0, 7, "index into X_BAUD_BPS"),
        reg(9, 1, "Return Delay Time", Field::ReturnDelayTime, RW, E, Some(250), 0, 254, "2 µs"),
        reg(11, 1, "Operating Mode", Field::OperatingMode, RW, E, Some(3), 3, 3, "3 = position control (the only mode)"),
        reg(13, 1, "Protocol Type", Field::BusProtocol, RW, E, Some(1), 1, 2, "1 = Protocol 1.0, 2 = Protocol 2.0"),
        reg(31, 1, "Temperature Limit", Field::TemperatureLimit, RW, E, Some(70), 0, 100, "1 °C"),
        reg(32, 2, "Max Voltage Limit", Field::MaxVoltageLimit, RW, E, Some(140), 60, 140, "0.1 V"),
        reg(34, 2, "Min Voltage Limit", Field::MinVoltageLimit, RW, E, Some(60), 60, 140, "0.1 V"),
        reg(44, 4, "Velocity Limit", Field::VelocityLimit, RW, E, Some(265), 0, 1023, "0.229 rpm"),
        reg(48, 4, "Max Position Limit", Field::MaxPositionLimit, RW, E, Some(4095), 0, 4095, "0.088° (4096 per turn)"),
        reg(52, 4, "Min Position Limit", Field::MinPositionLimit, RW, E, Some(0), 0, 4095, "0.088° (4096 per turn)"),
        reg(64, 1, "Torque Enable", Field::TorqueEnable, RW, M, Some(0), 0, 1, "0 off, 1 on"),
        reg(65, 1, "LED", Field::Led, RW, M, Some(0), 0, 1, "0 off, 1 on"),
        reg(68, 1, "Status Return Level", Field::StatusReturnLevel, RW, M, Some(2), 0, 2, "0 ping, 1 + read, 2 all"),
        reg(69, 1, "Registered Instruction", Field::Registered, R, M, Some(0), 0, 1, "1 = REG WRITE pending"),
        reg(70, 1, "Hardware Error Status", Field::HardwareErrorStatus, R, M, Some(0), 0, 255, "HardwareErrors bits"),
        signed(reg(104, 4, "Goal Velocity", Field::GoalVelocity, RW, M, Some(0), -1023, 1023, "0.229 rpm (stored; position mode ignores it)")),
        reg(108, 4, "Profile Acceleration", Field::ProfileAcceleration, RW, M, Some(0), 0, 32_767, "214.577 rev/min², 0 = no limit"),
        reg(112, 4, "Profile Velocity", Field::ProfileVelocity, RW, M, Some(0), 0, 32_767, "0.229 rpm, 0 = no limit"),
        reg(116, 4, "Goal Position", Field::GoalPositionX, RW, M, None, 0, 4095, "0.088° (4096 per turn)"),
        reg(122, 1, "Moving", Field::Moving, R, M, Some(0), 0, 1, "1 = moving"),
        signed(reg(126, 2, "Present Load", Field::PresentLoadX, R, M, None, -1000, 1000, "0.1 % of the torque capacity")),
        signed(reg(128, 4, "Present Velocity", Field::PresentVelocityX, R, M, None, i32::MIN, i32::MAX, "0.229 rpm")),
        reg(132, 4, "Present Position", Field::PresentPositionX, R, M, None, 0, 4095, "0.088°"),
        reg(144, 2, "Present Input Voltage", Field::PresentVoltage, R, M, None, 0, 65_535, "0.1 V"),
        reg(146, 1, "Present Temperature", Field::PresentTemperature, R, M, None, 0, 255, "1 °C"),
    ],
};

/// Calibration states of the Calibration State register.
pub mod calibration {
    /// Never calibrated: the build-time defaults are in use.
    pub const UNCALIBRATED: i32 = 0;
    /// A calibration is running.
    pub const RUNNING: i32 = 1;
    /// Calibrated, the result stored.
    pub const CALIBRATED: i32 = 2;
    /// The last calibration failed (the defaults or the previous result are in use).
    pub const FAILED: i32 = 3;
}

/// The actuator's registers beyond a stock servo, at offsets from a table's `extra_base`
/// (AX-12A: 50, X series: 1024). Writes are checked against the same ranges as our own
/// protocol's requests (`protocol::CLUTCH_MIN_UM` …); the backend applies the model's
/// checks (a stiffness the clutch cannot reach is refused).
#[rustfmt::skip]
pub static EXTRA: &[Register] = &[
    reg(0, 2, "Clutch Length", Field::ClutchLength, RW, E, None, CLUTCH_MIN_UM as i32, CLUTCH_MAX_UM as i32, "1 µm (configured active beam length L)"),
    reg(2, 4, "Stiffness", Field::Stiffness, RW, E, None, STIFFNESS_MIN_MNM_PER_RAD as i32, i32::MAX, "1 mN·m/rad (k(L); a write sets L = L(k))"),
    reg(6, 4, "Beam Capacity", Field::BeamCapacity, R, M, None, 0, i32::MAX, "1 µN·m (stress-limited torque at the current L)"),
    reg(10, 2, "Latched Faults", Field::Faults, RW, M, Some(0), 0, 0, "bit 1 << code (protocol::FaultSet); write 0 to clear"),
    reg(12, 1, "Calibration State", Field::CalibrationState, R, M, Some(calibration::UNCALIBRATED), 0, 3, "0 none, 1 running, 2 calibrated, 3 failed"),
    reg(13, 1, "Protocol Type", Field::BusProtocol, RW, E, Some(1), 1, 2, "1 = Protocol 1.0, 2 = Protocol 2.0"),
];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn baud_register_inverts_baud_bps() {
        for protocol in [Protocol::V1, Protocol::V2] {
            let r = protocol
                .table()
                .register(match protocol {
                    Protocol::V1 => Field::BaudRate,
                    Protocol::V2 => Field::BaudRateX,
                })
                .unwrap();
            for v in r.min..=r.max {
                let bps = baud_bps(protocol, v).unwrap();
                assert_eq!(baud_register(protocol, bps), Some(v), "{protocol:?} {v}");
            }
        }
        // 1 Mbit/s is AX 1 and X 3; 250 kbit/s only AX (7), 57 600 only X (1).
        assert_eq!(baud_register(Protocol::V1, 1_000_000), Some(1));
        assert_eq!(baud_register(Protocol::V2, 1_000_000), Some(3));
        assert_eq!(baud_register(Protocol::V1, 250_000), Some(7));
        assert_eq!(baud_register(Protocol::V2, 250_000), None);
        assert_eq!(baud_register(Protocol::V1, 57_600), None);
        assert_eq!(baud_register(Protocol::V2, 57_600), Some(1));
    }
}
