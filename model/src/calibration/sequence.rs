//! The calibration sequence (docs/calibration.md): one step per control tick from the
//! disabled state, seeing the actuator only through its raw readings ([`TickInput`], what
//! the sensor drivers deliver) and answering with the bridge duty. The motor torque never
//! exceeds a bound that holds at the longest clutch length ([`CalibrationConfig::new`]);
//! every tick checks the current against that bound and the trip level, the ADC rails and
//! the encoder's jumps, and a failure ends with the motor off and a [`Failure`] naming what
//! to check.
//!
//! Phases: rest (motor off: current offset and noise, pot noise and rails) → nudge (duty
//! ramped from 0 until a sensor moves: motor polarity, pot direction, dead sensors) →
//! nine moves at a constant duty from rest, each ended by the pot at a target angle
//! (−, +, −, … back to the middle; each start gives R from the first ticks' current and the
//! total inertia from the current's transient, each steady part k_e, the friction current
//! and the pot's slope and offset against the encoder) → done.
//!
//! Signs: the three wiring signs seen together are indistinguishable from none (the whole
//! actuator mirrored), so the encoder's direction is the configured reference (the
//! direction the user calls positive) and the motor's polarity and the pot's direction
//! are found relative to it. The current sense's gain multiplies R and divides k_t as
//! seen through it: R is found as the sense sees it (R/gain), the value the controller
//! needs. The stiffness needs a torque on the beams that a free link does not give
//! (at most J_link·α, a fraction of a pot count): it is reported as not resolvable.
//!
//! The pot's error table ([`PotErrorTable`], docs/calibration.md): once a − and a + move
//! have steady parts, the pot is fitted against the encoder over them (one slope, one
//! intercept per direction: the free play and the steady deflection are the difference of
//! the two intercepts); over the steady parts of every later move each bin of the
//! canonical pot track keeps the largest |pot − that line| it sees, in canonical counts.
//! At the end each visited bin's entry is that bound plus a noise margin (three standard
//! deviations of the pot at rest, at least half a count: the bound is the largest of the
//! samples seen, the next reading may round the other way); a bin the moves did not
//! visit gets the largest visited entry or the supervisor's fixed pot tolerance, whichever
//! is larger (nothing was measured there: no tighter than the fixed check, no tighter than
//! the worst seen). Entries are capped at [`MAX_ERROR_CENTI`] (a pot that bad trips the
//! supervisor's deflection check in use, which is the point).
//!
//! Arithmetic: integer sums per tick; the divisions happen once when the provisional fit
//! is made and once in the final tick.

use fixed::types::I32F32;

use super::correction::{wrapped_delta, Corrector, SensorCorrection, Sign};
use super::pot_error::{PotErrorTable, MAX_ERROR_CENTI, POT_ERROR_BINS};
use crate::beam::{BeamModel, Setting};
use crate::control::MotorParams;
use crate::design::Design;
use crate::sensors::{ADC_COUNTS_PER_A, POT_COUNTS, POT_SPAN_DEG};
use crate::servo::TickInput;
use crate::supervisor::SupervisorConfig;
use crate::units::Torque;

/// Ticks at rest with the motor off for the offset and noise statistics.
const REST_TICKS: u32 = 256;
/// Ticks of rest between moves.
const PAUSE_TICKS: u32 = 200;
/// Largest duty of the nudge, ‰, ramped by 1 ‰ per tick.
const NUDGE_MAX_DUTY: i32 = 400;
/// Pot counts (from its rest mean) that count as the gear having moved in the nudge.
const NUDGE_POT: i32 = 8;
/// Encoder counts that count as the link having moved in the nudge.
const NUDGE_ENC: i32 = 40;
/// Encoder counts below which a sensor is said not to have moved.
const STILL_ENC: i32 = 4;
/// Pot counts below which the pot is said not to have moved.
const STILL_POT: i32 = 3;
/// First tick of a move's steady part.
const STEADY_FROM: u32 = 160;
/// A move must last this long for its steady part to count.
const MIN_STEADY: u32 = 100;
/// Longest move, ticks.
const MOVE_TIMEOUT: u32 = 4000;
/// Moves: alternately to −0.6 and +0.6 rad, the last back to the middle. The inertia is
/// the average over them (one move's current transient carries about one ADC count of
/// rounding per tick, a percent of the total inertia).
const MOVES: usize = 9;
/// Target of the outer moves: ±0.6 rad of gear angle, in pot counts (0.6·1024/(300°·π/180)).
const TARGET_POT: i32 = 117;
/// Largest standard deviation at rest, counts: current sense and pot (the sensors' spec,
/// docs/calibration.md).
const MAX_CURRENT_SIGMA: i64 = 6;
const MAX_POT_SIGMA: i64 = 2;
/// Pot readings within this many counts of an end are at a rail.
const POT_RAIL: u16 = 2;
/// Noise margin of the pot error table: standard deviations of the pot at rest.
const TABLE_SIGMAS: i64 = 3;
/// Smallest noise margin of the pot error table, counts × 100 (half a count).
const TABLE_MIN_MARGIN_CENTI: i64 = 50;

/// Why calibration stopped (the motor is off). [`Failure::message`] says what to check.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum Failure {
    /// The current sense reads at a rail with the motor off.
    CurrentRail,
    /// The current sense is noisier than its spec with the motor off.
    CurrentNoisy,
    /// The current sense did not change while the motor was driven and turned.
    CurrentDead,
    /// The pot reads at a rail.
    PotRail,
    /// The pot is noisier than its spec.
    PotNoisy,
    /// The pot did not move while the link encoder did.
    PotDead,
    /// The link encoder did not move while the pot did.
    EncoderDead,
    /// Neither sensor moved and the motor drew no current.
    MotorOpen,
    /// Neither sensor moved while the motor drew the bounded current.
    MotorBlocked,
    /// The current exceeded the calibration's bound.
    OverCurrent,
    /// The link encoder jumped.
    EncoderJump,
    /// A move did not reach its target in time.
    Timeout,
    /// A driver returned an error.
    SensorRead,
    /// The measurements do not give a plausible motor (R or k_e out of range).
    Implausible,
    /// Stopped by the host.
    Aborted,
    /// The supervisor latched a fault (it stays armed throughout).
    Fault,
}

