//! What the store's integration tests share: record strategies, samples, and a power cycle
//! through the flash's byte snapshot (as the emulated boards do through the host file).
#![allow(dead_code)] // each test file uses a part

use proptest::prelude::*;
use protocol::{FaultCode, FaultRecord, Gains, Limits, KD_MAX, KI_MAX, KP_MAX, TARGET_MAX_URAD};
use store::{
    Boot, BusSettings, Calibration, Clutch, Config, FaultEntry, Outcome, RamFlash, RangeChecks,
    RecordSet, Store, PAGES,
};

/// The store's flash on every board.
pub type Flash = RamFlash<PAGES>;
/// A store on it.
pub type FlashStore = Store<Flash>;

/// Power off and on: a new flash from the old one's bytes (nothing else survives, the
/// armed cut included), and the store opened on it. Opening never fails.
pub fn reboot(flash: &Flash) -> (FlashStore, Boot) {
    let fresh = Flash::from_bytes(flash.as_bytes()).expect("same size");
    Store::open(fresh, &RangeChecks).expect("the store opens whatever the flash holds")
}

/// Asserts that nothing was rejected at load: every record is loaded or absent.
pub fn assert_nothing_rejected(boot: &Boot) {
    for (name, outcome) in boot.report.lines() {
        assert!(
            !matches!(outcome, Outcome::Rejected(_)),
            "{name}: {outcome} ({:?})",
            boot.report
        );
    }
    assert_eq!(boot.faults.dropped().0, 0, "fault entries dropped");
}

pub fn sample_config(length_um: u32) -> Config {
    Config {
        clutch: Clutch::LengthUm(length_um),
        link_inertia_kg_mm2: 1_000,
        gains: None,
        limits: Limits::DEFAULT,
        command_timeout_ms: 100,
    }
}

pub fn sample_calibration() -> Calibration {
    Calibration {
        wire: protocol::Calibration {
            motor_polarity: -1,
            encoder_direction: 1,
            pot_direction: -1,
            current_offset_counts: -12,
            pot_offset_counts: 7,
            resistance_mohm: 8_300,
            back_emf_uv_s_per_rad: 1_240_000,
            gear_friction_unm: 20_000,
            link_inertia_kg_mm2: 1_150,
            stiffness_mnm_per_rad: Some(265_000),
            clutch_length_um: Some(3_000),
            stiffness_uncertainty_permille: 40,
        },
        encoder_counts_per_turn: 4000,
        pot_gain_ppm: 1_021_000,
        current_gain_ppm: 980_000,
        pot_error_centi: Some([250; 16]),
    }
}

/// A full set, distinct for each `n`.
pub fn sample_set(n: u32) -> RecordSet {
    RecordSet {
        config: Some(sample_config(1_000 + n % 7_001)),
        calibration: Some(sample_calibration()),
        bus: Some(BusSettings {
            id: (n % 254) as u8,
            ..BusSettings::ax12a_default()
        }),
    }
}

pub fn sample_fault(n: u32) -> FaultRecord {
    FaultRecord {
        code: FaultCode::ALL[n as usize % FaultCode::ALL.len()],
        value: n as i32 * 1_001 - 50_000,
        tick: n * 37,
    }
}

fn limits() -> impl Strategy<Value = Limits> {
    let max = TARGET_MAX_URAD as i32;
    (
        1u16..=1000,
        1u16..=protocol::CURRENT_LIMIT_MAX_MA,
        1u32..=protocol::MOTOR_TORQUE_LIMIT_MAX_UNM,
        1u16..=1000,
        -max..=0,
        1..=max,
        0u16..=protocol::CLUTCH_TOLERANCE_MAX_UM,
    )
        .prop_map(|(margin, current, torque, duty, min, max, tol)| Limits {
            torque_margin_permille: margin,
            current_ma: current,
            motor_torque_unm: torque,
            duty_permille: duty,
            position_min_urad: min,
            position_max_urad: max,
            clutch_tolerance_um: tol,
        })
}

/// Valid configs over their whole ranges.
pub fn config() -> impl Strategy<Value = Config> {
    (
        prop_oneof![
            (protocol::CLUTCH_MIN_UM..=protocol::CLUTCH_MAX_UM).prop_map(Clutch::LengthUm),
            (1u32..=u32::MAX).prop_map(Clutch::StiffnessMnmPerRad),
        ],
        1u32..=1_000_000,
        proptest::option::of(
            (0..=KP_MAX, 0..=KI_MAX, 0..=KD_MAX).prop_map(|(kp, ki, kd)| Gains { kp, ki, kd }),
        ),
        limits(),
        1u32..=u32::MAX,
    )
        .prop_map(|(clutch, inertia, gains, limits, timeout)| Config {
            clutch,
            link_inertia_kg_mm2: inertia,
            gains,
            limits,
            command_timeout_ms: timeout,
        })
}

