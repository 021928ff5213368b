//! Shared test support: proptest strategies for every message, a recording mock device,
//! and helpers to drive the decoder and the handler.
#![allow(dead_code)] // each test binary uses a part of this module

use proptest::prelude::*;
use proptest::test_runner::Config;
use protocol::{
    Calibration, CalibrationProgress, CalibrationReport, Decoder, Device, ErrorCode, FaultCode,
    FaultRecord, FaultSet, Frame, Gains, Handler, LimitFlags, Limits, LoggedFault, Reply, Request,
    State, Status, TelemetrySample, CLUTCH_MAX_UM, CLUTCH_MIN_UM, KD_MAX, KI_MAX, KP_MAX,
    MOVE_DURATION_MAX_MS, SINE_AMPLITUDE_MAX_URAD, SINE_FREQUENCY_MAX_MHZ, SINE_FREQUENCY_MIN_MHZ,
    TARGET_MAX_URAD,
};

/// Proptest configuration: `default_cases` cases unless `PROPTEST_CASES` is set;
/// `Config::default()` applies the other `PROPTEST_*` variables (e.g. `PROPTEST_RNG_SEED`).
pub fn config(default_cases: u32) -> Config {
    let mut config = Config {
        // Shrinking a byte-stream failure can take long; keep it bounded.
        max_shrink_iters: 10_000,
        // Integration tests have no lib.rs beside them for proptest's regression files; a
        // failure prints its minimal input instead.
        failure_persistence: None,
        ..Config::default()
    };
    if std::env::var_os("PROPTEST_CASES").is_none() {
        config.cases = default_cases;
    }
    config
}

/// Cases per round-trip property by default.
pub const ROUNDTRIP_CASES: u32 = 10_000;
/// Cases per fuzz property by default (CI); `PROPTEST_CASES=1000000` for the long run.
pub const FUZZ_CASES: u32 = 50_000;

// ---------------------------------------------------------------------------------------
// Strategies: full-range values with the boundaries of every documented range mixed in,
// so that both valid and out-of-range requests are frequent.

fn edge_u32(lo: u32, hi: u32) -> BoxedStrategy<u32> {
    prop_oneof![
        3 => lo..=hi,
        2 => any::<u32>(),
        1 => prop::sample::select(vec![
            0,
            lo,
            hi,
            lo.saturating_sub(1),
            hi.saturating_add(1),
            u32::MAX
        ]),
    ]
    .boxed()
}

fn edge_u16(lo: u16, hi: u16) -> BoxedStrategy<u16> {
    prop_oneof![
        3 => lo..=hi,
        2 => any::<u16>(),
        1 => prop::sample::select(vec![
            0,
            lo,
            hi,
            lo.saturating_sub(1),
            hi.saturating_add(1),
            u16::MAX
        ]),
    ]
    .boxed()
}

fn edge_u64(hi: u64) -> BoxedStrategy<u64> {
    prop_oneof![
        3 => 0..=hi,
        2 => any::<u64>(),
        1 => prop::sample::select(vec![0, hi, hi + 1, u64::MAX]),
    ]
    .boxed()
}

fn angle() -> BoxedStrategy<i32> {
    let m = TARGET_MAX_URAD as i32;
    prop_oneof![
        3 => -m..=m,
        2 => any::<i32>(),
        1 => prop::sample::select(vec![0, m, -m, m + 1, -m - 1, i32::MAX, i32::MIN]),
    ]
    .boxed()
}

pub fn gains() -> impl Strategy<Value = Gains> {
    (edge_u64(KP_MAX), edge_u64(KI_MAX), edge_u64(KD_MAX)).prop_map(|(kp, ki, kd)| Gains {
        kp,
        ki,
        kd,
    })
}

pub fn limits() -> impl Strategy<Value = Limits> {
    (
        edge_u16(1, 1000),
        edge_u16(1, 10_000),
        edge_u32(1, 100_000_000),
        edge_u16(1, 1000),
        angle(),
        angle(),
        edge_u16(0, 5_000),
    )
        .prop_map(|(m, c, t, d, lo, hi, tol)| Limits {
            torque_margin_permille: m,
            current_ma: c,
            motor_torque_unm: t,
            duty_permille: d,
            position_min_urad: lo,
            position_max_urad: hi,
            clutch_tolerance_um: tol,
        })
}

