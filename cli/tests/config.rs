//! `vsa config` and `vsa faults` against the in-process fake board (`client::fake`), whose
//! store keeps the saved configuration and every latched fault. `cargo xtask persistence`
//! runs the same commands against the firmware on the emulated boards.

use std::process::{Command, Output};

use client::fake::FakeBoard;
use client::protocol::{FaultCode, FaultRecord, LoggedFault, State};

fn vsa(addr: &str, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_vsa"))
        .args(["--tcp", addr])
        .args(args)
        .output()
        .expect("run vsa")
}

fn stdout(o: &Output) -> String {
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    String::from_utf8_lossy(&o.stdout).to_string()
}

fn line<'a>(text: &'a str, key: &str) -> &'a str {
    text.lines()
        .find(|l| l.starts_with(key))
        .unwrap_or_else(|| panic!("no `{key}` line in:\n{text}"))
}

#[test]
fn status_says_whether_the_running_configuration_is_the_stored_one() {
    let board = FakeBoard::start().unwrap();
    let addr = board.addr().to_string();
    let differs = "differs from the running one (`vsa config save` keeps it)";
    let same = "same as the running one";
    assert!(line(&stdout(&vsa(&addr, &["status"])), "stored config").ends_with(same));
    stdout(&vsa(&addr, &["clutch", "5mm"]));
    assert!(line(&stdout(&vsa(&addr, &["status"])), "stored config").ends_with(differs));
    assert!(line(&stdout(&vsa(&addr, &["config", "show"])), "stored config").ends_with(differs));
    assert_eq!(
        stdout(&vsa(&addr, &["config", "save"])),
        "configuration saved: the board boots with it\n"
    );
    assert_eq!(board.shared().device.stored.map(|s| s.0), Some(5_000));
    let show = stdout(&vsa(&addr, &["config", "show"]));
    assert!(line(&show, "clutch length").ends_with("5 mm"));
    assert!(line(&show, "stored config").ends_with(same));
    stdout(&vsa(&addr, &["clutch", "2mm"]));
    stdout(&vsa(&addr, &["config", "load"]));
    assert!(line(&stdout(&vsa(&addr, &["status"])), "clutch length").ends_with("5 mm"));
    stdout(&vsa(&addr, &["config", "reset"]));
    assert!(line(&stdout(&vsa(&addr, &["status"])), "clutch length").ends_with("3 mm"));
    assert_eq!(board.shared().device.stored, None);
}

#[test]
fn a_save_while_enabled_is_refused_in_one_line() {
    let board = FakeBoard::start().unwrap();
    let addr = board.addr().to_string();
    board.shared().device.state = State::Enabled;
    let out = vsa(&addr, &["config", "save"]);
    assert_eq!(out.status.code(), Some(1));
    assert_eq!(
        String::from_utf8_lossy(&out.stderr).trim(),
        "error: the board refused save: not allowed in this state"
    );
}

#[test]
fn the_fault_log_lists_the_most_recent_first() {
    let board = FakeBoard::start().unwrap();
    let addr = board.addr().to_string();
    assert_eq!(
        stdout(&vsa(&addr, &["faults", "--log"])),
        "fault log empty\n"
    );
    let entry = |seq, code, tick| LoggedFault {
        seq,
        fault: FaultRecord {
            code,
            value: 7,
            tick,
        },
    };
    board.shared().device.fault_log = vec![
        entry(0, FaultCode::OverCurrent, 300),
        entry(1, FaultCode::CommandTimeout, 900),
    ];
    let text = stdout(&vsa(&addr, &["faults", "--log"]));
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines[0], "2 faults logged, most recent first:");
    assert!(lines[1].starts_with("#1") && lines[1].contains("command-timeout"));
    assert!(lines[2].starts_with("#0") && lines[2].contains("over-current"));
    assert_eq!(stdout(&vsa(&addr, &["faults"])), "no fault latched\n");
}
