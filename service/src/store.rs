//! The settings store as the command service sees it: what `save`, `load`,
//! `factory-reset` and `faults-log` do, what the board applies at boot, and the fault log
//! the latched faults go to.
//!
//! The store itself is the `store` crate (a versioned record set in a power-fail-safe
//! sequential-storage map); the firmware hands the service one through the object-safe
//! [`Storage`] trait ([`Service::attach_store`]): a [`store::Store`] over the board's flash,
//! which the emulated boards wrap to mirror their RAM flash to a host file. Every stored
//! config goes through the same checks as the requests that set it over the wire: the
//! record's own ranges ([`store::Record::check`], [`protocol::Request::validate`]) and then
//! [`Checks`], which prepares it on this design exactly as a request would
//! ([`model::servo::Prepared::new`]).
//!
//! # Flash and the 1 kHz loop
//!
//! Programming or erasing the STM32F4's flash stalls instruction fetch from it, and the
//! control loop runs from flash: `save` and `factory-reset` are refused with
//! [`ErrorCode::NotAllowed`] while the motor is enabled, and a latched fault (which has
//! disabled the motor) is logged only while it is not enabled. All of it runs at the
//! command task's priority, below the control tick (docs/design.md §10).
//!
//! # For the other parts of the firmware
//!
//! The bus identity and the calibration are records of the same set: read them with
//! [`Service::bus_settings`] and [`Service::calibration`], make a change persist with
//! [`Service::persist_bus`] / [`Service::persist_calibration`] (saves the whole set with the
//! stored config, not the running one; refused while enabled).

use model::control::{ClutchSetting, Config};
use model::servo::{Prepared, ServoState};
use model::supervisor::SupervisorConfig;
use model::{Design, Inertia};
use protocol::{ErrorCode, FaultRecord, LoggedFault};
use rtic_core::Mutex;
use store::{
    BusSettings, Calibration, Clutch, FaultLog, Outcome, Record, RecordSet, Rejection, Report,
    Store, StoreError, Validator,
};

use crate::{
    clutch_length, clutch_stiffness, limits_of, pid_gains, q32_to_milli, stiffness_mnm, wire_gains,
    with_limits, Actuator, Service, ServiceDevice,
};

/// A settings store the service can use (object safe, so the firmware can hand over its
/// board's store as `&'static mut dyn Storage`). Implemented by every [`store::Store`].
pub trait Storage {
    /// [`Store::load`].
    fn load(&mut self, checks: &Checks<'_>) -> store::Boot;
    /// [`Store::save`].
    ///
    /// # Errors
    /// As [`Store::save`].
    fn save(&mut self, set: &RecordSet, checks: &Checks<'_>) -> Result<u32, StoreError>;
    /// [`Store::factory_reset`].
    ///
    /// # Errors
    /// As [`Store::factory_reset`].
    fn factory_reset(&mut self) -> Result<(), StoreError>;
    /// [`Store::log_fault`].
    ///
    /// # Errors
    /// As [`Store::log_fault`].
    fn log_fault(&mut self, fault: FaultRecord) -> Result<u32, StoreError>;
    /// [`Store::fault_log`].
    fn fault_log(&mut self) -> FaultLog;
}

impl<F: embedded_storage::nor_flash::NorFlash> Storage for Store<F> {
    fn load(&mut self, checks: &Checks<'_>) -> store::Boot {
        Store::load(self, checks)
    }
    fn save(&mut self, set: &RecordSet, checks: &Checks<'_>) -> Result<u32, StoreError> {
        Store::save(self, set, checks)
    }
    fn factory_reset(&mut self) -> Result<(), StoreError> {
        Store::factory_reset(self)
    }
    fn log_fault(&mut self, fault: FaultRecord) -> Result<u32, StoreError> {
        Store::log_fault(self, fault)
    }
    fn fault_log(&mut self) -> FaultLog {
        Store::fault_log(self)
    }
}

/// The device's checks of a stored record, beyond its own ranges: a config must prepare
/// on this design (the clutch length the design reaches, L(k), the gain schedule), as the
/// same request over the wire must.
pub struct Checks<'a> {
    design: &'a Design,
    defaults: &'a (Config, SupervisorConfig),
}

impl Validator for Checks<'_> {
    fn config(&self, config: &store::Config) -> Result<(), &'static str> {
        let (c, s) = model_config(config, self.defaults).map_err(|_| "limits do not convert")?;
        Prepared::new(self.design, &c, &s)
            .map(|_| ())
            .map_err(|_| "the design cannot reach this configuration")
    }
}

