//! Telemetry samples as CSV in SI units, and back.
//!
//! ```text
//! t_s,tick,reference_rad,link_angle_rad,gear_angle_rad,current_a,torque_nm,duty,faults,limits
//! 0.000,51234,0.500000,0.499871,0.503310,0.212,0.041230,0.087,0,0
//! ```
//!
//! | column | unit | from the sample |
//! |---|---|---|
//! | `t_s` | s since the first sample | `tick` |
//! | `tick` | control tick (1 ms) | `tick` |
//! | `reference_rad`, `link_angle_rad`, `gear_angle_rad` | rad | µrad / 10⁶ |
//! | `current_a` | A | mA / 10³ |
//! | `torque_nm` | N·m | µN·m / 10⁶ |
//! | `duty` | fraction of the supply (−1…1) | ‰ / 10³ |
//! | `faults` | [`protocol::FaultSet`] bits | as is |
//! | `limits` | [`protocol::LimitFlags`] bits | as is |
//!
//! Values are written as exact decimals of the integers on the wire, so reading a file
//! written here gives back the very same samples ([`read_csv`]). [`read_table`] reads any
//! CSV of numbers by column name (also `vsa simulate --csv` files).

use std::io::{BufRead, Write};

use protocol::{FaultSet, LimitFlags, TelemetrySample};

use crate::{Error, Result};

/// The header line written by [`write_csv`].
pub const HEADER: &str =
    "t_s,tick,reference_rad,link_angle_rad,gear_angle_rad,current_a,torque_nm,duty,faults,limits";

/// `v / 10^decimals` as an exact decimal string (`-0.000500` for −500, 6).
fn decimal(v: i64, decimals: u32) -> String {
    let scale = 10u64.pow(decimals);
    let sign = if v < 0 { "-" } else { "" };
    let m = v.unsigned_abs();
    format!(
        "{sign}{}.{:0w$}",
        m / scale,
        m % scale,
        w = decimals as usize
    )
}

/// Parses a decimal string as `round(value · 10^decimals)`: exactly for plain decimals,
/// through f64 for anything else (`1e-3`). `None` if not a finite number.
fn scaled(s: &str, decimals: u32) -> Option<i64> {
    let t = s.trim();
    let (neg, body) = match t.strip_prefix('-') {
        Some(b) => (true, b),
        None => (false, t.strip_prefix('+').unwrap_or(t)),
    };
    let (int, frac) = body.split_once('.').unwrap_or((body, ""));
    let plain = !(int.is_empty() && frac.is_empty())
        && int.bytes().all(|b| b.is_ascii_digit())
        && frac.bytes().all(|b| b.is_ascii_digit())
        && frac.len() <= decimals as usize
        && int.len() <= 12;
    if plain {
        let i: i64 = if int.is_empty() { 0 } else { int.parse().ok()? };
        let f: i64 = if frac.is_empty() {
            0
        } else {
            frac.parse::<i64>().ok()? * 10i64.pow(decimals - frac.len() as u32)
        };
        let m = i.checked_mul(10i64.pow(decimals))?.checked_add(f)?;
        return Some(if neg { -m } else { m });
    }
    let v: f64 = t.parse().ok()?;
    let r = (v * 10f64.powi(decimals as i32)).round();
    (r.is_finite() && r.abs() < 9.0e18).then_some(r as i64)
}

/// One CSV line for `s` (no newline); `t0` is the tick of the first sample.
#[must_use]
pub fn row(s: &TelemetrySample, t0: u32) -> String {
    format!(
        "{},{},{},{},{},{},{},{},{},{}",
        decimal(i64::from(s.tick) - i64::from(t0), 3),
        s.tick,
        decimal(i64::from(s.reference_urad), 6),
        decimal(i64::from(s.link_angle_urad), 6),
        decimal(i64::from(s.gear_angle_urad), 6),
        decimal(i64::from(s.current_ma), 3),
        decimal(i64::from(s.torque_unm), 6),
        decimal(i64::from(s.duty_permille), 3),
        s.faults.0,
        s.limits.0,
    )
}

/// Writes [`HEADER`] and one line per sample; `t_s` counts from the first sample.
///
/// # Errors
/// The writer's.
pub fn write_csv<W: Write>(mut w: W, samples: &[TelemetrySample]) -> std::io::Result<()> {
    writeln!(w, "{HEADER}")?;
    let t0 = samples.first().map_or(0, |s| s.tick);
    for s in samples {
        writeln!(w, "{}", row(s, t0))?;
    }
    w.flush()
}

/// A CSV of numbers: column names and rows (an empty or non-numeric cell is NaN).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Table {
    /// Column names from the header line.
    pub columns: Vec<String>,
    /// The rows, each as long as `columns`.
    pub rows: Vec<Vec<f64>>,
}

impl Table {
    /// Index of the column `name`.
    #[must_use]
    pub fn index(&self, name: &str) -> Option<usize> {
        self.columns.iter().position(|c| c == name)
    }

    /// The values of column `name`, if there is one.
    #[must_use]
    pub fn column(&self, name: &str) -> Option<Vec<f64>> {
        let i = self.index(name)?;
        Some(
            self.rows
                .iter()
                .map(|r| r.get(i).copied().unwrap_or(f64::NAN))
                .collect(),
        )
    }
}

/// Data lines with their 1-based line numbers.
type Lines = Vec<(usize, String)>;

