//! Helpers of the `vsa explore` and `vsa advise` tests: run a subcommand, read its JSON.

use std::process::{Command, Output};

use serde_json::Value;

/// Runs `vsa SUB ARGS…`.
pub fn vsa(sub: &str, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_vsa"))
        .arg(sub)
        .args(args)
        .output()
        .expect("run vsa")
}

/// Runs `vsa SUB ARGS… --json`, which must succeed, and parses stdout.
pub fn json(sub: &str, args: &[&str]) -> Value {
    let mut a = args.to_vec();
    a.push("--json");
    let out = vsa(sub, &a);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("stdout is one JSON document")
}

/// The number at `k` in `v`.
pub fn num(v: &Value, k: &str) -> f64 {
    v[k].as_f64().unwrap_or_else(|| panic!("{k} in {v}"))
}