impl Failure {
    /// Short name (`encoder-dead`, …), as in `vsa calibrate --json`'s `status`.
    #[must_use]
    pub const fn name(self) -> &'static str {
        match self {
            Failure::CurrentRail => "current-rail",
            Failure::CurrentNoisy => "current-noisy",
            Failure::CurrentDead => "current-dead",
            Failure::PotRail => "pot-rail",
            Failure::PotNoisy => "pot-noisy",
            Failure::PotDead => "pot-dead",
            Failure::EncoderDead => "encoder-dead",
            Failure::MotorOpen => "motor-open",
            Failure::MotorBlocked => "motor-blocked",
            Failure::OverCurrent => "over-current",
            Failure::EncoderJump => "encoder-jump",
            Failure::Timeout => "timeout",
            Failure::SensorRead => "sensor-read",
            Failure::Implausible => "implausible",
            Failure::Aborted => "aborted",
            Failure::Fault => "fault",
        }
    }

    /// Every failure, in code order ([`Failure::code`] is the index + 1).
    pub const ALL: [Failure; 16] = [
        Failure::CurrentRail,
        Failure::CurrentNoisy,
        Failure::CurrentDead,
        Failure::PotRail,
        Failure::PotNoisy,
        Failure::PotDead,
        Failure::EncoderDead,
        Failure::MotorOpen,
        Failure::MotorBlocked,
        Failure::OverCurrent,
        Failure::EncoderJump,
        Failure::Timeout,
        Failure::SensorRead,
        Failure::Implausible,
        Failure::Aborted,
        Failure::Fault,
    ];

    /// The failure's number on the wire (1-based; 0 is none).
    #[must_use]
    pub const fn code(self) -> u8 {
        let mut i = 0;
        while i < Failure::ALL.len() {
            if Failure::ALL[i] as u8 == self as u8 {
                return i as u8 + 1;
            }
            i += 1;
        }
        0
    }

    /// The failure with wire number `code`, if any.
    #[must_use]
    pub const fn from_code(code: u8) -> Option<Failure> {
        if code == 0 || code as usize > Failure::ALL.len() {
            None
        } else {
            Some(Failure::ALL[code as usize - 1])
        }
    }

    /// What to check, one line.
    #[must_use]
    pub const fn message(self) -> &'static str {
        match self {
            Failure::CurrentRail => "the current sense reads at a rail with the motor off: check its supply, ground and output wire",
            Failure::CurrentNoisy => "the current sense is noisy with the motor off: check its ground and the ADC input's filter",
            Failure::CurrentDead => "the current sense did not change while the motor turned: check its output wire and that the motor current flows through it",
            Failure::PotRail => "the gear pot reads at a rail: check its 3V3/AGND supply and wiper wire",
            Failure::PotNoisy => "the gear pot is noisy at rest: feed it from the board's 3V3/AGND, not the servo's 5 V rail",
            Failure::PotDead => "the gear pot did not move while the link turned: check its wiper wire",
            Failure::EncoderDead => "the link encoder did not move while the gear moved: check its cable and supply",
            Failure::MotorOpen => "the motor did not move and drew no current: check its leads, the bridge's enable and supply",
            Failure::MotorBlocked => "the motor drew current but nothing moved: check that the gear and the link turn freely",
            Failure::OverCurrent => "the motor current exceeded the calibration's bound: check the motor and the supply voltage",
            Failure::EncoderJump => "the link encoder jumped: check its cable and the input filter",
            Failure::Timeout => "a move did not reach its target: check that the link turns freely over ±0.6 rad",
            Failure::SensorRead => "a sensor driver failed: check the wiring of the sensor named in the log",
            Failure::Implausible => "the motor's resistance or back-EMF came out implausible: check the supply voltage setting and the motor",
            Failure::Aborted => "stopped by the host",
            Failure::Fault => "the supervisor latched a fault (see vsa status): clear it and check what it names",
        }
    }
}

/// What the sequence needs to know beforehand (configuration; [`CalibrationConfig::new`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CalibrationConfig {
    /// Bridge supply, V (I32F32).
    pub supply_v: I32F32,
    /// Datasheet torque constant at the output, N·m/A (I32F32).
    pub torque_constant: I32F32,
    /// Datasheet rotor + gear inertia at the output, kg·m² × 10⁹ (g·mm² — integer).
    pub gear_inertia_nano: i64,
    /// Datasheet gear viscous friction, N·m·s/rad (I32F32).
    pub viscous: I32F32,
    /// The link encoder's direction (the reference of the signs).
    pub encoder_direction: Sign,
    /// Link encoder counts per turn.
    pub encoder_counts_per_turn: u16,
    /// Largest |motor current| allowed, ADC counts from the offset: the safe torque bound.
    pub current_bound_counts: i32,
    /// Duty of the moves, ‰.
    pub move_duty: i16,
    /// ADC rails (the supervisor's window).
    pub adc_min: u16,
    /// Highest valid ADC reading.
    pub adc_max: u16,
    /// The supervisor's fixed pot tolerance, counts: the pot error table's entry for a bin
    /// the moves did not visit is at least this (module docs). Default: the supervisor's
    /// default.
    pub pot_tolerance_counts: u16,
}

