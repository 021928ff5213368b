//! `cargo xtask test`: every check the project has, ending in `N passed, M failed`.

use anyhow::Result;
use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};
use std::time::Duration;

use crate::board::Board;
use crate::checks::Expected;
use crate::cmd::{cargo, describe};
use crate::e2e;
use crate::{bench, checks, fail_safe, firmware, qemu, scenarios, sensors, setup};
use plant::scenario::ScenarioId;

/// Control tick at which the panic-handler test panics on purpose.
const PANIC_TICK: u32 = 1500;

#[derive(Default)]
struct Tally {
    passed: usize,
    failed: usize,
    failures: Vec<String>,
}

impl Tally {
    fn record(&mut self, name: &str, result: Result<()>) {
        match result {
            Ok(()) => {
                self.passed += 1;
                println!("xtask test: ok   {name}");
            }
            Err(e) => {
                self.failed += 1;
                println!("xtask test: FAIL {name}: {e:#}");
                self.failures.push(name.to_owned());
            }
        }
    }
}

/// Runs a command to completion; a failure carries its command line.
fn step(mut cmd: Command) -> Result<()> {
    let status = cmd.status()?;
    anyhow::ensure!(
        status.success(),
        "`{}` exited with {status}",
        describe(&cmd)
    );
    Ok(())
}

/// Runs every check and returns whether all passed.
pub fn run() -> Result<bool> {
    setup::ensure_targets()?;
    setup::ensure_qemu()?;
    let mut tally = Tally::default();

    let mut fmt = cargo();
    fmt.args(["fmt", "--all", "--", "--check"]);
    tally.record("cargo fmt --check", step(fmt));
    tally.record("bash -n .ci/run", crate::ci_script::check());

    let mut clippy = cargo();
    clippy.args(["clippy", "--all-targets", "--", "-D", "warnings"]);
    tally.record("clippy (host crates)", step(clippy));

    for board in Board::ALL {
        let mut clippy = cargo();
        clippy
            .args(["clippy", "--release", "--package", "vsa-firmware"])
            .args(board.cargo_args())
            .args(["--", "-D", "warnings"]);
        tally.record(
            &format!("clippy (firmware, {})", board.feature()),
            step(clippy),
        );
    }
    let ttl = crate::dynamixel::clippy_ttl();
    tally.record("clippy (firmware, nucleo-f446re dynamixel-ttl)", step(ttl));

    // The f32 port the benchmark compares with, on both emulated cores (the firmware's
    // clippy above lints the benchmark program itself).
    for board in [Board::QemuM4, Board::QemuM3] {
        let mut clippy = cargo();
        clippy
            .args(["clippy", "--release", "--package", "vsa-bench"])
            .args(["--target", board.target()])
            .args(["--", "-D", "warnings"]);
        tally.record(
            &format!("clippy (f32 port, {})", board.feature()),
            step(clippy),
        );
    }

    host_tests(&mut tally);
    tally.record(
        "flex-bound program against the rigid bound",
        crate::flex_bound::check().map(|line| println!("[flex-bound] {line}")),
    );

    let mut elfs = Vec::new();
    for board in Board::ALL {
        let built = firmware::build(board);
        if let Ok(elf) = &built {
            elfs.push((board, elf.clone()));
        }
        tally.record(
            &format!("release build ({})", board.feature()),
            built.map(|_| ()),
        );
    }

    for (board, elf) in elfs.iter().filter(|(b, _)| b.qemu_machine().is_some()) {
        for id in ScenarioId::ALL {
            let args = scenarios::firmware_args(id);
            let result = qemu::run(*board, elf, &args, wall_limit(15), |line| {
                println!("[{} {}] {line}", board.feature(), id.name())
            })
            .and_then(|outcome| {
                let host = scenarios::host_summary(id)?;
                checks::check(&outcome, &Expected::Scenario { id, host: &host })
            });
            tally.record(&format!("{} on {}", id.name(), board.feature()), result);
        }
    }

    // The benchmark program runs and reports every benchmark; the control-only image
    // builds (`cargo xtask bench` has the full report).
    for board in [Board::QemuM4, Board::QemuM3] {
        let result = bench::build(board, "vsa-control-only")
            .and_then(|_| bench::run_bench(board, true))
            .map(|_| ());
        tally.record(&format!("benchmarks on {}", board.feature()), result);
    }

    for (board, elf) in elfs.iter().filter(|(b, _)| b.qemu_machine().is_some()) {
        let args = vec!["--inject-panic-at-tick".to_owned(), PANIC_TICK.to_string()];
        let result = qemu::run(*board, elf, &args, wall_limit(3), |line| {
            println!("[{} panic test] {line}", board.feature())
        })
        .and_then(|outcome| {
            checks::check(&outcome, &Expected::PanicAt(PANIC_TICK))?;
            fail_safe::check_bridge_off(&outcome, fail_safe::PANIC_REPORT)
        });
        tally.record(&format!("panic handler on {}", board.feature()), result);
        let result = fail_safe::hardfault_test(*board, elf, PANIC_TICK);
        tally.record(&format!("HardFault handler on {}", board.feature()), result);
    }

    for (board, elf) in elfs.iter().filter(|(b, _)| b.qemu_machine().is_some()) {
        println!(
            "[{} host link] end-to-end: configure, enable, move, record, garbage, heartbeat timeout",
            board.feature()
        );
        let result = e2e::run(*board, elf).map(|r| println!("[{} host link] {r}", board.feature()));
        tally.record(
            &format!("host link end-to-end on {}", board.feature()),
            result,
        );
    }

    for (board, elf) in elfs.iter().filter(|(b, _)| b.qemu_machine().is_some()) {
        let result =
            sensors::check(*board, elf).map(|r| println!("[{} sensors] {r}", board.feature()));
        tally.record(&format!("vsa sensors on {}", board.feature()), result);
    }

    for (board, elf) in elfs.iter().filter(|(b, _)| b.qemu_machine().is_some()) {
        tally.record(
            &format!("power-up anywhere on {}", board.feature()),
            crate::power_up::check(*board, elf)
                .map(|r| println!("[{} power-up] {r}", board.feature())),
        );
    }

    for (board, elf) in elfs.iter().filter(|(b, _)| b.qemu_machine().is_some()) {
        let result = crate::persistence::run(*board, elf)
            .map(|r| println!("[{} settings store] {r}", board.feature()));
        tally.record(&format!("settings store on {}", board.feature()), result);
    }

    for (board, elf) in elfs.iter().filter(|(b, _)| b.qemu_machine().is_some()) {
        let result = crate::dynamixel::run(*board, elf)
            .map(|r| println!("[{} dynamixel] {r}", board.feature()));
        tally.record(&format!("dynamixel-sdk on {}", board.feature()), result);
    }

    for (board, elf) in elfs.iter().filter(|(b, _)| b.qemu_machine().is_some()) {
        let result = crate::calibrate::check(*board, elf)
            .map(|r| println!("[{} calibration] {r}", board.feature()));
        tally.record(&format!("vsa calibrate on {}", board.feature()), result);
    }

    if !tally.failures.is_empty() {
        println!("xtask test: failed: {}", tally.failures.join(", "));
    }
    println!("{} passed, {} failed", tally.passed, tally.failed);
    Ok(tally.failed == 0)
}

