//! Round trips of every message through encode → byte-by-byte decode, frame sizes, the
//! CRC choice and a golden frame that pins the wire format.

mod common;

use common::*;
use proptest::prelude::*;
use protocol::{
    decode_payload, encode, encode_telemetry, encode_to_vec, telemetry_frame, Calibration,
    CalibrationProgress, CalibrationReport, Decoder, EncodeError, ErrorCode, FaultCode,
    FaultRecord, FaultSet, Frame, FrameError, Gains, LimitFlags, Limits, LoggedFault, Message,
    Reply, Request, State, Status, TelemetrySample, CRC, MAX_FRAME, MAX_PAYLOAD,
    MAX_TELEMETRY_FRAME, VERSION,
};

/// Decodes `bytes` byte by byte; panics on any error or a frame before the last byte.
fn decode_all<M: Message + std::fmt::Debug + PartialEq>(bytes: &[u8]) -> Frame<M> {
    let mut d = Decoder::<M>::new();
    let (last, init) = bytes.split_last().expect("non-empty");
    for (i, &b) in init.iter().enumerate() {
        assert_eq!(d.feed(b), Ok(None), "byte {i} of {bytes:02x?}");
    }
    assert_eq!(*last, 0, "frame ends with its delimiter");
    let frame = d.feed(*last).expect("decodes").expect("complete");
    assert!(d.is_idle());
    frame
}

fn check_wire(bytes: &[u8], max: usize) {
    assert!(bytes.len() <= max, "{} > {max}", bytes.len());
    assert!(
        !bytes[..bytes.len() - 1].contains(&0),
        "0x00 inside the frame"
    );
}

proptest! {
    #![proptest_config(config(ROUNDTRIP_CASES))]

    #[test]
    fn request_roundtrip(seq in any::<u16>(), req in request()) {
        let frame = Frame::new(seq, req);
        let bytes = wire(&frame);
        check_wire(&bytes, MAX_FRAME);
        prop_assert_eq!(decode_all::<Request>(&bytes), frame);
        // The variant index on the wire is the declaration order.
        let payload = cobs_decode(&bytes);
        let (_, body) = postcard::take_from_bytes::<(u8, u16)>(&payload).unwrap();
        prop_assert_eq!(u32::from(body[0]), request_index(&req));
        prop_assert!(request_index(&req) < Request::VARIANTS);
    }

    #[test]
    fn reply_roundtrip(seq in any::<u16>(), reply in reply()) {
        let frame = Frame::new(seq, reply);
        let bytes = wire(&frame);
        check_wire(&bytes, MAX_FRAME);
        prop_assert_eq!(decode_all::<Reply>(&bytes), frame);
        let payload = cobs_decode(&bytes);
        let (_, body) = postcard::take_from_bytes::<(u8, u16)>(&payload).unwrap();
        prop_assert_eq!(u32::from(body[0]), reply_index(&reply));
        prop_assert!(reply_index(&reply) < Reply::VARIANTS);
        // encode_to_vec gives the same bytes.
        let v = encode_to_vec(&frame).unwrap();
        prop_assert_eq!(v.as_slice(), &bytes[..]);
    }

    #[test]
    fn telemetry_roundtrip(seq in any::<u16>(), s in sample()) {
        let mut buf = [0u8; MAX_TELEMETRY_FRAME];
        let n = encode_telemetry(seq, &s, &mut buf).unwrap();
        check_wire(&buf[..n], MAX_TELEMETRY_FRAME);
        let q = telemetry_frame(seq, &s).unwrap();
        prop_assert_eq!(q.as_slice(), &buf[..n]);
        prop_assert_eq!(decode_all::<Reply>(&buf[..n]), Frame::new(seq, Reply::Telemetry(s)));
    }

    /// A frame whose version is not ours decodes to a version error with its seq, for
    /// every version byte.
    #[test]
    fn other_versions_are_refused(seq in any::<u16>(), version in any::<u8>(), req in request()) {
        prop_assume!(version != VERSION);
        let bytes = wire(&Frame { version, seq, body: req });
        let payload = cobs_decode(&bytes);
        prop_assert_eq!(
            decode_payload::<Request>(&payload),
            Err(FrameError::Version { found: version, seq: Some(seq) })
        );
    }
}

fn cobs_decode(bytes: &[u8]) -> Vec<u8> {
    let mut out = vec![0u8; bytes.len()];
    let n = cobs::decode(&bytes[..bytes.len() - 1], &mut out).expect("COBS");
    out.truncate(n);
    out
}

