//! The one plotting helper: a [`Figure`] (title, panels of line series) drawn to SVG and PNG
//! with plotters, text in the bundled DejaVu Sans (no system fonts at run time).

use std::path::Path;
use std::sync::OnceLock;

use plotters::coord::ranged1d::{AsRangedCoord, ValueFormatter};
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::FontStyle;

use super::text::GoodText;
use crate::format::trim;

/// DejaVu Sans 2.37 (Bitstream Vera licence, `cli/assets/DejaVuSans-LICENSE.txt`).
static FONT: &[u8] = include_bytes!("../../assets/DejaVuSans.ttf");
const FAMILY: &str = "sans-serif";

/// The bundled font for [`GoodText`].
fn font() -> Result<&'static ab_glyph::FontRef<'static>, String> {
    static PARSED: OnceLock<Option<ab_glyph::FontRef<'static>>> = OnceLock::new();
    PARSED
        .get_or_init(|| ab_glyph::FontRef::try_from_slice(FONT).ok())
        .as_ref()
        .ok_or_else(|| "the bundled font is not a valid TrueType font".to_string())
}

/// Registers the bundled font with plotters, once.
pub fn register_font() -> Result<(), String> {
    static DONE: OnceLock<Result<(), String>> = OnceLock::new();
    DONE.get_or_init(|| {
        plotters::style::register_font(FAMILY, FontStyle::Normal, FONT)
            .map_err(|_| "the bundled font is not a valid TrueType font".to_string())
    })
    .clone()
}

/// The tab10 palette.
pub const COLORS: [RGBColor; 6] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
];

/// One polyline.
pub struct Series {
    /// Legend text; `None` keeps it out of the legend.
    pub label: Option<String>,
    /// The points, in data coordinates.
    pub points: Vec<(f64, f64)>,
    /// Line colour.
    pub color: RGBColor,
    /// Dashed instead of solid.
    pub dashed: bool,
    /// Markers (filled circles) at the points instead of a line.
    pub marker: bool,
}

/// One chart.
pub struct Panel {
    /// Caption above the chart.
    pub caption: String,
    /// X axis label, with unit.
    pub x_label: String,
    /// Y axis label, with unit.
    pub y_label: String,
    /// Logarithmic y axis.
    pub log_y: bool,
    /// Include y = 0 in a linear y range.
    pub y_zero: bool,
    /// Extra room above the data for the legend, as a fraction of the y span (linear only).
    pub headroom: f64,
    /// Margin left and right of the data, as a fraction of the x span.
    pub x_margin: f64,
    /// The lines.
    pub series: Vec<Series>,
    /// Where the legend goes.
    pub legend: SeriesLabelPosition,
}

/// A titled figure of panels side by side. Every figure spells its panels out in full
/// (options, legend place, size): the literals look alike but each is that figure's layout.
pub struct Figure {
    /// Title above all panels.
    pub title: String,
    /// The panels, left to right.
    pub panels: Vec<Panel>,
    /// Image size in pixels.
    pub size: (u32, u32),
}

impl Figure {
    /// Writes `<stem>.svg` and `<stem>.png`, panels side by side.
    pub fn write(&self, stem: &Path) -> Result<(), String> {
        self.write_file(&stem.with_extension("svg"), false)?;
        self.write_file(&stem.with_extension("png"), false)
    }

    /// Writes one image, SVG or PNG by `path`'s extension, the panels side by side or
    /// (`stacked`) one above the other.
    pub fn write_file(&self, path: &Path, stacked: bool) -> Result<(), String> {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        match ext.as_deref() {
            Some("svg") => self.draw(
                SVGBackend::new(path, self.size).into_drawing_area(),
                stacked,
            ),
            Some("png") => {
                let backend = GoodText::new(BitMapBackend::new(path, self.size), font()?);
                self.draw(backend.into_drawing_area(), stacked)
            }
            _ => Err("unknown image format (use .png or .svg)".to_string()),
        }
        .map_err(|e| format!("{}: {e}", path.display()))
    }

    fn draw<DB: DrawingBackend>(
        &self,
        root: DrawingArea<DB, Shift>,
        stacked: bool,
    ) -> Result<(), String> {
        let err = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
        root.fill(&WHITE).map_err(err)?;
        let body = root
            .titled(&self.title, (FAMILY, 24).into_font().color(&BLACK))
            .map_err(err)?;
        let n = self.panels.len().max(1);
        let areas = body.split_evenly(if stacked { (n, 1) } else { (1, n) });
        for (area, p) in areas.iter().zip(&self.panels) {
            let (x0, x1) = bounds(p.series.iter().flat_map(|s| s.points.iter().map(|q| q.0)));
            let m = (x1 - x0) * p.x_margin;
            let (x0, x1) = (x0 - m, x1 + m);
            let (y0, y1) = bounds(p.series.iter().flat_map(|s| s.points.iter().map(|q| q.1)));
            if p.log_y {
                let (y0, y1) = log_bounds(p);
                draw_panel(area, p, x0..x1, (y0..y1).log_scale())?;
            } else {
                let (y0, y1) = pad(if p.y_zero { y0.min(0.0) } else { y0 }, y1.max(y0));
                let y1 = y1 + (y1 - y0) * p.headroom;
                draw_panel(area, p, x0..x1, y0..y1)?;
            }
        }
        root.present().map_err(err)
    }
}

