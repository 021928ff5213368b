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
//! --nocapture`; `seed_sweep` (ignored) totals the grids of many seeds, `VSA_GRID_SEEDS=A-B,…`. Limits not yet met are listed in [`OPEN`]: they are measured and
//! printed but only enforced with `VSA_GRID_STRICT=1`.

use host_tests::env_or;
use host_tests::grid::{self, Outcome};
use host_tests::grid_tally::Tally;
use plant::overrides::Override;

/// Metrics whose limit the controller does not meet on every case yet (printed with their
/// worst case and the number of violations; enforced only under `VSA_GRID_STRICT=1`).
/// Each is still violated on the default draw (docs/design.md §11, "Not reached yet"):
/// overshoot, settling, steady-state error and both rest spans by runs without load (the
/// link bounces in the free play), raw-step settling at soft settings with heavy links and
/// for small steps (the planned profile of `model::control::dash` leaves the loop too
/// little time there). An entry leaves this list when its metric holds on the long run.
const OPEN: &[&str] = &[
    grid::OVERSHOOT,
    grid::SETTLING,
    grid::STEADY_STATE,
    grid::REST_COUNT_SPAN,
    grid::REST_DUTY_SPAN,
    grid::RAW_STEP_BOUND,
];

/// Open on the off-nominal grid only: peak stress by free-play impacts of links heavier
/// than configured, faults and stress after a trip by runs whose impacts overload the
/// beams. With the nominal actuator they hold on the long run (5 000 cases: no fault, worst
/// peak stress 0.907 σ_allow; booted under its load 0.930) and are enforced.
const OPEN_OFF_NOMINAL: &[&str] = &[grid::PEAK_STRESS, grid::FAULTS, grid::STRESS_AFTER_TRIP];

/// `VSA_GRID_CLUTCH_TOLERANCE_UM`, µm (0 by default).
fn clutch_tolerance_um() -> u32 {
    env_or("VSA_GRID_CLUTCH_TOLERANCE_UM", 0) as u32
}

/// Whether the cases power the board up under their load: `wanted`, or every grid's under
/// `VSA_GRID_BOOT_UNDER_LOAD=1`.
fn booted_under_load(wanted: bool) -> bool {
    wanted || std::env::var("VSA_GRID_BOOT_UNDER_LOAD").is_ok_and(|v| v == "1")
}

/// The grid's cases for `seed`, each run, with the `VSA_GRID_*` settings of the module's
/// documentation.
fn outcomes(seed: u64, off_nominal: bool, boot_under_load: bool) -> Vec<Outcome> {
    let n = env_or("VSA_GRID_RUNS", 250) as usize;
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
    let tolerance_um = clutch_tolerance_um();
    grid::cases(n, seed, off_nominal)
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
        .collect()
}

