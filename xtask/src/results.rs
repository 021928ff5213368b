//! The machine-readable results in an emulated program's decoded log.
//!
//! Each result is one line `RESULT <record> <key>=<value> …`: values hold no spaces
//! (decimal numbers, `0x` and hex digits for a hash, kebab-case names, `true`/`false`);
//! whatever follows the last `key=value` (defmt's `(file:line)`) is not part of it. The
//! records, and the programs that write them (`firmware/src/`):
//!
//! | record | keys | written by |
//! |---|---|---|
//! | `setting` | `index clutch_mm stiffness_nm_per_rad torque_capacity_nm from_tick` | `vsa-firmware`, as each clutch setting of its scenario starts (`report.rs`) |
//! | `segment` | `index clutch_mm overshoot_pct rise_s settling_s steady_state_error_counts peak_stress_mpa peak_stress_ratio rms_error_rad torque_limited hash` | `vsa-firmware`, as each setting ends (`report.rs`) |
//! | `scenario` | `name ticks hash first_fault fault_tick inject_tick condition_tick driven_after_fault bridge_driving_after_fault passed` | `vsa-firmware`, when its scenario ends (`report.rs`) |
//! | `timing` | `seconds min_ticks max_ticks overruns expected_overruns dropped passed` | `vsa-firmware`, at the end of a run (`report.rs`) |
//! | `control_step` | `insns_mean insns_max hooks_insns_mean icount_shift` | `vsa-firmware`, when its scenario ends (`report.rs`) |
//! | `fault` | `name code value tick` | `vsa-firmware` on an emulated board, each fault latched (`report.rs`) |
//! | `stack` | `peak size boot running` (bytes) | `vsa-firmware`, `vsa-control-only` (`stack.rs`) |
//! | `clock` | `sysclk_hz` | `vsa-bench` |
//! | `bench` | `name n sum min max` (SysTick counts) | `vsa-bench`, one per benchmark |
//! | `f32_agreement` | `ticks duty_diff_mean_permille duty_diff_max_permille link_angle_diff_max_urad faults` | `vsa-bench` |

use anyhow::{anyhow, Context, Result};
use std::str::FromStr;

/// The word that starts a result.
const MARK: &str = "RESULT ";

/// One `RESULT` line.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Record {
    /// What the record is (`scenario`, `stack`, …).
    pub kind: String,
    fields: Vec<(String, String)>,
}

impl Record {
    /// The record in a decoded log line, if it holds one.
    pub fn parse(line: &str) -> Option<Record> {
        let start = line.find(MARK)?;
        if start > 0 && !line[..start].ends_with(' ') {
            return None;
        }
        let mut words = line[start + MARK.len()..].split_whitespace();
        let kind = words.next()?.to_owned();
        let fields = words
            .map_while(|w| w.split_once('='))
            .map(|(k, v)| (k.to_owned(), v.to_owned()))
            .collect();
        Some(Record { kind, fields })
    }

    /// The value of `key`, as written.
    pub fn text(&self, key: &str) -> Result<&str> {
        self.fields
            .iter()
            .find(|(k, _)| k == key)
            .map(|(_, v)| v.as_str())
            .ok_or_else(|| anyhow!("`RESULT {}` has no `{key}`", self.kind))
    }

    /// The value of `key`, parsed.
    pub fn get<T: FromStr>(&self, key: &str) -> Result<T>
    where
        T::Err: std::error::Error + Send + Sync + 'static,
    {
        let text = self.text(key)?;
        text.parse()
            .with_context(|| format!("`RESULT {}`: {key}={text}", self.kind))
    }

    /// The value of `key`, a `0x` hex number.
    pub fn hex(&self, key: &str) -> Result<u64> {
        let text = self.text(key)?;
        let digits = text
            .strip_prefix("0x")
            .ok_or_else(|| anyhow!("`RESULT {}`: {key}={text} is not 0x hex", self.kind))?;
        u64::from_str_radix(digits, 16)
            .with_context(|| format!("`RESULT {}`: {key}={text}", self.kind))
    }
}

/// Every `kind` record in `lines`, in order.
pub fn all<'a>(lines: &'a [String], kind: &'a str) -> impl Iterator<Item = Record> + 'a {
    lines
        .iter()
        .filter_map(|l| Record::parse(l))
        .filter(move |r| r.kind == kind)
}

/// The last `kind` record in `lines`.
pub fn last(lines: &[String], kind: &str) -> Result<Record> {
    all(lines, kind)
        .last()
        .ok_or_else(|| anyhow!("no `RESULT {kind} …` line in the log"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn records_parse_from_decoded_lines() {
        let lines = vec![
            "  0.6 PRINT RESULT scenario name=fault-overrun ticks=1100 hash=0x61923127aaaa1bdf first_fault=deadline-missed fault_tick=300 passed=true  (firmware/src/report.rs:1)".to_owned(),
            "  0.6 INFO  L = 1 mm: overshoot 0 %, NORESULT x=1".to_owned(),
            "PRINT RESULT stack peak=2312 size=113960 boot=2312 running=800".to_owned(),
        ];
        let s = last(&lines, "scenario").unwrap();
        assert_eq!(s.text("name").unwrap(), "fault-overrun");
        assert_eq!(s.hex("hash").unwrap(), 0x6192_3127_aaaa_1bdf);
        assert_eq!(s.get::<u32>("fault_tick").unwrap(), 300);
        assert!(s.get::<bool>("passed").unwrap());
        assert!(
            s.text("report.rs:1)").is_err(),
            "the location is not a field"
        );
        assert!(s.hex("ticks").is_err());
        let st = last(&lines, "stack").unwrap();
        assert_eq!(st.get::<u64>("running").unwrap(), 800);
        assert_eq!(all(&lines, "x").count(), 0);
        assert!(last(&lines, "bench").is_err());
    }
}
