//! The direct waveform fit: `R_eddy`, `ξ` and `f0` by nonlinear least squares on the measured
//! displacement of every dynamic experiment at once (MINPACK's Levenberg-Marquardt, crate
//! `levenberg-marquardt`), started from the phase-lag result.
//!
//! Why it is better than the phase-lag scheme: it uses the whole waveform (amplitude, harmonics
//! and phase of every frequency), not one phase per frequency; it identifies `f0` instead of
//! assuming it; and it has no grid resolution.
//!
//! **Residuals.** For experiment `k` with `n_k` samples in its steady-state window and measured
//! range `s_k` (max − min of `y` there), `r = (y_model − y_measured) / (s_k √n_k)`, so that
//! `‖r‖² = Σ_k NRMSE_k²`: every frequency weighs the same whatever its amplitude and length.
//!
//! **Parameters.** `x = (ln R_eddy, ln ξ, ln f0)`: positive by construction and of similar scale
//! (the Jacobian columns are relative sensitivities). The Jacobian is by central differences with
//! a step of 10⁻³ in `x` (0.1 %): the model runs in f32, whose rounding on `y` is ~10⁻⁶ of the
//! stroke, so the difference quotient's rounding error is ~10⁻³ of a unit sensitivity while its
//! truncation error is `O(10⁻⁶)`. The 6 perturbed runs and the experiments run in parallel.

use super::simulate::{simulate, DynamicParams};
use super::{Prepared, Progress};
use levenberg_marquardt::{LeastSquaresProblem, LevenbergMarquardt};
use magctl::preisach::PreisachMeasure;
use nalgebra::{DVector, Dyn, OMatrix, Owned, Vector3, U3};
use rayon::prelude::*;
use std::sync::atomic::{AtomicUsize, Ordering};

/// Relative step of the central differences (see the module docs).
const JACOBIAN_STEP: f64 = 1e-3;

/// Result of the waveform fit.
#[derive(Debug, Clone, PartialEq)]
pub struct WaveformResult {
    /// The fitted parameters.
    pub params: DynamicParams,
    /// The starting point.
    pub start: DynamicParams,
    /// NRMSE of the displacement per experiment (steady-state window) at the fit.
    pub nrmse: Vec<f64>,
    /// NRMSE per experiment at the starting point.
    pub nrmse_start: Vec<f64>,
    /// `√(Σ NRMSE_k² / K)` at the fit.
    pub rms_nrmse: f64,
    /// Approximate 1σ relative uncertainties of `(R_eddy, ξ, f0)` from `(JᵀJ)⁻¹` with the
    /// residual variance (assumes white residuals: a lower bound when model error dominates).
    pub relative_std: [f64; 3],
    /// Why Levenberg-Marquardt stopped.
    pub termination: String,
    /// Model evaluations (each simulates every experiment).
    pub evaluations: usize,
}

struct Problem<'a> {
    measure: &'a PreisachMeasure,
    prepared: &'a Prepared<'a>,
    x: Vector3<f64>,
    residuals: Option<DVector<f64>>,
    evaluations: &'a AtomicUsize,
    progress: &'a Progress<'a>,
}

/// `x` → parameters, each clamped to a physical box (`R_eddy ∈ [R̄/10⁴, 10 R̄]`,
/// `ξ ∈ [10⁻³, 10³]`, `f0 ∈ [1 Hz, 10⁶ Hz]`): a trial step of Levenberg-Marquardt outside the box
/// is evaluated at the box's edge, does not reduce the cost, and is rejected (the trust region
/// shrinks) instead of running the model with absurd constants.
fn params_of(x: &Vector3<f64>, r_bar_ohm: f64) -> DynamicParams {
    DynamicParams {
        eddy_resistance_ohm: x[0].exp().clamp(r_bar_ohm * 1e-4, r_bar_ohm * 10.0),
        damping_ratio: x[1].exp().clamp(1e-3, 1e3),
        resonance_hz: x[2].exp().clamp(1.0, 1e6),
    }
}

/// Scaled residuals of every experiment for `p` (None if the model produced a non-finite value).
fn residuals(
    measure: &PreisachMeasure,
    prepared: &Prepared<'_>,
    p: &DynamicParams,
) -> Option<DVector<f64>> {
    let parts: Vec<Vec<f64>> = prepared
        .experiments
        .par_iter()
        .map(|e| {
            let m = &e.experiment.measurement;
            let sim = simulate(measure, prepared.base, p, m, &prepared.options.simulation);
            let scale = e.displacement_range_m * (e.window.len() as f64).sqrt();
            e.window
                .clone()
                .map(|k| (sim.displacement_m[k] - m.displacement_m[k]) / scale)
                .collect()
        })
        .collect();
    let all: Vec<f64> = parts.into_iter().flatten().collect();
    all.iter()
        .all(|v| v.is_finite())
        .then(|| DVector::from_vec(all))
}

