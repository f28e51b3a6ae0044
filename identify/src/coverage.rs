//! The identification's coverage check: do the quasi-static records reverse where the dynamic
//! ones do? (`maglab_model::coverage` says which loops the masses were measured on.)
//!
//! When a dynamic loop is not covered, the masses of the cells it switches are fitted only
//! through long reversal branches; the smallest dynamic loops are then the worst-fitted ones
//! at every frequency, and the dynamic fit bends `R_eddy` and `ξ` to make up for what the
//! masses miss (docs/model.md, "Not on every design"). An uncovered loop is warned about only
//! when the identified model misses it by more than the quasi-static records' own NRMSE limit:
//! many rods' masses are smooth enough that the long branches determine them.

pub use maglab_model::coverage::{
    same_loop, turning_points, uncovered_loops, MeasuredLoops, UncoveredLoop,
};

use crate::experiments::DynamicExperiment;
use maglab_dataset::data::Dataset;

/// The loops the masses of `quasi_static` are measured on, on the grid cell of the whole
/// dataset's current range (the quasi-static and the `dynamic` records: the field the data
/// reach, [`crate::reach`]); `None` without a range.
pub fn measured_loops(
    quasi_static: &Dataset,
    dynamic: &[DynamicExperiment],
) -> Option<MeasuredLoops> {
    let records: Vec<&[f64]> = quasi_static
        .measurements
        .iter()
        .map(|m| m.current_a.as_slice())
        .collect();
    let cell_a = maglab_model::coverage::cell_of_currents(
        records
            .iter()
            .copied()
            .chain(dynamic.iter().map(|d| d.measurement.current_a.as_slice())),
    )?;
    Some(MeasuredLoops::of_records(&records, cell_a))
}

/// The warning for the dynamic loops no quasi-static record covers that the identified model
/// also misses by more than `limit` (NRMSE with the noise taken out, `nrmse_of` a file's) at
/// the lowest frequency the
/// data drive that loop at, or `None`. There the loop is closest to quasi-static, so `limit` is
/// the quasi-static records' own; at higher frequencies the misfit is the dynamics' as well. An
/// uncovered loop the model fits is no concern: the rod's masses are smooth enough there.
pub fn coverage_warning(
    uncovered: &[UncoveredLoop],
    nrmse_of: impl Fn(&str) -> Option<f64>,
    limit: f64,
    dynamic_count: usize,
) -> Option<String> {
    let slowest = |u: &UncoveredLoop| {
        !uncovered
            .iter()
            .any(|v| same_loop(u, v) && v.frequency_hz < u.frequency_hz)
    };
    let missed: Vec<(&UncoveredLoop, f64)> = uncovered
        .iter()
        .filter(|u| slowest(u))
        .filter_map(|u| nrmse_of(&u.file).filter(|e| *e > limit).map(|e| (u, e)))
        .collect();
    let (worst, nrmse) = missed.iter().max_by(|a, b| a.1.total_cmp(&b.1))?;
    Some(format!(
        "{} of {dynamic_count} dynamic records make loops that no quasi-static record reverses at \
         (within one grid cell) and the model misses by more than the quasi-static limit of \
         {:.0} % at the slowest frequency they are driven at, the worst {} between {:.3} and \
         {:.3} A at {:.1} %: the masses of the cells \
         such loops switch are fitted only through long reversal branches, and R_eddy, xi, f0 \
         absorb what they miss (docs/model.md); record slow loops (<= 1 Hz) between the same \
         currents and identify again",
        missed.len(),
        100.0 * limit,
        worst.file,
        worst.lo_a,
        worst.hi_a,
        100.0 * nrmse
    ))
}
