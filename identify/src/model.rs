//! A fitted generic Preisach model (`maglab preisach-fit` writes it as JSON, `preisach-predict`
//! reads it), its prediction and the error metric.
//!
//! `output = Σ_k w_k (2 f_k - 1) + offset + slope · ĥ(input)` on the grid `[h_min, h_max]` with
//! [`crate::LEVELS`] intervals; `f_k` from [`crate::cells`]; `ĥ` is the input itself on equal
//! intervals and the input carried through the grid's piecewise-affine map onto equal intervals
//! otherwise ([`Grid::equivalent_input`]: the reversible part is then monotone piecewise linear,
//! steeper where the grid is finer — where the loops are steep).

use crate::design::{run_experiment, Grid};
use crate::CELL_COUNT;
use maglab_dataset::StartState;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// Identifies the file format (version 2: start states in the workspace's one vocabulary,
/// `maglab_dataset::start`).
pub const FORMAT: &str = "maglab-preisach-model-2";

/// The first version of the format. Its `initial_state` names differ from version 2's:
/// `demagnetized` meant around the first input (`demagnetized-at-first-input` now) and
/// `demagnetized-at-zero` what `demagnetized` means now. Read, never written.
pub const FORMAT_1: &str = "maglab-preisach-model";

/// A generic Preisach model.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PreisachModel {
    /// Always [`FORMAT`].
    pub format: String,
    /// Name of the input column it was fitted on.
    pub input_column: String,
    /// Name of the output column it was fitted on.
    pub output_column: String,
    /// Grid levels (always [`crate::LEVELS`]).
    pub levels: usize,
    /// Bottom of the input range.
    pub h_min: f64,
    /// Top of the input range.
    pub h_max: f64,
    /// The `levels + 1` grid lines (input units) when the intervals are not equal.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub grid_lines: Option<Vec<f64>>,
    /// Cell masses (output units), alpha-major.
    pub weights: Vec<f64>,
    /// Affine offset (output units).
    pub offset: f64,
    /// Affine slope (output units per input unit).
    pub slope: f64,
    /// The piecewise reversible part's slope on each grid interval (output units per input
    /// unit, `>= 0`; [`crate::fit::Reversible::Piecewise`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reversible_slopes: Option<Vec<f64>>,
    /// Initial memory assumed for each experiment (with [`PreisachModel::closed_loops_periodic`],
    /// for each experiment that is not a closed loop).
    pub initial_state: StartState,
    /// `--initial auto`: each experiment is judged on its own, a closed loop
    /// ([`is_closed_loop`]) starting `periodic` and the others from `initial_state`.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub closed_loops_periodic: bool,
    /// How it was fitted (data, options, residuals, unexcited cells).
    pub provenance: serde_json::Value,
}

impl PreisachModel {
    /// The grid.
    pub fn grid(&self) -> Grid {
        // (`validate` checked the lines of a loaded model)
        match self.grid_lines.as_deref().map(Grid::from_line_slice) {
            Some(Ok(grid)) => grid,
            _ => Grid::uniform(self.h_min, self.h_max),
        }
    }

    /// The initial memory of an experiment: `initial_state`, or `periodic` for a closed loop when
    /// [`PreisachModel::closed_loops_periodic`].
    pub fn initial_for(&self, series: &crate::columns::Series) -> StartState {
        initial_of(series, self.initial_state, self.closed_loops_periodic)
    }

    /// Predicts the output for an input sequence from `initial`.
    pub fn predict(&self, input: &[f64], initial: StartState) -> Vec<f64> {
        let grid = self.grid();
        let rises = self
            .reversible_slopes
            .as_deref()
            .map(|slopes| reversible_rises(&grid, slopes));
        let mut out = Vec::with_capacity(input.len());
        run_experiment(&grid, input, initial, |t, x, f| {
            out.push(
                crate::cells::output(f, &self.weights)
                    + self.offset
                    + self.slope * grid.equivalent_input(input[t], x)
                    + rises
                        .as_deref()
                        .map_or(0.0, |rises| piecewise_reversible(rises, x)),
            );
        });
        out
    }

    /// A model of a field → magnetization operator with given masses and no affine part (used to
    /// simulate a parameter file's static model).
    pub fn from_weights(grid: Grid, weights: &[f64], initial_state: StartState) -> Self {
        PreisachModel {
            format: FORMAT.into(),
            input_column: "h_a_per_m".into(),
            output_column: "m_a_per_m".into(),
            levels: crate::LEVELS,
            h_min: grid.h_min,
            h_max: grid.h_max,
            grid_lines: grid.lines.map(|l| l.to_vec()),
            weights: weights.to_vec(),
            offset: 0.0,
            slope: 0.0,
            reversible_slopes: None,
            initial_state,
            closed_loops_periodic: false,
            provenance: serde_json::Value::Null,
        }
    }

