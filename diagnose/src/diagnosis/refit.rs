//! How far the refit may move the parameter file's dynamic constants (step 6): narrow for
//! constants the file gives, wide for those its provenance lists as identified from data.

use super::rules::IDENTIFIED_REFIT_RANGE;
use actuator_params::Provenance;
use serde::Serialize;

/// How far the refit may move each of `R_eddy`, `ξ`, `f0`, and why (in `diagnosis.json`).
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct ConstantsRange {
    /// Factors for `R_eddy`, `ξ`, `f0` (the refit stays within value ×/÷ factor).
    pub factors: [f64; 3],
    /// The constants the parameter file's provenance lists as identified from data.
    pub identified_from_data: Vec<String>,
    /// Why these factors, in words.
    pub reason: String,
}

/// The refit range for `params`: `base` (the options' range, normally
/// `maglab_model::candidates::REFIT_RANGE`) for constants given by the file, widened to
/// [`IDENTIFIED_REFIT_RANGE`] for each constant its provenance lists under `identified` (the
/// list `maglab identify` writes).
pub fn constants_range(params: &actuator_params::ActuatorParams, base: [f64; 3]) -> ConstantsRange {
    let listed: Vec<String> = params
        .provenance
        .identified_fields()
        .into_iter()
        .filter(|f| Provenance::DYNAMIC_FIELDS.contains(f))
        .map(String::from)
        .collect();
    let mut factors = base;
    for (i, field) in Provenance::DYNAMIC_FIELDS.iter().enumerate() {
        if listed.iter().any(|f| f == field) {
            factors[i] = factors[i].max(IDENTIFIED_REFIT_RANGE[i]);
        }
    }
    let band = params
        .provenance
        .details
        .get("dynamics")
        .and_then(|d| d.pointer("/refined_fit/details/fitted_up_to_hz"))
        .and_then(serde_json::Value::as_f64)
        .map_or_else(String::new, |hz| {
            format!(" on the experiments up to {hz:.0} Hz")
        });
    let reason = if listed.is_empty() {
        format!(
            "the parameter file's constants are taken as known to within an identification's \
             error: R_eddy x/ {}, xi x/ {}, f0 x/ {}",
            factors[0], factors[1], factors[2]
        )
    } else {
        format!(
            "{} identified from data{band} (provenance.identified), where an effect in the data \
             is absorbed into them: the refit may move R_eddy x/ {}, xi x/ {}, f0 x/ {}",
            listed.join(", "),
            factors[0],
            factors[1],
            factors[2]
        )
    };
    ConstantsRange {
        factors,
        identified_from_data: listed,
        reason,
    }
}
