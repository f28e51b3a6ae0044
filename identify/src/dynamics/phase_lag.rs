//! The paper's phase-lag scheme for `R_eddy` and `ξ` (Section 4, Steps 1-3 and Figure 5).
//!
//! For each dynamic experiment `k` (a sinusoidal current with DC bias at frequency `f_k`):
//!
//! 1. measured lag `θ_{y,I}` of the displacement's fundamental behind the current's
//!    ([`super::Phasors`], harmonic least squares over whole periods of the steady state);
//! 2. for every candidate `R_eddy⁽ⁱ⁾`, simulate (4) on the measured current from the experiment's
//!    initial state and take the lag `θ_{M²,I}` of `M²`'s fundamental (the drive of (5));
//! 3. the rest, `θ = θ_{y,I} − θ_{M²,I}`, is the lag of (5), a second-order low pass with
//!    `tan θ = 2ξ r / (1 − r²)`, `r = f_k / f0`, hence `ξ_k⁽ⁱ⁾ = tan θ (1 − r²) / (2 r)`.
//!
//! `f0` is not identified by the scheme: the paper measured it separately (392 Hz); here it is the
//! base file's value (the refined fit, [`super::RefinedFit`], identifies it).
//!
//! **Candidates.** `[0, R̄]` with `R̄ = 8πρN_m²/l_m` (the formula of Section 4 with `a = 0`: the
//! rod radius `b` cancels). The dynamics of (4) depend on `R_eddy` through the time constant
//! `∝ 1/R_eddy`, so they are most sensitive at small `R`: the mesh is geometric from `R̄/500` to
//! `R̄` (`R = 0` itself freezes `H` and is excluded), then refined with a second, uniform mesh
//! between the neighbours of the best coarse point (the paper: "finer in the region where the
//! dynamics of (4) is more sensitive").
//!
//! **Choice.** The paper takes the candidate whose `{ξ_k}` has the least variance, and `ξ` = their
//! mean. Both are computed and reported ([`Candidate::variance`], and the coefficient of variation
//! `std/mean`, which removes the variance's preference for candidates that make every `ξ_k`
//! small). The choice itself uses the same idea with each `ξ_k` weighted by how well its frequency
//! determines it: the phases `θ_k` carry errors of similar size at every frequency (the identified
//! Preisach measure's error in the large hysteresis lag of `M²`, 25-45° here, and sensor noise),
//! and `dξ/dθ = (1 − r²) / (2 r cos²θ)` is ~10 at `r` = 0.05 but ~1.3 at `r` = 0.5, so a 0.2°
//! error that is harmless at 200 Hz moves `ξ` at 20 Hz by 6 %. With weights
//! `w_k = (dθ/dξ)_k²` the weighted mean `ξ̄` is the one damping ratio that best explains every
//! mechanical lag, and the weighted spread is the RMS phase (rad) by which it fails to
//! ([`Candidate::phase_misfit_rad`]): the least-squares (maximum-likelihood, for equal phase
//! errors) form of "ξ varies least across frequencies". The chosen `ξ` is that `ξ̄`.

use super::simulate::{simulate, DynamicParams};
use super::{DynamicError, Prepared, Progress};
use magctl::preisach::PreisachMeasure;
use maglab_signal::spectrum::{harmonic_fit, wrap_lag_rad};
use rayon::prelude::*;

/// One candidate of the grid.
#[derive(Debug, Clone, PartialEq)]
pub struct Candidate {
    /// R_eddy⁽ⁱ⁾, Ω.
    pub eddy_resistance_ohm: f64,
    /// `θ_{M²,I}` per experiment, rad.
    pub lag_m2_rad: Vec<f64>,
    /// `ξ_k⁽ⁱ⁾` per experiment.
    pub damping_ratios: Vec<f64>,
    /// Mean of `ξ_k`.
    pub mean: f64,
    /// Sample variance of `ξ_k` (the paper's criterion).
    pub variance: f64,
    /// `std / mean` (infinite unless every `ξ_k > 0`).
    pub coefficient_of_variation: f64,
    /// Mean of `ξ_k` weighted by `(dθ/dξ)_k²` (the chosen `ξ`).
    pub weighted_mean: f64,
    /// RMS over `k` of `(ξ_k − ξ̄) (dθ/dξ)_k`, rad (the criterion used; infinite unless
    /// `ξ̄ > 0` and every `ξ_k` finite).
    pub phase_misfit_rad: f64,
}

