//! The sensor-correction layer (docs/design.md §9): the raw readings of a real build —
//! a motor wired either way round, an encoder with its own counts per turn and direction,
//! a pot with an offset, gain and direction, a current sense with an offset and gain —
//! turned into the canonical readings the servo is written for (encoder 4096 counts per
//! turn counting up with the link, pot 512 at gear angle 0 counting up with the gear at
//! 1024 counts per 300°, current 2048 at 0 A and 1024 counts per ampere of motor current
//! driving the gear positive), and the servo's duty turned into the bridge's.
//!
//! [`SensorCorrection`] is the configuration (what calibration found, in engineering
//! units); [`Corrector::new`] checks it and does the divisions once; per tick
//! [`Corrector::input`] and [`Corrector::duty`] are integer multiplies and shifts.
//!
//! The link encoder is incremental: it reads its power-up value wherever the link is.
//! [`Corrector::input`] therefore spends the first [`BOOT_TICKS`] ticks after construction
//! (or [`Corrector::realign`]) with the motor off averaging the absolute pot, then sets the
//! encoder's offset so that the link angle equals the gear angle from the pot: with the
//! motor off and the link unloaded the beams carry no torque, so the two differ by at most
//! the free play φ_b plus the pot's error (docs/calibration.md). Until then it returns
//! `None` and the caller keeps the bridge off without running the servo.

use crate::sensors::{ADC_COUNTS, ADC_MID, ENCODER_COUNTS, POT_COUNTS};
use crate::servo::TickInput;

/// Ticks of pot averaging at power-up before the encoder offset is set (32 ms).
pub const BOOT_TICKS: u16 = 32;
/// A link that turns this many encoder counts during the window (falling under a load
/// with the bridge off) ends it early, after at least [`BOOT_MIN_TICKS`]: the servo then
/// catches it sooner (docs/calibration.md, "The link's absolute angle at start-up").
pub const BOOT_MOVED_COUNTS: u32 = 2;
/// The fewest ticks a boot window averages (the current offset's noise ×2 of the full
/// window's).
pub const BOOT_MIN_TICKS: u16 = 8;

/// One in Q16.
const Q16: i64 = 1 << 16;

/// The nominal pot reading at gear angle 0 (the canonical pot's centre), counts.
pub const POT_CENTER: u16 = POT_COUNTS / 2;

/// Link encoder counts per pot count: 4096/2π rad⁻¹ · (300°/1024) = 3.333…, Q16.
/// Computed from the two resolutions: 4096·300·2¹⁶ / (360·1024).
const ENC_PER_POT_Q16: i64 =
    (ENCODER_COUNTS as i64 * 300 * Q16 + 180 * POT_COUNTS as i64) / (360 * POT_COUNTS as i64);

/// A wiring sign.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Sign {
    /// As the canonical readings.
    Plus,
    /// Reversed.
    Minus,
}

impl Sign {
    /// +1 or −1.
    #[must_use]
    pub const fn value(self) -> i32 {
        match self {
            Sign::Plus => 1,
            Sign::Minus => -1,
        }
    }

    /// The sign of `v` (0 counts as plus).
    #[must_use]
    pub const fn of(v: i64) -> Sign {
        if v < 0 {
            Sign::Minus
        } else {
            Sign::Plus
        }
    }
}

/// What is known about the wiring and the sensors (configuration; calibration's result).
/// Every field documents its unit and format.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SensorCorrection {
    /// Motor leads: [`Sign::Minus`] when a positive bridge duty turns the gear negative.
    pub motor_polarity: Sign,
    /// Link encoder counting direction relative to the link's positive direction.
    pub encoder_direction: Sign,
    /// Link encoder counts per turn, 16..=16384 (raw readings wrap there).
    pub encoder_counts_per_turn: u16,
    /// Pot counting direction relative to the gear's positive direction.
    pub pot_direction: Sign,
    /// Raw pot reading at gear angle 0, counts, Q16 (fractional counts), in 0..1024.
    pub pot_center_q16: i32,
    /// Pot slope relative to the nominal 1024 counts per 300°, Q16, in [0.5, 2].
    pub pot_gain_q16: i32,
    /// Raw current ADC reading at 0 A, counts, Q16, in 0..4096.
    pub current_offset_q16: i32,
    /// Current-sense slope relative to the nominal 1024 counts/A, Q16, in [0.5, 2].
    pub current_gain_q16: i32,
    /// Lowest raw ADC reading that is not a rail (the supervisor's `adc_min`), counts.
    pub adc_min: u16,
    /// Highest raw ADC reading that is not a rail (`adc_max`), counts.
    pub adc_max: u16,
}

