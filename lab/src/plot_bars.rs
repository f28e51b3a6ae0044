//! Horizontal bar charts of named cases on a logarithmic value axis, written as PNG and SVG:
//! one row per case (its name beside it), one bar per series in each row, a dashed reference
//! line (a goal). For categorical results that span decades (the robustness matrix).

use crate::plot::register_font;
use anyhow::{anyhow, Context, Result};
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use std::path::{Path, PathBuf};

/// One bar per case.
#[derive(Debug, Clone)]
pub struct BarSeries {
    /// Legend entry.
    pub label: String,
    /// Bar colour.
    pub color: RGBColor,
    /// One value per case (plot units; must be > 0 on the log axis, smaller ones are drawn at
    /// the axis's lower end).
    pub values: Vec<f64>,
}

/// A bar chart (module docs).
#[derive(Debug, Clone)]
pub struct BarChart {
    /// Title.
    pub title: String,
    /// Value-axis label, with its unit.
    pub value_label: String,
    /// Unit appended to the value axis's tick labels (`%`).
    pub unit: String,
    /// The case names, top to bottom.
    pub cases: Vec<String>,
    /// The series, drawn side by side in each row.
    pub series: Vec<BarSeries>,
    /// A reference value and its legend entry.
    pub reference: Option<(String, f64)>,
}

/// Pixels per case row.
const ROW_PX: u32 = 26;
/// Width of the case-name column, px.
const NAME_PX: u32 = 330;

impl BarChart {
    /// Writes `<stem>.png` and `<stem>.svg` and returns their paths.
    pub fn write(&self, stem: &Path) -> Result<Vec<PathBuf>> {
        if let Some(s) = self
            .series
            .iter()
            .find(|s| s.values.len() != self.cases.len())
        {
            return Err(anyhow!(
                "series `{}` has {} values for {} cases",
                s.label,
                s.values.len(),
                self.cases.len()
            ));
        }
        register_font()?;
        if let Some(dir) = stem.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir)
                .with_context(|| format!("cannot create directory {}", dir.display()))?;
        }
        let size = (1100, 150 + ROW_PX * self.cases.len() as u32);
        let png = stem.with_extension("png");
        let svg = stem.with_extension("svg");
        {
            let root = BitMapBackend::new(&png, size).into_drawing_area();
            self.draw(&root)
                .with_context(|| format!("drawing {}", png.display()))?;
            root.present()
                .map_err(|e| anyhow!("{e:?}"))
                .with_context(|| format!("cannot write {}", png.display()))?;
        }
        {
            let root = SVGBackend::new(&svg, size).into_drawing_area();
            self.draw(&root)
                .with_context(|| format!("drawing {}", svg.display()))?;
            root.present()
                .map_err(|e| anyhow!("{e:?}"))
                .with_context(|| format!("cannot write {}", svg.display()))?;
        }
        Ok(vec![png, svg])
    }

    /// The value axis: whole decades around every finite positive value and the reference, and
    /// one more decade on the right for the legend.
    fn value_range(&self) -> (f64, f64) {
        let values = self
            .series
            .iter()
            .flat_map(|s| s.values.iter().copied())
            .chain(self.reference.iter().map(|r| r.1))
            .filter(|v| v.is_finite() && *v > 0.0);
        let (lo, hi) = values.fold((f64::INFINITY, 0.0f64), |(a, b), v| (a.min(v), b.max(v)));
        if !(lo.is_finite() && hi > 0.0) {
            return (0.01, 100.0);
        }
        (
            10f64.powf(lo.log10().floor()),
            10f64.powf(hi.log10().ceil().max(lo.log10().floor() + 1.0) + 1.0),
        )
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<()> {
        let err = |e: DrawingAreaErrorKind<DB::ErrorType>| anyhow!("{e:?}");
        root.fill(&WHITE).map_err(err)?;
        let n = self.cases.len();
        let (lo, hi) = self.value_range();
        let unit = self.unit.clone();
        let mut chart = ChartBuilder::on(root)
            .caption(&self.title, ("sans-serif", 22))
            .margin(12)
            .margin_right(40)
            .x_label_area_size(48)
            .y_label_area_size(NAME_PX)
            .build_cartesian_2d((lo..hi).log_scale(), -0.5f64..(n as f64 - 0.5))
            .map_err(err)?;
        chart
            .configure_mesh()
            .x_desc(self.value_label.as_str())
            .axis_desc_style(("sans-serif", 18))
            .label_style(("sans-serif", 15))
            .x_label_formatter(&|v: &f64| format!("{} {unit}", decade_label(*v)))
            .y_labels(0)
            .disable_y_mesh()
            .light_line_style(RGBColor(235, 235, 235))
            .bold_line_style(RGBColor(200, 200, 200))
            .draw()
            .map_err(err)?;
        // Row `k` (top to bottom) at y = n - 1 - k; its bars share 70 % of the row.
        let band = 0.7 / self.series.len().max(1) as f64;
        for (s, series) in self.series.iter().enumerate() {
            let color = series.color;
            chart
                .draw_series(series.values.iter().enumerate().map(|(k, &v)| {
                    let y = (n - 1 - k) as f64 + 0.35 - s as f64 * band;
                    Rectangle::new([(lo, y), (v.clamp(lo, hi), y - band)], color.filled())
                }))
                .map_err(err)?
                .label(series.label.as_str())
                .legend(move |(x, y)| {
                    Rectangle::new([(x, y - 5), (x + 16, y + 5)], color.filled())
                });
        }
        if let Some((label, at)) = &self.reference {
            let style = BLACK.stroke_width(2);
            chart
                .draw_series(DashedLineSeries::new(
                    [(*at, -0.5), (*at, n as f64 - 0.5)],
                    8,
                    5,
                    style,
                ))
                .map_err(err)?
                .label(label.as_str())
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 16, y)], style));
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::LowerRight)
            .label_font(("sans-serif", 15))
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .draw()
            .map_err(err)?;
        // The case names, right-aligned against the plot area (drawn on the root: the chart
        // clips to its plot area).
        let name_style = TextStyle::from(("sans-serif", 15).into_font())
            .pos(Pos::new(HPos::Right, VPos::Center));
        for (k, name) in self.cases.iter().enumerate() {
            let (px, py) = chart.backend_coord(&(lo, (n - 1 - k) as f64));
            root.draw(&Text::new(name.as_str(), (px - 8, py), name_style.clone()))
                .map_err(err)?;
        }
        Ok(())
    }
}

/// A tick label on the log axis: `0.01`, `0.1`, `1`, `10`, ... (decades without trailing
/// zeros; other values with two significant digits).
fn decade_label(value: f64) -> String {
    let text = format!("{:.4}", value);
    let text = text.trim_end_matches('0').trim_end_matches('.');
    if text.is_empty() || text == "0" {
        format!("{value:.1e}")
    } else {
        text.to_string()
    }
}