impl CalibrationConfig {
    /// For `design` and the datasheet motor `motor`: the torque bound is half the beams'
    /// capacity at the longest clutch length (the weakest setting; half for the dynamic
    /// overshoot of a torque step on a spring), so it holds whatever the clutch is set to.
    ///
    /// # Errors
    /// The longest setting cannot be built.
    pub fn new(
        design: &Design,
        motor: &MotorParams,
        encoder_direction: Sign,
        encoder_counts_per_turn: u16,
    ) -> crate::Result<CalibrationConfig> {
        let (_, longest) = design.adjustable_range();
        let cap = Setting::new(design, longest, BeamModel::EulerBernoulli)?.torque_capacity();
        let bound = safe_torque(cap);
        // Current for that torque at the datasheet k_t, ADC counts.
        let kt = motor.torque_constant.to_bits().max(1);
        let amps_q32 = (i128::from(bound.to_bits()) << 32) / i128::from(kt);
        let counts = (amps_q32 * i128::from(ADC_COUNTS_PER_A)) >> 32;
        let current_bound_counts = counts.clamp(1, 2000) as i32;
        // Duty whose stall current is 75 % of the bound at the datasheet R, at most
        // 250 ‰: R 15 % low read through a sense 10 % high is 1.29 × that current, still
        // below the bound (at 80 % it was 1.035 × the bound: `over-current` on a healthy
        // build).
        let r = i128::from(motor.resistance_ohm.to_bits());
        let v = i128::from(motor.supply_v.to_bits()).max(1);
        let duty = (counts * 3 / 4 * r * 1000 / i128::from(ADC_COUNTS_PER_A)) / v;
        Ok(CalibrationConfig {
            supply_v: motor.supply_v,
            torque_constant: motor.torque_constant,
            gear_inertia_nano: (motor.rotor_inertia.to_bits() * 1000) >> 32,
            viscous: motor.viscous,
            encoder_direction,
            encoder_counts_per_turn,
            current_bound_counts,
            move_duty: duty.clamp(50, 250) as i16,
            adc_min: 16,
            adc_max: 4079,
            pot_tolerance_counts: SupervisorConfig::DEFAULT.pot_tolerance_counts,
        })
    }
}

/// Half the capacity `cap` (module docs).
fn safe_torque(cap: Torque) -> Torque {
    Torque::from_bits(cap.to_bits() / 2)
}

/// The result of a successful calibration.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CalibrationResult {
    /// The correction to install.
    pub correction: SensorCorrection,
    /// Armature resistance as the current sense sees it, mΩ.
    pub resistance_mohm: i32,
    /// Back-EMF constant at the output, mV·s/rad.
    pub back_emf_mv_s_per_rad: i32,
    /// The same, µV·s/rad.
    pub back_emf_uv_s_per_rad: i32,
    /// Gear Coulomb friction at the datasheet k_t, µN·m.
    pub gear_friction_unm: i32,
    /// Link inertia, kg·m² × 10⁹ (total from the transients minus the datasheet gear's).
    pub link_inertia_nano: i64,
    /// RMS of the pot about the line fitted to the encoder over the moves, pot counts
    /// ×100 (the pot's non-linearity and noise).
    pub pot_error_centi: i32,
    /// The pot's error bound per bin of its track (module docs): the supervisor's
    /// deflection check is sized from it.
    pub pot_error: PotErrorTable,
    /// Pot counts between the two sides of the free play (moving − and +), ×100.
    pub free_play_pot_centi: i32,
    /// Standard deviation of the current at rest, ADC counts ×100.
    pub current_noise_centi: i32,
    /// The bridge supply the resistance and back-EMF are read in, V (the run's
    /// [`CalibrationConfig::supply_v`]).
    pub supply_v: I32F32,
}

/// Progress, for the status and the progress bar.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Progress {
    /// Running: phase number (1..=PHASES) and percent done.
    Running {
        /// Phase, 1-based.
        phase: u8,
        /// Percent of the whole sequence, 0..=99.
        percent: u8,
    },
    /// Done: the result is in [`Calibration::result`].
    Done,
    /// Stopped with the motor off.
    Failed(Failure),
}

/// Per-move sums.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct Move {
    /// Direction of the move in the canonical frame, ±1.
    dir: i32,
    /// Ticks since the start.
    k: u32,
    /// Current (counts from the offset, canonical sign) at ticks 1, 2 and 3.
    i1: i64,
    i2: i64,
    i3: i64,
    /// Σ current since the start (cumulative charge, counts·ms).
    cum_i: i64,
    /// Over the steady part: Σ of the cumulative charge, of the driven ticks and of the
    /// encoder since the start (the momentum balance averaged over the link's ringing).
    sum_cum: i64,
    sum_t: i64,
    sum_enc: i64,
    /// Steady part: ticks, Σ current, canonical encoder at its start.
    n_ss: i64,
    sum_i_ss: i64,
    enc_ss0: i64,
    /// Pot vs encoder sums (x: raw encoder turned, y: raw pot).
    sx: i64,
    sy: i64,
    sxx: i64,
    sxy: i64,
    syy: i64,
    /// Canonical encoder at the start and at the last steady tick.
    enc0: i64,
    enc_last: i64,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Phase {
    Rest { left: u32 },
    Nudge { duty: i32 },
    Pause { left: u32, next: u8 },
    Moving { index: u8 },
    Finished,
}

/// The pot against the encoder as fitted over the first − and + moves' steady parts: raw
/// pot ≈ `slope`·(raw encoder turned) + the intercept of the move's direction.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct PotLine {
    /// Raw pot counts per raw encoder count, Q32.
    slope_q32: i64,
    /// Raw pot counts at encoder 0, Q32, moving + and moving −.
    plus_q32: i64,
    minus_q32: i64,
    /// Canonical pot counts per raw pot count (1/gain), Q16.
    inv_gain_q16: i64,
    /// The canonical pot reading of a raw one (the correction with the fitted gain).
    corrector: Corrector,
}

