//! The client against the in-process fake board (`client::fake`): request/reply matching,
//! typed helpers, refusals, timeouts, garbage and stale replies on the line, telemetry
//! buffering, heartbeats, and recordings with gaps.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

use client::fake::{Behaviour, FakeBoard};
use client::{
    Client, Error, ErrorCode, FaultCode, Gains, Limits, Request, State, TcpTransport, Transport,
};

fn connect(board: &FakeBoard) -> Client {
    Client::connect_tcp(&board.addr().to_string()).expect("connect to the fake board")
}

#[test]
fn typed_helpers_reach_the_device_in_order() {
    let board = FakeBoard::start().unwrap();
    let mut c = connect(&board);
    c.ping().unwrap();
    let s = c.status().unwrap();
    assert_eq!(s.state, State::Disabled);
    assert_eq!(s.clutch_length_um, 3_000);
    c.set_clutch_length(5_000).unwrap();
    assert_eq!(c.status().unwrap().clutch_length_um, 5_000);
    // k ∝ 1/L³ in the fake: L = 1 mm · (7 167 500 / 250 000)^⅓ = 3.061 mm.
    assert_eq!(c.set_stiffness(250_000).unwrap(), 3_061);
    c.enable().unwrap();
    c.move_to(500_000, 300).unwrap();
    c.step_to(-250_000).unwrap();
    c.sine(200_000, 1_000).unwrap();
    c.hold().unwrap();
    let g = Gains {
        kp: 800_000,
        ki: 2_000_000,
        kd: 20_000,
    };
    c.set_gains(g).unwrap();
    c.auto_gains().unwrap();
    let lim = Limits {
        current_ma: 1_000,
        ..Limits::DEFAULT
    };
    c.set_limits(&lim).unwrap();
    c.heartbeat().unwrap();
    c.disable().unwrap();
    c.clear_fault().unwrap();

    let log = board.shared().device.log.clone();
    assert_eq!(
        log,
        vec![
            Request::Ping,
            Request::GetStatus,
            Request::SetClutchLength { length_um: 5_000 },
            Request::GetStatus,
            Request::SetStiffness {
                stiffness_mnm_per_rad: 250_000
            },
            Request::Enable,
            Request::Move {
                target_urad: 500_000,
                duration_ms: 300
            },
            Request::Step {
                target_urad: -250_000
            },
            Request::Sine {
                amplitude_urad: 200_000,
                frequency_mhz: 1_000
            },
            Request::Hold,
            Request::SetGains(g),
            Request::AutoGains,
            Request::SetLimits(lim),
            Request::Disable,
            Request::ClearFault,
        ]
    );
    assert_eq!(board.shared().device.heartbeats, 1);
    let st = c.stats();
    assert_eq!(st.requests, 16);
    assert_eq!(st.replies, 16);
    assert_eq!(st.bad_frames + st.stale_replies + st.line_errors, 0);
}

#[test]
fn refusals_carry_the_error_code() {
    let board = FakeBoard::start().unwrap();
    let mut c = connect(&board);
    // Not enabled: the device refuses motion.
    match c.move_to(500_000, 300) {
        Err(Error::Refused { request, code }) => {
            assert_eq!(request, "move");
            assert_eq!(code, ErrorCode::NotAllowed);
        }
        other => panic!("{other:?}"),
    }
    // Out of the protocol's range: refused by the handler before the device.
    let e = c.set_clutch_length(9_000).unwrap_err();
    assert!(
        matches!(
            e,
            Error::Refused {
                code: ErrorCode::OutOfRange,
                ..
            }
        ),
        "{e}"
    );
    assert_eq!(
        e.to_string(),
        "the board refused set-clutch-length: value out of range"
    );
    // In range for the protocol, out of the design's range: refused by the device.
    assert!(matches!(
        c.set_stiffness(1),
        Err(Error::Refused {
            code: ErrorCode::OutOfRange,
            ..
        })
    ));
    assert!(matches!(
        c.stream_telemetry(5),
        Err(Error::Refused {
            code: ErrorCode::OutOfRange,
            ..
        })
    ));
    // The line is still in step.
    c.ping().unwrap();
    assert_eq!(c.status().unwrap().protocol_errors, 4);
}

