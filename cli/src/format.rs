//! Number formatting and plain-text tables for the reports.
//!
//! Formatting only: every number handed in here was computed by the model crate; the host
//! converts its fixed-point value to f64 for printing.

/// The placeholder for a quantity outside its domain (docs/design.md §6 "Tables and JSON").
pub const NONE: &str = "–";

/// `x` with `n` significant digits (never fewer integer digits than `x` has), fixed
/// notation for 1e-4 ≤ |x| < 1e9, scientific otherwise.
pub fn sig(x: f64, n: usize) -> String {
    if !x.is_finite() {
        return NONE.to_string();
    }
    if x == 0.0 {
        return "0".to_string();
    }
    let n = n.max(1);
    let mag = x.abs().log10().floor() as i32;
    if !(-4..9).contains(&mag) {
        format!("{:.*e}", n - 1, x)
    } else {
        let dec = (n as i32 - 1 - mag).max(0) as usize;
        format!("{x:.dec$}")
    }
}

/// `x` with up to 9 significant digits and no trailing zeros: for values that were typed
/// in as short decimals (7.8 mm is 7.800000000279 in I32F32).
pub fn trim(x: f64) -> String {
    let s = sig(x, 9);
    match s.split_once('e') {
        Some((m, e)) => format!("{}e{e}", strip_zeros(m)),
        None => strip_zeros(&s).to_string(),
    }
}

fn strip_zeros(s: &str) -> &str {
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.')
    } else {
        s
    }
}

/// `Some(x)` formatted with [`sig`], `None` as [`NONE`].
pub fn opt(x: Option<f64>, n: usize) -> String {
    x.map_or_else(|| NONE.to_string(), |v| sig(v, n))
}

/// A right-aligned text table with a two-line header (name, unit).
pub struct Table {
    columns: Vec<(String, String, Vec<String>)>,
}

impl Table {
    /// An empty table with these (name, unit) columns.
    pub fn new(headers: &[(&str, &str)]) -> Table {
        Table {
            columns: headers
                .iter()
                .map(|(h, u)| (h.to_string(), u.to_string(), Vec::new()))
                .collect(),
        }
    }

    /// Appends a row (one cell per column; missing cells are blank).
    pub fn row(&mut self, cells: Vec<String>) {
        let mut cells = cells.into_iter();
        for col in &mut self.columns {
            col.2.push(cells.next().unwrap_or_default());
        }
    }

    /// The table as text, columns separated by two spaces, each line ending in '\n'.
    pub fn render(&self) -> String {
        let width = |s: &str| s.chars().count();
        let widths: Vec<usize> = self
            .columns
            .iter()
            .map(|(h, u, cells)| {
                cells
                    .iter()
                    .map(|c| width(c))
                    .chain([width(h), width(u)])
                    .max()
                    .unwrap_or(0)
            })
            .collect();
        let rows = self.columns.first().map_or(0, |c| c.2.len());
        let mut out = String::new();
        let mut line = |cell: &dyn Fn(usize) -> String| {
            let mut l = String::new();
            for (i, w) in widths.iter().enumerate() {
                let c = cell(i);
                if i > 0 {
                    l.push_str("  ");
                }
                l.push_str(&" ".repeat(w - width(&c)));
                l.push_str(&c);
            }
            out.push_str(l.trim_end());
            out.push('\n');
        };
        line(&|i| self.columns[i].0.clone());
        line(&|i| self.columns[i].1.clone());
        for r in 0..rows {
            line(&|i| self.columns[i].2[r].clone());
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn significant_digits() {
        assert_eq!(sig(7167.5, 5), "7167.5");
        assert_eq!(sig(57.339, 5), "57.339");
        assert_eq!(sig(652.94, 3), "653");
        assert_eq!(sig(3265.4, 3), "3265");
        assert_eq!(sig(0.9188, 3), "0.919");
        assert_eq!(sig(0.016, 3), "0.0160");
        assert_eq!(sig(2.0, 3), "2.00");
        assert_eq!(sig(1.5e-7, 3), "1.50e-7");
        assert_eq!(sig(0.0, 3), "0");
        assert_eq!(sig(f64::NAN, 3), NONE);
        assert_eq!(trim(7.800000000279), "7.8");
        assert_eq!(trim(0.04999999999767), "0.05");
        assert_eq!(trim(200.0), "200");
        assert_eq!(trim(1.5e-12), "1.5e-12");
    }

    #[test]
    fn table_aligns_unicode() {
        let mut t = Table::new(&[("L", "mm"), ("k", "N·m/rad")]);
        t.row(vec!["1.000".into(), "7167.5".into()]);
        t.row(vec!["5.000".into(), NONE.into()]);
        let s = t.render();
        let lines: Vec<&str> = s.lines().collect();
        assert_eq!(lines.len(), 4);
        assert_eq!(lines[1], "   mm  N·m/rad");
        assert_eq!(lines[3], "5.000        –");
    }
}