/// The pooled pot-vs-encoder sums over `moves`' steady parts, each move centred on its
/// own means (the free play shifts the intercepts): (Σxx, Σxy, Σyy, Σn²), all ×n.
fn pooled(moves: &[Move]) -> (i128, i128, i128, i128) {
    let (mut sxx, mut sxy, mut syy, mut nsq) = (0i128, 0, 0, 0);
    for m in moves.iter().filter(|m| m.n_ss >= i64::from(MIN_STEADY)) {
        let nn = i128::from(m.n_ss);
        let (mx, my) = (i128::from(m.sx), i128::from(m.sy));
        sxx += i128::from(m.sxx) * nn - mx * mx;
        sxy += i128::from(m.sxy) * nn - mx * my;
        syy += i128::from(m.syy) * nn - my * my;
        nsq += nn * nn;
    }
    (sxx, sxy, syy, nsq)
}

/// The nominal pot slope, (1024/300°)/(cpt/360°) raw pot counts per raw encoder count,
/// Q32, for an encoder of `cpt` counts per turn (at least 1).
fn nominal_slope_q32(cpt: u16) -> i128 {
    (((i128::from(POT_COUNTS) * 360) << 32) / (i128::from(POT_SPAN_DEG) * i128::from(cpt))).max(1)
}

/// Raw pot counts at encoder 0 of move `m` at slope `slope_q32`, Q32.
fn intercept_q32(m: &Move, slope_q32: i128) -> i128 {
    let nn = i128::from(m.n_ss).max(1);
    ((i128::from(m.sy) << 32) - slope_q32 * i128::from(m.sx)) / nn
}

/// Phases reported in [`Progress::Running`].
pub const PHASES: u8 = 5;

/// The calibration sequence (module docs).
#[derive(Clone, Debug)]
pub struct Calibration {
    cfg: CalibrationConfig,
    phase: Phase,
    progress: Progress,
    ticks: u32,
    // Rest statistics.
    n_rest: i64,
    sum_adc: i64,
    sum_adc2: i64,
    sum_pot: i64,
    sum_pot2: i64,
    offset_q16: i64,
    pot_rest: i64,
    // Encoder unwrapping (raw counts turned).
    enc_prev: Option<u16>,
    enc_turned: i64,
    enc_nudge0: i64,
    // Found signs (canonical = sign × raw motion).
    motor: Sign,
    pot_dir: Sign,
    moves: [Move; MOVES],
    /// The provisional pot line (after the first − and + moves) and, per bin of the
    /// canonical pot track, the largest |pot − line| seen since, canonical counts × 100
    /// (`visited`: bit b set once bin b saw a sample).
    line: Option<PotLine>,
    pot_err_centi: [u16; POT_ERROR_BINS],
    visited: u16,
    result: Option<CalibrationResult>,
}

impl Calibration {
    /// A sequence about to start (motor off).
    #[must_use]
    pub fn new(cfg: &CalibrationConfig) -> Calibration {
        Calibration {
            cfg: *cfg,
            phase: Phase::Rest { left: REST_TICKS },
            progress: Progress::Running {
                phase: 1,
                percent: 0,
            },
            ticks: 0,
            n_rest: 0,
            sum_adc: 0,
            sum_adc2: 0,
            sum_pot: 0,
            sum_pot2: 0,
            offset_q16: 0,
            pot_rest: 0,
            enc_prev: None,
            enc_turned: 0,
            enc_nudge0: 0,
            motor: Sign::Plus,
            pot_dir: Sign::Plus,
            moves: [Move::default(); MOVES],
            line: None,
            pot_err_centi: [0; POT_ERROR_BINS],
            visited: 0,
            result: None,
        }
    }

    /// Progress after the last step.
    #[must_use]
    pub const fn progress(&self) -> Progress {
        self.progress
    }

    /// The result, once [`Progress::Done`].
    #[must_use]
    pub const fn result(&self) -> Option<&CalibrationResult> {
        self.result.as_ref()
    }

    /// Stops now (the next step returns the motor off).
    pub fn abort(&mut self) {
        self.fail(Failure::Aborted);
    }

    /// Stops now for `why` (e.g. [`Failure::Fault`]: the supervisor latched one); the next
    /// step returns the motor off.
    pub fn stop(&mut self, why: Failure) {
        if self.phase != Phase::Finished {
            self.fail(why);
        }
    }

    fn fail(&mut self, f: Failure) -> Option<i16> {
        self.phase = Phase::Finished;
        self.progress = Progress::Failed(f);
        None
    }

    /// Current from the offset, ADC counts, canonical sign (after the motor polarity).
    fn current(&self, adc: u16) -> i64 {
        (((i64::from(adc) << 16) - self.offset_q16) >> 16) * i64::from(self.motor.value())
    }

    /// Encoder counts turned, canonical (direction applied, raw counts per turn).
    fn enc_canonical(&self) -> i64 {
        self.enc_turned * i64::from(self.cfg.encoder_direction.value())
    }

    /// Pot from its rest mean, canonical direction, counts.
    fn pot_canonical(&self, pot: u16) -> i64 {
        (i64::from(pot) - self.pot_rest) * i64::from(self.pot_dir.value())
    }

