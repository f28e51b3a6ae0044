//! `maglab preisach-fit` and `maglab preisach-predict`: the Preisach identification of
//! `maglab-identify` on any (input, output) hysteresis data in a CSV file.
//!
//! `preisach-fit` reads two columns (optionally split into experiments by a group column, and
//! with a row filter choosing the rows that enter the fit — the memory always runs over every
//! row), fits the 325 masses (>= 0, smoothness-regularized) with an offset and a reversible part
//! (by default piecewise linear, a slope >= 0 per grid interval; grid lines and smoothness chosen
//! by validation on held-back fit rows), and writes the model JSON, the weight heat map and measured-vs-fitted loops. The input range is
//! the data's (all rows) widened by a margin, unless `--levels-range` gives it.
//!
//! `preisach-predict` runs a model on a file, prints the NRMSE over the scored rows (RMS error
//! divided by the measured range of those rows), writes the predicted CSV and the loop plot.

mod fit;
mod predict;

pub use fit::{run_fit, FitArgs};
pub use predict::{run_predict, PredictArgs};

use crate::plot::{Figure, Panel, Series, PALETTE};
use anyhow::{anyhow, Result};
use maglab_identify::columns::{ColumnSpec, RowFilter, Table};

/// The row filter of `--fit-rows` / `--score-rows` (`COL=V1,V2,...` or `COL=LO..HI`; all rows
/// without one).
fn filter(text: Option<&str>) -> Result<RowFilter> {
    text.map_or(Ok(RowFilter::All), |t| {
        RowFilter::parse(t).map_err(|e| anyhow!(e))
    })
}

/// Measured against fitted or predicted loops, one series per experiment (`what`: "fitted" or
/// "predicted").
fn loops_figure(
    table: &Table,
    predictions: &[Vec<f64>],
    spec: &ColumnSpec,
    what: &str,
) -> Result<Figure> {
    let mut panel = Panel::new(
        &format!("measured (thin) vs {what} (thick), selected rows"),
        &spec.input,
        &spec.output,
    );
    for (k, (s, p)) in table.series.iter().zip(predictions).enumerate() {
        let colour = PALETTE[k % PALETTE.len()];
        let pick = |v: &[f64]| -> Vec<(f64, f64)> {
            (0..s.input.len())
                .filter(|&t| s.selected[t])
                .map(|t| (s.input[t], v[t]))
                .collect()
        };
        let measured = pick(&s.output);
        if measured.is_empty() {
            continue;
        }
        panel.series.push(Series {
            label: Some(format!("{} measured", s.label)),
            points: measured,
            color: colour,
            width: 1,
        });
        panel.series.push(Series {
            label: Some(format!("{} {what}", s.label)),
            points: pick(p),
            color: colour,
            width: 3,
        });
    }
    Ok(Figure {
        panels: vec![panel],
        rows: 1,
        cols: 1,
        size_px: (1000, 800),
    })
}
