//! The servo: the controller under the supervisor, with the enable state machine. This is
//! the whole per-tick decision of the firmware, from raw readings to what the H-bridge
//! must do, independent of any hardware (the firmware reads its sensors through drivers,
//! calls [`Servo::tick`] and applies [`TickOutput::bridge`]).
//!
//! States: [`ServoState::Disabled`] (motor off; the controller keeps tracking the sensors)
//! → [`Servo::enable`] → [`ServoState::Enabled`] (the controller drives) → a fault →
//! [`ServoState::Faulted`] (motor off in the same tick, latched) → [`Servo::clear_fault`]
//! → [`ServoState::Disabled`]. Nothing but an explicit clear leaves `Faulted`, and nothing
//! but an explicit enable turns the motor on.

use crate::control::rest_resistance::{offset_tolerance_q16, RestResistance};
use crate::control::supply_window::SupplyWindow;
use crate::control::{
    Command, Config, ControlError, Controller, Impedance, ImpedanceCommand, ImpedanceError,
    Measurements, Output,
};
use crate::supervisor::{
    Fault, FaultCode, FaultSet, Readings, Sensor, Supervisor, SupervisorConfig, SupervisorError,
};
use crate::Design;

/// Enable state.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ServoState {
    /// Motor off, waiting for an enable.
    Disabled,
    /// The controller drives the motor.
    Enabled,
    /// A fault is latched; the motor is off until [`Servo::clear_fault`].
    Faulted,
}

/// What the H-bridge must do this tick.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum BridgeDemand {
    /// Drive with this duty, ‰.
    Drive(i16),
    /// Output stage off (disabled): the motor free-wheels.
    Off,
    /// Motor terminals shorted through the bridge's low sides (PWM 0, output stage on):
    /// dynamic braking, the reaction to a fault of the mechanics or the sensors
    /// ([`brakes_on`]). Never turns on a bridge that is off.
    Brake,
}

impl BridgeDemand {
    /// The duty the bridge applies, ‰: 0 unless driving.
    #[must_use]
    pub const fn duty(self) -> i16 {
        match self {
            BridgeDemand::Drive(d) => d,
            BridgeDemand::Off | BridgeDemand::Brake => 0,
        }
    }

    /// Whether the bridge drives the motor (neither off nor braking).
    #[must_use]
    pub const fn drives(self) -> bool {
        matches!(self, BridgeDemand::Drive(_))
    }
}

/// Whether the servo brakes (rather than coasts) once `faults` are latched: braking
/// needs a healthy bridge and current path, so an over-current, a current ADC at its
/// rail or a missed deadline (the firmware's timing) turn the bridge off; any other fault
/// shorts the motor. Measured on the acceptance grid's trips (docs/design.md §11, "Fault
/// reaction"): braking cut the link's runaway under load about sevenfold and the beam
/// stress after the trip in 6 of 7 runs.
#[must_use]
pub const fn brakes_on(faults: FaultSet) -> bool {
    !faults.is_empty()
        && !faults.contains(FaultCode::OverCurrent)
        && !faults.contains(FaultCode::AdcOutOfRange)
        && !faults.contains(FaultCode::DeadlineMissed)
}

/// Why a servo request was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ServoError {
    /// The controller rejected the configuration or command.
    Control(ControlError),
    /// The supervisor rejected its configuration.
    Supervisor(SupervisorError),
    /// Not allowed while faulted (clear first).
    Faulted,
    /// The impedance command was refused.
    Impedance(ImpedanceError),
    /// The sensor correction was rejected (`crate::calibration::pipeline`).
    Correction(crate::calibration::correction::CorrectionError),
}

impl core::fmt::Display for ServoError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            ServoError::Control(e) => write!(f, "controller: {e}"),
            ServoError::Supervisor(e) => write!(f, "supervisor: {e}"),
            ServoError::Faulted => f.write_str("a fault is latched (clear it first)"),
            ServoError::Impedance(e) => write!(f, "impedance: {e}"),
            ServoError::Correction(e) => write!(f, "sensor correction: {e}"),
        }
    }
}

impl core::error::Error for ServoError {}

/// One tick's raw inputs.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TickInput {
    /// Link encoder, raw counts.
    pub link_encoder: u16,
    /// Gear pot, raw counts, if fitted.
    pub gear_pot: Option<u16>,
    /// Current ADC, raw counts.
    pub current_adc: u16,
    /// Supply sense, raw counts ([`crate::sensors::SUPPLY_MV_PER_COUNT`]), if the board has
    /// one and its read succeeded: advisory, averaged after the tick
    /// ([`crate::control::supply_window`]); a failed read is left out, not a fault.
    pub supply_adc: Option<u16>,
    /// A driver failed (its reading is the last good one).
    pub read_error: Option<Sensor>,
}

