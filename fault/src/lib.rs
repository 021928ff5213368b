//! The fault codes of the actuator (docs/design.md §7): what the supervisor latches, the
//! firmware logs and the host protocol sends. One definition for all three: the number of
//! a code is its wire byte and its bit in a [`FaultSet`], the name is what the firmware
//! logs and the host prints.
#![no_std]
#![forbid(unsafe_code)]

/// What went wrong. The discriminant is the code logged and sent to the host; the value
/// a fault carries (`Fault::value` in the supervisor, `FaultRecord::value` on the wire)
/// is in the unit given for its code.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[repr(u8)]
pub enum FaultCode {
    /// A sensor driver returned an error. Value: the sensor (1 link encoder, 2 gear pot,
    /// 3 current ADC).
    SensorRead = 1,
    /// The current ADC reads at a rail. Value: raw counts.
    AdcOutOfRange = 2,
    /// The motor current exceeds the trip level. Value: mA.
    OverCurrent = 3,
    /// A sensor reading changed more than the physics allows in one tick. Value: counts.
    SensorJump = 4,
    /// The link encoder is frozen while the gear moves on. Value: deflection, µrad.
    SensorStuck = 5,
    /// The beams carry more than their stress-limited capacity. Value: torque, µN·m, or
    /// deflection, µrad.
    BeamOverload = 6,
    /// The link is outside its position window. Value: link angle, µrad.
    PositionLimit = 7,
    /// A control period overran its deadline. Value: sysclk counts of the tick.
    DeadlineMissed = 8,
    /// No heartbeat from the host within the command timeout. Value: ms since the last one.
    CommandTimeout = 9,
    /// The beams are softer than configured: the clutch is longer than the host said.
    /// Value: estimated/configured compliance, ‰.
    ClutchMismatch = 10,
}

impl FaultCode {
    /// Every code, in the supervisor's check order.
    pub const ALL: [FaultCode; 10] = [
        FaultCode::SensorRead,
        FaultCode::AdcOutOfRange,
        FaultCode::OverCurrent,
        FaultCode::SensorJump,
        FaultCode::SensorStuck,
        FaultCode::BeamOverload,
        FaultCode::PositionLimit,
        FaultCode::DeadlineMissed,
        FaultCode::CommandTimeout,
        FaultCode::ClutchMismatch,
    ];

    /// The code as logged and sent.
    #[must_use]
    pub const fn code(self) -> u8 {
        self as u8
    }

    /// The fault with this code, if any.
    #[must_use]
    pub const fn from_code(code: u8) -> Option<FaultCode> {
        Some(match code {
            1 => FaultCode::SensorRead,
            2 => FaultCode::AdcOutOfRange,
            3 => FaultCode::OverCurrent,
            4 => FaultCode::SensorJump,
            5 => FaultCode::SensorStuck,
            6 => FaultCode::BeamOverload,
            7 => FaultCode::PositionLimit,
            8 => FaultCode::DeadlineMissed,
            9 => FaultCode::CommandTimeout,
            10 => FaultCode::ClutchMismatch,
            _ => return None,
        })
    }

    /// Short name, as logged and printed (`over-current`, `command-timeout`, …).
    #[must_use]
    pub const fn name(self) -> &'static str {
        match self {
            FaultCode::SensorRead => "sensor-read",
            FaultCode::AdcOutOfRange => "adc-out-of-range",
            FaultCode::OverCurrent => "over-current",
            FaultCode::SensorJump => "sensor-jump",
            FaultCode::SensorStuck => "sensor-stuck",
            FaultCode::BeamOverload => "beam-overload",
            FaultCode::PositionLimit => "position-limit",
            FaultCode::DeadlineMissed => "deadline-missed",
            FaultCode::CommandTimeout => "command-timeout",
            FaultCode::ClutchMismatch => "clutch-mismatch",
        }
    }

    /// This code's bit in a [`FaultSet`]: `1 << code`.
    #[must_use]
    pub const fn bit(self) -> u16 {
        1 << (self as u8)
    }
}