/// A stored config on top of the defaults (what the firmware boots with): the same
/// conversions as the requests that set each field.
///
/// # Errors
/// [`ErrorCode::OutOfRange`] if the limits do not convert.
fn model_config(
    stored: &store::Config,
    defaults: &(Config, SupervisorConfig),
) -> Result<(Config, SupervisorConfig), ErrorCode> {
    let (mut config, mut supervision) = with_limits(defaults.0, defaults.1, &stored.limits)?;
    config.clutch = match stored.clutch {
        Clutch::LengthUm(um) => clutch_length(um),
        Clutch::StiffnessMnmPerRad(k) => clutch_stiffness(k),
    };
    config.link_inertia =
        Inertia::from_int(i32::try_from(stored.link_inertia_kg_mm2).unwrap_or(i32::MAX));
    config.gains.gains = stored.gains.map(pid_gains);
    supervision.command_timeout_ms = stored.command_timeout_ms;
    Ok((config, supervision))
}

/// The configuration in force as a stored config record (inverse of [`model_config`]).
fn stored_config(config: &Config, supervision: &SupervisorConfig) -> store::Config {
    let clutch = match config.clutch {
        ClutchSetting::Length(l) => {
            Clutch::LengthUm(u32::try_from(q32_to_milli(l.to_bits())).unwrap_or(0))
        }
        ClutchSetting::Stiffness(k) => Clutch::StiffnessMnmPerRad(stiffness_mnm(k)),
    };
    // kg·mm², I32F32: rounded to the nearest integer (the record's unit).
    let inertia = (config.link_inertia.to_bits().saturating_add(1 << 31)) >> 32;
    store::Config {
        clutch,
        link_inertia_kg_mm2: u32::try_from(inertia).unwrap_or(0),
        gains: config.gains.gains.as_ref().map(wire_gains),
        limits: limits_of(config, supervision),
        command_timeout_ms: supervision.command_timeout_ms,
    }
}

/// The service's side of the store: the store (if the board has one), the configuration
/// the board booted with (the defaults), the records in force, the last fault logged.
pub struct Settings {
    storage: Option<&'static mut (dyn Storage + Send)>,
    defaults: (Config, SupervisorConfig),
    pub(crate) stored: RecordSet,
    logged: Option<FaultRecord>,
    pub(crate) bus: crate::bus_settings::BusState,
}

impl core::fmt::Debug for Settings {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("Settings")
            .field("storage", &self.storage.is_some())
            .field("stored", &self.stored)
            .field("logged", &self.logged)
            .finish_non_exhaustive()
    }
}

impl Settings {
    /// No store; `config` and `supervision` are the defaults.
    #[must_use]
    pub const fn new(config: Config, supervision: SupervisorConfig) -> Self {
        Self {
            storage: None,
            defaults: (config, supervision),
            stored: RecordSet {
                config: None,
                calibration: None,
                bus: None,
            },
            logged: None,
            bus: crate::bus_settings::BusState::new(),
        }
    }
}

fn storage_error(e: StoreError) -> ErrorCode {
    match e {
        StoreError::Invalid { .. } => ErrorCode::OutOfRange,
        _ => ErrorCode::Storage,
    }
}

