//! Derived error budgets of the f32 core, used as tolerances by the tests (so no test tolerance
//! is tuned: each is one of these formulas, derived here once).
//!
//! Notation: `W = Σ w` (the saturation output, an upper bound of every partial mass), `u = 2⁻²⁴`
//! (f32 unit roundoff), `L` = 25 grid intervals, inputs normalized `x = (h - h_min) / Δ`.
//!
//! # One Everett evaluation
//!
//! `T(J + s, I + t)` is evaluated as `q0 + s (q1 + s q2)` with
//! `q0 = full + (1-t) (column + (1-t) w_II)`, `q1 = row + (1-t) w_IJ`, `q2 = w_JJ`,
//! `full`, `row`, `column` read from the per-pair table (see `magctl`'s `everett.rs`; before issue
//! 12 `row` and `column` were differences of two table entries, which this budget still covers).
//! `s` and `t` are exact (`x - ⌊x⌋` is exact in f32); `1 - t` carries one rounding (relative `u`).
//! Every table entry is one rounding (`<= u W`) of an f64 sum, and every intermediate value is the
//! mass of a set of cells times factors in `[0, 1]`, so `<= W` (`<= 2 W` in the diagonal case);
//! each operation then adds at most `u W`. Counting: `row`, `column` 3 each; `q0` 11; `q1` 7;
//! `q2` 1; the Horner steps 12 more: at most 23 `u W`, rounded up to
//! [`everett_rounding_a_per_m`] `= 24 u W` (second-order terms are below `u² W`).
//!
//! # One output
//!
//! The core keeps `μ(P₊)` as a running sum along the staircase: each of the `len - 1` stored
//! vertices holds the previous sum plus one Everett term (one evaluation, one addition of values
//! `<= W`), and the output adds the moving segment's term: `len` terms, each off by at most
//! `24 u W + u W`. `M = 2 μ(P₊) - W` doubles that and adds two roundings (`W` stored in f32, the
//! final subtraction): [`output_rounding_a_per_m`] `= (50 len + 2) u W`. Vertices that are popped
//! (wiping-out) take their error with them, so the error never grows with the number of steps,
//! only with the staircase length.
//!
//! # Changes of the output measured from a common stored vertex
//!
//! Two outputs computed from the **same** stored vertex (same running sum `c`) differ only in
//! their fresh Everett terms: `M = 2 fl(c + T) - W` each. So an output *increment* made of
//! `terms` fresh terms on top of a shared `c` (a minor-loop branch from its reversal point, the
//! same point reached at two sampling rates) carries at most `2 terms (24 u W + u W) + 2 u W`:
//! [`increment_rounding_a_per_m`]. The shared sum's own error cancels.
//!
//! # The exact inverse / solve
//!
//! The solver (`magctl`'s `solve.rs`) computes `q = r - g(x₀)` on the final piece, the piece's
//! quadratic `A σ² + B σ` and the root `σ = 2q / (B + √(B² + 4Aq))`, commits `x = x₀ + σ` and
//! recomputes `M` from the same stored vertex as `g(x₀)`, so the stored sum cancels again. Budget,
//! with `λ` below: `q` 52 `u W` (two Everett terms, four additions), the recomputed `M` 51 `u W`,
//! the coefficients of the piece 24 `u W` (`B` carries 11 roundings of values `<= 2W`, `A` one),
//! a piece chosen by a rounded end value 52 `u W`; the root's relative error `<= 6 u` on `σ <= 1`
//! and the rounding of `x₀ + σ` (`u L`) move along a slope `<= 2 λ + a Δ`. Plus the f32 products
//! `a·h` and the target: [`solve_rounding_a_per_m`]
//! `= 200 u W + (2 λ + a Δ)(L + 8) u + 4 u a |h|_max + 2 u |r|`.
//!
//! # Input rounding
//!
//! `x = (h - h_min) · (1/Δ)` in f32: the subtraction, the stored `1/Δ` and the product each add a
//! relative `u`, so `|x_f32 - x| <= 3 u · L` plus `u` for the f32 input itself (`~4 u L` total,
//! [`input_rounding_normalized`]). Since `|dM/dx| <= 2 λ` with `λ` the largest line integral of
//! the density ([`line_density_bound_a_per_m`]), an input perturbation `δx` moves the output by at
//! most `2 λ δx` along a monotone branch.