impl SensorCorrection {
    /// The canonical build: every sign plus, no offset, unit gains (the identity).
    pub const NOMINAL: SensorCorrection = SensorCorrection {
        motor_polarity: Sign::Plus,
        encoder_direction: Sign::Plus,
        encoder_counts_per_turn: ENCODER_COUNTS,
        pot_direction: Sign::Plus,
        pot_center_q16: (POT_CENTER as i32) << 16,
        pot_gain_q16: 1 << 16,
        current_offset_q16: (ADC_MID as i32) << 16,
        current_gain_q16: 1 << 16,
        adc_min: 16,
        adc_max: 4079,
    };
}

impl Default for SensorCorrection {
    fn default() -> Self {
        Self::NOMINAL
    }
}

/// Why a [`SensorCorrection`] was rejected.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum CorrectionError {
    /// Encoder counts per turn outside 16..=16384.
    EncoderCounts,
    /// Pot centre outside 0..1024 counts or gain outside [0.5, 2].
    Pot,
    /// Current offset outside 0..4096 counts or gain outside [0.5, 2].
    Current,
}

impl core::fmt::Display for CorrectionError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            CorrectionError::EncoderCounts => "encoder counts per turn outside 16..=16384",
            CorrectionError::Pot => "pot centre outside 0..1024 or gain outside 0.5..2",
            CorrectionError::Current => "current offset outside 0..4096 or gain outside 0.5..2",
        })
    }
}

impl core::error::Error for CorrectionError {}

/// The correction, derived for the per-tick path, and the encoder's unwrapping state.
/// Every per-tick quantity is an `i32` in Q16 and each sensor costs one 32-bit multiply
/// and an add: the offsets and the rounding are folded into constants when the
/// correction is built or the boot window ends.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Corrector {
    cal: SensorCorrection,
    /// Raw encoder counts per turn and half of it.
    cpt: i32,
    half: i32,
    /// Canonical encoder counts per raw count, signed, Q16: 4096/cpt·2¹⁶, so that
    /// |d·scale| ≤ 2²⁷ for any change |d| ≤ cpt/2.
    enc_scale_q16: i32,
    /// Canonical pot counts per raw count, signed (direction / gain), Q16 (|·| ≤ 2¹⁷).
    pot_scale_q16: i32,
    /// Canonical pot, Q16, of a raw 0, plus ½ (rounding): canonical = (raw·scale + this)
    /// >> 16.
    pot_bias_q16: i32,
    /// Canonical ADC counts per raw count, signed (polarity / gain), Q16 (|·| ≤ 2¹⁷).
    cur_scale_q16: i32,
    /// Canonical ADC, Q16, of a raw 0, plus ½: from the offset in use.
    cur_bias_q16: i32,
    /// Raw current ADC reading at 0 A in use, counts, Q16: measured at boot with the
    /// bridge off, else the configured one.
    cur_offset_q16: i32,
    /// Raw encoder reading of the last tick, `-1` before the first.
    enc_prev: i32,
    /// Canonical link encoder, Q16, modulo 2³² (only bits 16..28 are read: 4096 counts):
    /// the scaled changes since construction plus the boot alignment's offset.
    enc_q16: i32,
    /// Boot alignment: ticks left, the sum of the encoder offsets the pot gives (Q16) and
    /// of the raw current ADC (counts).
    boot_left: u16,
    boot_sum_q16: i64,
    boot_adc_sum: u32,
    /// The canonical encoder (Q16) at the window's first tick.
    boot_start_q16: i32,
}

/// Signed change of an encoder reading from `prev` to `now` at `per_turn` (≥ 1) counts
/// per turn, the shorter way round: in [−per_turn/2, per_turn/2). `now` is reduced
/// modulo `per_turn` first (a reading beyond the turn's last count).
#[must_use]
pub fn wrapped_delta(now: u16, prev: u16, per_turn: u16) -> i32 {
    let n = i32::from(per_turn.max(1));
    let mut d = (i32::from(now) % n - i32::from(prev)).rem_euclid(n);
    if d >= n / 2 {
        d -= n;
    }
    d
}

