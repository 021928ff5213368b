//! The calibration sequence on the device (docs/calibration.md): started and stopped by
//! [`protocol::Request::Calibrate`], one step per control tick from the disabled state
//! ([`Actuator::control`]), its result applied and stored by the command task
//! ([`Service::finish_calibration`]) and the stored one applied at boot (the controller's
//! motor model and link inertia, the supervisor's pot error table, and the sensor
//! correction installed in the actuator's correction layer, `Actuator::pipeline`).
//!
//! The supervisor stays armed throughout: the servo ticks as when disabled (its controller
//! tracks the sensors, its bridge demand off) behind the sensor-correction layer in force
//! (`model::calibration::pipeline`: the current about the offset measured at boot), and
//! every check runs on the tick's readings but the pot's: its direction and gain are what
//! the run measures, and a pot read the wrong way or 10 % off would show the ±0.6 rad moves
//! as a deflection far beyond the beams'. The beams are protected instead by the run's
//! current bound (half their capacity at the longest clutch length, checked every tick by
//! the sequence) and the supervisor's current-based torque check against the capacity.

use model::calibration::correction::{Sign, POT_CENTER};
use model::calibration::sequence::{
    Calibration as Sequence, CalibrationConfig, CalibrationResult, Failure, Progress,
};
use model::control::Config;
use model::sensors::{ADC_MID, ENCODER_COUNTS};
use model::servo::{BridgeDemand, ServoState, TickInput, TickOutput};
use model::Inertia;
use protocol::{CalibrationProgress, CalibrationReport, ErrorCode};
use rtic_core::Mutex;
use store::Calibration;

use crate::{Actuator, Service, ServiceDevice};

/// Phase reported while the command task applies and stores a finished run.
const APPLYING_PHASE: u8 = model::calibration::sequence::PHASES;

/// The calibration state of the actuator (part of [`Actuator`]).
#[derive(Clone, Debug, Default)]
pub struct Calibrator {
    /// The sequence running, if any.
    run: Option<Sequence>,
    /// A finished run's result the command task has not applied yet.
    pending: Option<CalibrationResult>,
    progress: CalibrationProgress,
}

impl Calibrator {
    /// Where the sequence is.
    #[must_use]
    pub const fn progress(&self) -> CalibrationProgress {
        self.progress
    }

    /// Whether a run drives the bridge (or waits to be applied).
    #[must_use]
    pub const fn running(&self) -> bool {
        matches!(self.progress, CalibrationProgress::Running { .. })
    }

    /// Stops a run (the next tick turns the motor off).
    pub fn abort(&mut self) {
        if let Some(run) = self.run.as_mut() {
            run.abort();
        }
    }

    fn failed(&mut self, why: Failure) {
        self.run = None;
        self.pending = None;
        self.progress = CalibrationProgress::Failed {
            failure: why.code(),
        };
    }

    /// One tick of a run: the raw readings `raw`, the servo's output `out` of this tick
    /// (a fault it latched ends the run). Returns the bridge demand.
    fn step(&mut self, raw: &TickInput, out: &TickOutput) -> BridgeDemand {
        let Some(run) = self.run.as_mut() else {
            return BridgeDemand::Off;
        };
        if out.new_fault.is_some() || out.state != ServoState::Disabled {
            run.stop(Failure::Fault);
        }
        let duty = run.step(raw);
        match run.progress() {
            Progress::Running { phase, percent } => {
                self.progress = CalibrationProgress::Running { phase, percent };
            }
            Progress::Done => {
                self.pending = run.result().copied();
                self.run = None;
                self.progress = CalibrationProgress::Running {
                    phase: APPLYING_PHASE,
                    percent: 99,
                };
            }
            Progress::Failed(why) => self.failed(why),
        }
        duty.map_or(BridgeDemand::Off, BridgeDemand::Drive)
    }
}

impl Actuator {
    /// One control tick on this tick's raw readings `raw` ([`Actuator::tick`]: the
    /// correction layer and the servo) and the bridge demand: the servo's own, a nudge's,
    /// or the calibration run's (module docs). Records the raw readings.
    pub fn control(&mut self, raw: &TickInput) -> (TickOutput, BridgeDemand) {
        if !self.calibration.running() {
            let out = self.tick(raw);
            let demand = self.open_loop.demand(raw, &out);
            return (out, demand);
        }
        // The supervisor's view: the pot hidden (module docs).
        let out = self.tick(&TickInput {
            gear_pot: None,
            ..*raw
        });
        // The raw readings for `vsa sensors` (no nudge runs: the start refused it).
        let _ = self.open_loop.demand(raw, &out);
        let demand = self.calibration.step(raw, &out);
        self.open_loop.note_duty(demand.duty());
        (out, demand)
    }
}