/// Result of the scheme.
#[derive(Debug, Clone, PartialEq)]
pub struct PhaseLagResult {
    /// `R̄`, Ω.
    pub r_bar_ohm: f64,
    /// Measured `θ_{y,I}` per experiment, rad.
    pub measured_lag_rad: Vec<f64>,
    /// The coarse grid (geometric), in increasing R.
    pub coarse: Vec<Candidate>,
    /// The refined grid around the best coarse candidate.
    pub fine: Vec<Candidate>,
    /// The chosen candidate (from `fine`).
    pub chosen: Candidate,
    /// `f0` used, Hz.
    pub resonance_hz: f64,
    /// The parameter file's `f0` when the scheme found no damping ratio there and `f0` was
    /// scanned instead ([`phase_lag_scheme_scanning_f0`]), Hz.
    pub scanned_from_hz: Option<f64>,
    /// Candidate with the least variance of `ξ_k` over both grids (the paper's literal
    /// criterion, for the report), Ω.
    pub least_variance_ohm: f64,
    /// Candidate with the least coefficient of variation over both grids, Ω.
    pub least_cv_ohm: f64,
}

/// Geometric mesh of `n` points from `r_bar / 500` to `r_bar`.
pub fn coarse_mesh(r_bar_ohm: f64, n: usize) -> Vec<f64> {
    let lo = r_bar_ohm / 500.0;
    (0..n)
        .map(|i| lo * (r_bar_ohm / lo).powf(i as f64 / (n.max(2) - 1) as f64))
        .collect()
}

/// `ξ` from the lag `θ` of (5) at `r = f / f0`.
pub fn damping_from_lag(theta_rad: f64, r: f64) -> f64 {
    theta_rad.tan() * (1.0 - r * r) / (2.0 * r)
}

fn evaluate(
    measure: &PreisachMeasure,
    prepared: &Prepared<'_>,
    measured: &[f64],
    r_ohm: f64,
    resonance_hz: f64,
) -> Candidate {
    let p = DynamicParams {
        eddy_resistance_ohm: r_ohm,
        damping_ratio: prepared.base_dynamic.damping_ratio,
        resonance_hz,
    };
    let mut lag_m2_rad = Vec::new();
    let mut damping_ratios = Vec::new();
    let mut slopes = Vec::new();
    for (e, theta_y) in prepared.experiments.iter().zip(measured) {
        let sim = simulate(
            measure,
            &prepared.base_actuator,
            &p,
            &e.experiment.measurement,
            &prepared.options.simulation,
        );
        let m2: Vec<f64> = sim.m_a_per_m.iter().map(|m| m * m).collect();
        let lag = match harmonic_fit(
            &m2,
            e.experiment.measurement.step_s,
            e.experiment.frequency_hz,
            e.window.clone(),
            prepared.options.harmonics,
        ) {
            Some(fit) => wrap_lag_rad(e.phasors.current.phase_rad() - fit.phase_rad()),
            None => f64::NAN,
        };
        let r = e.experiment.frequency_hz / resonance_hz;
        let theta = theta_y - lag;
        lag_m2_rad.push(lag);
        damping_ratios.push(damping_from_lag(theta, r));
        // dθ/dξ = 2 r cos²θ / (1 − r²).
        slopes.push(2.0 * r * theta.cos() * theta.cos() / (1.0 - r * r));
    }
    let n = damping_ratios.len() as f64;
    let mean = damping_ratios.iter().sum::<f64>() / n;
    let variance = if n > 1.0 {
        damping_ratios
            .iter()
            .map(|x| (x - mean) * (x - mean))
            .sum::<f64>()
            / (n - 1.0)
    } else {
        0.0
    };
    let all_positive = damping_ratios.iter().all(|x| x.is_finite() && *x > 0.0);
    let weights: Vec<f64> = slopes.iter().map(|s| s * s).collect();
    let wsum: f64 = weights.iter().sum();
    let weighted_mean = damping_ratios
        .iter()
        .zip(&weights)
        .map(|(x, w)| x * w)
        .sum::<f64>()
        / wsum;
    let misfit = (damping_ratios
        .iter()
        .zip(&slopes)
        .map(|(x, s)| ((x - weighted_mean) * s).powi(2))
        .sum::<f64>()
        / n)
        .sqrt();
    let usable = weighted_mean > 0.0 && misfit.is_finite();
    Candidate {
        eddy_resistance_ohm: r_ohm,
        lag_m2_rad,
        damping_ratios,
        mean,
        variance,
        coefficient_of_variation: if all_positive {
            variance.sqrt() / mean
        } else {
            f64::INFINITY
        },
        weighted_mean,
        phase_misfit_rad: if usable { misfit } else { f64::INFINITY },
    }
}