/// `num/den` in Q16, rounded to nearest (configuration time only). `den` > 0.
fn ratio_q16(num: i64, den: i64) -> i64 {
    (num * Q16 + den / 2).div_euclid(den)
}

/// The Q16 constant `k` with canonical = (raw·scale + k) >> 16 for a sensor whose raw
/// `center_q16` maps to the canonical `canonical_center`, rounded to nearest
/// (configuration time only).
fn bias_q16(canonical_center: u16, center_q16: i32, scale_q16: i32) -> i32 {
    let shifted = (i64::from(center_q16) * i64::from(scale_q16)) >> 16;
    ((i64::from(canonical_center) << 16) - shifted + Q16 / 2) as i32
}

impl Corrector {
    /// Checks `cal` and derives the per-tick scales; the boot alignment starts.
    ///
    /// # Errors
    /// [`CorrectionError`] for a field outside its documented range.
    pub fn new(cal: &SensorCorrection) -> Result<Corrector, CorrectionError> {
        let cpt = cal.encoder_counts_per_turn;
        if !(16..=16384).contains(&cpt) {
            return Err(CorrectionError::EncoderCounts);
        }
        let gain_ok = |g: i32| (Q16 / 2..=2 * Q16).contains(&i64::from(g));
        let pot_max = i32::from(POT_COUNTS) << 16;
        if !(0..pot_max).contains(&cal.pot_center_q16) || !gain_ok(cal.pot_gain_q16) {
            return Err(CorrectionError::Pot);
        }
        let adc_max = i32::from(ADC_COUNTS) << 16;
        if !(0..adc_max).contains(&cal.current_offset_q16)
            || !gain_ok(cal.current_gain_q16)
            || cal.adc_min >= cal.adc_max
        {
            return Err(CorrectionError::Current);
        }
        // Each scale is within ±2¹⁷ (gains ≥ 0.5) or ±2²⁴ (≥ 16 counts per turn).
        let scale = |sign: Sign, q: i64| (i64::from(sign.value()) * q) as i32;
        let pot_scale_q16 = scale(
            cal.pot_direction,
            ratio_q16(Q16, i64::from(cal.pot_gain_q16)),
        );
        let cur_scale_q16 = scale(
            cal.motor_polarity,
            ratio_q16(Q16, i64::from(cal.current_gain_q16)),
        );
        Ok(Corrector {
            cal: *cal,
            cpt: i32::from(cpt),
            half: i32::from(cpt / 2),
            enc_scale_q16: scale(
                cal.encoder_direction,
                ratio_q16(i64::from(ENCODER_COUNTS), i64::from(cpt)),
            ),
            pot_scale_q16,
            pot_bias_q16: bias_q16(POT_CENTER, cal.pot_center_q16, pot_scale_q16),
            cur_scale_q16,
            cur_bias_q16: bias_q16(ADC_MID, cal.current_offset_q16, cur_scale_q16),
            cur_offset_q16: cal.current_offset_q16,
            enc_prev: -1,
            enc_q16: 0,
            boot_left: BOOT_TICKS,
            boot_sum_q16: 0,
            boot_adc_sum: 0,
            boot_start_q16: 0,
        })
    }

    /// The configuration in use.
    #[must_use]
    pub const fn correction(&self) -> &SensorCorrection {
        &self.cal
    }

    /// Whether the boot alignment is done (the encoder's offset is set).
    #[must_use]
    pub const fn aligned(&self) -> bool {
        self.boot_left == 0
    }

    /// The raw current ADC reading taken as 0 A, counts, Q16: the mean of the boot window
    /// (bridge off) once aligned, unless that mean was at a rail; the configured one before.
    #[must_use]
    pub const fn current_offset_q16(&self) -> i32 {
        self.cur_offset_q16
    }

    /// Aligns the encoder to the pot again over the next [`BOOT_TICKS`] ticks (motor off):
    /// after a new correction was installed or the link was moved with the power off.
    pub fn realign(&mut self) {
        self.boot_left = BOOT_TICKS;
        self.boot_sum_q16 = 0;
        self.boot_adc_sum = 0;
    }

    /// Ends the boot window now without measuring: the encoder's raw zero is taken as
    /// link angle 0 (an absolute encoder, or a test or benchmark that starts from a board
    /// already booted at rest) and the configured current offset is kept.
    pub fn assume_aligned(&mut self) {
        self.boot_left = 0;
        self.boot_sum_q16 = 0;
        self.boot_adc_sum = 0;
        self.enc_prev = 0;
        self.enc_q16 = 0;
        self.set_current_offset(self.cal.current_offset_q16);
    }

