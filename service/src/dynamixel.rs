//! The actuator on a Dynamixel bus: a [`dynamixel::Backend`] over the servo, so that the
//! board answers Protocol 1.0 as an AX-12A and Protocol 2.0 as an X-series servo, with
//! the clutch and the stiffness as extra registers (tables in the `dynamixel` crate).
//!
//! [`Bus`] is the command task's persistent state (the decoders, the registers that are
//! pure settings); per call it borrows the [`Service`] and the shared [`Actuator`] like
//! [`crate::ServiceDevice`] does, so every register write reaches the servo through the
//! same preparation and the same checks as our own protocol's requests, between two
//! control ticks.
//!
//! What each register means on this actuator, what cannot be honoured, and the wiring:
//! `docs/dynamixel.md`. Latched faults show in every status as the hardware-error bits
//! ([`dynamixel::device::hardware`]): beam overload and over-current as overload
//! (over-current also as electrical shock), sensor faults as sensor.

use crate::{q32_to_micro, stiffness_mnm, Actuator, Service, ServiceDevice};
use dynamixel::device::hardware;
use dynamixel::table::calibration;
use dynamixel::{Backend, Field, Keep, MemoryBackend, Output, Port, Protocol, Refusal};
use model::control::trajectory::MIN_MOVE_MS;
use model::control::{ClutchSetting, Config};
use model::servo::{Prepared, ServoState};
use model::supervisor::FaultCode;
use model::{Length, Stiffness};
use protocol::{Device as _, MOVE_DURATION_MAX_MS};
use rtic_core::Mutex;
use store::BusSettings;

/// One AX-12A position count, nrad: 300° / 1024 = 5π/3072 rad.
pub const AX_COUNT_NRAD: i64 = 5_113_273;
/// AX-12A position count of the link angle 0 (the middle of 0–1023).
pub const AX_CENTRE: i32 = 512;
/// One X-series position pulse, nrad: 2π/4096 rad.
pub const X_PULSE_NRAD: i64 = 1_533_981;
/// X-series position of the link angle 0 (the middle of 0–4095).
pub const X_CENTRE: i32 = 2048;
/// One AX-12A speed unit, µrad/s: 0.111 rpm.
pub const AX_SPEED_URAD_S: i64 = 11_624;
/// One X-series velocity unit, µrad/s: 0.229 rpm.
pub const X_SPEED_URAD_S: i64 = 23_981;
/// The AX-12A's top speed (Moving Speed 1023, 114 rpm), what speed 0 ("no limit") means.
pub const TOP_SPEED_URAD_S: i64 = 1023 * AX_SPEED_URAD_S;
/// Full scale of Torque Limit and Present Load (AX: 1023 ≈ 100 %).
const AX_FULL_SCALE: i64 = 1023;
/// Full scale of the X series' Present Load (‰).
const X_FULL_SCALE: i64 = 1000;
/// AX direction bit of Present Speed and Present Load: the CW (negative) direction.
const AX_CW: i32 = 1 << 10;
/// Present Temperature without a sensor, °C (the in-memory backend's value too).
const NO_SENSOR_TEMPERATURE: i32 = 30;

/// Volts (I32F32) → 0.1 V, rounded.
fn volts_to_dv(v: fixed::types::I32F32) -> i32 {
    div_round(i64::from(q32_to_micro(v.to_bits())), 100_000) as i32
}

/// Rounded `a / b` for b > 0, half away from zero.
const fn div_round(a: i64, b: i64) -> i64 {
    if a >= 0 {
        (a + b / 2) / b
    } else {
        (a - b / 2) / b
    }
}

/// Position register → link angle, µrad, for a register with `centre` at 0 rad and
/// `nrad` nanoradians per step.
const fn register_to_urad(value: i32, centre: i32, nrad: i64) -> i32 {
    div_round((value - centre) as i64 * nrad, 1000) as i32
}

/// Link angle, µrad → position register (the inverse of [`register_to_urad`]), clamped to
/// 0..=`max`.
const fn urad_to_register(urad: i32, centre: i32, nrad: i64, max: i32) -> i32 {
    let c = centre as i64 + div_round(urad as i64 * 1000, nrad);
    if c < 0 {
        0
    } else if c > max as i64 {
        max
    } else {
        c as i32
    }
}

