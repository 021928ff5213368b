//! Sensors as the board sees them: quantisation, clamping, wrap, noise and fault hooks.
//! Their resolutions are `model::sensors`'.

use model::sensors::{
    ADC_COUNTS, ADC_COUNTS_PER_A, ADC_MID, ENCODER_COUNTS, POT_COUNTS, POT_SPAN_DEG,
    SUPPLY_MV_PER_COUNT,
};

/// One link-encoder count, rad (2π/4096; f64 for the host-side figures).
pub const ENCODER_COUNT_RAD: f64 = core::f64::consts::TAU / ENCODER_COUNTS as f64;

/// Potentiometer counts per radian of gear angle: 1024 / (300° in rad) = 195.57 (f32, the
/// plant's quantiser).
pub const POT_COUNTS_PER_RAD: f32 =
    POT_COUNTS as f32 / (POT_SPAN_DEG as f32 * (core::f32::consts::PI / 180.0));

/// Deterministic xorshift32 generator (Marsaglia), the noise source of the sensors.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct XorShift32 {
    state: u32,
}

impl XorShift32 {
    /// Seeded generator; seed 0 (a fixed point of xorshift) is replaced by 0x2545_F491.
    pub fn new(seed: u32) -> Self {
        Self {
            state: if seed == 0 { 0x2545_F491 } else { seed },
        }
    }

    /// Next 32-bit value (never 0).
    pub fn next_u32(&mut self) -> u32 {
        let mut x = self.state;
        x ^= x << 13;
        x ^= x >> 17;
        x ^= x << 5;
        self.state = x;
        x
    }

    /// Uniform in [0, 1) with 24-bit resolution (exact in f32).
    pub fn next_unit(&mut self) -> f32 {
        (self.next_u32() >> 8) as f32 * (1.0 / 16_777_216.0)
    }

    /// Approximately standard-normal sample (sum of four uniforms, scaled to unit
    /// variance; bounded to ±3.46).
    pub fn next_gaussian(&mut self) -> f32 {
        let s = self.next_unit() + self.next_unit() + self.next_unit() + self.next_unit();
        // Var(sum) = 4/12 = 1/3 → scale by √3.
        (s - 2.0) * 1.732_050_8
    }
}

/// A fault injected into one sensor channel (applied after quantisation).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum SensorFault {
    /// Healthy sensor.
    #[default]
    None,
    /// The channel reads this raw value (clamped to the channel's range), e.g. 4095 for a
    /// saturated current ADC, 0 for a disconnected pot.
    StuckAt(u16),
    /// The channel repeats its last reading.
    Frozen,
    /// The raw value is offset by this many counts (then clamped, or wrapped for the
    /// encoder): a jump or a calibration error.
    Offset(i16),
}

/// Fault hooks of the four channels.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SensorFaults {
    /// Gear-side potentiometer.
    pub gear_pot: SensorFault,
    /// Link-side magnetic encoder.
    pub link_encoder: SensorFault,
    /// Motor current ADC.
    pub current_adc: SensorFault,
    /// Supply sense ADC.
    pub supply_adc: SensorFault,
}

/// Raw sensor values, as the board's peripherals deliver them.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SensorReadings {
    /// Gear-side potentiometer, 0..=1023 over 300° (0.293°/count), clamped at the ends;
    /// `pot_center_counts` (default 512) at gear angle 0; rounds to nearest.
    pub gear_pot: u16,
    /// Link-side incremental encoder, 0..`encoder_counts_per_turn` (4096) per revolution,
    /// wraps; truncates (floor); `encoder_zero_counts` at the power-up angle.
    pub link_encoder: u16,
    /// Motor current ADC, 0..=4095: 2048 + 1024·gain·i (i in A, ±2 A full scale) + offset error +
    /// noise, rounded, clamped at the rails.
    pub current_adc: u16,
    /// Supply sense ADC, 0..=4095: gain·V_s / 5 mV (`SUPPLY_MV_PER_COUNT`), rounded,
    /// clamped at the rails.
    pub supply_adc: u16,
}

#[inline]
fn round_clamp(x: f32, max: u16) -> u16 {
    let r = libm::floorf(x + 0.5);
    if r <= 0.0 {
        0
    } else if r >= f32::from(max) {
        max
    } else {
        r as u16
    }
}