/// One tick's decision.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TickOutput {
    /// The control tick this is (1-based).
    pub tick: u32,
    /// What the H-bridge must do.
    pub bridge: BridgeDemand,
    /// The controller's output (estimates, live limits), computed in every state.
    pub control: Output,
    /// A fault latched in this tick (the motor is already off in `bridge`).
    pub new_fault: Option<Fault>,
    /// State after this tick.
    pub state: ServoState,
}

/// A configuration checked and turned into gains and thresholds ahead of time (the slow
/// maths: roots, divisions), ready for [`Servo::restart_prepared`] to install in a tick.
#[derive(Clone, Debug)]
pub struct Prepared {
    controller: Controller,
    supervisor: Supervisor,
}

impl Prepared {
    /// Prepares `config` for `design` with the supervisor settings `supervision`.
    ///
    /// # Errors
    /// A rejected configuration.
    pub fn new(
        design: &Design,
        config: &Config,
        supervision: &SupervisorConfig,
    ) -> Result<Prepared, ServoError> {
        let controller = Controller::new(design, config).map_err(ServoError::Control)?;
        let supervisor =
            Supervisor::new(supervision, controller.schedule()).map_err(ServoError::Supervisor)?;
        Ok(Prepared {
            controller,
            supervisor,
        })
    }

    /// The prepared controller (its schedule: L, k, gains).
    #[must_use]
    pub const fn controller(&self) -> &Controller {
        &self.controller
    }
}

/// The controller, the supervisor and the enable state.
#[derive(Clone, Debug)]
pub struct Servo {
    design: Design,
    controller: Controller,
    supervisor: Supervisor,
    state: ServoState,
    tick: u32,
    /// Whether the motor was off during the last tick (the observer must know).
    was_off: bool,
    /// The impedance command in force, if any: it sets the position loop's reference
    /// every tick.
    impedance: Option<Impedance>,
}

impl Servo {
    /// A disabled servo for `design` with the controller and supervisor configurations.
    ///
    /// # Errors
    /// A rejected configuration.
    pub fn new(
        design: &Design,
        config: &Config,
        supervision: &SupervisorConfig,
    ) -> Result<Servo, ServoError> {
        let controller = Controller::new(design, config).map_err(ServoError::Control)?;
        let supervisor =
            Supervisor::new(supervision, controller.schedule()).map_err(ServoError::Supervisor)?;
        Ok(Servo {
            design: *design,
            controller,
            supervisor,
            state: ServoState::Disabled,
            tick: 0,
            was_off: true,
            impedance: None,
        })
    }

    /// The state.
    #[must_use]
    pub const fn state(&self) -> ServoState {
        self.state
    }

    /// Ticks run so far.
    #[must_use]
    pub const fn ticks(&self) -> u32 {
        self.tick
    }

    /// The controller.
    #[must_use]
    pub const fn controller(&self) -> &Controller {
        &self.controller
    }

    /// The supervisor.
    #[must_use]
    pub const fn supervisor(&self) -> &Supervisor {
        &self.supervisor
    }

    /// The latched faults.
    #[must_use]
    pub const fn faults(&self) -> FaultSet {
        self.supervisor.latched()
    }

    /// Turns the motor on from `Disabled`: the controller restarts holding the link where
    /// it is (integrator and filters reset). No effect when already enabled.
    ///
    /// # Errors
    /// [`ServoError::Faulted`] while a fault is latched.
    pub fn enable(&mut self) -> Result<(), ServoError> {
        match self.state {
            ServoState::Faulted => Err(ServoError::Faulted),
            ServoState::Enabled => Ok(()),
            ServoState::Disabled => {
                self.controller.reset();
                self.impedance = None;
                self.state = ServoState::Enabled;
                Ok(())
            }
        }
    }

    /// Turns the motor off (from any state but `Faulted`, which stays).
    pub fn disable(&mut self) {
        self.impedance = None;
        if self.state == ServoState::Enabled {
            self.state = ServoState::Disabled;
        }
    }

