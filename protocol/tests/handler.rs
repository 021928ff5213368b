//! The command handler and the decoder on hand-made inputs: every request's reply, device
//! refusals, range boundaries, each kind of bad frame and its counter, overflow and resync.

mod common;

use common::*;
use protocol::{
    encode_raw, Decoder, ErrorCode, ErrorCounters, FaultCode, Frame, FrameError, Gains, Handler,
    Limits, Reply, Request, State, MAX_FRAME, MAX_PAYLOAD, NO_SEQ, VERSION,
};

fn send(rig: &mut Rig, seq: u16, req: Request) -> Frame<Reply> {
    let replies = rig.feed(&wire(&Frame::new(seq, req)));
    assert_eq!(replies.len(), 1, "{req:?}: {replies:?}");
    assert_eq!(replies[0].seq, seq);
    replies[0]
}

#[test]
fn a_session() {
    let mut rig = Rig::new(MockDevice::default());
    assert_eq!(send(&mut rig, 1, Request::Ping).body, Reply::Ok);
    assert!(rig.device.calls.is_empty(), "ping touches nothing");

    // Motion before enable is refused by the device and counted.
    let r = send(
        &mut rig,
        2,
        Request::Move {
            target_urad: 500_000,
            duration_ms: 300,
        },
    );
    assert_eq!(r.body, Reply::Error(ErrorCode::NotAllowed));
    assert_eq!(rig.handler.errors().not_allowed, 1);

    assert_eq!(send(&mut rig, 3, Request::Enable).body, Reply::Ok);
    assert_eq!(rig.device.state, State::Enabled);
    let r = send(
        &mut rig,
        4,
        Request::SetStiffness {
            stiffness_mnm_per_rad: 265_463,
        },
    );
    assert_eq!(r.body, Reply::ClutchToSet { length_um: 3_000 });
    let r = send(
        &mut rig,
        5,
        Request::Move {
            target_urad: 500_000,
            duration_ms: 300,
        },
    );
    assert_eq!(r.body, Reply::Ok);
    // Reconfiguring during the motion: busy.
    let r = send(&mut rig, 6, Request::SetClutchLength { length_um: 4_000 });
    assert_eq!(r.body, Reply::Error(ErrorCode::Busy));
    assert_eq!(send(&mut rig, 7, Request::Hold).body, Reply::Ok);
    assert_eq!(
        send(&mut rig, 8, Request::SetClutchLength { length_um: 4_000 }).body,
        Reply::Ok
    );
    // A stiffness whose clutch length is beyond 8 mm: the device refuses.
    let r = send(
        &mut rig,
        9,
        Request::SetStiffness {
            stiffness_mnm_per_rad: 1_000,
        },
    );
    assert_eq!(r.body, Reply::Error(ErrorCode::OutOfRange));
    assert_eq!(
        send(&mut rig, 10, Request::Step { target_urad: -100 }).body,
        Reply::Ok
    );
    assert_eq!(
        send(
            &mut rig,
            11,
            Request::Sine {
                amplitude_urad: 100_000,
                frequency_mhz: 2_000
            }
        )
        .body,
        Reply::Ok
    );
    let g = Gains {
        kp: 5_000_000,
        ki: 1_000,
        kd: 20,
    };
    assert_eq!(send(&mut rig, 12, Request::Hold).body, Reply::Ok);
    assert_eq!(send(&mut rig, 13, Request::SetGains(g)).body, Reply::Ok);
    assert_eq!(send(&mut rig, 14, Request::AutoGains).body, Reply::Ok);
    assert_eq!(
        send(&mut rig, 15, Request::SetLimits(Limits::DEFAULT)).body,
        Reply::Ok
    );
    assert_eq!(
        send(&mut rig, 16, Request::StreamTelemetry { rate_hz: 500 }).body,
        Reply::Ok
    );
    assert_eq!(send(&mut rig, 17, Request::Heartbeat).body, Reply::Ok);
    assert_eq!(send(&mut rig, 18, Request::Disable).body, Reply::Ok);

    // Garbage in between: counted, reported in the status.
    let replies = rig.feed(&[0x55, 0x13, 0x00, 0x00, 0x01, 0x00]);
    assert_eq!(replies.len(), 2);
    let Reply::Status(s) = send(&mut rig, 19, Request::GetStatus).body else {
        panic!("status expected");
    };
    assert_eq!(s.state, State::Disabled);
    assert_eq!(s.clutch_length_um, 4_000);
    assert_eq!(s.telemetry_rate_hz, 500);
    assert_eq!(s.protocol_errors, rig.handler.errors().total());
    assert_eq!(
        *rig.handler.errors(),
        ErrorCounters {
            not_allowed: 1,
            busy: 1,
            out_of_range: 1,
            cobs: 1,
            truncated: 1,
            ..Default::default()
        }
    );
    assert_eq!(rig.handler.requests(), 19);
    assert_eq!(
        rig.device.calls,
        vec![
            Call::Move(500_000, 300),
            Call::Enable,
            Call::SetStiffness(265_463),
            Call::Move(500_000, 300),
            Call::SetClutchLength(4_000),
            Call::Hold,
            Call::SetClutchLength(4_000),
            Call::SetStiffness(1_000),
            Call::Step(-100),
            Call::Sine(100_000, 2_000),
            Call::Hold,
            Call::SetGains(Some(g)),
            Call::SetGains(None),
            Call::SetLimits(Limits::DEFAULT),
            Call::TelemetryRate(500),
            Call::Heartbeat,
            Call::Disable,
            Call::Status,
        ]
    );
}