#[test]
fn unanswered_and_late_replies_time_out_and_are_skipped() {
    let board = FakeBoard::start().unwrap();
    board.shared().behaviour.ignore.insert("hold");
    let mut c = connect(&board).with_timeout(Duration::from_millis(150));
    // Without retries (tests/noisy_line.rs has them): each request times out once.
    c.set_retries(0);
    match c.hold() {
        Err(Error::Timeout {
            request,
            timeout,
            line_error: None,
        }) => {
            assert_eq!(request, "hold");
            assert_eq!(timeout, Duration::from_millis(150));
        }
        other => panic!("{other:?}"),
    }
    c.ping().unwrap();

    // A reply that comes after the timeout is stale for the next request.
    board.shared().behaviour.reply_delay = Duration::from_millis(400);
    let e = c.ping().unwrap_err();
    assert!(matches!(e, Error::Timeout { .. }), "{e}");
    board.shared().behaviour.reply_delay = Duration::ZERO;
    c.set_timeout(Duration::from_secs(2));
    // This request's reply follows the late one on the line.
    c.status().unwrap();
    assert_eq!(c.stats().stale_replies, 1);
    c.ping().unwrap();
}

#[test]
fn garbage_and_stale_replies_on_the_line_are_counted_and_skipped() {
    let board = FakeBoard::with_behaviour(Behaviour {
        garbage_before_reply: true,
        stale_before_reply: true,
        ..Behaviour::default()
    })
    .unwrap();
    let mut c = connect(&board);
    for _ in 0..20 {
        c.ping().unwrap();
    }
    assert_eq!(c.status().unwrap().clutch_length_um, 3_000);
    let st = c.stats();
    assert_eq!(st.replies, 21);
    // Two garbage chunks and one stale reply before every reply.
    assert_eq!(st.bad_frames, 42);
    assert_eq!(st.stale_replies, 21);
}

/// A transport that corrupts the next frame it writes when told to.
struct Corrupting {
    inner: TcpTransport,
    armed: Arc<AtomicBool>,
}

impl Transport for Corrupting {
    fn read(&mut self, buf: &mut [u8], wait: Duration) -> std::io::Result<usize> {
        self.inner.read(buf, wait)
    }

    fn write_all(&mut self, bytes: &[u8]) -> std::io::Result<()> {
        let mut b = bytes.to_vec();
        if self.armed.swap(false, Ordering::Relaxed) {
            // b[0] is the first COBS code byte, b[1] the version byte (data, never 0).
            b[1] ^= 0x40;
        }
        self.inner.write_all(&b)
    }

    fn describe(&self) -> String {
        self.inner.describe()
    }
}

#[test]
fn a_request_garbled_on_the_way_times_out_with_the_boards_complaint() {
    let board = FakeBoard::start().unwrap();
    let armed = Arc::new(AtomicBool::new(false));
    let t = TcpTransport::connect(&board.addr().to_string(), Duration::from_secs(1)).unwrap();
    let mut c = Client::new(Corrupting {
        inner: t,
        armed: Arc::clone(&armed),
    })
    .with_timeout(Duration::from_millis(200));
    // Without retries (tests/noisy_line.rs has them): the garbled request times out.
    c.set_retries(0);
    c.ping().unwrap();
    armed.store(true, Ordering::Relaxed);
    let e = c.enable().unwrap_err();
    match &e {
        Error::Timeout {
            request: "enable",
            line_error: Some(ErrorCode::BadCrc),
            ..
        } => {}
        other => panic!("{other:?}"),
    }
    assert!(e.to_string().contains("garbled frame: bad CRC"), "{e}");
    assert_eq!(c.stats().line_errors, 1);
    assert_eq!(c.status().unwrap().state, State::Disabled);
}