/// The result of a run as the store keeps it.
#[must_use]
pub fn record(r: &CalibrationResult) -> Calibration {
    let c = &r.correction;
    let sat_u32 = |v: i64| u32::try_from(v.max(0)).unwrap_or(u32::MAX);
    let offset = ((i64::from(c.current_offset_q16) + (1 << 15)) >> 16) - i64::from(ADC_MID);
    let pot_offset = ((i64::from(c.pot_center_q16) + (1 << 15)) >> 16) - i64::from(POT_CENTER);
    Calibration {
        wire: protocol::Calibration {
            motor_polarity: c.motor_polarity.value() as i8,
            encoder_direction: c.encoder_direction.value() as i8,
            pot_direction: c.pot_direction.value() as i8,
            current_offset_counts: offset.clamp(-i64::from(ADC_MID), i64::from(ADC_MID)) as i16,
            pot_offset_counts: pot_offset as i16,
            resistance_mohm: sat_u32(r.resistance_mohm.into()),
            back_emf_uv_s_per_rad: sat_u32(r.back_emf_uv_s_per_rad.into()),
            gear_friction_unm: sat_u32(r.gear_friction_unm.into()),
            // kg·m² × 10⁹ → kg·mm² (× 10⁶), rounded, at least the controller's minimum.
            link_inertia_kg_mm2: sat_u32((r.link_inertia_nano + 500) / 1000)
                .max(model::control::MIN_INERTIA as u32),
            stiffness_mnm_per_rad: None,
            clutch_length_um: None,
            stiffness_uncertainty_permille: 1000,
        },
        encoder_counts_per_turn: c.encoder_counts_per_turn,
        pot_gain_ppm: q16_ppm(c.pot_gain_q16),
        current_gain_ppm: q16_ppm(c.current_gain_q16),
        pot_error_centi: Some(r.pot_error.centi),
    }
}

/// `config` with what `cal` measured in force: the motor's resistance (as the current sense
/// sees it), back-EMF constant and gear friction, and the link inertia.
#[must_use]
pub fn calibrated_config(mut config: Config, cal: &Calibration) -> Config {
    config.motor.resistance_ohm =
        fixed::types::I32F32::from_bits(crate::milli_to_q32(cal.wire.resistance_mohm.into()));
    config.motor.back_emf =
        fixed::types::I32F32::from_bits(crate::micro_to_q32(cal.wire.back_emf_uv_s_per_rad.into()));
    config.motor.coulomb =
        fixed::types::I32F32::from_bits(crate::micro_to_q32(cal.wire.gear_friction_unm.into()));
    config.link_inertia =
        Inertia::from_int(i32::try_from(cal.wire.link_inertia_kg_mm2).unwrap_or(i32::MAX));
    config
}

/// Q16 → ppm, rounded, within the record's gain range (the sequence keeps gains there).
fn q16_ppm(q16: i32) -> u32 {
    let ppm = (i64::from(q16) * 1_000_000 + (1 << 15)) >> 16;
    (ppm.max(0) as u32).clamp(store::records::GAIN_MIN_PPM, store::records::GAIN_MAX_PPM)
}

impl Service {
    /// Applies and stores a run that has just finished (the command task calls this every
    /// tick; nothing to do most of the time). A result the controller refuses ends the
    /// run as `implausible`; a store that fails leaves the result in force until the next
    /// boot (the progress says done: `vsa calibrate --show` reads it back).
    pub fn finish_calibration(&mut self, actuator: &mut impl Mutex<T = Actuator>) {
        let Some(result) = actuator.lock(|a| a.calibration.pending.take()) else {
            return;
        };
        let cal = record(&result);
        let applied = self.device(actuator).apply_calibration(&cal, Some(&result));
        let outcome = applied.and_then(|()| match self.persist_calibration(cal, actuator) {
            // In force without a store (a board without flash): the set keeps it.
            Ok(()) | Err(ErrorCode::Storage) => Ok(()),
            Err(e) => Err(e),
        });
        actuator.lock(|a| match outcome {
            Ok(()) => a.calibration.progress = CalibrationProgress::Done,
            Err(_) => a.calibration.failed(Failure::Implausible),
        });
    }
}

impl Service {
    /// The Dynamixel Calibration State register's value (`dynamixel::table::calibration`):
    /// running, failed (the last run), calibrated (a calibration in force) or none.
    pub fn calibration_register(&self, actuator: &mut impl Mutex<T = Actuator>) -> i32 {
        use dynamixel::table::calibration as reg;
        match actuator.lock(|a| a.calibration.progress) {
            CalibrationProgress::Running { .. } => reg::RUNNING,
            CalibrationProgress::Failed { .. } => reg::FAILED,
            _ if self.calibration().is_some() => reg::CALIBRATED,
            _ => reg::UNCALIBRATED,
        }
    }
}

