//! Figures for every `maglab` command: line plots in one or more panels, written as PNG and SVG.
//!
//! Text is rendered with DejaVu Sans embedded in the binary (the `dejavu` crate) through
//! plotters' `ab_glyph` feature, so a plot looks the same on a clean machine with no system fonts
//! or fontconfig. A command builds a [`Figure`] (panels of [`Series`]) and calls
//! [`Figure::write`] with a path stem; the PNG is what the docs show, the SVG is for zooming.

use anyhow::{anyhow, Context, Result};
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// Colours for successive series: distinguishable, print-safe (Okabe-Ito palette plus black).
pub const PALETTE: [RGBColor; 8] = [
    RGBColor(0, 0, 0),
    RGBColor(0, 114, 178),
    RGBColor(213, 94, 0),
    RGBColor(0, 158, 115),
    RGBColor(204, 121, 167),
    RGBColor(230, 159, 0),
    RGBColor(86, 180, 233),
    RGBColor(120, 120, 120),
];

/// One polyline.
#[derive(Debug, Clone)]
pub struct Series {
    /// Legend entry; `None` draws the line without an entry.
    pub label: Option<String>,
    /// Points in plot units, drawn in order.
    pub points: Vec<(f64, f64)>,
    /// Line colour.
    pub color: RGBColor,
    /// Line width in pixels.
    pub width: u32,
}

/// One set of axes.
#[derive(Debug, Clone)]
pub struct Panel {
    /// Title drawn above the axes.
    pub title: String,
    /// X-axis label, with its unit.
    pub x_label: String,
    /// Y-axis label, with its unit.
    pub y_label: String,
    /// The lines, drawn in order.
    pub series: Vec<Series>,
    /// Axis ranges; `None` fits the data with a 5 % margin.
    pub x_range: Option<(f64, f64)>,
    /// See `x_range`.
    pub y_range: Option<(f64, f64)>,
    /// Where the legend goes.
    pub legend: SeriesLabelPosition,
}

impl Panel {
    /// An empty panel with the legend in the upper left corner.
    pub fn new(title: &str, x_label: &str, y_label: &str) -> Self {
        Panel {
            title: title.to_string(),
            x_label: x_label.to_string(),
            y_label: y_label.to_string(),
            series: Vec::new(),
            x_range: None,
            y_range: None,
            legend: SeriesLabelPosition::UpperLeft,
        }
    }
}

/// Panels on a grid of `rows × cols`, filled row by row.
#[derive(Debug, Clone)]
pub struct Figure {
    /// The panels.
    pub panels: Vec<Panel>,
    /// Grid rows.
    pub rows: usize,
    /// Grid columns.
    pub cols: usize,
    /// Image size in pixels (the SVG uses the same user units).
    pub size_px: (u32, u32),
}

impl Figure {
    /// Writes `<stem>.png` and `<stem>.svg` and returns their paths.
    pub fn write(&self, stem: &Path) -> Result<Vec<PathBuf>> {
        if self.panels.len() > self.rows * self.cols {
            return Err(anyhow!(
                "{} panels do not fit a {}x{} grid",
                self.panels.len(),
                self.rows,
                self.cols
            ));
        }
        register_font()?;
        if let Some(dir) = stem.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir)
                .with_context(|| format!("cannot create directory {}", dir.display()))?;
        }
        let png = stem.with_extension("png");
        let svg = stem.with_extension("svg");
        {
            let root = BitMapBackend::new(&png, self.size_px).into_drawing_area();
            self.draw(&root)
                .with_context(|| format!("drawing {}", png.display()))?;
            root.present()
                .map_err(|e| anyhow!("{e:?}"))
                .with_context(|| format!("cannot write {}", png.display()))?;
        }
        {
            let root = SVGBackend::new(&svg, self.size_px).into_drawing_area();
            self.draw(&root)
                .with_context(|| format!("drawing {}", svg.display()))?;
            root.present()
                .map_err(|e| anyhow!("{e:?}"))
                .with_context(|| format!("cannot write {}", svg.display()))?;
        }
        Ok(vec![png, svg])
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<()> {
        let err = |e: DrawingAreaErrorKind<DB::ErrorType>| anyhow!("{e:?}");
        root.fill(&WHITE).map_err(err)?;
        let areas = root.split_evenly((self.rows, self.cols));
        for (panel, area) in self.panels.iter().zip(areas.iter()) {
            draw_panel(panel, area)?;
        }
        Ok(())
    }
}