/// Reads the lines of a CSV: the header's cells, then the data lines.
fn lines<R: BufRead>(r: R) -> Result<(Vec<String>, Lines)> {
    let mut header = None;
    let mut rows = Vec::new();
    for (i, line) in r.lines().enumerate() {
        let line = line.map_err(|e| Error::Csv {
            line: i + 1,
            reason: e.to_string(),
        })?;
        let line = line.trim_end_matches('\r');
        if line.trim().is_empty() {
            continue;
        }
        if header.is_none() {
            header = Some(
                line.trim_start_matches('\u{feff}')
                    .split(',')
                    .map(|c| c.trim().to_string())
                    .collect::<Vec<_>>(),
            );
        } else {
            rows.push((i + 1, line.to_string()));
        }
    }
    let header = header.ok_or(Error::Csv {
        line: 1,
        reason: "empty file: no header line".to_string(),
    })?;
    Ok((header, rows))
}

fn check_width(line: usize, cells: usize, columns: usize) -> Result<()> {
    if cells == columns {
        Ok(())
    } else {
        Err(Error::Csv {
            line,
            reason: format!("{cells} cells, the header has {columns}"),
        })
    }
}

/// Reads a CSV of numbers with a header line.
///
/// # Errors
/// [`Error::Csv`] for an empty file, a row whose width differs from the header's, or a read
/// error.
pub fn read_table<R: BufRead>(r: R) -> Result<Table> {
    let (columns, lines) = lines(r)?;
    let mut rows = Vec::with_capacity(lines.len());
    for (n, line) in lines {
        let cells: Vec<f64> = line
            .split(',')
            .map(|c| c.trim().parse::<f64>().unwrap_or(f64::NAN))
            .collect();
        check_width(n, cells.len(), columns.len())?;
        rows.push(cells);
    }
    Ok(Table { columns, rows })
}

/// Reads samples written by [`write_csv`] (columns found by name; `t_s` is ignored,
/// `faults` and `limits` may be missing).
///
/// # Errors
/// [`Error::Csv`] naming the line and column of the first problem: a missing column, a
/// cell that is not a number or does not fit its wire type.
pub fn read_csv<R: BufRead>(r: R) -> Result<Vec<TelemetrySample>> {
    let (columns, lines) = lines(r)?;
    let col = |name: &str| {
        columns.iter().position(|c| c == name).ok_or(Error::Csv {
            line: 1,
            reason: format!("no column '{name}' in the header"),
        })
    };
    let tick = col("tick")?;
    let reference = col("reference_rad")?;
    let link = col("link_angle_rad")?;
    let gear = col("gear_angle_rad")?;
    let current = col("current_a")?;
    let torque = col("torque_nm")?;
    let duty = col("duty")?;
    let faults = col("faults").ok();
    let limits = col("limits").ok();
    let mut out = Vec::with_capacity(lines.len());
    for (n, line) in lines {
        let cells: Vec<&str> = line.split(',').collect();
        check_width(n, cells.len(), columns.len())?;
        let get = |i: usize, decimals: u32| -> Result<i64> {
            let cell = cells.get(i).copied().unwrap_or("");
            scaled(cell, decimals).ok_or_else(|| Error::Csv {
                line: n,
                reason: format!(
                    "column '{}': '{cell}' is not a number",
                    columns.get(i).map_or("?", String::as_str)
                ),
            })
        };
        let fit = |i: usize, v: i64| Error::Csv {
            line: n,
            reason: format!(
                "column '{}': {v} does not fit the wire format",
                columns.get(i).map_or("?", String::as_str)
            ),
        };
        macro_rules! int {
            ($i:expr, $d:expr) => {{
                let v = get($i, $d)?;
                v.try_into().map_err(|_| fit($i, v))?
            }};
        }
        let opt = |i: Option<usize>| -> Result<i64> { i.map_or(Ok(0), |i| get(i, 0)) };
        let f = opt(faults)?;
        let l = opt(limits)?;
        out.push(TelemetrySample {
            tick: int!(tick, 0),
            reference_urad: int!(reference, 6),
            link_angle_urad: int!(link, 6),
            gear_angle_urad: int!(gear, 6),
            current_ma: int!(current, 3),
            torque_unm: int!(torque, 6),
            duty_permille: int!(duty, 3),
            faults: FaultSet(f.try_into().map_err(|_| fit(faults.unwrap_or(0), f))?),
            limits: LimitFlags(l.try_into().map_err(|_| fit(limits.unwrap_or(0), l))?),
        });
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exact_decimals() {
        assert_eq!(decimal(-500, 6), "-0.000500");
        assert_eq!(decimal(1_234_567, 6), "1.234567");
        assert_eq!(decimal(0, 3), "0.000");
        assert_eq!(decimal(i64::from(i32::MIN), 6), "-2147.483648");
        assert_eq!(scaled("-0.000500", 6), Some(-500));
        assert_eq!(scaled("1.5", 6), Some(1_500_000));
        assert_eq!(scaled(".5", 3), Some(500));
        assert_eq!(scaled("1e-3", 3), Some(1));
        assert_eq!(scaled("-2147.483648", 6), Some(i64::from(i32::MIN)));
        assert_eq!(scaled("abc", 3), None);
        assert_eq!(scaled("", 3), None);
        assert_eq!(scaled("-", 3), None);
        assert_eq!(scaled("inf", 3), None);
    }
}
