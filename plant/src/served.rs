//! The simulated actuator of an emulated board that serves the command protocol: no
//! script, the host decides. The plant runs with the bridge lines as the firmware's driver
//! set them, and its clutch follows the controller's configuration (on the real actuator
//! the user slides the clutch to the length the board reports; here it is there at once).
//!
//! The link carries its inertia and, optionally, a constant load torque that is hung on
//! the first time the H-bridge drives (as one hangs a weight on an actuator that holds its
//! position: before that, the motor coasts and the gear train, which the simulation lets
//! back-drive, could not hold it). The load then stays: after a fault or a disable the
//! link falls away, as it would.

use model::control::{Command, Config, ControlError, Schedule};
use model::Design;

use crate::harness::{self, Scenario};
use crate::overrides::Overrides;
use crate::scenario::BridgeLines;
use crate::sensors::SensorReadings;
use crate::sim::Plant;

/// The plant of a serving emulated board.
pub struct ServedActuator {
    design: Design,
    plant: Plant,
    /// Clutch length the coupling was built for, I32F32 bits of mm.
    length_bits: i64,
    readings: SensorReadings,
    /// Load still to hang on at the first driven tick, N·m.
    pending_load_nm: Option<f32>,
}

impl ServedActuator {
    /// The plant for `design` at `config`'s clutch setting, at rest; `load_nm` (N·m,
    /// positive pushes the link positive) is hung on at the first driven tick.
    ///
    /// # Errors
    /// `config` was rejected.
    pub fn new(design: Design, config: &Config, load_nm: f32) -> Result<Self, ControlError> {
        Self::with_plant(design, config, load_nm, &Overrides::NONE)
    }

    /// [`ServedActuator::new`] on an actuator changed by `plant` (e.g. `power-up-angle`:
    /// the link at rest elsewhere, the incremental encoder reading zero there).
    ///
    /// # Errors
    /// `config` was rejected.
    pub fn with_plant(
        design: Design,
        config: &Config,
        load_nm: f32,
        plant: &Overrides,
    ) -> Result<Self, ControlError> {
        let sc = Scenario {
            design,
            load_nm: 0.0,
            plant: *plant,
            ..Scenario::new(*config, Command::Hold)
        };
        let plant = harness::plant_for(&sc)?;
        let sched = Schedule::new(&design, config)?;
        let readings = plant.readings();
        Ok(Self {
            design,
            plant,
            length_bits: sched.setting().length().to_bits(),
            readings,
            pending_load_nm: (load_nm != 0.0).then_some(load_nm),
        })
    }

    /// The simulated actuator, e.g. to warm its motor ([`Plant::set_resistance`]).
    pub fn plant_mut(&mut self) -> &mut Plant {
        &mut self.plant
    }

    /// One control period with `lines`; first, if the controller's clutch length
    /// (`schedule`) changed since the last tick, the coupling moves there. Returns the new
    /// readings.
    pub fn tick(&mut self, lines: BridgeLines, schedule: &Schedule) -> SensorReadings {
        let length = schedule.setting().length().to_bits();
        if length != self.length_bits {
            if let Ok(coupling) = harness::coupling_config(&self.design, schedule) {
                self.plant.set_coupling(coupling);
            }
            self.length_bits = length;
        }
        if lines.enabled {
            if let Some(load) = self.pending_load_nm.take() {
                self.plant.set_external_torque(load);
            }
        }
        self.readings = self.plant.step_tick_cmd(lines.command());
        self.readings
    }

    /// The readings of the last tick.
    #[must_use]
    pub const fn readings(&self) -> SensorReadings {
        self.readings
    }

    /// The plant (true state, for tests).
    #[must_use]
    pub const fn plant(&self) -> &Plant {
        &self.plant
    }
}