/// AX position count → link angle, µrad.
#[must_use]
pub const fn ax_count_to_urad(count: i32) -> i32 {
    register_to_urad(count, AX_CENTRE, AX_COUNT_NRAD)
}

/// Link angle, µrad → AX position count, clamped to 0–1023.
#[must_use]
pub const fn urad_to_ax_count(urad: i32) -> i32 {
    urad_to_register(urad, AX_CENTRE, AX_COUNT_NRAD, 1023)
}

/// X position → link angle, µrad.
#[must_use]
pub const fn x_pulse_to_urad(pulse: i32) -> i32 {
    register_to_urad(pulse, X_CENTRE, X_PULSE_NRAD)
}

/// Link angle, µrad → X position, clamped to 0–4095.
#[must_use]
pub const fn urad_to_x_pulse(urad: i32) -> i32 {
    urad_to_register(urad, X_CENTRE, X_PULSE_NRAD, 4095)
}

/// A signed quantity in AX sign-magnitude: |v| clamped to 1023, bit 10 when negative (CW).
const fn ax_signed(v: i64) -> i32 {
    let m = if v < 0 { -v } else { v };
    let m = if m > 1023 { 1023 } else { m as i32 };
    if v < 0 {
        m | AX_CW
    } else {
        m
    }
}

/// Duration of a minimum-jerk move over `distance_urad` whose peak speed (1.875 × the mean,
/// §11's trajectory) is `speed_urad_s`, ms, within what a move may last.
#[must_use]
pub fn move_duration_ms(distance_urad: i64, speed_urad_s: i64) -> u32 {
    let v = if speed_urad_s <= 0 {
        TOP_SPEED_URAD_S
    } else {
        speed_urad_s
    };
    // T = 1.875·D/v s = 1875·D/v ms.
    let ms = (distance_urad.unsigned_abs() as i64).saturating_mul(1875) / v;
    u32::try_from(ms)
        .unwrap_or(u32::MAX)
        .clamp(MIN_MOVE_MS, MOVE_DURATION_MAX_MS)
}

/// The bus side of the actuator that lives between calls: the decoders and the registers
/// the servo does not hold.
pub struct Bus {
    port: Port,
    regs: Registers,
}

/// The registers that are pure settings (ID, baud, return delay, limits, compliance, goal,
/// speed, …) in the in-memory store with the tables' defaults, and what the bus changed.
struct Registers {
    store: MemoryBackend,
    /// A goal was written while torque was off: go there when torque comes on.
    goal_pending: bool,
    /// A setting that lives beyond power-off (EEPROM area) changed since the last
    /// [`Bus::settings_changed`].
    eeprom_dirty: bool,
}

/// The backend of one call.
struct ServoBackend<'r, 'a, M> {
    regs: &'r mut Registers,
    dev: ServiceDevice<'a, M>,
}

impl Bus {
    /// A device with `id` on the bus, speaking `protocol`, every other setting at its
    /// table default.
    #[must_use]
    pub fn new(id: u8, protocol: Protocol) -> Self {
        let mut store = MemoryBackend::new(id, protocol);
        let port = Port::new(&mut store);
        Bus {
            port,
            regs: Registers {
                store,
                goal_pending: false,
                eeprom_dirty: false,
            },
        }
    }

    /// The protocol being spoken.
    #[must_use]
    pub fn protocol(&self) -> Protocol {
        self.port.protocol()
    }

    /// The device's ID.
    #[must_use]
    pub fn id(&self) -> u8 {
        u8::try_from(self.regs.store.get(Field::Id)).unwrap_or(u8::MAX)
    }

    /// The line's bit rate the settings ask for, bps.
    #[must_use]
    pub fn baud_bps(&self) -> Option<u32> {
        let field = match self.protocol() {
            Protocol::V1 => Field::BaudRate,
            Protocol::V2 => Field::BaudRateX,
        };
        dynamixel::table::baud_bps(self.protocol(), self.regs.store.get(field))
    }

    /// What the device has heard.
    #[must_use]
    pub fn counters(&self) -> dynamixel::Counters {
        self.port.counters()
    }