impl Service {
    /// The checks stored records go through on this service's design.
    #[must_use]
    pub fn checks(&self) -> Checks<'_> {
        Checks {
            design: &self.design,
            defaults: &self.settings.defaults,
        }
    }

    /// Takes `storage` as the board's settings store (the configuration in force now
    /// becomes the defaults), loads it and, if `apply`, applies what is stored and valid
    /// (a scripted run keeps its own configuration). Returns what became of each record,
    /// for the boot log. The motor stays as it is (disabled at boot).
    pub fn attach_store(
        &mut self,
        storage: &'static mut (dyn Storage + Send),
        actuator: &mut impl Mutex<T = Actuator>,
        apply: bool,
    ) -> (Report, FaultLog) {
        self.settings.defaults = (self.config, self.supervision);
        self.settings.storage = Some(storage);
        if !apply {
            let checks = Checks {
                design: &self.design,
                defaults: &self.settings.defaults,
            };
            let Some(storage) = self.settings.storage.as_deref_mut() else {
                return (Report::default(), FaultLog::default());
            };
            let boot = storage.load(&checks);
            self.settings.stored = boot.set;
            return (boot.report, boot.faults);
        }
        self.device(actuator).load_settings().unwrap_or_default()
    }

    /// The bus identity and settings in force: the stored ones, else the AX-12A's factory
    /// settings.
    #[must_use]
    pub fn bus_settings(&self) -> BusSettings {
        self.settings
            .stored
            .bus
            .unwrap_or_else(BusSettings::ax12a_default)
    }

    /// The stored calibration, if any.
    #[must_use]
    pub const fn calibration(&self) -> Option<Calibration> {
        self.settings.stored.calibration
    }

    /// Makes `bus` the bus settings in force and stores it (with the stored config and
    /// calibration).
    ///
    /// # Errors
    /// [`ErrorCode::NotAllowed`] while enabled, [`ErrorCode::OutOfRange`] if `bus` fails
    /// its checks (nothing changed); [`ErrorCode::Storage`] if it could not be stored (no
    /// store, or a flash error: it is in force until the next boot all the same).
    pub fn persist_bus(
        &mut self,
        bus: BusSettings,
        actuator: &mut impl Mutex<T = Actuator>,
    ) -> Result<(), ErrorCode> {
        bus.check().map_err(|_| ErrorCode::OutOfRange)?;
        let set = RecordSet {
            bus: Some(bus),
            ..self.settings.stored
        };
        self.device(actuator).store_set(set)
    }

    /// Makes `calibration` the calibration in force and stores it (with the stored config
    /// and bus settings).
    ///
    /// # Errors
    /// As [`Service::persist_bus`].
    pub fn persist_calibration(
        &mut self,
        calibration: Calibration,
        actuator: &mut impl Mutex<T = Actuator>,
    ) -> Result<(), ErrorCode> {
        calibration.check().map_err(|_| ErrorCode::OutOfRange)?;
        let set = RecordSet {
            calibration: Some(calibration),
            ..self.settings.stored
        };
        self.device(actuator).store_set(set)
    }

    /// Appends the fault latched since the last call to the stored fault log (the first
    /// fault of each latch, as the status reports it), once the motor is not enabled (a
    /// latched fault disables it). The firmware calls this from the command task.
    pub fn log_latched_fault(&mut self, actuator: &mut impl Mutex<T = Actuator>) {
        let (enabled, fault) = actuator.lock(|a| {
            (
                a.servo.state() == ServoState::Enabled,
                a.status().first_fault,
            )
        });
        let Some(fault) = fault else {
            return;
        };
        if enabled || self.settings.logged == Some(fault) {
            return;
        }
        self.settings.logged = Some(fault);
        if let Some(storage) = self.settings.storage.as_deref_mut() {
            // A flash error loses this entry only; the fault stays latched and reported.
            let _ = storage.log_fault(fault);
        }
    }
}

