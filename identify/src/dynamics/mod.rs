//! `R_eddy`, `ξ` and `f0` from dynamic experiments (sinusoidal currents with DC bias at several
//! frequencies), with the Preisach measure already identified: paper Section 4.
//!
//! * [`simulate`]: one experiment through the core's f32 model (4)-(5), driven by the measured
//!   current, from the experiment's initial state.
//! * [`phase_lag`]: the paper's scheme (grid over `R_eddy`, `ξ` from the phase of (5), least
//!   spread of `ξ` across frequencies) — the Figure 5 data.
//! * [`RefinedFit`]: the final fit of `(R_eddy, ξ, f0)` to the measured waveforms with the
//!   recording's nuisances estimated, started from the phase-lag result: made by the caller with
//!   the diagnosis' model (`maglab identify` uses `maglab_diagnose::identification`, the model the
//!   diagnosis refits), recorded here.
//! * [`record`]: the identified values and their provenance in the parameter file.
//! * [`fit_eddy_and_damping`]: the phase-lag scheme on every experiment, the library entry point
//!   of `maglab identify`.
//!
//! **Steady-state window.** Each experiment is analysed on whole periods after a settling time
//! `max(settle_periods / f, settle_time_constants / (ξ ω0))` (base `ξ`, `f0`): the mechanical
//! transient of (5) decays like `e^{-ξ ω0 t}`, the Preisach memory of a periodic input is
//! periodic after the first period (wiping out), and the transient of (4) is faster than either.
//!
//! **`R̄`.** `R̄ = 8πρ N_m² (b² − a²) / (l_m (b² + a²))` with `a = 0` is `8πρ N_m² / l_m`: the
//! rod radius `b = √(A_m / π)` (3.0 mm for the paper's rod) cancels. `ρ` defaults to
//! [`TERFENOL_RESISTIVITY_OHM_M`] = 6·10⁻⁷ Ω·m (Terfenol-D, manufacturer data sheets: 58-63·10⁻⁸
//! Ω·m); with the paper's `N_m = 1300`, `l_m = 5.13 cm`: `R̄ ≈ 497 Ω`.

pub mod phase_lag;
pub mod record;
pub mod simulate;
pub mod waveform;

use crate::experiments::DynamicExperiment;
use actuator_params::ActuatorParams;
use maglab_signal::spectrum::{harmonic_fit, wrap_lag_rad, HarmonicFit};
use simulate::{core_params, simulate as run, DynamicParams, SimulationOptions};
use std::fmt;
use std::ops::Range;

pub use phase_lag::{Candidate, PhaseLagResult, F0_SCAN_RATIO};
pub use simulate::DYNAMIC_STARTS;

/// Resistivity of Terfenol-D, Ω·m (see the module docs).
pub const TERFENOL_RESISTIVITY_OHM_M: f64 = 6e-7;

/// Progress callback: `(stage, done, total)`; `total = 0` when unknown.
pub type Progress<'a> = dyn Fn(&str, usize, usize) + Sync + 'a;

/// A dynamic identification that cannot proceed (names the file or the reason).
#[derive(Debug, Clone, PartialEq)]
pub struct DynamicError(pub String);

impl fmt::Display for DynamicError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for DynamicError {}

/// Options of [`fit_eddy_and_damping`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DynamicOptions {
    /// How experiments are simulated (initial state, current between samples, substeps).
    pub simulation: SimulationOptions,
    /// Settling: at least this many periods are skipped.
    pub settle_periods: f64,
    /// Settling: at least this many mechanical time constants `1 / (ξ ω0)` are skipped.
    pub settle_time_constants: f64,
    /// Harmonics fitted with the fundamental (DC bias and `M²` distortion, see
    /// [`maglab_signal::spectrum`]).
    pub harmonics: usize,
    /// Resistivity for `R̄`, Ω·m.
    pub resistivity_ohm_m: f64,
    /// Points of the coarse (geometric) grid over `[R̄/500, R̄]`.
    pub coarse_points: usize,
    /// Points of the refined grid between the neighbours of the best coarse point.
    pub fine_points: usize,
    /// `f0` assumed by the phase-lag scheme, Hz (`None`: the base file's).
    pub phase_lag_resonance_hz: Option<f64>,
}