fn sweep(label: &str, off_nominal: bool, seed_offset: u64, boot_under_load: bool) {
    let seed = env_or("VSA_GRID_SEED", 1) + seed_offset;
    let strict = std::env::var("VSA_GRID_STRICT").is_ok_and(|v| v == "1");
    let started = std::time::Instant::now();
    let tolerance_um = clutch_tolerance_um();
    let boot_under_load = booted_under_load(boot_under_load);
    let outcomes = outcomes(seed, off_nominal, boot_under_load);
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

/// `VSA_GRID_SEEDS`: comma-separated seeds and inclusive ranges, e.g. `101-130,201-230`
/// (default `101-130`).
fn seed_spec() -> String {
    std::env::var("VSA_GRID_SEEDS").unwrap_or_else(|_| "101-130".into())
}

/// The seeds of a [`seed_spec`].
fn seeds(spec: &str) -> Vec<u64> {
    spec.split(',')
        .filter(|p| !p.is_empty())
        .flat_map(|p| {
            let (a, b) = p.split_once('-').unwrap_or((p, p));
            match (a.trim().parse::<u64>(), b.trim().parse::<u64>()) {
                (Ok(a), Ok(b)) if a <= b => a..=b,
                _ => panic!("VSA_GRID_SEEDS: {p} is not a seed or a range A-B"),
            }
        })
        .collect()
}

/// The long sweep behind the figures of docs/design.md §11 that count runs over many draws:
/// for each seed in `VSA_GRID_SEEDS` the nominal grid of that seed and the off-nominal grid
/// of the seed plus 1 000 000 (as `VSA_GRID_SEED` does), the other `VSA_GRID_*` settings as
/// above, totals printed per grid. Not in `cargo xtask test` (90 seeds take about 70 s on
/// two cores): `VSA_GRID_SEEDS=101-130 cargo test --release -p host-tests --test grid --
/// --ignored --nocapture seed_sweep`.
#[test]
#[ignore = "long run: VSA_GRID_SEEDS=101-130 … -- --ignored --nocapture seed_sweep"]
fn seed_sweep() {
    let spec = seed_spec();
    let seeds = seeds(&spec);
    let boot_under_load = booted_under_load(false);
    let threads = std::thread::available_parallelism().map_or(1, usize::from);
    let started = std::time::Instant::now();
    for (label, off_nominal, offset) in [
        ("nominal actuator", false, 0),
        ("off-nominal actuator", true, 1_000_000),
    ] {
        let next = std::sync::atomic::AtomicUsize::new(0);
        let tallies: Vec<Tally> = std::thread::scope(|scope| {
            let workers: Vec<_> = (0..threads)
                .map(|_| {
                    scope.spawn(|| {
                        let mut tally = Tally::default();
                        loop {
                            let k = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                            let Some(seed) = seeds.get(k) else {
                                return tally;
                            };
                            for o in outcomes(seed + offset, off_nominal, boot_under_load) {
                                tally.add(&o);
                            }
                        }
                    })
                })
                .collect();
            workers
                .into_iter()
                .map(|w| w.join().expect("worker"))
                .collect()
        });
        let mut total = Tally::default();
        for t in &tallies {
            total.merge(t);
        }
        print!(
            "{}",
            total.report(&format!("{label}, {} seeds ({spec})", seeds.len()))
        );
    }
    println!("in {:.0} s", started.elapsed().as_secs_f64());
}

/// The tally's counts on seed 1's nominal draw against the grid's own verdicts
/// ([`grid::metric`]) and, for the runs without load, against the harness metrics read
/// directly with the grid's limits.
#[test]
fn tally_counts_the_grids_verdicts() {
    let outcomes = outcomes(1, false, false);
    let mut tally = Tally::default();
    for o in &outcomes {
        tally.add(o);
    }
    // Counted again in two halves and merged: the sweep's threads do that.
    let (a, b) = outcomes.split_at(outcomes.len() / 2);
    let (mut ta, mut tb) = (Tally::default(), Tally::default());
    a.iter().for_each(|o| ta.add(o));
    b.iter().for_each(|o| tb.add(o));
    ta.merge(&tb);
    assert_eq!(tally.runs, outcomes.len());
    assert_eq!(ta.runs, tally.runs);
    for (k, name) in outcomes[0].figures().map(|f| f.0).iter().enumerate() {
        let bad = grid::metric(&outcomes, k).1.len();
        assert_eq!(tally.violations(name), Some(bad), "{name}");
        assert_eq!(ta.violations(name), Some(bad), "{name}, merged");
    }
    let unloaded: Vec<_> = outcomes.iter().filter(|o| o.case.load_nm == 0.0).collect();
    let at_rest = |o: &Outcome| {
        o.metrics.steady_count_span <= grid::COUNT_SPAN_MAX
            && o.metrics.steady_duty_span <= grid::DUTY_SPAN_MAX
    };
    let within = |o: &Outcome| {
        at_rest(o) && o.metrics.steady_state_error_counts <= grid::STEADY_ERROR_MAX_COUNTS
    };
    let settled = |o: &Outcome| o.settle_s() <= o.settle_limit_s;
    assert!(!unloaded.is_empty());
    assert_eq!(tally.unloaded, unloaded.len());
    assert_eq!(
        tally.unloaded_at_rest,
        unloaded.iter().filter(|o| at_rest(o)).count()
    );
    assert_eq!(
        tally.unloaded_at_rest_within,
        unloaded.iter().filter(|o| within(o)).count()
    );
    assert_eq!(
        tally.unloaded_settled,
        unloaded.iter().filter(|o| settled(o)).count()
    );
    assert_eq!(ta.unloaded_settled, tally.unloaded_settled);
    let every_but_raw = outcomes
        .iter()
        .filter(|o| {
            let m = &o.metrics;
            m.overshoot_pct <= grid::OVERSHOOT_MAX_PCT
                && settled(o)
                && within(o)
                && m.peak_stress_ratio <= grid::STRESS_MAX_RATIO
                && m.faults.is_empty()
        })
        .count();
    assert_eq!(tally.every_limit_but_raw, every_but_raw);
    assert_eq!(ta.every_limit_but_raw, every_but_raw);
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
