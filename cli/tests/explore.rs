//! `vsa explore` end to end: the built binary's designs against the f64 oracle
//! (`host_tests::oracle`, independent of the model), a brute-force check of its verdicts and
//! of its Pareto front on a small grid, the paper's goals, bad input.

use host_tests::oracle;
use serde_json::Value;

mod common;

fn vsa(args: &[&str]) -> std::process::Output {
    common::vsa("explore", args)
}

fn json(args: &[&str]) -> Value {
    common::json("explore", args)
}

use common::num;

fn close(got: f64, want: f64) -> bool {
    (got - want).abs() <= 1e-6 * want.abs() + 1e-12
}

/// (E, σ_allow, ρ) of a material by key, from the tool's own `materials` list (the values
/// the oracle then uses independently).
fn material(found: &Value, key: &str) -> (f64, f64, f64) {
    let m = found["materials"]
        .as_array()
        .unwrap()
        .iter()
        .find(|m| m["key"] == key)
        .unwrap();
    (
        num(m, "modulus_pa"),
        num(m, "allowable_stress_pa"),
        num(m, "density_kg_m3"),
    )
}

fn oracle_design(found: &Value, d: &Value) -> (oracle::Design, f64) {
    let (e, s, rho) = material(found, d["material"].as_str().unwrap());
    let o = oracle::Design {
        n: d["beams"].as_u64().unwrap() as u32,
        r: num(d, "beam_radius_m"),
        pitch_r: num(d, "pitch_radius_m"),
        e,
        g: e / 2.6,
        sigma_allow: s,
        l: num(d, "active_length_max_m"),
        t_c: num(d, "active_length_min_m"),
        mu: 0.4,
    };
    (o, rho)
}

/// A small grid with goals relaxed so that some designs pass.
const SMALL: &[&str] = &[
    "--materials",
    "spring-steel,glass-fibre,titanium",
    "--beams",
    "3,4,6",
    "--beam-radii",
    "0.2mm..1.2mm:0.1mm",
    "--pitch-radii",
    "2mm..12mm:1mm",
    "--active-lengths",
    "3mm..8mm:1mm",
    "--min-capacity",
    "0.4117Nm",
    "--min-deflection",
    "0.0413rad",
    "--max-mass",
    "0.97g",
    "--max-volume",
    "3.9cm3",
];

#[test]
fn every_design_matches_the_oracle_and_its_verdict() {
    let mut args = SMALL.to_vec();
    args.push("--all");
    let v = json(&args);
    let designs = v["designs"].as_array().unwrap();
    // The grid: 3 materials × 3 beam counts × 11 radii × 11 pitch radii × 6 lengths, less
    // the combinations with R ≤ r that are not designs.
    let mut expected = 0;
    for _m in 0..3 {
        for _n in 0..3 {
            for ri in 2..=12 {
                for ki in 2..=12 {
                    if ki * 10 > ri {
                        expected += 6;
                    }
                }
            }
        }
    }
    assert_eq!(designs.len(), expected);
    assert_eq!(num(&v, "evaluated") as usize, expected);
    let (mut feasible, mut infeasible) = (0, 0);
    for d in designs {
        let (o, rho) = oracle_design(&v, d);
        let total = num(d, "beam_length_m");
        let cap = o.torque_capacity(o.l);
        let defl = o.deflection_capacity_closed_form(o.l);
        let mass = o.beam_mass(total, rho);
        let volume = o.envelope_volume(total);
        assert!(close(num(d, "capacity_nm"), cap), "{d}");
        assert!(close(num(d, "deflection_capacity_rad"), defl), "{d}");
        assert!(close(num(d, "energy_j"), o.energy_at_capacity(o.l)), "{d}");
        assert!(close(num(d, "mass_kg"), mass), "{d}");
        assert!(close(num(d, "volume_m3"), volume), "{d}");
        assert!(
            close(num(d, "stiffness_min_nm_per_rad"), o.stiffness(o.l)),
            "{d}"
        );
        assert!(
            close(num(d, "stiffness_max_nm_per_rad"), o.stiffness(o.t_c)),
            "{d}"
        );
        assert!(
            close(num(d, "capacity_stiff_nm"), o.torque_capacity(o.t_c)),
            "{d}"
        );
        assert_eq!(d["fits"].as_bool().unwrap(), o.slots_fit(), "{d}");
        let margins = [
            cap / 0.4117 - 1.0,
            defl / 0.0413 - 1.0,
            1.0 - mass / 0.97e-3,
            1.0 - volume / 3.9e-6,
        ];
        // The goals are off the grid's round numbers: no design sits on a bound.
        assert!(margins.iter().all(|m| m.abs() > 1e-9), "{d}");
        let meets = o.slots_fit() && margins.iter().all(|&m| m > 0.0);
        assert_eq!(d["meets_constraints"].as_bool().unwrap(), meets, "{d}");
        if meets {
            feasible += 1;
        } else {
            infeasible += 1;
        }
    }
    assert!(
        feasible > 20 && infeasible > 1000,
        "{feasible} / {infeasible}"
    );
    assert_eq!(num(&v, "feasible") as usize, feasible);
    assert!(v["binding"].is_null());

    // Pareto front, brute force: among the designs within the envelope, a design is
    // on the front if and only if no other is at least as good in all three and better
    // in one.
    let pool: Vec<(f64, f64, f64)> = designs
        .iter()
        .filter(|d| {
            d["fits"].as_bool().unwrap()
                && num(d, "volume_m3") <= 3.9e-6
                && num(d, "mass_kg") <= 0.97e-3
        })
        .map(|d| {
            (
                num(d, "capacity_nm"),
                num(d, "deflection_capacity_rad"),
                num(d, "mass_kg"),
            )
        })
        .collect();
    let dominated = |p: (f64, f64, f64)| {
        pool.iter().any(|q| {
            q.0 >= p.0 && q.1 >= p.1 && q.2 <= p.2 && (q.0 > p.0 || q.1 > p.1 || q.2 < p.2)
        })
    };
    let front: Vec<(f64, f64, f64)> = v["pareto"]
        .as_array()
        .unwrap()
        .iter()
        .map(|d| {
            (
                num(d, "capacity_nm"),
                num(d, "deflection_capacity_rad"),
                num(d, "mass_kg"),
            )
        })
        .collect();
    for p in &front {
        assert!(!dominated(*p), "{p:?} is dominated");
    }
    let undominated = pool.iter().filter(|p| !dominated(**p)).count();
    // Equal triples count once on the front.
    let mut distinct = pool.clone();
    distinct.retain(|p| !dominated(*p));
    distinct.sort_by(|a, b| a.partial_cmp(b).unwrap());
    distinct.dedup();
    assert!(
        front.len() == distinct.len() && undominated >= front.len(),
        "{} vs {}",
        front.len(),
        distinct.len()
    );
}

