//! Exact inverse and the monotone solve `a·h + Γ(h) = r`.
//!
//! From the current state, `g(h) = a·h + Γ(h)` is non-decreasing along a rising input path and
//! non-increasing along a falling one (piecewise monotonicity, Theorem 1.3), so the target side
//! fixes the direction. Along that path the output is piecewise quadratic in the normalized input:
//! pieces end at grid lines and at the reversal points the path wipes out. The solver walks the
//! pieces (at most `LEVELS` grid lines plus the stored reversals, a bounded loop), finds the
//! first piece whose end reaches the target and solves the quadratic there in the cancellation-free
//! form `σ = 2q / (B + √(B² + 4 A q))`. The memory is committed to the solution, exactly as if the
//! input had been applied with [`PreisachMeasure::apply`].
//!
//! Error: the returned `(h, M)` satisfy `|a·h + M - r|` within a few f32 roundings of
//! `max(|r|, Σ w)`, and applying `h` to the original state reproduces `M` to the same precision
//! (tested in `host-tests`).
//!
//! With `a > 0` every `r` has a solution: beyond the grid the memory saturates and `h` is solved
//! from the linear remainder. With `a = 0` (the plain inverse) targets beyond `±Σ w` are clamped
//! and reported through [`Saturation`].

use super::everett::{split, split_down, PreisachMeasure};
use super::grid::LEVELS;
use super::staircase::PreisachState;

/// Whether the target was out of reach and clamped.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Saturation {
    /// The target was reached.
    None,
    /// The target was below what is reachable: clamped to negative saturation.
    Low,
    /// The target was above what is reachable: clamped to positive saturation.
    High,
}

/// The solution of an inverse or a solve, already committed to the state.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Solution {
    /// The input `h`, A/m (may lie beyond the grid range when `a > 0`).
    pub h_a_per_m: f32,
    /// The output `M = Γ(h)`, A/m.
    pub m_a_per_m: f32,
    /// Whether the target was clamped.
    pub saturation: Saturation,
}

/// A rejected solve: the state is left unchanged.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SolveError {
    /// The target or the slope was NaN or infinite.
    NonFinite,
    /// The slope `a` was negative (the solve needs a monotone left side).
    NegativeSlope,
}

impl PreisachMeasure {
    /// Exact inverse: the input `h` with `Γ(h) = m_target_a_per_m` reached monotonically from the
    /// current state; commits the state. Targets beyond `±Σ w` are clamped and reported.
    pub fn invert<const N: usize>(
        &self,
        state: &mut PreisachState<N>,
        m_target_a_per_m: f32,
    ) -> Result<Solution, SolveError> {
        self.solve(state, 0.0, m_target_a_per_m)
    }

    /// Solves `a·h + Γ(h) = r` (`a >= 0`, units A/m) from the current state and commits the state.
    ///
    /// Cost: O(grid lines crossed + reversal points wiped out), each piece one Everett evaluation;
    /// one square root at the end.
    pub fn solve<const N: usize>(
        &self,
        state: &mut PreisachState<N>,
        a: f32,
        r_a_per_m: f32,
    ) -> Result<Solution, SolveError> {
        if !a.is_finite() || !r_a_per_m.is_finite() {
            return Err(SolveError::NonFinite);
        }
        if a < 0.0 {
            return Err(SolveError::NegativeSlope);
        }
        let g_now = a * self.denormalize(state.x) + self.output_a_per_m(state);
        if r_a_per_m > g_now {
            Ok(self.solve_rising(state, a, r_a_per_m))
        } else if r_a_per_m < g_now {
            Ok(self.solve_falling(state, a, r_a_per_m))
        } else {
            Ok(Solution {
                h_a_per_m: self.denormalize(state.x),
                m_a_per_m: self.output_a_per_m(state),
                saturation: Saturation::None,
            })
        }
    }

    /// `g = a·h + 2 μ(P₊) - Σ w` at normalized `x` for a given `μ(P₊)`.
    #[inline]
    fn g(&self, a: f32, x: f32, plus_mass: f32) -> f32 {
        a * self.denormalize(x) + 2.0 * plus_mass - self.total_a_per_m
    }

