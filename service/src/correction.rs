//! The stored calibration as the sensor-correction layer's configuration: the wiring
//! signs, the encoder's counts per turn, the pot's centre and gain and the current
//! sense's offset and gain of a [`store::Calibration`] record become a
//! [`SensorCorrection`], installed in the actuator's [`model::calibration::pipeline`] when
//! the store is loaded (the encoder is then aligned to the pot again, motor off); its pot
//! error table becomes the supervisor's ([`SupervisorConfig::pot_error`]), which sizes the
//! deflection check from it.

use model::calibration::correction::{SensorCorrection, Sign};
use model::calibration::pot_error::PotErrorTable;
use model::sensors::{ADC_MID, POT_COUNTS};
use model::supervisor::SupervisorConfig;
use rtic_core::Mutex;
use store::Calibration;

use crate::{Actuator, ServiceDevice};

/// ±1 as a sign (the record's check allows nothing else).
const fn sign(v: i8) -> Sign {
    if v < 0 {
        Sign::Minus
    } else {
        Sign::Plus
    }
}

/// ppm → Q16, rounded (the record's range 0.5..=2 keeps it in the correction's).
fn ppm_q16(ppm: u32) -> i32 {
    ((u64::from(ppm) * 65_536 + 500_000) / 1_000_000) as i32
}

/// The correction of a stored (checked) calibration; the ADC rails are the supervisor's.
#[must_use]
pub fn sensor_correction(cal: &Calibration, supervision: &SupervisorConfig) -> SensorCorrection {
    SensorCorrection {
        motor_polarity: sign(cal.wire.motor_polarity),
        encoder_direction: sign(cal.wire.encoder_direction),
        encoder_counts_per_turn: cal.encoder_counts_per_turn,
        pot_direction: sign(cal.wire.pot_direction),
        pot_center_q16: (i32::from(POT_COUNTS / 2) + i32::from(cal.wire.pot_offset_counts)) << 16,
        pot_gain_q16: ppm_q16(cal.pot_gain_ppm),
        current_offset_q16: (i32::from(ADC_MID) + i32::from(cal.wire.current_offset_counts)) << 16,
        current_gain_q16: ppm_q16(cal.current_gain_ppm),
        adc_min: supervision.adc_min,
        adc_max: supervision.adc_max,
    }
}

/// `supervision` with the pot error table of a stored (checked) calibration: the
/// measured table, or none (the fixed tolerance) where the record has none.
#[must_use]
pub fn with_pot_error(cal: &Calibration, supervision: &SupervisorConfig) -> SupervisorConfig {
    SupervisorConfig {
        pot_error: cal.pot_error_centi.map(|centi| PotErrorTable { centi }),
        ..*supervision
    }
}

impl<M: Mutex<T = Actuator>> ServiceDevice<'_, M> {
    /// Installs the stored calibration's correction (the nominal one without a stored
    /// calibration, or if the correction is refused); the boot window starts again.
    pub(crate) fn install_stored_correction(&mut self) {
        let wanted = match self.service.calibration() {
            Some(cal) => sensor_correction(&cal, &self.service.supervision),
            None => SensorCorrection::NOMINAL,
        };
        self.actuator.lock(|a| {
            if a.pipeline.corrector().correction() != &wanted
                && a.pipeline.install(&wanted).is_err()
            {
                let _ = a.pipeline.install(&SensorCorrection::NOMINAL);
            }
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use model::calibration::correction::Corrector;

    #[test]
    fn a_stored_calibration_becomes_the_correction() {
        let cal = Calibration {
            wire: protocol::Calibration {
                motor_polarity: -1,
                encoder_direction: -1,
                pot_direction: 1,
                current_offset_counts: -100,
                pot_offset_counts: 7,
                resistance_mohm: 8_300,
                back_emf_uv_s_per_rad: 1_240_000,
                gear_friction_unm: 20_000,
                link_inertia_kg_mm2: 1_150,
                stiffness_mnm_per_rad: None,
                clutch_length_um: None,
                stiffness_uncertainty_permille: 0,
            },
            encoder_counts_per_turn: 1000,
            pot_gain_ppm: 1_100_000,
            current_gain_ppm: 500_000,
            pot_error_centi: None,
        };
        let c = sensor_correction(&cal, &SupervisorConfig::DEFAULT);
        assert_eq!(c.motor_polarity, Sign::Minus);
        assert_eq!(c.encoder_direction, Sign::Minus);
        assert_eq!(c.encoder_counts_per_turn, 1000);
        assert_eq!(c.pot_center_q16, 519 << 16);
        assert_eq!(c.pot_gain_q16, 72_090); // 1.1 · 65 536 = 72 089.6
        assert_eq!(c.current_offset_q16, 1948 << 16);
        assert_eq!(c.current_gain_q16, 32_768);
        assert!(Corrector::new(&c).is_ok());
        // No table stored: the fixed tolerance; a stored table goes to the supervisor.
        let s = with_pot_error(&cal, &SupervisorConfig::DEFAULT);
        assert_eq!(s, SupervisorConfig::DEFAULT);
        let mut centi = [300; 16];
        centi[7] = 125;
        let measured = Calibration {
            pot_error_centi: Some(centi),
            ..cal
        };
        let s = with_pot_error(&measured, &SupervisorConfig::DEFAULT);
        assert_eq!(s.pot_error.map(|t| t.centi[7]), Some(125));
        assert_eq!(
            SupervisorConfig {
                pot_error: None,
                ..s
            },
            SupervisorConfig::DEFAULT
        );
    }
}
