//! `vsa plot CSV --out FILE`: a recorded (or simulated) run as a figure — reference, link
//! and gear angle against time above, motor current and coupling torque below. Offline: it
//! reads the CSV of `vsa record --csv` (or `vsa simulate --csv`) and needs no board.

use std::path::PathBuf;

use clap::Args;
use client::csv::{read_table, Table};
use plotters::prelude::SeriesLabelPosition;

use crate::error::{CliError, CliResult};
use crate::figures::plot::{register_font, Figure, Panel, Series, COLORS};
use crate::output;

/// Largest |value| plotted. Telemetry and simulation values are at most thousands (MPa
/// stresses are written in Pa: 10⁹); beyond this the axis maths of the plotting library
/// overflows (a span of ±1e308 panics, an infinite one never ends), so such a file is
/// refused.
pub const VALUE_MAX: f64 = 1e12;

/// Checks every cell that will be plotted: finite (an empty or non-numeric cell, NaN, is
/// left out of the line) and within ±[`VALUE_MAX`].
fn check_values(t: &Table, path: &str, names: &[&str]) -> CliResult<()> {
    for name in names {
        let Some(i) = t.index(name) else { continue };
        for (row, cells) in t.rows.iter().enumerate() {
            let v = cells.get(i).copied().unwrap_or(f64::NAN);
            if v.is_infinite() || v.abs() > VALUE_MAX {
                return Err(CliError::usage(
                    "plot",
                    format!(
                        "{path}: data row {}: {name} = {v:e} is outside ±{VALUE_MAX:e}",
                        row + 1
                    ),
                ));
            }
        }
    }
    Ok(())
}

/// Arguments of `vsa plot`.
#[derive(Args, Debug)]
pub struct PlotArgs {
    /// Telemetry CSV from `vsa record --csv` (or `vsa simulate --csv`)
    #[arg(value_name = "CSV")]
    pub csv: PathBuf,
    /// Output image, .png or .svg
    #[arg(long, value_name = "FILE")]
    pub out: PathBuf,
    /// Figure title [default: the CSV's file name]
    #[arg(long)]
    pub title: Option<String>,
}

/// One line of a panel from column `name`, if the table has it (rows where the time or
/// the value is missing are left out).
fn series(t: &Table, time: &[f64], name: &str, label: &str, color: usize) -> Option<Series> {
    let ys = t.column(name)?;
    Some(Series {
        label: Some(label.to_string()),
        points: time
            .iter()
            .copied()
            .zip(ys)
            .filter(|(x, y)| x.is_finite() && y.is_finite())
            .collect(),
        color: COLORS[color % COLORS.len()],
        dashed: name == "reference_rad",
        marker: false,
    })
}

fn panel(caption: &str, y_label: &str, series: Vec<Series>) -> Panel {
    Panel {
        caption: caption.to_string(),
        x_label: "t (s)".to_string(),
        y_label: y_label.to_string(),
        log_y: false,
        y_zero: false,
        headroom: 0.25,
        x_margin: 0.0,
        series,
        legend: SeriesLabelPosition::UpperRight,
    }
}

/// Runs `vsa plot`.
pub fn run(a: &PlotArgs) -> CliResult<()> {
    let ext = a
        .out
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    if !matches!(ext.as_deref(), Some("png" | "svg")) {
        return Err(CliError::usage(
            "--out",
            format!(
                "{}: unknown image format (use .png or .svg)",
                a.out.display()
            ),
        ));
    }
    let path = a.csv.display().to_string();
    let file = std::fs::File::open(&a.csv)
        .map_err(|e| CliError::usage("plot", format!("cannot read {path}: {e}")))?;
    let t = read_table(std::io::BufReader::new(file))
        .map_err(|e| CliError::usage("plot", format!("{path}: {e}")))?;
    let time = t
        .column("t_s")
        .ok_or_else(|| CliError::usage("plot", format!("{path}: no t_s column")))?;
    if time.iter().all(|x| !x.is_finite()) {
        return Err(CliError::usage("plot", format!("{path}: no samples")));
    }
    check_values(
        &t,
        &path,
        &[
            "t_s",
            "link_angle_rad",
            "gear_angle_rad",
            "reference_rad",
            "current_a",
            "torque_nm",
            "torque_estimate_nm",
        ],
    )?;
    // The reference last, dashed, on top of the measured angles.
    let angles: Vec<Series> = [
        ("link_angle_rad", "link", 1),
        ("gear_angle_rad", "gear", 2),
        ("reference_rad", "reference", 0),
    ]
    .iter()
    .filter_map(|&(c, l, color)| series(&t, &time, c, l, color))
    .collect();
    if angles.is_empty() {
        return Err(CliError::usage(
            "plot",
            format!("{path}: no reference_rad, link_angle_rad or gear_angle_rad column"),
        ));
    }
    let loads: Vec<Series> = [
        ("current_a", "current (A)"),
        ("torque_nm", "torque (N·m)"),
        ("torque_estimate_nm", "torque estimate (N·m)"),
    ]
    .iter()
    .enumerate()
    .filter_map(|(i, (c, l))| series(&t, &time, c, l, i + 3))
    .collect();
    let mut panels = vec![panel("Link angle", "angle (rad)", angles)];
    if !loads.is_empty() {
        panels.push(panel("Current and torque", "A, N·m", loads));
    }
    let title = a.title.clone().unwrap_or_else(|| {
        a.csv
            .file_name()
            .map_or_else(|| path.clone(), |n| n.to_string_lossy().to_string())
    });
    let fig = Figure {
        title,
        size: (1200, 450 * panels.len() as u32 + 50),
        panels,
    };
    register_font().map_err(CliError::runtime)?;
    output::check_writable(&a.out).map_err(|e| CliError::usage("--out", e))?;
    output::write_atomically(&a.out, |tmp| {
        fig.write_file(tmp, true)
            .map_err(|e| format!("cannot write {}: {e}", a.out.display()))
    })
    .map_err(CliError::runtime)?;
    eprintln!("wrote {} ({} samples)", a.out.display(), t.rows.len());
    Ok(())
}
