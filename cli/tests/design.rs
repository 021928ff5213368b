//! `vsa design` end to end: the built binary against docs/design.md §2.2 and the model crate.

use std::collections::BTreeSet;
use std::process::{Command, Output};

use fixed::types::I32F32;
use model::{Design, Length, Torque};
use serde_json::Value;

fn vsa(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_vsa"))
        .args(args)
        .output()
        .expect("run vsa")
}

fn design(args: &[&str]) -> Output {
    let mut all = vec!["design"];
    all.extend_from_slice(args);
    vsa(&all)
}

fn ok_stdout(args: &[&str]) -> String {
    let out = design(args);
    assert!(
        out.status.success(),
        "vsa design {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap()
}

fn json(args: &[&str]) -> Value {
    let mut a = args.to_vec();
    a.push("--json");
    let out = design(&a);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(out.stderr.is_empty(), "JSON mode wrote to stderr");
    serde_json::from_slice(&out.stdout).expect("stdout is one JSON document")
}

fn keys(v: &Value) -> BTreeSet<String> {
    v.as_object().unwrap().keys().cloned().collect()
}

fn set(k: &[&str]) -> BTreeSet<String> {
    k.iter().map(|s| s.to_string()).collect()
}

fn close(got: f64, want: f64, rel: f64) -> bool {
    ((got - want) / want).abs() <= rel
}

/// The table rows (lines starting with a number), split into cells.
fn rows(table: &str) -> Vec<Vec<String>> {
    table
        .lines()
        .filter(|l| l.trim_start().starts_with(|c: char| c.is_ascii_digit()))
        .map(|l| l.split_whitespace().map(str::to_string).collect())
        .collect()
}

fn num(s: &str) -> f64 {
    s.parse().unwrap_or_else(|_| panic!("not a number: {s}"))
}

#[test]
fn paper_table_matches_design_md() {
    let out = ok_stdout(&[]);
    let rows = rows(&out);
    assert_eq!(rows.len(), 5, "{out}");
    // docs/design.md §2.2: L, k, k_T, θ (°), σ (MPa), τ_cap.
    let want = [
        (1.0, 7167.5, 4680.8, 0.0160, 653.0, 4.59),
        (2.0, 895.9, 790.9, 0.128, 1306.0, 2.30),
        (3.0, 265.5, 250.7, 0.432, 1959.0, 1.53),
        (4.0, 112.0, 108.4, 1.02, 2612.0, 1.15),
        (5.0, 57.3, 56.1, 2.00, 3265.0, 0.92),
    ];
    for (r, (l, k, kt, deg, sigma, cap)) in rows.iter().zip(want) {
        assert_eq!(r.len(), 11, "{r:?}");
        assert_eq!(num(&r[0]), l);
        assert!(close(num(&r[1]), k, 1e-3), "k {r:?}");
        assert!(close(num(&r[2]), kt, 1e-3), "k_T {r:?}");
        assert!(close(num(&r[4]), deg, 6e-3), "θ° {r:?}");
        assert!((num(&r[6]) - sigma).abs() <= 1.0, "σ {r:?}");
        assert!((num(&r[8]) - cap).abs() <= 0.006, "τ_cap {r:?}");
        // Per-beam force P = 2/(4·7.8 mm) = 64.1 N; eq. 7 θ_b = 0.04·1/L.
        assert_eq!(r[5], "64.1");
        assert!(close(num(&r[10]), 0.04 / l, 3e-3), "θ_b {r:?}");
    }
    for header in [
        "I = πr⁴/4",
        "δ_max",
        "θ_max",
        "slot clearance",
        "slot radius",
        "φ_b",
    ] {
        assert!(out.contains(header), "header lacks {header}: {out}");
    }
    assert!(out.contains("0.3200 mm"), "δ_max = 0.32 mm");
}

#[test]
fn warnings_exactly_where_the_load_exceeds_capacity() {
    let warned = |args: &[&str]| -> Vec<String> {
        ok_stdout(args)
            .lines()
            .filter(|l| l.starts_with("WARNING"))
            .map(str::to_string)
            .collect()
    };
    let w = warned(&[]);
    // τ_cap = 4.59, 2.30, 1.53, 1.15, 0.92 N·m: 2 N·m overloads L = 3, 4, 5 mm.
    assert_eq!(w.len(), 3, "{w:?}");
    for (line, l) in w.iter().zip(["3.000", "4.000", "5.000"]) {
        assert!(line.starts_with(&format!("WARNING L = {l} mm: ")), "{line}");
    }
    assert_eq!(
        w[2],
        "WARNING L = 5.000 mm: 2.000 N·m exceeds the stress-limited capacity 0.919 N·m \
         (σ = 3265 MPa > σ_allow = 1500 MPa): the beams would yield"
    );
    assert_eq!(warned(&["--torque", "1Nm"]).len(), 1);
    assert!(warned(&["--torque", "500mNm"]).is_empty());
    // Exactly at the boundary: τ_cap(2 mm) = 2.297 N·m.
    let w = warned(&["--torque", "2.3Nm", "--lengths", "2mm"]);
    assert_eq!(w.len(), 1, "{w:?}");
    assert!(warned(&["--torque", "2.29Nm", "--lengths", "2mm"]).is_empty());
}

#[test]
fn json_has_exactly_the_documented_keys_and_model_values() {
    let v = json(&[]);
    assert_eq!(keys(&v), set(&["design", "torque_nm", "rows"]));
    assert_eq!(
        keys(&v["design"]),
        set(&[
            "beams",
            "beam_radius_m",
            "pitch_radius_m",
            "modulus_pa",
            "shear_modulus_pa",
            "allowable_stress_pa",
            "beam_length_m",
            "clutch_thickness_m",
        ])
    );
    let d = &v["design"];
    assert_eq!(d["beams"], 4);
    assert_eq!(d["beam_radius_m"], 0.0005);
    assert_eq!(d["pitch_radius_m"], 0.0078);
    assert_eq!(d["modulus_pa"], 2e11);
    assert_eq!(d["shear_modulus_pa"], 8e10);
    assert_eq!(d["allowable_stress_pa"], 1.5e9);
    assert_eq!(d["beam_length_m"], 0.008);
    assert_eq!(d["clutch_thickness_m"], 0.001);
    assert_eq!(v["torque_nm"], 2.0);
    let rows = v["rows"].as_array().unwrap();
    assert_eq!(rows.len(), 5);
    let model = Design::paper();
    let t = Torque::from_int(2);
    for (i, row) in rows.iter().enumerate() {
        assert_eq!(
            keys(row),
            set(&[
                "length_m",
                "stiffness_nm_per_rad",
                "stiffness_shear_nm_per_rad",
                "deflection_rad",
                "beam_force_n",
                "stress_pa",
                "torque_capacity_nm",
                "deflection_capacity_rad",
                "backlash_tilt_rad",
            ])
        );
        let len = Length::from_int(i as i32 + 1);
        let g = |k: &str| row[k].as_f64().unwrap();
        assert_eq!(g("length_m"), (i + 1) as f64 * 1e-3);
        let k = model.stiffness(len).unwrap().get().to_num::<f64>();
        assert!(close(g("stiffness_nm_per_rad"), k, 1e-9));
        let kt = model
            .stiffness_timoshenko(len)
            .unwrap()
            .get()
            .to_num::<f64>();
        assert!(close(g("stiffness_shear_nm_per_rad"), kt, 1e-9));
        let f = |x: I32F32| x.to_num::<f64>();
        let th = f(model.deflection(t, len).unwrap().get());
        assert!(close(g("deflection_rad"), th, 1e-9));
        let p = f(model.beam_force(t).unwrap().get());
        assert!(close(g("beam_force_n"), p, 1e-9));
        let s = f(model.root_stress(t, len).unwrap().get()) * 1e6;
        assert!(close(g("stress_pa"), s, 1e-9));
        let cap = f(model.torque_capacity(len).unwrap().get());
        assert!(close(g("torque_capacity_nm"), cap, 1e-9));
        let thc = f(model.deflection_capacity(len).unwrap().get());
        assert!(close(g("deflection_capacity_rad"), thc, 1e-9));
        let tb = f(model.tilt_backlash(len).unwrap().get());
        assert!(close(g("backlash_tilt_rad"), tb, 1e-9));
    }
}

#[test]
fn json_nulls_only_the_quantity_outside_its_domain() {
    let v = json(&["--lengths", "0.5mm,8mm"]);
    let jrows = v["rows"].as_array().unwrap();
    // x = 0.5 mm < t_c = 1 mm: eq. 7 is undefined there, the rest stands.
    assert!(jrows[0]["backlash_tilt_rad"].is_null());
    assert!(jrows[0]["stiffness_nm_per_rad"].is_f64());
    assert!(jrows[0]["torque_capacity_nm"].is_f64());
    assert!(close(
        jrows[1]["backlash_tilt_rad"].as_f64().unwrap(),
        0.005,
        1e-6
    ));
    let table = ok_stdout(&["--lengths", "0.5mm"]);
    let r = &rows(&table)[0];
    assert_eq!(r.last().unwrap(), "–", "{table}");
}

#[test]
fn units_and_ranges_are_equivalent_spellings() {
    let base = json(&[]);
    let same = json(&[
        "--beam-radius",
        "500um",
        "--pitch-radius",
        "7.8e-3m",
        "--modulus",
        "200e9Pa",
        "--shear-modulus",
        "80000MPa",
        "--allowable-stress",
        "1.5GPa",
        "--beam-length",
        "0.8cm",
        "--clutch-thickness",
        "1mm",
        "--friction",
        "0.4",
        "--beams",
        "4",
        "--torque",
        "2000mNm",
        "--lengths",
        "1mm,2mm,3mm,4mm,5mm",
    ]);
    assert_eq!(base, same);
    let v = json(&["--torque", "2N*m", "--lengths", "1mm..2mm:0.25mm"]);
    let ls: Vec<f64> = v["rows"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r["length_m"].as_f64().unwrap())
        .collect();
    assert_eq!(ls, [0.001, 0.00125, 0.0015, 0.00175, 0.002]);
}

#[test]
fn stiffness_250_gives_about_3_mm() {
    // (7167.5/250)^(1/3) = 3.061 mm (E–B); k_T: L³ + 0.53125·L = 28.67 → 3.003 mm.
    let v = json(&["--stiffness", "250Nm/rad"]);
    assert_eq!(
        keys(&v),
        set(&[
            "stiffness_nm_per_rad",
            "clutch_length_m",
            "clutch_length_shear_m"
        ])
    );
    assert_eq!(v["stiffness_nm_per_rad"], 250.0);
    let l = v["clutch_length_m"].as_f64().unwrap();
    let lt = v["clutch_length_shear_m"].as_f64().unwrap();
    assert!((0.00305..0.00307).contains(&l), "{l}");
    assert!((0.0030..0.00301).contains(&lt), "{lt}");
    let model = Design::paper();
    let want = model
        .clutch_length(model::Stiffness::from_int(250))
        .unwrap()
        .get()
        .to_num::<f64>();
    assert!(close(l, want * 1e-3, 1e-9));
    let text = ok_stdout(&["--stiffness", "250 N·m/rad"]);
    assert!(text.contains("L = 3.0606 mm"), "{text}");
    assert!(text.contains("L = 3.0028 mm"), "{text}");
}

#[test]
fn stiffness_outside_the_range_names_the_nearest_end() {
    let v = json(&["--stiffness", "10Nm/rad"]);
    assert!(v["clutch_length_m"].is_null());
    assert!(v["clutch_length_shear_m"].is_null());
    let text = ok_stdout(&["--stiffness", "10Nm/rad"]);
    assert!(
        text.contains("below the adjustable range")
            && text.contains("nearest end: L = l = 8 mm (softest), k = 13.999 N·m/rad"),
        "{text}"
    );
    let text = ok_stdout(&["--stiffness", "1e6Nm/rad"]);
    assert!(
        text.contains("nearest end: L = t_c = 1 mm (stiffest), k = 7167.5 N·m/rad"),
        "{text}"
    );
    assert!(text.contains("k = 4680.8 N·m/rad"), "{text}");
    // Inside the E–B range but stiffer than the shear-corrected model can go.
    let v = json(&["--stiffness", "5000Nm/rad"]);
    assert!(v["clutch_length_m"].is_f64());
    assert!(v["clutch_length_shear_m"].is_null());
}

#[test]
fn bad_input_is_one_line_on_stderr_and_exit_2() {
    let cases: &[(&[&str], &str)] = &[
        // unknown unit, bare number
        (&["--beam-radius", "0.5in"], "--beam-radius: "),
        (&["--beam-radius", "0.5"], "--beam-radius: "),
        (&["--modulus", "200"], "--modulus: "),
        (&["--torque", "2"], "--torque: "),
        (&["--stiffness", "250Nm"], "--stiffness: "),
        (&["--lengths", "1mm,2"], "--lengths: "),
        (&["--friction", "0.4mm"], "--friction: "),
        // negative values
        (&["--beam-radius", "-0.5mm"], "--beam-radius: "),
        (&["--torque", "-2Nm"], "--torque: "),
        (&["--stiffness", "-250Nm/rad"], "--stiffness: "),
        (&["--friction", "-0.1"], "--friction: "),
        // L outside (0, l]
        (&["--lengths", "0mm"], "--lengths: "),
        (&["--lengths", "9mm"], "--lengths: "),
        (&["--lengths", "1mm..9mm:1mm"], "--lengths: "),
        (&["--lengths", "5mm..1mm:1mm"], "--lengths: "),
        // designs the model rejects
        (
            &["--beam-radius", "0mm"],
            "--beam-radius: 0 mm is out of range [0.05, 5] mm",
        ),
        (
            &["--pitch-radius", "0.4mm", "--beam-radius", "0.5mm"],
            "--pitch-radius: ",
        ),
        (&["--shear-modulus", "60GPa"], "--shear-modulus: "),
        (&["--clutch-thickness", "8mm"], "--clutch-thickness: "),
        (&["--beam-length", "0.5mm"], "--beam-length: "),
        (&["--beams", "17"], "--beams: "),
        (&["--beams", "four"], "--beams: "),
        (&["--allowable-stress", "0Pa"], "--allowable-stress: "),
        // overflow
        (&["--beam-radius", "1e300m"], "--beam-radius: "),
        (&["--torque", "1e12Nm"], "--torque: "),
        (&["--stiffness", "1e40Nm/rad"], "--stiffness: "),
        (&["--lengths", "1mm..8mm:1um"], "--lengths: "),
    ];
    for (args, want) in cases {
        let out = design(args);
        let err = String::from_utf8(out.stderr).unwrap();
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(out.stdout.is_empty(), "{args:?} wrote to stdout");
        assert_eq!(err.lines().count(), 1, "{args:?}: {err}");
        assert!(
            err.starts_with(&format!("error: {want}")),
            "{args:?}: {err}"
        );
    }
    // The exact message the README shows.
    let out = design(&["--beam-radius", "0mm"]);
    assert_eq!(
        String::from_utf8(out.stderr).unwrap(),
        "error: --beam-radius: 0 mm is out of range [0.05, 5] mm\n"
    );
    // The list of accepted units is in the message.
    let out = design(&["--beam-radius", "0.5"]);
    let err = String::from_utf8(out.stderr).unwrap();
    assert!(err.contains("mm, m, cm, um"), "{err}");
}

#[test]
fn clap_usage_errors_also_exit_2() {
    for args in [
        &["--bogus"][..],
        &["--stiffness", "1Nm/rad", "--lengths", "1mm"],
        &["--beam-radius"],
    ] {
        let out = design(args);
        assert_eq!(out.status.code(), Some(2), "{args:?}");
        assert!(out.stdout.is_empty());
    }
}

#[test]
fn no_panic_on_odd_input() {
    let odd = [
        "",
        " ",
        "mm",
        "-",
        "+",
        ".",
        "e5mm",
        "1e",
        "1e-99999999999mm",
        "1e99999999999mm",
        "NaNmm",
        "infmm",
        "1,5mm",
        "0x10mm",
        "1..2",
        "..",
        "1mm..",
        "..1mm:1mm",
        "µm",
        "١mm",
        "99999999999999999999999999999999999999999999mm",
        "0.000000000000000000001mm",
        "1mm..5mm:1e-30mm",
        "1mm..5mm:-1mm",
        "-1mm..5mm:1mm",
        "1mm,,2mm",
    ];
    let args = [
        "--beams",
        "--beam-radius",
        "--pitch-radius",
        "--modulus",
        "--shear-modulus",
        "--allowable-stress",
        "--beam-length",
        "--clutch-thickness",
        "--friction",
        "--lengths",
        "--torque",
        "--stiffness",
    ];
    for a in args {
        for v in odd {
            let out = design(&[a, v]);
            let code = out.status.code();
            assert!(code == Some(0) || code == Some(2), "{a} {v:?}: {code:?}");
            if code == Some(2) {
                assert!(out.stdout.is_empty(), "{a} {v:?}");
                assert_eq!(out.stderr.iter().filter(|&&b| b == b'\n').count(), 1);
            }
        }
    }
    // Extreme but valid designs: nulls or numbers, never a panic.
    for args in [
        &["--lengths", "0.000001mm,8mm", "--torque", "2000000000Nm"][..],
        &[
            "--beam-radius",
            "5mm",
            "--pitch-radius",
            "100mm",
            "--beams",
            "16",
            "--modulus",
            "1000GPa",
            "--shear-modulus",
            "1000GPa",
            "--lengths",
            "0.001mm",
        ],
        &[
            "--beam-radius",
            "0.05mm",
            "--pitch-radius",
            "1mm",
            "--beams",
            "1",
            "--modulus",
            "1GPa",
            "--shear-modulus",
            "1GPa",
            "--beam-length",
            "100mm",
            "--lengths",
            "100mm",
        ],
    ] {
        for json in [false, true] {
            let mut a = args.to_vec();
            if json {
                a.push("--json");
            }
            let out = design(&a);
            assert_eq!(
                out.status.code(),
                Some(0),
                "{a:?}: {}",
                String::from_utf8_lossy(&out.stderr)
            );
            if json {
                let _: Value = serde_json::from_slice(&out.stdout).unwrap();
            }
        }
    }
}
