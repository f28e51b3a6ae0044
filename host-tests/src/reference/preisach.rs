//! Relay-level reference Preisach operator in f64 (paper eqs. (1)-(3)), independent of the core.
//!
//! # What it computes
//!
//! The core represents the measure of cell `(i, j)` (β in grid interval `i`, α in interval `j`,
//! `i <= j`, alpha-major weight order `j (j + 1) / 2 + i`; see `magctl::preisach`) as a density
//! spread **uniformly** over the cell, and evaluates `M = μ(P₊) - μ(P₋)` exactly through Everett
//! tables. This module instead does what the paper's definition (2) says literally: it places
//! finitely many elementary hysterons `γ̂_{β,α}` (the relay of eq. (1)) in the plane and sums
//! `mass · (±1)`. Each cell is subdivided into `k × k` sub-squares of side `1/k` (normalized
//! input units, `x = (h - h_min) / Δ`), and one relay sits at the centre of every sub-square that
//! lies in the Preisach half-plane `β <= α`, carrying the cell's mass over that sub-square:
//!
//! * off-diagonal cell (`i < j`, a unit square): every sub-square carries `w_ij / k²`;
//! * diagonal cell (`i == j`, a half-square of area ½, so density `2 w_ii`): sub-squares strictly
//!   above the diagonal carry `2 w_ii / k²`; the `k` sub-squares cut by the diagonal carry half of
//!   that, `w_ii / k²`, and their relay sits on the diagonal (`α = β`);
//!
//! so every cell's relays add up to exactly its mass, and the relay field converges to the
//! uniform cell density as `k → ∞`. Nothing here uses staircases, Everett functions or wiping-out:
//! each relay just obeys eq. (1) — `+1` once the input exceeds α, `-1` once it drops below β.
//!
//! # Cost
//!
//! There are `300 k² + 25 k (k + 1) / 2` relays. Between two samples the input is taken to move
//! monotonically (the paper's convention, rate independence), so a rise from `x₀` to `x₁` can only
//! switch on relays with `α ∈ [x₀, x₁)` and a fall can only switch off relays with
//! `β ∈ (x₁, x₀]`: every relay with `α < x` is already on and every relay with `β > x` already off
//! (the invariant eq. (1) maintains). The relays are kept sorted by α and by β, so an update is two
//! binary searches plus a visit of the relays whose threshold was crossed, and the output is kept
//! as a running sum of the switched-on mass.
//!
//! # Accuracy against the exact operator
//!
//! A relay at the centre of a sub-square `S` reports the state of the exact (continuous-density)
//! operator at that point. If the memory curve (the `P₊`/`P₋` boundary) does not cut `S`, every
//! point of `S` shares that state and the relay's `±μ(S)` equals the exact contribution
//! `μ(S ∩ P₊) - μ(S ∩ P₋)`; if it cuts `S`, the two differ by at most `2 μ(S)`. The memory curve is
//! a monotone staircase (β non-decreasing while α non-increasing) ending on the diagonal at the
//! current input, so the sub-squares it cuts form a monotone chain of edge- or corner-adjacent
//! sub-squares; a corner step can be replaced by an edge step through one more sub-square without
//! lowering the sum (masses are `>= 0`). Hence, for every input history,
//!
//! `|M_exact - M_relay| <= 2 · max over monotone sub-square paths of Σ μ(S)`
//!
//! which [`RelayPreisach::discretization_bound_a_per_m`] evaluates by dynamic programming over the
//! `kL × kL` sub-grid. A path has at most `2kL - 1` sub-squares of mass `<= ρ_max / k²` each
//! (`ρ_max` the largest cell density, diagonal cells counting `2 w`), so the bound is also
//! `<= 2 (2kL - 1) ρ_max / k² ≈ 4 L ρ_max / k`: it shrinks like `1 / k`.
//!
//! Rounding: the running sum adds or subtracts one relay mass (`<= Σ w`) per switch, each f64
//! addition off by at most `2⁻⁵³ Σ w`; [`RelayState::switch_count`] counts them so tests can add
//! `switches · 2⁻⁵³ Σ w` (and [`RelayPreisach::recomputed_output_a_per_m`] recomputes the sum from
//! scratch for a check).

