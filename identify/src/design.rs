//! The regression over one or more experiments, accumulated as normal equations, and the
//! excitation report.
//!
//! Row `t` of the design matrix holds the regressors `2 f_k(t) - 1` of the 325 cells (see
//! [`crate::cells`]) for the memory state after the input history up to `t`, optionally followed
//! by the affine columns `1` (offset) and `x / L - ½` (slope in normalized input, for a reversible
//! component). Only the normal equations `AᵀA`, `Aᵀb`, `bᵀb` are kept (at most 327² numbers,
//! whatever the number of samples).
//!
//! A cell is *excited* when its regressor takes more than one value over the rows that enter the
//! fit; a constant column cannot be told apart from the other constant columns (and from an
//! offset), so the data say nothing about that cell's own mass — [`Design::unexcited`] lists them
//! and the fit decides what to do with them, openly ([`crate::fit::Unexcited`]).

use crate::cells::fractions;
use crate::fit::Reversible;
use crate::memory::{Memory, Piece};
use crate::{CELL_COUNT, LEVELS};
use maglab_dataset::StartState;

/// The Preisach grid: `LEVELS` intervals of `[h_min, h_max]` (input units), equal or between
/// given lines. Inside interval `k` the normalized input runs affinely from `k` to `k + 1`, so a
/// cell's density is uniform in the input and the regressors ([`crate::cells`]) are those of the
/// uniform grid in the normalized input.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Grid {
    /// Bottom of the input range.
    pub h_min: f64,
    /// Top of the input range.
    pub h_max: f64,
    /// The `LEVELS + 1` grid lines (`lines[0] = h_min`, `lines[LEVELS] = h_max`, strictly
    /// increasing); `None`: equal intervals.
    pub lines: Option<[f64; LEVELS + 1]>,
    /// The inputs `(low, high)` a start `conditioned` swept (the firmware's conditioning of a
    /// rod it cannot saturate: up to `high`, down to `low`); `None`: that start is negative
    /// saturation.
    pub conditioning: Option<(f64, f64)>,
}

impl Grid {
    /// `LEVELS` equal intervals of `[h_min, h_max]`.
    pub fn uniform(h_min: f64, h_max: f64) -> Self {
        Grid {
            h_min,
            h_max,
            lines: None,
            conditioning: None,
        }
    }

    /// A grid between the given lines (checked: finite, strictly increasing).
    pub fn with_lines(lines: [f64; LEVELS + 1]) -> Result<Self, String> {
        if lines.iter().any(|h| !h.is_finite()) || lines.windows(2).any(|w| w[0] >= w[1]) {
            return Err(format!(
                "grid lines must be finite and increase strictly, got {lines:?}"
            ));
        }
        Ok(Grid {
            h_min: lines[0],
            h_max: lines[LEVELS],
            lines: Some(lines),
            conditioning: None,
        })
    }

    /// A grid between lines given as a slice (a parameter or model file's field): exactly
    /// `LEVELS + 1` of them, checked as [`Grid::with_lines`] does.
    pub fn from_line_slice(lines: &[f64]) -> Result<Self, String> {
        let lines = <[f64; LEVELS + 1]>::try_from(lines)
            .map_err(|_| format!("{} grid lines, need {}", lines.len(), LEVELS + 1))?;
        Grid::with_lines(lines)
    }

    /// The grid of a parameter file's `preisach` section: its lines, or equal intervals of its
    /// range. The error names the field.
    pub fn of_params(p: &actuator_params::Preisach) -> Result<Self, String> {
        match &p.grid_lines_a_per_m {
            Some(lines) => Grid::from_line_slice(lines)
                .map_err(|e| format!("preisach.grid_lines_a_per_m: {e}")),
            None => Ok(Grid::uniform(p.h_min_a_per_m, p.h_max_a_per_m)),
        }
    }

    /// The same grid with the sweep of a `conditioned` start.
    pub fn with_conditioning(mut self, sweep: Option<(f64, f64)>) -> Self {
        self.conditioning = sweep;
        self
    }

    /// The grid lines (equally spaced when none were given).
    pub fn lines(&self) -> [f64; LEVELS + 1] {
        match self.lines {
            Some(lines) => lines,
            None => std::array::from_fn(|k| {
                // (the ends exactly, not through the rounded width)
                if k == LEVELS {
                    self.h_max
                } else {
                    self.h_min + k as f64 * self.cell_width()
                }
            }),
        }
    }

    /// Normalized input: `(u - h_min) / Δ` on equal intervals, else interval `k` mapped affinely
    /// onto `[k, k + 1]` (the end intervals continued outward; not clamped).
    pub fn normalize(&self, u: f64) -> f64 {
        match &self.lines {
            None => (u - self.h_min) / self.cell_width(),
            Some(lines) => {
                let k = lines[1..LEVELS]
                    .partition_point(|&line| line <= u)
                    .min(LEVELS - 1);
                k as f64 + (u - lines[k]) / (lines[k + 1] - lines[k])
            }
        }
    }

