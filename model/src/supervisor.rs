//! The supervisor (docs/design.md §7): per-tick checks that latch a fault and turn the motor
//! off in the same tick, separate from the controller's live limits (clamps, which keep
//! running and are only reported).
//!
//! # Checks, in the order they are made each tick
//!
//! | code | fault | condition | value (unit) |
//! |---|---|---|---|
//! | 1 | [`FaultCode::SensorRead`] | a driver returned an error | sensor ([`Sensor`] as `u8`) |
//! | 2 | [`FaultCode::AdcOutOfRange`] | current ADC outside `adc_min..=adc_max` (the rails: saturated or open) | raw counts |
//! | 3 | [`FaultCode::OverCurrent`] | \|i\| > trip current | mA |
//! | 4 | [`FaultCode::SensorJump`] | link encoder moved more than the physics allows in one tick, or the pot did | counts |
//! | 5 | [`FaultCode::SensorStuck`] | the deflection pot − encoder is beyond the beams' envelope, the link count has not changed for `stuck_ticks`, and the torque estimate is below half the capacity (the link reading is frozen while the gear moves on) | µrad of deflection |
//! | 6 | [`FaultCode::BeamOverload`] | \|τ̂\| > τ_cap(L) in `overload_ticks` consecutive ticks, or the measured deflection is beyond the envelope | µN·m, or µrad |
//! | 7 | [`FaultCode::PositionLimit`] | measured link angle outside the position window | µrad |
//! | 8 | [`FaultCode::DeadlineMissed`] | the control period overran (reported by the firmware) | sysclk counts of the tick |
//! | 9 | [`FaultCode::CommandTimeout`] | heartbeats armed and none for `command_timeout_ms` | ms since the last |
//! | 10 | [`FaultCode::ClutchMismatch`] | the clutch monitor's compliance estimate shows the beams softer than configured beyond its tolerance ([`crate::clutch_monitor`]) | estimated/configured compliance, ‰ |
//!
//! With a clutch tolerance above 0 (`control::Limits::clutch_tolerance`, default 0) the
//! torque and stuck-sensor checks compare against the clutch monitor's capacity (the
//! weakest the tolerance allows until the monitor, if on, confirms the stiffness) instead
//! of τ_cap(L).
//!
//! Deflection envelope: φ_b + θ_cap(L) + one pot count + half an encoder count (the two
//! quantisations) + the pot's error: any larger measured deflection means the beams are
//! bent beyond their stress capacity or a sensor lies. The pot's error is the fixed
//! `pot_tolerance_counts` (the pot centre's calibration tolerance, docs/design.md §9), or,
//! with the table calibration measured (`pot_error`, [`PotErrorTable`],
//! docs/calibration.md), per sixteenth of the pot's track: the table's entry for the bin of
//! this tick's reading plus its largest entry (the encoder was aligned to the pot at
//! power-up, wherever the link was, so that reading's error is in the link angle). The 16
//! envelopes are computed with the thresholds; per tick the check reads the one of the
//! reading's bin (a shift and an index).
//!
//! The torque estimate is a model output (k_t·i minus the gear's inertial torque from the
//! back-EMF observer): a duty jump with an imperfect resistance or back-EMF constant gives
//! it a one-tick spike of several N·m that no beam sees. A real overload lasts (a
//! collision, a stall against the load), so the torque check latches after
//! `overload_ticks` consecutive ticks beyond τ_cap (default 2). The jump bound is `max_link_speed`·1 ms + 1 count.
//!
//! Every threshold is converted to the per-tick formats when the supervisor is built
//! ([`Supervisor::new`]), never per tick; the per-tick work is compares and one multiply.

use crate::calibration::pot_error::{PotErrorTable, POT_ERROR_BINS};
use crate::clutch_monitor::{ClutchLimits, ClutchMonitor};
use crate::control::{Output, Schedule};
use crate::sensors::{
    encoder_delta, ADC_COUNTS, ADC_COUNTS_PER_A, ADC_MID, ENCODER_COUNTS,
    ENCODER_COUNT_Q32 as COUNT_Q32, POT_COUNTS, POT_COUNT_Q32,
};
use crate::units::{Angle, Torque};
use fixed::types::I32F32;

/// Ticks the torque-estimate check waits after [`Supervisor::restart_estimates`] (the
/// observer's start-up transient lasts 2–3 ticks, measured in `plant`'s harness with a link
/// falling under 0.3 N·m at L = 5 mm).
pub const RESTART_GRACE_TICKS: u16 = 8;

/// One radian as I32F32 bits.
const Q32_ONE: i64 = 1 << 32;

pub use fault::{FaultCode, FaultSet};

/// Which sensor a [`FaultCode::SensorRead`] or [`FaultCode::SensorJump`] is about.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[repr(u8)]
pub enum Sensor {
    /// Link magnetic encoder.
    LinkEncoder = 1,
    /// Gear potentiometer.
    GearPot = 2,
    /// Motor current ADC.
    CurrentAdc = 3,
}

/// A latched fault: what, the offending value (unit per [`FaultCode`], see the module
/// table) and the tick it was detected in.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Fault {
    /// What.
    pub code: FaultCode,
    /// The offending value.
    pub value: i32,
    /// The control tick (1-based count of ticks since start).
    pub tick: u32,
}

