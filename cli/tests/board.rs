//! The board commands of `vsa` end to end: connection and argument errors (exit 2, nothing
//! sent), and whole sessions against the in-process fake board (`client::fake`) over
//! `--tcp`. No firmware needed.

use std::process::{Command, Output};

use client::fake::FakeBoard;
use client::{Request, State};

fn vsa(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_vsa"))
        .args(args)
        .output()
        .expect("run vsa")
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).to_string()
}

/// Runs `vsa args`, expects exit 2 with one `error: …` line on stderr containing `want`,
/// and nothing on stdout.
fn usage_error(args: &[&str], want: &str) {
    let out = vsa(args);
    let err = text(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "vsa {args:?}: {err}");
    assert!(
        out.stdout.is_empty(),
        "vsa {args:?} printed {}",
        text(&out.stdout)
    );
    assert!(err.starts_with("error: "), "{err}");
    assert!(err.contains(want), "vsa {args:?}: {err:?} lacks {want:?}");
}

/// A TCP port nothing listens on (bound then released).
fn closed_port() -> String {
    let l = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let a = l.local_addr().unwrap().to_string();
    drop(l);
    a
}

#[test]
fn connection_options_are_checked() {
    usage_error(
        &["status"],
        "no board connection: give --port PATH, --tcp HOST:PORT or --qemu",
    );
    usage_error(
        &["--tcp", "127.0.0.1:1", "--port", "/dev/null", "status"],
        "--port: cannot be combined with --tcp",
    );
    usage_error(
        &["status", "--tcp", "127.0.0.1:1", "--baud", "9600"],
        "--baud: only applies to --port",
    );
    usage_error(
        &["--tcp", "127.0.0.1:1", "--elf", "fw", "status"],
        "--elf: only applies to --qemu",
    );
    usage_error(
        &["--qemu", "--elf", "/nonexistent/vsa-firmware", "status"],
        "--elf: /nonexistent/vsa-firmware does not exist",
    );
    usage_error(
        &["--tcp", "127.0.0.1:1", "--timeout", "0s", "status"],
        "--timeout",
    );
    usage_error(
        &["design", "--tcp", "127.0.0.1:1"],
        "--tcp: connection options only apply to board commands",
    );
    usage_error(&["--qemu", "figures", "--out", "x"], "--qemu: connection");
}

#[test]
fn bad_values_are_rejected_before_connecting() {
    // Nothing listens there: a value checked after connecting would give exit 1.
    let addr = closed_port();
    let cases: &[(&[&str], &str)] = &[
        (
            &["clutch", "3"],
            "clutch: '3' has no unit (accepted units: mm",
        ),
        (&["clutch", "9mm"], "clutch: 9 mm is out of range [1, 8] mm"),
        (&["clutch", "3in"], "unknown unit 'in'"),
        (&["stiffness", "250Nm"], "stiffness: unknown unit 'Nm'"),
        (
            &["stiffness", "0Nm/rad"],
            "stiffness: 0 N·m/rad is out of range",
        ),
        (
            &["move", "7rad"],
            "move: 7 rad is out of range [-2.54, 2.54] rad",
        ),
        (&["move", "-7rad"], "move: -7 rad is out of range"),
        (
            &["move", "0.5rad", "--duration", "0ms"],
            "move --duration: 0 s is out of range",
        ),
        (&["step", "400deg"], "step: 400 deg is out of range"),
        (
            &["sine", "0.2rad", "--frequency", "50Hz"],
            "sine --frequency: 50 Hz is out of range",
        ),
        (
            &["sine", "2rad", "--frequency", "1Hz"],
            "sine: 2 rad is out of range [0, 1] rad",
        ),
        (
            &["record", "--rate", "5"],
            "record --rate: 5 Hz is out of range [10, 500] Hz",
        ),
        (
            &["record", "--seconds", "0"],
            "record --seconds: 0 s is out of range",
        ),
        (
            &["gains", "--kp", "1"],
            "gains: give all of --kp, --ki and --kd, or --auto",
        ),
        (
            &["gains", "--kp", "1", "--ki", "x", "--kd", "1"],
            "gains --ki: 'x' is not a number",
        ),
        (
            &["limits", "--duty", "1.5"],
            "limits --duty: '1.5' is out of range (0, 1]",
        ),
        (
            &["limits", "--current", "20A"],
            "limits --current: 20 A is out of range",
        ),
        (
            &[
                "limits",
                "--position-min",
                "1rad",
                "--position-max",
                "-1rad",
            ],
            "limits: the position window [1, -1] rad is empty",
        ),
        (
            &["wait", "soon"],
            "wait: 'soon' is not a number with a unit",
        ),
    ];
    for (args, want) in cases {
        let mut a = vec!["--tcp", addr.as_str()];
        a.extend_from_slice(args);
        usage_error(&a, want);
    }
}

