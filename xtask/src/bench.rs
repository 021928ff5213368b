//! `cargo xtask bench`: instruction counts, fixed point vs f32, footprint and stack.
//!
//! For each emulated board it builds the `vsa-firmware` crate's programs in release and
//! - runs `vsa-bench` under QEMU at `-icount shift=`[`BENCH_SHIFT`]: one instruction takes
//!   2^shift ns of virtual time and SysTick counts the core clock, so
//!   `2^shift·f_sysclk/10⁹` SysTick counts are one instruction (QEMU has no cycle counter);
//!   the program writes the counts of each benchmark as `RESULT bench` records
//!   (`firmware/src/bin/vsa-bench.rs` says what each one times and over which inputs), this
//!   converts them;
//! - reads the footprint of `vsa-control-only` (the control loop and host link without the simulated
//!   actuator) from its ELF;
//! - runs the real firmware's step sweep and reads its stack high-water mark (the firmware
//!   paints its stack at boot and writes `RESULT stack …` when the scenario ends) and
//!   its own in-situ control-step count;
//!
//! and reads the footprint of the firmware with the simulated actuator and of the
//! Nucleo-F446RE firmware. It prints markdown tables and writes
//! `target/bench/report.json`. `--quick` runs `vsa-bench` on qemu-m3 alone and prints its
//! rows.

use anyhow::{bail, Context, Result};
use object::{Object, ObjectSection, SectionFlags, SectionKind};
use serde_json::{json, Map, Value};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use crate::board::Board;
use crate::checks::{self, Expected};
use crate::cmd::target_dir;
use crate::{firmware, qemu, results, scenarios, setup, test};
use plant::scenario::ScenarioId;

/// icount shift of the benchmark runs: 128 ns per instruction, so 21.5 (M4, 168 MHz) and
/// 15.4 (M3, 120 MHz) SysTick counts per instruction.
pub const BENCH_SHIFT: u32 = 7;

/// The benchmarks `vsa-bench` logs, with their row labels.
pub const BENCHES: [(&str, &str); 14] = [
    (
        "control_step",
        "control step: sensors → servo (controller + supervisor) → H-bridge",
    ),
    (
        "control_step_unloaded",
        "control step without load (the link floats; the catch at rest)",
    ),
    ("control_step_f32", "control step, f32 port"),
    ("controller", "controller alone (`Controller::step`)"),
    ("controller_f32", "controller alone, f32 port"),
    ("stiffness", "stiffness k(L) (`Design::stiffness`)"),
    ("stiffness_f32", "k(L), f32"),
    ("inverse", "inverse L(k) (`Design::clutch_length`)"),
    ("inverse_f32", "L(k), f32 (`libm::cbrtf`)"),
    ("capacity", "capacity τ_cap(L) (`Design::torque_capacity`)"),
    (
        "capacity_check",
        "capacity check \\|τ̂\\| ≤ τ_cap (`Setting::within_capacity`)",
    ),
    (
        "speed_tracker",
        "speed tracker after the tick (`Servo::track_speed`)",
    ),
    (
        "telemetry",
        "telemetry encoding (`protocol::encode_telemetry`)",
    ),
    (
        "tick_overhead",
        "RTIC tick overhead (empty SysTick task, whole interrupt)",
    ),
];

/// One benchmark's result, instructions per call.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Insns {
    /// Calls measured.
    pub n: u64,
    /// Mean.
    pub mean: f64,
    /// Largest.
    pub max: f64,
}

/// ELF section sizes, bytes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Footprint {
    /// `.vector_table` + `.text`.
    pub text: u64,
    /// `.rodata` (and any other read-only allocated section in flash).
    pub rodata: u64,
    /// `.data` (its initial values are in flash too).
    pub data: u64,
    /// `.bss`.
    pub bss: u64,
    /// `.uninit` (RTIC's resources and queues, not zeroed at boot).
    pub uninit: u64,
}

impl Footprint {
    /// Flash: text + rodata + data.
    pub fn flash(&self) -> u64 {
        self.text + self.rodata + self.data
    }

    /// Static RAM: data + bss + uninit.
    pub fn static_ram(&self) -> u64 {
        self.data + self.bss + self.uninit
    }
}