#[test]
fn a_persisting_fault_is_not_cleared_and_says_why() {
    let mut rig = Rig::new(MockDevice::faulted());
    let now = protocol::FaultRecord {
        code: FaultCode::PositionLimit,
        value: 2_640_000,
        tick: 99,
    };
    rig.device.persisting = Some(now);
    assert_eq!(
        send(&mut rig, 1, Request::ClearFault).body,
        Reply::FaultPersists(now)
    );
    assert_eq!(rig.device.state, State::Faulted, "nothing cleared");
    assert!(rig.device.calls.is_empty(), "clear_fault was not called");
    rig.device.persisting = None;
    assert_eq!(send(&mut rig, 2, Request::ClearFault).body, Reply::Ok);
    assert_eq!(rig.device.state, State::Disabled);
    assert_eq!(
        send(&mut rig, 3, Request::GetLimits).body,
        Reply::Limits(Limits::DEFAULT)
    );
}

#[test]
fn every_valid_request_is_link_activity_once_armed_and_a_disarm_ends_it() {
    let mut rig = Rig::new(MockDevice::default());
    send(&mut rig, 1, Request::GetStatus);
    assert_eq!(rig.device.activity, 0, "not armed yet");
    send(&mut rig, 2, Request::Heartbeat);
    send(&mut rig, 3, Request::GetStatus);
    send(&mut rig, 4, Request::Ping);
    // Refused by the device, still proof that the host is there.
    send(&mut rig, 5, Request::Enable);
    send(
        &mut rig,
        6,
        Request::Move {
            target_urad: 0,
            duration_ms: 1,
        },
    );
    assert_eq!(rig.device.activity, 4, "status, ping, enable, move");
    // Out of range or garbled: not activity.
    send(
        &mut rig,
        7,
        Request::Move {
            target_urad: 9_000_000,
            duration_ms: 1,
        },
    );
    rig.feed(&[0x55, 0x13, 0x00]);
    assert_eq!(rig.device.activity, 4);
    assert_eq!(send(&mut rig, 8, Request::DisarmHeartbeat).body, Reply::Ok);
    assert!(!rig.device.armed);
    send(&mut rig, 9, Request::Ping);
    assert_eq!(
        rig.device.activity, 5,
        "the disarm itself counted, nothing after"
    );
}

#[test]
fn faults_block_enable_until_cleared() {
    let mut rig = Rig::new(MockDevice::faulted());
    assert_eq!(
        send(&mut rig, 1, Request::Enable).body,
        Reply::Error(ErrorCode::NotAllowed)
    );
    let Reply::Status(s) = send(&mut rig, 2, Request::GetStatus).body else {
        panic!()
    };
    assert_eq!(s.state, State::Faulted);
    assert!(s.faults.contains(FaultCode::CommandTimeout));
    assert_eq!(s.protocol_errors, 1);
    assert_eq!(send(&mut rig, 3, Request::ClearFault).body, Reply::Ok);
    assert_eq!(send(&mut rig, 4, Request::Enable).body, Reply::Ok);
}