/// Supervisor settings in engineering units (validated by [`Supervisor::new`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SupervisorConfig {
    /// Over-current trip, A, in (0, 2). Default 1.75 A: above the controller's default
    /// 1.5 A clamp plus noise, below the ADC's ±2 A full scale.
    pub trip_current_a: I32F32,
    /// Lowest valid current ADC reading, counts. Default 16.
    pub adc_min: u16,
    /// Highest valid current ADC reading, counts. Default 4079.
    pub adc_max: u16,
    /// Fastest plausible link speed, rad/s, in (0, 1000]. Default 60 rad/s (the AX-12A's
    /// gear reaches 6.2 rad/s; the link may ring faster on the beams).
    pub max_link_speed: I32F32,
    /// Largest plausible change of the gear pot in one tick, counts. Default 8 (0.04 rad,
    /// six times the no-load gear speed).
    pub max_pot_jump: u16,
    /// Ticks without a link-count change before a frozen encoder is suspected. Default 2.
    pub stuck_ticks: u16,
    /// Link position window, rad: lowest. Default −2.5 rad (the AX-12A turns 300° = ±2.62).
    pub position_min: Angle,
    /// Link position window, rad: highest. Default +2.5 rad.
    pub position_max: Angle,
    /// Heartbeat timeout, ms, ≥ 1. Armed by the first heartbeat. Default 100 ms.
    pub command_timeout_ms: u32,
    /// Calibration tolerance of the gear pot's centre, counts, ≤ 100, added to the
    /// deflection envelope. Default 3 (what calibration leaves, docs/design.md §9).
    pub pot_tolerance_counts: u16,
    /// Consecutive ticks the torque estimate must exceed τ_cap before `beam-overload`
    /// latches, 1..=10. Default 2 (a one-tick spike of the estimate is not a load).
    pub overload_ticks: u16,
    /// The pot's error per sixteenth of its track as calibration measured it
    /// ([`PotErrorTable`]); replaces `pot_tolerance_counts` in the deflection envelope,
    /// bin by bin (module docs). `None` (default): the fixed tolerance.
    pub pot_error: Option<PotErrorTable>,
    /// Runs the clutch monitor's stiffness estimate ([`crate::clutch_monitor`]): the
    /// `clutch-mismatch` fault and, once the stiffness is confirmed, the capacity at the
    /// configured length. Runs only with a clutch tolerance above 0 (a board's until a
    /// calibration confirms the clutch). Default on; off, the overload check keeps the
    /// tolerance's weak capacity.
    pub clutch_monitor: bool,
}

impl SupervisorConfig {
    /// The defaults above.
    pub const DEFAULT: SupervisorConfig = SupervisorConfig {
        trip_current_a: I32F32::lit("1.75"),
        adc_min: 16,
        adc_max: 4079,
        max_link_speed: I32F32::lit("60"),
        max_pot_jump: 8,
        stuck_ticks: 2,
        position_min: Angle::from_fixed(I32F32::lit("-2.5")),
        position_max: Angle::from_fixed(I32F32::lit("2.5")),
        command_timeout_ms: 100,
        pot_tolerance_counts: 3,
        overload_ticks: 2,
        pot_error: None,
        clutch_monitor: true,
    };
}

impl Default for SupervisorConfig {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// Why a [`SupervisorConfig`] was rejected.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum SupervisorError {
    /// `trip_current_a` not in (0, 2) A.
    TripCurrent,
    /// `adc_min` ≥ `adc_max`, or `adc_max` > 4095.
    AdcWindow,
    /// `max_link_speed` not in (0, 1000] rad/s, or `max_pot_jump` is 0 or ≥ 1024.
    JumpBound,
    /// `stuck_ticks` is 0.
    StuckTicks,
    /// `position_min` ≥ `position_max`.
    PositionWindow,
    /// `command_timeout_ms` is 0.
    Timeout,
    /// `pot_tolerance_counts` above 100.
    PotTolerance,
    /// `overload_ticks` not in 1..=10.
    OverloadTicks,
    /// A `pot_error` entry above
    /// [`MAX_ERROR_CENTI`](crate::calibration::pot_error::MAX_ERROR_CENTI) (50 pot counts).
    PotErrorTable,
}

impl core::fmt::Display for SupervisorError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            SupervisorError::TripCurrent => "trip current outside (0, 2) A",
            SupervisorError::AdcWindow => "current ADC window empty or beyond 4095",
            SupervisorError::JumpBound => "sensor jump bound out of range",
            SupervisorError::StuckTicks => "stuck-sensor ticks must be at least 1",
            SupervisorError::PositionWindow => "position window empty",
            SupervisorError::Timeout => "command timeout must be at least 1 ms",
            SupervisorError::PotTolerance => "pot tolerance above 100 counts",
            SupervisorError::OverloadTicks => "overload ticks outside 1..=10",
            SupervisorError::PotErrorTable => "pot error table entry above 50 counts",
        })
    }
}

impl core::error::Error for SupervisorError {}

/// Inputs of one check, besides the controller's output.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Readings {
    /// Link encoder, raw counts.
    pub link_encoder: u16,
    /// Gear pot, raw counts, if the board has one.
    pub gear_pot: Option<u16>,
    /// Current ADC, raw counts.
    pub current_adc: u16,
    /// A driver failed this tick.
    pub read_error: Option<Sensor>,
}

/// Thresholds in per-tick formats (see [`Supervisor::new`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Thresholds {
    trip_adc: i32,
    adc_min: u16,
    adc_max: u16,
    max_jump_counts: i32,
    max_pot_jump: i32,
    stuck_ticks: u16,
    /// τ_cap(L), I32F32 bits.
    torque_cap: i64,
    pot_center: i32,
    position_min: i64,
    position_max: i64,
    timeout_ticks: u32,
    overload_ticks: u16,
}

