//! What peers do, for the speed comparison (QEMU instruction counts, host benchmarks): two
//! baseline inverses a Preisach implementation would plausibly use, next to this crate's exact
//! one. Neither is used by the controller.
//!
//! * [`RelayGrid`]: one relay (hysteron) per cell of the 25-level grid, thresholds at the cell
//!   centres, weighted by the cell's mass; the output is one weighted sum over all 325 relay
//!   states, and the inverse a **bisection** on the input to f32 resolution, each trial a full
//!   relay update and sum on a copy of the states. The approach of mavasbel/matlab-preisach-model
//!   (a discretized relay grid with per-relay weights). It is a *different, coarser model* of
//!   the same measure (each cell's mass concentrated at its centre instead of spread uniformly),
//!   so its currents differ slightly from the exact operator's; only its cost is compared.
//! * [`everett_bisection_invert`]: the same exact operator as the core (Everett tables over a
//!   bounded extremum list — this crate's staircase), inverted by **bisection** on the input to
//!   f32 resolution, each trial one forward evaluation on a copy of the memory. The approach of
//!   openCFS (Everett function + extremum list, inverted iteratively). Same results as the
//!   core's closed-form inverse up to the bisection's resolution.
//!
//! Cost (per inverse): relay grid ≈ 50 bisection steps × 325 relays; Everett bisection ≈ 50 ×
//! (a memory copy + O(1) Everett update); the core's inverse: O(grid lines crossed).

use super::everett::PreisachMeasure;
use super::grid::LEVELS;
use super::staircase::PreisachState;

/// Bisection steps at most (the bracket halves to adjacent f32 values well before this).
pub const MAX_BISECTION_STEPS: u32 = 64;

/// Bisection on `f(x) = target` over `[lo, hi]` with `f` nondecreasing, to f32 resolution:
/// stops when the midpoint equals an end. Returns the `x` whose `f` is closest to the target.
#[inline]
fn bisect(mut lo: f32, mut hi: f32, target: f32, mut f: impl FnMut(f32) -> f32) -> f32 {
    let (mut f_lo, mut f_hi) = (f(lo), f(hi));
    if target <= f_lo {
        return lo;
    }
    if target >= f_hi {
        return hi;
    }
    for _ in 0..MAX_BISECTION_STEPS {
        let mid = 0.5 * (lo + hi);
        if mid <= lo || mid >= hi {
            break;
        }
        let f_mid = f(mid);
        if f_mid < target {
            lo = mid;
            f_lo = f_mid;
        } else {
            hi = mid;
            f_hi = f_mid;
        }
    }
    if target - f_lo <= f_hi - target {
        lo
    } else {
        hi
    }
}

/// The Everett-bisection baseline: moves `state` to the input `H` with `Γ(H) ≈ m_target` (the
/// closest f32 input found by bisection, monotone from the current input), commits it and
/// returns `(H, M)` in A/m. A target beyond the range ends at a range end. Non-finite targets
/// leave the memory unchanged and return the current point.
pub fn everett_bisection_invert<const N: usize>(
    measure: &PreisachMeasure,
    state: &mut PreisachState<N>,
    m_target_a_per_m: f32,
) -> (f32, f32) {
    let here_h = measure.input_a_per_m(state);
    let here_m = measure.output_a_per_m(state);
    if !m_target_a_per_m.is_finite() {
        return (here_h, here_m);
    }
    let (lo, hi) = if m_target_a_per_m >= here_m {
        (here_h, measure.h_max_a_per_m())
    } else {
        (measure.h_min_a_per_m(), here_h)
    };
    let h = bisect(lo, hi, m_target_a_per_m, |h| {
        let mut trial = state.clone();
        measure.apply(&mut trial, h).unwrap_or(here_m)
    });
    let m = measure.apply(state, h).unwrap_or(here_m);
    (h, m)
}