/// Every request, fields anywhere in their types (often out of range).
pub fn request() -> impl Strategy<Value = Request> {
    prop_oneof![
        Just(Request::Ping),
        Just(Request::GetStatus),
        Just(Request::Enable),
        Just(Request::Disable),
        Just(Request::ClearFault),
        edge_u32(CLUTCH_MIN_UM, CLUTCH_MAX_UM)
            .prop_map(|length_um| Request::SetClutchLength { length_um }),
        edge_u32(1, 10_000_000).prop_map(|k| Request::SetStiffness {
            stiffness_mnm_per_rad: k
        }),
        (angle(), edge_u32(1, MOVE_DURATION_MAX_MS)).prop_map(|(target_urad, duration_ms)| {
            Request::Move {
                target_urad,
                duration_ms,
            }
        }),
        angle().prop_map(|target_urad| Request::Step { target_urad }),
        (
            edge_u32(0, SINE_AMPLITUDE_MAX_URAD),
            edge_u32(SINE_FREQUENCY_MIN_MHZ, SINE_FREQUENCY_MAX_MHZ)
        )
            .prop_map(|(amplitude_urad, frequency_mhz)| Request::Sine {
                amplitude_urad,
                frequency_mhz
            }),
        Just(Request::Hold),
        gains().prop_map(Request::SetGains),
        Just(Request::AutoGains),
        limits().prop_map(Request::SetLimits),
        prop_oneof![Just(0u16), edge_u16(10, 500)]
            .prop_map(|rate_hz| Request::StreamTelemetry { rate_hz }),
        Just(Request::Heartbeat),
        Just(Request::DisarmHeartbeat),
        Just(Request::GetLimits),
        Just(Request::GetSensors),
        (any::<i16>(), edge_u16(1, protocol::NUDGE_DURATION_MAX_MS)).prop_map(
            |(duty_permille, duration_ms)| Request::Nudge {
                duty_permille,
                duration_ms
            }
        ),
        Just(Request::Save),
        Just(Request::Load),
        Just(Request::FactoryReset),
        any::<u8>().prop_map(|index| Request::FaultsLog { index }),
        (
            angle(),
            edge_u32(0, 10_000_000),
            edge_u32(0, 200_000_000),
            angle()
        )
            .prop_map(|(target_urad, k, d, t)| Request::Impedance {
                target_urad,
                stiffness_mnm_per_rad: k,
                damping_unms_per_rad: d,
                torque_unm: t.saturating_mul(64),
            }),
        (
            proptest::option::of(0u8..=3),
            proptest::option::of(prop_oneof![Just(0u8), Just(253), Just(254), any::<u8>()]),
            proptest::option::of(prop_oneof![Just(0u32), Just(1_000_000), any::<u32>()])
        )
            .prop_map(|(protocol_version, id, baud_bps)| Request::SetBus(
                protocol::BusChange {
                    protocol_version,
                    id,
                    baud_bps
                }
            )),
        any::<bool>().prop_map(|start| Request::Calibrate { start }),
        Just(Request::GetCalibration),
    ]
}

/// The variant index of a request (exhaustive: a new variant breaks this until added).
pub fn request_index(r: &Request) -> u32 {
    match r {
        Request::Ping => 0,
        Request::GetStatus => 1,
        Request::Enable => 2,
        Request::Disable => 3,
        Request::ClearFault => 4,
        Request::SetClutchLength { .. } => 5,
        Request::SetStiffness { .. } => 6,
        Request::Move { .. } => 7,
        Request::Step { .. } => 8,
        Request::Sine { .. } => 9,
        Request::Hold => 10,
        Request::SetGains(_) => 11,
        Request::AutoGains => 12,
        Request::SetLimits(_) => 13,
        Request::StreamTelemetry { .. } => 14,
        Request::Heartbeat => 15,
        Request::DisarmHeartbeat => 16,
        Request::GetLimits => 17,
        Request::GetSensors => 18,
        Request::Nudge { .. } => 19,
        Request::Save => 20,
        Request::Load => 21,
        Request::FactoryReset => 22,
        Request::FaultsLog { .. } => 23,
        Request::Impedance { .. } => 24,
        Request::SetBus(_) => 25,
        Request::Calibrate { .. } => 26,
        Request::GetCalibration => 27,
    }
}