use magctl::preisach::{cell_index, CELL_COUNT, LEVELS};

/// A rejected construction or input, naming what is wrong.
#[derive(Debug, Clone, PartialEq)]
pub struct ReferenceError(pub String);

impl std::fmt::Display for ReferenceError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for ReferenceError {}

/// One threshold of one relay, for the sorted threshold lists.
#[derive(Debug, Clone, Copy)]
struct Threshold {
    /// Normalized input value of the threshold.
    x: f64,
    /// Index of the relay.
    relay: u32,
}

/// The relay field: thresholds and masses (the coefficients; the state is a [`RelayState`]).
#[derive(Debug, Clone)]
pub struct RelayPreisach {
    subdivision: usize,
    h_min_a_per_m: f64,
    h_max_a_per_m: f64,
    /// The L + 1 grid lines, A/m (equally spaced unless built by [`RelayPreisach::with_lines`]).
    lines_a_per_m: Vec<f64>,
    /// Cell masses, alpha-major (as given).
    weights_a_per_m: Vec<f64>,
    /// Σ w, A/m.
    total_a_per_m: f64,
    /// Mass of each relay, A/m.
    relay_mass_a_per_m: Vec<f64>,
    /// All relays sorted by switch-up threshold α.
    by_alpha: Vec<Threshold>,
    /// All relays sorted by switch-down threshold β.
    by_beta: Vec<Threshold>,
}

/// The state of every relay and the current input.
#[derive(Debug, Clone, PartialEq)]
pub struct RelayState {
    /// `true` = relay output +1.
    on: Vec<bool>,
    /// Current normalized input.
    x: f64,
    /// Mass of the relays that are on, A/m (running sum).
    plus_mass_a_per_m: f64,
    /// Number of relay switches so far (each one f64 addition to the running sum).
    switches: u64,
}

impl RelayState {
    /// Current normalized input.
    pub fn input_normalized(&self) -> f64 {
        self.x
    }

    /// Number of relay switches so far (for the rounding budget of the running sum).
    pub fn switch_count(&self) -> u64 {
        self.switches
    }
}

impl RelayPreisach {
    /// Builds the relay field for cell masses `weights_a_per_m` (alpha-major, [`CELL_COUNT`] of
    /// them, A/m, finite and `>= 0`) over `[h_min, h_max]`, with `k = subdivision` relays per cell
    /// side.
    pub fn new(
        weights_a_per_m: &[f64],
        h_min_a_per_m: f64,
        h_max_a_per_m: f64,
        subdivision: usize,
    ) -> Result<Self, ReferenceError> {
        let width = (h_max_a_per_m - h_min_a_per_m) / LEVELS as f64;
        let lines: Vec<f64> = (0..=LEVELS)
            .map(|k| h_min_a_per_m + k as f64 * width)
            .collect();
        Self::build(
            weights_a_per_m,
            h_min_a_per_m,
            h_max_a_per_m,
            lines,
            subdivision,
        )
    }

    /// The same on a grid with the given `L + 1` strictly increasing lines (A/m): cell `(i, j)`
    /// spans `[lines[i], lines[i+1]] × [lines[j], lines[j+1]]` in the field and its relays sit at
    /// the same relative positions inside it (its density is uniform in the field).
    pub fn with_lines(
        weights_a_per_m: &[f64],
        lines_a_per_m: &[f64],
        subdivision: usize,
    ) -> Result<Self, ReferenceError> {
        if lines_a_per_m.len() != LEVELS + 1
            || lines_a_per_m.windows(2).any(|w| w[0] >= w[1])
            || lines_a_per_m.iter().any(|h| !h.is_finite())
        {
            return Err(ReferenceError(format!(
                "lines_a_per_m: need {} finite, strictly increasing grid lines, got {:?}",
                LEVELS + 1,
                lines_a_per_m
            )));
        }
        Self::build(
            weights_a_per_m,
            lines_a_per_m[0],
            lines_a_per_m[LEVELS],
            lines_a_per_m.to_vec(),
            subdivision,
        )
    }

