//! `vsa bus` end to end: argument errors (exit 2, nothing sent) and the request against
//! the in-process fake board (`client::fake`), which serves no Dynamixel bus: the wire
//! values sent, and the refusal explained (exit 1). The switch on an emulated bus board is
//! `cargo xtask dynamixel` (`dynamixel/tests/sdk_persist.py`).

use client::fake::FakeBoard;
use client::protocol::BusChange;
use client::Request;

#[allow(dead_code)] // json() and num() serve the other tests
mod common;

#[test]
fn bad_values_are_rejected_before_connecting() {
    // Nothing listens there: a value checked after connecting would give exit 1.
    let l = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = l.local_addr().unwrap().to_string();
    drop(l);
    let cases: &[(&[&str], &str)] = &[
        (&[], "bus: give at least one of --protocol, --id, --rate"),
        (
            &["--protocol", "3"],
            "bus --protocol: \"3\" is not a whole number 0–2",
        ),
        (&["--protocol", "0"], "bus --protocol: 0 is not 1 or 2"),
        (
            &["--id", "254"],
            "bus --id: \"254\" is not a whole number 0–253",
        ),
        (&["--rate", "0"], "bus --rate: 0 bit/s"),
    ];
    for (args, want) in cases {
        let mut a = args.to_vec();
        a.extend_from_slice(&["--tcp", addr.as_str()]);
        let out = common::vsa("bus", &a);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(want), "{args:?}: {err:?} lacks {want:?}");
    }
}

#[test]
fn a_board_without_a_bus_refuses() {
    let board = FakeBoard::start().unwrap();
    let addr = board.addr().to_string();
    let out = common::vsa(
        "bus",
        &[
            "--protocol",
            "2",
            "--id",
            "4",
            "--rate",
            "57600",
            "--tcp",
            &addr,
        ],
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains("does not serve a Dynamixel bus"), "{err:?}");
    assert!(board
        .shared()
        .device
        .log
        .contains(&Request::SetBus(BusChange {
            protocol_version: Some(2),
            id: Some(4),
            baud_bps: Some(57_600),
        })));
}
