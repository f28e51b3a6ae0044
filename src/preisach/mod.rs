//! The Preisach operator `M = Γ[H]` of the paper (Section 2, equations (1)-(3)) on a fixed grid.
//!
//! # Grid, cells and weight order (used everywhere in this project)
//!
//! The input range `[h_min, h_max]` is split into [`LEVELS`] = 25 equal intervals of width
//! `Δ = (h_max - h_min) / 25`. Internally inputs are *normalized*: `x = (h - h_min) / Δ ∈ [0, 25]`.
//! A hysteron (relay, equation (1)) has a switch-up threshold α and a switch-down threshold β,
//! `β <= α`. The Preisach plane `{β <= α}` over the range is cut into [`CELL_COUNT`] = 325 cells:
//! cell `(i, j)` holds the hysterons with `β ∈ [i, i+1]` and `α ∈ [j, j+1]` (normalized), `i <= j`.
//! The 300 cells with `i < j` are unit squares; the 25 cells with `i == j` are the half-squares
//! (triangles) on the diagonal. Cell `(i, j)` carries a non-negative mass `w_ij` (A/m) spread
//! **uniformly** over the cell (the paper's nonsingular measure, Section 4). Masses are stored in
//! **alpha-major** order: index [`cell_index`]`(i, j) = j (j + 1) / 2 + i`.
//!
//! The output is `M = μ(P₊) - μ(P₋) = 2 μ(P₊) - Σ w` (equation (3)), so it saturates at `±Σ w`
//! (the default measure has `Σ w = M_s`).
//!
//! # How the output is kept cheap
//!
//! [`PreisachMeasure`] holds the coefficients (computed once, at compile time for the baked
//! parameters): 2-D prefix sums of the masses from which the *Everett function*
//! `T(a, b) = μ{b <= β <= α <= a}` is evaluated exactly in O(1) for any real `a, b` — with uniform
//! cell densities `T` is a quadratic polynomial in `(a, b)` inside each pair of grid intervals.
//! [`PreisachState`] holds the memory: the staircase of dominant reversal points (wiping-out
//! property) with, at every vertex, the running `μ(P₊)` of the staircase up to that vertex. An
//! input update costs O(1 + corners wiped out); see [`staircase`](self::PreisachState) for the
//! algebra, the capacity and the merge rule.
//!
//! # Inverse
//!
//! Along a monotone input path the output is piecewise quadratic in the input (pieces end at grid
//! lines and at wiped-out reversal points), so [`PreisachMeasure::invert`] and the generalized
//! [`PreisachMeasure::solve`] (`a·h + Γ(h) = r`, `a >= 0`) walk the pieces and solve one quadratic:
//! exact up to f32 rounding, no bisection.

pub mod baselines;
mod everett;
mod grid;
pub mod naive;
mod solve;
mod staircase;

pub use everett::PreisachMeasure;
pub use grid::{cell_index, cell_of_index, CELL_COUNT, LEVELS};
pub use solve::{Saturation, Solution, SolveError};
pub use staircase::{
    InputError, PreisachState, DEFAULT_CAPACITY, DEMAGNETIZATION_HISTORY, DEMAGNETIZATION_STEPS,
};