    /// Pretty JSON with a final newline.
    pub fn to_json_pretty(&self) -> String {
        let mut text = serde_json::to_string_pretty(self).unwrap_or_default();
        text.push('\n');
        text
    }

    /// Checks the fields a prediction relies on; `name` is used in messages.
    pub fn validate(&self, name: &str) -> Result<(), String> {
        if self.format != FORMAT {
            return Err(format!(
                "{name}: field `format`: expected `{FORMAT}`, got `{}`",
                self.format
            ));
        }
        if self.levels != crate::LEVELS {
            return Err(format!(
                "{name}: field `levels`: expected {}, got {}",
                crate::LEVELS,
                self.levels
            ));
        }
        if !(self.h_min.is_finite() && self.h_max.is_finite() && self.h_min < self.h_max) {
            return Err(format!(
                "{name}: fields `h_min`/`h_max`: need finite h_min < h_max, got [{}, {}]",
                self.h_min, self.h_max
            ));
        }
        if let Some(lines) = &self.grid_lines {
            if lines.len() != crate::LEVELS + 1 {
                return Err(format!(
                    "{name}: field `grid_lines`: {} lines needed, got {}",
                    crate::LEVELS + 1,
                    lines.len()
                ));
            }
            for (k, h) in lines.iter().enumerate() {
                if !h.is_finite() || (k > 0 && *h <= lines[k - 1]) {
                    return Err(format!(
                        "{name}: field `grid_lines[{k}]`: lines must be finite and increase strictly, got {h}"
                    ));
                }
            }
            if lines.first() != Some(&self.h_min) || lines.last() != Some(&self.h_max) {
                return Err(format!(
                    "{name}: field `grid_lines`: the first and last lines must be h_min and h_max ({} and {})",
                    self.h_min, self.h_max
                ));
            }
        }
        if self.weights.len() != CELL_COUNT {
            return Err(format!(
                "{name}: field `weights`: {CELL_COUNT} masses needed, got {}",
                self.weights.len()
            ));
        }
        for (k, w) in self.weights.iter().enumerate() {
            if !(w.is_finite() && *w >= 0.0) {
                return Err(format!(
                    "{name}: field `weights[{k}]`: a mass must be finite and >= 0, got {w}"
                ));
            }
        }
        if let Some(slopes) = &self.reversible_slopes {
            if slopes.len() != crate::LEVELS {
                return Err(format!(
                    "{name}: field `reversible_slopes`: {} slopes needed (one per interval), got {}",
                    crate::LEVELS,
                    slopes.len()
                ));
            }
            for (k, c) in slopes.iter().enumerate() {
                if !(c.is_finite() && *c >= 0.0) {
                    return Err(format!(
                        "{name}: field `reversible_slopes[{k}]`: a slope must be finite and >= 0 \
                         (the reversible part is monotone), got {c}"
                    ));
                }
            }
        }
        for (field, v) in [("offset", self.offset), ("slope", self.slope)] {
            if !v.is_finite() {
                return Err(format!("{name}: field `{field}`: not finite ({v})"));
            }
        }
        Ok(())
    }

    /// Reads and validates a model file.
    pub fn load(path: &Path) -> Result<Self, String> {
        let name = path.display().to_string();
        let text =
            std::fs::read_to_string(path).map_err(|e| format!("{name}: cannot read: {e}"))?;
        let mut value: serde_json::Value =
            serde_json::from_str(&text).map_err(|e| format!("{name}: {e}"))?;
        if value.get("format").and_then(|f| f.as_str()) == Some(FORMAT_1) {
            upgrade_format_1(&mut value);
        }
        let model: Self = serde_json::from_value(value).map_err(|e| format!("{name}: {e}"))?;
        model.validate(&name)?;
        Ok(model)
    }
}

/// A [`FORMAT_1`] document as [`FORMAT`]: the format field and the `initial_state` names.
fn upgrade_format_1(value: &mut serde_json::Value) {
    value["format"] = FORMAT.into();
    let renamed = match value.get("initial_state").and_then(|s| s.as_str()) {
        Some("demagnetized") => Some(StartState::DemagnetizedAtFirstInput),
        Some("demagnetized-at-zero") => Some(StartState::Demagnetized),
        _ => None,
    };
    if let Some(state) = renamed {
        value["initial_state"] = state.name().into();
    }
}