#[test]
fn telemetry_is_buffered_while_waiting_for_replies() {
    let board = FakeBoard::start().unwrap();
    let mut c = connect(&board);
    c.stream_telemetry(200).unwrap();
    c.wait(Duration::from_millis(150)).unwrap();
    for _ in 0..5 {
        c.ping().unwrap();
    }
    let t = c.take_telemetry();
    assert!(t.len() >= 10, "{} samples", t.len());
    for w in t.windows(2) {
        assert_eq!(w[1].sample.tick - w[0].sample.tick, 5);
        assert_eq!(w[1].counter, w[0].counter.wrapping_add(1));
    }
    // A bounded buffer: the oldest samples go first.
    c.set_telemetry_capacity(5);
    c.wait(Duration::from_millis(100)).unwrap();
    assert_eq!(c.telemetry_len(), 5);
    assert!(c.stats().telemetry_overflow > 0);
    let next = c.next_telemetry(Duration::from_secs(1)).unwrap().unwrap();
    assert!(next.sample.tick > t.last().unwrap().sample.tick);
    c.stream_telemetry(0).unwrap();
    assert_eq!(c.stats().stale_replies, 0);
}

#[test]
fn heartbeat_mode_keeps_the_board_alive() {
    let board = FakeBoard::start().unwrap();
    // Heartbeats every 20 ms; a longer timeout than the firmware's 100 ms keeps the test
    // steady on a loaded machine.
    board.shared().device.command_timeout_ms = 250;
    let mut c = connect(&board);
    c.set_heartbeat(true);
    c.wait(Duration::from_millis(400)).unwrap();
    c.record(Duration::from_millis(200), 100, |_| {}).unwrap();
    let s = c.status().unwrap();
    assert_eq!(s.state, State::Disabled, "{s:?}");
    assert!(s.faults.is_empty());
    let st = c.stats();
    assert!(st.heartbeats >= 15, "{st:?}");
    assert!(st.heartbeat_acks >= st.heartbeats - 2, "{st:?}");
    assert_eq!(st.stale_replies, 0);
    assert!(board.shared().device.heartbeats >= 15);

    // Heartbeats stop while the client is idle: the board latches command-timeout.
    c.set_heartbeat(false);
    std::thread::sleep(Duration::from_millis(600));
    let s = c.status().unwrap();
    assert_eq!(s.state, State::Faulted);
    assert!(s.faults.contains(FaultCode::CommandTimeout));
    assert_eq!(s.first_fault.unwrap().code, FaultCode::CommandTimeout);
    assert!(matches!(
        c.enable(),
        Err(Error::Refused {
            code: ErrorCode::NotAllowed,
            ..
        })
    ));
    c.clear_fault().unwrap();
    c.enable().unwrap();
}

#[test]
fn record_collects_the_span_and_stops_streaming() {
    let board = FakeBoard::start().unwrap();
    let mut c = connect(&board);
    let mut last = None;
    let rec = c
        .record(Duration::from_millis(500), 100, |p| last = Some(*p))
        .unwrap();
    assert_eq!(rec.samples.len(), 50);
    assert_eq!(rec.expected_samples(), 50);
    let t0 = rec.samples[0].tick;
    for (i, s) in rec.samples.iter().enumerate() {
        assert_eq!(s.tick, t0 + 10 * i as u32);
    }
    assert!(rec.gaps.is_empty());
    assert_eq!(
        (rec.missing_samples, rec.counter_skipped, rec.dropped),
        (0, 0, 0)
    );
    let p = last.unwrap();
    assert_eq!((p.ticks_done, p.ticks_total, p.samples), (500, 500, 50));
    // Streaming is off and nothing more arrives.
    assert_eq!(c.status().unwrap().telemetry_rate_hz, 0);
    c.wait(Duration::from_millis(50)).unwrap();
    assert_eq!(c.telemetry_len(), 0);
}

#[test]
fn record_reports_dropped_and_lost_samples() {
    let board = FakeBoard::with_behaviour(Behaviour {
        drop_every: 10,
        corrupt_every: 7,
        ..Behaviour::default()
    })
    .unwrap();
    let mut c = connect(&board);
    let rec = c.record(Duration::from_secs(1), 250, |_| {}).unwrap();
    // 250 samples due; every 10th dropped at the board, every 7th (of the rest) lost.
    let got = rec.samples.len() as u64;
    assert!((180..=220).contains(&got), "{got} samples, {:?}", rec.gaps);
    // With the missing ones, the samples reach the end of the span (and a little past it
    // when samples were missing right at its end).
    let covered = got + rec.missing_samples;
    assert!((250..=260).contains(&covered), "{covered}: {rec:?}");
    assert_eq!(rec.missing_samples, rec.counter_skipped);
    assert!(rec.dropped >= 20, "{}", rec.dropped);
    assert_eq!(rec.dropped_total, board.shared().device.telemetry_dropped);
    assert!(rec.bad_frames >= 25, "{}", rec.bad_frames);
    for g in &rec.gaps {
        assert_eq!(g.before_tick - g.after_tick, 4 * (g.missing + 1));
    }
}