    /// One control tick: this tick's raw readings in, the bridge duty (‰, raw: polarity
    /// not corrected) out; `None`: motor off.
    pub fn step(&mut self, raw: &TickInput) -> Option<i16> {
        if self.phase == Phase::Finished {
            return None;
        }
        self.ticks = self.ticks.saturating_add(1);
        if raw.read_error.is_some() {
            return self.fail(Failure::SensorRead);
        }
        let Some(pot) = raw.gear_pot else {
            return self.fail(Failure::PotDead);
        };
        // Encoder: unwrap at its counts per turn; a jump beyond 60 rad/s is a fault.
        let cpt = self.cfg.encoder_counts_per_turn;
        if let Some(prev) = self.enc_prev {
            let d = i64::from(wrapped_delta(raw.link_encoder, prev, cpt));
            if d.abs() > i64::from(cpt / 100 + 1) {
                return self.fail(Failure::EncoderJump);
            }
            self.enc_turned += d;
        }
        self.enc_prev = Some(raw.link_encoder % cpt);
        let in_rails = (self.cfg.adc_min..=self.cfg.adc_max).contains(&raw.current_adc);
        match self.phase {
            Phase::Rest { left } => self.rest(left, raw.current_adc, pot, in_rails),
            Phase::Nudge { duty } => self.nudge(duty, raw.current_adc, pot, in_rails),
            Phase::Pause { left, next } => {
                if !in_rails {
                    return self.fail(Failure::CurrentRail);
                }
                if left > 1 {
                    self.phase = Phase::Pause {
                        left: left - 1,
                        next,
                    };
                } else if next as usize >= self.moves.len() {
                    return self.finish();
                } else {
                    if self.line.is_none() {
                        self.line = self.fit_line(usize::from(next));
                    }
                    self.start_move(next, pot);
                }
                Some(0)
            }
            Phase::Moving { index } => self.moving(index, raw.current_adc, pot, in_rails),
            Phase::Finished => None,
        }
    }

    fn rest(&mut self, left: u32, adc: u16, pot: u16, in_rails: bool) -> Option<i16> {
        if !in_rails {
            return self.fail(Failure::CurrentRail);
        }
        if pot <= POT_RAIL || pot >= POT_COUNTS - 1 - POT_RAIL {
            return self.fail(Failure::PotRail);
        }
        let (a, p) = (i64::from(adc), i64::from(pot));
        self.n_rest += 1;
        self.sum_adc += a;
        self.sum_adc2 += a * a;
        self.sum_pot += p;
        self.sum_pot2 += p * p;
        self.progress = Progress::Running {
            phase: 1,
            percent: (10 * (REST_TICKS - left + 1) / REST_TICKS) as u8,
        };
        if left > 1 {
            self.phase = Phase::Rest { left: left - 1 };
            return None;
        }
        let n = self.n_rest;
        // Variances ×n² (integers); σ > limit ⇔ n·Σx² − (Σx)² > limit²·n².
        let var_adc = n * self.sum_adc2 - self.sum_adc * self.sum_adc;
        let var_pot = n * self.sum_pot2 - self.sum_pot * self.sum_pot;
        if var_adc > MAX_CURRENT_SIGMA * MAX_CURRENT_SIGMA * n * n {
            return self.fail(Failure::CurrentNoisy);
        }
        if var_pot > MAX_POT_SIGMA * MAX_POT_SIGMA * n * n {
            return self.fail(Failure::PotNoisy);
        }
        self.offset_q16 = ((self.sum_adc << 16) + n / 2) / n;
        self.pot_rest = (self.sum_pot + n / 2) / n;
        self.enc_nudge0 = self.enc_turned;
        self.phase = Phase::Nudge { duty: 0 };
        None
    }

    fn nudge(&mut self, duty: i32, adc: u16, pot: u16, in_rails: bool) -> Option<i16> {
        if !in_rails {
            return self.fail(Failure::CurrentRail);
        }
        let i = ((i64::from(adc) << 16) - self.offset_q16) >> 16;
        let dpot = i64::from(pot) - self.pot_rest;
        let denc = self.enc_turned - self.enc_nudge0;
        self.progress = Progress::Running {
            phase: 2,
            percent: 10 + (10 * duty / NUDGE_MAX_DUTY) as u8,
        };
        let pot_moved = dpot.abs() >= i64::from(NUDGE_POT);
        let enc_moved = denc.abs() >= i64::from(NUDGE_ENC);
        if pot_moved && denc.abs() < i64::from(STILL_ENC) {
            return self.fail(Failure::EncoderDead);
        }
        if enc_moved && dpot.abs() < i64::from(STILL_POT) {
            return self.fail(Failure::PotDead);
        }
        if pot_moved && enc_moved {
            // The nudge drove positive duty: the link's canonical motion gives the motor's
            // polarity, the pot's raw motion against it the pot's direction.
            let link = denc * i64::from(self.cfg.encoder_direction.value());
            self.motor = Sign::of(link);
            self.pot_dir = Sign::of(dpot * link.signum());
            self.phase = Phase::Pause {
                left: PAUSE_TICKS,
                next: 0,
            };
            return Some(0);
        }
        if i.abs() > i64::from(self.cfg.current_bound_counts) {
            return self.fail(
                if denc.abs() < i64::from(STILL_ENC) && dpot.abs() < i64::from(STILL_POT) {
                    Failure::MotorBlocked
                } else {
                    Failure::OverCurrent
                },
            );
        }
        if duty >= NUDGE_MAX_DUTY {
            return self.fail(if i.abs() < 8 {
                Failure::MotorOpen
            } else {
                Failure::MotorBlocked
            });
        }
        let next = duty + 1;
        self.phase = Phase::Nudge { duty: next };
        Some(next as i16)
    }

