//! Steps 1–5 of the diagnosis, with the parameter file's model: the experiments, the recording's
//! nuisances, the noise level, where the model disagrees, and the split into training and
//! held-out experiments. Everything the candidate fits then take as given.

use super::report::Nuisance;
use super::split::split;
use super::DiagnoseOptions;
use crate::breakdown::{self, Where};
use magctl::preisach::PreisachMeasure;
use maglab_dataset::data::Measurement;
use maglab_dataset::dataset_info::DatasetInfo;
use maglab_dataset::{CurrentBetweenSamples, StartState};
use maglab_model::experiments::{
    describe, displacement_range, dynamic_indices, experiment_data, nominal_for_data,
    ExperimentInfo, QUASI_STATIC_BELOW_HZ,
};
use maglab_model::fit::{ExperimentData, ModelSetup};
use maglab_model::model::{Electro, Mech, Memory, ModelStart, Nominal};
use maglab_model::nuisance::{estimate_nuisances, lead_in_memory, NuisanceEstimate};
use maglab_model::residual::{offset_of, pooled_rms, systematic};
use maglab_signal::noise;
use std::sync::Arc;

/// A recorded dataset as the candidate fits see it.
pub struct Recording {
    /// Sampling rate, Hz.
    pub rate_hz: f64,
    /// The parameter file's Preisach operator.
    pub measure: PreisachMeasure,
    /// The parameter file's constants with what the data give (step 1).
    pub nominal: Nominal,
    /// Each experiment, its start state and whether it is held out.
    pub infos: Vec<ExperimentInfo>,
    /// Samples before scoring starts, per experiment.
    pub settles: Vec<usize>,
    /// The dynamic experiments (all but the quasi-static ones).
    pub dynamic: Vec<usize>,
    /// The training experiments.
    pub training: Vec<usize>,
    /// The held-out experiments.
    pub held_out: Vec<usize>,
    /// Every start plan (documented starts fixed, the others one plan each).
    pub start_sets: Vec<(StartState, Vec<(ModelStart, bool)>)>,
    /// The plan the nuisance estimate chose.
    pub plan: usize,
    /// What the current does between samples.
    pub interpolation: CurrentBetweenSamples,
    /// Channel skew, samples.
    pub skew: f64,
    /// The nuisances as the report shows them.
    pub nuisance: Nuisance,
    /// The parameter file's model with the nuisances (the sensor offset added), per experiment.
    pub nominal_preds: Vec<Vec<f64>>,
    /// Its RMS residual over the dynamic experiments, m.
    pub nominal_rms_m: f64,
    /// White-noise level σ, m.
    pub noise_m: f64,
    /// Measured displacement range over the dynamic experiments, m.
    pub range_m: f64,
    /// Where the parameter file's model disagrees (step 4).
    pub where_: Where,
}

impl Recording {
    /// The model with the estimated current between samples and `substeps`.
    pub fn setup(&self, substeps: usize) -> ModelSetup<'_> {
        ModelSetup {
            nominal: &self.nominal,
            measure: &self.measure,
            step_s: 1.0 / self.rate_hz,
            interpolation: self.interpolation,
            substeps,
            single_run: false,
        }
    }
}

