//! The quasi-static excitation current for identifying the Preisach masses: first-order reversal
//! curves (FORCs) with a reversal on every grid line.
//!
//! The field path (normalized units, `x ∈ [0, L]`): from the bottom of the grid (negative
//! saturation) up to the top, then for `r = L-1, L-2, ..., 0`: down to `x = r`, back up to the
//! top. The ends overshoot the grid by `overdrive` (a fraction of the range) so that the memory
//! is saturated even with a small error in `c0`.
//!
//! Why it reaches every cell, and determines every mass: the rising branch from reversal `r`
//! traces `T(u, r) = μ{r <= β <= α <= u}` (the Everett function) for all `u`; the difference of
//! the branches from `r` and `r + 1` at `u` is the mass of the strip `β ∈ [r, r+1]`, `α <= u`, and
//! as `u` crosses `α`-interval `j` it grows by exactly `w_{rj}` (densities uniform per cell), so
//! the 325 masses are a linear, invertible function of the data. `tests/excite.rs` checks it on
//! the design matrix: every column varies and `AᵀA` is positive definite.
//!
//! Timing: straight segments at the speed of a triangle wave over the full range at
//! `sweep_rate_hz`; every segment takes a whole number of samples so that each reversal point is a
//! sample (the sampled input reverses exactly on the grid line).

use actuator_params::PREISACH_LEVELS as LEVELS;

/// Options of the excitation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ExciteOptions {
    /// Bottom of the Preisach grid, A/m.
    pub h_min_a_per_m: f64,
    /// Top of the Preisach grid, A/m.
    pub h_max_a_per_m: f64,
    /// c0, 1/m: `H = c0 I` in the quasi-static limit.
    pub coil_factor_per_m: f64,
    /// Speed: that of a full-range triangle wave at this frequency, Hz.
    pub sweep_rate_hz: f64,
    /// Sampling rate of the written file, Hz.
    pub sample_rate_hz: f64,
    /// Overshoot beyond the grid at both ends, fraction of the range.
    pub overdrive: f64,
}

/// An excitation: uniformly sampled times and currents.
#[derive(Debug, Clone, PartialEq)]
pub struct Excitation {
    /// Times, s.
    pub t_s: Vec<f64>,
    /// Currents, A.
    pub current_a: Vec<f64>,
    /// Number of reversal curves (0 for the sine and soak records of [`crate::records`]).
    pub reversals: usize,
}

/// The reversal path in normalized units (see the module docs).
pub fn forc_waypoints(overdrive: f64) -> Vec<f64> {
    let top = LEVELS as f64 * (1.0 + overdrive);
    let bottom = -(LEVELS as f64) * overdrive;
    let mut path = vec![bottom, top];
    for r in (0..LEVELS).rev() {
        let r = if r == 0 { bottom } else { r as f64 };
        path.push(r);
        path.push(top);
    }
    path
}

/// Builds the FORC excitation.
pub fn forc_excitation(options: &ExciteOptions) -> Result<Excitation, String> {
    let o = options;
    for (name, v) in [
        ("coil factor", o.coil_factor_per_m),
        ("sweep rate", o.sweep_rate_hz),
        ("sample rate", o.sample_rate_hz),
    ] {
        if !(v.is_finite() && v > 0.0) {
            return Err(format!("{name} must be a finite number > 0, got {v}"));
        }
    }
    if !(o.h_min_a_per_m.is_finite() && o.h_max_a_per_m.is_finite())
        || o.h_min_a_per_m >= o.h_max_a_per_m
    {
        return Err(format!(
            "need a finite field range h_min < h_max, got [{}, {}]",
            o.h_min_a_per_m, o.h_max_a_per_m
        ));
    }
    if !(o.overdrive.is_finite() && (0.0..=0.5).contains(&o.overdrive)) {
        return Err(format!(
            "overdrive must be in [0, 0.5], got {}",
            o.overdrive
        ));
    }
    // A full-range triangle at f travels 2L cells per period.
    let cells_per_sample = 2.0 * LEVELS as f64 * o.sweep_rate_hz / o.sample_rate_hz;
    if cells_per_sample > 0.25 {
        return Err(format!(
            "the sweep moves {cells_per_sample:.3} grid cells per sample: raise the sample rate \
             or lower the sweep rate (at most 0.25 cells per sample, so that every cell is \
             crossed by several samples)"
        ));
    }
    let width = (o.h_max_a_per_m - o.h_min_a_per_m) / LEVELS as f64;
    let to_current = |x: f64| (o.h_min_a_per_m + x * width) / o.coil_factor_per_m;
    let path = forc_waypoints(o.overdrive);
    let mut xs = vec![path[0]];
    for pair in path.windows(2) {
        let (a, b) = (pair[0], pair[1]);
        let steps = ((b - a).abs() / cells_per_sample).ceil().max(1.0) as usize;
        for s in 1..=steps {
            xs.push(a + (b - a) * s as f64 / steps as f64);
        }
    }
    let dt = 1.0 / o.sample_rate_hz;
    Ok(Excitation {
        t_s: (0..xs.len()).map(|k| k as f64 * dt).collect(),
        current_a: xs.iter().map(|&x| to_current(x)).collect(),
        reversals: LEVELS,
    })
}