/// The supervisor: thresholds derived from the configuration, the latch and the little
/// history the checks need.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Supervisor {
    cfg: SupervisorConfig,
    th: Thresholds,
    latched: FaultSet,
    first: Option<Fault>,
    prev_encoder: Option<u16>,
    prev_pot: Option<u16>,
    unchanged_ticks: u16,
    /// Consecutive ticks the torque estimate has been beyond τ_cap.
    over_ticks: u16,
    /// Ticks left before the torque-estimate check counts again after
    /// [`Supervisor::restart_estimates`].
    grace_ticks: u16,
    last_heartbeat: Option<u32>,
    /// The first condition that held at the last check (latched then or before), with its
    /// value then: what a clear would latch again at the next tick. Events (a sensor jump,
    /// the command timeout) are not conditions.
    condition: Option<Fault>,
    /// The clutch monitor and its constants (when the clutch tolerance is > 0; kept out of
    /// the thresholds, which the check copies each tick).
    clutch: ClutchMonitor,
    clutch_lim: Option<ClutchLimits>,
    /// Deflection envelope per bin of the canonical pot reading
    /// ([`PotErrorTable::bin`]), I32F32 bits (rad): all equal without a pot error table.
    /// Kept out of the thresholds (which the check copies each tick): one entry is read.
    envelopes: [i64; POT_ERROR_BINS],
}

impl Supervisor {
    /// Derives the thresholds from `cfg` and the controller's schedule (τ_cap, θ_cap and
    /// φ_b at the configured clutch length, the pot calibration).
    ///
    /// # Errors
    /// [`SupervisorError`] for a setting out of its documented range.
    pub fn new(cfg: &SupervisorConfig, sched: &Schedule) -> Result<Supervisor, SupervisorError> {
        let th = Self::thresholds(cfg, sched)?;
        Ok(Supervisor {
            clutch_lim: Self::clutch_limits(sched),
            envelopes: Self::envelopes(cfg, sched),
            cfg: *cfg,
            th,
            latched: FaultSet(0),
            first: None,
            prev_encoder: None,
            prev_pot: None,
            unchanged_ticks: 0,
            over_ticks: 0,
            grace_ticks: 0,
            last_heartbeat: None,
            condition: None,
            clutch: ClutchMonitor::new(),
        })
    }

    /// Re-derives the thresholds for a new schedule (clutch length changed), keeping the
    /// latch and the history. On error nothing changes.
    ///
    /// # Errors
    /// As [`Supervisor::new`].
    pub fn reconfigure(
        &mut self,
        cfg: &SupervisorConfig,
        sched: &Schedule,
    ) -> Result<(), SupervisorError> {
        self.th = Self::thresholds(cfg, sched)?;
        self.cfg = *cfg;
        self.clutch = ClutchMonitor::new();
        self.clutch_lim = Self::clutch_limits(sched);
        self.envelopes = Self::envelopes(cfg, sched);
        Ok(())
    }

    /// The clutch monitor's constants (`None` with a zero clutch tolerance).
    fn clutch_limits(sched: &Schedule) -> Option<ClutchLimits> {
        (sched.clutch_tolerance().to_bits() > 0).then(|| ClutchLimits::new(sched))
    }

    fn thresholds(cfg: &SupervisorConfig, sched: &Schedule) -> Result<Thresholds, SupervisorError> {
        let trip = cfg.trip_current_a.to_bits();
        if trip <= 0 || trip >= 2 * Q32_ONE {
            return Err(SupervisorError::TripCurrent);
        }
        if cfg.adc_min >= cfg.adc_max || cfg.adc_max >= ADC_COUNTS {
            return Err(SupervisorError::AdcWindow);
        }
        let speed = cfg.max_link_speed.to_bits();
        if speed <= 0 || speed > 1000 * Q32_ONE {
            return Err(SupervisorError::JumpBound);
        }
        if cfg.max_pot_jump == 0 || cfg.max_pot_jump >= POT_COUNTS {
            return Err(SupervisorError::JumpBound);
        }
        if cfg.stuck_ticks == 0 {
            return Err(SupervisorError::StuckTicks);
        }
        if cfg.position_min.to_bits() >= cfg.position_max.to_bits() {
            return Err(SupervisorError::PositionWindow);
        }
        if cfg.command_timeout_ms == 0 {
            return Err(SupervisorError::Timeout);
        }
        if cfg.pot_tolerance_counts > 100 {
            return Err(SupervisorError::PotTolerance);
        }
        if !(1..=10).contains(&cfg.overload_ticks) {
            return Err(SupervisorError::OverloadTicks);
        }
        if cfg.pot_error.is_some_and(|t| !t.is_valid()) {
            return Err(SupervisorError::PotErrorTable);
        }
        // Counts per tick at max speed: speed[rad/s]·1e-3 s / count, rounded up, + 1.
        let per_tick = speed / 1000;
        let max_jump_counts = (per_tick + COUNT_Q32 - 1) / COUNT_Q32 + 1;
        let setting = sched.setting();
        Ok(Thresholds {
            // |adc − mid| > trip·1024, rounded down: trips at or above the trip current.
            trip_adc: ((trip * i64::from(ADC_COUNTS_PER_A)) >> 32) as i32,
            adc_min: cfg.adc_min,
            adc_max: cfg.adc_max,
            max_jump_counts: max_jump_counts.clamp(1, i64::from(ENCODER_COUNTS / 2)) as i32,
            max_pot_jump: i32::from(cfg.max_pot_jump),
            stuck_ticks: cfg.stuck_ticks,
            torque_cap: setting.torque_capacity().to_bits(),
            pot_center: sched.pot_center,
            position_min: cfg.position_min.to_bits(),
            position_max: cfg.position_max.to_bits(),
            timeout_ticks: cfg.command_timeout_ms,
            overload_ticks: cfg.overload_ticks,
        })
    }