    fn build(
        weights_a_per_m: &[f64],
        h_min_a_per_m: f64,
        h_max_a_per_m: f64,
        lines_a_per_m: Vec<f64>,
        subdivision: usize,
    ) -> Result<Self, ReferenceError> {
        if weights_a_per_m.len() != CELL_COUNT {
            return Err(ReferenceError(format!(
                "weights_a_per_m: need {CELL_COUNT} cell masses, got {}",
                weights_a_per_m.len()
            )));
        }
        if let Some((k, w)) = weights_a_per_m
            .iter()
            .enumerate()
            .find(|(_, w)| !w.is_finite() || **w < 0.0)
        {
            return Err(ReferenceError(format!(
                "weights_a_per_m[{k}]: a cell mass must be finite and >= 0, got {w}"
            )));
        }
        if !(h_min_a_per_m.is_finite() && h_max_a_per_m.is_finite())
            || h_min_a_per_m >= h_max_a_per_m
        {
            return Err(ReferenceError(format!(
                "h_min_a_per_m, h_max_a_per_m: need finite h_min < h_max, got [{h_min_a_per_m}, {h_max_a_per_m}]"
            )));
        }
        if subdivision == 0 || subdivision > 256 {
            return Err(ReferenceError(format!(
                "subdivision: need 1 ..= 256 relays per cell side, got {subdivision}"
            )));
        }
        let k = subdivision;
        let kf = k as f64;
        let mut alpha = Vec::new();
        let mut beta = Vec::new();
        let mut mass = Vec::new();
        for j in 0..LEVELS {
            for i in 0..=j {
                let w = weights_a_per_m[cell_index(i, j)];
                for q in 0..k {
                    for p in 0..k {
                        // Sub-square p (along β) × q (along α) of cell (i, j).
                        let m = if i < j {
                            w / (kf * kf)
                        } else if p < q {
                            2.0 * w / (kf * kf)
                        } else if p == q {
                            w / (kf * kf)
                        } else {
                            continue; // below the diagonal: not in the Preisach plane
                        };
                        beta.push(i as f64 + (p as f64 + 0.5) / kf);
                        alpha.push(j as f64 + (q as f64 + 0.5) / kf);
                        mass.push(m);
                    }
                }
            }
        }
        let sorted = |thresholds: &[f64]| {
            let mut v: Vec<Threshold> = thresholds
                .iter()
                .enumerate()
                .map(|(r, &x)| Threshold { x, relay: r as u32 })
                .collect();
            v.sort_by(|a, b| a.x.total_cmp(&b.x));
            v
        };
        Ok(RelayPreisach {
            subdivision,
            h_min_a_per_m,
            h_max_a_per_m,
            lines_a_per_m,
            weights_a_per_m: weights_a_per_m.to_vec(),
            total_a_per_m: weights_a_per_m.iter().sum(),
            relay_mass_a_per_m: mass,
            by_alpha: sorted(&alpha),
            by_beta: sorted(&beta),
        })
    }

    /// The relay field of the parameters baked into `magctl` (the same f32 masses the core uses,
    /// widened exactly to f64).
    pub fn from_baked(subdivision: usize) -> Result<Self, ReferenceError> {
        let p = magctl::params::BAKED_PARAMETERS.preisach;
        let w: Vec<f64> = p.weights_a_per_m.iter().map(|&w| w as f64).collect();
        if let Some(lines) = p.lines_a_per_m {
            let lines: Vec<f64> = lines.iter().map(|&h| h as f64).collect();
            return Self::with_lines(&w, &lines, subdivision);
        }
        Self::new(
            &w,
            p.h_min_a_per_m as f64,
            p.h_max_a_per_m as f64,
            subdivision,
        )
    }

    /// Relays per cell side, `k`.
    pub fn subdivision(&self) -> usize {
        self.subdivision
    }

