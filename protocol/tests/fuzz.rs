//! Hostile input: the decoder and the handler under proptest-driven fuzzing.
//!
//! Every property runs [`FUZZ_CASES`] (50 000) cases by default; the dedicated long run is
//! `PROPTEST_CASES=1000000 cargo test -p vsa-protocol --release --test fuzz`.
//!
//! Invariants checked on every case: no panic; exactly one reply per non-empty
//! 0x00-delimited chunk (per request); an invalid frame or an out-of-range request is
//! answered with an error, never reaches the device (the mock records every call and its
//! state is compared), and moves exactly one error counter; the decoder recovers at the
//! next 0x00 (a good frame right after is handled).

mod common;

use common::*;
use proptest::prelude::*;
use protocol::{
    encode_raw, Decoder, ErrorCode, ErrorCounters, Frame, Message, Reply, Request, State,
    MAX_FRAME, MAX_PAYLOAD, NO_SEQ, VERSION,
};

/// Independent statement of the documented request ranges (the issue and the crate docs),
/// to check `Request::validate` against.
fn in_range(r: &Request) -> bool {
    // 2.54 rad: inside the gear pot's measurable ±2.613 rad (300° over 1024 counts, 511 from
    // the centre).
    const MEASURABLE_URAD: i64 = 2_540_000;
    let angle = |a: i32| i64::from(a).abs() <= MEASURABLE_URAD;
    match *r {
        Request::SetClutchLength { length_um } => (1_000..=8_000).contains(&length_um),
        Request::SetStiffness {
            stiffness_mnm_per_rad,
        } => stiffness_mnm_per_rad > 0,
        Request::Move {
            target_urad,
            duration_ms,
        } => angle(target_urad) && (1..=60_000).contains(&duration_ms),
        Request::Step { target_urad } => angle(target_urad),
        Request::Sine {
            amplitude_urad,
            frequency_mhz,
        } => amplitude_urad <= 1_000_000 && (10..=20_000).contains(&frequency_mhz),
        Request::SetGains(g) => {
            g.kp <= 1_000_000_000 && g.ki <= 10_000_000_000 && g.kd <= 10_000_000
        }
        Request::SetLimits(l) => {
            (1..=1000).contains(&l.torque_margin_permille)
                && (1..=10_000).contains(&l.current_ma)
                && (1..=100_000_000).contains(&l.motor_torque_unm)
                && (1..=1000).contains(&l.duty_permille)
                && angle(l.position_min_urad)
                && angle(l.position_max_urad)
                && l.position_min_urad < l.position_max_urad
                && l.clutch_tolerance_um <= 5_000
        }
        Request::StreamTelemetry { rate_hz } => rate_hz == 0 || (10..=500).contains(&rate_hz),
        // 0.1 N·m/rad up; 100 N·m·s/rad; ±100 N·m.
        Request::Impedance {
            target_urad,
            stiffness_mnm_per_rad,
            damping_unms_per_rad,
            torque_unm,
        } => {
            angle(target_urad)
                && stiffness_mnm_per_rad >= 100
                && damping_unms_per_rad <= 100_000_000
                && i64::from(torque_unm).abs() <= 100_000_000
        }
        // Protocol 1 or 2, a rate above 0, any ID (the device's check); at least one.
        Request::SetBus(c) => {
            let given = [
                c.protocol_version.is_some(),
                c.id.is_some(),
                c.baud_bps.is_some(),
            ];
            given.contains(&true)
                && c.protocol_version.is_none_or(|v| v == 1 || v == 2)
                && c.baud_bps.is_none_or(|b| b >= 1)
        }
        Request::Ping
        | Request::GetStatus
        | Request::Enable
        | Request::Disable
        | Request::ClearFault
        | Request::Hold
        | Request::AutoGains
        | Request::Heartbeat
        | Request::DisarmHeartbeat
        | Request::GetLimits
        | Request::GetSensors
        | Request::Save
        | Request::Load
        | Request::FactoryReset
        | Request::FaultsLog { .. }
        | Request::Calibrate { .. }
        | Request::GetCalibration => true,
        Request::Nudge {
            duty_permille,
            duration_ms,
        } => {
            (1..=120).contains(&duty_permille.unsigned_abs()) && (1..=1_000).contains(&duration_ms)
        }
    }
}

