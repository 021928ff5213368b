//! Telemetry CSV: SI units out, the very same samples back, and clear errors.

use client::csv::{read_csv, read_table, write_csv, HEADER};
use client::{Error, FaultSet, LimitFlags, TelemetrySample};

fn samples() -> Vec<TelemetrySample> {
    vec![
        TelemetrySample {
            tick: 51_234,
            reference_urad: 500_000,
            link_angle_urad: 499_871,
            gear_angle_urad: 503_310,
            current_ma: 212,
            torque_unm: -41_230,
            duty_permille: 87,
            faults: FaultSet::EMPTY,
            limits: LimitFlags::NONE,
        },
        TelemetrySample {
            tick: 51_236,
            reference_urad: i32::MIN,
            link_angle_urad: i32::MAX,
            gear_angle_urad: -1,
            current_ma: i16::MIN,
            torque_unm: i32::MAX,
            duty_permille: -1000,
            faults: FaultSet(1 << 9 | 1 << 3),
            limits: LimitFlags(LimitFlags::TORQUE | LimitFlags::DUTY),
        },
        TelemetrySample {
            tick: u32::MAX,
            current_ma: i16::MAX,
            duty_permille: 1000,
            ..TelemetrySample::default()
        },
    ]
}

#[test]
fn round_trip_is_exact() {
    let s = samples();
    let mut out = Vec::new();
    write_csv(&mut out, &s).unwrap();
    let text = String::from_utf8(out.clone()).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some(HEADER));
    assert_eq!(
        lines.next(),
        Some("0.000,51234,0.500000,0.499871,0.503310,0.212,-0.041230,0.087,0,0")
    );
    assert_eq!(
        lines.next(),
        Some("0.002,51236,-2147.483648,2147.483647,-0.000001,-32.768,2147.483647,-1.000,520,5")
    );
    assert_eq!(read_csv(out.as_slice()).unwrap(), s);
}

#[test]
fn table_reads_si_columns() {
    let mut out = Vec::new();
    write_csv(&mut out, &samples()).unwrap();
    let t = read_table(out.as_slice()).unwrap();
    assert_eq!(t.columns.len(), 10);
    assert_eq!(t.column("t_s").unwrap(), vec![0.0, 0.002, 4_294_916.061]);
    assert_eq!(t.column("current_a").unwrap()[0], 0.212);
    assert!(t.column("nope").is_none());
}

#[test]
fn columns_are_found_by_name_and_flags_are_optional() {
    let text = "duty,tick,torque_nm,current_a,gear_angle_rad,link_angle_rad,reference_rad\n\
                0.5,10,1e-6,-0.001,0,.25,-0.5\n";
    let s = read_csv(text.as_bytes()).unwrap();
    assert_eq!(
        s,
        vec![TelemetrySample {
            tick: 10,
            reference_urad: -500_000,
            link_angle_urad: 250_000,
            gear_angle_urad: 0,
            current_ma: -1,
            torque_unm: 1,
            duty_permille: 500,
            faults: FaultSet::EMPTY,
            limits: LimitFlags::NONE,
        }]
    );
}

fn csv_err(text: &str) -> (usize, String) {
    match read_csv(text.as_bytes()) {
        Err(Error::Csv { line, reason }) => (line, reason),
        other => panic!("{other:?}"),
    }
}

#[test]
fn errors_name_the_line_and_column() {
    assert_eq!(csv_err("").0, 1);
    let (line, why) = csv_err("t_s,tick\n0,1\n");
    assert_eq!(line, 1);
    assert!(why.contains("no column 'reference_rad'"), "{why}");
    let good = format!("{HEADER}\n0,1,0,0,0,0,0,0,0,0\n");
    assert!(read_csv(good.as_bytes()).is_ok());
    let (line, why) = csv_err(&format!("{good}0,2,x,0,0,0,0,0,0,0\n"));
    assert_eq!(line, 3);
    assert!(
        why.contains("'reference_rad': 'x' is not a number"),
        "{why}"
    );
    let (line, why) = csv_err(&format!("{good}0,3,0,0\n"));
    assert_eq!(line, 3);
    assert!(why.contains("4 cells, the header has 10"), "{why}");
    let (_, why) = csv_err(&format!("{good}0,4,0,0,0,40,0,0,0,0\n"));
    assert!(why.contains("'current_a': 40000 does not fit"), "{why}");
    let (_, why) = csv_err(&format!("{good}0,-5,0,0,0,0,0,0,0,0\n"));
    assert!(why.contains("'tick'"), "{why}");
}