/// Valid calibrations over their whole ranges.
pub fn calibration() -> impl Strategy<Value = Calibration> {
    let sign = || prop_oneof![Just(1i8), Just(-1i8)];
    (
        (sign(), sign(), sign()),
        (-2048i16..=2048, -512i16..=512),
        (
            1u32..=u32::MAX,
            1u32..=u32::MAX,
            any::<u32>(),
            1u32..=1_000_000,
        ),
        (
            proptest::option::of(1u32..=u32::MAX),
            proptest::option::of(protocol::CLUTCH_MIN_UM..=protocol::CLUTCH_MAX_UM),
            0u16..=1000,
        ),
    )
        .prop_map(
            |((m, e, p), (ci, po), (r, ke, fr, j), (k, l, u))| Calibration {
                wire: protocol::Calibration {
                    motor_polarity: m,
                    encoder_direction: e,
                    pot_direction: p,
                    current_offset_counts: ci,
                    pot_offset_counts: po,
                    resistance_mohm: r,
                    back_emf_uv_s_per_rad: ke,
                    gear_friction_unm: fr,
                    link_inertia_kg_mm2: j,
                    stiffness_mnm_per_rad: k,
                    clutch_length_um: l,
                    stiffness_uncertainty_permille: u,
                },
                encoder_counts_per_turn: 4096,
                pot_gain_ppm: 1_000_000,
                current_gain_ppm: 1_000_000,
                pot_error_centi: None,
            },
        )
}

/// Valid bus settings over their whole ranges (IDs valid in both tables).
pub fn bus() -> impl Strategy<Value = BusSettings> {
    let baud = prop_oneof![
        (1u8..=254).prop_map(|v| (1u8, dynamixel::table::ax_baud_bps(v))),
        proptest::sample::select(&dynamixel::table::X_BAUD_BPS[..]).prop_map(|b| (2u8, b)),
    ];
    (
        0u8..=252,
        baud,
        0u8..=254,
        0u8..=2,
        0u16..=511,
        511u16..=1023,
        (0u16..=1023, 0u8..=100, 50u8..=160, 0u8..=127, 0u16..=2047),
    )
        .prop_map(
            |(id, (proto, baud), delay, level, cw, ccw, (torque, temp, volt, mask, pos))| {
                BusSettings {
                    id,
                    baud_bps: baud,
                    protocol_version: proto,
                    return_delay_2us: delay,
                    status_return_level: level,
                    cw_angle_limit: cw,
                    ccw_angle_limit: ccw,
                    limits: store::BusLimits {
                        max_torque: torque,
                        temperature_limit: temp,
                        min_voltage_limit: volt,
                        max_voltage_limit: volt,
                        alarm_led: mask,
                        shutdown: mask,
                        velocity_limit: torque,
                        min_position_limit: pos,
                        max_position_limit: pos + 2048,
                    },
                }
            },
        )
}

/// Valid record sets, each record present or not.
pub fn record_set() -> impl Strategy<Value = RecordSet> {
    (
        proptest::option::of(config()),
        proptest::option::of(calibration()),
        proptest::option::of(bus()),
    )
        .prop_map(|(config, calibration, bus)| RecordSet {
            config,
            calibration,
            bus,
        })
}

/// The fault log a boot found, oldest first.
pub fn faults(boot: &Boot) -> Vec<FaultEntry> {
    boot.faults.iter().copied().collect()
}

/// What the store must hold: the last completed save (or reset), its generation, the
/// fault log.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Expected {
    pub set: RecordSet,
    pub generation: Option<u32>,
    pub faults: Vec<FaultEntry>,
    pub next_seq: u32,
}

impl Expected {
    /// What a boot found.
    pub fn booted(boot: &Boot) -> Expected {
        Expected {
            set: boot.set,
            generation: boot.report.generation,
            faults: faults(boot),
            next_seq: boot.faults.latest().map_or(0, |e| e.seq + 1),
        }
    }

    /// After `fault` is logged: the next number, the oldest of a full log dropped.
    pub fn logged(&self, fault: FaultRecord) -> Expected {
        let mut next = self.clone();
        next.faults.push(FaultEntry {
            seq: self.next_seq,
            fault,
        });
        if next.faults.len() > store::FAULT_LOG_LEN {
            next.faults.remove(0);
        }
        next.next_seq += 1;
        next
    }

    pub fn saved(&self, set: RecordSet) -> Expected {
        Expected {
            set,
            generation: Some(self.generation.map_or(1, |g| g + 1)),
            ..self.clone()
        }
    }

    pub fn reset(&self) -> Expected {
        Expected {
            set: RecordSet::default(),
            generation: Some(self.generation.map_or(1, |g| g + 1)),
            faults: Vec::new(),
            next_seq: self.next_seq,
        }
    }

    pub fn matches(&self, boot: &Boot) -> bool {
        boot.set == self.set
            && boot.report.generation == self.generation
            && faults(boot) == self.faults
    }
}