    /// Clears the latched faults: `Faulted` → `Disabled` (the motor stays off until
    /// [`Servo::enable`]). A condition still present latches again at the next tick.
    pub fn clear_fault(&mut self) {
        self.supervisor.clear();
        if self.state == ServoState::Faulted {
            self.state = ServoState::Disabled;
        }
    }

    /// A heartbeat from the host, received before the next tick (arms the command
    /// timeout): counted at the tick about to run.
    pub fn heartbeat(&mut self) {
        self.supervisor.heartbeat(self.tick.wrapping_add(1));
    }

    /// Ends the heartbeat session: the command timeout is off until the next heartbeat.
    pub fn disarm_heartbeat(&mut self) {
        self.supervisor.disarm_heartbeat();
    }

    /// Gives the controller a new command (it ends an impedance command).
    ///
    /// # Errors
    /// [`ServoError::Faulted`] while faulted; the controller's rejection.
    pub fn command(&mut self, cmd: Command) -> Result<(), ServoError> {
        if self.state == ServoState::Faulted {
            return Err(ServoError::Faulted);
        }
        self.controller.command(cmd).map_err(ServoError::Control)?;
        self.impedance = None;
        Ok(())
    }

    /// Starts an impedance command (`crate::control::impedance`): from the next tick the
    /// position loop's reference follows the virtual spring-damper, until a position
    /// command, a disable, a fault or a new configuration (which holds the last reference).
    ///
    /// # Errors
    /// [`ServoError::Faulted`] while faulted; [`ServoError::Impedance`] for a value out of
    /// range, among them a virtual stiffness above the beams' at the clutch setting.
    pub fn impedance(&mut self, cmd: &ImpedanceCommand) -> Result<(), ServoError> {
        if self.state == ServoState::Faulted {
            return Err(ServoError::Faulted);
        }
        let start = self.controller.trajectory().reference().position;
        let c = &self.controller;
        let imp = Impedance::new(cmd, c.schedule(), c.config().link_inertia)
            .map_err(ServoError::Impedance)?;
        self.controller
            .command(imp.approach(start))
            .map_err(ServoError::Control)?;
        self.impedance = Some(imp);
        Ok(())
    }

    /// The impedance command in force, if any.
    #[must_use]
    pub const fn impedance_command(&self) -> Option<&ImpedanceCommand> {
        match &self.impedance {
            Some(imp) => Some(imp.command()),
            None => None,
        }
    }

    /// Applies a new controller configuration (e.g. a clutch length) and re-derives the
    /// supervisor's thresholds; on any error nothing changes.
    ///
    /// # Errors
    /// A rejected configuration.
    pub fn configure(&mut self, config: &Config) -> Result<(), ServoError> {
        let mut controller = self.controller.clone();
        controller.configure(config).map_err(ServoError::Control)?;
        let mut supervisor = self.supervisor;
        let sup_cfg = *supervisor.config();
        supervisor
            .reconfigure(&sup_cfg, controller.schedule())
            .map_err(ServoError::Supervisor)?;
        self.controller = controller;
        self.supervisor = supervisor;
        self.impedance = None;
        Ok(())
    }

    /// After [`Servo::tick`], outside the control step: the running move's velocity
    /// feed-forward scale takes the tick's observer velocity, current and gear travel, and
    /// a raw step's or a move's first duty jump gives the observer's resistance
    /// ([`crate::control::Controller::track_speed`]; only while the bridge drove). The
    /// service calls it after each tick, as it keeps the rest resistance's window.
    pub fn track_speed(&mut self, out: &TickOutput) {
        if out.bridge.drives() {
            self.controller.track_speed(&out.control);
        }
    }

    /// The configuration to prepare when the actuator differs from the one in force
    /// beyond a tolerance: the supply the board measured (`supply`, kept by the caller
    /// after each tick: [`SupplyWindow::tick`]), then the armature resistance a still,
    /// held link under load showed (`window`: [`RestResistance::tick`]), that resistance
    /// taken with the supply now in force. Returns the one in force with those, and the
    /// supervisor's settings in force. `offset_calibrated`: a calibration is in force and
    /// the current sense's zero known; without one the resistance moves only as far as the
    /// offset's tolerance allows ([`RestResistance::differs_from`]). Called before a
    /// command (docs/design.md §11, "The supply the board measures", "Tracking a warm
    /// motor's resistance").
    #[must_use]
    pub fn tracked_configuration(
        &self,
        supply: &SupplyWindow,
        window: &RestResistance,
        offset_calibrated: bool,
    ) -> Option<(Config, SupervisorConfig)> {
        let mut config = *self.controller.config();
        let configured = config.motor.supply_v;
        config.motor.supply_v = supply.in_force(configured);
        let resistance = window.differs_from(
            config.motor.supply_v,
            config.motor.resistance_ohm,
            offset_tolerance_q16(offset_calibrated),
        );
        if let Some(r) = resistance {
            config.motor.resistance_ohm = r;
        }
        (config.motor.supply_v != configured || resistance.is_some())
            .then(|| (config, *self.supervisor.config()))
    }

