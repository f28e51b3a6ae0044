//! Step 2 of the identification: `R_eddy`, `ξ` by the paper's phase-lag scheme, then `R_eddy`,
//! `ξ`, `f0` by the waveform fit with the recording's nuisances ([`crate::dynamics::waveform`]),
//! on one set of masses.

use super::{IdentifyError, IdentifyOptions, RecordedDataset};
use crate::dynamics::simulate::DynamicParams;
use crate::dynamics::waveform::{identify_dynamics, IdentificationOptions};
use crate::dynamics::{fit_eddy_and_damping, DynamicFit, Progress, RefinedFit};
use actuator_params::ActuatorParams;
use maglab_dataset::data::Measurement;

/// The dynamic step with the dataset and the options fixed: each pass of the alternation runs
/// it on its own masses.
pub struct DynamicStage<'a> {
    /// The dataset.
    pub dataset: &'a RecordedDataset,
    /// The identification's settings.
    pub options: &'a IdentifyOptions,
    /// The phase-lag scheme's progress.
    pub progress: &'a Progress<'a>,
}

impl DynamicStage<'_> {
    /// The phase-lag scheme on `params` (its masses and constants), then, with the waveform fit
    /// on, the final fit: its search is centred on `params`' `R_eddy`, `ξ`, `f0` and starts
    /// there, at the phase-lag scheme's result and at `also_from` when given (the best start by
    /// cost is refined).
    pub fn fit(
        &self,
        params: &ActuatorParams,
        also_from: Option<[f64; 3]>,
    ) -> Result<DynamicFit, IdentifyError> {
        let o = &self.options.dynamics;
        if !(o.simulation.max_substep_s > 0.0 && o.resistivity_ohm_m > 0.0) {
            return Err(IdentifyError::Dataset(format!(
                "the phase-lag scheme's longest model step ({} s) and the rod's resistivity ({} \
                 ohm m) must be > 0",
                o.simulation.max_substep_s, o.resistivity_ohm_m
            )));
        }
        let mut fit = fit_eddy_and_damping(self.dataset.dynamic_input(), params, o, self.progress)
            .map_err(|e| IdentifyError::step("phase-lag scheme", e))?;
        if self.options.waveform_fit {
            self.refine(&mut fit, params, also_from)?;
        }
        Ok(fit)
    }

    /// The final fit, attached to `fit`.
    fn refine(
        &self,
        fit: &mut DynamicFit,
        params: &ActuatorParams,
        also_from: Option<[f64; 3]>,
    ) -> Result<(), IdentifyError> {
        let split = &self.dataset.split;
        // Recording order (file-name order): an experiment recorded without a reset continues
        // the one before it. The split sorts the dynamic experiments by frequency.
        let mut measurements: Vec<Measurement> = self
            .dataset
            .dynamic_input()
            .iter()
            .map(|d| d.measurement.clone())
            .collect();
        measurements.sort_by(|a, b| a.path.cmp(&b.path));
        let lead_in = lead_in(&split.quasi_static, &measurements);
        let pl = fit.phase_lag_params;
        let starts: Vec<[f64; 3]> =
            std::iter::once([pl.eddy_resistance_ohm, pl.damping_ratio, pl.resonance_hz])
                .chain(also_from)
                .collect();
        let id = identify_dynamics(
            params,
            &measurements,
            lead_in,
            self.dataset.documented.as_ref(),
            &starts,
            &IdentificationOptions {
                substeps: self.options.substeps,
                measured_current_input: self.dataset.measured_current_input(),
                ..IdentificationOptions::default()
            },
        )
        .map_err(|e| IdentifyError::step("final fit of R_eddy, xi, f0", e))?;
        // The predictions by the report's file names (the paths as the split read them).
        let predictions: Vec<(String, Vec<f64>)> = id
            .predictions
            .iter()
            .map(|(file, y)| {
                let path = measurements
                    .iter()
                    .find(|m| {
                        m.path
                            .file_name()
                            .is_some_and(|n| n.to_string_lossy() == file.as_str())
                    })
                    .map_or_else(|| file.clone(), |m| m.path.display().to_string());
                (path, y.clone())
            })
            .collect();
        let details = serde_json::json!({
            "method": "Levenberg-Marquardt on the displacement of every dynamic experiment with the \
                       model of maglab diagnose (core Preisach operator, backward-Euler eddy step with \
                       Richardson extrapolation, f64 mechanics), started from the base file's values, the \
                       phase-lag result and, after the alternation's second pass, the pass before's \
                       (the best), within the search around the base file's values, \
                       fitted on the experiments up to fitted_up_to_hz (the higher ones are \
                       predicted: unmodelled dynamics grow with frequency), with `substeps` \
                       electromagnetic substeps per sample (given, or enough that one spans at most \
                       1/200 of the period of fitted_up_to_hz)",
            "estimated": {
                "current_between_samples": id.current_between_samples,
                "channel_skew_samples": id.channel_skew_samples,
                "sensor_offset_m": id.sensor_offset_m,
                "start_state_of_undocumented_experiments": id.start_state,
                "documented_start_states": id.documented_starts,
            },
            "rms_residual_m": id.rms_m,
            "noise_m": id.noise_m,
            "systematic_residual_m": id.systematic_m,
            "model_evaluations": id.evaluations,
            "fitted_up_to_hz": id.fitted_up_to_hz,
            "instruments_fitted_with_the_rod": id
                .instruments
                .iter()
                .map(|(name, v)| (name.clone(), serde_json::json!(v)))
                .collect::<serde_json::Map<_, _>>(),
            "substeps": id.substeps,
        });
        fit.attach_refined(
            RefinedFit {
                params: DynamicParams {
                    eddy_resistance_ohm: id.eddy_resistance_ohm,
                    damping_ratio: id.damping_ratio,
                    resonance_hz: id.resonance_hz,
                },
                rms_nrmse: 0.0,
                current_read_shift_samples: id
                    .current_read_shift_samples(measurements.first().map_or(1.0, |m| m.step_s)),
                details,
            },
            &predictions,
        );
        Ok(())
    }
}

/// The quasi-static record recorded right before the first dynamic one (in the same folder, the
/// last whose file name sorts before it), if any: the memory it leaves is where a chain of
/// dynamic experiments recorded without a reset starts.
fn lead_in<'a>(
    quasi_static: &'a [Measurement],
    dynamic_in_order: &[Measurement],
) -> Option<&'a Measurement> {
    let first = dynamic_in_order.first()?;
    quasi_static
        .iter()
        .filter(|q| q.path.parent() == first.path.parent() && q.path < first.path)
        .max_by(|a, b| a.path.cmp(&b.path))
}

/// Where the current is read for each displacement sample, in samples after its own sample
/// time (`MassOptions::current_shift_samples`), as the final dynamic fit of `fit` estimated
/// it; 0 without a final fit.
pub fn current_shift_samples(fit: &DynamicFit) -> f64 {
    fit.refined
        .as_ref()
        .map_or(0.0, |r| r.current_read_shift_samples)
}

/// `[R_eddy, ξ, f0]` the sines gave.
pub fn fit_constants(fit: &DynamicFit) -> [f64; 3] {
    let best = fit.best();
    [
        best.eddy_resistance_ohm,
        best.damping_ratio,
        best.resonance_hz,
    ]
}

/// RMS NRMSE of the final fit on the sines (infinite without one).
pub fn rms_nrmse(fit: &DynamicFit) -> f64 {
    fit.refined.as_ref().map_or(f64::INFINITY, |r| r.rms_nrmse)
}