impl Default for DynamicOptions {
    fn default() -> Self {
        DynamicOptions {
            simulation: SimulationOptions::default(),
            settle_periods: 2.0,
            settle_time_constants: 10.0,
            harmonics: 5,
            resistivity_ohm_m: TERFENOL_RESISTIVITY_OHM_M,
            coarse_points: 40,
            fine_points: 21,
            phase_lag_resonance_hz: None,
        }
    }
}

/// Fundamentals of the measured current and displacement over the steady-state window.
#[derive(Debug, Clone, PartialEq)]
pub struct Phasors {
    /// The current's harmonic fit.
    pub current: HarmonicFit,
    /// The displacement's harmonic fit.
    pub displacement: HarmonicFit,
}

impl Phasors {
    /// `θ_{y,I}`: lag of the displacement's fundamental behind the current's, rad.
    pub fn lag_rad(&self) -> f64 {
        wrap_lag_rad(self.current.phase_rad() - self.displacement.phase_rad())
    }
}

/// An experiment ready for the fits.
#[derive(Debug, Clone)]
pub struct PreparedExperiment<'a> {
    /// The experiment.
    pub experiment: &'a DynamicExperiment,
    /// Steady-state window: whole periods after the settling time.
    pub window: Range<usize>,
    /// Measured fundamentals over the window.
    pub phasors: Phasors,
    /// max − min of the measured displacement over the window, m.
    pub displacement_range_m: f64,
}

/// Everything the two methods share.
#[derive(Debug, Clone)]
pub struct Prepared<'a> {
    /// Base parameters (constants and the identified Preisach masses).
    pub base: &'a ActuatorParams,
    /// Base dynamic parameters.
    pub base_dynamic: DynamicParams,
    /// The base's constants in the core's f32 types.
    pub base_actuator: magctl::params::Actuator,
    /// Options.
    pub options: DynamicOptions,
    /// `R̄`, Ω.
    pub r_bar_ohm: f64,
    /// The experiments.
    pub experiments: Vec<PreparedExperiment<'a>>,
}

/// `R̄ = 8πρ N_m² / l_m` (see the module docs), Ω.
pub fn eddy_resistance_upper_bound_ohm(params: &ActuatorParams, resistivity_ohm_m: f64) -> f64 {
    let a = &params.actuator;
    8.0 * std::f64::consts::PI * resistivity_ohm_m * a.coil_turns * a.coil_turns / a.rod_length_m
}

fn file_name(e: &DynamicExperiment) -> String {
    e.measurement.path.display().to_string()
}

