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
use super::staircase::{PieceMemo, PreisachState};
use crate::select::{clamp_f32, max_f32, min_f32};

/// Whether the target was out of reach and clamped.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Saturation {
    /// The target was reached.
    None,
    /// The target was below what is reachable: clamped to negative saturation.
    Low,
    /// The target was above what is reachable: clamped to positive saturation.
    High,
    /// The walk stopped at the end of its piece budget
    /// ([`PreisachMeasure::invert_within`]) short of the target: the memory is committed where
    /// it stopped, on the path to the target (the next call continues from there).
    Truncated,
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
        // The same walk as `solve` with `a = 0` known at compile time (the control interrupt's
        // case): the `a·h` terms drop out; the results are bit-identical to `solve(state, 0, m)`.
        self.solve_impl::<N, true, { usize::MAX }>(state, 0.0, m_target_a_per_m)
    }

    /// [`PreisachMeasure::invert`] walking at most `max_pieces` pieces: a target further away
    /// stops the walk at the end of the last piece ([`Saturation::Truncated`]), on the monotone
    /// path toward it, the memory committed there. Each piece ends at a grid line or a wiped-out
    /// reversal point and costs one Everett evaluation and a few compares, so the call's cost is
    /// bounded by design whatever the target: the control interrupt's worst case
    /// (`inverse::control_loop::INVERSE_PIECES_PER_TICK`). Within the budget it is exactly
    /// `invert`.
    ///
    /// The budget is a constant, so the unbounded walk and this one are each compiled for their
    /// own bound (a run-time budget cost the control interrupt ~20 instructions a tick).
    #[inline]
    pub fn invert_within<const N: usize, const MAX_PIECES: usize>(
        &self,
        state: &mut PreisachState<N>,
        m_target_a_per_m: f32,
    ) -> Result<Solution, SolveError> {
        self.solve_impl::<N, true, MAX_PIECES>(state, 0.0, m_target_a_per_m)
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
        self.solve_impl::<N, false, { usize::MAX }>(state, a, r_a_per_m)
    }

    /// `solve`, with `PLAIN` telling that `a` is 0.
    #[inline(always)]
    fn solve_impl<const N: usize, const PLAIN: bool, const MAX_PIECES: usize>(
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
        // Without a reversible part its terms are compiled out (`REV = false`): the control
        // interrupt of an actuator with `M = Γ[H]` pays one branch for it.
        if self.has_reversible {
            Ok(self.solve_walk::<N, PLAIN, true, MAX_PIECES>(state, a, r_a_per_m))
        } else {
            Ok(self.solve_walk::<N, PLAIN, false, MAX_PIECES>(state, a, r_a_per_m))
        }
    }

    /// The walk of [`Self::solve_impl`], with `REV` telling whether the measure has a reversible
    /// part.
    #[inline(always)]
    fn solve_walk<const N: usize, const PLAIN: bool, const REV: bool, const MAX_PIECES: usize>(
        &self,
        state: &mut PreisachState<N>,
        a: f32,
        r_a_per_m: f32,
    ) -> Solution {
        let m_now = if REV {
            self.output_a_per_m(state)
        } else {
            2.0 * state.plus_mass - self.output_bias_a_per_m
        };
        let g_now = if PLAIN {
            m_now
        } else {
            a * self.denormalize(state.x) + m_now
        };
        if r_a_per_m > g_now {
            self.solve_rising::<N, PLAIN, REV, MAX_PIECES>(state, a, r_a_per_m)
        } else if r_a_per_m < g_now {
            self.solve_falling::<N, PLAIN, REV, MAX_PIECES>(state, a, r_a_per_m)
        } else {
            Solution {
                h_a_per_m: self.denormalize(state.x),
                m_a_per_m: m_now,
                saturation: Saturation::None,
            }
        }
    }

    /// `g = a·h + 2 μ(P₊) - Σ w + R(x)` at normalized `x` in interval `k` for a given `μ(P₊)`
    /// (`PLAIN`: `a = 0`; `REV`: with the reversible part).
    #[inline(always)]
    fn g<const PLAIN: bool, const REV: bool>(
        &self,
        a: f32,
        x: f32,
        k: usize,
        plus_mass: f32,
    ) -> f32 {
        let m = self.m_in::<REV>(x, k, plus_mass);
        if PLAIN {
            m
        } else {
            a * self.denormalize(x) + m
        }
    }

    #[inline(always)]
    fn solve_rising<const N: usize, const PLAIN: bool, const REV: bool, const MAX_PIECES: usize>(
        &self,
        state: &mut PreisachState<N>,
        a: f32,
        r: f32,
    ) -> Solution {
        if !state.rising() {
            self.reverse(state);
        }
        // Without a budget the walk needs at most LEVELS + N + 2 pieces (every grid line and
        // every stored reversal) to saturate; with one, running out ends it short of the target.
        let full = LEVELS + N + 2;
        let budget = if MAX_PIECES < full { MAX_PIECES } else { full };
        'walk: {
            for _ in 0..budget {
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
                // d(a·h + R)/dx on this interval (every interval has width Δ on a uniform grid).
                let a_cells = self.linear_per_cell::<PLAIN, REV>(a, big_j);
                let tag = big_j as u32;
                let (quad, xb, plus_b, remembered) = match state.piece.lookup(tag, base, cap) {
                    Some((quad, xb, plus_b)) => (quad, xb, plus_b, true),
                    None => {
                        let grid_next = if s0 < 1.0 { big_j as f32 + 1.0 } else { x0 };
                        let xb = min_f32(grid_next, cap);
                        let (big_i, t) = split(base.x);
                        let quad = self.quadratic_in_alpha(big_j, big_i, t);
                        (quad, xb, base.cum + quad.at(xb - big_j as f32), false)
                    }
                };
                let g_b = self.g::<PLAIN, REV>(a, xb, big_j, plus_b);
                if g_b >= r {
                    let q = r - self.g::<PLAIN, REV>(a, x0, big_j, state.plus_mass);
                    let b_lin = 2.0 * quad.slope(s0) + a_cells;
                    let a_quad = 2.0 * quad.q2;
                    let sigma = positive_root(a_quad, b_lin, q, xb - x0);
                    state.x = x0 + sigma;
                    // μ(P₊) on this piece is the same quadratic: no second Everett evaluation.
                    state.plus_mass = base.cum + quad.at(state.x - big_j as f32);
                    if !remembered {
                        state.piece = PieceMemo {
                            tag,
                            base_x: base.x,
                            base_cum: base.cum,
                            bound: cap,
                            quad,
                            end_x: xb,
                            end_plus_mass: plus_b,
                        };
                    }
                    return self.solution_in::<N, REV>(state, big_j);
                }
                state.x = xb;
                state.plus_mass = plus_b;
                if xb >= cap && m >= 2 {
                    self.wipe_out(state, xb);
                    self.update_plus_mass(state);
                } else if xb >= LEVELS as f32 {
                    break 'walk;
                }
            }
            if MAX_PIECES < full {
                return self.solution(state, Saturation::Truncated);
            }
        }
        // Positive saturation reached (or, defensively, the full budget exhausted).
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

    #[inline(always)]
    fn solve_falling<
        const N: usize,
        const PLAIN: bool,
        const REV: bool,
        const MAX_PIECES: usize,
    >(
        &self,
        state: &mut PreisachState<N>,
        a: f32,
        r: f32,
    ) -> Solution {
        if state.rising() {
            self.reverse(state);
        }
        let full = LEVELS + N + 2;
        let budget = if MAX_PIECES < full { MAX_PIECES } else { full };
        'walk: {
            for _ in 0..budget {
                let m = state.last_index();
                let base = state
                    .vertices
                    .get(m)
                    .copied()
                    .unwrap_or(super::staircase::Vertex { x: 0.0, cum: 0.0 });
                let x0 = state.x;
                let floor = if m >= 3 { state.vertex_x(m - 1) } else { 0.0 };
                let (big_i, t0) = split_down(x0);
                let a_cells = self.linear_per_cell::<PLAIN, REV>(a, big_i);
                let tag = big_i as u32 | PieceMemo::FALLING;
                let (quad, xb, plus_b, remembered) = match state.piece.lookup(tag, base, floor) {
                    Some((quad, xb, plus_b)) => (quad, xb, plus_b, true),
                    None => {
                        let grid_next = if t0 > 0.0 { big_i as f32 } else { x0 };
                        let xb = max_f32(grid_next, floor);
                        let (big_j, s) = split(base.x);
                        let quad = self.quadratic_in_beta(big_j, s, big_i);
                        // v = I + 1 - x grows as x falls.
                        (quad, xb, base.cum - quad.at(big_i as f32 + 1.0 - xb), false)
                    }
                };
                let v0 = 1.0 - t0;
                let g_b = self.g::<PLAIN, REV>(a, xb, big_i, plus_b);
                if g_b <= r {
                    let q = self.g::<PLAIN, REV>(a, x0, big_i, state.plus_mass) - r;
                    let b_lin = 2.0 * quad.slope(v0) + a_cells;
                    let a_quad = 2.0 * quad.q2;
                    let sigma = positive_root(a_quad, b_lin, q, x0 - xb);
                    state.x = x0 - sigma;
                    state.plus_mass = base.cum - quad.at(big_i as f32 + 1.0 - state.x);
                    if !remembered {
                        state.piece = PieceMemo {
                            tag,
                            base_x: base.x,
                            base_cum: base.cum,
                            bound: floor,
                            quad,
                            end_x: xb,
                            end_plus_mass: plus_b,
                        };
                    }
                    return self.solution_in::<N, REV>(state, big_i);
                }
                state.x = xb;
                state.plus_mass = plus_b;
                if xb <= floor && (m >= 3 || xb <= 0.0) {
                    self.wipe_out(state, xb);
                    self.update_plus_mass(state);
                    if xb <= 0.0 {
                        break 'walk;
                    }
                }
            }
            if MAX_PIECES < full {
                return self.solution(state, Saturation::Truncated);
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

    /// `M = 2 μ(P₊) − Σ w (+ R(x))` at `x` in interval `k`.
    #[inline(always)]
    fn m_in<const REV: bool>(&self, x: f32, k: usize, plus_mass: f32) -> f32 {
        let hysteretic = 2.0 * plus_mass - self.output_bias_a_per_m;
        if REV {
            hysteretic + self.reversible_in(x, k)
        } else {
            hysteretic
        }
    }

    /// `d(a·h + R)/dx` on interval `k`: `a Δ_k + ρ_k`.
    #[inline(always)]
    fn linear_per_cell<const PLAIN: bool, const REV: bool>(&self, a: f32, k: usize) -> f32 {
        let rev = if REV { self.reversible_rise(k) } else { 0.0 };
        if PLAIN {
            rev
        } else {
            a * self.widths_a_per_m[k.min(LEVELS - 1)] + rev
        }
    }

    /// The solution on the piece of interval `k` (not saturated).
    #[inline(always)]
    fn solution_in<const N: usize, const REV: bool>(
        &self,
        state: &PreisachState<N>,
        k: usize,
    ) -> Solution {
        Solution {
            h_a_per_m: self.denormalize_in(state.x, k),
            m_a_per_m: self.m_in::<REV>(state.x, k, state.plus_mass),
            saturation: Saturation::None,
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
    // Compare-and-select instead of f32::max/clamp (library calls on the M4F, `crate::select`).
    let q = max_f32(q, 0.0);
    let disc = max_f32(b_lin * b_lin + 4.0 * a_quad * q, 0.0);
    let denom = b_lin + crate::sqrt::sqrt_f32(disc);
    let limit = max_f32(limit, 0.0);
    let sigma = if denom > 0.0 { 2.0 * q / denom } else { limit };
    if sigma.is_finite() {
        clamp_f32(sigma, 0.0, limit)
    } else {
        limit
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::super::staircase::{PieceMemo, PIECE_MEMO_HITS};
    use super::super::PreisachState;
    use crate::params::BAKED_MEASURE;
    use core::sync::atomic::Ordering;

    /// The piece memo changes no result: the same random sequence of inverses, solves (with
    /// `a > 0`) and forward updates on two copies of a state, one of which forgets its memo before
    /// every call, gives bit-identical inputs, outputs and memories — through reversals, wipe-outs,
    /// saturation, full-buffer merges (capacity 8) and a resolution that merges hair-thin pairs.
    #[test]
    fn the_piece_memo_changes_no_result() {
        let measure = &BAKED_MEASURE;
        let total = measure.saturation_a_per_m();
        let mut seed = 0x9E37_79B9_7F4A_7C15u64;
        let mut uniform = move || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 40) as f32 / (1u64 << 24) as f32
        };
        for resolution in [0.0, 1.0e-3] {
            let mut with: PreisachState<8> = measure.demagnetized();
            with.set_resolution(resolution);
            let mut without = with.clone();
            let hits_before = PIECE_MEMO_HITS.load(Ordering::Relaxed);
            let mut target = 0.0f32;
            for step in 0..20_000 {
                // Mostly small moves (the control interrupt's case: the memo hits), now and then a
                // jump across the range or beyond saturation.
                let u = uniform();
                target = if u < 0.9 {
                    target + 0.004 * total * (uniform() - 0.5)
                } else {
                    1.2 * total * (2.0 * uniform() - 1.0)
                };
                without.piece.tag = PieceMemo::NONE;
                let (a, b) = match step % 7 {
                    0 => {
                        let a = 40.0 * uniform();
                        (
                            measure.solve(&mut with, a, target),
                            measure.solve(&mut without, a, target),
                        )
                    }
                    1 => {
                        let h = measure.h_min_a_per_m()
                            + (measure.h_max_a_per_m() - measure.h_min_a_per_m()) * uniform();
                        let (ma, mb) =
                            (measure.apply(&mut with, h), measure.apply(&mut without, h));
                        assert_eq!(ma.map(f32::to_bits), mb.map(f32::to_bits));
                        continue;
                    }
                    _ => (
                        measure.invert(&mut with, target),
                        measure.invert(&mut without, target),
                    ),
                };
                let (a, b) = (a.expect("finite"), b.expect("finite"));
                assert_eq!(a.h_a_per_m.to_bits(), b.h_a_per_m.to_bits(), "step {step}");
                assert_eq!(a.m_a_per_m.to_bits(), b.m_a_per_m.to_bits(), "step {step}");
                assert_eq!(a.saturation, b.saturation);
                assert_eq!(with.x.to_bits(), without.x.to_bits());
                assert_eq!(with.plus_mass.to_bits(), without.plus_mass.to_bits());
                assert_eq!(with.vertices, without.vertices, "step {step}");
            }
            // Other tests may add to the counter too; this one alone makes thousands of hits.
            let hits = PIECE_MEMO_HITS.load(Ordering::Relaxed) - hits_before;
            assert!(hits > 5_000, "the memo was used {hits} times");
        }
    }
}