    /// The deflection envelope of each pot bin (module docs), I32F32 bits. `cfg` is
    /// valid. Without a table every bin has φ_b + θ_cap + (1 + `pot_tolerance_counts`)
    /// pot counts + half an encoder count; with one, bin b has φ_b + θ_cap + one pot
    /// count + half an encoder count + the table's entry b (the reading's error here) +
    /// its largest entry (the error of the reading the encoder was aligned to at power-up,
    /// anywhere on the track).
    fn envelopes(cfg: &SupervisorConfig, sched: &Schedule) -> [i64; POT_ERROR_BINS] {
        let base = sched
            .free_play()
            .to_bits()
            .saturating_add(sched.setting().deflection_capacity().to_bits())
            .saturating_add(POT_COUNT_Q32)
            .saturating_add(COUNT_Q32 / 2);
        let counts = |centi: u16| POT_COUNT_Q32 * i64::from(centi) / 100;
        match cfg.pot_error {
            None => {
                [base.saturating_add(counts(cfg.pot_tolerance_counts.saturating_mul(100)));
                    POT_ERROR_BINS]
            }
            Some(t) => {
                let aligned = counts(t.max_centi());
                t.centi
                    .map(|e| base.saturating_add(aligned).saturating_add(counts(e)))
            }
        }
    }

    /// Takes the configuration and thresholds of `other` (built for another schedule),
    /// keeping this supervisor's latch and history.
    pub fn install_thresholds(&mut self, other: &Supervisor) {
        self.cfg = other.cfg;
        self.th = other.th;
        self.clutch = ClutchMonitor::new();
        self.clutch_lim = other.clutch_lim;
        self.envelopes = other.envelopes;
    }

    /// The configuration in use.
    #[must_use]
    pub const fn config(&self) -> &SupervisorConfig {
        &self.cfg
    }

    /// τ_cap(L) at the configured clutch length.
    #[must_use]
    pub fn torque_capacity(&self) -> Torque {
        Torque::from_bits(self.th.torque_cap)
    }

    /// The capacity the overload and stuck-sensor checks use now: τ_cap(L), or with a
    /// clutch tolerance the clutch monitor's (the weak one until it confirms).
    #[must_use]
    pub fn checked_capacity(&self) -> Torque {
        Torque::from_bits(self.capacity())
    }

    /// [`Supervisor::checked_capacity`], I32F32 bits.
    fn capacity(&self) -> i64 {
        match &self.clutch_lim {
            Some(lim) => self.clutch.capacity(lim),
            None => self.th.torque_cap,
        }
    }

    /// The clutch monitor's compliance estimate relative to the configured one, Q16
    /// (`None` without enough evidence, with the monitor off or the clutch tolerance 0).
    /// Divides: for reports.
    #[must_use]
    pub fn clutch_ratio_q16(&self) -> Option<i64> {
        self.monitor_limits()
            .and_then(|lim| self.clutch.ratio_q16(lim))
    }

    /// The clutch monitor's conclusion (`None` with the monitor off or the clutch
    /// tolerance 0).
    #[must_use]
    pub fn clutch_state(&self) -> Option<crate::clutch_monitor::ClutchState> {
        self.monitor_limits().map(|_| self.clutch.state())
    }

    /// The clutch monitor's constants when it runs.
    fn monitor_limits(&self) -> Option<&ClutchLimits> {
        monitor_running(&self.clutch_lim, &self.cfg)
    }

    /// Deflection envelope (φ_b + θ_cap + the pot's error + quantisation) the overload and
    /// stuck checks use at canonical pot reading `pot`.
    #[must_use]
    pub fn deflection_envelope_at(&self, pot: u16) -> Angle {
        Angle::from_bits(self.envelopes[PotErrorTable::bin(pot)])
    }

    /// The smallest deflection envelope over the pot's track (the only one without a pot
    /// error table).
    #[must_use]
    pub fn deflection_envelope(&self) -> Angle {
        Angle::from_bits(self.envelopes.iter().copied().min().unwrap_or(0))
    }

    /// Largest plausible link-encoder change per tick, counts.
    #[must_use]
    pub const fn max_jump_counts(&self) -> i32 {
        self.th.max_jump_counts
    }

    /// The latched faults.
    #[must_use]
    pub const fn latched(&self) -> FaultSet {
        self.latched
    }

    /// The first fault latched since the last clear.
    #[must_use]
    pub const fn first_fault(&self) -> Option<Fault> {
        self.first
    }

    /// Records a heartbeat from the host at `tick`; the first one arms the timeout.
    pub fn heartbeat(&mut self, tick: u32) {
        self.last_heartbeat = Some(tick);
    }

    /// Stops the heartbeat timeout (the host said goodbye).
    pub fn disarm_heartbeat(&mut self) {
        self.last_heartbeat = None;
    }

    /// Whether a heartbeat has armed the timeout (and nothing disarmed it since).
    #[must_use]
    pub const fn heartbeat_armed(&self) -> bool {
        self.last_heartbeat.is_some()
    }

    /// The first fault condition that held at the last check, with its value and tick
    /// then: a [`Supervisor::clear`] now would see it latch again at the next tick.
    #[must_use]
    pub const fn condition(&self) -> Option<Fault> {
        self.condition
    }