/// Runs the scheme (see the module docs).
pub fn phase_lag_scheme(
    measure: &PreisachMeasure,
    prepared: &Prepared<'_>,
    resonance_hz: f64,
    progress: &Progress<'_>,
) -> Result<PhaseLagResult, DynamicError> {
    let o = &prepared.options;
    let measured: Vec<f64> = prepared
        .experiments
        .iter()
        .map(|e| e.phasors.lag_rad())
        .collect();
    let r_bar = prepared.r_bar_ohm;
    let mesh = coarse_mesh(r_bar, o.coarse_points);
    let total = mesh.len() + o.fine_points;
    let done = std::sync::atomic::AtomicUsize::new(0);
    let tick = || {
        let d = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
        progress("phase-lag grid", d, total);
    };
    let coarse: Vec<Candidate> = mesh
        .par_iter()
        .map(|&r| {
            let c = evaluate(measure, prepared, &measured, r, resonance_hz);
            tick();
            c
        })
        .collect();
    let best = best_index(&coarse).ok_or_else(|| {
        DynamicError(format!(
            "phase-lag scheme: no candidate R_eddy in [{:.3}, {:.3}] Ω gives a positive mean \
             damping ratio (measured lags {:?} rad): the data do not fit (4)-(5) with \
             f0 = {resonance_hz} Hz",
            mesh[0], r_bar, measured
        ))
    })?;
    let lo = mesh[best.saturating_sub(1)];
    let hi = mesh[(best + 1).min(mesh.len() - 1)];
    let fine_mesh: Vec<f64> = (0..o.fine_points)
        .map(|i| lo + (hi - lo) * i as f64 / (o.fine_points.max(2) - 1) as f64)
        .collect();
    let fine: Vec<Candidate> = fine_mesh
        .par_iter()
        .map(|&r| {
            let c = evaluate(measure, prepared, &measured, r, resonance_hz);
            tick();
            c
        })
        .collect();
    let chosen = best_index(&fine)
        .map(|k| fine[k].clone())
        .unwrap_or_else(|| coarse[best].clone());
    let least = |key: fn(&Candidate) -> f64| {
        coarse
            .iter()
            .chain(&fine)
            .filter(|c| key(c).is_finite())
            .min_by(|a, b| key(a).total_cmp(&key(b)))
            .map_or(f64::NAN, |c| c.eddy_resistance_ohm)
    };
    let least_variance_ohm = least(|c| c.variance);
    let least_cv_ohm = least(|c| c.coefficient_of_variation);
    Ok(PhaseLagResult {
        r_bar_ohm: r_bar,
        measured_lag_rad: measured,
        coarse,
        fine,
        chosen,
        resonance_hz,
        scanned_from_hz: None,
        least_variance_ohm,
        least_cv_ohm,
    })
}

fn best_index(candidates: &[Candidate]) -> Option<usize> {
    candidates
        .iter()
        .enumerate()
        .filter(|(_, c)| c.phase_misfit_rad.is_finite())
        .min_by(|a, b| a.1.phase_misfit_rad.total_cmp(&b.1.phase_misfit_rad))
        .map(|(k, _)| k)
}

/// Ratio of the largest to the smallest `f0` of [`phase_lag_scheme_scanning_f0`]'s scan, each
/// side of the file's value.
pub const F0_SCAN_RATIO: f64 = 3.0;

/// Points of that scan (geometric, the file's value in the middle).
pub const F0_SCAN_POINTS: usize = 9;

/// The scheme at the parameter file's `f0`; when no `R_eddy` gives a positive damping ratio there
/// (the rig's measured lags need another resonance: a load on the rod, another rod, an extra lag
/// in the chain), the scheme at each `f0` of a geometric scan from `f0/3` to `3 f0`, keeping the
/// result with the least phase misfit. The scan is recorded in
/// [`PhaseLagResult::scanned_from_hz`]; the error at the file's `f0` is returned when no scanned
/// `f0` works either.
pub fn phase_lag_scheme_scanning_f0(
    measure: &PreisachMeasure,
    prepared: &Prepared<'_>,
    resonance_hz: f64,
    progress: &Progress<'_>,
) -> Result<PhaseLagResult, DynamicError> {
    let at_file = match phase_lag_scheme(measure, prepared, resonance_hz, progress) {
        Ok(r) => return Ok(r),
        Err(e) => e,
    };
    let middle = F0_SCAN_POINTS / 2;
    let half = middle as f64;
    (0..F0_SCAN_POINTS)
        // The middle point is the file's f0, already tried.
        .filter(|&i| i != middle)
        .map(|i| resonance_hz * F0_SCAN_RATIO.powf((i as f64 - half) / half))
        .filter_map(|f0| phase_lag_scheme(measure, prepared, f0, progress).ok())
        .min_by(|a, b| {
            a.chosen
                .phase_misfit_rad
                .total_cmp(&b.chosen.phase_misfit_rad)
        })
        .map(|r| PhaseLagResult {
            scanned_from_hz: Some(resonance_hz),
            ..r
        })
        .ok_or(at_file)
}