    /// Canonical pot reading, counts, Q16 (not rounded), of raw reading `raw`.
    #[must_use]
    pub fn pot_q16(&self, raw: u16) -> i64 {
        // A reading beyond the pot's counts (a driver's bug) counts as its last one.
        let p = i32::from(raw.min(POT_COUNTS - 1));
        i64::from(p * self.pot_scale_q16 + self.pot_bias_q16 - (1 << 15))
    }

    /// Sets the current offset in use (raw counts at 0 A, Q16) and its bias.
    fn set_current_offset(&mut self, offset_q16: i32) {
        self.cur_offset_q16 = offset_q16;
        self.cur_bias_q16 = bias_q16(ADC_MID, offset_q16, self.cur_scale_q16);
    }

    /// Unwraps this tick's raw encoder reading into the canonical encoder (Q16).
    #[inline(always)]
    fn unwrap_encoder(&mut self, now: i32) {
        let mut d = now - self.enc_prev;
        if d >= self.half {
            d -= self.cpt;
        } else if d < -self.half {
            d += self.cpt;
        }
        // |d·scale| ≤ 2²⁷; the sum wraps modulo 2³², a multiple of the 2²⁸ read.
        self.enc_q16 = self.enc_q16.wrapping_add(d * self.enc_scale_q16);
        self.enc_prev = now;
    }

    /// The canonical readings of this tick's raw ones, `None` during the boot alignment
    /// (keep the bridge off and do not run the servo).
    pub fn input(&mut self, raw: &TickInput) -> Option<TickInput> {
        let mut c = TickInput::default();
        self.correct(raw, &mut c).then_some(c)
    }

    /// [`Corrector::input`] into `out` (the per-tick form: no copy of the readings);
    /// `false` during the boot alignment (`out` untouched).
    #[inline(always)]
    pub fn correct(&mut self, raw: &TickInput, out: &mut TickInput) -> bool {
        if self.boot_left > 0 {
            self.boot_step(raw);
            return false;
        }
        // Encoder: unwrapped at the raw counts per turn (a reading is below it: the timer
        // counts modulo it; one beyond it is a driver's fault, seen as a jump). The
        // canonical encoder has 4096 counts per turn: the wrap is a mask.
        self.unwrap_encoder(i32::from(raw.link_encoder));
        out.link_encoder = ((self.enc_q16 >> 16) & (i32::from(ENCODER_COUNTS) - 1)) as u16;
        out.gear_pot = match raw.gear_pot {
            Some(p) => {
                // p ≤ 1023, |scale| ≤ 2¹⁷: the product fits in i32.
                let p = i32::from(p.min(POT_COUNTS - 1));
                let c = (p * self.pot_scale_q16 + self.pot_bias_q16) >> 16;
                Some(c.clamp(0, i32::from(POT_COUNTS) - 1) as u16)
            }
            None => None,
        };
        let (lo, hi) = (self.cal.adc_min, self.cal.adc_max);
        out.current_adc = if raw.current_adc < lo {
            0
        } else if raw.current_adc > hi {
            ADC_COUNTS - 1
        } else {
            // raw < 4096, |scale| ≤ 2¹⁷: the product fits in i32.
            let c = (i32::from(raw.current_adc) * self.cur_scale_q16 + self.cur_bias_q16) >> 16;
            // A valid raw reading stays off the rails (the supervisor's rails mean a
            // saturated or open sense, which the raw test above already decided).
            c.clamp(i32::from(lo), i32::from(hi)) as u16
        };
        // The supply sense as read (its gain is not calibrated: docs/design.md §11, "The
        // supply the board measures").
        out.supply_adc = raw.supply_adc;
        out.read_error = raw.read_error;
        true
    }