/// The variant index of a reply (exhaustive).
pub fn reply_index(r: &Reply) -> u32 {
    match r {
        Reply::Ok => 0,
        Reply::Error(_) => 1,
        Reply::Status(_) => 2,
        Reply::ClutchToSet { .. } => 3,
        Reply::Telemetry(_) => 4,
        Reply::Limits(_) => 5,
        Reply::FaultPersists(_) => 6,
        Reply::Sensors(_) => 7,
        Reply::FaultsLog { .. } => 8,
        Reply::Calibration(_) => 9,
    }
}

pub fn error_code() -> impl Strategy<Value = ErrorCode> {
    prop::sample::select(vec![
        ErrorCode::BadFrame,
        ErrorCode::BadCrc,
        ErrorCode::UnknownMessage,
        ErrorCode::OutOfRange,
        ErrorCode::NotAllowed,
        ErrorCode::Busy,
        ErrorCode::UnsupportedVersion,
        ErrorCode::Storage,
    ])
}

pub fn fault_code() -> impl Strategy<Value = FaultCode> {
    prop::sample::select(FaultCode::ALL.to_vec())
}

pub fn state() -> impl Strategy<Value = State> {
    prop::sample::select(vec![State::Disabled, State::Enabled, State::Faulted])
}

pub fn status() -> impl Strategy<Value = Status> {
    (
        (
            state(),
            any::<u16>(),
            prop::option::of((fault_code(), any::<i32>(), any::<u32>())),
            any::<u8>(),
            any::<u32>(),
            any::<u32>(),
        ),
        (
            any::<u32>(),
            any::<bool>(),
            any::<u16>(),
            any::<u32>(),
            any::<u32>(),
            any::<bool>(),
        ),
        (calibration_progress(), any::<u16>()),
    )
        .prop_map(
            |(
                (state, faults, first, limits, clutch, k),
                (tick, moving, rate, dropped, errors, differs),
                (calibration, tolerance),
            )| {
                Status {
                    state,
                    faults: FaultSet(faults),
                    first_fault: first.map(|(code, value, tick)| FaultRecord { code, value, tick }),
                    limits: LimitFlags(limits),
                    clutch_length_um: clutch,
                    stiffness_mnm_per_rad: k,
                    clutch_tolerance_um: tolerance,
                    tick,
                    moving,
                    telemetry_rate_hz: rate,
                    telemetry_dropped: dropped,
                    protocol_errors: errors,
                    differs_from_stored: differs,
                    calibration,
                }
            },
        )
}

pub fn calibration_progress() -> impl Strategy<Value = CalibrationProgress> {
    prop_oneof![
        Just(CalibrationProgress::Idle),
        (any::<u8>(), any::<u8>())
            .prop_map(|(phase, percent)| CalibrationProgress::Running { phase, percent }),
        Just(CalibrationProgress::Done),
        any::<u8>().prop_map(|failure| CalibrationProgress::Failed { failure }),
    ]
}

pub fn calibration() -> impl Strategy<Value = Calibration> {
    (
        (
            any::<i8>(),
            any::<i8>(),
            any::<i8>(),
            any::<i16>(),
            any::<i16>(),
        ),
        (any::<u32>(), any::<u32>(), any::<u32>(), any::<u32>()),
        (
            prop::option::of(any::<u32>()),
            prop::option::of(any::<u32>()),
            any::<u16>(),
        ),
    )
        .prop_map(
            |((m, e, p, ci, po), (r, ke, f, j), (k, l, u))| Calibration {
                motor_polarity: m,
                encoder_direction: e,
                pot_direction: p,
                current_offset_counts: ci,
                pot_offset_counts: po,
                resistance_mohm: r,
                back_emf_uv_s_per_rad: ke,
                gear_friction_unm: f,
                link_inertia_kg_mm2: j,
                stiffness_mnm_per_rad: k,
                clutch_length_um: l,
                stiffness_uncertainty_permille: u,
            },
        )
}