    /// Takes a configuration prepared ahead of time (its schedule and thresholds, a copy,
    /// no maths) and keeps the state: an enabled servo holds on with its integrator and
    /// filters, the sensor history stays, latched faults stay latched; the clutch monitor
    /// starts its evidence again (new thresholds). For a change of the motor's parameters
    /// between commands ([`Servo::tracked_configuration`]).
    ///
    /// # Errors
    /// A running sine's feed-forward that does not fit the new schedule.
    pub fn adopt_prepared(&mut self, prepared: &Prepared) -> Result<(), ServoError> {
        self.controller
            .adopt(&prepared.controller)
            .map_err(ServoError::Control)?;
        self.supervisor.install_thresholds(&prepared.supervisor);
        Ok(())
    }

    /// Restarts on a configuration prepared ahead of time: disable, install its controller
    /// and thresholds (a copy, no maths), forget the sensor history (the mechanism may have
    /// been moved or re-mounted meanwhile), enable. Latched faults stay latched (the servo
    /// is then left faulted).
    ///
    /// # Errors
    /// [`ServoError::Faulted`].
    pub fn restart_prepared(&mut self, prepared: &Prepared) -> Result<(), ServoError> {
        self.disable();
        self.impedance = None;
        self.controller = prepared.controller.clone();
        self.supervisor.install_thresholds(&prepared.supervisor);
        self.supervisor.forget_history();
        self.enable()
    }

    /// Installs a configuration prepared ahead of time without leaving the current state:
    /// its controller and thresholds are copied in (no maths) and the sensor history is
    /// forgotten. An enabled servo stays enabled and holds the link where it is (the
    /// controller restarts as on [`Servo::enable`]); a disabled or faulted one stays so,
    /// and latched faults stay latched. The heartbeat timeout keeps running.
    pub fn install_prepared(&mut self, prepared: &Prepared) {
        self.impedance = None;
        self.controller = prepared.controller.clone();
        self.supervisor.install_thresholds(&prepared.supervisor);
        self.supervisor.forget_history();
        if self.state == ServoState::Enabled {
            self.controller.reset();
        }
    }

    /// The design in use.
    #[must_use]
    pub const fn design(&self) -> &Design {
        &self.design
    }

    fn fault(&mut self) {
        self.impedance = None;
        self.state = ServoState::Faulted;
        self.was_off = true;
    }

    /// A tick without trustworthy readings (the sensor-correction layer's boot alignment,
    /// `crate::calibration::pipeline`): counted like any tick, the motor off, no controller
    /// step and no checks (the readings are not yet in the servo's frame).
    pub fn tick_off(&mut self) -> TickOutput {
        self.tick = self.tick.wrapping_add(1);
        self.was_off = true;
        TickOutput {
            tick: self.tick,
            bridge: BridgeDemand::Off,
            control: Output::default(),
            new_fault: None,
            state: self.state,
        }
    }

    /// The readings' frame changed (the encoder was aligned to the pot again): the
    /// controller restarts holding the link where the next reading puts it and the
    /// supervisor forgets the sensor history, as after [`Servo::install_prepared`].
    pub fn sensors_realigned(&mut self) {
        self.impedance = None;
        self.controller.reset();
        self.supervisor.restart_estimates();
    }

    /// One 1 kHz tick: controller step on the readings, supervisor checks, and the bridge
    /// demand (off unless enabled and no fault latched, including one found now).
    pub fn tick(&mut self, input: &TickInput) -> TickOutput {
        self.tick_signed(input, false)
    }

