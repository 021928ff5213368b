//! The client against the real firmware on an emulated board. Needs `qemu-system-arm` and a
//! firmware ELF that serves the protocol, so it is ignored by default:
//!
//! ```sh
//! VSA_FIRMWARE_ELF=target/thumbv7em-none-eabihf/release/vsa-firmware \
//!     cargo test -p vsa-client --test qemu -- --ignored
//! ```
//!
//! (`VSA_BOARD=qemu-m3` with the M3 ELF for the other board.) `cargo xtask test` runs the
//! end-to-end checks itself.

use std::sync::mpsc;
use std::time::Duration;

use client::qemu::{Board, LogSink, QemuBoard};
use client::State;

#[test]
#[ignore = "needs qemu-system-arm and VSA_FIRMWARE_ELF (a firmware that serves the protocol)"]
fn session_on_the_emulated_board() {
    let elf = std::env::var("VSA_FIRMWARE_ELF").expect("set VSA_FIRMWARE_ELF");
    let board: Board = std::env::var("VSA_BOARD")
        .unwrap_or_else(|_| "qemu-m4".to_string())
        .parse()
        .unwrap();
    let (tx, rx) = mpsc::channel();
    let (mut qemu, mut c) =
        QemuBoard::start(board, elf.as_ref(), &[], LogSink::Channel(tx)).expect("start");
    let s = c.status().unwrap();
    assert_eq!(s.state, State::Disabled);
    assert_eq!(s.clutch_length_um, 3_000);
    c.set_heartbeat(true);
    c.enable().unwrap();
    c.wait(Duration::from_millis(50)).unwrap();
    c.move_to(500_000, 300).unwrap();
    let rec = c.record(Duration::from_secs(1), 500, |_| {}).unwrap();
    assert_eq!(rec.samples.len(), 500, "{:?}", rec.gaps);
    assert_eq!(rec.missing_samples, 0);
    let last = rec.samples.last().unwrap();
    assert!((last.link_angle_urad - 500_000).abs() < 20_000, "{last:?}");
    c.disable().unwrap();
    let s = c.status().unwrap();
    assert!(s.faults.is_empty(), "{s:?}");
    assert_eq!(c.stats().bad_frames, 0);
    qemu.kill();
    let log: usize = rx.try_iter().map(|b| b.len()).sum();
    assert!(log > 0, "no defmt bytes from QEMU");
}

/// QEMU gets SIGKILL when the thread that started it ends (`PR_SET_PDEATHSIG`), so a
/// killed `vsa` (whose main thread starts it) never leaves it running. A stand-in for
/// QEMU (a shell script that becomes `sleep`) shows it without an emulator.
#[cfg(target_os = "linux")]
#[test]
fn qemu_dies_with_the_thread_that_started_it() {
    use std::os::unix::fs::PermissionsExt;
    use std::os::unix::process::ExitStatusExt;
    use std::time::Instant;

    let script = std::env::temp_dir().join(format!("fake-qemu-{}.sh", std::process::id()));
    std::fs::write(&script, "#!/bin/sh\nexec sleep 30\n").unwrap();
    std::fs::set_permissions(&script, std::fs::Permissions::from_mode(0o755)).unwrap();
    let line = client::qemu::QemuCommand {
        qemu: script.clone(),
        machine: "netduinoplus2".into(),
        elf: "firmware.elf".into(),
        argv: vec!["vsa-firmware".into()],
        serials: vec!["null".into()],
        icount: "shift=3".into(),
    };
    let mut child = std::thread::spawn(move || line.command().unwrap().spawn().unwrap())
        .join()
        .unwrap();
    let start = Instant::now();
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        assert!(
            start.elapsed() < Duration::from_secs(5),
            "the stand-in outlived the thread that started it"
        );
        std::thread::sleep(Duration::from_millis(10));
    };
    let _ = std::fs::remove_file(&script);
    assert_eq!(status.signal(), Some(9), "{status:?}");
}
