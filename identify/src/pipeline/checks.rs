//! Step 4 of the identification: does the identified model describe the data it came from?
//! ([`crate::quality`] and [`crate::drift`] hold the checks and their limits.)

use super::dynamic::fit_constants;
use super::passes::constants_of;
use crate::dynamics::DynamicFit;
use crate::masses::MassIdentification;
use crate::quality::{self, DynamicResidual};
use actuator_params::ActuatorParams;
use maglab_dataset::data::Dataset;
use maglab_model::candidates::IDENTIFICATION_RANGE;
use std::path::Path;

/// The final fit's residual per dynamic experiment, as the checks read it.
fn dynamic_residuals(fit: &DynamicFit) -> Vec<DynamicResidual> {
    fit.experiments
        .iter()
        .filter_map(|e| {
            e.nrmse_refined.map(|nrmse| DynamicResidual {
                file: Path::new(&e.file)
                    .file_name()
                    .map_or_else(|| e.file.clone(), |n| n.to_string_lossy().into_owned()),
                frequency_hz: e.frequency_hz,
                nrmse,
            })
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
///   friction) rather than the shape of the loop ([`crate::drift::drift_warning`]).
pub fn warnings(
    masses: &MassIdentification,
    dynamic: Option<&DynamicFit>,
    base: &ActuatorParams,
    quasi_static: &Dataset,
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
        let name = m.path.file_name().map_or_else(
            || m.path.display().to_string(),
            |n| n.to_string_lossy().into_owned(),
        );
        warnings.extend(crate::drift::drift_warning(
            &name,
            &m.t_s,
            &m.current_a,
            &m.displacement_m,
        ));
    }
    warnings
}