    /// The input as the affine/reversible part sees it: the input itself on equal intervals,
    /// `h_min + Δ·x` (the normalized input `x` mapped back with the mean width) otherwise — a
    /// monotone piecewise-linear function of the input with a kink at every line, the regressor
    /// the fit's affine column uses (`x / L − ½`).
    pub fn equivalent_input(&self, u: f64, x: f64) -> f64 {
        match self.lines {
            None => u,
            Some(_) => self.h_min + self.cell_width() * x,
        }
    }

    /// Δ, the mean width of an interval (the width of every interval on equal intervals).
    pub fn cell_width(&self) -> f64 {
        (self.h_max - self.h_min) / LEVELS as f64
    }

    /// A grid over the data range `[lo, hi]` widened by `margin` (a fraction of `hi - lo`) on each
    /// side, so that the extreme samples do not sit on the grid edge.
    pub fn around(lo: f64, hi: f64, margin: f64) -> Self {
        let pad = (hi - lo) * margin;
        Grid::uniform(lo - pad, hi + pad)
    }
}

/// One experiment for the design: the input and output in fit units, which rows enter the fit,
/// and the initial memory.
#[derive(Debug, Clone, Copy)]
pub struct Experiment<'a> {
    /// Label for reports.
    pub label: &'a str,
    /// Input sequence (e.g. H in A/m).
    pub input: &'a [f64],
    /// Output sequence (e.g. M in A/m).
    pub output: &'a [f64],
    /// Rows that enter the fit (same length as `input`).
    pub selected: &'a [bool],
    /// Initial memory.
    pub initial: StartState,
    /// Weight of each row (inverse variance of the output, normalized by the caller), `None`:
    /// all 1.
    pub weights: Option<&'a [f64]>,
}

/// Runs the memory through an experiment and calls `row(t, x_normalized, fractions)` (`x` not
/// clamped to the grid) for every
/// sample `t` (after the input moved to sample `t`). Returns the number of samples whose input
/// lay outside the grid (those saturate the memory: counted, not hidden).
pub fn run_experiment(
    grid: &Grid,
    input: &[f64],
    initial: StartState,
    mut row: impl FnMut(usize, f64, &[f64; CELL_COUNT]),
) -> usize {
    // Demagnetized: around zero input, or around the first input. Periodic: around the middle of the experiment's
    // excursion (a centred periodic loop was reached by cycling down from larger amplitudes about
    // its centre; the preconditioning period then wipes out everything inside the excursion).
    let centre_x = if initial == StartState::Periodic {
        let (lo, hi) = input
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &u| {
                (a.min(u), b.max(u))
            });
        grid.normalize(0.5 * (lo + hi))
    } else if matches!(
        initial,
        StartState::Demagnetized | StartState::SwitchOnDemagnetized
    ) {
        grid.normalize(0.0)
    } else {
        input.first().map_or(0.0, |&u| grid.normalize(u))
    };
    let mut memory = Memory::initial(LEVELS, initial, centre_x);
    if let (StartState::Conditioned, Some((low, high))) = (initial, grid.conditioning) {
        memory.move_to(grid.normalize(high).clamp(0.0, LEVELS as f64));
        memory.move_to(grid.normalize(low).clamp(0.0, LEVELS as f64));
    }
    if initial == StartState::Periodic {
        for &u in input {
            memory.move_to(grid.normalize(u));
        }
    }
    let mut pieces: Vec<Piece> = Vec::new();
    let mut f = [0.0; CELL_COUNT];
    let mut outside = 0;
    let top = LEVELS as f64;
    for (t, &u) in input.iter().enumerate() {
        let x = grid.normalize(u);
        if !(0.0..=top).contains(&x) {
            outside += 1;
        }
        memory.move_to(x);
        fractions(&memory, &mut pieces, &mut f);
        // Unclamped: the affine part continues beyond the grid (the memory saturates there), the
        // same as `PreisachModel::predict` evaluates it.
        row(t, x, &f);
    }
    outside
}

/// Interval `k`'s ramp of the piecewise reversible part at normalized input `x`:
/// `clamp(x - k, 0, 1) - ½` (centred, so that an odd curve needs no offset).
pub fn ramp(x: f64, k: usize) -> f64 {
    (x - k as f64).clamp(0.0, 1.0) - 0.5
}

/// Normal equations of the regression and the excitation bookkeeping.
#[derive(Debug, Clone)]
pub struct Design {
    /// The reversible part's columns after the masses.
    pub reversible: Reversible,
    /// Number of unknowns: 325 plus [`Reversible::unknowns`].
    pub unknowns: usize,
    /// `AᵀA`, dense, row-major `unknowns × unknowns` (both triangles filled at the end).
    pub ata: Vec<f64>,
    /// `Aᵀb`.
    pub atb: Vec<f64>,
    /// `bᵀb`.
    pub btb: f64,
    /// Rows accumulated.
    pub rows: usize,
    /// Smallest and largest value of each cell's regressor over the rows.
    pub column_range: Vec<(f64, f64)>,
    /// Smallest and largest output over the rows.
    pub output_range: (f64, f64),
    /// Samples whose input was outside the grid, per experiment label.
    pub outside: Vec<(String, usize)>,
    /// Rows that were selected but skipped by the row stride.
    pub strided_out: usize,
}