    fn solve_rising<const N: usize>(
        &self,
        state: &mut PreisachState<N>,
        a: f32,
        r: f32,
    ) -> Solution {
        if !state.rising() {
            self.reverse(state);
        }
        let a_cells = a * self.cell_width_a_per_m;
        for _ in 0..(LEVELS + N + 2) {
            let m = state.last_index();
            let base = state
                .vertices
                .get(m)
                .copied()
                .unwrap_or(super::staircase::Vertex { x: 0.0, cum: 0.0 });
            let x0 = state.x;
            let cap = if m >= 2 {
                state.vertex_x(m - 1)
            } else {
                LEVELS as f32
            };
            let (big_j, s0) = split(x0);
            let grid_next = if s0 < 1.0 { big_j as f32 + 1.0 } else { x0 };
            let xb = grid_next.min(cap);
            let (big_i, t) = split(base.x);
            let quad = self.quadratic_in_alpha(big_j, big_i, t);
            let plus_b = base.cum + quad.at(xb - big_j as f32);
            let g_b = self.g(a, xb, plus_b);
            if g_b >= r {
                let q = r - self.g(a, x0, state.plus_mass);
                let b_lin = 2.0 * quad.slope(s0) + a_cells;
                let a_quad = 2.0 * quad.q2;
                let sigma = positive_root(a_quad, b_lin, q, xb - x0);
                state.x = x0 + sigma;
                self.update_plus_mass(state);
                return self.solution(state, Saturation::None);
            }
            state.x = xb;
            state.plus_mass = plus_b;
            if xb >= cap && m >= 2 {
                self.wipe_out(state, xb);
                self.update_plus_mass(state);
            } else if xb >= LEVELS as f32 {
                break;
            }
        }
        // Positive saturation reached (or, defensively, the piece budget exhausted).
        state.x = LEVELS as f32;
        self.wipe_out(state, state.x);
        self.update_plus_mass(state);
        let m_sat = self.output_a_per_m(state);
        if a > 0.0 {
            let h = (r - m_sat) / a;
            Solution {
                h_a_per_m: h.max(self.h_max_a_per_m),
                m_a_per_m: m_sat,
                saturation: Saturation::None,
            }
        } else {
            self.solution(state, Saturation::High)
        }
    }

    fn solve_falling<const N: usize>(
        &self,
        state: &mut PreisachState<N>,
        a: f32,
        r: f32,
    ) -> Solution {
        if state.rising() {
            self.reverse(state);
        }
        let a_cells = a * self.cell_width_a_per_m;
        for _ in 0..(LEVELS + N + 2) {
            let m = state.last_index();
            let base = state
                .vertices
                .get(m)
                .copied()
                .unwrap_or(super::staircase::Vertex { x: 0.0, cum: 0.0 });
            let x0 = state.x;
            let floor = if m >= 3 { state.vertex_x(m - 1) } else { 0.0 };
            let (big_i, t0) = split_down(x0);
            let grid_next = if t0 > 0.0 { big_i as f32 } else { x0 };
            let xb = grid_next.max(floor);
            let (big_j, s) = split(base.x);
            let quad = self.quadratic_in_beta(big_j, s, big_i);
            // v = I + 1 - x grows as x falls.
            let v0 = 1.0 - t0;
            let plus_b = base.cum - quad.at(big_i as f32 + 1.0 - xb);
            let g_b = self.g(a, xb, plus_b);
            if g_b <= r {
                let q = self.g(a, x0, state.plus_mass) - r;
                let b_lin = 2.0 * quad.slope(v0) + a_cells;
                let a_quad = 2.0 * quad.q2;
                let sigma = positive_root(a_quad, b_lin, q, x0 - xb);
                state.x = x0 - sigma;
                self.update_plus_mass(state);
                return self.solution(state, Saturation::None);
            }
            state.x = xb;
            state.plus_mass = plus_b;
            if xb <= floor && (m >= 3 || xb <= 0.0) {
                self.wipe_out(state, xb);
                self.update_plus_mass(state);
                if xb <= 0.0 {
                    break;
                }
            }
        }
        state.x = 0.0;
        self.wipe_out(state, 0.0);
        self.update_plus_mass(state);
        let m_sat = self.output_a_per_m(state);
        if a > 0.0 {
            let h = (r - m_sat) / a;
            Solution {
                h_a_per_m: h.min(self.h_min_a_per_m),
                m_a_per_m: m_sat,
                saturation: Saturation::None,
            }
        } else {
            self.solution(state, Saturation::Low)
        }
    }

    fn solution<const N: usize>(
        &self,
        state: &PreisachState<N>,
        saturation: Saturation,
    ) -> Solution {
        Solution {
            h_a_per_m: self.denormalize(state.x),
            m_a_per_m: self.output_a_per_m(state),
            saturation,
        }
    }
}

/// The root `σ ∈ [0, limit]` of `A σ² + B σ = q` (`q >= 0`, `B >= 0` on a monotone piece), in the
/// form that avoids cancellation. Degenerate pieces return the end of the piece.
#[inline]
fn positive_root(a_quad: f32, b_lin: f32, q: f32, limit: f32) -> f32 {
    let q = q.max(0.0);
    let disc = (b_lin * b_lin + 4.0 * a_quad * q).max(0.0);
    let denom = b_lin + crate::sqrt::sqrt_f32(disc);
    let sigma = if denom > 0.0 { 2.0 * q / denom } else { limit };
    if sigma.is_finite() {
        sigma.clamp(0.0, limit.max(0.0))
    } else {
        limit.max(0.0)
    }
}