impl<M: Mutex<T = Actuator>> ServiceDevice<'_, M> {
    fn refuse_if_enabled(&mut self) -> Result<(), ErrorCode> {
        if self.actuator.lock(|a| a.servo.state()) == ServoState::Enabled {
            Err(ErrorCode::NotAllowed)
        } else {
            Ok(())
        }
    }

    /// The configuration in force as a config record.
    fn running(&self) -> store::Config {
        stored_config(&self.service.config, &self.service.supervision)
    }

    /// Whether the running configuration differs from the stored one (from the defaults
    /// when none is stored); `false` without a store.
    pub(crate) fn differs_from_stored(&self) -> bool {
        let s = &self.service.settings;
        if s.storage.is_none() {
            return false;
        }
        let stored = s
            .stored
            .config
            .unwrap_or_else(|| stored_config(&s.defaults.0, &s.defaults.1));
        self.running() != stored
    }

    /// Writes `set` (refused while enabled) and makes it the stored set.
    fn store_set(&mut self, set: RecordSet) -> Result<(), ErrorCode> {
        self.refuse_if_enabled()?;
        let service = &mut *self.service;
        let checks = Checks {
            design: &service.design,
            defaults: &service.settings.defaults,
        };
        let Some(storage) = service.settings.storage.as_deref_mut() else {
            service.settings.stored = set;
            return Err(ErrorCode::Storage);
        };
        storage.save(&set, &checks).map_err(storage_error)?;
        service.settings.stored = set;
        Ok(())
    }

    /// `save`: the running config with the stored calibration and bus settings.
    pub(crate) fn save_settings(&mut self) -> Result<(), ErrorCode> {
        let set = RecordSet {
            config: Some(self.running()),
            ..self.service.settings.stored
        };
        self.store_set(set)
    }

    /// `load`: re-reads the store and applies the stored config (the defaults if none is
    /// stored or it is rejected). A stored config that the device then refuses is
    /// reported rejected and the defaults apply.
    pub(crate) fn load_settings(&mut self) -> Result<(Report, FaultLog), ErrorCode> {
        let service = &mut *self.service;
        let checks = Checks {
            design: &service.design,
            defaults: &service.settings.defaults,
        };
        let storage = service
            .settings
            .storage
            .as_deref_mut()
            .ok_or(ErrorCode::Storage)?;
        let mut boot = storage.load(&checks);
        let faults = storage.fault_log();
        let defaults = service.settings.defaults;
        // Until the stored calibration (if any) is applied below, nothing confirms the clutch.
        service.calibrated_longest_um = None;
        service.set_offset_calibrated(false);
        let wanted = match boot.set.config {
            Some(c) => model_config(&c, &defaults),
            None => Ok(defaults),
        };
        let applied = wanted.and_then(|(c, s)| self.reconfigure(c, s).map(|_| ()));
        if applied.is_err() {
            boot.set.config = None;
            boot.report.config = Outcome::Rejected(Rejection::Invalid("refused by the device"));
            self.reconfigure(defaults.0, defaults.1)?;
        }
        self.service.settings.stored = boot.set;
        self.apply_stored_calibration();
        self.install_stored_correction();
        Ok((boot.report, faults))
    }

    /// `factory-reset`: forgets the stored records and the fault log, back to the defaults.
    pub(crate) fn reset_settings(&mut self) -> Result<(), ErrorCode> {
        self.refuse_if_enabled()?;
        let settings = &mut self.service.settings;
        let storage = settings.storage.as_deref_mut().ok_or(ErrorCode::Storage)?;
        storage.factory_reset().map_err(storage_error)?;
        settings.stored = RecordSet::default();
        let defaults = settings.defaults;
        self.service.calibrated_longest_um = None;
        self.service.set_offset_calibrated(false);
        self.reconfigure(defaults.0, defaults.1).map(|_| ())
    }

    /// `faults-log`: the log's length and entry `index` (0 = the most recent).
    pub(crate) fn logged_fault(
        &mut self,
        index: u8,
    ) -> Result<(u8, Option<LoggedFault>), ErrorCode> {
        let storage = self
            .service
            .settings
            .storage
            .as_deref_mut()
            .ok_or(ErrorCode::Storage)?;
        let log = storage.fault_log();
        let count = u8::try_from(log.len()).unwrap_or(u8::MAX);
        let entry = log
            .iter()
            .rev()
            .nth(usize::from(index))
            .map(|e| LoggedFault {
                seq: e.seq,
                fault: e.fault,
            });
        Ok((count, entry))
    }
}