#[test]
fn record_rejects_bad_arguments_and_silent_boards() {
    let board = FakeBoard::start().unwrap();
    let mut c = connect(&board).with_timeout(Duration::from_millis(200));
    assert!(matches!(
        c.record(Duration::from_secs(1), 5, |_| {}),
        Err(Error::InvalidArgument(_))
    ));
    assert!(matches!(
        c.record(Duration::ZERO, 100, |_| {}),
        Err(Error::InvalidArgument(_))
    ));
    // A board that accepts the stream but never sends: no telemetry.
    board.shared().behaviour.drop_every = 1;
    let e = c.record(Duration::from_secs(1), 100, |_| {}).unwrap_err();
    assert!(matches!(e, Error::NoTelemetry { .. }), "{e}");
    assert_eq!(c.status().unwrap().telemetry_rate_hz, 0);
}

#[test]
fn wait_ready_and_a_closed_connection() {
    let board = FakeBoard::start().unwrap();
    let mut c = connect(&board);
    c.wait_ready(Duration::from_secs(2), Duration::from_millis(50))
        .unwrap();
    drop(board);
    let e = c.ping().unwrap_err();
    assert!(matches!(e, Error::Io { .. }), "{e}");
}

#[test]
fn a_clear_that_cannot_hold_reports_the_condition_and_the_window() {
    let board = FakeBoard::start().unwrap();
    let mut c = connect(&board);
    c.enable().unwrap();
    c.move_to(500_000, 100).unwrap();
    let narrow = Limits {
        position_max_urad: 100_000,
        ..Limits::DEFAULT
    };
    c.set_limits(&narrow).unwrap();
    c.wait(Duration::from_millis(20)).unwrap();
    assert_eq!(c.status().unwrap().state, State::Faulted);
    match c.clear_fault() {
        Err(Error::FaultPersists { record, limits }) => {
            assert_eq!(record.code, FaultCode::PositionLimit);
            assert_eq!(record.value, 499_880);
            assert_eq!(limits, Some(narrow));
        }
        other => panic!("{other:?}"),
    }
    assert_eq!(c.limits().unwrap(), narrow);
    c.set_limits(&Limits::DEFAULT).unwrap();
    c.clear_fault().unwrap();
    c.enable().unwrap();
}

#[test]
fn an_explicit_disarm_ends_the_heartbeat_session() {
    let board = FakeBoard::start().unwrap();
    let mut c = connect(&board);
    c.set_heartbeat(true);
    c.wait(Duration::from_millis(100)).unwrap();
    assert!(board.shared().device.last_heartbeat.is_some());
    c.disarm_heartbeat().unwrap();
    assert!(!c.heartbeat_enabled());
    assert_eq!(board.shared().device.last_heartbeat, None);
    std::thread::sleep(Duration::from_millis(400));
    assert!(c.status().unwrap().faults.is_empty());
}

#[test]
fn a_recording_names_the_faults_seen_in_it() {
    let board = FakeBoard::start().unwrap();
    let mut c = connect(&board);
    c.enable().unwrap();
    c.move_to(500_000, 100).unwrap();
    let b = &board;
    let rec = std::thread::scope(|s| {
        s.spawn(|| {
            std::thread::sleep(Duration::from_millis(100));
            b.shared().device.limits.position_max_urad = 100_000;
        });
        c.record(Duration::from_millis(300), 100, |_| {}).unwrap()
    });
    assert!(rec.faults_before.is_empty());
    assert!(rec.new_faults().contains(FaultCode::PositionLimit));
    assert_eq!(
        rec.first_fault_after.map(|f| f.code),
        Some(FaultCode::PositionLimit)
    );
    assert!(rec
        .samples
        .iter()
        .any(|s| s.faults.contains(FaultCode::PositionLimit)));
}
