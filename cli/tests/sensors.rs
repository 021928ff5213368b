//! `vsa sensors` without firmware: its arguments are checked before anything is sent
//! (exit 2), and a board that does not know the bring-up requests (the in-process fake
//! board, `client::fake`) is reported in one line (exit 1). `cargo xtask test` runs it
//! against the firmware on both emulated boards.

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
