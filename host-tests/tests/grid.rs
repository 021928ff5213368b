//! The position controller's acceptance grid (see `host_tests::grid`): seeded random
//! cases over clutch length 1…8 mm, link inertia 0.3e-3…5e-3 kg·m², load −0.3…+0.3 N·m
//! (a quarter of the cases exactly 0), raw steps and minimum-jerk moves of 0.05…0.6 rad
//! in both directions; once with the nominal actuator and once off-nominal (docs/design.md §9:
//! resistance ×0.8…×1.4, k_t and k_e ×0.9…×1.1, gear inertia ×0.8…×1.25, gear friction
//! ×0.5…×3, supply 10.5…12.6 V, current offset ±20 counts and gain ±5 %, pot offset ±3
//! counts, link inertia ×0.5…×3 of the configured one). Every metric's worst case is
//! printed (`-- --nocapture`) with the `vsa simulate` arguments that rerun it exactly (add
//! `--csv FILE` for every tick); any violation fails.
//!
//! `VSA_GRID_RUNS=N` (default 250 per grid, 500 in all) and `VSA_GRID_SEED=S` change the
//! draw; `VSA_GRID_MAX_LOAD=T` keeps only the drawn cases with |load| ≤ T N·m (a fast subset
//! while tuning, e.g. `0` for the runs without load); `VSA_GRID_PLANT=NAME=VALUE[,…]`
//! changes every case's simulated actuator too (the names of `vsa simulate --plant`, e.g.
//! `link-friction=0.002Nm` for an output bearing with dry friction);
//! `VSA_GRID_CLUTCH_TOLERANCE_UM=1000` runs every case with the clutch tolerance a board
//! takes until a calibration confirms the clutch (the weak capacity and the clutch
//! monitor, docs/calibration.md). `nominal_actuator_grid_booted_under_its_load` runs the
//! nominal cases on a board powered up with the load hanging, `VSA_GRID_BOOT_UNDER_LOAD=1`
//! every grid's cases (their dump files `PREFIX.boot-under-load.SEED.tsv`).
//! The long run is `VSA_GRID_RUNS=5000 cargo test --release -p host-tests --test grid --
//! --nocapture`. Limits not yet met are listed in [`OPEN`]: they are measured and
//! printed but only enforced with `VSA_GRID_STRICT=1`.

use host_tests::env_or;
use host_tests::grid::{self, Outcome};
use plant::overrides::Override;

/// Metrics whose limit the controller does not meet on every case yet (printed with their
/// worst case and the number of violations; enforced only under `VSA_GRID_STRICT=1`).
/// Each is still violated on the default draw (docs/design.md §11, "Not reached yet"):
/// overshoot, settling, steady-state error and both rest spans by runs without load (the
/// link bounces in the free play), raw-step settling at soft settings with heavy links and
/// for small steps (the planned profile of `model::control::dash` leaves the loop too
/// little time there). An entry leaves this list when its metric holds on the long run.
const OPEN: &[&str] = &[
    "overshoot %",
    grid::SETTLING,
    "steady-state error counts",
    "rest count span",
    "rest duty span ‰",
    grid::RAW_STEP_BOUND,
];

/// Open on the off-nominal grid only: peak stress by free-play impacts of links heavier
/// than configured, faults and stress after a trip by runs whose impacts overload the
/// beams. With the nominal actuator they hold on the long run (5 000 cases: no fault, worst
/// peak stress 0.907 σ_allow; booted under its load 0.930) and are enforced.
const OPEN_OFF_NOMINAL: &[&str] = &[
    "peak stress / σ_allow",
    "faults latched",
    "stress after a trip / σ_allow",
];