#[test]
fn script_lines_are_all_checked_before_connecting() {
    let addr = closed_port();
    usage_error(
        &["--tcp", &addr, "script", "clutch 3mm", "bogus"],
        "script command 2 ('bogus'): unrecognized subcommand 'bogus'",
    );
    usage_error(
        &["--tcp", &addr, "script", "status", "move 7rad"],
        "script command 2 ('move 7rad'): move: 7 rad is out of range",
    );
    usage_error(
        &["--tcp", &addr, "script", "record --csv 'a.csv"],
        "script command 1 ('record --csv 'a.csv'): unterminated quote",
    );
    usage_error(&["--tcp", &addr, "script", "  "], "empty command");
}

#[test]
fn an_unreachable_board_is_a_runtime_error() {
    let addr = closed_port();
    let out = vsa(&["--tcp", &addr, "status"]);
    assert_eq!(out.status.code(), Some(1));
    assert!(text(&out.stderr).contains(&format!("tcp {addr}")));
}

#[test]
fn one_shot_commands_against_the_fake_board() {
    let board = FakeBoard::start().unwrap();
    let addr = board.addr().to_string();
    let ok = |args: &[&str]| {
        let mut a = vec!["--tcp", addr.as_str()];
        a.extend_from_slice(args);
        let out = vsa(&a);
        assert!(out.status.success(), "vsa {a:?}: {}", text(&out.stderr));
        text(&out.stdout)
    };
    let s = ok(&["status"]);
    assert!(s.contains("state            disabled"), "{s}");
    assert!(s.contains("clutch length    3 mm"), "{s}");
    assert!(s.contains("telemetry        off, 0 samples dropped"), "{s}");
    assert_eq!(
        ok(&["stiffness", "250Nm/rad"]),
        "configured for k = 250 N·m/rad: set the clutch to L = 3.061 mm\n"
    );
    assert!(ok(&["clutch", "5mm"]).starts_with("clutch L = 5 mm configured: k = 57.34 N·m/rad"));

    // Refused: not enabled. Exit 1 with the board's reason.
    let out = vsa(&["--tcp", &addr, "move", "0.5rad"]);
    assert_eq!(out.status.code(), Some(1));
    assert_eq!(
        text(&out.stderr),
        "error: the board refused move: not allowed in this state\n"
    );
    assert_eq!(ok(&["enable"]), "enabled\n");
    assert_eq!(
        ok(&["move", "-30deg", "--duration", "1.5s"]),
        "moving to -0.523599 rad in 1500 ms\n"
    );
    ok(&["gains", "--kp", "800", "--ki", "2000", "--kd", "20.5"]);
    ok(&["limits", "--current", "1.2A", "--duty", "80%"]);
    let log = board.shared().device.log.clone();
    assert!(log.contains(&Request::Move {
        target_urad: -523_599,
        duration_ms: 1_500
    }));
    assert!(log.contains(&Request::SetGains(client::Gains {
        kp: 800_000,
        ki: 2_000_000,
        kd: 20_500
    })));
    assert!(log.contains(&Request::SetLimits(client::Limits {
        current_ma: 1_200,
        duty_permille: 800,
        ..client::Limits::DEFAULT
    })));
    // One-shot commands send no heartbeats.
    assert_eq!(board.shared().device.heartbeats, 0);
}

#[test]
fn a_script_session_records_a_csv_with_heartbeats() {
    let board = FakeBoard::start().unwrap();
    // Heartbeats every 20 ms; a longer timeout than the firmware's 100 ms keeps the test
    // steady on a loaded machine (a fault would now fail the script, as it should).
    board.shared().device.command_timeout_ms = 1_000;
    let addr = board.addr().to_string();
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("run.csv");
    let out = vsa(&[
        "--tcp",
        &addr,
        "script",
        "clutch 5mm",
        "enable",
        "move 0.5rad --duration 300ms",
        &format!("record --seconds 0.3 --rate 100 --csv '{}'", csv.display()),
        "disable",
    ]);
    let stdout = text(&out.stdout);
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert!(stdout.contains("> enable\nenabled\n"), "{stdout}");
    assert!(
        stdout.contains("recorded 30 of 30 samples at 100 Hz over 0.3 s"),
        "{stdout}"
    );
    assert!(
        stdout.contains("missing 0 in 0 gaps; board dropped 0 (0 since boot); 0 bad frames"),
        "{stdout}"
    );
    let samples =
        client::csv::read_csv(std::io::BufReader::new(std::fs::File::open(&csv).unwrap())).unwrap();
    assert_eq!(samples.len(), 30);
    assert!(samples.iter().all(|s| s.reference_urad == 500_000));
    let sh = board.shared();
    assert_eq!(sh.device.state, State::Disabled);
    assert!(sh.device.heartbeats > 5, "{}", sh.device.heartbeats);
    assert_eq!(sh.connections, 1);
}

#[test]
fn a_failing_script_command_names_its_line() {
    let board = FakeBoard::start().unwrap();
    let addr = board.addr().to_string();
    let out = vsa(&[
        "--tcp",
        &addr,
        "script",
        "--no-heartbeat",
        "status",
        "step 0.1rad",
    ]);
    assert_eq!(out.status.code(), Some(1));
    assert_eq!(
        text(&out.stderr),
        "error: script command 2 ('step 0.1rad'): the board refused step: not allowed in this state\n"
    );
    assert!(text(&out.stdout).contains("> status\nstate            disabled"));
    assert_eq!(board.shared().device.heartbeats, 0);
}