    /// Targets of the moves in canonical pot counts from the rest mean: −, +, middle. The
    /// rest mean is where the gear was at power-up, anywhere: the targets are taken from
    /// the pot's electrical centre, corrected for direction.
    fn target(&self, index: u8) -> i64 {
        let centre = (i64::from(POT_COUNTS / 2) - self.pot_rest) * i64::from(self.pot_dir.value());
        centre
            + if usize::from(index) + 1 == MOVES {
                0
            } else if index.is_multiple_of(2) {
                -i64::from(TARGET_POT)
            } else {
                i64::from(TARGET_POT)
            }
    }

    fn start_move(&mut self, index: u8, pot: u16) {
        let dir = if self.target(index) > self.pot_canonical(pot) {
            1
        } else {
            -1
        };
        self.moves[usize::from(index)] = Move {
            dir,
            ..Move::default()
        };
        self.phase = Phase::Moving { index };
    }

    fn moving(&mut self, index: u8, adc: u16, pot: u16, in_rails: bool) -> Option<i16> {
        if !in_rails {
            return self.fail(Failure::CurrentRail);
        }
        let i = self.current(adc);
        if i.abs() > i64::from(self.cfg.current_bound_counts) {
            return self.fail(Failure::OverCurrent);
        }
        let enc = self.enc_canonical();
        let turned = self.enc_turned;
        let target = self.target(index);
        let here = self.pot_canonical(pot);
        let m = &mut self.moves[usize::from(index)];
        m.k += 1;
        let k = m.k;
        // The current this tick answers the duty applied during the tick before (k − 1).
        if k == 1 {
            m.enc0 = enc;
        } else if k == 2 {
            m.i1 = i;
        } else if k == 3 {
            m.i2 = i;
        } else if k == 4 {
            m.i3 = i;
        }
        if k >= 2 {
            m.cum_i += i;
        }
        if k == STEADY_FROM {
            m.enc_ss0 = enc;
        }
        if k > STEADY_FROM {
            m.n_ss += 1;
            m.sum_i_ss += i;
            let (x, y) = (turned, i64::from(pot));
            m.sx += x;
            m.sy += y;
            m.sxx += x * x;
            m.sxy += x * y;
            m.syy += y * y;
            m.enc_last = enc;
            m.sum_cum += m.cum_i;
            m.sum_t += i64::from(k - 1);
            m.sum_enc += enc - m.enc0;
        }
        let (dir, i1) = (m.dir, m.i1);
        if k > STEADY_FROM {
            self.note_pot_error(turned, pot, dir);
        }
        self.progress = Progress::Running {
            phase: if usize::from(index) + 1 == MOVES {
                4
            } else {
                3
            },
            percent: (20 + (75 * u32::from(index) + k.min(800) * 75 / 800) / MOVES as u32) as u8,
        };
        let reached = if dir > 0 {
            here >= target
        } else {
            here <= target
        };
        if reached {
            self.phase = Phase::Pause {
                left: PAUSE_TICKS,
                next: index + 1,
            };
            return Some(0);
        }
        if k > MOVE_TIMEOUT {
            return self.fail(Failure::Timeout);
        }
        if k == 3 && i1.abs() < 16 {
            // The first driven tick's current is V/R, hundreds of counts.
            return self.fail(Failure::CurrentDead);
        }
        let duty = i64::from(self.cfg.move_duty) * i64::from(dir) * i64::from(self.motor.value());
        Some(duty as i16)
    }

    /// The provisional pot line from the steady parts of the first `done` moves, once
    /// they hold a − and a + move (module docs).
    fn fit_line(&self, done: usize) -> Option<PotLine> {
        let moves = &self.moves[..done];
        let steady = |d: i32| {
            moves
                .iter()
                .find(|m| m.dir == d && m.n_ss >= i64::from(MIN_STEADY))
        };
        let (plus, minus) = (steady(1)?, steady(-1)?);
        let (sxx, sxy, _, _) = pooled(moves);
        if sxx <= 0 || sxy == 0 {
            return None;
        }
        let slope_q32 = (sxy << 32) / sxx;
        let gain_q16 = ((slope_q32.abs() << 16)
            / nominal_slope_q32(self.cfg.encoder_counts_per_turn))
        .clamp(1 << 15, 1 << 17);
        let correction = SensorCorrection {
            pot_direction: Sign::of(
                (slope_q32 * i128::from(self.cfg.encoder_direction.value())) as i64,
            ),
            pot_gain_q16: gain_q16 as i32,
            ..SensorCorrection::NOMINAL
        };
        Some(PotLine {
            slope_q32: slope_q32 as i64,
            plus_q32: intercept_q32(plus, slope_q32) as i64,
            minus_q32: intercept_q32(minus, slope_q32) as i64,
            inv_gain_q16: (1i64 << 32) / gain_q16 as i64,
            corrector: Corrector::new(&correction).ok()?,
        })
    }

    /// One steady sample of a move in direction `dir` (raw encoder turned `x`, raw pot
    /// `pot`) against the provisional line, into the table's bin of the reading.
    fn note_pot_error(&mut self, x: i64, pot: u16, dir: i32) {
        let Some(line) = &self.line else {
            return;
        };
        let b = if dir > 0 {
            line.plus_q32
        } else {
            line.minus_q32
        };
        let predicted = i128::from(line.slope_q32) * i128::from(x) + i128::from(b);
        let off_q32 = ((i128::from(pot) << 32) - predicted).abs();
        // Canonical counts × 100: raw counts / gain.
        let centi = (off_q32 * i128::from(line.inv_gain_q16) * 100) >> 48;
        let canonical = (line.corrector.pot_q16(pot) >> 16).clamp(0, i64::from(POT_COUNTS) - 1);
        let bin = PotErrorTable::bin(canonical as u16);
        let e = centi.min(i128::from(u16::MAX)) as u16;
        self.pot_err_centi[bin] = self.pot_err_centi[bin].max(e);
        self.visited |= 1 << bin;
    }