/// Each documented range, just inside and just outside.
#[test]
fn range_boundaries() {
    use Request as R;
    let ok = |r: R| assert_eq!(r.validate(), Ok(()), "{r:?}");
    let bad = |r: R| assert_eq!(r.validate(), Err(ErrorCode::OutOfRange), "{r:?}");
    ok(R::SetClutchLength { length_um: 1_000 });
    ok(R::SetClutchLength { length_um: 8_000 });
    bad(R::SetClutchLength { length_um: 999 });
    bad(R::SetClutchLength { length_um: 8_001 });
    ok(R::SetStiffness {
        stiffness_mnm_per_rad: 1,
    });
    ok(R::SetStiffness {
        stiffness_mnm_per_rad: u32::MAX,
    });
    bad(R::SetStiffness {
        stiffness_mnm_per_rad: 0,
    });
    ok(R::Move {
        target_urad: 2_540_000,
        duration_ms: 1,
    });
    ok(R::Move {
        target_urad: -2_540_000,
        duration_ms: 60_000,
    });
    bad(R::Move {
        target_urad: 2_550_001,
        duration_ms: 1,
    });
    bad(R::Move {
        target_urad: i32::MIN,
        duration_ms: 1,
    });
    bad(R::Move {
        target_urad: 0,
        duration_ms: 0,
    });
    bad(R::Move {
        target_urad: 0,
        duration_ms: 60_001,
    });
    ok(R::Step {
        target_urad: -2_540_000,
    });
    bad(R::Step {
        target_urad: -2_550_001,
    });
    ok(R::Sine {
        amplitude_urad: 0,
        frequency_mhz: 10,
    });
    ok(R::Sine {
        amplitude_urad: 1_000_000,
        frequency_mhz: 20_000,
    });
    bad(R::Sine {
        amplitude_urad: 1_000_001,
        frequency_mhz: 1_000,
    });
    bad(R::Sine {
        amplitude_urad: 1,
        frequency_mhz: 9,
    });
    bad(R::Sine {
        amplitude_urad: 1,
        frequency_mhz: 20_001,
    });
    let g = Gains {
        kp: 1_000_000_000,
        ki: 10_000_000_000,
        kd: 10_000_000,
    };
    ok(R::SetGains(g));
    ok(R::SetGains(Gains::default()));
    bad(R::SetGains(Gains { kp: g.kp + 1, ..g }));
    bad(R::SetGains(Gains { ki: g.ki + 1, ..g }));
    bad(R::SetGains(Gains { kd: g.kd + 1, ..g }));
    let l = Limits::DEFAULT;
    ok(R::SetLimits(l));
    bad(R::SetLimits(Limits {
        torque_margin_permille: 0,
        ..l
    }));
    bad(R::SetLimits(Limits {
        torque_margin_permille: 1_001,
        ..l
    }));
    bad(R::SetLimits(Limits { current_ma: 0, ..l }));
    bad(R::SetLimits(Limits {
        current_ma: 10_001,
        ..l
    }));
    bad(R::SetLimits(Limits {
        motor_torque_unm: 0,
        ..l
    }));
    bad(R::SetLimits(Limits {
        motor_torque_unm: 100_000_001,
        ..l
    }));
    bad(R::SetLimits(Limits {
        duty_permille: 0,
        ..l
    }));
    bad(R::SetLimits(Limits {
        duty_permille: 1_001,
        ..l
    }));
    ok(R::SetLimits(Limits {
        clutch_tolerance_um: 5_000,
        ..l
    }));
    bad(R::SetLimits(Limits {
        clutch_tolerance_um: 5_001,
        ..l
    }));
    bad(R::SetLimits(Limits {
        position_min_urad: 1,
        position_max_urad: 1,
        ..l
    }));
    bad(R::SetLimits(Limits {
        position_min_urad: -2_550_001,
        ..l
    }));
    bad(R::SetLimits(Limits {
        position_max_urad: 2_550_001,
        ..l
    }));
    for rate_hz in [0, 10, 250, 500] {
        ok(R::StreamTelemetry { rate_hz });
    }
    for rate_hz in [1, 9, 501, u16::MAX] {
        bad(R::StreamTelemetry { rate_hz });
    }
}