/// The rises `ρ_k = χ_k width_k` of the piecewise reversible part over each interval of `grid`
/// (`slopes`: the `χ_k`, output units per input unit).
pub fn reversible_rises(grid: &Grid, slopes: &[f64]) -> Vec<f64> {
    let lines = grid.lines();
    slopes
        .iter()
        .enumerate()
        .map(|(k, chi)| chi * (lines[k + 1] - lines[k]))
        .collect()
}

/// The piecewise reversible part at normalized input `x` from its rises
/// ([`reversible_rises`]): `Σ_k ρ_k (clamp(x - k, 0, 1) - ½)` (= `Σ_k χ_k (clamp(u, line_k,
/// line_k+1) - mid_k)` in the input `u`; flat beyond the grid, `½ Σ ρ` at its top).
pub fn piecewise_reversible(rises: &[f64], x: f64) -> f64 {
    rises
        .iter()
        .enumerate()
        .map(|(k, rho)| rho * crate::design::ramp(x, k))
        .sum()
}

/// Normalized RMS error: `RMS(predicted - measured) / (max - min of measured)` over the rows with
/// `selected[t]` (all rows when `selected` is `None`). `None` if no row or no output range.
pub fn nrmse(predicted: &[f64], measured: &[f64], selected: Option<&[bool]>) -> Option<f64> {
    let mut sum = 0.0;
    let mut count = 0usize;
    let mut lo = f64::INFINITY;
    let mut hi = f64::NEG_INFINITY;
    for (t, (p, m)) in predicted.iter().zip(measured).enumerate() {
        if selected.is_some_and(|s| !s.get(t).copied().unwrap_or(false)) {
            continue;
        }
        sum += (p - m) * (p - m);
        count += 1;
        lo = lo.min(*m);
        hi = hi.max(*m);
    }
    if count == 0 || hi.partial_cmp(&lo) != Some(std::cmp::Ordering::Greater) {
        return None;
    }
    Some((sum / count as f64).sqrt() / (hi - lo))
}

/// Margin added on each side of the data's input range for a generic fit (fraction of the
/// range): the extreme samples then lie inside the top and bottom intervals, not on the edge.
pub const DEFAULT_RANGE_MARGIN: f64 = 0.02;

