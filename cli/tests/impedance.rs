//! `vsa impedance` end to end: argument errors (exit 2, nothing sent) and the command
//! against the in-process fake board (`client::fake`) over `--tcp`: the wire values sent,
//! and the refusal of a stiffness above the joint's explained with the board's figures.

use std::process::Output;

use client::fake::FakeBoard;
use client::Request;

mod common;

/// Runs `vsa ARGS…` (the subcommand first).
fn vsa(args: &[&str]) -> Output {
    common::vsa(args[0], &args[1..])
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).to_string()
}

#[test]
fn bad_values_are_rejected_before_connecting() {
    // Nothing listens there: a value checked after connecting would give exit 1.
    let l = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = l.local_addr().unwrap().to_string();
    drop(l);
    let base = ["--stiffness", "20Nm/rad", "--damping", "0.2Nms/rad"];
    let cases: &[(&[&str], &str)] = &[
        (
            &["7rad", base[0], base[1], base[2], base[3]],
            "impedance: 7 rad is out of range [-2.54, 2.54] rad",
        ),
        (
            &["0.3rad", "--stiffness", "0.05Nm/rad", base[2], base[3]],
            "impedance --stiffness: 0.05 N·m/rad is out of range [0.1, ",
        ),
        (
            &["0.3rad", base[0], base[1], "--damping", "0.2Nm/rad"],
            "impedance --damping: unknown unit 'Nm/rad'",
        ),
        (
            &["0.3rad", base[0], base[1], "--damping", "-1Nms/rad"],
            "impedance --damping: -1 N·m·s/rad is out of range [0, 100] N·m·s/rad",
        ),
        (
            &[
                "0.3rad", base[0], base[1], base[2], base[3], "--torque", "200Nm",
            ],
            "impedance --torque: 200 N·m is out of range [-100, 100] N·m",
        ),
    ];
    for (args, want) in cases {
        let mut a = vec!["impedance", "--tcp", addr.as_str()];
        a.extend_from_slice(args);
        let out = vsa(&a);
        let err = text(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "vsa {a:?}: {err}");
        assert!(out.stdout.is_empty());
        assert!(
            err.starts_with("error: ") && err.contains(want),
            "{err:?} lacks {want:?}"
        );
    }
}

#[test]
fn against_the_fake_board() {
    let board = FakeBoard::start().unwrap();
    let addr = board.addr().to_string();
    let run = |args: &[&str]| {
        let mut a = args.to_vec();
        a.extend_from_slice(&["--tcp", addr.as_str()]);
        vsa(&a)
    };
    assert!(run(&["enable"]).status.success());
    let out = run(&[
        "impedance",
        "0.3rad",
        "--stiffness",
        "20Nm/rad",
        "--damping",
        "0.2Nms/rad",
        "--torque",
        "-0.1Nm",
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert_eq!(
        text(&out.stdout),
        "holding 0.3 rad with k = 20 N·m/rad, d = 0.2 N·m·s/rad, τ_ff = -0.1 N·m\n"
    );
    assert!(board.shared().device.log.contains(&Request::Impedance {
        target_urad: 300_000,
        stiffness_mnm_per_rad: 20_000,
        damping_unms_per_rad: 200_000,
        torque_unm: -100_000,
    }));
    // The fake joint at L = 3 mm: k = 7 167.5/27 = 265.463 N·m/rad.
    let out = run(&[
        "impedance",
        "0.3rad",
        "--stiffness",
        "300Nm/rad",
        "--damping",
        "0.2Nms/rad",
    ]);
    assert_eq!(out.status.code(), Some(1));
    assert_eq!(
        text(&out.stderr),
        "error: the board refused impedance: virtual stiffness 300 N·m/rad is above the \
         joint's k = 265.463 N·m/rad at the clutch length 3 mm (a shorter clutch length \
         makes the joint stiffer)\n"
    );
}

#[test]
fn simulate_reports_the_deflection_at_rest() {
    // L = 5 mm (k = 57.3 N·m/rad), k_v = 20 N·m/rad, load +0.2 N·m, τ_ff = −0.1 N·m:
    // (0.2 − 0.1)/20 = 5 mrad.
    let v = common::json(
        "simulate",
        &[
            "--clutch-length",
            "5mm",
            "--load",
            "0.2Nm",
            "--impedance",
            "0.3rad:20Nm/rad:0.2Nms/rad:-0.1Nm",
        ],
    );
    assert!(
        (common::num(&v, "expected_deflection_rad") - 0.005).abs() < 1e-12,
        "{v}"
    );
    let count = std::f64::consts::TAU / 4096.0;
    assert!(
        (common::num(&v, "deflection_rad") - 0.005).abs() <= count,
        "{v}"
    );
    assert_eq!(v["faults"], serde_json::json!([]), "{v}");
    // Stiffer than the beams: a one-line error, exit 2.
    let out = vsa(&[
        "simulate",
        "--clutch-length",
        "5mm",
        "--impedance",
        "0.3rad:60Nm/rad:0.2Nms/rad",
    ]);
    assert_eq!(out.status.code(), Some(2));
    assert_eq!(
        text(&out.stderr),
        "error: simulate: --impedance: virtual stiffness 60 N·m/rad is above the joint's \
         k = 57.340 N·m/rad at this clutch setting\n"
    );
}
