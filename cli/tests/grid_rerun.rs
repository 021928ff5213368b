//! The acceptance grid's cases rerun exactly with `vsa simulate`: the arguments the grid
//! prints for a case (`host_tests::grid::Case::simulate_args`) give the same run as the
//! grid's own (docs/tools.md, "Closed loop on the host").

#[allow(dead_code)] // num() serves the other tests
mod common;

use host_tests::grid;

/// Cases of both grids (raw steps and moves, loads and none, off-nominal actuators) and
/// one with the clutch tolerance: every figure `vsa simulate --json` reports is the grid's
/// (to the last digit JSON keeps: serde_json reads a float back within an ulp or two).
#[test]
fn grid_cases_rerun_with_vsa_simulate() {
    let mut cases: Vec<grid::Case> = grid::cases(4, 1, false);
    cases.extend(grid::cases(6, 1_000_001, true));
    let mut tolerant = cases[5];
    tolerant.clutch_tolerance_um = 1000;
    cases.push(tolerant);
    for (i, case) in cases.iter().enumerate() {
        let args = case.simulate_args();
        let argv: Vec<&str> = args.split(' ').collect();
        let v = common::json("simulate", &argv);
        let m = grid::run(i, case).metrics;
        let same = |k: &str, want: Option<f64>| {
            let got = v[k].as_f64();
            let want = want.filter(|x| x.is_finite());
            let ok = match (got, want) {
                (Some(a), Some(b)) => (a - b).abs() <= 1e-12 * b.abs().max(1.0),
                (a, b) => a == b,
            };
            assert!(ok, "{k}: vsa simulate {got:?}, grid {want:?}: {args}");
        };
        same("overshoot_pct", Some(m.overshoot_pct));
        same(
            "steady_state_error_counts",
            Some(m.steady_state_error_counts),
        );
        same("peak_stress_ratio", Some(m.peak_stress_ratio));
        same("settling_time_s", m.settling_time_s);
        assert_eq!(
            v["steady_count_span"].as_i64(),
            Some(i64::from(m.steady_count_span)),
            "{args}"
        );
        assert_eq!(
            v["steady_duty_span"].as_i64(),
            Some(i64::from(m.steady_duty_span)),
            "{args}"
        );
        let faults: Vec<&str> = v["faults"]
            .as_array()
            .expect("faults")
            .iter()
            .filter_map(|x| x.as_str())
            .collect();
        let faults = if faults.is_empty() {
            "none".to_string()
        } else {
            faults.join(",")
        };
        assert_eq!(faults, grid::fault_names(&m), "{args}");
    }
}
