//! The bring-up mode's device side: the raw readings of the last tick
//! ([`protocol::Request::GetSensors`]) and the open-loop nudge
//! ([`protocol::Request::Nudge`]).
//!
//! The nudge drives the bridge at a low, bounded duty for a bounded time while the servo is
//! disabled, so that the motor's direction and each sensor can be checked before the loop
//! is closed. The servo and its supervisor keep running every tick as they do when
//! disabled: a fault latches as ever, and the nudge ends with it.

use model::servo::{BridgeDemand, ServoState, TickInput, TickOutput};
use protocol::{ErrorCode, RawSensors};

/// The open-loop nudge and the last raw readings (part of [`crate::Actuator`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct OpenLoop {
    /// Duty of the nudge running, ‰.
    duty: i16,
    /// Ticks of it left (0: none).
    ticks_left: u16,
    /// The readings of the last tick.
    last: RawSensors,
    /// Whether a tick has recorded `last` (before the first one there is no reading).
    ticked: bool,
}

impl OpenLoop {
    /// Starts a nudge of `duty_permille` for `duration_ms` (1 tick per ms), replacing one
    /// that runs. The protocol has checked the ranges.
    ///
    /// # Errors
    /// [`ErrorCode::NotAllowed`] unless the servo is `state` disabled: never while it drives
    /// the motor itself, nor with a fault latched.
    pub fn start(
        &mut self,
        state: ServoState,
        duty_permille: i16,
        duration_ms: u16,
    ) -> Result<(), ErrorCode> {
        if state != ServoState::Disabled {
            return Err(ErrorCode::NotAllowed);
        }
        self.duty = duty_permille;
        self.ticks_left = duration_ms;
        Ok(())
    }

    /// Ends the nudge, if one runs.
    pub fn stop(&mut self) {
        self.ticks_left = 0;
    }

    /// Whether a nudge runs.
    #[must_use]
    pub const fn running(&self) -> bool {
        self.ticks_left != 0
    }

    /// The bridge demand of a tick whose servo output is `out`: the servo's own, unless a
    /// nudge runs and the servo is still disabled after this tick (a fault or an enable
    /// ends the nudge). Records the tick's raw readings with the duty applied.
    pub fn demand(&mut self, input: &TickInput, out: &TickOutput) -> BridgeDemand {
        if out.state != ServoState::Disabled {
            self.stop();
        }
        let nudge = if self.ticks_left == 0 {
            0
        } else {
            self.ticks_left -= 1;
            self.duty
        };
        self.last = RawSensors {
            tick: out.tick,
            link_encoder: input.link_encoder,
            gear_pot: input.gear_pot,
            current_adc: input.current_adc,
            supply_adc: input.supply_adc,
            nudge_duty_permille: nudge,
        };
        self.ticked = true;
        if nudge == 0 {
            out.bridge
        } else {
            BridgeDemand::Drive(nudge)
        }
    }

    /// Records `duty_permille` as the open-loop duty of the last tick (the calibration's).
    pub fn note_duty(&mut self, duty_permille: i16) {
        self.last.nudge_duty_permille = duty_permille;
    }

    /// The readings of the last tick.
    ///
    /// # Errors
    /// [`ErrorCode::Busy`] before the first tick: there is no reading yet (a link that
    /// comes up before the control tick must not pass off zeros as one).
    pub const fn last(&self) -> Result<RawSensors, ErrorCode> {
        if self.ticked {
            Ok(self.last)
        } else {
            Err(ErrorCode::Busy)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use model::control::Config;
    use model::servo::Servo;
    use model::supervisor::SupervisorConfig;
    use model::{Design, Length};

    fn servo() -> Servo {
        Servo::new(
            &Design::paper(),
            &Config::paper(Length::from_int(3)),
            &SupervisorConfig::DEFAULT,
        )
        .unwrap()
    }

    const AT_REST: TickInput = TickInput {
        link_encoder: 0,
        gear_pot: Some(512),
        current_adc: 2048,
        supply_adc: None,
        read_error: None,
    };

    #[test]
    fn a_nudge_drives_for_its_duration_then_gives_the_bridge_back() {
        let mut s = servo();
        let mut o = OpenLoop::default();
        o.start(s.state(), -80, 3).unwrap();
        let mut applied = Vec::new();
        for _ in 0..5 {
            let out = s.tick(&AT_REST);
            applied.push(o.demand(&AT_REST, &out));
        }
        let d = BridgeDemand::Drive(-80);
        assert_eq!(applied, [d, d, d, BridgeDemand::Off, BridgeDemand::Off]);
        let last = o.last().unwrap();
        assert_eq!(last.nudge_duty_permille, 0);
        assert_eq!(last.tick, 5);
        assert_eq!(last.gear_pot, Some(512));
    }

    #[test]
    fn no_reading_before_the_first_tick() {
        let mut s = servo();
        let mut o = OpenLoop::default();
        assert_eq!(o.last(), Err(ErrorCode::Busy));
        let out = s.tick(&AT_REST);
        o.demand(&AT_REST, &out);
        assert_eq!(o.last().map(|r| r.tick), Ok(1));
    }

    #[test]
    fn no_nudge_while_enabled_and_an_enable_ends_one() {
        let mut s = servo();
        let mut o = OpenLoop::default();
        o.start(s.state(), 50, 100).unwrap();
        let out = s.tick(&AT_REST);
        assert_eq!(o.demand(&AT_REST, &out), BridgeDemand::Drive(50));
        assert_eq!(o.last().unwrap().nudge_duty_permille, 50);
        s.enable().unwrap();
        let out = s.tick(&AT_REST);
        assert_eq!(o.demand(&AT_REST, &out), out.bridge);
        assert!(!o.running());
        assert_eq!(o.start(s.state(), 50, 100), Err(ErrorCode::NotAllowed));
    }
}