    /// Number of relays.
    pub fn relay_count(&self) -> usize {
        self.relay_mass_a_per_m.len()
    }

    /// Saturation output `Σ w`, A/m.
    pub fn saturation_a_per_m(&self) -> f64 {
        self.total_a_per_m
    }

    /// Field range `(h_min, h_max)`, A/m.
    pub fn range_a_per_m(&self) -> (f64, f64) {
        (self.h_min_a_per_m, self.h_max_a_per_m)
    }

    /// Largest cell density (mass per unit normalized area; diagonal half-squares count `2 w`).
    pub fn max_density_a_per_m(&self) -> f64 {
        let mut max = 0.0f64;
        for j in 0..LEVELS {
            for i in 0..=j {
                let w = self.weights_a_per_m[cell_index(i, j)];
                max = max.max(if i == j { 2.0 * w } else { w });
            }
        }
        max
    }

    /// Normalized input of field `h` (A/m): interval `k` mapped affinely onto `[k, k + 1]`
    /// (`(h - h_min) / Δ` on a uniform grid), continued with the end intervals' widths beyond the
    /// range, not clamped (relays only exist in `[0, L]`, so inputs beyond simply saturate).
    pub fn normalize(&self, h_a_per_m: f64) -> f64 {
        let lines = &self.lines_a_per_m;
        // The interval k with lines[k] <= h < lines[k + 1], the end intervals continued outward.
        let k = lines[1..LEVELS]
            .partition_point(|&line| line <= h_a_per_m)
            .min(LEVELS - 1);
        k as f64 + (h_a_per_m - lines[k]) / (lines[k + 1] - lines[k])
    }

    /// Field (A/m) at normalized input `x`, the inverse of [`RelayPreisach::normalize`].
    pub fn field_of(&self, x: f64) -> f64 {
        let lines = &self.lines_a_per_m;
        let k = (x.floor().max(0.0) as usize).min(LEVELS - 1);
        lines[k] + (x - k as f64) * (lines[k + 1] - lines[k])
    }

    /// All relays at -1, input at `h_min` (normalized 0).
    pub fn negative_saturation(&self) -> RelayState {
        RelayState {
            on: vec![false; self.relay_count()],
            x: 0.0,
            plus_mass_a_per_m: 0.0,
            switches: 0,
        }
    }

    /// All relays at +1, input at `h_max` (normalized L).
    pub fn positive_saturation(&self) -> RelayState {
        RelayState {
            on: vec![true; self.relay_count()],
            x: LEVELS as f64,
            plus_mass_a_per_m: self.total_a_per_m,
            switches: 0,
        }
    }

    /// The AC-demagnetized state, *defined by its input history*
    /// (`magctl::preisach::DEMAGNETIZATION_HISTORY`, normalized inputs from negative saturation).
    /// The history is data, not algorithm: replaying it on the relays keeps this independent.
    pub fn demagnetized(&self) -> RelayState {
        let mut state = self.negative_saturation();
        for &x in magctl::preisach::DEMAGNETIZATION_HISTORY.iter() {
            self.apply_normalized(&mut state, x as f64);
        }
        state
    }

    /// The ideal AC-demagnetized state about normalized input `c`, *defined by its region*:
    /// every relay with `α + β < 2c` on, the input at `c` (no history, so it checks the core's
    /// histories independently).
    pub fn ideal_demagnetized(&self, c: f64) -> RelayState {
        let mut alpha = vec![0.0; self.relay_count()];
        for t in &self.by_alpha {
            alpha[t.relay as usize] = t.x;
        }
        let mut state = self.negative_saturation();
        for t in &self.by_beta {
            let r = t.relay as usize;
            if alpha[r] + t.x < 2.0 * c {
                state.on[r] = true;
                state.plus_mass_a_per_m += self.relay_mass_a_per_m[r];
                state.switches += 1;
            }
        }
        state.x = c;
        state
    }

