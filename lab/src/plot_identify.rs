//! The figures of `maglab identify`: the identified masses on the Preisach plane, measured vs
//! predicted M-H loops, the Figure 5 chart (ξ against frequency per candidate R_eddy) and
//! measured vs predicted displacement loops per frequency.

use crate::plot::{Figure, Panel, Series, PALETTE};
use crate::plot_preisach::WeightMap;
use anyhow::Result;
use maglab_identify::dynamics::DynamicFit;
use maglab_identify::experiments::SplitDataset;
use maglab_identify::Identified;
use std::path::{Path, PathBuf};

/// Writes every figure of `id` (from the dataset `split`, on the grid of `base`) into `dir`;
/// returns the files written.
pub fn write_all(
    id: &Identified,
    split: &SplitDataset,
    base: &actuator_params::ActuatorParams,
    dir: &Path,
) -> Result<Vec<PathBuf>> {
    let mut written = Vec::new();
    let map = WeightMap {
        title: "identified masses".into(),
        axis_label: "kA/m".into(),
        axis_scale: 1e-3,
        h_min: base.preisach.h_min_a_per_m,
        h_max: base.preisach.h_max_a_per_m,
        weights: &id.masses.fit.weights,
        outlined: &id.masses.fit.unexcited,
    };
    written.extend(map.write(&dir.join("identified-weights"))?);
    written.extend(mh_loops(id).write(&dir.join("identified-loops"))?);
    if let Some(fit) = &id.dynamic {
        written.extend(figure5(fit).write(&dir.join("identified-figure5"))?);
        written.extend(dynamic_loops(fit, split).write(&dir.join("identified-dynamic-loops"))?);
    }
    Ok(written)
}

/// Measured (thin) vs predicted (thick) M-H loops of every quasi-static record.
fn mh_loops(id: &Identified) -> Figure {
    let mut panel = Panel::new(
        "measured (thin) vs predicted (thick) M-H loops",
        "H, kA/m",
        "M, kA/m",
    );
    for (k, f) in id.masses.files.iter().enumerate() {
        let colour = PALETTE[k % PALETTE.len()];
        let pts = |m: &[f64]| -> Vec<(f64, f64)> {
            f.h_a_per_m
                .iter()
                .zip(m)
                .map(|(h, m)| (h * 1e-3, m * 1e-3))
                .collect()
        };
        panel.series.push(Series {
            label: Some(format!("{} measured", f.file)),
            points: pts(&f.m_measured_a_per_m),
            color: colour,
            width: 1,
        });
        panel.series.push(Series {
            label: Some(format!("{} predicted", f.file)),
            points: pts(&f.m_predicted_a_per_m),
            color: colour,
            width: 3,
        });
    }
    Figure {
        panels: vec![panel],
        rows: 1,
        cols: 1,
        size_px: (1000, 800),
    }
}

/// The Figure 5 chart: `ξ_k` against frequency for candidates around the chosen `R_eddy`.
fn figure5(fit: &DynamicFit) -> Figure {
    let pl = &fit.phase_lag;
    let freqs: Vec<f64> = fit.experiments.iter().map(|e| e.frequency_hz).collect();
    let mut panel = Panel::new(
        "damping ratio from the phase lag of (5), per candidate R_eddy (Figure 5)",
        "frequency, Hz",
        "ξ",
    );
    let best = pl
        .coarse
        .iter()
        .enumerate()
        .min_by(|a, b| {
            (a.1.eddy_resistance_ohm - pl.chosen.eddy_resistance_ohm)
                .abs()
                .total_cmp(&(b.1.eddy_resistance_ohm - pl.chosen.eddy_resistance_ohm).abs())
        })
        .map_or(0, |(k, _)| k);
    let lo = best.saturating_sub(3);
    let hi = (best + 3).min(pl.coarse.len() - 1);
    for (colour, c) in (1..).zip(&pl.coarse[lo..=hi]) {
        panel.series.push(Series {
            label: Some(format!("R = {:.1} Ω", c.eddy_resistance_ohm)),
            points: freqs
                .iter()
                .copied()
                .zip(c.damping_ratios.iter().copied())
                .collect(),
            color: PALETTE[colour % PALETTE.len()],
            width: 2,
        });
    }
    panel.series.push(Series {
        label: Some(format!(
            "chosen R = {:.1} Ω, ξ = {:.3}",
            pl.chosen.eddy_resistance_ohm, pl.chosen.weighted_mean
        )),
        points: freqs
            .iter()
            .copied()
            .zip(pl.chosen.damping_ratios.iter().copied())
            .collect(),
        color: PALETTE[0],
        width: 4,
    });
    let ys = panel
        .series
        .iter()
        .flat_map(|s| s.points.iter().map(|p| p.1));
    let (y0, y1) = ys
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(v), b.max(v))
        });
    let m = pl.chosen.weighted_mean;
    // Keep the chart readable: at most ±100 % of the chosen ξ around it.
    panel.y_range = Some((y0.max(0.0).min(m * 0.5), y1.min(m * 2.0).max(m * 1.5)));
    panel.legend = plotters::chart::SeriesLabelPosition::UpperRight;
    Figure {
        panels: vec![panel],
        rows: 1,
        cols: 1,
        size_px: (1000, 700),
    }
}

/// Measured vs predicted displacement against current over each experiment's steady state.
fn dynamic_loops(fit: &DynamicFit, split: &SplitDataset) -> Figure {
    let mut panels = Vec::new();
    for (e, d) in fit.experiments.iter().zip(&split.dynamic) {
        let m = &d.measurement;
        let pts = |y: &[f64]| -> Vec<(f64, f64)> {
            e.window
                .clone()
                .map(|k| (m.current_a[k], y[k] * 1e6))
                .collect()
        };
        let mut panel = Panel::new(
            &format!("{:.1} Hz", e.frequency_hz),
            "current, A",
            "displacement, µm",
        );
        panel.series.push(Series {
            label: Some("measured".into()),
            points: pts(&m.displacement_m),
            color: PALETTE[7],
            width: 1,
        });
        panel.series.push(Series {
            label: Some(format!("phase-lag ({:.2} %)", 100.0 * e.nrmse_phase_lag)),
            points: pts(&e.predicted_phase_lag_m),
            color: PALETTE[2],
            width: 2,
        });
        if let (Some(y), Some(n)) = (&e.predicted_refined_m, e.nrmse_refined) {
            panel.series.push(Series {
                label: Some(format!("final fit ({:.2} %)", 100.0 * n)),
                points: pts(y),
                color: PALETTE[1],
                width: 2,
            });
        }
        panels.push(panel);
    }
    let cols = 3.min(panels.len()).max(1);
    let rows = panels.len().div_ceil(cols);
    Figure {
        panels,
        rows,
        cols,
        size_px: (500 * cols as u32, 400 * rows as u32),
    }
}