//! # The reversible part
//!
//! With a reversible part (`PreisachMeasure::with_reversible`) the output adds
//! `R(x) = R_k + ρ_k (x − k)`: the stored line value and rise are each one rounding of an f64
//! value `<= ½ Σρ` (`Σρ` the rises' sum, [`reversible_rises_a_per_m`]), the evaluation one product
//! and two additions: `<= 4 u Σρ` per evaluation, added to every output, increment and residual
//! budget above (twice where two evaluations meet). In the solve the piece's linear coefficient
//! gains `ρ_k`, so the slope along which the root's error moves is `2 λ + a Δ + ρ_max`
//! ([`output_slope_bound_a_per_m`] without the `a Δ`). `W` already includes `½ Σρ`
//! (`saturation_a_per_m`). Without a reversible part every added term is 0.

use magctl::preisach::{PreisachMeasure, LEVELS};

/// f32 unit roundoff `u = 2⁻²⁴`.
pub const F32_UNIT_ROUNDOFF: f64 = f32::EPSILON as f64 * 0.5;

/// f64 unit roundoff `2⁻⁵³`.
pub const F64_UNIT_ROUNDOFF: f64 = f64::EPSILON * 0.5;

/// Worst-case rounding of one f32 Everett evaluation: `24 u W`, A/m (module docs).
pub fn everett_rounding_a_per_m(measure: &PreisachMeasure) -> f64 {
    24.0 * F32_UNIT_ROUNDOFF * measure.saturation_a_per_m() as f64
}

/// Worst-case rounding of the core's output for a staircase of `len` vertices (anchor
/// included): `(50 len + 2) u W`, A/m (module docs).
pub fn output_rounding_a_per_m(measure: &PreisachMeasure, len: usize) -> f64 {
    (50.0 * len as f64 + 2.0) * F32_UNIT_ROUNDOFF * measure.saturation_a_per_m() as f64
        + reversible_rounding_a_per_m(measure)
}

/// Worst-case rounding of an output increment made of `terms` fresh Everett terms on top of a
/// shared stored vertex: `2 terms · 25 u W + 2 u W`, A/m (module docs).
pub fn increment_rounding_a_per_m(measure: &PreisachMeasure, terms: usize) -> f64 {
    (50.0 * terms as f64 + 2.0) * F32_UNIT_ROUNDOFF * measure.saturation_a_per_m() as f64
        + 2.0 * reversible_rounding_a_per_m(measure)
}

/// The rises `ρ_k = χ_k Δ_k` of the reversible part over each interval, A/m (all 0 without one).
pub fn reversible_rises_a_per_m(measure: &PreisachMeasure) -> Vec<f64> {
    measure
        .reversible_susceptibility()
        .iter()
        .enumerate()
        .map(|(k, &chi)| chi as f64 * measure.interval_width_a_per_m(k) as f64)
        .collect()
}

/// Rounding of one evaluation of the reversible part: `4 u Σρ`, A/m (module docs).
pub fn reversible_rounding_a_per_m(measure: &PreisachMeasure) -> f64 {
    4.0 * F32_UNIT_ROUNDOFF * reversible_rises_a_per_m(measure).iter().sum::<f64>()
}

/// `|dM/dx| <= 2 λ + ρ_max` along a monotone branch (normalized input), A/m: what an input
/// perturbation `δx` can do to the output.
pub fn output_slope_bound_a_per_m(measure: &PreisachMeasure) -> f64 {
    2.0 * line_density_bound_a_per_m(measure)
        + reversible_rises_a_per_m(measure)
            .into_iter()
            .fold(0.0, f64::max)
}