    /// One tick of the boot window (motor off): unwraps the encoder, sums the encoder
    /// offset this tick's pot gives and the current; at its end the alignment and the
    /// current offset.
    fn boot_step(&mut self, raw: &TickInput) {
        let now = i32::from(raw.link_encoder);
        if self.enc_prev < 0 {
            self.enc_prev = now;
        }
        self.unwrap_encoder(now);
        if self.boot_left == BOOT_TICKS {
            self.boot_start_q16 = self.enc_q16;
        }
        self.boot_left -= 1;
        let done = BOOT_TICKS - self.boot_left;
        // The offset that makes the link angle the gear angle from this tick's pot,
        // canonical encoder counts, Q16: averaged per tick, so that a link that moves
        // during the window (falling under a load with the motor off) is aligned as well.
        let scaled = i64::from(self.enc_q16);
        let offset_q16 = match raw.gear_pot {
            Some(p) => {
                let from_center = self.pot_q16(p) - (i64::from(POT_CENTER) << 16);
                ((from_center * ENC_PER_POT_Q16) >> 16) - scaled
            }
            // No absolute sensor: the link is where it was at power-up (angle 0).
            None => -scaled,
        };
        self.boot_sum_q16 = self.boot_sum_q16.saturating_add(offset_q16);
        self.boot_adc_sum = self.boot_adc_sum.saturating_add(u32::from(raw.current_adc));
        let moved = self
            .enc_q16
            .wrapping_sub(self.boot_start_q16)
            .unsigned_abs()
            >= BOOT_MOVED_COUNTS << 16;
        if moved && done >= BOOT_MIN_TICKS {
            self.boot_left = 0;
        }
        if self.boot_left == 0 {
            // Mean offset, rounded to whole counts (the reading is the centre of its
            // count), added to the canonical encoder.
            let mean_q16 = self.boot_sum_q16 / i64::from(done);
            let offset = ((mean_q16 + Q16 / 2) >> 16) as i32;
            self.enc_q16 = self.enc_q16.wrapping_add(offset.wrapping_shl(16));
            // Mean raw current with the bridge off: 0 A, unless it sits at a rail (a dead
            // or unidirectional sense, which the supervisor then reports).
            let n = u32::from(done);
            let mean = self.boot_adc_sum / n;
            let rails = u32::from(self.cal.adc_min)..=u32::from(self.cal.adc_max);
            let offset_q16 = if rails.contains(&mean) {
                ((u64::from(self.boot_adc_sum) << 16) / u64::from(n)) as i32
            } else {
                self.cal.current_offset_q16
            };
            self.set_current_offset(offset_q16);
        }
    }

    /// Whether the motor's leads are reversed (the bridge's duty is the servo's negated).
    #[must_use]
    pub const fn reversed(&self) -> bool {
        matches!(self.cal.motor_polarity, Sign::Minus)
    }