    /// Whether a packet has begun and is not yet decided.
    #[must_use]
    pub fn receiving(&self) -> bool {
        self.port.receiving()
    }

    /// One byte heard on the line (not one this device sent).
    pub fn push(&mut self, byte: u8) {
        self.port.push(byte);
    }

    /// The line has been idle for a character time.
    pub fn idle(&mut self) {
        self.port.idle();
    }

    /// The next thing to do for the bytes heard so far (call until `None`): the status to
    /// send after its delay, and what to do after it.
    pub fn poll<M: Mutex<T = Actuator>>(
        &mut self,
        service: &mut Service,
        actuator: &mut M,
    ) -> Option<Output> {
        let mut backend = ServoBackend {
            regs: &mut self.regs,
            dev: service.device(actuator),
        };
        self.port.poll(&mut backend)
    }

    /// REBOOT: the bus state starts anew (Lock and a registered write cleared); the
    /// settings and the actuator stay as they are (the board itself does not restart).
    pub fn restart(&mut self) {
        self.port = Port::new(&mut self.regs.store);
    }

    /// The compliance registers (CW margin, CCW margin, CW slope, CCW slope; AX units) for
    /// the controller's virtual compliance. The hook for an impedance command: nothing
    /// applies them yet.
    #[must_use]
    pub fn compliance(&self) -> [i32; 4] {
        [
            Field::CwComplianceMargin,
            Field::CcwComplianceMargin,
            Field::CwComplianceSlope,
            Field::CcwComplianceSlope,
        ]
        .map(|f| self.regs.store.get(f))
    }

    /// Sets the Calibration State register ([`calibration`] values), the calibration's hook.
    pub fn set_calibration_state(&mut self, state: i32) {
        self.regs.store.set(Field::CalibrationState, state);
    }

    /// Switches the protocol (from our own protocol or the command line); takes effect at
    /// once, dropping any partial packet.
    pub fn set_protocol(&mut self, protocol: Protocol) {
        self.regs.store.set(Field::BusProtocol, protocol.number());
        self.regs.eeprom_dirty = true;
        self.port = Port::new(&mut self.regs.store);
    }

    /// Whether an EEPROM-area setting (ID, baud, protocol, limits, …) changed since the
    /// last call (the link then hands them to the store, `crate::bus_settings`).
    pub fn settings_changed(&mut self) -> bool {
        core::mem::take(&mut self.regs.eeprom_dirty)
    }

    /// The value of a stored setting (for the store's hook and the tests).
    #[must_use]
    pub fn setting(&self, field: Field) -> i32 {
        self.regs.store.get(field)
    }

    /// A device with the stored bus `settings` (ID, protocol, the protocol's Baud Rate,
    /// return delay, status return level, angle limits, the other EEPROM-area limits);
    /// every other register at its table default.
    #[must_use]
    pub fn from_settings(settings: &BusSettings) -> Self {
        let protocol =
            Protocol::from_number(i32::from(settings.protocol_version)).unwrap_or(Protocol::V1);
        let mut bus = Bus::new(settings.id, protocol);
        bus.apply(settings);
        bus.regs.eeprom_dirty = false;
        bus
    }

    /// The bus settings in force, as the store keeps them (the baud rate is the active
    /// protocol's Baud Rate register's).
    #[must_use]
    pub fn settings(&self) -> BusSettings {
        let byte = |f| u8::try_from(self.regs.store.get(f)).unwrap_or(u8::MAX);
        let word = |f| u16::try_from(self.regs.store.get(f)).unwrap_or(u16::MAX);
        BusSettings {
            id: self.id(),
            baud_bps: self.baud_bps().unwrap_or(0),
            protocol_version: u8::try_from(self.protocol().number()).unwrap_or(1),
            return_delay_2us: byte(Field::ReturnDelayTime),
            status_return_level: byte(Field::StatusReturnLevel),
            cw_angle_limit: word(Field::CwAngleLimit),
            ccw_angle_limit: word(Field::CcwAngleLimit),
            limits: store::BusLimits::from_fields(|f| self.regs.store.get(f)),
        }
    }