/// A column whose regressor varies by less than this over the fit rows is not excited
/// (fractions are sums of a few exact areas: rounding is ~1e-15).
pub const EXCITATION_THRESHOLD: f64 = 1e-9;

impl Design {
    /// Builds the normal equations over `experiments`. `output_scale` divides the outputs (the
    /// fit works in units of the output range); `row_stride` keeps every n-th selected row (the
    /// memory still sees every sample; the count of rows left out is reported).
    pub fn build(
        grid: &Grid,
        experiments: &[Experiment<'_>],
        reversible: Reversible,
        output_scale: f64,
        row_stride: usize,
    ) -> Self {
        let unknowns = CELL_COUNT + reversible.unknowns();
        let mut design = Design {
            reversible,
            unknowns,
            ata: vec![0.0; unknowns * unknowns],
            atb: vec![0.0; unknowns],
            btb: 0.0,
            rows: 0,
            column_range: vec![(f64::INFINITY, f64::NEG_INFINITY); CELL_COUNT],
            output_range: (f64::INFINITY, f64::NEG_INFINITY),
            outside: Vec::new(),
            strided_out: 0,
        };
        let stride = row_stride.max(1);
        let mut a = vec![0.0; unknowns];
        for e in experiments {
            let mut selected_seen = 0usize;
            let outside = run_experiment(grid, e.input, e.initial, |t, x, f| {
                if !e.selected.get(t).copied().unwrap_or(false) {
                    return;
                }
                selected_seen += 1;
                if !(selected_seen - 1).is_multiple_of(stride) {
                    design.strided_out += 1;
                    return;
                }
                for k in 0..CELL_COUNT {
                    a[k] = 2.0 * f[k] - 1.0;
                    let r = &mut design.column_range[k];
                    r.0 = r.0.min(a[k]);
                    r.1 = r.1.max(a[k]);
                }
                match reversible {
                    Reversible::None => {}
                    Reversible::Offset => a[CELL_COUNT] = 1.0,
                    Reversible::Linear => {
                        a[CELL_COUNT] = 1.0;
                        a[CELL_COUNT + 1] = x / LEVELS as f64 - 0.5;
                    }
                    Reversible::Piecewise | Reversible::PiecewiseNoOffset => {
                        if reversible == Reversible::Piecewise {
                            a[CELL_COUNT] = 1.0;
                        }
                        let first = reversible.first_slope();
                        for k in 0..LEVELS {
                            a[first + k] = ramp(x, k);
                        }
                    }
                }
                let y = e.output[t];
                design.output_range.0 = design.output_range.0.min(y);
                design.output_range.1 = design.output_range.1.max(y);
                let b = y / output_scale;
                let w = e.weights.and_then(|w| w.get(t).copied()).unwrap_or(1.0);
                design.add_row(&a, b, w);
            });
            design.outside.push((e.label.to_string(), outside));
        }
        design.symmetrize();
        design
    }

    fn add_row(&mut self, a: &[f64], b: f64, weight: f64) {
        let n = self.unknowns;
        for r in 0..n {
            let ar = a[r] * weight;
            if ar == 0.0 {
                continue;
            }
            let row = &mut self.ata[r * n..(r + 1) * n];
            for (c, &ac) in a.iter().enumerate().skip(r) {
                row[c] += ar * ac;
            }
            self.atb[r] += ar * b;
        }
        self.btb += weight * b * b;
        self.rows += 1;
    }

    fn symmetrize(&mut self) {
        let n = self.unknowns;
        for r in 0..n {
            for c in 0..r {
                self.ata[r * n + c] = self.ata[c * n + r];
            }
        }
    }

    /// [`Design::unexcited`], with the cells of `bands` also unexcited when their regressor
    /// varies by less than [`crate::fit::BAND_EXCITATION`].
    pub fn unexcited_with_bands(&self, bands: crate::fit::Bands) -> Vec<usize> {
        self.column_range
            .iter()
            .enumerate()
            .filter(|&(k, (lo, hi))| {
                let threshold = if bands.contains(k) {
                    crate::fit::BAND_EXCITATION
                } else {
                    EXCITATION_THRESHOLD
                };
                (hi - lo).is_nan() || hi - lo <= threshold
            })
            .map(|(k, _)| k)
            .collect()
    }

    /// Cells whose regressor is constant over the fit rows (alpha-major indices).
    pub fn unexcited(&self) -> Vec<usize> {
        self.column_range
            .iter()
            .enumerate()
            .filter(|(_, (lo, hi))| (hi - lo).is_nan() || hi - lo <= EXCITATION_THRESHOLD)
            .map(|(k, _)| k)
            .collect()
    }
}