fn sweep(label: &str, off_nominal: bool, seed_offset: u64, boot_under_load: bool) {
    let n = env_or("VSA_GRID_RUNS", 250) as usize;
    let seed = env_or("VSA_GRID_SEED", 1) + seed_offset;
    let strict = std::env::var("VSA_GRID_STRICT").is_ok_and(|v| v == "1");
    let started = std::time::Instant::now();
    let max_load = std::env::var("VSA_GRID_MAX_LOAD")
        .ok()
        .and_then(|v| v.parse::<f64>().ok())
        .unwrap_or(f64::INFINITY);
    let extra: Vec<Override> = std::env::var("VSA_GRID_PLANT")
        .unwrap_or_default()
        .split(',')
        .filter(|o| !o.is_empty())
        .map(|o| Override::parse(o).unwrap_or_else(|e| panic!("VSA_GRID_PLANT {o}: {e}")))
        .collect();
    let tolerance_um = env_or("VSA_GRID_CLUTCH_TOLERANCE_UM", 0) as u32;
    let boot_under_load =
        boot_under_load || std::env::var("VSA_GRID_BOOT_UNDER_LOAD").is_ok_and(|v| v == "1");
    let outcomes: Vec<Outcome> = grid::cases(n, seed, off_nominal)
        .into_iter()
        .enumerate()
        .filter(|(_, c)| c.load_nm.abs() <= max_load)
        .map(|(i, mut c)| {
            for o in &extra {
                c.plant.set(*o);
            }
            c.clutch_tolerance_um = tolerance_um;
            c.boot_under_load = boot_under_load;
            grid::run(i, &c)
        })
        .collect();
    println!(
        "{label}: {} cases (seed {seed}, clutch tolerance {tolerance_um} µm) in {:.1} s",
        outcomes.len(),
        started.elapsed().as_secs_f64()
    );
    let names = outcomes[0].figures().map(|f| f.0);
    if let Some(path) = std::env::var("VSA_GRID_DUMP")
        .ok()
        .filter(|p| !p.is_empty())
    {
        let boot = if boot_under_load {
            ".boot-under-load"
        } else {
            ""
        };
        dump(&format!("{path}{boot}.{seed}.tsv"), &names, &outcomes);
    }
    let open_here =
        |name: &str| OPEN.contains(&name) || (off_nominal && OPEN_OFF_NOMINAL.contains(&name));
    for o in OPEN.iter().chain(OPEN_OFF_NOMINAL) {
        assert!(names.contains(o), "OPEN names an unknown metric: {o}");
    }
    let mut failed = Vec::new();
    for (k, name) in names.iter().enumerate() {
        let (worst, bad) = grid::metric(&outcomes, k);
        let (_, value, limit, _) = worst.figures()[k];
        let open = open_here(name);
        println!(
            "  {name:<28} worst {value:>9.3} (limit {limit}) in case #{}: {}; violations {}/{}{}",
            worst.index,
            worst.case,
            bad.len(),
            outcomes.len(),
            if open && !strict {
                " [open: not enforced]"
            } else {
                ""
            }
        );
        println!("      rerun: vsa simulate {}", worst.case.simulate_args());
        if !bad.is_empty() && (!open || strict) {
            failed.push(*name);
        }

        for o in bad.iter().take(3) {
            let m = &o.metrics;
            println!(
                "      #{} {}: overshoot {:.2} %, settle {:.0} ms (limit {:.0}, T_opt {:.0}), \
                 ss {:.2}, spans {} counts {} ‰, stress {:.3}, faults {}",
                o.index,
                o.case,
                m.overshoot_pct,
                o.settle_s() * 1e3,
                o.settle_limit_s * 1e3,
                o.t_opt_s * 1e3,
                m.steady_state_error_counts,
                m.steady_count_span,
                m.steady_duty_span,
                m.peak_stress_ratio,
                grid::fault_names(m)
            );
        }
    }
    assert!(failed.is_empty(), "{label}: limits violated: {failed:?}");
}

/// Writes one line per case (its figures, the case, the `vsa simulate` arguments that rerun
/// it) for tuning: `VSA_GRID_DUMP=PREFIX` writes `PREFIX.SEED.tsv`.
fn dump(path: &str, names: &[&str], outcomes: &[Outcome]) {
    let mut text = format!(
        "index\tload_nm\t{}\tfirst fault\tcase\tvsa simulate\n",
        names.join("\t")
    );
    for o in outcomes {
        let values: Vec<String> = o.figures().iter().map(|f| format!("{:.3}", f.1)).collect();
        let first = o.metrics.first_fault.map_or("-".into(), |f| {
            format!("{} {} at tick {}", f.code.name(), f.value, f.tick)
        });
        text.push_str(&format!(
            "{}\t{:.3}\t{}\t{first}\t{}\t{}\n",
            o.index,
            o.case.load_nm,
            values.join("\t"),
            o.case,
            o.case.simulate_args()
        ));
    }
    std::fs::write(path, text).expect("VSA_GRID_DUMP writable");
}

#[test]
fn nominal_actuator_grid() {
    sweep("nominal actuator", false, 0, false);
}

#[test]
fn off_nominal_actuator_grid() {
    sweep("off-nominal actuator", true, 1_000_000, false);
}

/// The nominal grid's cases on a board powered up with the load already hanging: the link
/// falls while the boot window keeps the bridge off, and the servo catches it before the
/// hold (docs/design.md §11, "The boot window before the hold"). The nominal grid's enforced
/// limits hold.
#[test]
fn nominal_actuator_grid_booted_under_its_load() {
    sweep("nominal actuator, booted under its load", false, 0, true);
}

#[test]
fn time_optimal_bound_matches_the_design_brief() {
    // docs/design.md §10: 0.5 rad with J_l = 1e-3: 107 ms; 0.3 rad: 74 ms; 0.5 rad with
    // J_l = 3e-3: 119 ms (any L where the beams do not limit: 3 mm).
    for (h, j, want_ms) in [(0.5, 1e-3, 107.0), (0.3, 1e-3, 74.0), (0.5, 3e-3, 119.0)] {
        let t = grid::RigidActuator::nominal(j, 3e-3).time_optimal_s(h) * 1e3;
        println!("time-optimal {h} rad, J_l {j:e}: {t:.2} ms");
        assert!(
            (t - want_ms).abs() < 0.6,
            "{h} rad, {j}: {t} ms vs {want_ms}"
        );
    }
    // Where the beams limit, the bound is longer: L = 8 mm, J_l = 5e-3 (τ_lim = 0.49 N·m).
    let soft = grid::RigidActuator::nominal(5e-3, 8e-3);
    let stiff = grid::RigidActuator::nominal(5e-3, 1e-3);
    assert!(soft.time_optimal_s(0.5) > stiff.time_optimal_s(0.5) + 0.01);
}