    /// Makes `settings` the ones in force (our protocol's `SetBus`, or the store at boot):
    /// the registers take them (the baud rate goes to the register of `settings`'
    /// protocol, where it selects one), and a change of protocol drops any partial
    /// packet. Lock and a registered write survive unless the protocol changes.
    pub fn apply(&mut self, settings: &BusSettings) {
        let protocol =
            Protocol::from_number(i32::from(settings.protocol_version)).unwrap_or(Protocol::V1);
        let store = &mut self.regs.store;
        store.set(Field::Id, i32::from(settings.id));
        if let Some(v) = dynamixel::table::baud_register(protocol, settings.baud_bps) {
            let field = match protocol {
                Protocol::V1 => Field::BaudRate,
                Protocol::V2 => Field::BaudRateX,
            };
            store.set(field, v);
        }
        store.set(Field::ReturnDelayTime, i32::from(settings.return_delay_2us));
        store.set(
            Field::StatusReturnLevel,
            i32::from(settings.status_return_level),
        );
        store.set(Field::CwAngleLimit, i32::from(settings.cw_angle_limit));
        store.set(Field::CcwAngleLimit, i32::from(settings.ccw_angle_limit));
        for (field, value) in settings.limits.fields() {
            store.set(field, value);
        }
        if protocol != self.protocol() {
            self.set_protocol(protocol);
        }
        self.regs.eeprom_dirty = true;
    }
}

impl<M: Mutex<T = Actuator>> ServoBackend<'_, '_, M> {
    fn enabled(&mut self) -> bool {
        self.dev
            .actuator
            .lock(|a| a.servo.state() == ServoState::Enabled)
    }

    /// The supply the board measured, 0.1 V (Present Voltage's unit), if it has a sense
    /// and a window has passed.
    fn measured_supply_dv(&mut self) -> Option<i32> {
        self.dev
            .actuator
            .lock(|a| a.measured_supply())
            .map(volts_to_dv)
    }

    /// The measured link angle, µrad.
    fn link_urad(&mut self) -> i32 {
        let bits = self.dev.actuator.lock(|a| a.link_angle);
        q32_to_micro(bits)
    }

    /// The goal in force, µrad, and the speed limit, µrad/s, in the units of `protocol`.
    fn goal_and_speed(&self, protocol: Protocol) -> (i32, i64) {
        let s = &self.regs.store;
        match protocol {
            Protocol::V1 => (
                ax_count_to_urad(s.get(Field::GoalPosition)),
                i64::from(s.get(Field::MovingSpeed)) * AX_SPEED_URAD_S,
            ),
            Protocol::V2 => (
                x_pulse_to_urad(s.get(Field::GoalPositionX)),
                i64::from(s.get(Field::ProfileVelocity)) * X_SPEED_URAD_S,
            ),
        }
    }

    /// A move to `goal_urad` at the speed limit; only while enabled.
    fn go_to(&mut self, goal_urad: i32, speed_urad_s: i64) {
        let here = self.link_urad();
        let duration = move_duration_ms(i64::from(goal_urad) - i64::from(here), speed_urad_s);
        let _ = self.dev.command_move(goal_urad, duration);
    }

    fn protocol(&self) -> Protocol {
        Protocol::from_number(self.regs.store.get(Field::BusProtocol)).unwrap_or(Protocol::V1)
    }

    /// The beams' stress-limited capacity τ_cap(L), µN·m.
    fn capacity_unm(&mut self) -> i64 {
        self.dev.actuator.lock(|a| {
            let cap = a.servo.controller().schedule().setting().torque_capacity();
            i64::from(q32_to_micro(cap.to_bits()))
        })
    }

    /// The configuration with `clutch`, prepared (the same checks as our protocol's
    /// SetClutchLength / SetStiffness).
    fn prepare(&self, clutch: ClutchSetting) -> Result<Config, Refusal> {
        let mut config = *self.dev.service.config();
        config.clutch = clutch;
        Prepared::new(
            &self.dev.service.design,
            &config,
            self.dev.service.supervision(),
        )
        .map(|_| config)
        .map_err(|_| Refusal::Range)
    }