/// A set of fault codes: bit `code` for each [`FaultCode`] in it (bits 0 and 11–15 are
/// not codes).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct FaultSet(pub u16);

impl FaultSet {
    /// No fault.
    pub const EMPTY: FaultSet = FaultSet(0);

    /// Whether `code` is in the set.
    #[must_use]
    pub const fn contains(self, code: FaultCode) -> bool {
        self.0 & code.bit() != 0
    }

    /// The set with `code` added.
    #[must_use]
    pub const fn with(self, code: FaultCode) -> FaultSet {
        FaultSet(self.0 | code.bit())
    }

    /// Whether the set is empty.
    #[must_use]
    pub const fn is_empty(self) -> bool {
        self.0 == 0
    }
}

/// On the wire a code is its number, one byte; any other byte is refused.
#[cfg(feature = "serde")]
impl serde::Serialize for FaultCode {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_u8(self.code())
    }
}

#[cfg(feature = "serde")]
impl<'de> serde::Deserialize<'de> for FaultCode {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let code = <u8 as serde::Deserialize>::deserialize(d)?;
        FaultCode::from_code(code).ok_or_else(|| {
            serde::de::Error::invalid_value(
                serde::de::Unexpected::Unsigned(code.into()),
                &"a fault code, 1..=10",
            )
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The codes and names as docs/protocol.md and docs/design.md §7 give them, written
    /// out here apart from the enum: a renumbered or renamed code breaks the wire and the
    /// logs, and must fail here.
    const TABLE: [(u8, &str); 10] = [
        (1, "sensor-read"),
        (2, "adc-out-of-range"),
        (3, "over-current"),
        (4, "sensor-jump"),
        (5, "sensor-stuck"),
        (6, "beam-overload"),
        (7, "position-limit"),
        (8, "deadline-missed"),
        (9, "command-timeout"),
        (10, "clutch-mismatch"),
    ];

    #[test]
    fn codes_and_names_are_the_documented_ones() {
        assert_eq!(FaultCode::ALL.len(), TABLE.len());
        for (c, (code, name)) in FaultCode::ALL.iter().zip(TABLE) {
            assert_eq!(c.code(), code);
            assert_eq!(c.name(), name);
            assert_eq!(FaultCode::from_code(code), Some(*c));
            assert_eq!(c.bit(), 1u16 << code);
        }
        for bad in [0u8, 11, 12, 200, 255] {
            assert_eq!(FaultCode::from_code(bad), None, "{bad}");
        }
    }

    #[test]
    fn a_set_holds_exactly_what_was_added() {
        let set = FaultSet::EMPTY
            .with(FaultCode::OverCurrent)
            .with(FaultCode::ClutchMismatch);
        assert_eq!(set.0, (1 << 3) | (1 << 10));
        for c in FaultCode::ALL {
            let inside = matches!(c, FaultCode::OverCurrent | FaultCode::ClutchMismatch);
            assert_eq!(set.contains(c), inside, "{}", c.name());
        }
        assert!(FaultSet::EMPTY.is_empty() && !set.is_empty());
    }

    #[test]
    fn on_the_wire_a_code_is_one_byte_and_a_set_its_u16() {
        let mut buf = [0u8; 8];
        for (code, _) in TABLE {
            let c = FaultCode::from_code(code).unwrap();
            assert_eq!(postcard::to_slice(&c, &mut buf).unwrap(), &[code]);
        }
        // 0x0408 as a varint: 0x88 0x08.
        let set = FaultSet((1 << 3) | (1 << 10));
        assert_eq!(postcard::to_slice(&set, &mut buf).unwrap(), &[0x88, 0x08]);
        assert_eq!(
            postcard::from_bytes::<FaultCode>(&[10]).unwrap(),
            FaultCode::ClutchMismatch
        );
        assert!(postcard::from_bytes::<FaultCode>(&[11]).is_err());
        assert!(postcard::from_bytes::<FaultCode>(&[0]).is_err());
    }
}