/// NRMSE per experiment from the scaled residuals.
fn per_experiment(prepared: &Prepared<'_>, r: &DVector<f64>) -> Vec<f64> {
    let mut offset = 0;
    prepared
        .experiments
        .iter()
        .map(|e| {
            let n = e.window.len();
            let s = r.rows(offset, n).norm();
            offset += n;
            s
        })
        .collect()
}

impl Problem<'_> {
    fn eval(&self, x: &Vector3<f64>) -> Option<DVector<f64>> {
        let r = residuals(
            self.measure,
            self.prepared,
            &params_of(x, self.prepared.r_bar_ohm),
        );
        let d = self.evaluations.fetch_add(1, Ordering::Relaxed) + 1;
        (self.progress)("waveform fit (model runs)", d, 0);
        r
    }

    fn jacobian_at(&self, x: &Vector3<f64>) -> Option<OMatrix<f64, Dyn, U3>> {
        let columns: Vec<Option<(DVector<f64>, DVector<f64>)>> = (0..3)
            .into_par_iter()
            .map(|j| {
                let mut plus = *x;
                let mut minus = *x;
                plus[j] += JACOBIAN_STEP;
                minus[j] -= JACOBIAN_STEP;
                let (a, b) = rayon::join(|| self.eval(&plus), || self.eval(&minus));
                Some((a?, b?))
            })
            .collect();
        let rows = self.residuals.as_ref()?.len();
        let mut jac = OMatrix::<f64, Dyn, U3>::zeros(rows);
        for (j, col) in columns.into_iter().enumerate() {
            let (a, b) = col?;
            jac.set_column(j, &((a - b) / (2.0 * JACOBIAN_STEP)));
        }
        Some(jac)
    }
}

impl LeastSquaresProblem<f64, Dyn, U3> for Problem<'_> {
    type ResidualStorage = Owned<f64, Dyn>;
    type JacobianStorage = Owned<f64, Dyn, U3>;
    type ParameterStorage = Owned<f64, U3>;

    fn set_params(&mut self, x: &Vector3<f64>) {
        self.x = *x;
        self.residuals = self.eval(x);
    }

    fn params(&self) -> Vector3<f64> {
        self.x
    }

    fn residuals(&self) -> Option<DVector<f64>> {
        self.residuals.clone()
    }

    fn jacobian(&self) -> Option<OMatrix<f64, Dyn, U3>> {
        self.jacobian_at(&self.x)
    }
}

/// Fits `(R_eddy, ξ, f0)` starting from `start`.
pub fn waveform_fit(
    measure: &PreisachMeasure,
    prepared: &Prepared<'_>,
    start: DynamicParams,
    progress: &Progress<'_>,
) -> Result<WaveformResult, super::DynamicError> {
    let evaluations = AtomicUsize::new(0);
    let x0 = Vector3::new(
        start.eddy_resistance_ohm.ln(),
        start.damping_ratio.ln(),
        start.resonance_hz.ln(),
    );
    let mut problem = Problem {
        measure,
        prepared,
        x: x0,
        residuals: None,
        evaluations: &evaluations,
        progress,
    };
    problem.set_params(&x0);
    let r0 = problem.residuals.clone().ok_or_else(|| {
        super::DynamicError(format!(
            "waveform fit: the model gives non-finite displacements at the start {start:?}"
        ))
    })?;
    let nrmse_start = per_experiment(prepared, &r0);
    let (problem, report) = LevenbergMarquardt::new()
        .with_ftol(1e-10)
        .with_xtol(1e-7)
        .with_gtol(1e-10)
        .with_patience(prepared.options.max_iterations)
        // First step at most ~e^{±1} per parameter: the start is the phase-lag result.
        .with_stepbound(1.0)
        .minimize(problem);
    let r = problem.residuals.clone().ok_or_else(|| {
        super::DynamicError(format!(
            "waveform fit failed ({:?}) at {:?}",
            report.termination,
            params_of(&problem.x, prepared.r_bar_ohm)
        ))
    })?;
    let nrmse = per_experiment(prepared, &r);
    let k = nrmse.len() as f64;
    let rms_nrmse = (nrmse.iter().map(|v| v * v).sum::<f64>() / k).sqrt();
    let relative_std = problem
        .jacobian()
        .and_then(|j| {
            let dof = (r.len() as f64 - 3.0).max(1.0);
            let s2 = r.norm_squared() / dof;
            let jtj = j.transpose() * &j;
            jtj.try_inverse()
                .map(|inv| [0, 1, 2].map(|i| (s2 * inv[(i, i)]).max(0.0).sqrt()))
        })
        .unwrap_or([f64::NAN; 3]);
    Ok(WaveformResult {
        params: params_of(&problem.x, prepared.r_bar_ohm),
        start,
        nrmse,
        nrmse_start,
        rms_nrmse,
        relative_std,
        termination: format!("{:?}", report.termination),
        evaluations: evaluations.load(Ordering::Relaxed),
    })
}