/// Sizes of the allocated sections of `elf`: executable ones are text, writable ones with
/// contents data, writable ones without (NOBITS) bss or `.uninit`, the rest rodata.
pub fn footprint(elf: &Path) -> Result<Footprint> {
    let bytes = std::fs::read(elf).with_context(|| format!("reading {}", elf.display()))?;
    let file =
        object::File::parse(&*bytes).with_context(|| format!("parsing {}", elf.display()))?;
    let mut f = Footprint::default();
    for section in file.sections() {
        let SectionFlags::Elf { sh_flags } = section.flags() else {
            bail!("{} is not an ELF file", elf.display());
        };
        const SHF_WRITE: u64 = 0x1;
        const SHF_ALLOC: u64 = 0x2;
        const SHF_EXECINSTR: u64 = 0x4;
        if sh_flags & SHF_ALLOC == 0 || section.size() == 0 {
            continue;
        }
        let size = section.size();
        let name = section.name().unwrap_or("");
        if section.kind() == SectionKind::UninitializedData || name.starts_with(".bss") {
            if name.starts_with(".uninit") {
                f.uninit += size;
            } else {
                f.bss += size;
            }
        } else if sh_flags & SHF_EXECINSTR != 0 || name == ".vector_table" {
            f.text += size;
        } else if sh_flags & SHF_WRITE != 0 {
            f.data += size;
        } else {
            f.rodata += size;
        }
    }
    Ok(f)
}

/// Builds program `bin` for `board` in release; returns a copy of the ELF at
/// `target/firmware/<board>-<bin>.elf`.
pub fn build(board: Board, bin: &str) -> Result<PathBuf> {
    firmware::build_program(board, bin, format!("{}-{bin}.elf", board.feature()))
}

/// What one `vsa-bench` run reported.
#[derive(Debug, Default)]
pub struct BenchRun {
    /// Core clock the board reported, Hz.
    pub sysclk_hz: u64,
    /// Results by benchmark name, instructions.
    pub results: BTreeMap<String, Insns>,
    /// The f32-vs-fixed closed-loop agreement line.
    pub agreement: Option<String>,
}

/// The records every `vsa-bench` run must write (one `bench` per benchmark).
const BENCH_RECORDS: [&str; 3] = ["clock", "bench", "f32_agreement"];

/// Reads a `vsa-bench` run at icount `shift` from its `RESULT` records.
pub fn parse_run(lines: &[String], shift: u32) -> Result<BenchRun> {
    let mut run = BenchRun {
        sysclk_hz: results::last(lines, "clock")?.get("sysclk_hz")?,
        ..BenchRun::default()
    };
    let a = results::last(lines, "f32_agreement")?;
    run.agreement = Some(format!(
        "f32 port vs fixed point, each in its own closed loop: {} ticks, |duty difference| mean {} max {} permille, link angle difference max {} urad, {} faults",
        a.text("ticks")?,
        a.text("duty_diff_mean_permille")?,
        a.text("duty_diff_max_permille")?,
        a.text("link_angle_diff_max_urad")?,
        a.text("faults")?
    ));
    // SysTick counts per instruction: 2^shift ns per instruction at f_sysclk.
    let per_insn = (run.sysclk_hz as f64) * f64::from(1u32 << shift) / 1e9;
    for r in results::all(lines, "bench") {
        let (n, sum, max): (u64, u64, u64) = (r.get("n")?, r.get("sum")?, r.get("max")?);
        let mean = if n == 0 { 0.0 } else { sum as f64 / n as f64 };
        run.results.insert(
            r.text("name")?.to_owned(),
            Insns {
                n,
                mean: mean / per_insn,
                max: max as f64 / per_insn,
            },
        );
    }
    for (name, _) in BENCHES.iter() {
        if !run.results.contains_key(*name) {
            bail!("no `RESULT bench name={name} …` line in the log");
        }
    }
    Ok(run)
}

/// Builds and runs `vsa-bench` on `board`.
pub fn run_bench(board: Board, echo: bool) -> Result<BenchRun> {
    let elf = build(board, "vsa-bench")?;
    let outcome = qemu::run_with_shift(
        board,
        &elf,
        &[],
        BENCH_SHIFT,
        test::wall_limit(30),
        |line| {
            if echo {
                println!("[{} bench] {line}", board.feature())
            }
        },
    )?;
    checks::check(&outcome, &Expected::Records(&BENCH_RECORDS))
        .with_context(|| format!("vsa-bench on {}", board.feature()))?;
    parse_run(&outcome.lines, BENCH_SHIFT)
}

