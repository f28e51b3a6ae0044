//! The regressors of the Preisach fit: for a memory state, the fraction `f_k ∈ [0, 1]` of each
//! cell's area that lies in `P₊`.
//!
//! With a density uniform inside each cell (paper Section 4: each identified mass is spread
//! uniformly over its cell), `μ(P₊) = Σ_k w_k f_k` exactly, so the output (3) is
//!
//! `Γ = μ(P₊) - μ(P₋) = Σ_k w_k (2 f_k - 1)`,
//!
//! linear in the masses `w_k`. Areas are exact: square cell `(i, j)`, `i < j`, overlapped by a
//! staircase piece `β ∈ [lo, hi)`, `α <= φ`: `(hi - lo) · clamp(φ - j, 0, 1)`; diagonal
//! half-square `(i, i)`: `∫_{lo}^{min(hi, top)} (top - β) dβ` with `top = min(φ, i + 1)`, divided by
//! its area ½.

use crate::memory::{Memory, Piece};
use crate::{cell_index, CELL_COUNT, LEVELS};

/// Computes the fractions (alpha-major order) of `memory` into `out`; `pieces` is scratch space.
pub fn fractions(memory: &Memory, pieces: &mut Vec<Piece>, out: &mut [f64; CELL_COUNT]) {
    out.fill(0.0);
    memory.pieces(pieces);
    for piece in pieces.iter() {
        let first = piece.beta_lo.floor().max(0.0) as usize;
        for i in first..LEVELS {
            let (cell_lo, cell_hi) = (i as f64, i as f64 + 1.0);
            if cell_lo >= piece.beta_hi {
                break;
            }
            let lo = piece.beta_lo.max(cell_lo);
            let hi = piece.beta_hi.min(cell_hi);
            if hi <= lo {
                continue;
            }
            // Diagonal half-square (i, i).
            let top = piece.phi.min(cell_hi);
            let end = hi.min(top);
            if end > lo {
                out[cell_index(i, i)] += (top - lo) * (top - lo) - (top - end) * (top - end);
            }
            // Squares (i, j), j > i, up to the one the staircase height cuts.
            let width = hi - lo;
            for j in (i + 1)..LEVELS {
                let height = (piece.phi - j as f64).clamp(0.0, 1.0);
                if height <= 0.0 {
                    break;
                }
                out[cell_index(i, j)] += width * height;
            }
        }
    }
}

/// The output `Σ_k w_k (2 f_k - 1)` for fractions `f` and masses `w`.
pub fn output(fractions: &[f64; CELL_COUNT], weights: &[f64]) -> f64 {
    fractions
        .iter()
        .zip(weights)
        .map(|(f, w)| w * (2.0 * f - 1.0))
        .sum()
}