    /// [`Servo::tick`] for a motor wired the other way round when `reversed`: the bridge
    /// demand's duty is the controller's negated (`control.duty` stays the controller's).
    /// The sensor-correction layer's per-tick call (`crate::calibration::pipeline`).
    pub fn tick_signed(&mut self, input: &TickInput, reversed: bool) -> TickOutput {
        self.tick = self.tick.wrapping_add(1);
        let m = Measurements {
            link_encoder: input.link_encoder,
            gear_pot: input.gear_pot,
            current_adc: input.current_adc,
            applied_duty: if self.was_off { Some(0) } else { None },
        };
        if let Some(imp) = self.impedance.as_ref().filter(|i| !i.approaching()) {
            // Within ±MAX_ANGLE_RAD by construction: never refused.
            let _ = self.controller.jump(imp.reference());
        }
        let control = self.controller.step(&m);
        if let Some(imp) = &mut self.impedance {
            imp.advance(
                control.torque_estimate,
                self.controller.trajectory().is_moving(),
            );
        }
        let readings = Readings {
            link_encoder: input.link_encoder,
            gear_pot: input.gear_pot,
            current_adc: input.current_adc,
            read_error: input.read_error,
        };
        let new_fault = self.supervisor.check(self.tick, &readings, &control);
        if new_fault.is_some() {
            self.fault();
        }
        let bridge = if self.state == ServoState::Enabled {
            BridgeDemand::Drive(if reversed {
                control.duty.saturating_neg()
            } else {
                control.duty
            })
        } else if self.state == ServoState::Faulted && brakes_on(self.faults()) {
            BridgeDemand::Brake
        } else {
            BridgeDemand::Off
        };
        // Braking applies 0 V; off, the observer is told 0 as well (its best guess).
        self.was_off = !bridge.drives();
        TickOutput {
            tick: self.tick,
            bridge,
            control,
            new_fault,
            state: self.state,
        }
    }