pub fn sample() -> impl Strategy<Value = TelemetrySample> {
    (
        (any::<u32>(), any::<i32>(), any::<i32>(), any::<i32>()),
        (
            any::<i16>(),
            any::<i32>(),
            any::<i16>(),
            any::<u16>(),
            any::<u8>(),
        ),
    )
        .prop_map(
            |((tick, r, link, gear), (current_ma, torque_unm, duty_permille, faults, limits))| {
                TelemetrySample {
                    tick,
                    reference_urad: r,
                    link_angle_urad: link,
                    gear_angle_urad: gear,
                    current_ma,
                    torque_unm,
                    duty_permille,
                    faults: FaultSet(faults),
                    limits: LimitFlags(limits),
                }
            },
        )
}

/// Every reply, any field values.
pub fn reply() -> impl Strategy<Value = Reply> {
    prop_oneof![
        Just(Reply::Ok),
        error_code().prop_map(Reply::Error),
        status().prop_map(Reply::Status),
        any::<u32>().prop_map(|length_um| Reply::ClutchToSet { length_um }),
        sample().prop_map(Reply::Telemetry),
        limits().prop_map(Reply::Limits),
        (fault_code(), any::<i32>(), any::<u32>()).prop_map(|(code, value, tick)| {
            Reply::FaultPersists(FaultRecord { code, value, tick })
        }),
        (
            any::<u32>(),
            any::<u16>(),
            prop::option::of(any::<u16>()),
            any::<u16>(),
            prop::option::of(any::<u16>()),
            any::<i16>()
        )
            .prop_map(
                |(tick, link_encoder, gear_pot, current_adc, supply_adc, nudge)| {
                    Reply::Sensors(protocol::RawSensors {
                        tick,
                        link_encoder,
                        gear_pot,
                        current_adc,
                        supply_adc,
                        nudge_duty_permille: nudge,
                    })
                }
            ),
        (
            any::<u8>(),
            prop::option::of((any::<u32>(), fault_code(), any::<i32>(), any::<u32>()))
        )
            .prop_map(|(count, entry)| Reply::FaultsLog {
                count,
                entry: entry.map(|(seq, code, value, tick)| LoggedFault {
                    seq,
                    fault: FaultRecord { code, value, tick }
                }),
            }),
        (
            calibration_progress(),
            prop::option::of(calibration()),
            prop::option::of(any::<u16>())
        )
            .prop_map(|(progress, calibration, tracked)| Reply::Calibration(
                CalibrationReport {
                    progress,
                    calibration,
                    tracked_resistance_permille: tracked,
                }
            )),
    ]
}

// ---------------------------------------------------------------------------------------
// The mock device.

/// One call the handler made.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Call {
    Enable,
    Disable,
    ClearFault,
    SetClutchLength(u32),
    SetStiffness(u32),
    Move(i32, u32),
    Step(i32),
    Sine(u32, u32),
    Hold,
    SetGains(Option<Gains>),
    SetLimits(Limits),
    TelemetryRate(u16),
    Heartbeat,
    DisarmHeartbeat,
    Limits,
    Status,
    RawSensors,
    Nudge(i16, u16),
    Save,
    Load,
    FactoryReset,
    FaultsLog(u8),
    Impedance(i32, u32, u32, i32),
    SetBus(protocol::BusChange),
    Calibrate(bool),
    Calibration,
}

/// A device that records every call and keeps a little state, refusing like the
/// firmware will: motion only when enabled, enable not while faulted, reconfiguration
/// not while moving (Busy), stiffness whose clutch length is outside 1–8 mm (OutOfRange).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MockDevice {
    pub calls: Vec<Call>,
    pub state: State,
    pub faults: FaultSet,
    pub clutch_um: u32,
    pub stiffness_mnm_per_rad: u32,
    pub moving: bool,
    pub gains: Option<Gains>,
    pub limits: Limits,
    pub rate_hz: u16,
    pub heartbeats: u32,
    /// Whether a heartbeat armed the timeout (a disarm ends it).
    pub armed: bool,
    /// Link activity seen while armed.
    pub activity: u32,
    /// What [`Device::persisting_fault`] answers.
    pub persisting: Option<FaultRecord>,
}

impl Default for MockDevice {
    fn default() -> Self {
        MockDevice {
            calls: Vec::new(),
            state: State::Disabled,
            faults: FaultSet::EMPTY,
            clutch_um: 3_000,
            stiffness_mnm_per_rad: stiffness_of(3_000),
            moving: false,
            gains: None,
            limits: Limits::DEFAULT,
            rate_hz: 0,
            heartbeats: 0,
            armed: false,
            activity: 0,
            persisting: None,
        }
    }
}