    /// The controller's limits with Torque Limit `v` (0–1023) as the torque margin.
    fn limits_with_torque(&mut self, v: i32) -> protocol::Limits {
        let mut limits = self.dev.limits();
        let permille = div_round(i64::from(v) * 1000, AX_FULL_SCALE).clamp(1, 1000);
        limits.torque_margin_permille = permille as u16;
        limits
    }
}

fn clutch_length(length_um: i32) -> ClutchSetting {
    ClutchSetting::Length(Length::from_bits(crate::milli_to_q32(length_um.into())))
}

fn clutch_stiffness(mnm_per_rad: i32) -> ClutchSetting {
    // mN·m/rad = 1000 µN·m/rad.
    ClutchSetting::Stiffness(Stiffness::from_micro(i64::from(mnm_per_rad) * 1_000))
}

impl<M: Mutex<T = Actuator>> Backend for ServoBackend<'_, '_, M> {
    fn read(&mut self, field: Field) -> i32 {
        match field {
            Field::TorqueEnable => i32::from(self.enabled()),
            Field::PresentPosition => urad_to_ax_count(self.link_urad()),
            Field::PresentPositionX => urad_to_x_pulse(self.link_urad()),
            Field::PresentSpeed | Field::PresentVelocityX => {
                let urad_s = i64::from(self.dev.actuator.lock(|a| q32_to_micro(a.link_velocity)));
                if field == Field::PresentSpeed {
                    ax_signed(div_round(urad_s, AX_SPEED_URAD_S))
                } else {
                    div_round(urad_s, X_SPEED_URAD_S) as i32
                }
            }
            Field::PresentLoad | Field::PresentLoadX => {
                let torque = i64::from(self.dev.actuator.lock(|a| q32_to_micro(a.torque)));
                let cap = self.capacity_unm().max(1);
                if field == Field::PresentLoad {
                    ax_signed(div_round(torque * AX_FULL_SCALE, cap))
                } else {
                    div_round(torque * X_FULL_SCALE, cap).clamp(-X_FULL_SCALE, X_FULL_SCALE) as i32
                }
            }
            Field::TorqueLimit => {
                let margin = self.dev.service.config().limits.torque_margin;
                div_round(
                    i64::from(q32_to_micro(margin.to_bits())) * AX_FULL_SCALE,
                    1_000_000,
                ) as i32
            }
            Field::Moving => self
                .dev
                .actuator
                .lock(|a| i32::from(a.servo.controller().trajectory().is_moving())),
            Field::PresentVoltage => self
                .measured_supply_dv()
                .unwrap_or_else(|| volts_to_dv(self.dev.service.config().motor.supply_v)),
            Field::PresentTemperature => NO_SENSOR_TEMPERATURE,
            Field::ClutchLength => self.dev.actuator.lock(|a| {
                let l = a.servo.controller().schedule().setting().length();
                crate::q32_to_milli(l.to_bits())
            }),
            Field::Stiffness => self.dev.actuator.lock(|a| {
                i32::try_from(stiffness_mnm(a.servo.controller().schedule().stiffness()))
                    .unwrap_or(i32::MAX)
            }),
            Field::BeamCapacity => i32::try_from(self.capacity_unm()).unwrap_or(i32::MAX),
            Field::Faults => i32::from(self.dev.actuator.lock(|a| a.servo.faults().0)),
            f => self.regs.store.get(f),
        }
    }