    /// Forgets the sensor history (last readings, frozen-count counter): the next tick
    /// is the first of a new run, e.g. after the mechanism was re-mounted.
    pub fn forget_history(&mut self) {
        self.prev_encoder = None;
        self.prev_pot = None;
        self.unchanged_ticks = 0;
        self.over_ticks = 0;
    }

    /// The readings' frame changed (the sensor-correction layer aligned the encoder to the
    /// pot at power-up): [`Supervisor::forget_history`], and the torque-estimate check
    /// waits [`RESTART_GRACE_TICKS`] ticks. The controller's observer then starts from
    /// rest while the mechanism may be moving (a link that fell under its load during the
    /// boot window, motor off): its first estimates carry the gear's deceleration as a
    /// torque no beam sees. The deflection check (measured, pot against encoder) guards the
    /// beams from the first tick.
    pub fn restart_estimates(&mut self) {
        self.forget_history();
        self.grace_ticks = RESTART_GRACE_TICKS;
    }

    /// Clears the latch (the caller decides when the motor may run again).
    pub fn clear(&mut self) {
        self.latched = FaultSet(0);
        self.first = None;
    }

    fn latch(&mut self, code: FaultCode, value: i32, tick: u32) -> Option<Fault> {
        if self.latched.contains(code) {
            return None;
        }
        self.latched.0 |= code.bit();
        let fault = Fault { code, value, tick };
        if self.first.is_none() {
            self.first = Some(fault);
        }
        Some(fault)
    }

    /// Reports a control period that overran, measured by the firmware (`busy` sysclk
    /// counts); latches [`FaultCode::DeadlineMissed`].
    pub fn deadline_missed(&mut self, tick: u32, busy: u32) -> Option<Fault> {
        let v = i32::try_from(busy).unwrap_or(i32::MAX);
        self.latch(FaultCode::DeadlineMissed, v, tick)
    }

    /// Runs the per-tick checks on this tick's readings and the controller's output and
    /// returns the first fault newly latched in this tick, if any (later checks of the
    /// same tick still latch their codes in [`Supervisor::latched`]).
    pub fn check(&mut self, tick: u32, r: &Readings, out: &Output) -> Option<Fault> {
        let mut new: Option<Fault> = None;
        self.condition = None;
        let mut note = |s: &mut Self, code: FaultCode, value: i32| {
            // A jump (a change between two ticks) and the timeout (which ends its
            // session) are events, gone at the next tick; the rest are conditions.
            let event = matches!(code, FaultCode::SensorJump | FaultCode::CommandTimeout);
            if s.condition.is_none() && !event {
                s.condition = Some(Fault { code, value, tick });
            }
            if let Some(f) = s.latch(code, value, tick) {
                if new.is_none() {
                    new = Some(f);
                }
            }
        };
        let th = self.th;

        if let Some(sensor) = r.read_error {
            note(self, FaultCode::SensorRead, sensor as i32);
        }

        // Current: the rails first (a saturated or open ADC says nothing about i).
        if r.current_adc < th.adc_min || r.current_adc > th.adc_max {
            note(self, FaultCode::AdcOutOfRange, i32::from(r.current_adc));
        } else {
            let adc = i32::from(r.current_adc) - i32::from(ADC_MID);
            if adc.abs() > th.trip_adc {
                // mA = counts·1000/1024.
                note(
                    self,
                    FaultCode::OverCurrent,
                    adc * 1000 / i32::from(ADC_COUNTS_PER_A),
                );
            }
        }

        // Encoder jump (wrapped difference).
        let mut link_moved = true;
        if let Some(prev) = self.prev_encoder {
            let d = encoder_delta(r.link_encoder, prev);
            if d.abs() > th.max_jump_counts {
                note(self, FaultCode::SensorJump, d);
            }
            link_moved = d != 0;
        }
        self.prev_encoder = Some(r.link_encoder);
        self.unchanged_ticks = if link_moved {
            0
        } else {
            self.unchanged_ticks.saturating_add(1)
        };

        // Deflection from the pot: θ_g − θ_l against the envelope.
        if let Some(pot) = r.gear_pot {
            if let Some(prev) = self.prev_pot {
                let d = i32::from(pot) - i32::from(prev);
                if d.abs() > th.max_pot_jump {
                    note(self, FaultCode::SensorJump, d);
                }
            }
            self.prev_pot = Some(pot);
            let theta_g = i64::from(i32::from(pot) - th.pot_center).saturating_mul(POT_COUNT_Q32);
            let phi = theta_g.saturating_sub(out.link_angle.to_bits());
            // The fields, not `monitor_limits`: the monitor itself is borrowed mutably.
            let mismatch = match monitor_running(&self.clutch_lim, &self.cfg) {
                Some(lim) if self.clutch.update(phi, out, lim) => {
                    Some(self.clutch.mismatch_permille())
                }
                _ => None,
            };
            if let Some(permille) = mismatch {
                note(self, FaultCode::ClutchMismatch, permille);
            }
            if phi.saturating_abs() > self.envelopes[PotErrorTable::bin(pot)] {
                let tau = out.torque_estimate.to_bits().saturating_abs();
                let micro = to_micro(phi);
                if self.unchanged_ticks >= th.stuck_ticks && tau < self.capacity() / 2 {
                    note(self, FaultCode::SensorStuck, micro);
                } else {
                    note(self, FaultCode::BeamOverload, micro);
                }
            }
        } else {
            self.prev_pot = None;
        }

        let tau = out.torque_estimate.to_bits();
        let cap = self.capacity();
        if self.grace_ticks > 0 {
            self.grace_ticks -= 1;
        } else if tau.saturating_abs() > cap {
            self.over_ticks = self.over_ticks.saturating_add(1);
            if self.over_ticks >= th.overload_ticks {
                note(self, FaultCode::BeamOverload, to_micro(tau));
            }
        } else {
            self.over_ticks = 0;
        }

        let theta = out.link_angle.to_bits();
        if theta < th.position_min || theta > th.position_max {
            note(self, FaultCode::PositionLimit, to_micro(theta));
        }

        if let Some(last) = self.last_heartbeat {
            let since = tick.wrapping_sub(last);
            if since > th.timeout_ticks {
                note(
                    self,
                    FaultCode::CommandTimeout,
                    i32::try_from(since).unwrap_or(i32::MAX),
                );
                // The session that armed the timeout is over: a clear recovers.
                self.last_heartbeat = None;
            }
        }
        new
    }
}