    /// The firmware found that the tick just run overran its deadline (`busy` sysclk
    /// counts): latches [`crate::supervisor::FaultCode::DeadlineMissed`] and turns the motor
    /// off now; the caller disables the bridge when this returns a fault.
    pub fn deadline_missed(&mut self, busy: u32) -> Option<Fault> {
        let f = self.supervisor.deadline_missed(self.tick, busy);
        if f.is_some() {
            self.fault();
        }
        f
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::supervisor::FaultCode;
    use crate::Length;
    use fixed::types::I32F32;

    fn servo() -> Servo {
        let d = Design::paper();
        Servo::new(
            &d,
            &Config::paper(Length::from_int(3)),
            &SupervisorConfig::DEFAULT,
        )
        .unwrap()
    }

    const QUIET: TickInput = TickInput {
        link_encoder: 0,
        gear_pot: Some(512),
        current_adc: 2048,
        supply_adc: None,
        read_error: None,
    };

    #[test]
    fn the_motor_runs_only_between_enable_and_a_fault_and_stays_off_until_clear_and_enable() {
        let mut s = servo();
        assert_eq!(s.tick(&QUIET).bridge, BridgeDemand::Off);
        s.enable().unwrap();
        assert!(matches!(s.tick(&QUIET).bridge, BridgeDemand::Drive(_)));
        let mut bad = QUIET;
        bad.current_adc = 4095;
        let out = s.tick(&bad);
        assert_eq!(out.bridge, BridgeDemand::Off, "off in the same tick");
        assert_eq!(out.new_fault.unwrap().code, FaultCode::AdcOutOfRange);
        assert_eq!(out.state, ServoState::Faulted);
        // Healthy again, still off; enable and commands refused while faulted.
        assert_eq!(s.tick(&QUIET).bridge, BridgeDemand::Off);
        assert_eq!(s.enable(), Err(ServoError::Faulted));
        assert_eq!(s.command(Command::Hold), Err(ServoError::Faulted));
        s.clear_fault();
        assert_eq!(s.state(), ServoState::Disabled);
        assert_eq!(s.tick(&QUIET).bridge, BridgeDemand::Off);
        s.enable().unwrap();
        assert!(matches!(s.tick(&QUIET).bridge, BridgeDemand::Drive(_)));
    }

    #[test]
    fn a_fault_of_the_mechanics_or_a_sensor_brakes_an_electrical_one_coasts() {
        // A link encoder that jumps half a turn: a sensor fault, the motor shorted.
        let mut s = servo();
        s.enable().unwrap();
        s.tick(&QUIET);
        let mut jump = QUIET;
        jump.link_encoder = 2048;
        let out = s.tick(&jump);
        assert_eq!(out.new_fault.unwrap().code, FaultCode::SensorJump);
        assert_eq!(out.bridge, BridgeDemand::Brake, "braking in the same tick");
        assert_eq!(s.tick(&jump).bridge, BridgeDemand::Brake);
        assert_eq!(out.bridge.duty(), 0);
        // An over-current (1.9 A): free-wheeling, whatever else latches later.
        let mut s = servo();
        s.enable().unwrap();
        s.tick(&QUIET);
        let mut high = QUIET;
        high.current_adc = 2048 + 1946;
        let out = s.tick(&high);
        assert_eq!(out.new_fault.unwrap().code, FaultCode::OverCurrent);
        assert_eq!(out.bridge, BridgeDemand::Off);
        let mut both = high;
        both.link_encoder = 2048;
        assert_eq!(s.tick(&both).bridge, BridgeDemand::Off);
        assert!(!brakes_on(FaultSet(0)), "no fault: nothing to brake for");
    }

    #[test]
    fn an_overrun_turns_the_motor_off() {
        let mut s = servo();
        s.enable().unwrap();
        s.tick(&QUIET);
        let f = s.deadline_missed(200_000).unwrap();
        assert_eq!(
            (f.code, f.value, f.tick),
            (FaultCode::DeadlineMissed, 200_000, 1)
        );
        assert_eq!(s.tick(&QUIET).bridge, BridgeDemand::Off);
    }

    #[test]
    fn an_impedance_command_lasts_until_a_position_command_a_disable_or_a_fault() {
        use crate::control::{ImpedanceCommand, ImpedanceError};
        use crate::{Angle, Stiffness, Torque};
        let imp = |k: i64| ImpedanceCommand {
            target: Angle::from_micro(300_000).unwrap(),
            stiffness: Stiffness::from_int(k),
            damping: fixed::types::I32F32::from_num(0.2),
            torque: Torque::ZERO,
        };
        let mut s = servo(); // L = 3 mm: k = 265.5 N·m/rad
        s.enable().unwrap();
        s.impedance(&imp(20)).unwrap();
        assert_eq!(s.impedance_command(), Some(&imp(20)));
        // The approach: a move to the target.
        assert!(s.controller().trajectory().is_moving());
        assert_eq!(
            s.impedance(&imp(266)),
            Err(ServoError::Impedance(
                ImpedanceError::StiffnessAbovePhysical
            ))
        );
        assert_eq!(
            s.impedance_command(),
            Some(&imp(20)),
            "a refusal changes nothing"
        );
        s.command(Command::Hold).unwrap();
        assert_eq!(s.impedance_command(), None);
        s.impedance(&imp(20)).unwrap();
        s.disable();
        assert_eq!(s.impedance_command(), None);
        s.enable().unwrap();
        s.impedance(&imp(20)).unwrap();
        let mut bad = QUIET;
        bad.current_adc = 4095;
        assert!(s.tick(&bad).new_fault.is_some());
        assert_eq!(s.impedance_command(), None);
        assert_eq!(s.impedance(&imp(20)), Err(ServoError::Faulted));
    }

    #[test]
    fn a_rejected_configuration_changes_nothing() {
        let mut s = servo();
        let before = s.supervisor().torque_capacity();
        let mut cfg = Config::paper(Length::from_int(3));
        cfg.link_inertia = crate::Inertia::from_int(0);
        assert!(s.configure(&cfg).is_err());
        assert_eq!(s.supervisor().torque_capacity(), before);
        s.configure(&Config::paper(Length::from_int(5))).unwrap();
        assert!(s.supervisor().torque_capacity() < before);
    }

    #[test]
    fn a_measured_supply_beyond_its_tolerance_is_configured_before_a_command() {
        let s = servo();
        let twelve = s.controller().config().motor.supply_v;
        assert_eq!(twelve, I32F32::from_num(12));
        let still = RestResistance::NEW;
        let window = |counts: u16| {
            let mut w = SupplyWindow::NEW;
            for _ in 0..256 {
                w.tick(Some(counts));
            }
            w
        };
        // No window yet, and 12.2 V (within 3 % of 12 V): the configuration stays.
        assert!(s
            .tracked_configuration(&SupplyWindow::NEW, &still, false)
            .is_none());
        assert!(s
            .tracked_configuration(&window(2440), &still, false)
            .is_none());
        // 11 V (2 200 counts of 5 mV): the configuration in force with 11 V, nothing else.
        let (config, supervision) = s
            .tracked_configuration(&window(2200), &still, false)
            .unwrap();
        assert_eq!(config.motor.supply_v, I32F32::from_num(11));
        let mut expected = *s.controller().config();
        expected.motor.supply_v = I32F32::from_num(11);
        assert_eq!(config, expected);
        assert_eq!(supervision, *s.supervisor().config());
    }
}