    fn check(&mut self, field: Field, value: i32) -> Result<(), Refusal> {
        match field {
            Field::GoalPosition | Field::GoalPositionX => {
                let urad = if field == Field::GoalPosition {
                    ax_count_to_urad(value)
                } else {
                    x_pulse_to_urad(value)
                };
                // The supervisor's position window: our protocol's target check.
                self.dev
                    .target(urad)
                    .map(|_| ())
                    .map_err(|_| Refusal::Limit)
            }
            Field::TorqueEnable if value != 0 => {
                let faulted = self
                    .dev
                    .actuator
                    .lock(|a| a.servo.state() == ServoState::Faulted);
                if faulted {
                    Err(Refusal::Failed)
                } else {
                    Ok(())
                }
            }
            Field::TorqueLimit => {
                let limits = self.limits_with_torque(value);
                // Our protocol's own check of a SetLimits request.
                protocol::Request::SetLimits(limits)
                    .validate()
                    .map_err(|_| Refusal::Range)
            }
            Field::BaudRate | Field::BaudRateX => {
                let protocol = if field == Field::BaudRate {
                    Protocol::V1
                } else {
                    Protocol::V2
                };
                // The rate the register selects must be one the board's UART makes.
                dynamixel::table::baud_bps(protocol, value)
                    .filter(|&bps| self.dev.service.uart_makes(bps))
                    .map(|_| ())
                    .ok_or(Refusal::Range)
            }
            Field::ClutchLength => self.prepare(clutch_length(value)).map(|_| ()),
            Field::Stiffness => self.prepare(clutch_stiffness(value)).map(|_| ()),
            Field::Faults => match self.dev.persisting_fault() {
                Some(_) => Err(Refusal::Failed),
                None => Ok(()),
            },
            _ => Ok(()),
        }
    }

    fn write(&mut self, field: Field, value: i32) {
        let area_eeprom = self
            .protocol()
            .table()
            .register(field)
            .is_some_and(|r| r.area == dynamixel::table::Area::Eeprom);
        match field {
            Field::TorqueEnable if value != 0 => {
                if !self.enabled() && self.dev.enable().is_ok() {
                    let protocol = self.protocol();
                    if self.regs.goal_pending {
                        let (goal, speed) = self.goal_and_speed(protocol);
                        self.go_to(goal, speed);
                    } else {
                        // The AX-12A holds where it is: the goal becomes the present position.
                        let here = self.link_urad();
                        self.regs
                            .store
                            .set(Field::GoalPosition, urad_to_ax_count(here));
                        self.regs
                            .store
                            .set(Field::GoalPositionX, urad_to_x_pulse(here));
                    }
                    self.regs.goal_pending = false;
                }
            }
            Field::TorqueEnable => {
                let _ = self.dev.disable();
            }
            Field::GoalPosition | Field::GoalPositionX => {
                self.regs.store.set(field, value);
                let protocol = self.protocol();
                if self.enabled() {
                    let (goal, speed) = self.goal_and_speed(protocol);
                    self.go_to(goal, speed);
                } else {
                    self.regs.goal_pending = true;
                }
            }
            Field::TorqueLimit => {
                let limits = self.limits_with_torque(value);
                let _ = self.dev.set_limits(&limits);
            }
            Field::ClutchLength => {
                let _ = self.dev.set_clutch_length(value.unsigned_abs());
            }
            Field::Stiffness => {
                let _ = self.dev.set_stiffness(value.unsigned_abs());
            }
            Field::Faults => {
                let _ = self.dev.clear_fault();
            }
            f => self.regs.store.set(f, value),
        }
        self.regs.eeprom_dirty |= area_eeprom;
    }

    fn factory_reset(&mut self, keep: Keep) {
        // The stored settings only: the clutch is where the user's hand put it.
        self.regs.store.factory_reset(keep);
        self.regs
            .store
            .set(Field::CalibrationState, calibration::UNCALIBRATED);
        self.regs.eeprom_dirty = true;
    }

    fn hardware_errors(&mut self) -> u8 {
        let faults = self.dev.actuator.lock(|a| a.servo.faults());
        // The supply the board measures outside the voltage limits (stored, 0.1 V).
        let (lo, hi) = (
            self.regs.store.get(Field::MinVoltageLimit),
            self.regs.store.get(Field::MaxVoltageLimit),
        );
        let mut bits = match self.measured_supply_dv() {
            Some(dv) if dv < lo || dv > hi => hardware::INPUT_VOLTAGE,
            _ => 0,
        };
        for code in FaultCode::ALL {
            if !faults.contains(code) {
                continue;
            }
            bits |= match code {
                FaultCode::BeamOverload => hardware::OVERLOAD,
                FaultCode::OverCurrent => hardware::OVERLOAD | hardware::ELECTRICAL_SHOCK,
                FaultCode::SensorRead
                | FaultCode::AdcOutOfRange
                | FaultCode::SensorJump
                | FaultCode::SensorStuck => hardware::SENSOR,
                _ => 0,
            };
        }
        bits
    }
}