/// Worst-case residual `|a·h + M - r|` of the core's solve (and, with `a = 0`, `|M - m_target|` of
/// the inverse), A/m; `h_a_per_m` is the returned input (module docs).
pub fn solve_rounding_a_per_m(
    measure: &PreisachMeasure,
    a: f64,
    r_a_per_m: f64,
    h_a_per_m: f64,
) -> f64 {
    let u = F32_UNIT_ROUNDOFF;
    let w = measure.saturation_a_per_m() as f64;
    // `a Δ` per unit of normalized input; on a nonuniform grid the widest interval's width.
    let slope = output_slope_bound_a_per_m(measure) + a * measure.widest_interval_a_per_m() as f64;
    let h_max = h_a_per_m
        .abs()
        .max(measure.h_min_a_per_m().abs() as f64)
        .max(measure.h_max_a_per_m().abs() as f64);
    200.0 * u * w
        + 2.0 * reversible_rounding_a_per_m(measure)
        + slope * (LEVELS as f64 + 8.0) * u
        + 4.0 * u * a * h_max
        + 2.0 * u * r_a_per_m.abs()
}

/// Worst-case rounding of the core's normalized input, `4 u L` (module docs).
pub fn input_rounding_normalized() -> f64 {
    4.0 * F32_UNIT_ROUNDOFF * LEVELS as f64
}

/// `λ`: the largest mass per unit length along one grid row (fixed α) or column (fixed β) of the
/// density, A/m per normalized input unit. A diagonal half-square contributes its density `2 w`
/// over a length `<= 1`. Along a monotone input branch `|dM/dx| <= 2 λ`: moving the input by `dx`
/// switches the relays in a strip of width `dx` along one row or column.
pub fn line_density_bound_a_per_m(measure: &PreisachMeasure) -> f64 {
    let mut lambda = 0.0f64;
    for n in 0..LEVELS {
        // Row α ∈ [n, n+1]: cells (i, n), i < n, plus the diagonal cell.
        let row: f64 = (0..n)
            .map(|i| measure.cell_mass_a_per_m(i, n) as f64)
            .sum::<f64>()
            + 2.0 * measure.cell_mass_a_per_m(n, n) as f64;
        // Column β ∈ [n, n+1]: cells (n, j), j > n, plus the diagonal cell.
        let column: f64 = (n + 1..LEVELS)
            .map(|j| measure.cell_mass_a_per_m(n, j) as f64)
            .sum::<f64>()
            + 2.0 * measure.cell_mass_a_per_m(n, n) as f64;
        lambda = lambda.max(row).max(column);
    }
    lambda
}

/// f32 rounding of the core's dynamic model in displacement, m: about 16 roundings of relative
/// size `ε = 2⁻²⁴` per step on values bounded by the stroke, damped by the mechanical contraction
/// `e^{-ξ ω0 h}` per step, so at most `16 ε · stroke / (ξ ω0 h)` (`h` = 1 / `rate_hz`).
pub fn model_rounding_m(actuator: &magctl::params::Actuator, rate_hz: f64) -> f64 {
    let xi_omega_h =
        actuator.damping_ratio as f64 * 2.0 * std::f64::consts::PI * actuator.resonance_hz as f64
            / rate_hz;
    16.0 * f32::EPSILON as f64 * actuator.stroke_m() as f64 / xi_omega_h
}

/// Rounding of the reference's f64 running sum after `switches` relay switches: each switch is
/// one f64 addition of values `<= W`, and the output doubles the sum: `2 switches 2⁻⁵³ W`, plus
/// the same for building `W` itself from `relays` masses.
pub fn relay_sum_rounding_a_per_m(total_a_per_m: f64, switches: u64, relays: usize) -> f64 {
    2.0 * (switches as f64 + relays as f64) * F64_UNIT_ROUNDOFF * total_a_per_m
}