/// One bad frame of each kind: its error reply, its seq convention, its counter.
#[test]
fn each_bad_frame_kind() {
    let mut rig = Rig::new(MockDevice::default());
    let before = rig.device.clone();

    // COBS: a block that claims 5 bytes but ends after 2.
    assert_eq!(
        rig.feed(&[0x05, 0x11, 0x22, 0x00]),
        vec![Frame::new(NO_SEQ, Reply::Error(ErrorCode::BadFrame))]
    );
    // Truncated: 3 decoded bytes.
    assert_eq!(
        rig.feed(&[0x04, 1, 2, 3, 0x00]),
        vec![Frame::new(NO_SEQ, Reply::Error(ErrorCode::BadFrame))]
    );
    // CRC: a good frame with one payload byte changed (and re-stuffed).
    let mut w = wire(&Frame::new(77, Request::Enable));
    w[2] ^= 0x40;
    assert_eq!(
        rig.feed(&w),
        vec![Frame::new(NO_SEQ, Reply::Error(ErrorCode::BadCrc))]
    );
    // Version: echoes the seq.
    let w = wire(&Frame {
        version: 2,
        seq: 78,
        body: Request::Enable,
    });
    assert_eq!(
        rig.feed(&w),
        vec![Frame::new(78, Reply::Error(ErrorCode::UnsupportedVersion))]
    );
    // The first unknown message index with a good CRC: echoes the seq.
    let mut w = [0u8; MAX_FRAME];
    let unknown = <Request as protocol::Message>::VARIANTS as u8;
    let n = encode_raw(&[VERSION, 79, unknown], &mut w).unwrap();
    assert_eq!(
        rig.feed(&w[..n]),
        vec![Frame::new(79, Reply::Error(ErrorCode::UnknownMessage))]
    );
    // Decode: SetClutchLength whose u32 varint never ends.
    let n = encode_raw(
        &[VERSION, 80, 5, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff],
        &mut w,
    )
    .unwrap();
    assert_eq!(
        rig.feed(&w[..n]),
        vec![Frame::new(80, Reply::Error(ErrorCode::BadFrame))]
    );
    // Header that does not decode (seq varint runs into the CRC): no seq to echo.
    let n = encode_raw(&[VERSION, 0xff], &mut w).unwrap();
    assert_eq!(
        rig.feed(&w[..n]),
        vec![Frame::new(NO_SEQ, Reply::Error(ErrorCode::BadFrame))]
    );
    // Overflow: reported once, as soon as it overflows.
    let long = vec![0x42u8; 3 * MAX_FRAME];
    let replies = rig.feed(&long);
    assert_eq!(
        replies,
        vec![Frame::new(NO_SEQ, Reply::Error(ErrorCode::BadFrame))]
    );
    assert!(
        rig.feed(&[0x00]).is_empty(),
        "no second error at the delimiter"
    );
    // Out of range: echoes the seq.
    let r = send(&mut rig, 81, Request::StreamTelemetry { rate_hz: 5 });
    assert_eq!(r.body, Reply::Error(ErrorCode::OutOfRange));

    assert_eq!(rig.device, before, "nothing reached the device");
    assert_eq!(
        *rig.handler.errors(),
        ErrorCounters {
            overflow: 1,
            cobs: 1,
            truncated: 1,
            crc: 1,
            version: 1,
            unknown_message: 1,
            decode: 2,
            out_of_range: 1,
            not_allowed: 0,
            busy: 0,
            other: 0,
        }
    );
    // Empty frames are ignored, and the decoder takes the next good frame.
    assert!(rig.feed(&[0, 0, 0, 0]).is_empty());
    assert_eq!(send(&mut rig, 82, Request::Ping).body, Reply::Ok);
}