/// Steps 1–5 (module docs) on `measurements` with the file `params`; `documented` is the
/// dataset's `dataset.json` when it has one.
pub fn analyse(
    params: &actuator_params::ActuatorParams,
    measurements: &[Measurement],
    documented: Option<&DatasetInfo>,
    options: &DiagnoseOptions,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<Recording, String> {
    // ---- Step 1: the experiments and the constants the data give.
    let rate_hz = check_dataset(params, measurements, documented)?;
    let core = magctl::params::ActuatorParameters::from_file(params, "nominal parameters")
        .map_err(|e| e.to_string())?;
    let measure = core.preisach.measure();
    let mut infos = describe(measurements, rate_hz);
    let nominal = nominal_for_data(params, measurements, &infos);
    let documented_starts: Vec<Option<StartState>> = measurements
        .iter()
        .map(|m| documented.and_then(|d| d.start_of(&file_name(m))))
        .collect();
    progress(1);
    let dynamic = dynamic_experiments(&infos)?;
    let settles: Vec<usize> = infos.iter().map(|i| i.settle_samples).collect();
    // ---- Step 2: nuisances, with the parameter file's model.
    let file = FileModel::estimate(
        (&nominal, &measure, rate_hz),
        options,
        Experiments {
            measurements,
            infos: &infos,
            settles: &settles,
            dynamic: &dynamic,
            documented_starts: &documented_starts,
        },
    );
    record_starts(&mut infos, &documented_starts, &file.estimate);
    progress(1);
    // ---- Step 3: noise.
    let noise_m = noise_level(measurements, &dynamic, &settles, &file.preds);
    let nuisance = nuisance_report(&file.estimate, file.sensor_offset, &infos);
    // ---- Step 5: split (first: it groups the experiments into the frequency bands that step 4
    // reports on).
    split(&mut infos, &dynamic)?;
    // ---- Step 4: where.
    let nominal_preds: Vec<Vec<f64>> = file
        .preds
        .iter()
        .map(|p| p.iter().map(|v| v + file.sensor_offset).collect())
        .collect();
    let where_ = breakdown::analyse(measurements, &nominal_preds, &infos, noise_m, rate_hz);
    let (training, held_out): (Vec<usize>, Vec<usize>) =
        dynamic.iter().copied().partition(|&k| !infos[k].held_out);
    let NuisanceEstimate {
        start_sets,
        plan,
        interpolation,
        skew,
        ..
    } = file.estimate;
    Ok(Recording {
        rate_hz,
        measure,
        nominal,
        settles,
        range_m: displacement_range(measurements, &dynamic),
        infos,
        dynamic,
        training,
        held_out,
        start_sets,
        plan,
        interpolation,
        skew,
        nuisance,
        nominal_preds,
        nominal_rms_m: file.nominal_rms_m,
        noise_m,
        where_,
    })
}

/// Step 2's result: the recording's nuisances and the parameter file's model with them.
struct FileModel {
    /// Start states, current between samples, channel skew.
    estimate: NuisanceEstimate,
    /// Its prediction per experiment, without the sensor offset, m.
    preds: Vec<Vec<f64>>,
    /// The sensor offset over the dynamic experiments, m.
    sensor_offset: f64,
    /// Its RMS residual over the dynamic experiments, m.
    nominal_rms_m: f64,
}

impl FileModel {
    /// The nuisances estimated with the parameter file's model ([`file_nuisances`]) and its
    /// predictions with them ([`file_predictions`]), on the model of `nominal`, `measure`
    /// sampled at `rate_hz`.
    fn estimate(
        (nominal, measure, rate_hz): (&Nominal, &PreisachMeasure, f64),
        options: &DiagnoseOptions,
        x: Experiments<'_>,
    ) -> FileModel {
        let file_electro = Electro::nominal(nominal.eddy_resistance_ohm);
        let file_mech = Mech::nominal(nominal.damping_ratio, nominal.resonance_hz);
        let setup_for = |interpolation| ModelSetup {
            nominal,
            measure,
            step_s: 1.0 / rate_hz,
            interpolation,
            substeps: options.substeps,
            single_run: false,
        };
        let (measurements, settles, dynamic) = (x.measurements, x.settles, x.dynamic);
        let estimate = file_nuisances(
            &setup_for(CurrentBetweenSamples::Linear),
            options,
            x,
            (&file_electro, &file_mech),
        );
        let data = experiment_data(measurements, settles, &estimate.start_sets[estimate.plan].1);
        let nuisance_mech = Mech {
            skew_samples: estimate.skew,
            ..file_mech
        };
        let (preds, sensor_offset, nominal_rms_m) = file_predictions(
            &setup_for(estimate.interpolation),
            (&file_electro, &nuisance_mech),
            &data,
            dynamic,
        );
        FileModel {
            estimate,
            preds,
            sensor_offset,
            nominal_rms_m,
        }
    }
}

/// The experiments the diagnosis scores on: those with a fundamental of at least
/// [`QUASI_STATIC_BELOW_HZ`], at least two (one to train on, one to hold out).
fn dynamic_experiments(infos: &[ExperimentInfo]) -> Result<Vec<usize>, String> {
    let dynamic = dynamic_indices(infos);
    if dynamic.len() < 2 {
        return Err(format!(
            "the diagnosis needs at least 2 dynamic experiments (fundamental >= {QUASI_STATIC_BELOW_HZ} Hz), got {}",
            dynamic.len()
        ));
    }
    Ok(dynamic)
}

/// The records and what step 1 found in them.
#[derive(Clone, Copy)]
struct Experiments<'a> {
    measurements: &'a [Measurement],
    infos: &'a [ExperimentInfo],
    settles: &'a [usize],
    dynamic: &'a [usize],
    documented_starts: &'a [Option<StartState>],
}