    /// The bridge duty, ‰, for the servo's `duty`.
    #[must_use]
    pub const fn duty(&self, duty: i16) -> i16 {
        match self.cal.motor_polarity {
            Sign::Plus => duty,
            Sign::Minus => duty.saturating_neg(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn raw(enc: u16, pot: u16, adc: u16) -> TickInput {
        TickInput {
            link_encoder: enc,
            gear_pot: Some(pot),
            current_adc: adc,
            supply_adc: None,
            read_error: None,
        }
    }

    fn booted(c: &mut Corrector, r: &TickInput) {
        for _ in 0..BOOT_TICKS {
            assert_eq!(c.input(r), None);
        }
    }

    #[test]
    fn the_nominal_correction_is_the_identity() {
        let mut c = Corrector::new(&SensorCorrection::NOMINAL).unwrap();
        booted(&mut c, &raw(0, 512, 2048));
        for (e, p, a) in [
            (0, 512, 2048),
            (5, 515, 2100),
            (4095, 0, 20),
            (3000, 1023, 4000),
        ] {
            // Encoder steps of more than half a turn unwrap the other way; keep them short.
            let mut c2 = c;
            let got = c2.input(&raw(e, p, a)).unwrap();
            assert_eq!(got.gear_pot, Some(p));
            assert_eq!(got.current_adc, a);
            assert_eq!(got.link_encoder, e);
        }
        assert_eq!(c.duty(-300), -300);
    }

    #[test]
    fn boot_aligns_the_encoder_with_the_pot() {
        // Gear at +60 pot counts from the centre: 60·3.333 = 200 encoder counts.
        let mut c = Corrector::new(&SensorCorrection::NOMINAL).unwrap();
        booted(&mut c, &raw(0, 572, 2048));
        assert_eq!(c.input(&raw(0, 572, 2048)).unwrap().link_encoder, 200);
        // The link turns 10 counts: the offset stays.
        assert_eq!(c.input(&raw(10, 575, 2048)).unwrap().link_encoder, 210);
        // Negative angles wrap below 4096.
        let mut c = Corrector::new(&SensorCorrection::NOMINAL).unwrap();
        booted(&mut c, &raw(1234, 452, 2048));
        assert_eq!(
            c.input(&raw(1234, 452, 2048)).unwrap().link_encoder,
            4096 - 200
        );
    }

    #[test]
    fn a_link_that_falls_ends_the_boot_window_early() {
        // Gear held at +200 encoder counts by the pot; the link still for 4 ticks, then
        // falling a count a tick: moved 2 counts by the 6th tick, so the window ends at its
        // 8th (`BOOT_MIN_TICKS`), the offsets averaged over those 8: 200 − (1+2+3+4)/8 =
        // 198.75, rounded to 199; the current's mean over the same 8 ticks.
        let mut c = Corrector::new(&SensorCorrection::NOMINAL).unwrap();
        let enc = [0u16, 0, 0, 0, 1, 2, 3, 4];
        for (k, e) in enc.iter().enumerate() {
            assert!(!c.aligned(), "aligned before tick {k}");
            let adc = if k < 4 { 2050 } else { 2054 };
            assert_eq!(c.input(&raw(*e, 572, adc)), None);
        }
        assert!(c.aligned());
        assert_eq!(c.input(&raw(5, 572, 2052)).unwrap().link_encoder, 5 + 199);
        assert_eq!(c.current_offset_q16(), 2052 << 16);
        // A link that stays within a count takes the whole window.
        let mut c = Corrector::new(&SensorCorrection::NOMINAL).unwrap();
        for k in 0..BOOT_TICKS {
            assert_eq!(c.input(&raw(k % 2, 572, 2048)), None, "tick {k}");
        }
        assert!(c.aligned());
    }

    #[test]
    fn reversed_and_scaled_sensors_are_made_canonical() {
        let cal = SensorCorrection {
            motor_polarity: Sign::Minus,
            encoder_direction: Sign::Minus,
            encoder_counts_per_turn: 4000,
            pot_direction: Sign::Minus,
            pot_center_q16: 530 << 16,
            pot_gain_q16: (Q16 * 11 / 10) as i32,
            current_offset_q16: 2148 << 16,
            current_gain_q16: (Q16 * 9 / 10) as i32,
            ..SensorCorrection::NOMINAL
        };
        let mut c = Corrector::new(&cal).unwrap();
        booted(&mut c, &raw(0, 530, 2148));
        let at_rest = c.input(&raw(0, 530, 2148)).unwrap();
        assert_eq!(
            (at_rest.link_encoder, at_rest.gear_pot, at_rest.current_adc),
            (0, Some(512), 2048)
        );
        // The encoder counts down 1000 raw counts (a quarter turn of 4000): +1024 canonical.
        let mut e = 0u16;
        for _ in 0..100 {
            e = (e + 4000 - 10) % 4000;
            c.input(&raw(e, 530, 2148));
        }
        assert_eq!(c.input(&raw(e, 530, 2148)).unwrap().link_encoder, 1024);
        // Pot 110 counts below its centre with gain 1.1: +100 canonical.
        assert_eq!(c.input(&raw(e, 420, 2148)).unwrap().gear_pot, Some(612));
        // Raw +90 counts with gain 0.9 and reversed motor: −100 canonical.
        assert_eq!(c.input(&raw(e, 420, 2238)).unwrap().current_adc, 1948);
        // The rails stay rails.
        assert_eq!(c.input(&raw(e, 420, 4095)).unwrap().current_adc, 4095);
        assert_eq!(c.input(&raw(e, 420, 3)).unwrap().current_adc, 0);
        assert_eq!(c.duty(300), -300);
        assert_eq!(c.duty(i16::MIN), i16::MAX);
    }

    #[test]
    fn rejects_corrections_out_of_range() {
        let bad = |f: fn(&mut SensorCorrection)| {
            let mut c = SensorCorrection::NOMINAL;
            f(&mut c);
            Corrector::new(&c).unwrap_err()
        };
        assert_eq!(
            bad(|c| c.encoder_counts_per_turn = 8),
            CorrectionError::EncoderCounts
        );
        assert_eq!(bad(|c| c.pot_gain_q16 = 1 << 14), CorrectionError::Pot);
        assert_eq!(bad(|c| c.pot_center_q16 = 1024 << 16), CorrectionError::Pot);
        assert_eq!(
            bad(|c| c.current_gain_q16 = 3 << 16),
            CorrectionError::Current
        );
        assert_eq!(bad(|c| c.current_offset_q16 = -1), CorrectionError::Current);
    }
}