/// The overflow boundary is exactly MAX_PAYLOAD decoded bytes.
#[test]
fn overflow_boundary() {
    let mut d = Decoder::<Request>::new();
    // MAX_PAYLOAD bytes of 0x42: COBS block code MAX_PAYLOAD + 1, then the bytes.
    let mut w = vec![(MAX_PAYLOAD + 1) as u8];
    w.extend(std::iter::repeat_n(0x42, MAX_PAYLOAD));
    for &b in &w {
        assert_eq!(d.feed(b), Ok(None));
    }
    assert_eq!(
        d.feed(0),
        Err(FrameError::Crc),
        "fits: checked, not overflowed"
    );
    let mut w = vec![(MAX_PAYLOAD + 2) as u8];
    w.extend(std::iter::repeat_n(0x42, MAX_PAYLOAD + 1));
    let results: Vec<_> = w.iter().map(|&b| d.feed(b)).collect();
    assert_eq!(results.last(), Some(&Err(FrameError::Overflow)));
    assert!(results[..results.len() - 1].iter().all(|r| *r == Ok(None)));
    assert_eq!(d.feed(0), Ok(None));
    assert!(d.is_idle());
}

#[test]
fn handle_request_rejects_foreign_versions_without_the_device() {
    let mut h = Handler::new();
    let mut dev = MockDevice::default();
    let reply = h.handle_request(
        Frame {
            version: 9,
            seq: 5,
            body: Request::Enable,
        },
        &mut dev,
    );
    assert_eq!(
        reply,
        Frame::new(5, Reply::Error(ErrorCode::UnsupportedVersion))
    );
    assert!(dev.calls.is_empty());
    assert_eq!(h.errors().version, 1);
    // handle() dispatches both ways.
    let reply = h.handle(Err(FrameError::Crc), &mut dev);
    assert_eq!(reply, Frame::new(NO_SEQ, Reply::Error(ErrorCode::BadCrc)));
    let reply = h.handle(Ok(Frame::new(6, Request::Enable)), &mut dev);
    assert_eq!(reply, Frame::new(6, Reply::Ok));
    assert_eq!(dev.calls, vec![Call::Enable]);
}

#[test]
fn frame_error_replies() {
    let cases = [
        (FrameError::Overflow, NO_SEQ, ErrorCode::BadFrame),
        (FrameError::Cobs, NO_SEQ, ErrorCode::BadFrame),
        (FrameError::Truncated, NO_SEQ, ErrorCode::BadFrame),
        (FrameError::Crc, NO_SEQ, ErrorCode::BadCrc),
        (
            FrameError::Version {
                found: 3,
                seq: None,
            },
            NO_SEQ,
            ErrorCode::UnsupportedVersion,
        ),
        (
            FrameError::Version {
                found: 3,
                seq: Some(4),
            },
            4,
            ErrorCode::UnsupportedVersion,
        ),
        (
            FrameError::UnknownMessage { seq: 5, index: 99 },
            5,
            ErrorCode::UnknownMessage,
        ),
        (
            FrameError::Decode { seq: None },
            NO_SEQ,
            ErrorCode::BadFrame,
        ),
        (FrameError::Decode { seq: Some(6) }, 6, ErrorCode::BadFrame),
    ];
    for (e, seq, code) in cases {
        assert_eq!(e.reply(), Frame::new(seq, Reply::Error(code)), "{e}");
    }
}

#[test]
fn a_retried_request_is_answered_from_the_cache_and_carried_out_once() {
    let mut rig = Rig::new(MockDevice::default());
    let first = send(&mut rig, 5, Request::Enable);
    assert_eq!(first.body, Reply::Ok);
    let calls = rig.device.calls.len();
    // The host got no reply (the line ate it) and sends the same frame again.
    assert_eq!(send(&mut rig, 5, Request::Enable), first);
    assert_eq!(rig.device.calls.len(), calls, "not carried out twice");
    assert_eq!(rig.handler.replayed(), 1);
    assert_eq!(rig.handler.requests(), 1);
    // The same seq with another request (a wrapped counter) is carried out.
    assert_eq!(send(&mut rig, 5, Request::Disable).body, Reply::Ok);
    assert_eq!(rig.device.state, State::Disabled);
    // A refusal is replayed as well, without counting a second refusal.
    let r = send(&mut rig, 6, Request::SetClutchLength { length_um: 1 });
    assert_eq!(r.body, Reply::Error(ErrorCode::OutOfRange));
    assert_eq!(
        send(&mut rig, 6, Request::SetClutchLength { length_um: 1 }),
        r
    );
    assert_eq!(rig.handler.errors().out_of_range, 1);
}