/// Paper preset, E–B: k(L) = 7167.5 N·m/rad · (1 mm / L)³, in mN·m/rad.
pub fn stiffness_of(length_um: u32) -> u32 {
    let l_mm = f64::from(length_um) / 1000.0;
    (7_167_500.0 / (l_mm * l_mm * l_mm)).round() as u32
}

/// Inverse of [`stiffness_of`], µm.
pub fn clutch_of(stiffness_mnm_per_rad: u32) -> f64 {
    1000.0 * (7_167_500.0 / f64::from(stiffness_mnm_per_rad)).cbrt()
}

impl MockDevice {
    /// A device with a latched fault.
    pub fn faulted() -> Self {
        MockDevice {
            state: State::Faulted,
            faults: FaultSet::EMPTY.with(FaultCode::CommandTimeout),
            ..MockDevice::default()
        }
    }

    fn motion(&mut self) -> Result<(), ErrorCode> {
        if self.state == State::Enabled {
            self.moving = true;
            Ok(())
        } else {
            Err(ErrorCode::NotAllowed)
        }
    }

    fn idle(&self) -> Result<(), ErrorCode> {
        if self.moving {
            Err(ErrorCode::Busy)
        } else {
            Ok(())
        }
    }

    /// The device with its call log cleared (to compare states).
    pub fn without_calls(&self) -> MockDevice {
        MockDevice {
            calls: Vec::new(),
            ..self.clone()
        }
    }
}

impl Device for MockDevice {
    fn enable(&mut self) -> Result<(), ErrorCode> {
        self.calls.push(Call::Enable);
        if self.state == State::Faulted {
            return Err(ErrorCode::NotAllowed);
        }
        self.state = State::Enabled;
        Ok(())
    }

    fn disable(&mut self) -> Result<(), ErrorCode> {
        self.calls.push(Call::Disable);
        if self.state == State::Enabled {
            self.state = State::Disabled;
        }
        self.moving = false;
        Ok(())
    }

    fn clear_fault(&mut self) -> Result<(), ErrorCode> {
        self.calls.push(Call::ClearFault);
        if self.state == State::Faulted {
            self.state = State::Disabled;
        }
        self.faults = FaultSet::EMPTY;
        Ok(())
    }

    fn set_clutch_length(&mut self, length_um: u32) -> Result<(), ErrorCode> {
        self.calls.push(Call::SetClutchLength(length_um));
        self.idle()?;
        self.clutch_um = length_um;
        self.stiffness_mnm_per_rad = stiffness_of(length_um);
        Ok(())
    }

    fn set_stiffness(&mut self, k: u32) -> Result<u32, ErrorCode> {
        self.calls.push(Call::SetStiffness(k));
        self.idle()?;
        let l = clutch_of(k);
        if !(f64::from(CLUTCH_MIN_UM)..=f64::from(CLUTCH_MAX_UM)).contains(&l) {
            return Err(ErrorCode::OutOfRange);
        }
        self.clutch_um = l.round() as u32;
        self.stiffness_mnm_per_rad = k;
        Ok(self.clutch_um)
    }

    fn command_move(&mut self, target_urad: i32, duration_ms: u32) -> Result<(), ErrorCode> {
        self.calls.push(Call::Move(target_urad, duration_ms));
        self.motion()
    }

    fn command_step(&mut self, target_urad: i32) -> Result<(), ErrorCode> {
        self.calls.push(Call::Step(target_urad));
        self.motion()
    }

    fn command_sine(&mut self, amplitude_urad: u32, frequency_mhz: u32) -> Result<(), ErrorCode> {
        self.calls.push(Call::Sine(amplitude_urad, frequency_mhz));
        self.motion()
    }

    fn hold(&mut self) -> Result<(), ErrorCode> {
        self.calls.push(Call::Hold);
        self.moving = false;
        Ok(())
    }

    fn set_gains(&mut self, gains: Option<Gains>) -> Result<(), ErrorCode> {
        self.calls.push(Call::SetGains(gains));
        self.idle()?;
        self.gains = gains;
        Ok(())
    }