    /// The pot error table from the bounds seen (module docs); `pot_sigma_centi` is the
    /// pot's standard deviation at rest, counts × 100.
    fn pot_error_table(&self, pot_sigma_centi: i64) -> PotErrorTable {
        let margin = (TABLE_SIGMAS * pot_sigma_centi).max(TABLE_MIN_MARGIN_CENTI);
        let cap = i64::from(MAX_ERROR_CENTI);
        let mut t = PotErrorTable::default();
        let mut worst = 0;
        for (b, e) in self.pot_err_centi.iter().enumerate() {
            if self.visited & (1 << b) != 0 {
                t.centi[b] = (i64::from(*e) + margin).min(cap) as u16;
                worst = worst.max(t.centi[b]);
            }
        }
        let fixed = (i64::from(self.cfg.pot_tolerance_counts) * 100).min(cap) as u16;
        for (b, e) in t.centi.iter_mut().enumerate() {
            if self.visited & (1 << b) == 0 {
                *e = worst.max(fixed);
            }
        }
        t
    }

    /// The final tick: the estimates from the sums (the only divisions).
    fn finish(&mut self) -> Option<i16> {
        const PER_A: i128 = ADC_COUNTS_PER_A as i128;
        let kt_q32 = i128::from(self.cfg.torque_constant.to_bits());
        let b_q32 = i128::from(self.cfg.viscous.to_bits());
        // Move voltage, mV.
        let v_mv = ((i128::from(self.cfg.supply_v.to_bits()) * 1000) >> 32)
            * i128::from(self.cfg.move_duty)
            / 1000;
        // nrad per raw encoder count.
        let nrad = 6_283_185_307i128 / i128::from(self.cfg.encoder_counts_per_turn);
        // R from the moves' starts: the current extrapolated to t = 0 (ω = 0 there, no
        // back-EMF): R [mΩ] = V[mV]·1024/counts. The extrapolation assumes the gear
        // crossing the free play alone, its back-EMF rising linearly, so the current
        // falls over the first three ticks; only such moves count (all if none).
        // A gear that starts against the link (a heavy link thrown back on stiff beams)
        // slows at once: R came out up to 7 % high. That error is one-sided, so the
        // highest of the moves' R are left out: the two highest of five or more, the
        // highest of three or four. A move that reached its target within two ticks has
        // no start currents (not a dead sense).
        let started = |m: &&Move| m.k >= 3;
        let free = |m: &&Move| m.k >= 4 && m.i2.abs() < m.i1.abs() && m.i3.abs() < m.i2.abs();
        let any_free = self.moves.iter().any(|m| free(&m));
        let (mut r_sum, mut r_n) = (0i128, 0i128);
        let (mut r_top, mut r_second) = (0i128, 0i128);
        for m in self
            .moves
            .iter()
            .filter(|m| if any_free { free(m) } else { started(m) })
        {
            let i0 = 2 * i128::from(m.i1) - i128::from(m.i2);
            if i0.abs() < 16 {
                return self.fail(Failure::CurrentDead);
            }
            let r = v_mv * PER_A * 1000 / i0.abs();
            if r > r_top {
                (r_top, r_second) = (r, r_top);
            } else if r > r_second {
                r_second = r;
            }
            r_sum += r;
            r_n += 1;
        }
        if r_n == 0 {
            return self.fail(Failure::CurrentDead);
        }
        if r_n >= 5 {
            (r_sum, r_n) = (r_sum - r_top - r_second, r_n - 2);
        } else if r_n >= 3 {
            (r_sum, r_n) = (r_sum - r_top, r_n - 1);
        }
        let r_mohm = r_sum / 1000 / r_n;
        let (mut ke_sum, mut j_sum, mut n_used) = (0i128, 0i128, 0i128);
        let (mut i_plus, mut i_minus, mut w_plus, mut w_minus) = (0i128, 0i128, 0i128, 0i128);
        for m in &self.moves {
            if m.n_ss < i64::from(MIN_STEADY) {
                continue;
            }
            let n = i128::from(m.n_ss);
            let dir = i128::from(m.dir);
            let i_ss = i128::from(m.sum_i_ss) * 1_000_000 / n; // counts ×10⁶
            let d_enc = i128::from(m.enc_last - m.enc_ss0);
            let w_urad = d_enc * nrad / n; // µrad/s
            if w_urad * dir <= 0 {
                return self.fail(Failure::Timeout);
            }
            // k_e [µV·s/rad] = (V − R·i)/ω.
            let ri_uv = r_mohm * i_ss / PER_A / 1000;
            ke_sum += (dir * v_mv * 1000 - ri_uv) * 1_000_000 / w_urad;
            // Momentum at the steady speed, pN·m·s, averaged over the steady part (the
            // link rings on the beams): k_t·∫(i − i_ss)dt (trapezoid from the
            // extrapolated i(0)) plus the viscous torque's share b·∫(ω_ss − ω)dt (the
            // position the move lost to its start, from the encoder).
            let i0 = 2 * i128::from(m.i1) - i128::from(m.i2);
            let mean_cum = i128::from(m.sum_cum) * 1_000_000 / n; // counts·ms ×10⁶
            let mean_t_milli = i128::from(m.sum_t) * 1000 / n; // ms ×10³
            let excess = mean_cum + i0 * 500_000 - i_ss * mean_t_milli / 1000;
            let p_i = (kt_q32 * excess * 1000 / PER_A) >> 32;
            let lost_milli = d_enc * mean_t_milli / n - i128::from(m.sum_enc) * 1000 / n; // counts ×10³
            let p_b = (b_q32 * lost_milli * nrad / 1000) >> 32;
            j_sum += (p_i + p_b) * 1000 / w_urad; // kg·m² ×10⁹
            n_used += 1;
            if m.dir > 0 {
                (i_plus, w_plus) = (i_ss, w_urad);
            } else {
                (i_minus, w_minus) = (i_ss, w_urad);
            }
        }
        if n_used == 0 || i_plus == 0 || i_minus == 0 {
            return self.fail(Failure::Timeout);
        }
        let ke_uv = ke_sum / n_used;
        if !(100..=1_000_000).contains(&r_mohm) || !(10_000..=100_000_000).contains(&ke_uv) {
            return self.fail(Failure::Implausible);
        }
        // Coulomb friction: half the difference of the steady torques, minus viscous.
        let tau_unm = (kt_q32 * (i_plus - i_minus) / 2 / PER_A) >> 32;
        let visc_unm = (b_q32 * (w_plus - w_minus) / 2) >> 32;
        let j_link = j_sum / n_used - i128::from(self.cfg.gear_inertia_nano);
        // Pot against the encoder over the moves' steady parts (pooled slope).
        let (sxx, sxy, syy, nsq) = pooled(&self.moves);
        if sxx <= 0 {
            return self.fail(Failure::PotDead);
        }
        let slope_q32 = (sxy << 32) / sxx; // raw pot counts per raw encoder count
        let gain_q16 =
            (slope_q32.abs() << 16) / nominal_slope_q32(self.cfg.encoder_counts_per_turn);
        let pot_dir = Sign::of((slope_q32 * i128::from(self.cfg.encoder_direction.value())) as i64);
        // Residual variance of the pot about the fitted lines, ×10⁴ counts².
        let resid = (syy - ((slope_q32 * sxy) >> 32)).max(0) * 10_000 / nsq.max(1);
        // Free play: the + and − moves' intercepts at the pooled slope, canonical.
        let intercept = |m: &Move| intercept_q32(m, slope_q32) * 100;
        let by_dir = |d: i32| {
            self.moves
                .iter()
                .find(|m| m.dir == d && m.n_ss >= i64::from(MIN_STEADY))
        };
        let fp = match (by_dir(1), by_dir(-1)) {
            (Some(p), Some(q)) => {
                ((intercept(p) - intercept(q)) >> 32) * i128::from(pot_dir.value())
            }
            _ => 0,
        };
        let nr = i128::from(self.n_rest).max(1);
        let sa = i128::from(self.sum_adc);
        let var = (nr * i128::from(self.sum_adc2) - sa * sa) * 10_000 / (nr * nr);
        let sp = i128::from(self.sum_pot);
        let var_pot = (nr * i128::from(self.sum_pot2) - sp * sp) * 10_000 / (nr * nr);
        let pot_sigma = crate::fixmath::isqrt_round(var_pot.max(0) as u128);
        let pot_error = self.pot_error_table(i64::try_from(pot_sigma).unwrap_or(i64::MAX));
        let correction = SensorCorrection {
            motor_polarity: self.motor,
            encoder_direction: self.cfg.encoder_direction,
            encoder_counts_per_turn: self.cfg.encoder_counts_per_turn,
            pot_direction: pot_dir,
            // The centre stays the pot's electrical one: it defines the absolute zero.
            pot_center_q16: i32::from(POT_COUNTS / 2) << 16,
            pot_gain_q16: gain_q16.clamp(1 << 15, 1 << 17) as i32,
            current_offset_q16: self.offset_q16 as i32,
            current_gain_q16: 1 << 16,
            adc_min: self.cfg.adc_min,
            adc_max: self.cfg.adc_max,
        };
        let clamp32 = |v: i128| v.clamp(i128::from(i32::MIN), i128::from(i32::MAX)) as i32;
        self.result = Some(CalibrationResult {
            correction,
            resistance_mohm: clamp32(r_mohm),
            back_emf_mv_s_per_rad: clamp32(ke_uv / 1000),
            back_emf_uv_s_per_rad: clamp32(ke_uv),
            gear_friction_unm: clamp32(tau_unm - visc_unm),
            link_inertia_nano: j_link.clamp(i128::from(i64::MIN), i128::from(i64::MAX)) as i64,
            pot_error_centi: crate::fixmath::isqrt_round(resid as u128) as i32,
            pot_error,
            free_play_pot_centi: clamp32(fp),
            current_noise_centi: crate::fixmath::isqrt_round(var.max(0) as u128) as i32,
            supply_v: self.cfg.supply_v,
        });
        self.phase = Phase::Finished;
        self.progress = Progress::Done;
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::control::MotorParams;

    #[test]
    fn unvisited_bins_get_the_worst_visited_entry_or_the_fixed_tolerance() {
        let cfg = CalibrationConfig::new(&Design::paper(), &MotorParams::AX12A, Sign::Plus, 4096)
            .unwrap();
        let mut c = Calibration::new(&cfg);
        c.pot_err_centi[6] = 180;
        c.pot_err_centi[7] = 420;
        c.visited = (1 << 6) | (1 << 7);
        // σ = 0.4 count: margin 3σ = 120 centi.
        let t = c.pot_error_table(40);
        assert_eq!((t.centi[6], t.centi[7]), (300, 540));
        assert!(t.centi.iter().enumerate().all(|(b, &e)| b == 6 || e == 540));
        // A quiet pot: the margin's floor, and the fixed 3 counts where nothing was seen.
        c.pot_err_centi[7] = 100;
        let t = c.pot_error_table(0);
        assert_eq!((t.centi[6], t.centi[7], t.centi[0]), (230, 150, 300));
        // Entries are capped at the table's bound.
        c.pot_err_centi[6] = u16::MAX;
        assert_eq!(c.pot_error_table(0).max_centi(), MAX_ERROR_CENTI);
    }
}