/// Picks one error counter.
type Counter = fn(&ErrorCounters) -> u32;

/// A device in one of the states that matter for refusals.
fn device() -> impl Strategy<Value = MockDevice> {
    prop_oneof![
        Just(MockDevice::default()),
        Just(MockDevice {
            state: State::Enabled,
            ..MockDevice::default()
        }),
        Just(MockDevice {
            state: State::Enabled,
            moving: true,
            ..MockDevice::default()
        }),
        Just(MockDevice::faulted()),
    ]
}

/// Random bytes: uniform, or with frequent 0x00 (many short chunks), or long runs without
/// 0x00 (overflow).
fn garbage() -> impl Strategy<Value = Vec<u8>> {
    prop_oneof![
        prop::collection::vec(any::<u8>(), 0..200),
        prop::collection::vec(prop_oneof![1 => Just(0u8), 7 => any::<u8>()], 0..200),
        prop::collection::vec(1u8..=255, 0..(3 * MAX_FRAME)),
    ]
}

/// Checks that `replies` are all errors, that the device was not touched, and that the
/// error counters moved by exactly `replies.len()`.
fn assert_only_errors(
    rig: &Rig,
    before: &MockDevice,
    replies: &[Frame<Reply>],
) -> Result<(), TestCaseError> {
    for r in replies {
        prop_assert!(matches!(r.body, Reply::Error(_)), "not an error: {r:?}");
        prop_assert_eq!(r.version, VERSION);
    }
    prop_assert_eq!(&rig.device, before, "the device changed");
    prop_assert_eq!(rig.handler.requests(), 0);
    prop_assert_eq!(rig.handler.errors().frames() as usize, replies.len());
    prop_assert_eq!(rig.handler.errors().total() as usize, replies.len());
    Ok(())
}

/// After whatever came before, the decoder must take a good frame.
fn assert_recovers(rig: &mut Rig, seq: u16) -> Result<(), TestCaseError> {
    let replies = rig.feed(&wire(&Frame::new(seq, Request::Ping)));
    prop_assert_eq!(replies, vec![Frame::new(seq, Reply::Ok)]);
    Ok(())
}