/// `cargo xtask bench --quick`: `vsa-bench` on qemu-m3 alone (the board of the 2 000
/// instruction budget), one row per benchmark, instructions mean / max.
pub fn quick() -> Result<()> {
    setup::ensure_targets()?;
    setup::ensure_qemu()?;
    let board = Board::QemuM3;
    eprintln!("xtask: benchmarks on {}", board.feature());
    let run = run_bench(board, false)?;
    println!(
        "| instructions per call | {0} mean | {0} max |",
        board.feature()
    );
    println!("|---|---:|---:|");
    for (name, label) in BENCHES.iter() {
        let r = &run.results[*name];
        println!("| {label} | {:.1} | {:.1} |", r.mean, r.max);
    }
    Ok(())
}

/// The `RESULT stack` record → (peak, size, boot, running), bytes.
pub fn parse_stack(lines: &[String]) -> Result<(u64, u64, u64, u64)> {
    let r = results::last(lines, "stack")?;
    Ok((
        r.get("peak")?,
        r.get("size")?,
        r.get("boot")?,
        r.get("running")?,
    ))
}

/// What the real firmware's step sweep on one board gave.
struct FirmwareRun {
    footprint: Footprint,
    stack: (u64, u64, u64, u64),
    step: (u64, u64),
}

fn run_firmware(board: Board) -> Result<FirmwareRun> {
    let elf = firmware::build(board)?;
    let id = ScenarioId::StepSweep;
    let outcome = qemu::run(
        board,
        &elf,
        &scenarios::firmware_args(id),
        test::wall_limit(15),
        |_| {},
    )?;
    let host = scenarios::host_summary(id)?;
    checks::check(&outcome, &Expected::Scenario { id, host: &host })
        .with_context(|| format!("the step sweep on {}", board.feature()))?;
    Ok(FirmwareRun {
        footprint: footprint(&elf)?,
        stack: parse_stack(&outcome.lines)?,
        step: scenarios::step_insns(&outcome.lines)?,
    })
}

/// What the control firmware image (no plant) gave: its footprint and its stack after a
/// 2 s run holding still with the host link idle.
#[derive(Clone, Copy)]
struct ControlRun {
    footprint: Footprint,
    stack: (u64, u64, u64, u64),
}

fn run_control_only(board: Board) -> Result<ControlRun> {
    let elf = build(board, "vsa-control-only")?;
    let outcome = qemu::run(board, &elf, &[], test::wall_limit(2), |_| {})?;
    checks::check(&outcome, &Expected::Records(&["stack"]))
        .with_context(|| format!("vsa-control-only on {} (an overrun?)", board.feature()))?;
    Ok(ControlRun {
        footprint: footprint(&elf)?,
        stack: parse_stack(&outcome.lines)?,
    })
}

fn fmt_bytes(b: u64) -> String {
    format!("{b} ({:.1} KiB)", b as f64 / 1024.0)
}

/// Runs everything and prints the report.
pub fn run() -> Result<()> {
    setup::ensure_targets()?;
    setup::ensure_qemu()?;
    let boards = [Board::QemuM4, Board::QemuM3];
    let mut benches = Vec::new();
    let mut controls = Vec::new();
    let mut firmwares = Vec::new();
    for board in boards {
        eprintln!("xtask: benchmarks on {}", board.feature());
        benches.push(run_bench(board, false)?);
        controls.push(run_control_only(board)?);
        eprintln!(
            "xtask: the firmware's step sweep on {} (stack)",
            board.feature()
        );
        firmwares.push(run_firmware(board)?);
    }
    let nucleo = footprint(&firmware::build(Board::NucleoF446re)?)?;

    let md = markdown(&boards, &benches, &controls, &firmwares, &nucleo);
    println!("{md}");

    let mut report = Map::new();
    report.insert("icount_shift".into(), json!(BENCH_SHIFT));
    for (i, board) in boards.iter().enumerate() {
        let mut b = Map::new();
        for (name, r) in &benches[i].results {
            b.insert(format!("{name}_insns_mean"), json!(r.mean.round() as u64));
            b.insert(format!("{name}_insns_max"), json!(r.max.round() as u64));
        }
        let get = |k: &str| benches[i].results.get(k).map(|r| r.max.round() as u64);
        b.insert("stiffness_insns".into(), json!(get("stiffness")));
        b.insert("inverse_insns".into(), json!(get("inverse")));
        // The control firmware (no plant): the figures the performance targets are about;
        // then the emulated firmware with the simulated actuator, after its step sweep.
        let (c, f) = (&controls[i], &firmwares[i]);
        for (key, value) in [
            ("flash_bytes", json!(c.footprint.flash())),
            ("static_ram_bytes", json!(c.footprint.static_ram())),
            ("stack_bytes", json!(c.stack.0)),
            ("stack_size_bytes", json!(c.stack.1)),
            ("stack_boot_bytes", json!(c.stack.2)),
            ("stack_running_bytes", json!(c.stack.3)),
            ("firmware_stack_bytes", json!(f.stack.0)),
            ("firmware_stack_boot_bytes", json!(f.stack.2)),
            ("firmware_stack_running_bytes", json!(f.stack.3)),
            ("firmware_flash_bytes", json!(f.footprint.flash())),
            ("firmware_static_ram_bytes", json!(f.footprint.static_ram())),
            (
                "firmware_step_sweep_control_step_insns_mean",
                json!(f.step.0),
            ),
            (
                "firmware_step_sweep_control_step_insns_max",
                json!(f.step.1),
            ),
        ] {
            b.insert(key.into(), value);
        }
        report.insert(board.feature().into(), Value::Object(b));
    }
    report.insert(
        Board::NucleoF446re.feature().into(),
        json!({
            "flash_bytes": nucleo.flash(),
            "static_ram_bytes": nucleo.static_ram(),
            "stack_bytes": null,
        }),
    );
    let dir = target_dir().join("bench");
    std::fs::create_dir_all(&dir)?;
    let path = dir.join("report.json");
    std::fs::write(
        &path,
        serde_json::to_string_pretty(&Value::Object(report))? + "\n",
    )
    .with_context(|| format!("writing {}", path.display()))?;
    println!("Written: {}", path.display());
    Ok(())
}

