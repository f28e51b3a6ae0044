//! The naive baseline the fast operator is measured against (benchmarks, QEMU instruction counts).
//!
//! Same operator (same grid, same cell-uniform density, same staircase memory), computed the
//! textbook way: every forward update integrates the `P₊` region over **all 325 cells** (exact
//! area of each cell under the staircase), and the inverse is a **bisection** on the input, each
//! trial a full forward evaluation on a copy of the memory. Nothing here uses the Everett tables,
//! so it also serves as an independent check of their algebra.
//!
//! Cost: forward O(325 + 25 × staircase pieces) multiply-adds; inverse 32 × that.

use super::everett::PreisachMeasure;
use super::grid::LEVELS;
use heapless::Vec;

/// Memory of the naive operator: reversal points (normalized, anchor 0 first) and the input.
#[derive(Debug, Clone, PartialEq)]
pub struct NaiveState<const N: usize = 64> {
    points: Vec<f32, N>,
    x: f32,
}

impl<const N: usize> NaiveState<N> {
    /// Negative saturation.
    pub fn negative_saturation() -> Self {
        let mut points = Vec::new();
        let _ = points.push(0.0);
        NaiveState { points, x: 0.0 }
    }

    /// The memory of the fast operator's state `fast`: its reversal points replayed in order,
    /// then its input (a staircase is the record of its own dominant reversals).
    pub fn replaying<const M: usize>(fast: &super::PreisachState<M>) -> Self {
        let mut state = Self::negative_saturation();
        for x in fast.reversal_points_normalized().skip(1) {
            state.move_to(x);
        }
        state.move_to(fast.input_normalized());
        state
    }

    fn rising(&self) -> bool {
        self.points.len() % 2 == 1
    }

    fn move_to(&mut self, x: f32) {
        if x == self.x {
            return;
        }
        if self.rising() != (x > self.x) {
            if self.points.is_full() {
                // Drop the innermost pair (the baseline keeps it simple).
                let keep = self.points.len().saturating_sub(2).max(1);
                self.points.truncate(keep);
            }
            let _ = self.points.push(self.x);
        }
        loop {
            let n = self.points.len();
            let last_is_min = n % 2 == 1;
            let prev = if n >= 2 {
                self.points.get(n - 2).copied()
            } else {
                None
            };
            match prev {
                Some(p) if last_is_min && n >= 3 && x >= p => self.points.truncate(n - 2),
                Some(p) if !last_is_min && n >= 4 && x <= p => self.points.truncate(n - 2),
                Some(_) if !last_is_min && n == 2 && x <= 0.0 => self.points.truncate(1),
                _ => break,
            }
        }
        self.x = x;
    }
}

/// Mass of `{β ∈ [b0, b1], β <= α <= phi}` summed over all cells, with exact per-cell areas.
fn region_mass(measure: &PreisachMeasure, b0: f32, b1: f32, phi: f32) -> f32 {
    let mut sum = 0.0f32;
    for i in 0..LEVELS {
        let lo = b0.max(i as f32);
        let hi = b1.min(i as f32 + 1.0);
        if hi <= lo {
            continue;
        }
        for j in i..LEVELS {
            let w = measure.cell_mass_a_per_m(i, j);
            let top = phi.min(j as f32 + 1.0);
            if i < j {
                let height = (top - j as f32).clamp(0.0, 1.0);
                sum += w * (hi - lo) * height;
            } else {
                // Diagonal half-square: ∫ max(top - β, 0) dβ over [lo, hi], divided by area 1/2.
                let end = hi.min(top);
                if end > lo {
                    let area = 0.5 * ((top - lo) * (top - lo) - (top - end) * (top - end));
                    sum += w * 2.0 * area;
                }
            }
        }
    }
    sum
}

impl PreisachMeasure {
    /// Naive forward: moves the memory and integrates `P₊` over every cell. Returns `M`, A/m.
    pub fn naive_apply<const N: usize>(&self, state: &mut NaiveState<N>, h_a_per_m: f32) -> f32 {
        if h_a_per_m.is_finite() {
            state.move_to(self.normalize(h_a_per_m));
        }
        self.naive_output(state)
    }

    /// Naive output of a memory: `2 μ(P₊) - Σ w + R(x)` with `μ(P₊)` integrated cell by cell
    /// (`R` the reversible part, see [`PreisachMeasure::with_reversible`]).
    pub fn naive_output<const N: usize>(&self, state: &NaiveState<N>) -> f32 {
        // P₊ = ∪ {β ∈ [previous minimum, next minimum), α <= maximum} plus the moving segment.
        let mut plus = 0.0f32;
        let pts = &state.points;
        let n = pts.len();
        let mut k = 1;
        while k < n {
            let lo = pts.get(k - 1).copied().unwrap_or(0.0);
            let max = pts.get(k).copied().unwrap_or(0.0);
            let hi = pts.get(k + 1).copied().unwrap_or(state.x);
            plus += region_mass(self, lo, hi, max);
            k += 2;
        }
        if n % 2 == 1 {
            // Rising from the last minimum to x.
            let lo = pts.get(n - 1).copied().unwrap_or(0.0);
            plus += region_mass(self, lo, LEVELS as f32, state.x);
        }
        2.0 * plus - self.output_bias_a_per_m + self.reversible_at(state.x)
    }

    /// Naive inverse: bisection (32 halvings of the field range) for `a·h + Γ(h) = r`, each trial a
    /// naive forward on a copy of the memory; commits the memory. Targets out of reach clamp to the
    /// range ends. Returns `(h, M)`.
    pub fn naive_solve<const N: usize>(
        &self,
        state: &mut NaiveState<N>,
        a: f32,
        r: f32,
    ) -> (f32, f32) {
        let mut lo = self.h_min_a_per_m;
        let mut hi = self.h_max_a_per_m;
        for _ in 0..32 {
            let mid = 0.5 * (lo + hi);
            let mut trial = state.clone();
            let g = a * mid + self.naive_apply(&mut trial, mid);
            if g < r {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        let h = 0.5 * (lo + hi);
        let m = self.naive_apply(state, h);
        (h, m)
    }
}