proptest! {
    #![proptest_config(config(FUZZ_CASES))]

    /// Random bytes: one error reply per chunk, nothing reaches the device.
    #[test]
    fn random_bytes(bytes in garbage(), dev in device(), seq in 1u16..) {
        let mut rig = Rig::new(dev.clone());
        let mut input = bytes;
        input.push(0);
        let replies = rig.feed(&input);
        prop_assert_eq!(replies.len(), chunks(&input));
        assert_only_errors(&rig, &dev, &replies)?;
        assert_recovers(&mut rig, seq)?;
    }

    /// The host side: random bytes into a reply decoder give one error per chunk, and a
    /// good reply right after decodes.
    #[test]
    fn reply_decoder_random_bytes(bytes in garbage(), reply in reply(), seq in any::<u16>()) {
        let mut d = Decoder::<Reply>::new();
        let mut input = bytes;
        input.push(0);
        let mut errors = 0;
        for &b in &input {
            match d.feed(b) {
                Ok(None) => {}
                Ok(Some(f)) => return Err(TestCaseError::fail(format!("garbage decoded: {f:?}"))),
                Err(_) => errors += 1,
            }
        }
        prop_assert_eq!(errors, chunks(&input));
        let frame = Frame::new(seq, reply);
        let got: Vec<_> = wire(&frame).iter().filter_map(|&b| d.feed(b).transpose()).collect();
        prop_assert_eq!(got, vec![Ok(frame)]);
    }

    /// A frame cut short (its delimiter arrives early): one error reply, nothing changes;
    /// the next frame is handled.
    #[test]
    fn truncated_frames(req in request(), seq in 1u16.., cut in any::<prop::sample::Index>(),
                        dev in device()) {
        let bytes = wire(&Frame::new(seq, req));
        // Keep 1..len-1 bytes of the frame (without its delimiter), then a 0x00.
        let k = 1 + cut.index(bytes.len() - 2);
        let mut input = bytes[..k].to_vec();
        input.push(0);
        let mut rig = Rig::new(dev.clone());
        let replies = rig.feed(&input);
        prop_assert_eq!(replies.len(), 1);
        prop_assert_eq!(replies[0].seq, NO_SEQ);
        prop_assert!(matches!(replies[0].body,
            Reply::Error(ErrorCode::BadFrame | ErrorCode::BadCrc)), "{:?}", replies[0]);
        assert_only_errors(&rig, &dev, &replies)?;
        // The full frame right after is handled (one reply, its seq).
        let replies = rig.feed(&bytes);
        prop_assert_eq!(replies.len(), 1);
        prop_assert_eq!(replies[0].seq, seq);
    }

    /// A frame whose delimiter was lost merges with the next frame: one error for the
    /// merged chunk, and the frame after that is handled.
    #[test]
    fn lost_delimiter(a in request(), b in request(), seq in 1u16.., dev in device()) {
        let mut input = wire(&Frame::new(seq, a));
        input.pop();
        input.extend(wire(&Frame::new(seq.wrapping_add(1), b)));
        let mut rig = Rig::new(dev.clone());
        let replies = rig.feed(&input);
        prop_assert_eq!(replies.len(), 1);
        assert_only_errors(&rig, &dev, &replies)?;
        assert_recovers(&mut rig, seq)?;
    }

    /// Good frames with 1–4 flipped bits anywhere (delimiter included): one error per
    /// resulting chunk, nothing reaches the device.
    #[test]
    fn flipped_bits(req in request(), seq in 1u16.., dev in device(),
                    flips in prop::collection::vec((any::<prop::sample::Index>(), 0u8..8), 1..=4)) {
        let bytes = wire(&Frame::new(seq, req));
        let mut input = bytes.clone();
        for (i, bit) in &flips {
            input[i.index(bytes.len())] ^= 1 << bit;
        }
        if input == bytes {
            // The flips cancelled out: flip the first one again.
            let (i, bit) = &flips[0];
            input[i.index(bytes.len())] ^= 1 << bit;
        }
        input.push(0);
        let mut rig = Rig::new(dev.clone());
        let replies = rig.feed(&input);
        prop_assert_eq!(replies.len(), chunks(&input));
        prop_assert!(!replies.is_empty());
        assert_only_errors(&rig, &dev, &replies)?;
        assert_recovers(&mut rig, seq)?;
    }

    /// Well-formed frames (good CRC) with any field values: out-of-range ones are answered
    /// `OutOfRange` with their seq and never reach the device; in-range ones make exactly
    /// their one device call. `validate` agrees with the documented ranges.
    #[test]
    fn valid_crc_any_fields(req in request(), seq in any::<u16>(), dev in device()) {
        prop_assert_eq!(req.validate().is_ok(), in_range(&req), "validate vs spec: {:?}", req);
        let mut rig = Rig::new(dev.clone());
        let replies = rig.feed(&wire(&Frame::new(seq, req)));
        prop_assert_eq!(replies.len(), 1);
        let reply = replies[0];
        prop_assert_eq!(reply.seq, seq);
        prop_assert_eq!(rig.handler.requests(), 1);
        prop_assert_eq!(rig.handler.errors().frames(), 0);
        if in_range(&req) {
            prop_assert_eq!(rig.device.calls.clone(), expected_call(&req).into_iter().collect::<Vec<_>>());
            match reply.body {
                Reply::Error(code) => {
                    // A refusal by the device: it changed nothing, and it is counted.
                    prop_assert_eq!(rig.device.without_calls(), dev.without_calls());
                    prop_assert_eq!(rig.handler.errors().total(), 1);
                    prop_assert!(matches!(code,
                        ErrorCode::OutOfRange | ErrorCode::NotAllowed | ErrorCode::Busy));
                }
                Reply::Ok => {
                    let data_reply = matches!(req, Request::GetStatus | Request::SetStiffness { .. } | Request::GetSensors);
                    prop_assert!(!data_reply, "Ok for {:?}", req);
                }
                Reply::Status(s) => {
                    prop_assert_eq!(req, Request::GetStatus);
                    prop_assert_eq!(s.protocol_errors, 0);
                }
                Reply::ClutchToSet { length_um } => {
                    let Request::SetStiffness { stiffness_mnm_per_rad } = req else {
                        return Err(TestCaseError::fail("ClutchToSet for another request"));
                    };
                    prop_assert!((1_000..=8_000).contains(&length_um));
                    prop_assert!((clutch_of(stiffness_mnm_per_rad) - f64::from(length_um)).abs() <= 0.5);
                }
                Reply::Telemetry(_) => return Err(TestCaseError::fail("telemetry as a reply")),
                Reply::Limits(l) => {
                    prop_assert_eq!(req, Request::GetLimits);
                    prop_assert_eq!(l, dev.limits);
                }
                Reply::FaultPersists(_) => {
                    return Err(TestCaseError::fail("the mock never has a persisting fault"))
                }
                Reply::Sensors(r) => {
                    prop_assert_eq!(req, Request::GetSensors);
                    prop_assert_eq!(r, protocol::RawSensors::default());
                }
                Reply::FaultsLog { count, entry } => {
                    let asked = matches!(req, Request::FaultsLog { .. });
                    prop_assert!(asked, "FaultsLog for {:?}", req);
                    prop_assert_eq!((count, entry), (0, None), "the mock's log is empty");
                }
                Reply::Calibration(r) => {
                    prop_assert_eq!(req, Request::GetCalibration);
                    prop_assert_eq!(r.calibration, None, "the mock has no calibration");
                }
            }
        } else {
            prop_assert_eq!(reply.body, Reply::Error(ErrorCode::OutOfRange));
            prop_assert_eq!(&rig.device, &dev, "the device changed");
            prop_assert_eq!(*rig.handler.errors(), ErrorCounters { out_of_range: 1, ..Default::default() });
        }
    }

    /// Good CRC around hostile content: another version, an unknown message index, bytes
    /// after the body, a body cut short, or random bytes after a good header. Each is
    /// answered once, with the frame's seq, by the matching error, and counted once.
    #[test]
    fn valid_crc_bad_content(req in request(), seq in 1u16.., dev in device(),
                             version in any::<u8>(), index in Request::VARIANTS..,
                             tail in prop::collection::vec(any::<u8>(), 0..16),
                             extra in prop::collection::vec(any::<u8>(), 1..8),
                             cut in any::<prop::sample::Index>(), which in 0..5u8) {
        let mut post = [0u8; MAX_PAYLOAD];
        let good = postcard::to_slice(&Frame::new(seq, req), &mut post).unwrap().to_vec();
        let header = postcard::to_slice(&(VERSION, seq), &mut [0u8; 4]).unwrap().to_vec();
        let mut data;
        let expect: Option<(ErrorCode, Counter)>;
        match which {
            0 => {
                data = good.clone();
                data[0] = if version == VERSION { VERSION.wrapping_add(1) } else { version };
                expect = Some((ErrorCode::UnsupportedVersion, |c| c.version));
            }
            1 => {
                data = header.clone();
                data.extend(postcard::to_slice(&index, &mut [0u8; 5]).unwrap().iter());
                data.extend(&tail);
                expect = Some((ErrorCode::UnknownMessage, |c| c.unknown_message));
            }
            2 | 3 => {
                let fields = good.len() - header.len() - 1;
                if which == 3 && fields > 0 {
                    // Drop 1.. bytes of the fields (keep the header and the variant index).
                    data = good[..good.len() - 1 - cut.index(fields)].to_vec();
                } else {
                    // Bytes after the body (also for bodies without fields).
                    data = good.clone();
                    data.extend(&extra);
                }
                expect = Some((ErrorCode::BadFrame, |c| c.decode));
            }
            _ => {
                data = header.clone();
                data.extend(&tail);
                expect = None; // decided by the reference decoder below
            }
        }
        prop_assert!(data.len() + 4 <= MAX_PAYLOAD);
        let mut input = vec![0u8; MAX_FRAME];
        let n = encode_raw(&data, &mut input).unwrap();
        input.truncate(n);
        let mut rig = Rig::new(dev.clone());
        let replies = rig.feed(&input);
        prop_assert_eq!(replies.len(), 1);
        prop_assert_eq!(replies[0].seq, seq);
        match expect {
            Some((code, counter)) => {
                prop_assert_eq!(replies[0].body, Reply::Error(code));
                prop_assert_eq!(counter(rig.handler.errors()), 1);
                assert_only_errors(&rig, &dev, &replies)?;
            }
            None => {
                // Random body: postcard (as a reference) says whether it is a request.
                let body = &data[header.len()..];
                match postcard::take_from_bytes::<Request>(body) {
                    Ok((r, [])) => {
                        prop_assert_eq!(rig.handler.requests(), 1);
                        if !in_range(&r) {
                            prop_assert_eq!(replies[0].body, Reply::Error(ErrorCode::OutOfRange));
                            prop_assert_eq!(&rig.device, &dev);
                        }
                    }
                    _ => {
                        prop_assert!(matches!(replies[0].body,
                            Reply::Error(ErrorCode::BadFrame | ErrorCode::UnknownMessage)));
                        assert_only_errors(&rig, &dev, &replies)?;
                    }
                }
            }
        }
    }

    /// A stream of good frames, garbage chunks and cut frames: exactly one reply per chunk,
    /// in order, each good frame's reply carries its seq, and the device sees exactly the
    /// calls of the good, in-range requests, in order.
    #[test]
    fn mixed_stream(items in prop::collection::vec(prop_oneof![
            3 => (request(), 1u16..).prop_map(|(r, s)| (0u8, s, r, Vec::new())),
            1 => prop::collection::vec(1u8..=255, 1..80).prop_map(|g| (1u8, 0, Request::Ping, g)),
            1 => (request(), 1u16.., 1usize..40).prop_map(|(r, s, k)| (2u8, s, r, vec![k as u8])),
        ], 1..12), dev in device()) {
        let mut rig = Rig::new(dev);
        let mut input = Vec::new();
        let mut expected = Vec::new(); // Some(seq) for a good frame, None for a bad chunk
        for (kind, seq, req, extra) in &items {
            match kind {
                0 => {
                    input.extend(wire(&Frame::new(*seq, *req)));
                    expected.push(Some((*seq, *req)));
                }
                1 => {
                    input.extend(extra);
                    input.push(0);
                    expected.push(None);
                }
                _ => {
                    let bytes = wire(&Frame::new(*seq, *req));
                    let k = usize::from(extra[0]).min(bytes.len() - 2);
                    input.extend(&bytes[..k]);
                    input.push(0);
                    expected.push(None);
                }
            }
        }
        let replies = rig.feed(&input);
        prop_assert_eq!(replies.len(), expected.len());
        let mut calls = Vec::new();
        // A good frame with the seq and request of the last good one is a retry: answered
        // from the reply cache, not carried out or counted again (bad chunks between the
        // two do not matter).
        let mut last = None;
        let mut replays = 0;
        for (reply, exp) in replies.iter().zip(&expected) {
            match exp {
                Some((seq, req)) => {
                    prop_assert_eq!(reply.seq, *seq);
                    let retry = last == Some((*seq, *req));
                    last = Some((*seq, *req));
                    if retry {
                        replays += 1;
                    } else if in_range(req) {
                        calls.extend(expected_call(req));
                    }
                    if !in_range(req) {
                        prop_assert_eq!(reply.body, Reply::Error(ErrorCode::OutOfRange));
                    }
                }
                None => {
                    prop_assert!(matches!(reply.body, Reply::Error(_)));
                }
            }
        }
        prop_assert_eq!(&rig.device.calls, &calls);
        let bad = expected.iter().filter(|e| e.is_none()).count();
        prop_assert_eq!(rig.handler.errors().frames() as usize, bad);
        prop_assert_eq!(rig.handler.requests() as usize, expected.len() - bad - replays);
        prop_assert_eq!(rig.handler.replayed() as usize, replays);
    }
}

#[test]
fn frames_are_bounded_and_message_counts_match() {
    println!("fuzz cases per property: {}", config(FUZZ_CASES).cases);
    assert_eq!(Request::VARIANTS, 28);
    assert_eq!(Reply::VARIANTS, 10);
    const { assert!(MAX_FRAME <= 64, "a frame fits a 64-byte DMA/queue slot") };
}
