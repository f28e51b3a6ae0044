//! A fitted generic Preisach model (`maglab preisach-fit` writes it as JSON, `preisach-predict`
//! reads it; [`crate::table_fit`] fits it), its prediction and the error metric.
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
