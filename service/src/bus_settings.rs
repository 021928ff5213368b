//! The Dynamixel bus settings between the bus device, our protocol and the store: which
//! are in force, switching them from our protocol ([`protocol::Request::SetBus`]), and
//! storing them.
//!
//! The bus device ([`crate::dynamixel::Bus`], in the link task) holds the settings in
//! force; the service keeps a copy ([`BusState`]) so that a `SetBus` request — handled
//! where the bus is out of reach — can check a change against them. Either side's change
//! is in force at once (the bus applies a `SetBus` after its reply) and is stored as the
//! `bus` record once the motor is off: programming the flash stalls the control loop
//! (`store`'s rule for `save`), so an EEPROM-area write made on the bus while torque is on
//! waits for torque off. At boot the stored record makes the bus device; without one,
//! the AX-12A's factory settings with the board's factory ID.

use protocol::{BusChange, ErrorCode};
use rtic_core::Mutex;
use store::{BusSettings, Record};

use crate::{Actuator, Service, ServiceDevice};

/// The service's side of the bus settings.
#[derive(Clone, Copy, Debug)]
pub(crate) struct BusState {
    /// The bus device's settings in force (`None`: no bus served).
    live: Option<BusSettings>,
    /// `live` is not stored yet.
    unsaved: bool,
    /// A `SetBus` changed `live`: the link applies it to its bus device.
    requested: bool,
    /// Whether the board's UART makes a rate, bit/s (`None`: any).
    uart_makes: Option<fn(u32) -> bool>,
}

impl BusState {
    pub(crate) const fn new() -> Self {
        BusState {
            live: None,
            unsaved: false,
            requested: false,
            uart_makes: None,
        }
    }
}

impl Service {
    /// The bus settings to start the bus device with: the stored ones, else the AX-12A's
    /// factory settings with `factory_id` (the board's `--dxl-id`).
    #[must_use]
    pub fn boot_bus_settings(&self, factory_id: u8) -> BusSettings {
        self.settings.stored.bus.unwrap_or(BusSettings {
            id: factory_id,
            ..BusSettings::ax12a_default()
        })
    }

    /// Whether the store holds bus settings.
    #[must_use]
    pub fn bus_settings_stored(&self) -> bool {
        self.settings.stored.bus.is_some()
    }

    /// Tells the service which line rates the board's UART makes (the board's check of a
    /// Baud Rate write or a `SetBus`); without it, any.
    pub fn set_uart_rates(&mut self, makes: fn(u32) -> bool) {
        self.settings.bus.uart_makes = Some(makes);
    }

    /// Whether the board's UART makes `bps`.
    #[must_use]
    pub fn uart_makes(&self, bps: u32) -> bool {
        self.settings.bus.uart_makes.is_none_or(|f| f(bps))
    }

    /// The bus device starts with `settings` (those of [`Service::boot_bus_settings`]).
    pub fn bus_started(&mut self, settings: BusSettings) {
        self.settings.bus.live = Some(settings);
        self.settings.bus.unsaved = false;
    }

    /// The bus device's settings are now `settings` (a write on the bus, or `SetBus`):
    /// stored once the motor is off if they differ from the stored ones.
    pub fn bus_in_force(&mut self, settings: BusSettings) {
        self.settings.bus.live = Some(settings);
        self.settings.bus.unsaved = self.settings.stored.bus != Some(settings);
    }

    /// The settings a `SetBus` put in force, for the bus device (once).
    pub(crate) fn take_bus_request(&mut self) -> Option<BusSettings> {
        let state = &mut self.settings.bus;
        core::mem::take(&mut state.requested)
            .then_some(state.live)
            .flatten()
    }

    /// Whether bus settings in force wait to be stored.
    #[must_use]
    pub fn bus_unsaved(&self) -> bool {
        self.settings.bus.unsaved
    }

    /// Stores the bus settings in force if they wait to be and the motor is off (the link
    /// task calls this when it has nothing else to do). One attempt per change: a flash
    /// error leaves them in force until the next boot.
    pub fn store_bus_settings(&mut self, actuator: &mut impl Mutex<T = Actuator>) {
        let _ = self.store_waiting_bus(actuator);
    }

    /// [`Service::store_bus_settings`], with what became of the attempt: `Ok` also when
    /// nothing waits or the motor is on (then they wait for it to go off).
    fn store_waiting_bus(
        &mut self,
        actuator: &mut impl Mutex<T = Actuator>,
    ) -> Result<(), ErrorCode> {
        let state = self.settings.bus;
        let Some(live) = state.live.filter(|_| state.unsaved) else {
            return Ok(());
        };
        match self.persist_bus(live, actuator) {
            Err(ErrorCode::NotAllowed) => Ok(()),
            stored => {
                self.settings.bus.unsaved = false;
                stored
            }
        }
    }
}

/// [`protocol::Request::SetBus`]: `change` over the settings in force, checked by the
/// control table's ranges ([`Record::check`]) and the UART; in force after the reply,
/// stored now if the motor is off, else once it is.
pub(crate) fn set<M: Mutex<T = Actuator>>(
    dev: &mut ServiceDevice<'_, M>,
    change: &BusChange,
) -> Result<(), ErrorCode> {
    let service = &mut *dev.service;
    let live = service.settings.bus.live.ok_or(ErrorCode::NotAllowed)?;
    let next = BusSettings {
        protocol_version: change.protocol_version.unwrap_or(live.protocol_version),
        id: change.id.unwrap_or(live.id),
        baud_bps: change.baud_bps.unwrap_or(live.baud_bps),
        ..live
    };
    next.check().map_err(|_| ErrorCode::OutOfRange)?;
    if !service.uart_makes(next.baud_bps) {
        return Err(ErrorCode::OutOfRange);
    }
    service.settings.bus.requested = true;
    service.bus_in_force(next);
    service.store_waiting_bus(dev.actuator)
}