/// Relays per cell side of the relay grid: 4 × 25 = 100 input levels, 5,050 relays; each cell's
/// uniform mass is spread over its 16 (diagonal cells: 10) relays, so the grid's output jumps by
/// at most 1/8 of a cell mass where the exact operator moves continuously.
pub const RELAYS_PER_CELL_SIDE: usize = 4;
/// Input levels of the relay grid.
pub const RELAY_LEVELS: usize = LEVELS * RELAYS_PER_CELL_SIDE;
/// Relays of the grid (`α ≥ β`).
pub const RELAY_COUNT: usize = RELAY_LEVELS * (RELAY_LEVELS + 1) / 2;

/// The relay-grid baseline: [`RELAY_COUNT`] relays on a [`RELAY_LEVELS`]-level grid and their
/// states.
#[derive(Debug, Clone, PartialEq)]
pub struct RelayGrid<'m> {
    measure: &'m PreisachMeasure,
    /// Relay states (`true` = +1), alpha-major: relay `(b, a)`, `b ≤ a`, at `a(a+1)/2 + b`.
    up: [bool; RELAY_COUNT],
    /// Current normalized input (cell units).
    x: f32,
}

impl<'m> RelayGrid<'m> {
    /// The relay grid of `measure`, every relay down (negative saturation).
    pub fn new(measure: &'m PreisachMeasure) -> Self {
        RelayGrid {
            measure,
            up: [false; RELAY_COUNT],
            x: 0.0,
        }
    }

    /// Output the relays would give at normalized input `x` from the current states (one
    /// weighted sum over all relays), optionally committing the new states. A relay `(b, a)`
    /// switches up at `α = (a + ½)/K`, down at `β = (b + ½)/K`; its weight is its share of its
    /// cell's mass (a full fine square `w/K²`, a fine triangle on the diagonal half of that).
    #[inline]
    fn output_at(&mut self, x: f32, commit: bool) -> f32 {
        let k = RELAYS_PER_CELL_SIDE;
        let inv_k = 1.0 / k as f32;
        let square_share = inv_k * inv_k;
        let mut sum = 0.0f32;
        let mut states = self.up.iter_mut();
        for a in 0..RELAY_LEVELS {
            let alpha = (a as f32 + 0.5) * inv_k;
            let above_alpha = x >= alpha;
            let row = self.measure.w.get(a / k);
            for b in 0..=a {
                let Some(up) = states.next() else {
                    return sum;
                };
                let beta = (b as f32 + 0.5) * inv_k;
                let state = above_alpha || (x > beta && *up);
                if commit {
                    *up = state;
                }
                let cell_mass = row.and_then(|r| r.get(b / k)).copied().unwrap_or(0.0);
                // Off-diagonal cell: a fine square of its k² → w/k². Diagonal cell (uniform over
                // a triangle of area k²/2): a fine square 2w/k², a fine triangle (a = b) w/k².
                let w = if a / k == b / k && a != b {
                    2.0 * cell_mass * square_share
                } else {
                    cell_mass * square_share
                };
                sum += if state { w } else { -w };
            }
        }
        if commit {
            self.x = x;
        }
        sum + self.measure.reversible_at(x) + self.measure.offset_a_per_m
    }

    /// Output at the current input, A/m.
    pub fn output_a_per_m(&mut self) -> f32 {
        self.output_at(self.x, false)
    }

    /// Sets the input to `h_a_per_m` and returns the output, A/m (a non-finite input leaves the
    /// state unchanged).
    pub fn apply(&mut self, h_a_per_m: f32) -> f32 {
        if !h_a_per_m.is_finite() {
            return self.output_a_per_m();
        }
        let x = self.measure.normalize(h_a_per_m);
        self.output_at(x, true)
    }

