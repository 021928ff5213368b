//! `vsa plot CSV --out FILE`: offline figures of recorded (or simulated) runs.

use std::path::Path;
use std::process::{Command, Output};

use client::{FaultSet, LimitFlags, TelemetrySample};

fn vsa(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_vsa"))
        .args(args)
        .output()
        .expect("run vsa")
}

fn recording(path: &Path) {
    let samples: Vec<TelemetrySample> = (0..500)
        .map(|i| {
            let t = f64::from(i) * 2e-3;
            let r = (0.5 * (t / 0.3).min(1.0) * 1e6) as i32;
            TelemetrySample {
                tick: 1_000 + 2 * i,
                reference_urad: r,
                link_angle_urad: r - 3_000,
                gear_angle_urad: r + 8_000,
                current_ma: (300.0 * (t * 20.0).sin()) as i16,
                torque_unm: (150_000.0 * (t * 20.0).cos()) as i32,
                duty_permille: 120,
                faults: FaultSet::EMPTY,
                limits: LimitFlags::NONE,
            }
        })
        .collect();
    let f = std::fs::File::create(path).unwrap();
    client::csv::write_csv(std::io::BufWriter::new(f), &samples).unwrap();
}

fn ok(args: &[&str]) {
    let out = vsa(args);
    assert!(
        out.status.success(),
        "vsa {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

fn usage_error(args: &[&str], want: &str) {
    let out = vsa(args);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains(want), "{err:?} lacks {want:?}");
}

#[test]
fn plots_a_recording_as_png_and_svg() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("run.csv");
    recording(&csv);
    let png = dir.path().join("fig.png");
    let svg = dir.path().join("fig.svg");
    let (csv_s, png_s, svg_s) = (
        csv.to_str().unwrap(),
        png.to_str().unwrap(),
        svg.to_str().unwrap(),
    );
    ok(&["plot", csv_s, "--out", png_s]);
    ok(&["plot", csv_s, "--out", svg_s, "--title", "step at L = 3 mm"]);
    let png = std::fs::read(&png).unwrap();
    assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");
    assert!(png.len() > 20_000, "{} bytes", png.len());
    let svg = std::fs::read_to_string(&svg).unwrap();
    assert!(svg.starts_with("<svg"));
    for label in [
        "step at L = 3 mm",
        "Link angle",
        "reference",
        "link",
        "gear",
        "Current and torque",
        "current (A)",
        "torque (N·m)",
        "t (s)",
    ] {
        assert!(svg.contains(label), "no '{label}' in the SVG");
    }
}

#[test]
fn plots_a_simulate_csv() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("sim.csv");
    let out = dir.path().join("sim.svg");
    ok(&[
        "simulate",
        "--clutch-length",
        "3mm",
        "--step",
        "0.5rad",
        "--seconds",
        "0.3",
        "--settle",
        "0",
        "--csv",
        csv.to_str().unwrap(),
    ]);
    ok(&[
        "plot",
        csv.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    let svg = std::fs::read_to_string(&out).unwrap();
    assert!(svg.contains("torque estimate (N·m)"));
}

#[test]
fn bad_plot_input_is_a_usage_error() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("run.csv");
    recording(&csv);
    let csv_s = csv.to_str().unwrap();
    let jpg = dir.path().join("fig.jpg");
    usage_error(&["plot", csv_s, "--out", jpg.to_str().unwrap()], "--out: ");
    usage_error(
        &["plot", "/nonexistent/run.csv", "--out", "x.png"],
        "plot: cannot read /nonexistent/run.csv",
    );
    let other = dir.path().join("other.csv");
    std::fs::write(&other, "t_s,x\n0,1\n").unwrap();
    usage_error(
        &["plot", other.to_str().unwrap(), "--out", "x.png"],
        "no reference_rad, link_angle_rad or gear_angle_rad column",
    );
    std::fs::write(&other, "x,reference_rad\n0,1\n").unwrap();
    usage_error(
        &["plot", other.to_str().unwrap(), "--out", "x.png"],
        "no t_s column",
    );
    std::fs::write(&other, "t_s,reference_rad\n0,1\n1\n").unwrap();
    usage_error(
        &["plot", other.to_str().unwrap(), "--out", "x.png"],
        "line 3: 1 cells, the header has 2",
    );
    std::fs::write(&other, "").unwrap();
    usage_error(
        &["plot", other.to_str().unwrap(), "--out", "x.png"],
        "empty file",
    );
    assert!(!Path::new("x.png").exists());
}
