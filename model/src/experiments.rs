//! The experiments of a recorded dataset as the model sees them: each record's fundamental,
//! amplitude, bias and settling, which records are quasi-static, and the nominal constants with
//! the fields only the data give (the operating field, the slowest excitation).

use crate::fit::ExperimentData;
use crate::model::{ModelStart, Nominal};
use maglab_dataset::data::Measurement;
use maglab_signal::spectrum;
use serde::Serialize;

/// Records with a fundamental below this are quasi-static (step 1), Hz.
pub const QUASI_STATIC_BELOW_HZ: f64 = 5.0;

/// Excitation properties read from the current of one experiment.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct ExperimentInfo {
    /// File name.
    pub name: String,
    /// Fundamental (dominant) frequency of the current, Hz.
    pub fundamental_hz: f64,
    /// Half the peak-to-peak current after `settle_samples`, A.
    pub amplitude_a: f64,
    /// Mean current after `settle_samples`, A.
    pub bias_a: f64,
    /// Samples before scoring starts.
    pub settle_samples: usize,
    /// Quasi-static (in the "where" breakdown only).
    pub quasi_static: bool,
    /// Held out (`true`) or training.
    pub held_out: bool,
    /// Frequency group index (sorted by frequency).
    pub frequency_group: usize,
    /// Start state used for this experiment.
    pub start_state: String,
    /// `documented` (dataset.json) or `estimated`.
    pub start_state_source: String,
}

/// The parameter file's nominal constants with the fields read from the data filled in: the
/// operating field `c0 max |I|` and the slowest dynamic (not quasi-static) excitation's period.
/// The diagnosis and `maglab identify`'s dynamic fit both start here.
pub fn nominal_for_data(
    params: &actuator_params::ActuatorParams,
    measurements: &[Measurement],
    infos: &[ExperimentInfo],
) -> Nominal {
    let mut nominal = Nominal::from_params(params);
    nominal.operating_field_a_per_m = nominal.c0_per_m
        * measurements
            .iter()
            .flat_map(|m| m.current_a.iter())
            .fold(0.0f64, |a, &i| a.max(i.abs()));
    if let Some(slowest_hz) = infos
        .iter()
        .filter(|i| !i.quasi_static)
        .map(|i| i.fundamental_hz)
        .min_by(f64::total_cmp)
    {
        nominal.slowest_period_s = 1.0 / slowest_hz;
    }
    nominal
}

/// The indices of the dynamic experiments: those with a fundamental of at least
/// [`QUASI_STATIC_BELOW_HZ`], the ones R_eddy, ξ, f0 show in.
pub fn dynamic_indices(infos: &[ExperimentInfo]) -> Vec<usize> {
    (0..infos.len())
        .filter(|&k| !infos[k].quasi_static)
        .collect()
}

/// Peak-to-peak displacement over the records `which`, m.
pub fn displacement_range(measurements: &[Measurement], which: &[usize]) -> f64 {
    let (lo, hi) = which
        .iter()
        .flat_map(|&k| measurements[k].displacement_m.iter())
        .fold((f64::MAX, f64::MIN), |(lo, hi), &v| (lo.min(v), hi.max(v)));
    (hi - lo).max(0.0)
}

/// Fundamental, settling, and the amplitude and bias after settling, of each record.
pub fn describe(measurements: &[Measurement], rate_hz: f64) -> Vec<ExperimentInfo> {
    measurements
        .iter()
        .map(|m| {
            let n = m.len();
            let f = spectrum::dominant_frequency_hz(&m.current_a, rate_hz)
                .unwrap_or(rate_hz / n as f64);
            let settle = ((rate_hz / f).max(0.02 * n as f64) as usize).min(n / 4);
            // Amplitude and bias of the settled part: a measured coil current opens with the
            // amplifier's transient from where the record before left it (a sine after a sweep
            // that ended at full current), which is no part of the excitation.
            let settled = &m.current_a[settle..];
            let (lo, hi) = settled
                .iter()
                .fold((f64::MAX, f64::MIN), |(lo, hi), &v| (lo.min(v), hi.max(v)));
            ExperimentInfo {
                name: m
                    .path
                    .file_name()
                    .map(|s| s.to_string_lossy().into_owned())
                    .unwrap_or_default(),
                fundamental_hz: f,
                amplitude_a: 0.5 * (hi - lo),
                bias_a: settled.iter().sum::<f64>() / settled.len().max(1) as f64,
                settle_samples: settle,
                quasi_static: f < QUASI_STATIC_BELOW_HZ,
                held_out: false,
                frequency_group: 0,
                start_state: String::new(),
                start_state_source: String::new(),
            }
        })
        .collect()
}

/// The fit's view of every record with the start `starts[k]` (and whether it continues the
/// record before it: the coil's heat history carries over).
pub fn experiment_data<'a>(
    measurements: &'a [Measurement],
    settles: &[usize],
    starts: &[(ModelStart, bool)],
) -> Vec<ExperimentData<'a>> {
    let mut out: Vec<ExperimentData<'a>> = Vec::with_capacity(measurements.len());
    for k in 0..measurements.len() {
        let (start, chained) = &starts[k];
        let heat_history = match out.last() {
            Some(prev) if *chained => {
                let mut h = prev.heat_history.clone();
                h.push(prev.current_a);
                h
            }
            _ => Vec::new(),
        };
        out.push(ExperimentData {
            current_a: &measurements[k].current_a,
            measured_m: &measurements[k].displacement_m,
            settle: settles[k],
            start: start.clone(),
            heat_history,
        });
    }
    out
}