/// Fits a generic model to the selected rows of `table` (every experiment starts from
/// `initial`, or, with `closed_loops_periodic`, each closed loop `periodic`: [`is_closed_loop`]). The grid is `range` if given, else the input range of the whole table (all rows,
/// selected or not, so that prediction on the other rows stays inside the grid) widened by
/// `margin` on each side. `lines` (when `Auto`) and `auto_smoothness` (among
/// [`SMOOTHNESS_CANDIDATES`]) are chosen by [`validate_choices`].
// (each argument is one independent choice of the fit; a struct would only rename them)
#[allow(clippy::too_many_arguments)]
pub fn fit_table(
    table: &crate::columns::Table,
    spec: &crate::columns::ColumnSpec,
    range: Option<(f64, f64)>,
    margin: f64,
    (initial, closed_loops_periodic): (StartState, bool),
    lines: crate::lines::LineChoice,
    auto_smoothness: bool,
    options: &crate::fit::FitOptions,
) -> Result<(PreisachModel, crate::fit::FitResult), crate::fit::FitError> {
    let range_grid = match range {
        Some((lo, hi)) => Grid::uniform(lo, hi),
        None => {
            let (lo, hi) = table.input_range();
            if hi.partial_cmp(&lo) != Some(std::cmp::Ordering::Greater) {
                return Err(crate::fit::FitError(format!(
                    "{}: column `{}` has no variation: no hysteresis to fit",
                    table.path.display(),
                    spec.input
                )));
            }
            Grid::around(lo, hi, margin)
        }
    };
    let experiments: Vec<crate::design::Experiment<'_>> = table
        .series
        .iter()
        .map(|s| crate::design::Experiment {
            label: &s.label,
            input: &s.input,
            output: &s.output,
            selected: &s.selected,
            initial: initial_of(s, initial, closed_loops_periodic),
            weights: None,
        })
        .collect();
    // (the choices made are recorded in the provenance's `grid_lines` and `options`)
    let line_candidates: &[crate::lines::LineChoice] = match lines {
        crate::lines::LineChoice::Auto => &[
            crate::lines::LineChoice::Uniform,
            crate::lines::LineChoice::EqualOutput,
        ],
        ref fixed => std::slice::from_ref(fixed),
    };
    let smoothness_candidates: &[f64] = if auto_smoothness {
        &SMOOTHNESS_CANDIDATES
    } else {
        std::slice::from_ref(&options.smoothness)
    };
    let (lines, options, validation) = if line_candidates.len() * smoothness_candidates.len() > 1 {
        let (choice, smoothness, scores) = validate_choices(
            &range_grid,
            &experiments,
            options,
            line_candidates,
            smoothness_candidates,
        )?;
        (
            choice,
            crate::fit::FitOptions {
                smoothness,
                ..*options
            },
            Some(scores),
        )
    } else {
        (line_candidates[0], *options, None)
    };
    let options = &options;
    let grid = crate::lines::choose_grid(range_grid.h_min, range_grid.h_max, lines, &experiments);
    let result = crate::fit::fit(&grid, &experiments, None, options)?;
    let provenance = serde_json::json!({
        "source": "maglab preisach-fit",
        "file": table.path.display().to_string(),
        "experiments": table.series.iter().map(|s| serde_json::json!({
            "label": s.label, "rows": s.input.len(), "fit_rows": s.selected_count()
        })).collect::<Vec<_>>(),
        "row_filter": spec.filter.describe(),
        "initial_states": table.series.iter().map(|s| serde_json::json!({
            "label": s.label,
            "initial_state": initial_of(s, initial, closed_loops_periodic).name(),
        })).collect::<Vec<_>>(),
        "group_column": spec.group,
        "range_margin": if range.is_some() { None } else { Some(margin) },
        "grid_lines": lines.name(),
        "validation": validation.as_ref().map(|scores| scores.iter().map(|(c, smoothness, rms)| {
            serde_json::json!({"lines": c.name(), "smoothness": smoothness, "held_back_rms": rms})
        }).collect::<Vec<_>>()),
        "options": {
            "smoothness": options.smoothness,
            "ridge": options.ridge,
            "reversible": options.reversible.name(),
            "unexcited": options.unexcited.name(),
            "row_stride": options.row_stride,
        },
        "fit": {
            "rows": result.rows,
            "selected_rows_left_out_by_stride": result.strided_out,
            "rms_residual": result.rms_residual,
            "output_range": result.output_scale,
            "solver": result.solver,
        },
        "unexcited_cells": {
            "count": result.unexcited.len(),
            "treatment": options.unexcited.name(),
            "cells_i_j": result.unexcited.iter().map(|&k| {
                let (i, j) = crate::cell_of_index(k); [i, j]
            }).collect::<Vec<_>>(),
        },
    });
    let model = PreisachModel {
        format: FORMAT.into(),
        input_column: spec.input.clone(),
        output_column: spec.output.clone(),
        levels: crate::LEVELS,
        h_min: grid.h_min,
        h_max: grid.h_max,
        grid_lines: grid.lines.map(|l| l.to_vec()),
        weights: result.weights.clone(),
        offset: result.offset,
        slope: result.slope,
        reversible_slopes: options
            .reversible
            .is_piecewise()
            .then(|| result.reversible_slopes.clone()),
        initial_state: initial,
        closed_loops_periodic,
        provenance,
    };
    Ok((model, result))
}

/// The smoothness weights `auto` smoothness chooses from (see [`crate::fit`]: `1e-6` weighs a
/// density jump of 100 % between every pair of neighbours like a 1 % RMS residual).
pub const SMOOTHNESS_CANDIDATES: [f64; 3] = [1e-7, 1e-6, 1e-5];

/// A validated choice: lines, smoothness, and the held-back RMS (output units) of a candidate.
pub type Candidate = (crate::lines::LineChoice, f64, f64);