fn markdown(
    boards: &[Board],
    benches: &[BenchRun],
    controls: &[ControlRun],
    firmwares: &[FirmwareRun],
    nucleo: &Footprint,
) -> String {
    let mut s = String::new();
    let mut head = String::from("| instructions per call |");
    let mut rule = String::from("|---|");
    for b in boards {
        head.push_str(&format!(" {0} mean | {0} max |", b.feature()));
        rule.push_str("---:|---:|");
    }
    s.push_str(&format!("{head}\n{rule}\n"));
    let cell = |r: Option<&Insns>| match r {
        Some(r) => format!(" {:.0} | {:.0} |", r.mean, r.max),
        None => " – | – |".to_owned(),
    };
    for (name, label) in BENCHES.iter() {
        let mut row = format!("| {label} |");
        for run in benches {
            row.push_str(&cell(run.results.get(*name)));
        }
        s.push_str(&row);
        s.push('\n');
        if let Some(fixed) = name.strip_suffix("_f32") {
            let mut row = format!("| ↳ fixed/f32 ({fixed}) |");
            for run in benches {
                match (run.results.get(fixed), run.results.get(*name)) {
                    (Some(a), Some(b)) if b.mean > 0.0 && b.max > 0.0 => {
                        row.push_str(&format!(" {:.2} | {:.2} |", a.mean / b.mean, a.max / b.max))
                    }
                    _ => row.push_str(" – | – |"),
                }
            }
            s.push_str(&row);
            s.push('\n');
        }
    }
    let mut row = String::from("| firmware step sweep, control step in situ (icount shift 3) |");
    for f in firmwares {
        row.push_str(&format!(" {} | {} |", f.step.0, f.step.1));
    }
    s.push_str(&row);
    s.push('\n');
    if let Some(a) = benches.first().and_then(|b| b.agreement.as_ref()) {
        s.push_str(&format!("\n{a}\n"));
    }

    s.push_str("\n| image | board | flash (text + rodata + data) | static RAM (data + bss + uninit) | stack high-water |\n|---|---|---:|---:|---:|\n");
    // One row: image, board, footprint and stack high-water (peak, size, boot, running).
    let row = |image: &str, board: Board, f: &Footprint, st: &(u64, u64, u64, u64)| {
        format!(
            "| {image} | {} | {} | {} | {} of {} (boot {}, running {}) |\n",
            board.feature(),
            fmt_bytes(f.flash()),
            fmt_bytes(f.static_ram()),
            st.0,
            st.1,
            st.2,
            st.3
        )
    };
    for (b, c) in boards.iter().zip(controls) {
        s.push_str(&row(
            "control firmware without the plant: control loop + host link (`vsa-control-only`, 2 s holding)",
            *b,
            &c.footprint,
            &c.stack,
        ));
    }
    for (b, f) in boards.iter().zip(firmwares) {
        s.push_str(&row(
            "firmware with the simulated actuator (`vsa-firmware`, step sweep)",
            *b,
            &f.footprint,
            &f.stack,
        ));
    }
    s.push_str(&format!(
        "| firmware (`vsa-firmware`, real board) | nucleo-f446re | {} | {} | – (no board here) |\n",
        fmt_bytes(nucleo.flash()),
        fmt_bytes(nucleo.static_ram())
    ));

    // The performance targets (README, Performance), checked.
    let at = |b: Board| boards.iter().position(|x| *x == b);
    let (m3, m4) = (at(Board::QemuM3), at(Board::QemuM4));
    let r = |i: Option<usize>, name: &str| i.and_then(|i| benches[i].results.get(name)).copied();
    let ratio = match (r(m3, "control_step"), r(m3, "control_step_f32")) {
        (Some(a), Some(b)) if a.mean > 0.0 => Some(b.mean / a.mean),
        _ => None,
    };
    let m4c = m4.map(|i| controls[i]);
    let kib = 1024.0;
    let rows: [(&str, Option<f64>, f64, &str); 7] = [
        (
            "qemu-m3 control step ≤ 2000 instructions (max, with and without load)",
            r(m3, "control_step")
                .zip(r(m3, "control_step_unloaded"))
                .map(|(a, b)| a.max.max(b.max)),
            2000.0,
            "",
        ),
        (
            "qemu-m3 control step f32/fixed ≥ 3 (mean; as a bound: fixed/f32 ≤ 1/3)",
            ratio.map(|x| 1.0 / x),
            1.0 / 3.0,
            "",
        ),
        (
            "qemu-m3 k(L) ≤ 150 instructions (max)",
            r(m3, "stiffness").map(|x| x.max),
            150.0,
            "",
        ),
        (
            "qemu-m3 L(k) ≤ 600 instructions (max)",
            r(m3, "inverse").map(|x| x.max),
            600.0,
            "",
        ),
        (
            "qemu-m4 control-only (loop + host link) flash ≤ 48 KiB",
            m4c.map(|c| c.footprint.flash() as f64),
            48.0 * kib,
            " B",
        ),
        (
            "qemu-m4 control-only static RAM ≤ 8 KiB",
            m4c.map(|c| c.footprint.static_ram() as f64),
            8.0 * kib,
            " B",
        ),
        (
            "qemu-m4 control-only stack ≤ 4 KiB (high-water, boot included)",
            m4c.map(|c| c.stack.0 as f64),
            4.0 * kib,
            " B",
        ),
    ];
    let mut t = String::from("\n| target | measured | met |\n|---|---:|:---:|\n");
    for (what, value, limit, unit) in rows {
        let (v, met) = match value {
            Some(v) if limit < 1.0 => (
                format!("f32/fixed = {:.2}", 1.0 / v),
                if v <= limit { "yes" } else { "no" },
            ),
            Some(v) => (
                format!("{v:.0}{unit}"),
                if v <= limit { "yes" } else { "no" },
            ),
            None => ("–".to_owned(), "–"),
        };
        t.push_str(&format!("| {what} | {v} | {met} |\n"));
    }
    s.push_str(&t);
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bench_records_convert_to_instructions() {
        let lines: Vec<String> = [
            "PRINT RESULT clock sysclk_hz=125000000",
            "PRINT RESULT f32_agreement ticks=10000 duty_diff_mean_permille=0.5 duty_diff_max_permille=3 link_angle_diff_max_urad=12 faults=0",
            "PRINT RESULT stack peak=2312 size=113960 boot=2312 running=800  (f.rs:1)",
        ]
        .iter()
        .map(|s| s.to_string())
        .chain(BENCHES.iter().map(|(name, _)| {
            format!("PRINT RESULT bench name={name} n=10 sum=1000 min=50 max=250  (b.rs:1)")
        }))
        .collect();
        // 125 MHz at shift 3: one instruction is one SysTick count.
        let run = parse_run(&lines, 3).unwrap();
        assert_eq!(run.sysclk_hz, 125_000_000);
        let step = run.results["control_step"];
        assert_eq!((step.n, step.mean, step.max), (10, 100.0, 250.0));
        assert!(run.agreement.unwrap().contains("max 3 permille"));
        assert_eq!(parse_stack(&lines).unwrap(), (2312, 113_960, 2312, 800));
        assert!(
            parse_run(&lines[..3], 3).is_err(),
            "every benchmark must be there"
        );
    }
}