    /// Moves the input monotonically to normalized `x` and returns the output `M` (A/m).
    /// Panics on a non-finite `x` (a test bug, not a data condition).
    pub fn apply_normalized(&self, state: &mut RelayState, x: f64) -> f64 {
        assert!(x.is_finite(), "reference input must be finite, got {x}");
        if x > state.x {
            // Eq. (1): v = +1 once u > α. Relays with α < x_old are already on.
            let lo = self.by_alpha.partition_point(|t| t.x < state.x);
            let hi = self.by_alpha.partition_point(|t| t.x < x);
            for t in &self.by_alpha[lo..hi] {
                let r = t.relay as usize;
                if !state.on[r] {
                    state.on[r] = true;
                    state.plus_mass_a_per_m += self.relay_mass_a_per_m[r];
                    state.switches += 1;
                }
            }
        } else if x < state.x {
            // Eq. (1): v = -1 once u < β. Relays with β > x_old are already off.
            let lo = self.by_beta.partition_point(|t| t.x <= x);
            let hi = self.by_beta.partition_point(|t| t.x <= state.x);
            for t in &self.by_beta[lo..hi] {
                let r = t.relay as usize;
                if state.on[r] {
                    state.on[r] = false;
                    state.plus_mass_a_per_m -= self.relay_mass_a_per_m[r];
                    state.switches += 1;
                }
            }
        }
        state.x = x;
        self.output_a_per_m(state)
    }

    /// Moves the input monotonically to field `h` (A/m) and returns `M` (A/m).
    pub fn apply_a_per_m(&self, state: &mut RelayState, h_a_per_m: f64) -> f64 {
        self.apply_normalized(state, self.normalize(h_a_per_m))
    }

    /// Output `M = μ(P₊) - μ(P₋) = 2 μ(P₊) - Σ w` (eq. (3)) from the running sum, A/m.
    pub fn output_a_per_m(&self, state: &RelayState) -> f64 {
        2.0 * state.plus_mass_a_per_m - self.total_a_per_m
    }

    /// Output recomputed from scratch as `Σ mass · v` over all relays (eq. (2)), A/m.
    pub fn recomputed_output_a_per_m(&self, state: &RelayState) -> f64 {
        state
            .on
            .iter()
            .zip(&self.relay_mass_a_per_m)
            .map(|(&on, &m)| if on { m } else { -m })
            .sum()
    }

    /// Worst-case `|M_exact - M_relay|` over all input histories, A/m: twice the largest total
    /// mass of sub-squares along one monotone path (β non-decreasing, α non-increasing) through
    /// the `kL × kL` sub-grid (see the module docs for why the memory curve cuts no more).
    pub fn discretization_bound_a_per_m(&self) -> f64 {
        let k = self.subdivision;
        let n = k * LEVELS;
        let kk = (k * k) as f64;
        let sub_mass = |p: usize, q: usize| -> f64 {
            let (i, j) = (p / k, q / k);
            if p > q {
                0.0
            } else if i < j {
                self.weights_a_per_m[cell_index(i, j)] / kk
            } else if p < q {
                2.0 * self.weights_a_per_m[cell_index(i, j)] / kk
            } else {
                self.weights_a_per_m[cell_index(i, j)] / kk
            }
        };
        // best[p][q]: heaviest monotone path ending at (p, q), arriving from (p - 1, q) or
        // (p, q + 1). Rows p ascending, α index q descending.
        let mut previous_row = vec![0.0f64; n];
        let mut row = vec![0.0f64; n];
        let mut best = 0.0f64;
        for p in 0..n {
            for q in (0..n).rev() {
                let from_left = previous_row[q];
                let from_above = if q + 1 < n { row[q + 1] } else { 0.0 };
                row[q] = sub_mass(p, q) + from_left.max(from_above);
                best = best.max(row[q]);
            }
            std::mem::swap(&mut previous_row, &mut row);
        }
        2.0 * best
    }

    /// The closed-form upper bound of [`Self::discretization_bound_a_per_m`]:
    /// `2 (2kL - 1) ρ_max / k²`, A/m.
    pub fn discretization_bound_closed_form_a_per_m(&self) -> f64 {
        let k = self.subdivision as f64;
        2.0 * (2.0 * k * LEVELS as f64 - 1.0) * self.max_density_a_per_m() / (k * k)
    }
}