/// The strategies generate every variant (so the round trips cover every message).
#[test]
fn strategies_cover_every_variant() {
    use proptest::strategy::ValueTree;
    let mut runner = proptest::test_runner::TestRunner::deterministic();
    let mut req = vec![false; Request::VARIANTS as usize];
    let mut rep = vec![false; Reply::VARIANTS as usize];
    for _ in 0..2_000 {
        let r = request().new_tree(&mut runner).unwrap().current();
        req[request_index(&r) as usize] = true;
        let r = reply().new_tree(&mut runner).unwrap().current();
        rep[reply_index(&r) as usize] = true;
    }
    assert!(req.iter().all(|&b| b), "requests not generated: {req:?}");
    assert!(rep.iter().all(|&b| b), "replies not generated: {rep:?}");
}

fn max_gains() -> Gains {
    Gains {
        kp: u64::MAX,
        ki: u64::MAX,
        kd: u64::MAX,
    }
}

/// The largest value of every request and reply variant (every varint at its longest).
fn largest_requests() -> Vec<Request> {
    vec![
        Request::Ping,
        Request::GetStatus,
        Request::Enable,
        Request::Disable,
        Request::ClearFault,
        Request::SetClutchLength {
            length_um: u32::MAX,
        },
        Request::SetStiffness {
            stiffness_mnm_per_rad: u32::MAX,
        },
        Request::Move {
            target_urad: i32::MIN,
            duration_ms: u32::MAX,
        },
        Request::Step {
            target_urad: i32::MIN,
        },
        Request::Sine {
            amplitude_urad: u32::MAX,
            frequency_mhz: u32::MAX,
        },
        Request::Hold,
        Request::SetGains(max_gains()),
        Request::AutoGains,
        Request::SetLimits(Limits {
            torque_margin_permille: u16::MAX,
            current_ma: u16::MAX,
            motor_torque_unm: u32::MAX,
            duty_permille: u16::MAX,
            position_min_urad: i32::MIN,
            position_max_urad: i32::MIN,
            clutch_tolerance_um: u16::MAX,
        }),
        Request::StreamTelemetry { rate_hz: u16::MAX },
        Request::Heartbeat,
        Request::DisarmHeartbeat,
        Request::GetLimits,
        Request::GetSensors,
        Request::Nudge {
            duty_permille: i16::MIN,
            duration_ms: u16::MAX,
        },
        Request::Save,
        Request::Load,
        Request::FactoryReset,
        Request::FaultsLog { index: u8::MAX },
        Request::Impedance {
            target_urad: i32::MIN,
            stiffness_mnm_per_rad: u32::MAX,
            damping_unms_per_rad: u32::MAX,
            torque_unm: i32::MIN,
        },
        Request::SetBus(protocol::BusChange {
            protocol_version: Some(u8::MAX),
            id: Some(u8::MAX),
            baud_bps: Some(u32::MAX),
        }),
        Request::Calibrate { start: true },
        Request::GetCalibration,
    ]
}

fn largest_sample() -> TelemetrySample {
    TelemetrySample {
        tick: u32::MAX,
        reference_urad: i32::MIN,
        link_angle_urad: i32::MIN,
        gear_angle_urad: i32::MIN,
        current_ma: i16::MIN,
        torque_unm: i32::MIN,
        duty_permille: i16::MIN,
        faults: FaultSet(u16::MAX),
        limits: LimitFlags(u8::MAX),
    }
}

fn largest_replies() -> Vec<Reply> {
    vec![
        Reply::Ok,
        Reply::Error(ErrorCode::UnsupportedVersion),
        Reply::Status(Status {
            state: State::Faulted,
            faults: FaultSet(u16::MAX),
            first_fault: Some(FaultRecord {
                code: FaultCode::CommandTimeout,
                value: i32::MIN,
                tick: u32::MAX,
            }),
            limits: LimitFlags(u8::MAX),
            clutch_length_um: u32::MAX,
            stiffness_mnm_per_rad: u32::MAX,
            clutch_tolerance_um: u16::MAX,
            tick: u32::MAX,
            moving: true,
            telemetry_rate_hz: u16::MAX,
            telemetry_dropped: u32::MAX,
            protocol_errors: u32::MAX,
            differs_from_stored: true,
            calibration: CalibrationProgress::Running {
                phase: u8::MAX,
                percent: u8::MAX,
            },
        }),
        Reply::ClutchToSet {
            length_um: u32::MAX,
        },
        Reply::Telemetry(largest_sample()),
        Reply::Limits(Limits {
            torque_margin_permille: u16::MAX,
            current_ma: u16::MAX,
            motor_torque_unm: u32::MAX,
            duty_permille: u16::MAX,
            position_min_urad: i32::MIN,
            position_max_urad: i32::MIN,
            clutch_tolerance_um: u16::MAX,
        }),
        Reply::FaultPersists(FaultRecord {
            code: FaultCode::CommandTimeout,
            value: i32::MIN,
            tick: u32::MAX,
        }),
        Reply::Sensors(protocol::RawSensors {
            tick: u32::MAX,
            link_encoder: u16::MAX,
            gear_pot: Some(u16::MAX),
            current_adc: u16::MAX,
            supply_adc: Some(u16::MAX),
            nudge_duty_permille: i16::MIN,
        }),
        Reply::FaultsLog {
            count: u8::MAX,
            entry: Some(LoggedFault {
                seq: u32::MAX,
                fault: FaultRecord {
                    code: FaultCode::CommandTimeout,
                    value: i32::MIN,
                    tick: u32::MAX,
                },
            }),
        },
        Reply::Calibration(CalibrationReport {
            progress: CalibrationProgress::Running {
                phase: u8::MAX,
                percent: u8::MAX,
            },
            calibration: Some(Calibration {
                motor_polarity: i8::MIN,
                encoder_direction: i8::MIN,
                pot_direction: i8::MIN,
                current_offset_counts: i16::MIN,
                pot_offset_counts: i16::MIN,
                resistance_mohm: u32::MAX,
                back_emf_uv_s_per_rad: u32::MAX,
                gear_friction_unm: u32::MAX,
                link_inertia_kg_mm2: u32::MAX,
                stiffness_mnm_per_rad: Some(u32::MAX),
                clutch_length_um: Some(u32::MAX),
                stiffness_uncertainty_permille: u16::MAX,
            }),
            tracked_resistance_permille: Some(u16::MAX),
        }),
    ]
}

