//! An in-memory [`Backend`]: one value per [`Field`], the tables' defaults, no physics.
//! For tests, the `pty_bus` example and host tools; the firmware implements [`Backend`]
//! over the servo instead.

use crate::device::{Backend, Keep};
use crate::table::{Field, Protocol, AX12A, X_SERIES};

/// Stores what is written; the present position follows the goal of the same table while
/// torque is enabled (an ideal servo). Values without a table default start at
/// [`MemoryBackend::initial`].
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MemoryBackend {
    values: [i32; Field::COUNT],
    /// [`crate::device::hardware`] bits to report.
    pub hardware_errors: u8,
    /// Factory resets carried out.
    pub resets: u32,
}

impl MemoryBackend {
    /// A device with `id`, speaking `protocol`, every other setting at its default.
    #[must_use]
    pub fn new(id: u8, protocol: Protocol) -> Self {
        let mut m = MemoryBackend {
            values: [0; Field::COUNT],
            hardware_errors: 0,
            resets: 0,
        };
        m.load_defaults(Keep::default());
        m.set(Field::Id, i32::from(id));
        m.set(Field::BusProtocol, protocol.number());
        m
    }

    /// The start value of a field the tables give no default (the state of an actuator at
    /// rest in the middle of its range).
    #[must_use]
    pub const fn initial(field: Field) -> i32 {
        match field {
            Field::GoalPosition | Field::PresentPosition => 512,
            Field::GoalPositionX | Field::PresentPositionX => 2048,
            Field::TorqueLimit => 1023,
            Field::ClutchLength => 4_000,
            Field::PresentVoltage => 120,
            Field::PresentTemperature => 30,
            _ => 0,
        }
    }

    /// The stored value of `field`.
    #[must_use]
    pub fn get(&self, field: Field) -> i32 {
        self.values[field.index()]
    }

    /// Set a stored value (tests use it for the actuator's state: load, voltage, …).
    pub fn set(&mut self, field: Field, value: i32) {
        self.values[field.index()] = value;
    }

    /// Every stored value (to compare states in tests).
    #[must_use]
    pub fn values(&self) -> &[i32; Field::COUNT] {
        &self.values
    }

    fn load_defaults(&mut self, keep: Keep) {
        // The AX-12A table last: where both tables hold a field, the actuator's default wins.
        for table in [&X_SERIES, &AX12A] {
            for r in table.registers() {
                let kept = match r.field {
                    Field::Id => keep.id,
                    Field::BaudRate | Field::BaudRateX => keep.baud,
                    Field::BusProtocol => true,
                    _ => false,
                };
                if !kept {
                    self.set(r.field, r.default.unwrap_or(Self::initial(r.field)));
                }
            }
        }
    }
}

impl Backend for MemoryBackend {
    fn read(&mut self, field: Field) -> i32 {
        let torque = self.get(Field::TorqueEnable) != 0;
        match field {
            Field::PresentPosition if torque => self.get(Field::GoalPosition),
            Field::PresentPositionX if torque => self.get(Field::GoalPositionX),
            f => self.get(f),
        }
    }

    fn write(&mut self, field: Field, value: i32) {
        self.set(field, value);
    }

    fn factory_reset(&mut self, keep: Keep) {
        self.resets = self.resets.saturating_add(1);
        self.load_defaults(keep);
    }

    fn hardware_errors(&mut self) -> u8 {
        self.hardware_errors
    }
}