    fn set_limits(&mut self, limits: &Limits) -> Result<(), ErrorCode> {
        self.calls.push(Call::SetLimits(*limits));
        self.limits = *limits;
        Ok(())
    }

    fn set_telemetry_rate(&mut self, rate_hz: u16) -> Result<(), ErrorCode> {
        self.calls.push(Call::TelemetryRate(rate_hz));
        self.rate_hz = rate_hz;
        Ok(())
    }

    fn heartbeat(&mut self) {
        self.calls.push(Call::Heartbeat);
        self.heartbeats += 1;
        self.armed = true;
    }

    fn disarm_heartbeat(&mut self) {
        self.calls.push(Call::DisarmHeartbeat);
        self.armed = false;
    }

    fn link_activity(&mut self) {
        if self.armed {
            self.activity += 1;
        }
    }

    fn limits(&mut self) -> Limits {
        self.calls.push(Call::Limits);
        self.limits
    }

    fn impedance(
        &mut self,
        target_urad: i32,
        stiffness_mnm_per_rad: u32,
        damping_unms_per_rad: u32,
        torque_unm: i32,
    ) -> Result<(), ErrorCode> {
        self.calls.push(Call::Impedance(
            target_urad,
            stiffness_mnm_per_rad,
            damping_unms_per_rad,
            torque_unm,
        ));
        if stiffness_mnm_per_rad > self.stiffness_mnm_per_rad {
            return Err(ErrorCode::OutOfRange);
        }
        self.motion()
    }

    fn persisting_fault(&mut self) -> Option<FaultRecord> {
        self.persisting
    }

    fn raw_sensors(&mut self) -> Result<protocol::RawSensors, ErrorCode> {
        self.calls.push(Call::RawSensors);
        Ok(protocol::RawSensors::default())
    }

    fn nudge(&mut self, duty_permille: i16, duration_ms: u16) -> Result<(), ErrorCode> {
        self.calls.push(Call::Nudge(duty_permille, duration_ms));
        if self.state == State::Disabled {
            Ok(())
        } else {
            Err(ErrorCode::NotAllowed)
        }
    }

    fn status(&mut self) -> Status {
        self.calls.push(Call::Status);
        Status {
            state: self.state,
            faults: self.faults,
            first_fault: None,
            limits: LimitFlags::NONE,
            clutch_length_um: self.clutch_um,
            stiffness_mnm_per_rad: self.stiffness_mnm_per_rad,
            clutch_tolerance_um: 0,
            tick: 0,
            moving: self.moving,
            telemetry_rate_hz: self.rate_hz,
            telemetry_dropped: 0,
            // The handler must overwrite this.
            protocol_errors: 0xDEAD,
            differs_from_stored: false,
            calibration: CalibrationProgress::Idle,
        }
    }

    fn save(&mut self) -> Result<(), ErrorCode> {
        self.calls.push(Call::Save);
        Ok(())
    }

    fn load(&mut self) -> Result<(), ErrorCode> {
        self.calls.push(Call::Load);
        Ok(())
    }

    fn factory_reset(&mut self) -> Result<(), ErrorCode> {
        self.calls.push(Call::FactoryReset);
        Ok(())
    }

    fn faults_log(&mut self, index: u8) -> Result<(u8, Option<LoggedFault>), ErrorCode> {
        self.calls.push(Call::FaultsLog(index));
        Ok((0, None))
    }

    fn set_bus(&mut self, change: &protocol::BusChange) -> Result<(), ErrorCode> {
        self.calls.push(Call::SetBus(*change));
        Ok(())
    }
    fn calibrate(&mut self, start: bool) -> Result<(), ErrorCode> {
        self.calls.push(Call::Calibrate(start));
        Ok(())
    }

    fn calibration(&mut self) -> Result<CalibrationReport, ErrorCode> {
        self.calls.push(Call::Calibration);
        Ok(CalibrationReport {
            progress: CalibrationProgress::Idle,
            calibration: None,
            tracked_resistance_permille: None,
        })
    }
}