    /// Moves to the input with output closest to `m_target_a_per_m` (bisection to f32
    /// resolution, monotone from the current input), commits it and returns `(H, M)`, A/m.
    pub fn invert(&mut self, m_target_a_per_m: f32) -> (f32, f32) {
        let here_m = self.output_a_per_m();
        let here_h = self.measure.denormalize(self.x);
        if !m_target_a_per_m.is_finite() {
            return (here_h, here_m);
        }
        let (lo, hi) = if m_target_a_per_m >= here_m {
            (self.x, LEVELS as f32)
        } else {
            (0.0, self.x)
        };
        let x = bisect(lo, hi, m_target_a_per_m, |x| self.output_at(x, false));
        let m = self.output_at(x, true);
        (self.measure.denormalize(x), m)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::params::{BAKED_MEASURE, BAKED_PARAMETERS};

    #[test]
    fn everett_bisection_agrees_with_the_exact_inverse() {
        let m = &BAKED_MEASURE;
        let mut exact = m.negative_saturation::<64>();
        let mut bisected = exact.clone();
        let ms = m.saturation_a_per_m();
        for &target in &[0.3, -0.2, 0.6, 0.1, 0.5, -0.7, 0.0] {
            let s = m.invert(&mut exact, target * ms).unwrap();
            let (h, out) = everett_bisection_invert(m, &mut bisected, target * ms);
            assert!(
                (out - s.m_a_per_m).abs() <= 1e-4 * ms,
                "{target}: {out} vs {}",
                s.m_a_per_m
            );
            assert!(
                (h - s.h_a_per_m).abs() <= 1e-3 * m.h_max_a_per_m(),
                "{target}: {h}"
            );
        }
    }

    #[test]
    fn relay_grid_equals_the_exact_operator_on_its_fine_grid_lines() {
        // On a monotone path every fine square is either fully switched or not at x = m/K, for
        // the relays and for the exact operator alike.
        let m = &BAKED_MEASURE;
        let mut grid = RelayGrid::new(m);
        let mut exact = m.negative_saturation::<64>();
        let ms = m.saturation_a_per_m();
        for level in 0..=RELAY_LEVELS {
            let h = m.denormalize(level as f32 / RELAYS_PER_CELL_SIDE as f32);
            let (r, e) = (grid.apply(h), m.apply(&mut exact, h).unwrap());
            assert!(
                (r - e).abs() <= 2e-5 * ms,
                "level {level}: relay {r}, exact {e}"
            );
        }
        for level in (0..RELAY_LEVELS).rev().step_by(3) {
            let h = m.denormalize(level as f32 / RELAYS_PER_CELL_SIDE as f32);
            let (r, e) = (grid.apply(h), m.apply(&mut exact, h).unwrap());
            assert!(
                (r - e).abs() <= 2e-5 * ms,
                "down, level {level}: relay {r}, exact {e}"
            );
        }
    }

    #[test]
    fn relay_grid_follows_the_exact_operator_within_a_cell() {
        let m = &BAKED_MEASURE;
        let mut grid = RelayGrid::new(m);
        let mut exact = m.negative_saturation::<64>();
        let ms = m.saturation_a_per_m();
        assert!((grid.output_a_per_m() + ms).abs() <= 1e-3 * ms);
        for &target in &[0.3, -0.2, 0.6, 0.1, 0.5, -0.7, 0.0] {
            let (h, out) = grid.invert(target * ms);
            // The grid's output is a staircase in H with steps of at most one fine row of relays:
            // the bisection lands within one step of the target, and the exact operator at the
            // same input within one step of the grid.
            let max_cell = BAKED_PARAMETERS
                .preisach
                .weights_a_per_m
                .iter()
                .fold(0.0f32, |a, &w| a.max(w));
            let step = 2.0 * max_cell * LEVELS as f32 / RELAYS_PER_CELL_SIDE as f32;
            assert!(
                (out - target * ms).abs() <= step,
                "{target}: {out} (step {step})"
            );
            let exact_out = m.apply(&mut exact, h).unwrap();
            assert!(
                (out - exact_out).abs() <= step,
                "{target}: relay {out}, exact {exact_out} (step {step})"
            );
        }
    }
}
