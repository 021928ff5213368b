//! One control tick from the raw readings to the bridge, the same on every board and in
//! the host simulation: raw [`TickInput`] → [`Corrector`] (the sensor-correction layer,
//! [`super::correction`]) → [`Servo`] → the servo's duty in the bridge's sign (the motor
//! polarity applied).
//!
//! For the first [`super::correction::BOOT_TICKS`] ticks after construction,
//! [`Pipeline::install`] or [`Pipeline::realign`] the corrector aligns the incremental
//! encoder to the absolute pot and measures the current-sense offset with the bridge off:
//! the servo's tick is then [`Servo::tick_off`] (counted, motor off, no controller step
//! and no supervisor check, so a link powered up away from the pot's centre latches
//! nothing). At the end of the window the servo is told that the readings' frame changed
//! ([`Servo::sensors_realigned`]). The per-tick cost after the window is the corrector's:
//! integer multiplies and shifts, the readings corrected in place.

use super::correction::{CorrectionError, Corrector, SensorCorrection};
use crate::servo::{Servo, TickInput, TickOutput};

/// The correction layer in front of a [`Servo`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Pipeline {
    corrector: Corrector,
    /// The readings the servo saw at the last tick (canonical; the raw ones during the
    /// boot window).
    input: TickInput,
}

impl Pipeline {
    /// A pipeline for the wiring and sensors `correction`; the boot window starts.
    ///
    /// # Errors
    /// The correction was rejected ([`Corrector::new`]).
    pub fn new(correction: &SensorCorrection) -> Result<Pipeline, CorrectionError> {
        Ok(Pipeline {
            corrector: Corrector::new(correction)?,
            input: TickInput::default(),
        })
    }

    /// The canonical build ([`SensorCorrection::NOMINAL`]), boot window started.
    #[must_use]
    pub fn nominal() -> Pipeline {
        match Corrector::new(&SensorCorrection::NOMINAL) {
            Ok(corrector) => Pipeline {
                corrector,
                input: TickInput::default(),
            },
            // NOMINAL passes every check (tested).
            Err(_) => unreachable!(),
        }
    }

    /// Installs a new correction (e.g. calibration's result); the boot window starts
    /// again. On error nothing changes.
    ///
    /// # Errors
    /// The correction was rejected.
    pub fn install(&mut self, correction: &SensorCorrection) -> Result<(), CorrectionError> {
        self.corrector = Corrector::new(correction)?;
        Ok(())
    }

    /// Starts the boot window again (the link may have been moved with the power off).
    pub fn realign(&mut self) {
        self.corrector.realign();
    }

    /// Ends the boot window now, the encoder's raw zero taken as link angle 0
    /// ([`Corrector::assume_aligned`]).
    pub fn assume_aligned(&mut self) {
        self.corrector.assume_aligned();
    }

    /// The corrector (the correction in use, whether aligned, the current offset).
    #[must_use]
    pub const fn corrector(&self) -> &Corrector {
        &self.corrector
    }

    /// Whether the boot window is over.
    #[must_use]
    pub const fn aligned(&self) -> bool {
        self.corrector.aligned()
    }

    /// The readings the servo saw at the last tick: canonical (what telemetry reports);
    /// the raw ones during the boot window.
    #[must_use]
    pub const fn input(&self) -> &TickInput {
        &self.input
    }

    /// One 1 kHz tick of `servo` on this tick's raw readings: the servo's output with
    /// `bridge` what the H-bridge must do (the motor polarity applied; `control.duty` stays
    /// the servo's own). The readings it saw: [`Pipeline::input`].
    #[inline]
    pub fn tick(&mut self, servo: &mut Servo, raw: &TickInput) -> TickOutput {
        if self.corrector.correct(raw, &mut self.input) {
            return servo.tick_signed(&self.input, self.corrector.reversed());
        }
        self.input = *raw;
        let out = servo.tick_off();
        if self.corrector.aligned() {
            servo.sensors_realigned();
        }
        out
    }
}