/// The pot's reading at gear angle `gear_angle_rad`: centre + direction·gain·slope·θ, plus
/// the non-linearity `inl`·sin(2π·c/1024) at ideal count c and `noise` (counts), rounded
/// and clamped at the rails. With direction and gain 1 and no non-linearity or noise it is
/// the ideal pot, bit for bit (the extra terms are skipped).
pub(crate) fn pot_counts(gear_angle_rad: f64, s: &crate::SensorConfig, noise: f32) -> u16 {
    let slope = f64::from(POT_COUNTS_PER_RAD);
    let ideal = if s.pot_direction == 1.0 && s.pot_gain == 1.0 {
        gear_angle_rad * slope
    } else {
        gear_angle_rad * slope * f64::from(s.pot_direction * s.pot_gain)
    };
    // Clamp in f64 first so that huge angles do not lose the clamp in f32.
    let mut x = (ideal + f64::from(s.pot_center_counts)).clamp(-1.0, 1024.0) as f32;
    if s.pot_nonlinearity_counts != 0.0 {
        let turn = x * (core::f32::consts::TAU / f32::from(POT_COUNTS));
        x += s.pot_nonlinearity_counts * libm::sinf(turn);
    }
    round_clamp(x + noise, POT_COUNTS - 1)
}

/// The incremental link encoder: `zero` at power-up, counting `direction` × the link's
/// turn since then at `per_turn` counts per turn (floor), wrapping at `per_turn`.
pub(crate) fn encoder_counts(since_power_up_rad: f64, s: &crate::SensorConfig) -> u16 {
    let per_turn = s.encoder_counts_per_turn.max(1);
    let counts_per_rad = f64::from(per_turn) / (2.0 * core::f64::consts::PI);
    let turned = if s.encoder_direction < 0.0 {
        -since_power_up_rad
    } else {
        since_power_up_rad
    };
    // `as` saturates (NaN → 0): no panic; rem_euclid by a positive constant cannot panic.
    let c = libm::floor(turned * counts_per_rad) as i64 + i64::from(s.encoder_zero_counts);
    c.rem_euclid(i64::from(per_turn)) as u16
}

/// The supply sense's reading of `supply_v` through a divider whose gain is `gain` times
/// the nominal one (resistor and reference tolerances).
pub(crate) fn supply_counts(supply_v: f32, gain: f32) -> u16 {
    let mv = (supply_v * gain * 1000.0).clamp(0.0, 1.0e5);
    round_clamp(mv / f32::from(SUPPLY_MV_PER_COUNT), ADC_COUNTS - 1)
}

pub(crate) fn adc_counts(current_a: f32, gain: f32, offset: f32, noise: f32) -> u16 {
    // Keep the product well inside the f32 → u16 range before rounding (constant bounds:
    // `clamp` cannot panic).
    let i = (gain * current_a).clamp(-4.0, 4.0);
    round_clamp(
        f32::from(ADC_MID) + i * f32::from(ADC_COUNTS_PER_A) + offset + noise,
        ADC_COUNTS - 1,
    )
}

fn apply(fault: SensorFault, raw: u16, last: u16, max: u16, wrap: bool) -> u16 {
    match fault {
        SensorFault::None => raw,
        SensorFault::StuckAt(v) => {
            if v > max {
                max
            } else {
                v
            }
        }
        SensorFault::Frozen => last,
        SensorFault::Offset(d) => {
            let v = i32::from(raw) + i32::from(d);
            if wrap {
                v.rem_euclid(i32::from(max) + 1) as u16
            } else {
                v.clamp(0, i32::from(max)) as u16
            }
        }
    }
}

impl SensorFaults {
    pub(crate) fn apply(&self, raw: SensorReadings, last: SensorReadings) -> SensorReadings {
        SensorReadings {
            gear_pot: apply(
                self.gear_pot,
                raw.gear_pot,
                last.gear_pot,
                POT_COUNTS - 1,
                false,
            ),
            link_encoder: apply(
                self.link_encoder,
                raw.link_encoder,
                last.link_encoder,
                ENCODER_COUNTS - 1,
                true,
            ),
            current_adc: apply(
                self.current_adc,
                raw.current_adc,
                last.current_adc,
                ADC_COUNTS - 1,
                false,
            ),
            supply_adc: apply(
                self.supply_adc,
                raw.supply_adc,
                last.supply_adc,
                ADC_COUNTS - 1,
                false,
            ),
        }
    }
}