/// Step 2: the recording's nuisances (start states, current between samples, channel skew)
/// estimated with the parameter file's model `file` (electromagnetic, mechanical), each
/// experiment that continues another starting from the memory its predecessor left.
fn file_nuisances(
    linear: &ModelSetup<'_>,
    options: &DiagnoseOptions,
    x: Experiments<'_>,
    (file_electro, file_mech): (&Electro, &Mech),
) -> NuisanceEstimate {
    let probe_lens: Vec<usize> = (0..x.measurements.len())
        .map(|k| {
            (x.infos[k].settle_samples + options.fit.max_fit_samples).min(x.measurements[k].len())
        })
        .collect();
    let lead_ins = lead_ins(
        linear,
        file_electro,
        x.measurements,
        x.infos,
        x.documented_starts,
    );
    let interpolations: &[CurrentBetweenSamples] = if options.measured_current_input {
        &[CurrentBetweenSamples::Linear]
    } else {
        &[CurrentBetweenSamples::Linear, CurrentBetweenSamples::Hold]
    };
    estimate_nuisances(
        linear,
        interpolations,
        x.measurements,
        x.settles,
        x.dynamic,
        &probe_lens,
        x.documented_starts,
        &lead_ins,
        file_electro,
        file_mech,
    )
}

/// The parameter file's model with the nuisances on every experiment of `data`, without the
/// sensor offset: `(predictions, sensor offset, pooled RMS residual over the dynamic
/// experiments)`, m.
fn file_predictions(
    setup: &ModelSetup<'_>,
    (file_electro, nuisance_mech): (&Electro, &Mech),
    data: &[ExperimentData<'_>],
    dynamic: &[usize],
) -> (Vec<Vec<f64>>, f64, f64) {
    let everything: Vec<usize> = (0..data.len()).collect();
    let file_preds = setup.predict_all(file_electro, nuisance_mech, data, &everything);
    let dyn_items: Vec<(&[f64], &[f64], usize)> = dynamic
        .iter()
        .map(|&k| (file_preds[k].as_slice(), data[k].measured_m, data[k].settle))
        .collect();
    let sensor_offset = offset_of(&dyn_items);
    let nominal_rms_m = pooled_rms(&dyn_items, sensor_offset);
    (file_preds, sensor_offset, nominal_rms_m)
}

/// The file name of a record (its path's last component).
fn file_name(m: &Measurement) -> String {
    m.path
        .file_name()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default()
}

/// The parameter file validates, the dataset holds two experiments at one rate and
/// `dataset.json` documents only files it has; returns the rate, Hz.
fn check_dataset(
    params: &actuator_params::ActuatorParams,
    measurements: &[Measurement],
    documented: Option<&DatasetInfo>,
) -> Result<f64, String> {
    params
        .validate("nominal parameters")
        .map_err(|e| e.to_string())?;
    if measurements.len() < 2 {
        return Err(format!(
            "the diagnosis needs at least 2 experiments (training and held-out), got {}",
            measurements.len()
        ));
    }
    let rate_hz = 1.0 / measurements[0].step_s;
    for m in measurements {
        let r = 1.0 / m.step_s;
        if (r - rate_hz).abs() > 1e-3 * rate_hz {
            return Err(format!(
                "{}: sampled at {r:.3} Hz, but {} is at {rate_hz:.3} Hz; all experiments of a \
                 dataset must share one rate",
                m.path.display(),
                measurements[0].path.display()
            ));
        }
    }
    if let Some(doc) = documented {
        let names: Vec<String> = measurements.iter().map(file_name).collect();
        doc.check_files(
            measurements[0]
                .path
                .parent()
                .unwrap_or(std::path::Path::new(".")),
            names.iter().map(|s| s.as_str()),
        )
        .map_err(|e| e.to_string())?;
    }
    Ok(rate_hz)
}

/// The memory a quasi-static record leaves for the dynamic experiment recorded right after it
/// (a reversal sweep before the sines), simulated once, for each experiment that may continue
/// one: only when some experiment may continue another (a start `previous` documented or left
/// to estimate).
fn lead_ins(
    linear: &ModelSetup<'_>,
    electro: &Electro,
    measurements: &[Measurement],
    infos: &[ExperimentInfo],
    documented_starts: &[Option<StartState>],
) -> Vec<Option<Arc<Memory>>> {
    let may_continue = documented_starts
        .iter()
        .any(|s| s.is_none_or(|s| s == StartState::Previous));
    (0..measurements.len())
        .map(|k| {
            let continues_a_sweep = k > 0 && infos[k - 1].quasi_static && !infos[k].quasi_static;
            (may_continue && continues_a_sweep).then(|| {
                lead_in_memory(
                    linear,
                    electro,
                    &measurements[k - 1],
                    documented_starts[k - 1],
                )
            })
        })
        .collect()
}

/// Each experiment's start state and whether it was documented or estimated.
fn record_starts(
    infos: &mut [ExperimentInfo],
    documented_starts: &[Option<StartState>],
    estimate: &NuisanceEstimate,
) {
    for (k, info) in infos.iter_mut().enumerate() {
        match documented_starts[k] {
            Some(s) => {
                info.start_state = s.name().into();
                info.start_state_source = "documented".into();
            }
            None => {
                info.start_state = estimate.start_sets[estimate.plan].0.name().into();
                info.start_state_source = "estimated".into();
            }
        }
    }
}

/// σ: the median over the dynamic experiments of the white-noise level of the file model's
/// residual (step 3).
fn noise_level(
    measurements: &[Measurement],
    dynamic: &[usize],
    settles: &[usize],
    file_preds: &[Vec<f64>],
) -> f64 {
    let mut sigmas: Vec<f64> = dynamic
        .iter()
        .map(|&k| {
            let r: Vec<f64> = (settles[k]..measurements[k].len())
                .map(|i| measurements[k].displacement_m[i] - file_preds[k][i])
                .collect();
            noise::white_noise_sigma(&r)
        })
        .collect();
    sigmas.sort_by(f64::total_cmp);
    sigmas[sigmas.len() / 2]
}

/// The nuisances as the report shows them.
fn nuisance_report(
    estimate: &NuisanceEstimate,
    sensor_offset_m: f64,
    infos: &[ExperimentInfo],
) -> Nuisance {
    let between = if estimate.rms_hold.is_finite() {
        format!(
            "current between samples: {} (RMS residual {:.3e} m held, {:.3e} m linear)",
            estimate.interpolation.name(),
            estimate.rms_hold,
            estimate.rms_linear
        )
    } else {
        "current between samples: linear (the measured coil current, a sampled continuous \
         signal)"
            .to_string()
    };
    let mut estimated = vec![
        between,
        format!(
            "channel skew: {:+.3} samples (displacement read after the current sample when positive)",
            estimate.skew
        ),
        format!("sensor offset: {:.3e} m", sensor_offset_m),
    ];
    let estimated_starts = infos
        .iter()
        .filter(|i| i.start_state_source == "estimated")
        .count();
    if estimated_starts > 0 {
        estimated.push(format!(
            "start state `{}` of {estimated_starts} of {} experiments (not documented in dataset.json; \
             each candidate re-chooses it)",
            estimate.start_sets[estimate.plan].0.name(),
            infos.len()
        ));
    }
    Nuisance {
        current_between_samples: estimate.interpolation.name().into(),
        rms_hold_m: estimate.rms_hold,
        rms_linear_m: estimate.rms_linear,
        channel_skew_samples: estimate.skew,
        sensor_offset_m,
        estimated,
    }
}

/// The systematic part of the parameter file's residual, m.
pub fn nominal_systematic_m(recording: &Recording) -> f64 {
    systematic(recording.nominal_rms_m, recording.noise_m)
}