impl<M: Mutex<T = Actuator>> ServiceDevice<'_, M> {
    /// [`protocol::Request::Calibrate`].
    pub(crate) fn calibrate(&mut self, start: bool) -> Result<(), ErrorCode> {
        if !start {
            self.actuator.lock(|a| a.calibration.abort());
            return Ok(());
        }
        // Configuration time: the bound and the duty from the design and the datasheet; the
        // pot error table's floor for unvisited bins is the supervisor's fixed tolerance.
        // The supply the configuration will hold: the resistance and back-EMF come out in
        // the volts of the loop's duty scale (docs/design.md §11, "The supply the board
        // measures").
        let mut motor = self.service.config.motor;
        motor.supply_v = self.actuator.lock(|a| a.supply_in_force(motor.supply_v));
        let cfg = CalibrationConfig {
            pot_tolerance_counts: self.service.supervision.pot_tolerance_counts,
            ..CalibrationConfig::new(&self.service.design, &motor, Sign::Plus, ENCODER_COUNTS)
                .map_err(|_| ErrorCode::OutOfRange)?
        };
        self.actuator.lock(|a| {
            // Not during the correction layer's boot window (motor off, no checks).
            if a.servo.state() != ServoState::Disabled
                || a.open_loop.running()
                || !a.pipeline.aligned()
            {
                return Err(ErrorCode::NotAllowed);
            }
            if a.calibration.running() {
                return Err(ErrorCode::Busy);
            }
            a.calibration.run = Some(Sequence::new(&cfg));
            a.calibration.pending = None;
            a.calibration.progress = CalibrationProgress::Running {
                phase: 1,
                percent: 0,
            };
            Ok(())
        })
    }

    /// [`protocol::Request::GetCalibration`].
    pub(crate) fn calibration_report(&mut self) -> CalibrationReport {
        CalibrationReport {
            progress: self.actuator.lock(|a| a.calibration.progress),
            calibration: self.service.calibration().map(|c| c.wire),
            tracked_resistance_permille: self.service.tracked_resistance_permille,
        }
    }

    /// Puts `cal` in force: the motor's resistance, back-EMF and gear friction and the link
    /// inertia for the controller, its pot error table for the supervisor, the sensor correction
    /// (`run`'s, else the one `cal` gives). The supply in force is the one `run`'s figures are
    /// in (the one its start took, `calibrate`); for a stored calibration, the one in force.
    pub(crate) fn apply_calibration(
        &mut self,
        cal: &Calibration,
        run: Option<&CalibrationResult>,
    ) -> Result<(), ErrorCode> {
        let mut config = calibrated_config(self.service.config, cal);
        config.motor.supply_v = match run {
            Some(r) => r.supply_v,
            None => self
                .actuator
                .lock(|a| a.supply_in_force(config.motor.supply_v)),
        };
        let correction = run.map_or_else(
            || crate::correction::sensor_correction(cal, &self.service.supervision),
            |r| r.correction,
        );
        // Checked before anything changes; installing it starts the layer's boot window
        // (the encoder aligned to the pot again in the new frame, motor off).
        model::calibration::correction::Corrector::new(&correction)
            .map_err(|_| ErrorCode::OutOfRange)?;
        let supervision = crate::correction::with_pot_error(cal, &self.service.supervision);
        // The clutch the calibration measured bounds the clutch tolerance in force.
        let previous = self.service.calibrated_longest_um;
        self.service.calibrated_longest_um = crate::clutch_confirmation::calibrated_longest_um(
            cal.wire.clutch_length_um,
            cal.wire.stiffness_uncertainty_permille,
        );
        if let Err(e) = self.reconfigure(config, supervision) {
            self.service.calibrated_longest_um = previous;
            return Err(e);
        }
        self.actuator
            .lock(|a| a.pipeline.install(&correction))
            .map_err(|_| ErrorCode::OutOfRange)?;
        self.service.set_offset_calibrated(true);
        Ok(())
    }

    /// At boot and on `load`: the stored calibration in force, if any (one the controller
    /// refuses is left out, the datasheet values stay).
    pub(crate) fn apply_stored_calibration(&mut self) {
        if let Some(cal) = self.service.calibration() {
            let _ = self.apply_calibration(&cal, None);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use model::calibration::correction::SensorCorrection;
    use model::calibration::pot_error::PotErrorTable;
    use store::Record;

    #[test]
    fn the_stored_record_keeps_the_pot_error_table() {
        let mut pot_error = PotErrorTable {
            centi: [410; model::calibration::pot_error::POT_ERROR_BINS],
        };
        pot_error.centi[7] = 321;
        let r = CalibrationResult {
            correction: SensorCorrection::NOMINAL,
            resistance_mohm: 8_000,
            back_emf_mv_s_per_rad: 1_940,
            back_emf_uv_s_per_rad: 1_940_000,
            gear_friction_unm: 10_000,
            link_inertia_nano: 1_000_000,
            pot_error_centi: 120,
            pot_error,
            free_play_pot_centi: 100,
            current_noise_centi: 100,
            supply_v: fixed::types::I32F32::from_num(12),
        };
        let cal = record(&r);
        assert_eq!(cal.pot_error_centi, Some(pot_error.centi));
        assert_eq!(cal.check(), Ok(()));
    }
}