/// The call a valid request makes (`None` for `Ping`).
pub fn expected_call(r: &Request) -> Option<Call> {
    Some(match *r {
        Request::Ping => return None,
        Request::GetStatus => Call::Status,
        Request::Enable => Call::Enable,
        Request::Disable => Call::Disable,
        Request::ClearFault => Call::ClearFault,
        Request::SetClutchLength { length_um } => Call::SetClutchLength(length_um),
        Request::SetStiffness {
            stiffness_mnm_per_rad,
        } => Call::SetStiffness(stiffness_mnm_per_rad),
        Request::Move {
            target_urad,
            duration_ms,
        } => Call::Move(target_urad, duration_ms),
        Request::Step { target_urad } => Call::Step(target_urad),
        Request::Sine {
            amplitude_urad,
            frequency_mhz,
        } => Call::Sine(amplitude_urad, frequency_mhz),
        Request::Hold => Call::Hold,
        Request::SetGains(g) => Call::SetGains(Some(g)),
        Request::AutoGains => Call::SetGains(None),
        Request::SetLimits(l) => Call::SetLimits(l),
        Request::StreamTelemetry { rate_hz } => Call::TelemetryRate(rate_hz),
        Request::Heartbeat => Call::Heartbeat,
        Request::DisarmHeartbeat => Call::DisarmHeartbeat,
        Request::GetLimits => Call::Limits,
        Request::GetSensors => Call::RawSensors,
        Request::Nudge {
            duty_permille,
            duration_ms,
        } => Call::Nudge(duty_permille, duration_ms),
        Request::Save => Call::Save,
        Request::Load => Call::Load,
        Request::FactoryReset => Call::FactoryReset,
        Request::FaultsLog { index } => Call::FaultsLog(index),
        Request::Impedance {
            target_urad,
            stiffness_mnm_per_rad,
            damping_unms_per_rad,
            torque_unm,
        } => Call::Impedance(
            target_urad,
            stiffness_mnm_per_rad,
            damping_unms_per_rad,
            torque_unm,
        ),
        Request::SetBus(change) => Call::SetBus(change),
        Request::Calibrate { start } => Call::Calibrate(start),
        Request::GetCalibration => Call::Calibration,
    })
}

// ---------------------------------------------------------------------------------------
// Driving the decoder and the handler.

/// A board under test: decoder, handler, mock device.
pub struct Rig {
    pub decoder: Decoder<Request>,
    pub handler: Handler,
    pub device: MockDevice,
}

impl Rig {
    pub fn new(device: MockDevice) -> Self {
        Rig {
            decoder: Decoder::new(),
            handler: Handler::new(),
            device,
        }
    }

    /// Feeds `bytes`; returns every reply, in order.
    pub fn feed(&mut self, bytes: &[u8]) -> Vec<Frame<Reply>> {
        bytes
            .iter()
            .filter_map(|&b| self.handler.feed(&mut self.decoder, b, &mut self.device))
            .collect()
    }
}

/// Encodes a frame into a `Vec` (wire bytes, delimiter included).
pub fn wire<M: protocol::Message>(frame: &Frame<M>) -> Vec<u8> {
    let mut buf = [0u8; protocol::MAX_FRAME];
    let n = protocol::encode(frame, &mut buf).expect("fits MAX_FRAME");
    buf[..n].to_vec()
}

/// Number of non-empty 0x00-delimited chunks in `bytes` that end with a 0x00, plus the
/// trailing unterminated chunk if it overflowed (it was reported already).
pub fn chunks(bytes: &[u8]) -> usize {
    let mut n = 0;
    let mut parts = bytes.split(|&b| b == 0).peekable();
    while let Some(part) = parts.next() {
        let terminated = parts.peek().is_some();
        if !part.is_empty() && (terminated || overflows(part)) {
            n += 1;
        }
    }
    n
}

/// Whether a chunk of COBS bytes decodes to more than `MAX_PAYLOAD` bytes before its end
/// (the decoder reports those as soon as they overflow).
pub fn overflows(chunk: &[u8]) -> bool {
    let mut state = cobs::DecoderState::Idle;
    let mut n = 0usize;
    for &b in chunk {
        match state.feed(b) {
            Ok(cobs::DecodeResult::DataContinue(_)) => {
                n += 1;
                if n > protocol::MAX_PAYLOAD {
                    return true;
                }
            }
            Ok(_) => {}
            Err(_) => return false,
        }
    }
    false
}