/// The size constants are exact: the largest request and reply fill them, and every
/// variant's largest value fits. Prints the table of sizes (`--nocapture`).
#[test]
fn frame_sizes() {
    let seq = u16::MAX; // longest seq varint
    let mut largest_payload = 0;
    println!(
        "{:<40} {:>8} {:>8}",
        "message (largest values)", "payload", "wire"
    );
    for r in largest_requests() {
        let bytes = wire(&Frame::new(seq, r));
        let payload = cobs_decode(&bytes).len();
        largest_payload = largest_payload.max(payload);
        let name = format!("{r:?}");
        let name = name.split([' ', '(', '{']).next().unwrap().to_string();
        println!("Request::{name:<31} {payload:>8} {:>8}", bytes.len());
        assert!(bytes.len() <= MAX_FRAME);
    }
    assert_eq!(
        largest_payload,
        protocol::MAX_HEADER + protocol::MAX_REQUEST_BODY + 4
    );
    for r in largest_replies() {
        let bytes = wire(&Frame::new(seq, r));
        let payload = cobs_decode(&bytes).len();
        largest_payload = largest_payload.max(payload);
        let name = format!("{r:?}");
        let name = name.split([' ', '(', '{']).next().unwrap().to_string();
        println!("Reply::{name:<33} {payload:>8} {:>8}", bytes.len());
        assert!(bytes.len() <= MAX_FRAME);
    }
    assert_eq!(largest_payload, MAX_PAYLOAD);
    let tele = wire(&Frame::new(seq, Reply::Telemetry(largest_sample())));
    assert_eq!(tele.len(), MAX_TELEMETRY_FRAME);
    assert_eq!(
        wire(&Frame::new(seq, largest_replies()[2])).len(),
        MAX_FRAME,
        "the largest status fills MAX_FRAME exactly"
    );
    // A typical 500 Hz telemetry frame: tick ≈ 10 min, angles ≈ 0.5 rad, 0.3 A, 0.2 N·m.
    let typical = TelemetrySample {
        tick: 600_000,
        reference_urad: 500_000,
        link_angle_urad: 498_000,
        gear_angle_urad: 503_000,
        current_ma: 300,
        torque_unm: 200_000,
        duty_permille: 250,
        faults: FaultSet::EMPTY,
        limits: LimitFlags::NONE,
    };
    let t = telemetry_frame(40_000, &typical).unwrap();
    println!(
        "typical telemetry frame: {} bytes ({} B/s at 500 Hz); MAX_PAYLOAD {MAX_PAYLOAD}, \
         MAX_FRAME {MAX_FRAME}, MAX_TELEMETRY_FRAME {MAX_TELEMETRY_FRAME}",
        t.len(),
        t.len() * 500
    );
    assert!(t.len() <= 32);
    println!(
        "RAM (host layout): Decoder<Request> {} B, Handler {} B, Frame<Request> {} B, \
         Frame<Reply> {} B",
        size_of::<Decoder<Request>>(),
        size_of::<protocol::Handler>(),
        size_of::<Frame<Request>>(),
        size_of::<Frame<Reply>>()
    );
}