/// Monotone solve on the relay field, for the dynamics reference (`reference::dynamics`).
impl RelayPreisach {
    /// Solves `a·h + Γ(h) = r` (`a > 0`, A/m) along the monotone input path from `state`
    /// **without changing it**, walking the sorted thresholds exactly. Where the target falls
    /// inside an output jump (a relay switching at threshold `h_t`), the solution is `h = h_t` with
    /// the output taken as `r - a·h_t` (the jump is traversed partially), which keeps `a·h + M`
    /// continuous in `r`. Returns `(h, M)` with `a·h + M = r`.
    pub fn preview_solve(&self, state: &RelayState, a: f64, r_a_per_m: f64) -> (f64, f64) {
        let h_of = |x: f64| self.field_of(x);
        let h0 = h_of(state.x);
        let mut m = self.output_a_per_m(state);
        if a * h0 + m == r_a_per_m {
            return (h0, m);
        }
        if a * h0 + m < r_a_per_m {
            // Rising: relays with α in [x, ·) switch on, in α order (same convention as apply).
            let lo = self.by_alpha.partition_point(|t| t.x < state.x);
            for t in &self.by_alpha[lo..] {
                let h_t = h_of(t.x);
                if a * h_t + m >= r_a_per_m {
                    return ((r_a_per_m - m) / a, m);
                }
                let r = t.relay as usize;
                if state.on[r] {
                    continue;
                }
                m += 2.0 * self.relay_mass_a_per_m[r];
                if a * h_t + m >= r_a_per_m {
                    return (h_t, r_a_per_m - a * h_t);
                }
            }
        } else {
            // Falling: relays with β in (·, x] switch off, in descending β order.
            let hi = self.by_beta.partition_point(|t| t.x <= state.x);
            for t in self.by_beta[..hi].iter().rev() {
                let h_t = h_of(t.x);
                if a * h_t + m <= r_a_per_m {
                    return ((r_a_per_m - m) / a, m);
                }
                let r = t.relay as usize;
                if !state.on[r] {
                    continue;
                }
                m -= 2.0 * self.relay_mass_a_per_m[r];
                if a * h_t + m <= r_a_per_m {
                    return (h_t, r_a_per_m - a * h_t);
                }
            }
        }
        ((r_a_per_m - m) / a, m)
    }
}

