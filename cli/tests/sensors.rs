//! `vsa sensors` without firmware: its arguments are checked before anything is sent
//! (exit 2), and a board that does not know the bring-up requests (the in-process fake
//! board, `client::fake`) is reported in one line (exit 1), and so is one that never has a
//! reading (a scripted board answering busy); one with no reading yet is asked again.
//! `cargo xtask test` runs `vsa sensors` against the firmware on both emulated boards.

use std::process::{Command, Output};

use client::fake::FakeBoard;

fn vsa(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_vsa"))
        .args(args)
        .output()
        .expect("run vsa")
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).to_string()
}

#[test]
fn bad_arguments_exit_2_before_connecting() {
    // No board listens on port 9 of this machine: only the argument check can answer.
    for (args, want) in [
        (
            &["--nudge", "20%"][..],
            "sensors --nudge: '20%' is above the nudge's 120‰",
        ),
        (
            &["--nudge", "fast"],
            "sensors --nudge: 'fast' is not a fraction",
        ),
        (
            &["--nudge", "5%", "--nudge-for", "2s"],
            "sensors --nudge-for",
        ),
        (
            &["--rate", "500"],
            "sensors --rate: '500' is not a rate of 1–100",
        ),
        (&["--seconds", "2h"], "sensors --seconds"),
        (
            &["--nudge-for", "1s"],
            "sensors --nudge-for: only applies to --nudge",
        ),
    ] {
        let mut all = vec!["--tcp", "127.0.0.1:9", "sensors"];
        all.extend_from_slice(args);
        let out = vsa(&all);
        let err = text(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{all:?}: {err}");
        assert!(
            out.stdout.is_empty(),
            "{all:?} printed {}",
            text(&out.stdout)
        );
        assert!(err.contains(want), "{all:?}: {err:?} lacks {want:?}");
    }
}

#[test]
fn a_board_without_raw_readings_is_one_error_line() {
    let board = FakeBoard::start().unwrap();
    let addr = board.addr().to_string();
    let out = vsa(&["--tcp", &addr, "sensors", "--seconds", "0.2"]);
    let err = text(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert_eq!(
        err.trim(),
        "error: the board refused get-sensors: not allowed in this state"
    );
}

/// A board serving the protocol on a TCP port that knows only `GetSensors`: it answers
/// the first `busy` of them with [`ErrorCode::Busy`] (its control tick has not run yet),
/// then readings of ticks 1, 2, …
fn board_busy_at_first(busy: usize) -> std::net::SocketAddr {
    use client::protocol::{encode_to_vec, Decoder, ErrorCode, Frame, RawSensors, Reply, Request};
    use std::io::{Read, Write};

    let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = listener.local_addr().unwrap();
    std::thread::spawn(move || {
        let (mut line, _) = listener.accept().unwrap();
        let mut decoder = Decoder::<Request>::new();
        let (mut asked, mut tick) = (0, 0);
        let mut buf = [0u8; 256];
        while let Ok(n @ 1..) = line.read(&mut buf) {
            for &b in &buf[..n] {
                let Ok(Some(frame)) = decoder.feed(b) else {
                    continue;
                };
                asked += 1;
                let body = match frame.body {
                    Request::GetSensors if asked <= busy => Reply::Error(ErrorCode::Busy),
                    Request::GetSensors => {
                        tick += 1;
                        Reply::Sensors(RawSensors {
                            tick,
                            gear_pot: Some(512),
                            current_adc: 2048,
                            ..RawSensors::default()
                        })
                    }
                    _ => Reply::Error(ErrorCode::NotAllowed),
                };
                let reply = encode_to_vec(&Frame::new(frame.seq, body)).unwrap();
                if line.write_all(&reply).is_err() {
                    return;
                }
            }
        }
    });
    addr
}

/// A board whose control tick has not run yet has no reading: `vsa sensors` asks again
/// rather than failing or printing a made-up one.
#[test]
fn a_board_without_a_reading_yet_is_asked_again() {
    let addr = board_busy_at_first(3).to_string();
    let out = vsa(&["--tcp", &addr, "sensors", "--seconds", "0.1"]);
    let (stdout, err) = (text(&out.stdout), text(&out.stderr));
    assert_eq!(out.status.code(), Some(0), "{err}");
    let first = stdout.lines().nth(1).unwrap_or_default();
    assert_eq!(first, "1\t0\t512\t2048\t0\t-", "{stdout}");
}

/// One that never gets a reading is one error line, after a bounded wait.
#[test]
fn a_board_that_never_has_a_reading_is_one_error_line() {
    let addr = board_busy_at_first(usize::MAX).to_string();
    let out = vsa(&["--tcp", &addr, "sensors", "--seconds", "1"]);
    let err = text(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert_eq!(
        err.trim(),
        "error: the board had no reading within 200 ms: has its control loop started?"
    );
    assert_eq!(
        text(&out.stdout),
        "tick\tlink_encoder\tgear_pot\tcurrent_adc\tnudge_permille\tsupply_adc\n"
    );
}

/// A refused nudge says how to get a board that takes one.
#[test]
fn a_refused_nudge_gives_the_way_out() {
    let addr = board_busy_at_first(0).to_string();
    let out = vsa(&[
        "--tcp",
        &addr,
        "sensors",
        "--seconds",
        "0.1",
        "--nudge",
        "5%",
    ]);
    let err = text(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains("(`vsa disable`, `vsa clear`)"), "{err}");
}