impl Default for Pipeline {
    fn default() -> Self {
        Self::nominal()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calibration::correction::{Sign, BOOT_TICKS};
    use crate::control::Config;
    use crate::servo::{BridgeDemand, ServoState};
    use crate::supervisor::SupervisorConfig;
    use crate::{Design, Length};

    fn servo() -> Servo {
        Servo::new(
            &Design::paper(),
            &Config::paper(Length::from_int(3)),
            &SupervisorConfig::DEFAULT,
        )
        .unwrap()
    }

    fn raw(enc: u16, pot: u16, adc: u16) -> TickInput {
        TickInput {
            link_encoder: enc,
            gear_pot: Some(pot),
            current_adc: adc,
            supply_adc: None,
            read_error: None,
        }
    }

    #[test]
    fn the_motor_stays_off_and_nothing_latches_until_the_encoder_is_aligned() {
        // Link at +0.8 rad (pot 512 + 0.8/5.11e-3 = 668), encoder at zero.
        let mut s = servo();
        let mut p = Pipeline::nominal();
        s.enable().unwrap();
        for k in 1..=u32::from(BOOT_TICKS) {
            let c = p.tick(&mut s, &raw(0, 668, 2048));
            assert_eq!(c.bridge, BridgeDemand::Off);
            assert_eq!(c.tick, k);
        }
        assert!(p.aligned());
        // The servo itself would latch beam-overload on these raw readings at once.
        let mut bare = servo();
        assert!(bare.tick(&raw(0, 668, 2048)).new_fault.is_some());
        for _ in 0..200 {
            let c = p.tick(&mut s, &raw(0, 668, 2048));
            assert_eq!(c.new_fault, None);
            assert!(matches!(c.bridge, BridgeDemand::Drive(_)));
        }
        assert_eq!(s.state(), ServoState::Enabled);
        // 156 pot counts · 3.333 = 520 encoder counts: 0.798 rad.
        let angle = s.controller().trajectory().reference().position.to_bits();
        assert!(
            (angle - (798 << 32) / 1000).abs() < (3 << 32) / 1000,
            "{angle}"
        );
    }

    #[test]
    fn the_duty_reaches_the_bridge_in_its_own_sign() {
        let cal = SensorCorrection {
            motor_polarity: Sign::Minus,
            ..SensorCorrection::NOMINAL
        };
        let (mut a, mut b) = (servo(), servo());
        let mut p = Pipeline::new(&cal).unwrap();
        let mut q = Pipeline::nominal();
        a.enable().unwrap();
        b.enable().unwrap();
        for _ in 0..BOOT_TICKS {
            p.tick(&mut a, &raw(0, 512, 2048));
            q.tick(&mut b, &raw(0, 512, 2048));
        }
        a.command(crate::control::Command::Step {
            target: crate::Angle::from_micro(100_000).unwrap(),
        })
        .unwrap();
        b.command(crate::control::Command::Step {
            target: crate::Angle::from_micro(100_000).unwrap(),
        })
        .unwrap();
        // The raw current of the reversed motor reads the other way round.
        let x = p.tick(&mut a, &raw(0, 512, 2048));
        let y = q.tick(&mut b, &raw(0, 512, 2048));
        assert_eq!(x.control.duty, y.control.duty);
        let (BridgeDemand::Drive(dx), BridgeDemand::Drive(dy)) = (x.bridge, y.bridge) else {
            panic!("not driven");
        };
        assert!(dy > 0);
        assert_eq!(dx, -dy);
    }

    #[test]
    fn an_assumed_alignment_is_the_identity_from_the_first_tick() {
        let mut s = servo();
        let mut p = Pipeline::nominal();
        p.assume_aligned();
        let c = p.tick(&mut s, &raw(1234, 600, 2100));
        assert_eq!(*p.input(), raw(1234, 600, 2100));
        assert_eq!(c.tick, 1);
    }

    #[test]
    fn the_current_offset_is_measured_with_the_bridge_off() {
        let mut s = servo();
        let mut p = Pipeline::nominal();
        for k in 0..BOOT_TICKS {
            // A sense reading 2248 ± 3 at 0 A.
            p.tick(&mut s, &raw(0, 512, 2245 + k % 7));
        }
        assert_eq!(p.corrector().current_offset_q16() >> 16, 2247);
        p.tick(&mut s, &raw(0, 512, 2248));
        let c = p.input();
        assert!((i32::from(c.current_adc) - 2048).abs() <= 1, "{c:?}");
        // A sense at a rail keeps the configured offset (the supervisor reports the rail).
        let mut p = Pipeline::nominal();
        for _ in 0..BOOT_TICKS {
            p.tick(&mut s, &raw(0, 512, 3));
        }
        assert_eq!(p.corrector().current_offset_q16(), 2048 << 16);
    }
}
