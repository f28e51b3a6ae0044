//! `maglab-identify`: identification of the actuator model from measured data (paper Section 4).
//!
//! This crate owns everything between a folder of measurement files and an identified parameter
//! file:
//!
//! * the measurement format (`t_s,current_a,displacement_m`, one experiment per file, a dataset
//!   is a folder) and its errors (file, line, column, value) are `maglab_dataset`'s; [`columns`]
//!   reads two arbitrary numeric columns of any CSV for the generic hysteresis fit.
//! * [`memory`]: an f64 Preisach memory (the staircase of dominant reversal points) written
//!   independently of the no_std core, and [`cells`]: the exact fraction of every grid cell's area
//!   inside `P₊` for a memory state. These fractions are the regressors: with a density uniform per
//!   cell, `Γ = Σ_k w_k (2 f_k - 1)` exactly (equation (3)).
//! * [`design`]: the regression (design) matrix over one or more experiments, accumulated as
//!   normal equations, and the report of cells the data never excited.
//! * [`fit`]: non-negative, optionally regularized least squares of the cell masses (and of an
//!   optional affine/reversible part) solved as a convex QP with `clarabel`.
//! * [`model`]: a fitted generic Preisach model (JSON), its prediction and the NRMSE metric.
//! * [`lines`] and [`reach`]: where the grid's lines go, and the grid from the field the data
//!   reach (a rod the coil cannot saturate).
//! * [`masses`]: the 325 masses of a quasi-static dataset, through [`magnetization`]
//!   (displacement → magnetization by the static model (6)).
//! * [`experiments`]: the dataset convention — which files are quasi-static and which are dynamic
//!   (sub-folders `quasi-static/`, `dynamic/`, or the spectrum of each file's current, with
//!   `maglab_signal::spectrum`).
//! * [`dynamics`]: `R_eddy`, `ξ`, `f0` from the dynamic experiments with the core's model (4)-(5):
//!   the paper's phase-lag scheme and a direct waveform fit (Levenberg-Marquardt).
//! * [`coverage`]: whether the quasi-static records reverse where the dynamic ones do;
//!   [`quality`]: the checks of a result before it is written (its warnings).
//! * [`pipeline`]: `maglab identify`: dataset → weights (and, with dynamic experiments, R_eddy,
//!   ξ, f0) → the full `ActuatorParams` JSON with provenance. Without dynamic experiments R_eddy,
//!   ξ and f0 are copied from a base parameter file and the provenance says so. The quasi-static
//!   excitation current (first-order reversal curves) is `maglab_dataset::excitation`'s.
//!
//! Grid conventions are the core's (`magctl::preisach`): 25 intervals of `[h_min, h_max]` (equal, or
//! between chosen lines: [`lines`]),
//! cell `(i, j)` (β in interval `i`, α in interval `j`, `i <= j`), alpha-major index
//! `j (j + 1) / 2 + i`, diagonal cells are half-squares, weights are cell masses.

pub mod cells;
pub mod columns;
pub mod coverage;
pub mod design;
pub mod dynamics;
pub mod experiments;
pub mod fit;
pub mod lines;
pub mod magnetization;
pub mod masses;
pub mod memory;
pub mod model;
pub mod pipeline;
pub mod quality;
pub mod reach;
pub mod table_fit;

/// Number of input levels of the grid (the core's `LEVELS`).
pub const LEVELS: usize = actuator_params::PREISACH_LEVELS;
/// Number of cells, `LEVELS (LEVELS + 1) / 2`.
pub const CELL_COUNT: usize = LEVELS * (LEVELS + 1) / 2;

/// Index of cell `(i, j)`, `i <= j`, alpha-major (the core's and the schema's order).
pub const fn cell_index(i: usize, j: usize) -> usize {
    j * (j + 1) / 2 + i
}

/// The cell `(i, j)` at `index` (inverse of [`cell_index`]).
pub fn cell_of_index(index: usize) -> (usize, usize) {
    let mut j = 0;
    while (j + 1) * (j + 2) / 2 <= index {
        j += 1;
    }
    (index - j * (j + 1) / 2, j)
}

pub use pipeline::{identify, Base, Identified, IdentifyError, IdentifyOptions, RecordedDataset};