/// The clutch monitor's constants when `cfg` runs it (and a clutch tolerance gave them).
fn monitor_running<'a>(
    lim: &'a Option<ClutchLimits>,
    cfg: &SupervisorConfig,
) -> Option<&'a ClutchLimits> {
    lim.as_ref().filter(|_| cfg.clutch_monitor)
}

/// I32F32 bits → millionths (µrad, µN·m), saturated to i32.
fn to_micro(bits: i64) -> i32 {
    let v = (i128::from(bits) * 1_000_000) >> 32;
    v.clamp(i128::from(i32::MIN), i128::from(i32::MAX)) as i32
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::control::Config;
    use crate::{Design, Length};

    fn sup(len_mm: i32) -> (Supervisor, Schedule) {
        let d = Design::paper();
        let sched = Schedule::new(&d, &Config::paper(Length::from_int(len_mm))).unwrap();
        (
            Supervisor::new(&SupervisorConfig::DEFAULT, &sched).unwrap(),
            sched,
        )
    }

    fn quiet(enc: u16) -> Readings {
        Readings {
            link_encoder: enc,
            gear_pot: Some(512),
            current_adc: 2048,
            read_error: None,
        }
    }

    fn at_rest() -> Output {
        Output {
            link_angle: Angle::from_bits(COUNT_Q32 / 2),
            ..Output::default()
        }
    }

    #[test]
    fn a_quiet_actuator_raises_nothing() {
        let (mut s, _) = sup(3);
        for t in 1..100 {
            assert_eq!(s.check(t, &quiet(0), &at_rest()), None);
        }
        assert!(s.latched().is_empty());
    }

    #[test]
    fn thresholds_follow_the_configuration() {
        let (s, sched) = sup(5);
        // 60 rad/s·1 ms = 0.06 rad = 39.1 counts → 40 + 1.
        assert_eq!(s.max_jump_counts(), 41);
        assert_eq!(s.torque_capacity(), sched.setting().torque_capacity());
        let env = s.deflection_envelope().to_bits();
        let parts = sched.free_play().to_bits() + sched.setting().deflection_capacity().to_bits();
        assert_eq!(env, parts + 4 * POT_COUNT_Q32 + COUNT_Q32 / 2);
    }

    #[test]
    fn each_check_latches_its_code_with_value_and_tick() {
        let (mut s, _) = sup(3);
        s.check(1, &quiet(0), &at_rest());
        // ADC rail.
        let mut r = quiet(0);
        r.current_adc = 4095;
        let f = s.check(2, &r, &at_rest()).unwrap();
        assert_eq!(
            (f.code, f.value, f.tick),
            (FaultCode::AdcOutOfRange, 4095, 2)
        );
        // Over-current: 1.8 A = 2048 + 1843.
        r.current_adc = 2048 + 1843;
        let f = s.check(3, &r, &at_rest()).unwrap();
        assert_eq!((f.code, f.value), (FaultCode::OverCurrent, 1799));
        // Already latched codes are not reported again.
        assert_eq!(s.check(4, &r, &at_rest()), None);
        assert!(s.latched().contains(FaultCode::AdcOutOfRange));
        assert_eq!(s.first_fault().unwrap().code, FaultCode::AdcOutOfRange);
        s.clear();
        assert!(s.latched().is_empty());
        let f = s.check(5, &r, &at_rest()).unwrap();
        assert_eq!(f.code, FaultCode::OverCurrent);
    }

    #[test]
    fn an_encoder_jump_beyond_the_speed_bound_is_a_sensor_fault() {
        let (mut s, _) = sup(3);
        s.check(1, &quiet(4090), &at_rest());
        // Wrapping by 41 counts (4090 → 35) is allowed, 42 is not.
        assert_eq!(s.check(2, &quiet(35), &at_rest()), None);
        let f = s.check(3, &quiet(77), &at_rest()).unwrap();
        assert_eq!((f.code, f.value), (FaultCode::SensorJump, 42));
    }

    #[test]
    fn torque_beyond_capacity_is_an_overload_and_the_window_a_position_limit() {
        let d = Design::paper();
        let full = Schedule::new(&d, &Config::paper(Length::from_int(5)))
            .unwrap()
            .setting()
            .torque_capacity()
            .to_bits();
        // Without a clutch tolerance τ_cap(L); with 0.6 mm, while the clutch monitor is
        // undecided, the capacity of a clutch 0.6 mm long, τ_cap·5/5.6 (τ_cap ∝ 1/L), to
        // within a few bits of rounding.
        for (tol_um, cap) in [(0, full), (600, full * 50 / 56 - (1 << 8))] {
            let mut cfg = Config::paper(Length::from_int(5));
            cfg.limits.clutch_tolerance = Length::from_micro(tol_um * 1000).unwrap();
            let sched = Schedule::new(&d, &cfg).unwrap();
            let mut s = Supervisor::new(&SupervisorConfig::DEFAULT, &sched).unwrap();
            let mut out = at_rest();
            out.torque_estimate = Torque::from_bits(cap);
            assert_eq!(s.check(1, &quiet(0), &out), None);
            let beyond = cap + (1 << 9);
            out.torque_estimate = Torque::from_bits(-beyond);
            // One tick beyond is a spike of the estimate, two are a load.
            assert_eq!(s.check(2, &quiet(0), &out), None);
            out.torque_estimate = Torque::from_bits(cap);
            assert_eq!(s.check(3, &quiet(0), &out), None);
            out.torque_estimate = Torque::from_bits(-beyond);
            assert_eq!(s.check(4, &quiet(0), &out), None);
            assert_eq!(
                s.check(5, &quiet(0), &out).unwrap().code,
                FaultCode::BeamOverload,
                "tolerance {tol_um} µm"
            );
        }
        let (mut s, _) = sup(5);
        let mut out = at_rest();
        out.link_angle = Angle::from_bits(-(5 * Q32_ONE) / 2 - 1);
        let mut no_pot = quiet(0);
        no_pot.gear_pot = None; // the pot would see a deflection
        let f = s.check(3, &no_pot, &out).unwrap();
        assert_eq!((f.code, f.value), (FaultCode::PositionLimit, -2_500_001));
    }

    #[test]
    fn deflection_beyond_the_envelope_is_overload_unless_the_encoder_is_frozen() {
        // Pot 3 counts off: the calibration tolerance, no fault.
        let mut r = quiet(0);
        r.gear_pot = Some(515);
        let (mut s, _) = sup(1);
        for t in 1..=5 {
            assert_eq!(s.check(t, &r, &at_rest()), None);
        }
        let (mut s, _) = sup(1);
        // Pot 8 counts (0.041 rad) off the link: beyond φ_b + θ_cap + margins at L = 1 mm.
        r.gear_pot = Some(520);
        s.check(1, &quiet(0), &at_rest());
        let f = s.check(2, &r, &at_rest()).unwrap();
        // The link count did not change in 1 tick only: not yet "stuck".
        assert_eq!(f.code, FaultCode::BeamOverload);
        let (mut s, _) = sup(1);
        for t in 1..=3 {
            assert_eq!(s.check(t, &quiet(0), &at_rest()), None);
        }
        let f = s.check(4, &r, &at_rest()).unwrap();
        assert_eq!(f.code, FaultCode::SensorStuck);
        assert!(f.value > 39_000, "{f:?}");
    }

    #[test]
    fn without_a_pot_error_table_every_bin_has_the_fixed_envelope() {
        let (s, _) = sup(3);
        let env = s.deflection_envelope();
        for pot in (0..1024).step_by(7) {
            assert_eq!(s.deflection_envelope_at(pot), env);
        }
    }

    /// A table with bin 4 at 10 counts (the largest) and bin 10 at 1 count.
    fn with_table() -> SupervisorConfig {
        let mut t = PotErrorTable {
            centi: [250; POT_ERROR_BINS],
        };
        t.centi[4] = 1000;
        t.centi[10] = 100;
        SupervisorConfig {
            pot_error: Some(t),
            ..SupervisorConfig::DEFAULT
        }
    }

    #[test]
    fn the_pot_error_table_sizes_the_envelope_bin_by_bin() {
        let d = Design::paper();
        let sched = Schedule::new(&d, &Config::paper(Length::from_int(3))).unwrap();
        let mut s = Supervisor::new(&with_table(), &sched).unwrap();
        // Oracle in f64: φ_b + θ_cap from the schedule, the quantisations and the table's
        // entries from the sensors' resolutions (300°/1024, 2π/4096).
        let rad = |bits: i64| bits as f64 / 4_294_967_296.0;
        let pot_count = 300f64.to_radians() / 1024.0;
        let fixed = rad(sched.free_play().to_bits())
            + rad(sched.setting().deflection_capacity().to_bits())
            + pot_count
            + core::f64::consts::PI / 4096.0;
        // Bin b: its entry + the largest (10 counts: the alignment at power-up).
        let want = |centi: f64| fixed + pot_count * (centi + 1000.0) / 100.0;
        for (pot, centi) in [
            (256u16, 1000.0),
            (300, 1000.0),
            (640, 100.0),
            (703, 100.0),
            (0, 250.0),
        ] {
            let got = rad(s.deflection_envelope_at(pot).to_bits());
            assert!(
                (got - want(centi)).abs() < 1e-8,
                "pot {pot}: {got} vs {}",
                want(centi)
            );
        }
        assert!((rad(s.deflection_envelope().to_bits()) - want(100.0)).abs() < 1e-8);
        // In bin 10 (pot 660) the envelope is 12 counts + φ_b + θ_cap + half an encoder
        // count (2.3 counts at L = 3 mm): 15 counts off trips, 12 do not. The link angle is
        // set to the pot's gear angle, then the pot moves off it.
        let at = |pot: u16, off: i32| -> (Readings, Output) {
            let mut r = quiet(0);
            r.gear_pot = Some((i32::from(pot) + off) as u16);
            let out = Output {
                link_angle: Angle::from_bits(i64::from(i32::from(pot) - 512) * POT_COUNT_Q32),
                ..Output::default()
            };
            (r, out)
        };
        let (r, out) = at(660, 12);
        assert_eq!(s.check(1, &r, &out), None);
        let (r, out) = at(660, 15);
        assert_eq!(s.check(2, &r, &out).unwrap().code, FaultCode::BeamOverload);
        // In bin 4 (pot 290, entry 10 counts) 20 counts are within the envelope (23.3).
        let (mut s, _) = (Supervisor::new(&with_table(), &sched).unwrap(), ());
        let (r, out) = at(290, 14);
        assert_eq!(s.check(1, &r, &out), None);
        let (r, out) = at(290, 20);
        assert_eq!(s.check(2, &r, &out), None);
        // The fixed tolerance trips there at once.
        let (mut f, _) = sup(3);
        let (r, out) = at(290, 14);
        assert_eq!(f.check(1, &r, &out).unwrap().code, FaultCode::BeamOverload);
    }

    #[test]
    fn reconfiguring_keeps_the_table_and_installing_copies_it() {
        let d = Design::paper();
        let s3 = Schedule::new(&d, &Config::paper(Length::from_int(3))).unwrap();
        let s5 = Schedule::new(&d, &Config::paper(Length::from_int(5))).unwrap();
        let mut s = Supervisor::new(&with_table(), &s3).unwrap();
        let other = Supervisor::new(&with_table(), &s5).unwrap();
        s.reconfigure(&with_table(), &s5).unwrap();
        assert_eq!(
            s.deflection_envelope_at(290),
            other.deflection_envelope_at(290)
        );
        let (mut plain, _) = sup(5);
        plain.install_thresholds(&other);
        assert_eq!(
            plain.deflection_envelope_at(660),
            other.deflection_envelope_at(660)
        );
        assert_eq!(plain.config().pot_error, with_table().pot_error);
    }

    #[test]
    fn the_heartbeat_timeout_is_armed_by_the_first_heartbeat() {
        let (mut s, _) = sup(3);
        assert_eq!(s.check(500, &quiet(0), &at_rest()), None);
        s.heartbeat(500);
        assert_eq!(s.check(600, &quiet(0), &at_rest()), None);
        let f = s.check(601, &quiet(0), &at_rest()).unwrap();
        assert_eq!((f.code, f.value), (FaultCode::CommandTimeout, 101));
        // The timeout ends the session: disarmed, no condition left, a clear holds.
        assert!(!s.heartbeat_armed());
        assert_eq!(s.condition(), None);
        assert_eq!(s.check(602, &quiet(0), &at_rest()), None);
        s.clear();
        assert_eq!(s.check(700, &quiet(0), &at_rest()), None);
        assert!(s.latched().is_empty());
    }

    #[test]
    fn the_condition_of_the_last_check_is_kept_for_a_clear() {
        let (mut s, _) = sup(3);
        let mut out = at_rest();
        let mut no_pot = quiet(0);
        no_pot.gear_pot = None;
        // Outside the window: latched, and still there at the next check.
        out.link_angle = Angle::from_bits(3 * Q32_ONE);
        s.check(1, &no_pot, &out).unwrap();
        assert_eq!(s.check(2, &no_pot, &out), None);
        let c = s.condition().unwrap();
        assert_eq!(
            (c.code, c.value, c.tick),
            (FaultCode::PositionLimit, 3_000_000, 2)
        );
        // Back inside: the condition is gone, the latch stays until cleared.
        s.check(3, &no_pot, &at_rest());
        assert_eq!(s.condition(), None);
        assert!(s.latched().contains(FaultCode::PositionLimit));
    }

    #[test]
    fn bad_settings_are_rejected() {
        let d = Design::paper();
        let sched = Schedule::new(&d, &Config::paper(Length::from_int(3))).unwrap();
        let bad = |f: fn(&mut SupervisorConfig)| {
            let mut c = SupervisorConfig::DEFAULT;
            f(&mut c);
            Supervisor::new(&c, &sched).unwrap_err()
        };
        assert_eq!(
            bad(|c| c.trip_current_a = I32F32::ZERO),
            SupervisorError::TripCurrent
        );
        assert_eq!(
            bad(|c| c.trip_current_a = I32F32::lit("2")),
            SupervisorError::TripCurrent
        );
        assert_eq!(bad(|c| c.adc_min = 4079), SupervisorError::AdcWindow);
        assert_eq!(bad(|c| c.adc_max = 4096), SupervisorError::AdcWindow);
        assert_eq!(
            bad(|c| c.max_link_speed = I32F32::ZERO),
            SupervisorError::JumpBound
        );
        assert_eq!(bad(|c| c.max_pot_jump = 0), SupervisorError::JumpBound);
        assert_eq!(bad(|c| c.stuck_ticks = 0), SupervisorError::StuckTicks);
        assert_eq!(
            bad(|c| c.position_max = c.position_min),
            SupervisorError::PositionWindow
        );
        assert_eq!(bad(|c| c.command_timeout_ms = 0), SupervisorError::Timeout);
        assert_eq!(
            bad(|c| c.pot_tolerance_counts = 101),
            SupervisorError::PotTolerance
        );
        assert_eq!(
            bad(|c| c.overload_ticks = 0),
            SupervisorError::OverloadTicks
        );
        assert_eq!(
            bad(|c| c.overload_ticks = 11),
            SupervisorError::OverloadTicks
        );
        assert_eq!(
            bad(|c| {
                let mut t = PotErrorTable::default();
                t.centi[9] = crate::calibration::pot_error::MAX_ERROR_CENTI + 1;
                c.pot_error = Some(t);
            }),
            SupervisorError::PotErrorTable
        );
    }
}
