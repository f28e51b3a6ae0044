//! Figures of the identification commands that the line-plot module does not draw: the heat map
//! of cell masses on the Preisach plane (`β` horizontal, `α` vertical, density = mass / cell area,
//! unexcited cells outlined), written as PNG and SVG like every `maglab` figure.

use crate::plot::register_font;
use anyhow::{anyhow, Context, Result};
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::{Path, PathBuf};

/// Heat map of the masses `weights` (alpha-major) on the grid `[h_min, h_max]`.
pub struct WeightMap<'a> {
    /// Title.
    pub title: String,
    /// Axis unit label, e.g. "kA/m".
    pub axis_label: String,
    /// Input value → axis value (e.g. A/m → kA/m).
    pub axis_scale: f64,
    /// Grid range.
    pub h_min: f64,
    /// Grid range.
    pub h_max: f64,
    /// Masses.
    pub weights: &'a [f64],
    /// Cells to outline (unexcited).
    pub outlined: &'a [usize],
}

/// Sequential colour map (dark blue → yellow), `v ∈ [0, 1]`.
fn colour(v: f64) -> RGBColor {
    let v = v.clamp(0.0, 1.0);
    let stops = [
        (0.0, (255.0, 255.0, 255.0)),
        (0.25, (65.0, 105.0, 225.0)),
        (0.6, (0.0, 158.0, 115.0)),
        (1.0, (240.0, 228.0, 66.0)),
    ];
    for w in stops.windows(2) {
        let ((a, ca), (b, cb)) = (w[0], w[1]);
        if v <= b {
            let s = (v - a) / (b - a);
            let mix = |x: f64, y: f64| (x + (y - x) * s).round() as u8;
            return RGBColor(mix(ca.0, cb.0), mix(ca.1, cb.1), mix(ca.2, cb.2));
        }
    }
    RGBColor(240, 228, 66)
}

impl WeightMap<'_> {
    /// Writes `<stem>.png` and `<stem>.svg`.
    pub fn write(&self, stem: &Path) -> Result<Vec<PathBuf>> {
        register_font()?;
        if let Some(dir) = stem.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir)
                .with_context(|| format!("cannot create directory {}", dir.display()))?;
        }
        let png = stem.with_extension("png");
        let svg = stem.with_extension("svg");
        {
            let root = BitMapBackend::new(&png, (900, 800)).into_drawing_area();
            self.draw(&root)?;
            root.present()
                .map_err(|e| anyhow!("cannot write {}: {e:?}", png.display()))?;
        }
        {
            let root = SVGBackend::new(&svg, (900, 800)).into_drawing_area();
            self.draw(&root)?;
            root.present()
                .map_err(|e| anyhow!("cannot write {}: {e:?}", svg.display()))?;
        }
        Ok(vec![png, svg])
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<()> {
        let err = |e: DrawingAreaErrorKind<DB::ErrorType>| anyhow!("{e:?}");
        root.fill(&WHITE).map_err(err)?;
        let levels = maglab_identify::LEVELS;
        let (lo, hi) = (self.h_min * self.axis_scale, self.h_max * self.axis_scale);
        let width = (hi - lo) / levels as f64;
        let density = |k: usize| {
            let (i, j) = maglab_identify::cell_of_index(k);
            self.weights[k] / if i == j { 0.5 } else { 1.0 }
        };
        let max = (0..self.weights.len())
            .map(density)
            .fold(0.0f64, f64::max)
            .max(f64::MIN_POSITIVE);
        let mut chart = ChartBuilder::on(root)
            .caption(
                format!("{} (max density {:.4e} per cell area)", self.title, max),
                ("sans-serif", 20),
            )
            .margin(15)
            .x_label_area_size(45)
            .y_label_area_size(60)
            .build_cartesian_2d(lo..hi, lo..hi)
            .map_err(err)?;
        chart
            .configure_mesh()
            .x_desc(format!("β (switch-down threshold), {}", self.axis_label))
            .y_desc(format!("α (switch-up threshold), {}", self.axis_label))
            .label_style(("sans-serif", 15))
            .draw()
            .map_err(err)?;
        for k in 0..self.weights.len() {
            let (i, j) = maglab_identify::cell_of_index(k);
            let (x0, y0) = (lo + i as f64 * width, lo + j as f64 * width);
            let fill = colour(density(k) / max).filled();
            if i == j {
                chart
                    .draw_series(std::iter::once(Polygon::new(
                        vec![(x0, y0), (x0, y0 + width), (x0 + width, y0 + width)],
                        fill,
                    )))
                    .map_err(err)?;
            } else {
                chart
                    .draw_series(std::iter::once(Rectangle::new(
                        [(x0, y0), (x0 + width, y0 + width)],
                        fill,
                    )))
                    .map_err(err)?;
            }
            if self.outlined.contains(&k) {
                chart
                    .draw_series(std::iter::once(Rectangle::new(
                        [(x0, y0), (x0 + width, y0 + width)],
                        RED.stroke_width(2),
                    )))
                    .map_err(err)?;
            }
        }
        Ok(())
    }
}