/// Windows and measured phasors of every experiment.
pub fn prepare<'a>(
    experiments: &'a [DynamicExperiment],
    base: &'a ActuatorParams,
    options: &DynamicOptions,
) -> Result<Prepared<'a>, DynamicError> {
    if experiments.is_empty() {
        return Err(DynamicError(
            "no dynamic experiments (sinusoidal currents at >= the dynamic threshold): R_eddy, \
             xi and f0 cannot be identified"
                .into(),
        ));
    }
    if experiments.len() < 2 {
        return Err(DynamicError(format!(
            "{} dynamic experiment(s): the phase-lag scheme compares ξ across frequencies and \
             needs at least 2 frequencies",
            experiments.len()
        )));
    }
    let base_dynamic = DynamicParams::of(base);
    let mech_tau_s =
        1.0 / (base_dynamic.damping_ratio * 2.0 * std::f64::consts::PI * base_dynamic.resonance_hz);
    let mut prepared = Vec::new();
    for e in experiments {
        let m = &e.measurement;
        let f = e.frequency_hz;
        let settle_s = (options.settle_periods / f).max(options.settle_time_constants * mech_tau_s);
        let start = (settle_s / m.step_s).ceil() as usize;
        let available_s = m.len().saturating_sub(start) as f64 * m.step_s;
        let periods = (available_s * f).floor();
        if periods < 1.0 {
            return Err(DynamicError(format!(
                "{}: {:.3} s at {f:.3} Hz leaves no whole period after the settling time of \
                 {settle_s:.4} s (max of {} periods and {} mechanical time constants): record \
                 more periods",
                file_name(e),
                m.len() as f64 * m.step_s,
                options.settle_periods,
                options.settle_time_constants
            )));
        }
        let end = (start + (periods / (f * m.step_s)).round() as usize).min(m.len());
        let window = start..end;
        let fit = |signal: &[f64], what: &str| {
            harmonic_fit(signal, m.step_s, f, window.clone(), options.harmonics).ok_or_else(|| {
                DynamicError(format!(
                    "{}: column `{what}`: the steady-state window ({} samples) is too short for \
                     {} harmonics",
                    file_name(e),
                    window.len(),
                    options.harmonics
                ))
            })
        };
        let phasors = Phasors {
            current: fit(&m.current_a, "current_a")?,
            displacement: fit(&m.displacement_m, "displacement_m")?,
        };
        let (lo, hi) = m.displacement_m[window.clone()]
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &y| {
                (a.min(y), b.max(y))
            });
        if hi.partial_cmp(&lo) != Some(std::cmp::Ordering::Greater) {
            return Err(DynamicError(format!(
                "{}: column `displacement_m`: no variation in the steady-state window",
                file_name(e)
            )));
        }
        prepared.push(PreparedExperiment {
            experiment: e,
            window,
            phasors,
            displacement_range_m: hi - lo,
        });
    }
    Ok(Prepared {
        base,
        base_dynamic,
        base_actuator: core_params(base)?.actuator,
        options: *options,
        r_bar_ohm: eddy_resistance_upper_bound_ohm(base, options.resistivity_ohm_m),
        experiments: prepared,
    })
}

/// Per-experiment summary of a fit.
#[derive(Debug, Clone, PartialEq)]
pub struct ExperimentReport {
    /// File.
    pub file: String,
    /// Excitation frequency, Hz.
    pub frequency_hz: f64,
    /// Current: DC bias and fundamental amplitude, A.
    pub current_bias_a: f64,
    /// See `current_bias_a`.
    pub current_amplitude_a: f64,
    /// Steady-state window, samples.
    pub window: Range<usize>,
    /// Measured `θ_{y,I}`, degrees.
    pub measured_lag_deg: f64,
    /// Measured displacement, m.
    pub measured_m: Vec<f64>,
    /// Predicted displacement over the whole record with the phase-lag parameters, m.
    pub predicted_phase_lag_m: Vec<f64>,
    /// Predicted displacement with the refined parameters (nuisances included), m (if refined).
    pub predicted_refined_m: Option<Vec<f64>>,
    /// NRMSE over the window, phase-lag parameters.
    pub nrmse_phase_lag: f64,
    /// NRMSE over the window, refined parameters.
    pub nrmse_refined: Option<f64>,
}

/// The final fit of `(R_eddy, ξ, f0)` with the recording's nuisances (module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct RefinedFit {
    /// The parameters.
    pub params: DynamicParams,
    /// `√(Σ NRMSE_k² / K)` over the experiments' steady-state windows.
    pub rms_nrmse: f64,
    /// Where the current belongs to each displacement sample, in samples after the current's
    /// own sample time, as the fit estimated it (channel skew and the current between samples):
    /// what [`crate::masses::MassOptions::current_shift_samples`] takes.
    pub current_read_shift_samples: f64,
    /// How it was made and what it estimated, for the provenance.
    pub details: serde_json::Value,
}

/// Both methods' results.
#[derive(Debug, Clone, PartialEq)]
pub struct DynamicFit {
    /// The paper's scheme.
    pub phase_lag: PhaseLagResult,
    /// Its parameters: `(R_eddy, mean ξ, f0 assumed)`.
    pub phase_lag_params: DynamicParams,
    /// The final fit (if the caller made one).
    pub refined: Option<RefinedFit>,
    /// Per experiment.
    pub experiments: Vec<ExperimentReport>,
    /// Options used.
    pub options: DynamicOptions,
}

impl DynamicFit {
    /// The parameters to write: the refined fit's if there is one, else the phase-lag scheme's.
    pub fn best(&self) -> DynamicParams {
        self.refined
            .as_ref()
            .map_or(self.phase_lag_params, |w| w.params)
    }