#[test]
fn encode_into_small_buffers_fails_cleanly() {
    let frame = Frame::new(1, largest_replies()[2]);
    let full = wire(&frame);
    for n in 0..full.len() {
        let mut buf = vec![0u8; n];
        assert_eq!(
            encode(&frame, &mut buf),
            Err(EncodeError::BufferTooSmall),
            "{n}"
        );
    }
    let mut small = [0u8; MAX_TELEMETRY_FRAME - 1];
    assert_eq!(
        encode_telemetry(u16::MAX, &largest_sample(), &mut small),
        Err(EncodeError::BufferTooSmall)
    );
    assert_eq!(
        protocol::encode_raw(&[1u8; MAX_PAYLOAD - 3], &mut [0u8; 2 * MAX_FRAME]),
        Err(EncodeError::TooLarge)
    );
}

/// A fault code travels as its number (the supervisor's code), and only 1..=9 decode.
#[test]
fn fault_codes_on_the_wire() {
    for code in FaultCode::ALL {
        let mut buf = [0u8; 1];
        assert_eq!(postcard::to_slice(&code, &mut buf).unwrap(), &[code.code()]);
        assert_eq!(FaultCode::from_code(code.code()), Some(code));
        assert_eq!(code.bit(), 1 << code.code());
        assert_eq!(postcard::from_bytes::<FaultCode>(&[code.code()]), Ok(code));
    }
    assert_eq!(
        FaultCode::ALL.map(FaultCode::code),
        [1, 2, 3, 4, 5, 6, 7, 8, 9, 10]
    );
    for bad in [0u8, 11, 255] {
        assert_eq!(FaultCode::from_code(bad), None);
        assert!(postcard::from_bytes::<FaultCode>(&[bad]).is_err());
    }
    // A status whose first fault has code 0 does not decode (good CRC): a Decode error.
    let mut status = largest_replies()[2];
    let Reply::Status(s) = &mut status else {
        unreachable!()
    };
    s.first_fault = Some(FaultRecord {
        code: FaultCode::SensorRead,
        value: 0,
        tick: 0,
    });
    let bytes = wire(&Frame::new(3, status));
    let mut payload = cobs_decode(&bytes);
    let data_len = payload.len() - 4;
    // Layout: version, seq, tag 2, state, faults (3), Some (1), code.
    let at = 1 + 1 + 1 + 1 + 3 + 1;
    assert_eq!(payload[at], 1);
    payload[at] = 0;
    let crc = CRC.checksum(&payload[..data_len]).to_le_bytes();
    payload[data_len..].copy_from_slice(&crc);
    assert_eq!(
        decode_payload::<Reply>(&payload),
        Err(FrameError::Decode { seq: Some(3) })
    );
}

/// CRC-32/ISO-HDLC, the zlib CRC-32.
#[test]
fn crc_is_crc32_iso_hdlc() {
    assert_eq!(CRC.checksum(b"123456789"), 0xCBF4_3926);
}

/// Pins the wire format: a host in any language must produce these bytes.
#[test]
fn golden_frames() {
    // Move to 0.5 rad in 300 ms, seq 258: postcard 01 82 02 07 c0 84 3d ac 02, CRC-32 LE.
    let bytes = wire(&Frame::new(
        258,
        Request::Move {
            target_urad: 500_000,
            duration_ms: 300,
        },
    ));
    let payload = cobs_decode(&bytes);
    assert_eq!(
        &payload[..payload.len() - 4],
        &[0x01, 0x82, 0x02, 0x07, 0xc0, 0x84, 0x3d, 0xac, 0x02]
    );
    let crc = CRC.checksum(&payload[..payload.len() - 4]).to_le_bytes();
    assert_eq!(&payload[payload.len() - 4..], &crc);
    println!("golden Move frame: {bytes:02x?}");
    // Ping, seq 1: postcard 01 01 00.
    let ping = wire(&Frame::new(1, Request::Ping));
    assert_eq!(&cobs_decode(&ping)[..3], &[0x01, 0x01, 0x00]);
    // An Ok reply, seq 1: postcard 01 01 00.
    assert_eq!(
        wire(&Frame::new(1, Reply::Ok)),
        ping,
        "same bytes, other direction"
    );
}

#[test]
fn decoder_is_const_and_resets() {
    static_assertions_like();
    let mut d = Decoder::<Request>::default();
    let bytes = wire(&Frame::new(9, Request::Hold));
    for &b in &bytes[..bytes.len() - 2] {
        assert_eq!(d.feed(b), Ok(None));
    }
    assert!(!d.is_idle());
    d.reset();
    assert!(d.is_idle());
    assert_eq!(decode_all::<Request>(&bytes), Frame::new(9, Request::Hold));
}

fn static_assertions_like() {
    static _D: std::sync::Mutex<Decoder<Request>> = std::sync::Mutex::new(Decoder::new());
    const _H: protocol::Handler = protocol::Handler::new();
}