/// The choice of grid lines ([`crate::lines::LineChoice::Auto`]) and smoothness (`auto`): every
/// candidate fitted on the training part of every validation fold and scored (RMS, output units)
/// on its held-back part; the lowest pooled RMS wins (the first candidate on a tie or when there
/// is nothing to validate on). Returns the choice and every candidate's score.
pub fn validate_choices(
    range: &Grid,
    experiments: &[crate::design::Experiment<'_>],
    options: &crate::fit::FitOptions,
    lines: &[crate::lines::LineChoice],
    smoothness: &[f64],
) -> Result<(crate::lines::LineChoice, f64, Vec<Candidate>), crate::fit::FitError> {
    use crate::lines::{choose_grid, validation_folds};
    let first = (lines[0], smoothness[0]);
    let selected: Vec<&[bool]> = experiments.iter().map(|e| e.selected).collect();
    let folds = validation_folds(&selected);
    if folds.is_empty() {
        return Ok((first.0, first.1, Vec::new()));
    }
    let mut scores = Vec::new();
    for &candidate in lines {
        for &lambda in smoothness {
            let trial = crate::fit::FitOptions {
                smoothness: lambda,
                ..*options
            };
            let (mut sum_sq, mut count) = (0.0, 0usize);
            for (fit_masks, predict_masks) in &folds {
                let training: Vec<crate::design::Experiment<'_>> = experiments
                    .iter()
                    .zip(fit_masks)
                    .map(|(e, mask)| crate::design::Experiment {
                        selected: mask,
                        ..*e
                    })
                    .collect();
                let grid = choose_grid(range.h_min, range.h_max, candidate, &training);
                let result = match crate::fit::fit(&grid, &training, None, &trial) {
                    Ok(r) => r,
                    // A fold whose training rows excite nothing scores as unusable for every
                    // candidate alike: skip it.
                    Err(_) => continue,
                };
                let mut model =
                    PreisachModel::from_weights(grid, &result.weights, StartState::Periodic);
                model.offset = result.offset;
                model.slope = result.slope;
                model.reversible_slopes = options
                    .reversible
                    .is_piecewise()
                    .then(|| result.reversible_slopes.clone());
                for (e, mask) in experiments.iter().zip(predict_masks) {
                    if !mask.iter().any(|&m| m) {
                        continue;
                    }
                    let predicted = model.predict(e.input, e.initial);
                    for ((&p, &y), &m) in predicted.iter().zip(e.output).zip(mask) {
                        if m {
                            sum_sq += (p - y) * (p - y);
                            count += 1;
                        }
                    }
                }
            }
            let rms = if count > 0 {
                (sum_sq / count as f64).sqrt()
            } else {
                f64::INFINITY
            };
            scores.push((candidate, lambda, rms));
        }
    }
    let best = scores
        .iter()
        .filter(|s| s.2.is_finite())
        .min_by(|a, b| a.2.total_cmp(&b.2))
        .map_or(first, |s| (s.0, s.1));
    Ok((best.0, best.1, scores))
}

/// Predictions of `model` for every experiment of `table` (from the model's initial state) and
/// the NRMSE over the selected rows of all experiments together (range = measured range of those
/// rows).
pub fn predict_table(
    model: &PreisachModel,
    table: &crate::columns::Table,
) -> (Vec<Vec<f64>>, Option<f64>) {
    let predictions: Vec<Vec<f64>> = table
        .series
        .iter()
        .map(|s| model.predict(&s.input, model.initial_for(s)))
        .collect();
    let mut pred = Vec::new();
    let mut meas = Vec::new();
    for (s, p) in table.series.iter().zip(&predictions) {
        for ((&sel, &pt), &mt) in s.selected.iter().zip(p).zip(&s.output) {
            if sel {
                pred.push(pt);
                meas.push(mt);
            }
        }
    }
    let score = nrmse(&pred, &meas, None);
    (predictions, score)
}

/// Whether an experiment is a closed loop — one period of a periodic steady state: its last row
/// within 2 % of its input and output ranges of its first. Judged on the experiment's selected
/// rows when it has any (the rows a fit uses), else on all of them.
pub fn is_closed_loop(series: &crate::columns::Series) -> bool {
    let rows: Vec<(f64, f64)> = if series.selected.iter().any(|&s| s) {
        series
            .input
            .iter()
            .zip(&series.output)
            .zip(&series.selected)
            .filter(|(_, &s)| s)
            .map(|((&u, &y), _)| (u, y))
            .collect()
    } else {
        series
            .input
            .iter()
            .copied()
            .zip(series.output.iter().copied())
            .collect()
    };
    let span = |v: &mut dyn Iterator<Item = f64>| {
        let (lo, hi) = v.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
            (a.min(x), b.max(x))
        });
        hi - lo
    };
    match (rows.first(), rows.last()) {
        (Some(&(u0, y0)), Some(&(u1, y1))) => {
            let su = span(&mut rows.iter().map(|r| r.0));
            let sy = span(&mut rows.iter().map(|r| r.1));
            su > 0.0 && (u1 - u0).abs() <= 0.02 * su && (y1 - y0).abs() <= 0.02 * sy.max(1e-300)
        }
        _ => false,
    }
}

/// The initial memory of `series`: `periodic` for a closed loop when `closed_loops_periodic`,
/// else `initial`.
#[doc(hidden)]
pub fn initial_of(
    series: &crate::columns::Series,
    initial: StartState,
    closed_loops_periodic: bool,
) -> StartState {
    if closed_loops_periodic && is_closed_loop(series) {
        StartState::Periodic
    } else {
        initial
    }
}