    /// Records the refined fit and its predictions (`(file, displacement)`, as
    /// [`ExperimentReport::file`] names them); fills each report's refined NRMSE over its window.
    pub fn attach_refined(&mut self, refined: RefinedFit, predictions: &[(String, Vec<f64>)]) {
        let mut sum = 0.0;
        for r in self.experiments.iter_mut() {
            if let Some((_, p)) = predictions.iter().find(|(f, _)| *f == r.file) {
                let n = r.window.len().max(1) as f64;
                let y = &r.measured_m;
                let (lo, hi) = r
                    .window
                    .clone()
                    .fold((f64::MAX, f64::MIN), |(a, b), k| (a.min(y[k]), b.max(y[k])));
                let e = (r.window.clone().map(|k| (p[k] - y[k]).powi(2)).sum::<f64>() / n).sqrt()
                    / (hi - lo).max(1e-300);
                sum += e * e;
                r.nrmse_refined = Some(e);
                r.predicted_refined_m = Some(p.clone());
            }
        }
        let k = self.experiments.len().max(1) as f64;
        self.refined = Some(RefinedFit {
            rms_nrmse: (sum / k).sqrt(),
            ..refined
        });
    }
}

fn nrmse_window(pred: &[f64], e: &PreparedExperiment<'_>) -> f64 {
    let y = &e.experiment.measurement.displacement_m;
    let n = e.window.len() as f64;
    (e.window
        .clone()
        .map(|k| (pred[k] - y[k]) * (pred[k] - y[k]))
        .sum::<f64>()
        / n)
        .sqrt()
        / e.displacement_range_m
}

/// Identifies `R_eddy`, `ξ` by the phase-lag scheme from `experiments`, with the Preisach masses
/// and constants of `base` (normally the parameters the quasi-static identification just
/// produced); the caller may then attach a refined fit ([`DynamicFit::attach_refined`]).
/// `progress` is called from worker threads.
pub fn fit_eddy_and_damping(
    experiments: &[DynamicExperiment],
    base: &ActuatorParams,
    options: &DynamicOptions,
    progress: &Progress<'_>,
) -> Result<DynamicFit, DynamicError> {
    let prepared = prepare(experiments, base, options)?;
    let measure = core_params(base)?.preisach.measure();
    // An f0 given by the user stands (the scheme's error included); the file's f0 is scanned
    // around when the measured lags cannot be met with it.
    let phase_lag = match options.phase_lag_resonance_hz {
        Some(f0) => phase_lag::phase_lag_scheme(&measure, &prepared, f0, progress)?,
        None => phase_lag::phase_lag_scheme_scanning_f0(
            &measure,
            &prepared,
            base.actuator.resonance_hz,
            progress,
        )?,
    };
    let phase_lag_params = DynamicParams {
        eddy_resistance_ohm: phase_lag.chosen.eddy_resistance_ohm,
        damping_ratio: phase_lag.chosen.weighted_mean,
        resonance_hz: phase_lag.resonance_hz,
    };
    let reports = prepared
        .experiments
        .iter()
        .map(|e| {
            let m = &e.experiment.measurement;
            let pl = run(
                &measure,
                &prepared.base_actuator,
                &phase_lag_params,
                m,
                &options.simulation,
            )
            .displacement_m;
            ExperimentReport {
                file: file_name(e.experiment),
                frequency_hz: e.experiment.frequency_hz,
                current_bias_a: e.phasors.current.mean,
                current_amplitude_a: e.phasors.current.amplitude(),
                window: e.window.clone(),
                measured_lag_deg: e.phasors.lag_rad().to_degrees(),
                measured_m: m.displacement_m.clone(),
                nrmse_phase_lag: nrmse_window(&pl, e),
                nrmse_refined: None,
                predicted_phase_lag_m: pl,
                predicted_refined_m: None,
            }
        })
        .collect();
    Ok(DynamicFit {
        phase_lag,
        phase_lag_params,
        refined: None,
        experiments: reports,
        options: *options,
    })
}