/// The reversible part `R(h) = Σ_k χ_k (clamp(h, l_k, l_{k+1}) − (l_k + l_{k+1}) / 2)` in f64,
/// evaluated from its definition in the field (`lines`: the `L + 1` grid lines, `chi`: one
/// susceptibility per interval) — no normalized input, no tables: the check of the core's
/// `PreisachMeasure::with_reversible`.
pub fn reversible_a_per_m(lines_a_per_m: &[f64], susceptibility: &[f64], h_a_per_m: f64) -> f64 {
    lines_a_per_m
        .windows(2)
        .zip(susceptibility)
        .map(|(w, chi)| chi * (h_a_per_m.clamp(w[0], w[1]) - 0.5 * (w[0] + w[1])))
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn uniform_weights() -> Vec<f64> {
        // Density 1 everywhere: squares 1, diagonal half-squares 1/2.
        (0..CELL_COUNT)
            .map(|idx| {
                let (i, j) = magctl::preisach::cell_of_index(idx).unwrap();
                if i == j {
                    0.5
                } else {
                    1.0
                }
            })
            .collect()
    }

    #[test]
    fn relay_masses_add_up_to_each_cell() {
        let w: Vec<f64> = (0..CELL_COUNT).map(|k| 1.0 + k as f64).collect();
        for k in [1, 2, 3, 8] {
            let r = RelayPreisach::new(&w, -1.0, 1.0, k).unwrap();
            assert_eq!(r.relay_count(), 300 * k * k + 25 * k * (k + 1) / 2);
            // Sum the relays of each cell from their centres.
            let mut beta_of = vec![f64::NAN; r.relay_count()];
            for b in &r.by_beta {
                beta_of[b.relay as usize] = b.x;
            }
            let mut per_cell = vec![0.0f64; CELL_COUNT];
            for t in &r.by_alpha {
                let rel = t.relay as usize;
                let (i, j) = (beta_of[rel].floor() as usize, t.x.floor() as usize);
                assert!(beta_of[rel] <= t.x, "relay below the diagonal");
                per_cell[cell_index(i, j)] += r.relay_mass_a_per_m[rel];
            }
            for (c, (&got, &want)) in per_cell.iter().zip(&w).enumerate() {
                // Each cell sums k² terms of size <= 2w/k²: relative rounding <= k² 2⁻⁵².
                assert!(
                    (got - want).abs() <= want * (k * k) as f64 * f64::EPSILON,
                    "cell {c}, k {k}: {got} vs {want}"
                );
            }
        }
    }

    #[test]
    fn saturation_and_running_sum() {
        let w = uniform_weights();
        let r = RelayPreisach::new(&w, 0.0, 25.0, 4).unwrap();
        let total = r.saturation_a_per_m();
        assert_eq!(total, 312.5);
        let mut s = r.negative_saturation();
        assert_eq!(r.output_a_per_m(&s), -total);
        // Every relay switches on once: the running sum is exact up to one rounding per switch.
        let out = r.apply_a_per_m(&mut s, 30.0);
        assert!(s.on.iter().all(|&on| on));
        assert!((out - total).abs() <= s.switch_count() as f64 * f64::EPSILON * total);
        for x in [3.3, 20.1, 7.7, 11.0, 9.2, 24.9, 0.3, 13.0] {
            let out = r.apply_normalized(&mut s, x);
            // Running sum vs fresh sum: ~switches·2⁻⁵³ Σw each; a factor 2 for the output.
            let tol = 2.0
                * (s.switch_count() + r.relay_count() as u64) as f64
                * 0.5
                * f64::EPSILON
                * total;
            assert!((out - r.recomputed_output_a_per_m(&s)).abs() <= tol);
        }
    }

    /// For the uniform density the relay output along the first ascending branch is known in
    /// closed form: rising from negative saturation to `x` switches on every relay with α < x,
    /// i.e. the triangle of area x²/2 (up to the relays cut by the line α = x), M = x² - Σw.
    #[test]
    fn uniform_density_first_branch_matches_closed_form() {
        let w = uniform_weights();
        for k in [2, 5, 16] {
            let r = RelayPreisach::new(&w, 0.0, 25.0, k).unwrap();
            let bound = r.discretization_bound_a_per_m();
            let closed = r.discretization_bound_closed_form_a_per_m();
            assert!(bound <= closed * (1.0 + 1e-12), "{bound} > {closed}");
            let mut s = r.negative_saturation();
            for step in 1..=50 {
                let x = 0.5 * step as f64 - 0.013;
                let out = r.apply_normalized(&mut s, x);
                let exact = x * x - r.saturation_a_per_m();
                assert!(
                    (out - exact).abs() <= bound,
                    "k {k}, x {x}: {out} vs {exact}, bound {bound}"
                );
            }
        }
    }

    #[test]
    fn bad_construction_names_the_argument() {
        let w = uniform_weights();
        let e = RelayPreisach::new(&w[..10], 0.0, 1.0, 2).unwrap_err();
        assert!(e.0.starts_with("weights_a_per_m:"), "{e}");
        let mut bad = w.clone();
        bad[17] = -1.0;
        let e = RelayPreisach::new(&bad, 0.0, 1.0, 2).unwrap_err();
        assert!(e.0.starts_with("weights_a_per_m[17]"), "{e}");
        let e = RelayPreisach::new(&w, 1.0, 1.0, 2).unwrap_err();
        assert!(e.0.contains("h_min"), "{e}");
        let e = RelayPreisach::new(&w, 0.0, 1.0, 0).unwrap_err();
        assert!(e.0.starts_with("subdivision"), "{e}");
    }
}