fn draw_panel<DB: DrawingBackend>(panel: &Panel, area: &DrawingArea<DB, Shift>) -> Result<()> {
    let err = |e: DrawingAreaErrorKind<DB::ErrorType>| anyhow!("{e:?}");
    let all = || panel.series.iter().flat_map(|s| s.points.iter());
    let (x0, x1) = panel.x_range.unwrap_or_else(|| padded(all().map(|p| p.0)));
    let (y0, y1) = panel.y_range.unwrap_or_else(|| padded(all().map(|p| p.1)));
    let mut chart = ChartBuilder::on(area)
        .caption(&panel.title, ("sans-serif", 22))
        .margin(12)
        .x_label_area_size(48)
        .y_label_area_size(72)
        .build_cartesian_2d(x0..x1, y0..y1)
        .map_err(err)?;
    chart
        .configure_mesh()
        .x_desc(panel.x_label.as_str())
        .y_desc(panel.y_label.as_str())
        .axis_desc_style(("sans-serif", 18))
        .label_style(("sans-serif", 15))
        .x_label_formatter(&tick_label)
        .y_label_formatter(&tick_label)
        .light_line_style(RGBColor(235, 235, 235))
        .bold_line_style(RGBColor(200, 200, 200))
        .draw()
        .map_err(err)?;
    let mut any_label = false;
    for series in &panel.series {
        let style = series.color.stroke_width(series.width);
        let drawn = chart
            .draw_series(LineSeries::new(series.points.iter().copied(), style))
            .map_err(err)?;
        if let Some(label) = &series.label {
            any_label = true;
            drawn
                .label(label.as_str())
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 24, y)], style));
        }
    }
    if any_label {
        chart
            .configure_series_labels()
            .position(panel.legend.clone())
            .label_font(("sans-serif", 15))
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .draw()
            .map_err(err)?;
    }
    Ok(())
}

/// Tick label: up to four decimals, trailing zeros dropped (`800`, `0.25`, `-1.5`).
fn tick_label(value: &f64) -> String {
    let text = format!("{value:.4}");
    let text = text.trim_end_matches('0').trim_end_matches('.');
    if text == "-0" {
        "0".to_string()
    } else {
        text.to_string()
    }
}

/// Data range with a 5 % margin on each side; a unit range around a constant, `(-1, 1)` for no
/// finite data.
fn padded(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = values
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        });
    if lo > hi {
        return (-1.0, 1.0);
    }
    if lo == hi {
        return (lo - 1.0, hi + 1.0);
    }
    let pad = 0.05 * (hi - lo);
    (lo - pad, hi + pad)
}

/// Registers the embedded DejaVu Sans as plotters' "sans-serif" family (once per process). Every
/// figure module calls it before drawing text.
pub fn register_font() -> Result<()> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let ok = *REGISTERED.get_or_init(|| {
        let normal = plotters::style::register_font(
            "sans-serif",
            FontStyle::Normal,
            dejavu::sans::regular(),
        );
        let bold =
            plotters::style::register_font("sans-serif", FontStyle::Bold, dejavu::sans::bold());
        normal.is_ok() && bold.is_ok()
    });
    if ok {
        Ok(())
    } else {
        Err(anyhow!("the embedded DejaVu Sans font could not be parsed"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn padded_range_covers_the_data_with_margin() {
        assert_eq!(padded([0.0, 10.0].into_iter()), (-0.5, 10.5));
        assert_eq!(padded([3.0].into_iter()), (2.0, 4.0));
        assert_eq!(padded([f64::NAN].into_iter()), (-1.0, 1.0));
    }

    #[test]
    fn tick_labels_drop_trailing_zeros() {
        assert_eq!(tick_label(&800.0), "800");
        assert_eq!(tick_label(&-0.25), "-0.25");
        assert_eq!(tick_label(&0.30000000000000004), "0.3");
        assert_eq!(tick_label(&-0.00001), "0");
    }

    /// Writes a small figure and checks both files are there and the PNG has text pixels drawn
    /// with the embedded font (a blank or font-less render would fail `write`).
    #[test]
    fn writes_png_and_svg() {
        let dir = std::env::temp_dir().join(format!("maglab-plot-{}", std::process::id()));
        let mut panel = Panel::new("test", "x (1)", "y (1)");
        panel.series.push(Series {
            label: Some("line".into()),
            points: vec![(0.0, 0.0), (1.0, 1.0)],
            color: PALETTE[1],
            width: 2,
        });
        let figure = Figure {
            panels: vec![panel],
            rows: 1,
            cols: 1,
            size_px: (320, 240),
        };
        let files = figure.write(&dir.join("fig")).unwrap();
        for f in &files {
            let len = std::fs::metadata(f).unwrap().len();
            assert!(len > 1000, "{} has {len} bytes", f.display());
        }
        let svg = std::fs::read_to_string(&files[1]).unwrap();
        assert!(
            svg.lines().any(|l| l.trim() == "test"),
            "the SVG has the title text"
        );
        std::fs::remove_dir_all(&dir).ok();
    }
}