/// `cargo test` on the host crates, every test binary even after one fails (a failure
/// must not hide the others). Each Rust test counts on its own; a cargo failure that
/// reports no failing test (a build error) counts as one failure.
fn host_tests(tally: &mut Tally) {
    let mut cmd = cargo();
    cmd.args(["test", "--no-fail-fast"]).stdout(Stdio::piped());
    let mut child = match cmd.spawn() {
        Ok(child) => child,
        Err(e) => return tally.record("cargo test", Err(e.into())),
    };
    let (mut passed, mut failed) = (0, 0);
    if let Some(stdout) = child.stdout.take() {
        for line in BufReader::new(stdout).lines().map_while(Result::ok) {
            println!("{line}");
            if let Some((p, f)) = parse_test_result(&line) {
                passed += p;
                failed += f;
            }
        }
    }
    let success = child.wait().map(|s| s.success()).unwrap_or(false);
    tally.passed += passed;
    tally.failed += failed;
    if failed > 0 {
        tally.failures.push(format!("{failed} host tests"));
    }
    if !success && failed == 0 {
        tally.record("cargo test", Err(anyhow::anyhow!("cargo test failed")));
    }
    println!("xtask test: host tests: {passed} passed, {failed} failed");
}

/// `test result: ok. 12 passed; 0 failed; …` → (12, 0).
fn parse_test_result(line: &str) -> Option<(usize, usize)> {
    let rest = line.strip_prefix("test result: ")?;
    let rest = &rest[rest.find(". ")? + 2..];
    let (passed, rest) = rest.split_once(" passed; ")?;
    let (failed, _) = rest.split_once(" failed")?;
    Some((passed.parse().ok()?, failed.parse().ok()?))
}

/// Wall-clock allowance for an emulated run of `seconds` seconds.
pub fn wall_limit(seconds: u32) -> Duration {
    Duration::from_secs(120 + 20 * u64::from(seconds))
}

#[cfg(test)]
mod tests {
    use super::parse_test_result;

    #[test]
    fn reads_cargo_test_summaries() {
        assert_eq!(
            parse_test_result("test result: ok. 12 passed; 0 failed; 0 ignored; 0 measured"),
            Some((12, 0))
        );
        assert_eq!(
            parse_test_result("test result: FAILED. 3 passed; 2 failed; 0 ignored"),
            Some((3, 2))
        );
        assert_eq!(parse_test_result("running 3 tests"), None);
    }
}
