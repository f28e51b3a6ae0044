//! Were the parameter file's masses measured where this dataset's loops run?
//!
//! A file whose Preisach masses `maglab identify` fitted records the reversals of the
//! quasi-static records they came from (`maglab_model::coverage::MeasuredLoops`). A dynamic
//! loop none of them reverses at (within one cell of both ends) is predicted by the fit's
//! smoothness alone: a gap there may be the masses', not an effect's, and no candidate of the
//! library models it. On rods whose coercivities lie within a few cells of the diagonal that
//! static misfit reaches several times the noise at every frequency (docs/model.md, "Not on
//! every design"). The diagnosis does not change its verdict for it — the data may still hold
//! an effect — but says so next to the verdict and advises the recording that measures those
//! masses ([`super::advice::Recording::MeasuredLoops`]).
//!
//! A file without that record (the analytic default, a nominal file from a datasheet or
//! another tool, or one identified before the record existed) is taken as it is: its measure
//! is given, not measured.

use maglab_dataset::data::Measurement;
use maglab_model::coverage::{uncovered_loops, MeasuredLoops};
use maglab_model::experiments::ExperimentInfo;
use serde::Serialize;

/// A dynamic loop of the dataset that the file's masses were not measured on.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct UnmeasuredLoop {
    /// The record.
    pub file: String,
    /// Its lower reversal current, A.
    pub lo_a: f64,
    /// Its upper reversal current, A.
    pub hi_a: f64,
    /// Its fundamental, Hz.
    pub frequency_hz: f64,
}

impl UnmeasuredLoop {
    /// `(bias, amplitude)`, A.
    pub fn bias_and_amplitude_a(&self) -> (f64, f64) {
        (0.5 * (self.hi_a + self.lo_a), 0.5 * (self.hi_a - self.lo_a))
    }
}

/// The dynamic loops of `measurements` (their `infos`) that `params`' masses were not measured
/// on; empty when the file does not record where they were; an error naming the field when
/// that record is malformed.
pub fn unmeasured_loops(
    params: &actuator_params::ActuatorParams,
    measurements: &[Measurement],
    infos: &[ExperimentInfo],
) -> Result<Vec<UnmeasuredLoop>, String> {
    let Some(measured) = MeasuredLoops::from_provenance(&params.provenance) else {
        return Ok(Vec::new());
    };
    let measured = measured.map_err(|e| format!("parameter file: {e}"))?;
    let dynamic: Vec<(String, f64, &[f64])> = measurements
        .iter()
        .zip(infos)
        .filter(|(_, info)| !info.quasi_static)
        .map(|(m, info)| {
            (
                info.name.clone(),
                info.fundamental_hz,
                m.current_a.as_slice(),
            )
        })
        .collect();
    Ok(uncovered_loops(&measured, &dynamic)
        .into_iter()
        .map(|u| UnmeasuredLoop {
            file: u.file,
            lo_a: u.lo_a,
            hi_a: u.hi_a,
            frequency_hz: u.frequency_hz,
        })
        .collect())
}

/// The warning for `loops` out of `dynamic_count` dynamic records (`None` when there are none).
pub fn warning(loops: &[UnmeasuredLoop], dynamic_count: usize) -> Option<String> {
    let first = loops.first()?;
    let mut ranges: Vec<(f64, f64)> = Vec::new();
    for l in loops {
        if !ranges
            .iter()
            .any(|(lo, hi)| (lo - l.lo_a).abs() < 1e-3 && (hi - l.hi_a).abs() < 1e-3)
        {
            ranges.push((l.lo_a, l.hi_a));
        }
    }
    let listed: Vec<String> = ranges
        .iter()
        .take(4)
        .map(|(lo, hi)| format!("{lo:.3}-{hi:.3} A"))
        .collect();
    Some(format!(
        "the parameter file's masses were not measured on {} of {dynamic_count} dynamic records' \
         loops ({}{}, e.g. {}): no quasi-static record of its identification reversed within one \
         grid cell of their ends, so the model predicts them by the fit's smoothness alone and \
         part of any gap there may be the masses', not an effect; record quasi-static loops \
         between the same currents and identify again",
        loops.len(),
        listed.join(", "),
        if ranges.len() > listed.len() {
            ", ..."
        } else {
            ""
        },
        first.file
    ))
}
