//! Step 4 of the identification: does the identified model describe the data it came from?
//! ([`crate::quality`] and [`maglab_model::drift`] hold the checks and their limits.)

use super::dynamic::fit_constants;
use super::passes::constants_of;
use crate::coverage;
use crate::dynamics::DynamicFit;
use crate::experiments::DynamicExperiment;
use crate::masses::MassIdentification;
use crate::quality::{self, DynamicResidual};
use actuator_params::ActuatorParams;
use maglab_dataset::data::Dataset;
use maglab_model::candidates::IDENTIFICATION_RANGE;
use maglab_model::residual::systematic;
use std::path::Path;

/// The final fit's residual per dynamic experiment, as the checks read it.
fn dynamic_residuals(fit: &DynamicFit) -> Vec<DynamicResidual> {
    fit.experiments
        .iter()
        .filter_map(|e| {
            e.nrmse_refined.map(|nrmse| DynamicResidual {
                file: file_name(Path::new(&e.file)),
                frequency_hz: e.frequency_hz,
                nrmse,
            })
        })
        .collect()
}

/// Per dynamic experiment (file name), the refined fit's NRMSE over its window with the noise
/// taken out: `√max(0, rms² − σ²) / range`, σ the fit's white-noise estimate. A small loop's
/// range is small, so its plain NRMSE carries the noise at full weight.
fn systematic_nrmse(fit: &DynamicFit) -> Vec<(String, f64)> {
    let noise_m = fit
        .refined
        .as_ref()
        .and_then(|r| r.details.get("noise_m"))
        .and_then(serde_json::Value::as_f64)
        .unwrap_or(0.0);
    fit.experiments
        .iter()
        .filter_map(|e| {
            let nrmse = e.nrmse_refined?;
            let y = &e.measured_m;
            let (lo, hi) = e
                .window
                .clone()
                .fold((f64::MAX, f64::MIN), |(a, b), k| (a.min(y[k]), b.max(y[k])));
            let range_m = (hi - lo).max(1e-300);
            let systematic_m = systematic(nrmse * range_m, noise_m);
            Some((file_name(Path::new(&e.file)), systematic_m / range_m))
        })
        .collect()
}

/// Every warning for the identification `masses` (with `dynamic`, its dynamic fit) of the
/// quasi-static records `quasi_static`, from `base`:
/// * the model's residuals on the records and the sines, and the sum of the masses
///   ([`quality::warnings`]);
/// * a constant the fit left at an end of its search: it has absorbed something, or the base
///   file is far off ([`quality::search_bound_warnings`]);
/// * a quasi-static record whose returns to the same extreme read differently: time (or
///   friction) rather than the shape of the loop ([`maglab_model::drift::drift_warning`]);
/// * dynamic records (`dynamic_records`) whose loops no quasi-static record reverses at
///   ([`crate::coverage`]).
pub fn warnings(
    masses: &MassIdentification,
    dynamic: Option<&DynamicFit>,
    base: &ActuatorParams,
    quasi_static: &Dataset,
    dynamic_records: &[DynamicExperiment],
) -> Vec<String> {
    let residuals: Vec<DynamicResidual> = dynamic.map(dynamic_residuals).unwrap_or_default();
    let fitted_up_to_hz = dynamic
        .and_then(|fit| fit.refined.as_ref())
        .and_then(|r| r.details.get("fitted_up_to_hz"))
        .and_then(serde_json::Value::as_f64);
    let sum_a_per_m = masses.fit.weights.iter().sum();
    let mass_check = if masses.params.preisach.reach_a_per_m.is_some() {
        quality::Masses::Reach {
            sum_a_per_m,
            offset_a_per_m: masses.params.preisach.offset_a_per_m,
        }
    } else {
        quality::Masses::Saturating { sum_a_per_m }
    };
    let mut warnings = quality::warnings(
        &masses.files,
        mass_check,
        masses.params.actuator.saturation_magnetization_a_per_m,
        &residuals,
        fitted_up_to_hz,
    );
    if let Some(fit) = dynamic {
        warnings.extend(quality::search_bound_warnings(
            fit_constants(fit),
            constants_of(base),
            IDENTIFICATION_RANGE,
        ));
    }
    for m in &quasi_static.measurements {
        warnings.extend(maglab_model::drift::drift_warning(
            &file_name(&m.path),
            &m.t_s,
            &m.current_a,
            &m.displacement_m,
        ));
    }
    let dynamic_currents: Vec<(String, f64, &[f64])> = dynamic_records
        .iter()
        .map(|d| {
            (
                file_name(&d.measurement.path),
                d.frequency_hz,
                d.measurement.current_a.as_slice(),
            )
        })
        .collect();
    let uncovered = coverage::measured_loops(quasi_static, dynamic_records)
        .map_or_else(Vec::new, |measured| {
            coverage::uncovered_loops(&measured, &dynamic_currents)
        });
    let systematic = dynamic.map(systematic_nrmse).unwrap_or_default();
    let nrmse_of = |file: &str| systematic.iter().find(|(f, _)| f == file).map(|(_, e)| *e);
    warnings.extend(coverage::coverage_warning(
        &uncovered,
        nrmse_of,
        quality::QUASI_STATIC_NRMSE_LIMIT,
        dynamic_records.len(),
    ));
    warnings
}

/// The file name of `path` (the whole path when it has none).
fn file_name(path: &Path) -> String {
    path.file_name().map_or_else(
        || path.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    )
}
