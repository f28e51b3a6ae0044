//! Writes a dynamic identification into a parameter file: the values of the refined fit (or of
//! the phase-lag scheme when the fit was not run), and a provenance section with both methods'
//! results side by side, their residuals, the options and every file's classification.

use super::DynamicFit;
use crate::experiments::{Rule, SplitDataset};
use actuator_params::{ActuatorParams, Provenance};
use serde_json::json;

/// Sets `R_eddy`, `ξ`, `f0` of `params` from `fit` and records how in `params.provenance`
/// (`dynamics`, `dataset_classification`; the three fields move from `not_identified` to
/// `identified`, and `not_identified` is removed when it becomes empty).
pub fn record(params: &mut ActuatorParams, fit: &DynamicFit, split: &SplitDataset) {
    let best = fit.best();
    params.actuator.eddy_resistance_ohm = best.eddy_resistance_ohm;
    params.actuator.damping_ratio = best.damping_ratio;
    params.actuator.resonance_hz = best.resonance_hz;
    let mut identified: Vec<String> = params
        .provenance
        .identified_fields()
        .into_iter()
        .map(String::from)
        .collect();
    let written: &[&str] = if fit.refined.is_some() {
        &Provenance::DYNAMIC_FIELDS
    } else {
        &Provenance::DYNAMIC_FIELDS[..2]
    };
    for f in written {
        if !identified.iter().any(|v| v == f) {
            identified.push(f.to_string());
        }
    }
    let d = &mut params.provenance.details;
    d.insert(Provenance::IDENTIFIED.into(), json!(identified));
    if fit.refined.is_some() {
        d.remove("not_identified");
    } else {
        d.insert(
            "not_identified".into(),
            json!({
                "fields": ["actuator.resonance_hz"],
                "values": { "resonance_hz": best.resonance_hz },
                "reason": "no refined fit was made; the phase-lag scheme assumes f0",
            }),
        );
    }
    let pl = &fit.phase_lag;
    let o = &fit.options;
    d.insert(
        "dynamics".into(),
        json!({
            "written": if fit.refined.is_some() { "refined_fit" } else { "phase_lag" },
            "phase_lag": {
                "method": "paper Section 4: theta_yI measured, theta_M2I simulated with (4) for each \
                           candidate R_eddy, xi_k = tan(theta) (1 - r^2) / (2 r); R_eddy = least \
                           (dtheta/dxi)^2-weighted spread of xi_k (RMS phase misfit), xi = weighted mean",
                "eddy_resistance_ohm": pl.chosen.eddy_resistance_ohm,
                "damping_ratio": pl.chosen.weighted_mean,
                "damping_ratio_plain_mean": pl.chosen.mean,
                "resonance_hz_assumed": pl.resonance_hz,
                "phase_misfit_deg": pl.chosen.phase_misfit_rad.to_degrees(),
                "damping_ratios_per_experiment": pl.chosen.damping_ratios,
                "least_variance_candidate_ohm": pl.least_variance_ohm,
                "least_coefficient_of_variation_candidate_ohm": pl.least_cv_ohm,
                "r_bar_ohm": pl.r_bar_ohm,
                "resistivity_ohm_m": o.resistivity_ohm_m,
                "grid": {"coarse_points": o.coarse_points, "fine_points": o.fine_points,
                         "coarse_range_ohm": [pl.coarse.first().map(|c| c.eddy_resistance_ohm),
                                              pl.coarse.last().map(|c| c.eddy_resistance_ohm)]},
                "nrmse_per_experiment": fit.experiments.iter().map(|e| e.nrmse_phase_lag).collect::<Vec<_>>(),
            },
            "refined_fit": fit.refined.as_ref().map(|w| json!({
                "eddy_resistance_ohm": w.params.eddy_resistance_ohm,
                "damping_ratio": w.params.damping_ratio,
                "resonance_hz": w.params.resonance_hz,
                "rms_nrmse": w.rms_nrmse,
                "nrmse_per_experiment": fit.experiments.iter().map(|e| e.nrmse_refined).collect::<Vec<_>>(),
                "details": w.details,
            })),
            "experiments": fit.experiments.iter().map(|e| json!({
                "file": e.file,
                "frequency_hz": e.frequency_hz,
                "current_bias_a": e.current_bias_a,
                "current_amplitude_a": e.current_amplitude_a,
                "steady_state_window": [e.window.start, e.window.end],
                "measured_lag_deg": e.measured_lag_deg,
            })).collect::<Vec<_>>(),
            "simulation": {
                "model": "magctl::model::DynamicModel (core f32), substeps of at most max_substep_s",
                "start": o.simulation.start.name(),
                "current_between_samples": o.simulation.current.name(),
                "max_substep_s": o.simulation.max_substep_s,
                "settle_periods": o.settle_periods,
                "settle_time_constants": o.settle_time_constants,
                "harmonics": o.harmonics,
            },
        }),
    );
    d.insert(
        "dataset_classification".into(),
        json!(split
            .classification
            .iter()
            .map(|c| json!({
                "file": c.path.display().to_string(),
                "kind": c.kind.name(),
                "rule": match c.rule { Rule::Folder => "sub-folder", Rule::Spectrum => "spectrum" },
                "reason": c.reason,
            }))
            .collect::<Vec<_>>()),
    );
    params.provenance.source = if fit.refined.is_some() {
        "maglab identify (Preisach masses, R_eddy, xi, f0 identified)".into()
    } else {
        "maglab identify (Preisach masses, R_eddy, xi identified; f0 assumed)".into()
    };
}