fn bounds(v: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = v
        .filter(|x| x.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), x| {
            (lo.min(x), hi.max(x))
        });
    if lo.is_finite() && hi > lo {
        (lo, hi)
    } else if lo.is_finite() {
        (lo - 1.0, lo + 1.0)
    } else {
        (0.0, 1.0)
    }
}

/// A linear range with 5 % head room at both ends (none below an exact 0).
fn pad(lo: f64, hi: f64) -> (f64, f64) {
    let m = (hi - lo) * 0.05;
    (if lo == 0.0 { 0.0 } else { lo - m }, hi + m)
}

/// A log range from the decade below the smallest positive value to the one above the largest.
fn log_bounds(p: &Panel) -> (f64, f64) {
    let (lo, hi) = bounds(
        p.series
            .iter()
            .flat_map(|s| s.points.iter().map(|q| q.1))
            .filter(|y| *y > 0.0),
    );
    let lo = if lo > 0.0 { lo } else { 1e-3 };
    // Slightly wider than the decades so that both end decades get a tick label.
    (
        10f64.powf(lo.log10().floor()) * 0.999,
        10f64.powf(hi.max(lo).log10().ceil()) * 1.001,
    )
}

/// Tick label: short decimal (`0.01`, `1000`), scientific beyond.
fn tick(v: f64) -> String {
    if v != 0.0 && v.abs() < 1e-12 {
        return "0".to_string();
    }
    trim(v)
}

fn draw_panel<DB, Y>(
    area: &DrawingArea<DB, Shift>,
    p: &Panel,
    x: std::ops::Range<f64>,
    y: Y,
) -> Result<(), String>
where
    DB: DrawingBackend,
    Y: AsRangedCoord<Value = f64>,
    Y::CoordDescType: ValueFormatter<f64>,
{
    let err = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
    let mut chart = ChartBuilder::on(area)
        .caption(&p.caption, (FAMILY, 19))
        .margin(14)
        .x_label_area_size(52)
        .y_label_area_size(78)
        .build_cartesian_2d(x, y)
        .map_err(err)?;
    chart
        .configure_mesh()
        .x_desc(p.x_label.as_str())
        .y_desc(p.y_label.as_str())
        .x_label_formatter(&|v| tick(*v))
        .y_label_formatter(&|v| tick(*v))
        .x_labels(8)
        .y_labels(10)
        .label_style((FAMILY, 15))
        .axis_desc_style((FAMILY, 17))
        .light_line_style(WHITE.mix(0.0))
        .bold_line_style(BLACK.mix(0.12))
        .draw()
        .map_err(err)?;
    let mut any_label = false;
    for s in &p.series {
        let style = ShapeStyle {
            color: s.color.to_rgba(),
            filled: false,
            stroke_width: 2,
        };
        let pts = s
            .points
            .iter()
            .copied()
            .filter(|q| q.0.is_finite() && q.1.is_finite());
        let ann = if s.marker {
            let fill = ShapeStyle {
                filled: true,
                ..style
            };
            chart.draw_series(pts.map(|q| Circle::new(q, 6, fill)))
        } else if s.dashed {
            chart.draw_series(DashedLineSeries::new(pts, 9, 6, style))
        } else {
            chart.draw_series(LineSeries::new(pts, style))
        }
        .map_err(err)?;
        if let Some(label) = &s.label {
            any_label = true;
            let dashed = s.dashed;
            if s.marker {
                let fill = ShapeStyle {
                    filled: true,
                    ..style
                };
                ann.label(label.as_str())
                    .legend(move |(x, y)| Circle::new((x + 11, y), 6, fill));
            } else {
                ann.label(label.as_str()).legend(move |(x, y)| {
                    let seg = if dashed { 8 } else { 22 };
                    PathElement::new(vec![(x, y), (x + seg, y)], style)
                });
            }
        }
    }
    if any_label {
        chart
            .configure_series_labels()
            .position(p.legend.clone())
            .background_style(WHITE.mix(0.9))
            .border_style(BLACK.mix(0.4))
            .label_font((FAMILY, 15))
            .margin(12)
            .draw()
            .map_err(err)?;
    }
    Ok(())
}