#[test]
fn ranked_designs_meet_every_constraint_best_margin_first() {
    let v = json(SMALL);
    let designs = v["designs"].as_array().unwrap();
    assert_eq!(designs.len(), 10);
    let mut last = f64::INFINITY;
    for d in designs {
        assert!(d["meets_constraints"].as_bool().unwrap());
        let m = num(d, "margin");
        assert!(m >= 0.0 && m <= last, "{m} after {last}");
        last = m;
    }
}

#[test]
fn the_papers_goals_are_out_of_reach_and_say_why() {
    // The paper's goals (the defaults), coarser steps than the default grid.
    let v = json(&[
        "--beam-radii",
        "0.1mm..2mm:0.1mm",
        "--pitch-radii",
        "2mm..14mm:1mm",
    ]);
    assert_eq!(num(&v, "feasible"), 0.0);
    let binding = v["binding"].as_str().unwrap();
    assert!(
        binding == "deflection" || binding == "capacity",
        "{binding}"
    );
    // Dropping the deflection or the capacity goal alone frees designs; the mass and
    // volume goals are not what stands in the way.
    assert!(v["relaxed"]["deflection"].as_u64().unwrap() > 0);
    assert!(v["relaxed"]["capacity"].as_u64().unwrap() > 0);
    assert_eq!(v["relaxed"]["mass"].as_u64().unwrap(), 0);
    assert_eq!(v["relaxed"]["volume"].as_u64().unwrap(), 0);
    // Every material would need more active length than the 8 mm the envelope leaves,
    // by the oracle's own closed form.
    for m in v["materials"].as_array().unwrap() {
        let l = oracle::min_active_length(
            1.5,
            0.2,
            num(m, "modulus_pa"),
            num(m, "allowable_stress_pa"),
        );
        assert!(close(num(m, "min_active_length_m"), l), "{m}");
        assert!(l > 8e-3, "{m}");
    }
    // The closest designs are listed, none meeting the goals.
    let designs = v["designs"].as_array().unwrap();
    assert!(!designs.is_empty());
    assert!(designs
        .iter()
        .all(|d| !d["meets_constraints"].as_bool().unwrap()));
    // With 10 mm of active length (12 mm beams) glass fibre gets there.
    let v = json(&[
        "--max-beam-length",
        "12mm",
        "--materials",
        "glass-fibre",
        "--beam-radii",
        "0.1mm..2mm:0.1mm",
        "--pitch-radii",
        "2mm..14mm:0.5mm",
        "--active-lengths",
        "9mm,10mm",
    ]);
    assert!(num(&v, "feasible") > 0.0, "{}", v["designs"]);
    assert!(v["binding"].is_null());
}

#[test]
fn figure_and_table() {
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("region.png");
    let mut args = SMALL.to_vec();
    args.extend(["--figure", png.to_str().unwrap()]);
    let out = vsa(&args);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(std::fs::metadata(&png).unwrap().len() > 10_000);
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(text.contains("Designs meeting every constraint"), "{text}");
    assert!(text.contains("Pareto front"), "{text}");
    // No temporary file left beside it.
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
}

#[test]
fn bad_input_is_one_line_and_exit_2() {
    let dir = tempfile::tempdir().unwrap();
    let txt = dir.path().join("region.txt");
    for (args, arg) in [
        (vec!["--min-capacity", "-1Nm"], "--min-capacity"),
        (vec!["--min-deflection", "0.2"], "--min-deflection"),
        (vec!["--max-mass", "5kgm2"], "--max-mass"),
        (vec!["--materials", "unobtainium"], "--materials"),
        (vec!["--beams", "0"], "--beams"),
        (vec!["--beam-radii", "1mm..0.5mm:0.1mm"], "--beam-radii"),
        (vec!["--pitch-radii", "20mm"], "--pitch-radii"),
        (vec!["--max-beam-length", "2mm"], "--max-beam-length"),
        (
            vec![
                "--figure",
                txt.to_str().unwrap(),
                "--beams",
                "4",
                "--beam-radii",
                "0.5mm",
                "--pitch-radii",
                "8mm",
                "--active-lengths",
                "5mm",
            ],
            "--figure",
        ),
    ] {
        let out = vsa(&args);
        assert_eq!(out.status.code(), Some(2), "{args:?}");
        assert!(out.stdout.is_empty(), "{args:?}");
        let err = String::from_utf8(out.stderr).unwrap();
        assert_eq!(err.lines().count(), 1, "{err}");
        assert!(err.starts_with(&format!("error: {arg}: ")), "{err}");
    }
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
}
