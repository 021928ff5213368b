//! `vsa` used carelessly and then with hostile intent: argument attacks, hostile CSVs for
//! `vsa plot`, files that must survive failed runs, and the ways out of latched faults on
//! the in-process fake board (`client::fake`, which applies the firmware's rules for the
//! position window, `clear` and the command timeout).

use std::path::Path;
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use client::fake::{Behaviour, FakeBoard};
use client::{FaultCode, State};

fn vsa(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_vsa"))
        .args(args)
        .output()
        .expect("run vsa")
}

/// Runs `vsa args`, killed after `limit` (a hang is a failure, not a stuck test).
fn vsa_within(args: &[&str], limit: Duration) -> Output {
    let mut child = Command::new(env!("CARGO_BIN_EXE_vsa"))
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("run vsa");
    let start = Instant::now();
    while child.try_wait().unwrap().is_none() {
        if start.elapsed() > limit {
            let _ = child.kill();
            panic!("vsa {args:?} still running after {limit:?}");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    child.wait_with_output().unwrap()
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).to_string()
}

/// Exit 2, one `error:` line containing `want`, nothing on stdout.
fn usage_error(out: &Output, want: &str) {
    let err = text(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(out.stdout.is_empty(), "{}", text(&out.stdout));
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(
        err.starts_with("error: ") && err.contains(want),
        "{err:?} lacks {want:?}"
    );
}

/// A TCP port nothing listens on.
fn closed_port() -> String {
    let l = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let a = l.local_addr().unwrap().to_string();
    drop(l);
    a
}

#[test]
fn argument_attacks_exit_2_naming_the_argument() {
    let addr = closed_port();
    let tcp = |args: &[&str]| {
        let mut a = vec!["--tcp", addr.as_str()];
        a.extend_from_slice(args);
        vsa(&a)
    };
    // Beyond what the gear pot measures: refused before anything is sent.
    usage_error(
        &tcp(&["move", "2.6rad"]),
        "move: 2.6 rad is out of range [-2.54, 2.54] rad",
    );
    usage_error(&tcp(&["step", "-150deg"]), "step: -150 deg is out of range");
    usage_error(
        &tcp(&["limits", "--position-max", "3rad"]),
        "limits --position-max: 3 rad is out of range [-2.54, 2.54] rad",
    );
    usage_error(
        &vsa(&["--tcp", "localhost", "status"]),
        "--tcp: 'localhost' is not HOST:PORT",
    );
    usage_error(&vsa(&["--tcp", ":4000", "status"]), "--tcp: ':4000'");
    usage_error(&vsa(&["--tcp", "h:99999", "status"]), "--tcp: 'h:99999'");
    // A script whose recording could not be written fails before it moves anything.
    usage_error(
        &tcp(&["script", "enable", "record --csv /nonexistent/x.csv"]),
        "script command 2 ('record --csv /nonexistent/x.csv'): record --csv: cannot write \
         /nonexistent/x.csv",
    );
    for (args, want) in [
        (
            &["simulate", "--step", "0.5rad", "--seconds", "0"][..],
            "--seconds",
        ),
        (
            &["simulate", "--step", "0.5rad", "--load", "1e9Nm"],
            "--load",
        ),
        (&["simulate", "--step", "1e9rad"], "--step"),
        (&["simulate", "--move", "1e9rad:1s"], "--move"),
        (&["simulate", "--sine", "1e9rad:1Hz"], "--sine"),
        (
            &["simulate", "--step", "0.5rad", "--inertia=-1"],
            "--inertia",
        ),
        (
            &["simulate", "--step", "0.5rad", "--clutch-tolerance", "6mm"],
            "--clutch-tolerance",
        ),
        (
            &["simulate", "--step", "0.5rad", "--clutch-tolerance=-1mm"],
            "--clutch-tolerance",
        ),
    ] {
        usage_error(&vsa(args), want);
    }
}

#[test]
fn a_failed_simulation_leaves_an_existing_csv_alone() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("x.csv");
    std::fs::write(&csv, "precious\n").unwrap();
    let c = csv.to_str().unwrap();
    usage_error(
        &vsa(&["simulate", "--step", "1e9rad", "--csv", c]),
        "--step",
    );
    assert_eq!(std::fs::read_to_string(&csv).unwrap(), "precious\n");
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    let out = vsa(&[
        "simulate",
        "--step",
        "0.5rad",
        "--seconds",
        "0.1",
        "--csv",
        c,
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let written = std::fs::read_to_string(&csv).unwrap();
    assert!(written.starts_with("t_s,"), "{written}");
    assert!(written.lines().count() > 100, "{}", written.lines().count());
}

fn write(path: &Path, s: &str) {
    std::fs::write(path, s).unwrap();
}

#[test]
fn hostile_csvs_never_panic_hang_or_leave_a_partial_image() {
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("out.png");
    let p = png.to_str().unwrap();
    let case = |name: &str, body: &str, want: &str| {
        let csv = dir.path().join(name);
        write(&csv, body);
        let out = vsa_within(
            &["plot", csv.to_str().unwrap(), "--out", p],
            Duration::from_secs(30),
        );
        usage_error(&out, want);
        assert!(!png.exists(), "{name}: an image was left behind");
        assert_eq!(
            std::fs::read_dir(dir.path())
                .unwrap()
                .filter(|e| e
                    .as_ref()
                    .unwrap()
                    .file_name()
                    .to_string_lossy()
                    .starts_with('.'))
                .count(),
            0,
            "{name}: a temporary file was left behind"
        );
    };
    let h = "t_s,link_angle_rad\n";
    case(
        "huge_t.csv",
        &format!("{h}-1e308,0\n1e308,1\n"),
        "t_s = -1e308",
    );
    case("inf_t.csv", &format!("{h}0,0\n1.8e308,1\n"), "t_s = inf");
    case(
        "inf_y.csv",
        &format!("{h}0,-1.8e308\n1,1\n"),
        "link_angle_rad = -inf",
    );
    case(
        "huge_y.csv",
        &format!("{h}0,1e200\n1,1\n"),
        "link_angle_rad = 1e200",
    );
    case("empty.csv", "", "empty file");
    case("header.csv", h, "no samples");
    case("nan.csv", &format!("{h}nan,1\nx,2\n"), "no samples");
    case(
        "ragged.csv",
        &format!("{h}0,1,2\n"),
        "3 cells, the header has 2",
    );
    case("no_angles.csv", "t_s,foo\n0,1\n", "no reference_rad");
    // Tiny spans and missing cells are data, not attacks.
    let csv = dir.path().join("tiny.csv");
    write(&csv, &format!("{h}0,1e-300\n1e-300,\n2e-300,3e-300\n"));
    let out = vsa_within(
        &["plot", csv.to_str().unwrap(), "--out", p],
        Duration::from_secs(30),
    );
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert!(png.exists());
}

#[test]
fn an_unwritable_plot_is_one_clear_line_and_an_old_image_survives() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("run.csv");
    write(&csv, "t_s,link_angle_rad\n0,0\n1,1\n");
    let c = csv.to_str().unwrap();
    usage_error(
        &vsa(&["plot", c, "--out", "/nonexistent/dir/out.png"]),
        "--out: cannot write /nonexistent/dir/out.png: No such file or directory",
    );
    // A file whose data is refused leaves the previous image as it was.
    let png = dir.path().join("out.png");
    write(&png, "old image");
    let bad = dir.path().join("bad.csv");
    write(&bad, "t_s,link_angle_rad\n0,0\n1e308,1\n-1e308,1\n");
    usage_error(
        &vsa(&[
            "plot",
            bad.to_str().unwrap(),
            "--out",
            png.to_str().unwrap(),
        ]),
        "outside ±1e12",
    );
    assert_eq!(std::fs::read_to_string(&png).unwrap(), "old image");
}

fn on(board: &FakeBoard, args: &[&str]) -> Output {
    let addr = board.addr().to_string();
    let mut a = vec!["--tcp", addr.as_str()];
    a.extend_from_slice(args);
    vsa(&a)
}

fn ok(board: &FakeBoard, args: &[&str]) -> String {
    let out = on(board, args);
    assert!(out.status.success(), "vsa {args:?}: {}", text(&out.stderr));
    text(&out.stdout)
}

fn fails(board: &FakeBoard, args: &[&str]) -> String {
    let out = on(board, args);
    assert_eq!(
        out.status.code(),
        Some(1),
        "vsa {args:?}: {}",
        text(&out.stderr)
    );
    text(&out.stderr)
}

#[test]
fn a_heartbeat_session_ends_disarmed_so_clear_and_enable_work_after_it() {
    let board = FakeBoard::start().unwrap();
    // Longer than the firmware's 100 ms: steady on a loaded machine.
    board.shared().device.command_timeout_ms = 1_000;
    ok(&board, &["script", "enable", "wait 300ms", "disable"]);
    assert!(board.shared().device.heartbeats > 5);
    assert_eq!(board.shared().device.last_heartbeat, None, "disarmed");
    std::thread::sleep(Duration::from_millis(300));
    assert_eq!(ok(&board, &["clear"]), "faults cleared\n");
    assert_eq!(ok(&board, &["enable"]), "enabled\n");
    std::thread::sleep(Duration::from_millis(300));
    let s = ok(&board, &["status"]);
    assert!(s.contains("state            enabled"), "{s}");
    assert!(s.contains("faults           none"), "{s}");
    // A session that dies without disarming: the timeout fires, and disarms itself, so a
    // plain clear recovers.
    {
        let mut sh = board.shared();
        sh.device.last_heartbeat = Some(sh.device.tick);
    }
    std::thread::sleep(Duration::from_millis(1_200));
    let s = ok(&board, &["status"]);
    assert!(s.contains("command-timeout (9)"), "{s}");
    assert_eq!(ok(&board, &["clear"]), "faults cleared\n");
    std::thread::sleep(Duration::from_millis(1_200));
    assert_eq!(ok(&board, &["enable"]), "enabled\n");
}

#[test]
fn a_target_outside_the_window_is_refused_with_the_window() {
    let board = FakeBoard::start().unwrap();
    ok(&board, &["enable"]);
    let e = fails(&board, &["move", "2.52rad"]);
    assert_eq!(
        e,
        "error: the board refused move: target 2.52 rad is outside the position window \
         [-2.5, 2.5] rad (`limits --position-min/--position-max` widen it, up to ±2.54 rad)\n"
    );
    ok(&board, &["limits", "--position-max", "2.54rad"]);
    ok(&board, &["move", "2.52rad"]);
}

#[test]
fn a_fault_during_a_script_names_it_and_clear_says_what_remains() {
    let board = FakeBoard::start().unwrap();
    board.shared().device.command_timeout_ms = 1_000;
    // The window shrinks under a link at 0.5 rad: position-limit latches.
    let out = on(
        &board,
        &[
            "script",
            "enable",
            "move 0.5rad",
            "limits --position-max 0.1rad",
            "wait 100ms",
            "status",
        ],
    );
    assert_eq!(out.status.code(), Some(1));
    let e = text(&out.stderr);
    assert!(
        e.starts_with(
            "error: script command 3 ('limits --position-max 0.1rad'): fault latched: \
             position-limit (7); first fault position-limit (code 7): 499880 µrad"
        ),
        "{e}"
    );
    assert!(!text(&out.stdout).contains("> wait"), "the script stopped");
    // Clear refuses while the link is outside, with the value, the window and the way out.
    let e = fails(&board, &["clear"]);
    assert!(
        e.starts_with(
            "error: the board cleared nothing: position-limit (code 7) persists at tick "
        ),
        "{e}"
    );
    assert!(
        e.contains(
            ": link at 0.49988 rad, outside the position window [-2.5, 0.1] rad: move it back \
             by hand, or widen the window"
        ),
        "{e}"
    );
    assert_eq!(board.shared().device.state, State::Faulted);
    // The way out: widen the window, clear, enable.
    ok(&board, &["limits"]);
    assert_eq!(ok(&board, &["clear"]), "faults cleared\n");
    assert_eq!(ok(&board, &["enable"]), "enabled\n");
}

#[test]
fn a_command_timeout_during_a_recording_is_reported_and_the_csv_kept() {
    let board = FakeBoard::start().unwrap();
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("run.csv");
    let b = &board;
    let out = std::thread::scope(|s| {
        // Mid-recording the board's timeout becomes shorter than the heartbeat interval.
        s.spawn(|| {
            std::thread::sleep(Duration::from_millis(250));
            b.shared().device.command_timeout_ms = 5;
        });
        on(
            b,
            &[
                "script",
                "enable",
                &format!("record --seconds 1 --rate 50 --csv '{}'", csv.display()),
            ],
        )
    });
    assert_eq!(out.status.code(), Some(1), "{}", text(&out.stderr));
    let e = text(&out.stderr);
    assert!(e.contains("command-timeout (9)"), "{e}");
    assert!(
        text(&out.stdout).contains("recorded 50 of 50 samples"),
        "{}",
        text(&out.stdout)
    );
    let samples =
        client::csv::read_csv(std::io::BufReader::new(std::fs::File::open(&csv).unwrap())).unwrap();
    assert!(samples
        .iter()
        .any(|s| s.faults.contains(FaultCode::CommandTimeout)));
}

#[test]
fn a_one_shot_recording_reports_a_fault_and_exits_1() {
    let board = FakeBoard::start().unwrap();
    ok(&board, &["enable"]);
    ok(&board, &["move", "0.5rad"]);
    let b = &board;
    std::thread::scope(|s| {
        s.spawn(|| {
            std::thread::sleep(Duration::from_millis(150));
            b.shared().device.limits.position_max_urad = 100_000;
        });
        let e = fails(b, &["record", "--seconds", "0.4", "--rate", "50"]);
        assert!(
            e.starts_with("error: fault latched during the recording: position-limit (7)"),
            "{e}"
        );
    });
}

#[test]
fn an_existing_csv_survives_a_silent_board() {
    let board = FakeBoard::with_behaviour(Behaviour {
        ignore: ["stream-telemetry"].into_iter().collect(),
        ..Behaviour::default()
    })
    .unwrap();
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("existing.csv");
    write(&csv, "precious\n");
    let e = fails(
        &board,
        &[
            "--timeout",
            "200ms",
            "record",
            "--seconds",
            "0.2",
            "--csv",
            csv.to_str().unwrap(),
        ],
    );
    assert!(e.contains("no reply to stream-telemetry"), "{e}");
    assert_eq!(std::fs::read_to_string(&csv).unwrap(), "precious\n");
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
}

#[test]
fn a_recording_across_the_tick_wrap_is_whole() {
    let board = FakeBoard::with_behaviour(Behaviour {
        tick_offset: u32::MAX - 150,
        ..Behaviour::default()
    })
    .unwrap();
    let s = ok(&board, &["record", "--seconds", "0.4", "--rate", "100"]);
    assert!(s.contains("recorded 40 of 40 samples"), "{s}");
    assert!(s.contains("missing 0 in 0 gaps"), "{s}");
}
