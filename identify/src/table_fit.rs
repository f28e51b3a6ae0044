//! A generic Preisach model fitted to an (input, output) table (`maglab preisach-fit`) and
//! predicted on one (`maglab preisach-predict`): the grid from the data's range, the choice of
//! lines and smoothness by validation, each experiment's start state (a closed loop periodic).

use crate::design::Grid;
use crate::model::{initial_of, nrmse, PreisachModel, FORMAT};
use maglab_dataset::StartState;

/// Margin added on each side of the data's input range for a generic fit (fraction of the
/// range): the extreme samples then lie inside the top and bottom intervals, not on the edge.
pub const DEFAULT_RANGE_MARGIN: f64 = 0.02;

/// Fits a generic model to the selected rows of `table` (every experiment starts from
/// `initial`, or, with `closed_loops_periodic`, each closed loop `periodic`: [`crate::model::is_closed_loop`]). The grid is `range` if given, else the input range of the whole table (all rows,
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
    let range_grid = range_grid(table, spec, range, margin)?;
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
    let (lines, options, validation) =
        choose_lines_and_smoothness(&range_grid, &experiments, lines, auto_smoothness, options)?;
    let options = &options;
    let grid = crate::lines::choose_grid(range_grid.h_min, range_grid.h_max, lines, &experiments);
    let result = crate::fit::fit(&grid, &experiments, None, options)?;
    let provenance = provenance(
        table,
        spec,
        (initial, closed_loops_periodic),
        (range, margin),
        (lines, validation.as_deref()),
        options,
        &result,
    );
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

/// The uniform grid the lines are chosen in: `range` if given, else the input range of the
/// whole table (all rows, selected or not, so that prediction on the other rows stays inside
/// the grid) widened by `margin` on each side. An input without variation is an error naming
/// the column.
fn range_grid(
    table: &crate::columns::Table,
    spec: &crate::columns::ColumnSpec,
    range: Option<(f64, f64)>,
    margin: f64,
) -> Result<Grid, crate::fit::FitError> {
    if let Some((lo, hi)) = range {
        return Ok(Grid::uniform(lo, hi));
    }
    let (lo, hi) = table.input_range();
    if hi.partial_cmp(&lo) != Some(std::cmp::Ordering::Greater) {
        return Err(crate::fit::FitError(format!(
            "{}: column `{}` has no variation: no hysteresis to fit",
            table.path.display(),
            spec.input
        )));
    }
    Ok(Grid::around(lo, hi, margin))
}

/// The grid lines and the fit options with their smoothness: `lines` and `options` as given
/// when each is fixed, else chosen by [`validate_choices`] (with every candidate's score).
fn choose_lines_and_smoothness(
    range_grid: &Grid,
    experiments: &[crate::design::Experiment<'_>],
    lines: crate::lines::LineChoice,
    auto_smoothness: bool,
    options: &crate::fit::FitOptions,
) -> Result<
    (
        crate::lines::LineChoice,
        crate::fit::FitOptions,
        Option<Vec<Candidate>>,
    ),
    crate::fit::FitError,
> {
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
    if line_candidates.len() * smoothness_candidates.len() == 1 {
        return Ok((line_candidates[0], *options, None));
    }
    let (choice, smoothness, scores) = validate_choices(
        range_grid,
        experiments,
        options,
        line_candidates,
        smoothness_candidates,
    )?;
    Ok((
        choice,
        crate::fit::FitOptions {
            smoothness,
            ..*options
        },
        Some(scores),
    ))
}

/// The model's provenance: the source table and its experiments, the rows fitted, each
/// experiment's start, the grid's range and lines with the validation that chose them, the
/// options and the fit's figures.
fn provenance(
    table: &crate::columns::Table,
    spec: &crate::columns::ColumnSpec,
    (initial, closed_loops_periodic): (StartState, bool),
    (range, margin): (Option<(f64, f64)>, f64),
    (lines, validation): (crate::lines::LineChoice, Option<&[Candidate]>),
    options: &crate::fit::FitOptions,
    result: &crate::fit::FitResult,
) -> serde_json::Value {
    serde_json::json!({
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
        "validation": validation.map(|scores| scores.iter().map(|(c, smoothness, rms)| {
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
    })
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
