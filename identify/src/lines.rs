//! Where the grid's 26 lines go: equal intervals, or narrower where the data's output
//! changes most.
//!
//! # Equal output change
//!
//! With a density uniform per cell, the output can only bend inside a cell in the way a
//! quadratic does; a uniform grid wastes its 25 intervals on saturated tails where the output
//! barely moves and lumps the steep part of the loops — the coercive region of a soft ferrite,
//! a few percent of the range — into one or two cells. The lines are therefore placed so that
//! each interval carries the same share of the output change the fit data show: every step
//! between two consecutive fit samples of an experiment contributes `|Δy|` at the midpoint of its
//! input step, and the interior lines are the quantiles `k/25` of that distribution over the
//! input (equal *mass* of the measured branches per interval, the Preisach measure's own
//! currency: a branch's output change is twice the mass it switches). The end lines stay at the
//! grid's range. Two guards keep the grid usable: no interval narrower than a tenth of the
//! uniform width (a jump in the data would otherwise stack lines on one point), and intervals
//! with no data in them keep their share of the range (quantiles of nothing collapse).
//!
//! # Validation (`auto`, the default of `maglab preisach-fit`)
//!
//! Finer lines where the output is steep can help loops that reverse there (soft ferrites with a
//! single-slope reversible part: held-out NRMSE 2.04 → 1.19 %) and cost resolution elsewhere (a
//! piezo stack whose fit rows include a switch-on transient: 0.17 → 0.33 %); with the piecewise
//! reversible part carrying the steep anhysteretic curve, equal intervals did better on the
//! ferrites too (validation keeps them). `auto` decides from the fit rows alone: each candidate (uniform,
//! equal output) is fitted on part of them and scored on the rest ([`validation_folds`]:
//! alternate blocks of every experiment's fit rows), and the candidate with the lower pooled RMS
//! error wins; the scores are reported.

use crate::design::{Experiment, Grid};
use crate::LEVELS;

/// How the lines are chosen.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LineChoice {
    /// `LEVELS` equal intervals of the range.
    Uniform,
    /// Equal output change per interval (module docs).
    EqualOutput,
    /// Whichever of the two predicts held-back fit rows better (module docs, "Validation";
    /// `crate::table_fit::fit_table` runs it).
    Auto,
}

impl LineChoice {
    /// Parses `uniform` / `equal-output` / `auto`.
    pub fn parse(text: &str) -> Result<Self, String> {
        match text {
            "uniform" => Ok(LineChoice::Uniform),
            "equal-output" => Ok(LineChoice::EqualOutput),
            "auto" => Ok(LineChoice::Auto),
            other => Err(format!(
                "grid lines `{other}`: expected `auto`, `uniform` or `equal-output`"
            )),
        }
    }

    /// The name [`LineChoice::parse`] reads.
    pub fn name(self) -> &'static str {
        match self {
            LineChoice::Uniform => "uniform",
            LineChoice::EqualOutput => "equal-output",
            LineChoice::Auto => "auto",
        }
    }
}

/// One validation fold: per experiment, the rows that fit and the rows that are predicted.
pub type Fold = (Vec<Vec<bool>>, Vec<Vec<bool>>);

/// Consecutive blocks each experiment's fit rows are cut into for validation.
pub const VALIDATION_BLOCKS: usize = 20;

/// Validation folds over the fit rows: every experiment's fit rows cut into
/// [`VALIDATION_BLOCKS`] consecutive blocks, the even blocks fitting and the odd ones predicted,
/// and the other way round. Every part of every record (a switch-on transient, the later cycles,
/// each amplitude) is on both sides, so a candidate is judged on the input range and history the
/// final fit (on all fit rows) will cover — not on extrapolation: leaving a whole loop out and
/// predicting it from the others scores a candidate on an amplitude its training rows never
/// reached, which chose finer lines that predicted worse (an almost anhysteretic loop: 1.29 %
/// instead of 0.13 %; the ferrites: 0.87 / 0.99 % instead of 0.90 / 0.79 %). Returns, per fold,
/// the masks of rows that fit and that are predicted, per experiment (empty when no experiment has
/// fit rows).
pub fn validation_folds(selected: &[&[bool]]) -> Vec<Fold> {
    if !selected.iter().any(|s| s.iter().any(|&x| x)) {
        return Vec::new();
    }
    [0, 1]
        .into_iter()
        .map(|parity| {
            let mut fit: Vec<Vec<bool>> = selected.iter().map(|s| vec![false; s.len()]).collect();
            let mut predict = fit.clone();
            for (e, rows) in selected.iter().enumerate() {
                let count = rows.iter().filter(|&&x| x).count();
                let block = count.div_ceil(VALIDATION_BLOCKS).max(1);
                let selected_rows = (0..rows.len()).filter(|&t| rows[t]);
                for (n, t) in selected_rows.enumerate() {
                    if (n / block) % 2 == parity {
                        fit[e][t] = true;
                    } else {
                        predict[e][t] = true;
                    }
                }
            }
            (fit, predict)
        })
        .collect()
}

/// Smallest interval, as a fraction of the uniform width.
pub const MIN_INTERVAL_FRACTION: f64 = 0.1;

/// The grid over `[h_min, h_max]` with lines chosen by `choice` from the selected rows of
/// `experiments`. Falls back to equal intervals when the data show no output change.
pub fn choose_grid(
    h_min: f64,
    h_max: f64,
    choice: LineChoice,
    experiments: &[Experiment<'_>],
) -> Grid {
    let uniform = Grid::uniform(h_min, h_max);
    if choice == LineChoice::Uniform {
        return uniform;
    }
    // (input position, output change) of every step between consecutive selected samples.
    let mut steps: Vec<(f64, f64)> = Vec::new();
    for e in experiments {
        let mut previous: Option<(f64, f64)> = None;
        for ((&u, &y), &selected) in e.input.iter().zip(e.output).zip(e.selected) {
            if !(selected && u.is_finite() && y.is_finite()) {
                previous = None;
                continue;
            }
            if let Some((u0, y0)) = previous {
                let position = 0.5 * (u0 + u);
                if position > h_min && position < h_max && y != y0 {
                    steps.push((position, (y - y0).abs()));
                }
            }
            previous = Some((u, y));
        }
    }
    let total: f64 = steps.iter().map(|s| s.1).sum();
    if steps.is_empty() || total <= 0.0 || !total.is_finite() {
        return uniform;
    }
    steps.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut lines = [0.0; LEVELS + 1];
    lines[0] = h_min;
    lines[LEVELS] = h_max;
    let mut accumulated = 0.0;
    let mut k = 1;
    for &(position, change) in &steps {
        accumulated += change;
        while k < LEVELS && accumulated >= total * k as f64 / LEVELS as f64 {
            lines[k] = position;
            k += 1;
        }
    }
    while k < LEVELS {
        lines[k] = h_max;
        k += 1;
    }
    enforce_min_width(&mut lines, MIN_INTERVAL_FRACTION * uniform.cell_width());
    Grid::with_lines(lines).unwrap_or(uniform)
}

/// Moves interior lines so that every interval is at least `min_width` wide, keeping the ends:
/// a forward pass pushes lines up, a backward pass pulls them down from the top (both feasible
/// because `LEVELS · min_width` is below the range).
fn enforce_min_width(lines: &mut [f64; LEVELS + 1], min_width: f64) {
    for k in 1..LEVELS {
        lines[k] = lines[k].max(lines[k - 1] + min_width);
    }
    for k in (1..LEVELS).rev() {
        lines[k] = lines[k].min(lines[k + 1] - min_width);
    }
}
