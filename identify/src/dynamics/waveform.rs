//! `R_eddy`, `ξ`, `f0` from dynamic experiments with the recording's nuisances estimated: the fit
//! `maglab identify` writes into the parameter file.
//!
//! It is the diagnosis' refitted nominal model (the same model, the same nuisance estimate, the
//! same Levenberg-Marquardt fit: `maglab-model`, as `maglab diagnose` steps 2 and 6 fit it) with
//! three differences:
//! every dynamic experiment is fitted (nothing is held out), the constants may move far from
//! their starting values ([`IDENTIFICATION_RANGE`]: identification is where they are found, not
//! checked), and the start values come from the caller (the paper's phase-lag scheme).
//! Identifying with the model the diagnosis uses means an identified file is exactly what the
//! diagnosis' refit would give on the same data: an identification error is never taken for an
//! effect.
//!
//! **Instruments from a datasheet.** When the base file's `datasheet` gives the sensor's or the
//! amplifier's bandwidth (`maglab_model::priors`), that instrument is fitted with the rod, its
//! parameters within the datasheet's bands: a sensor or amplifier lag is then not absorbed into
//! `R_eddy`, `ξ`, `f0` (which the firmware's model, without the instrument, would carry). The
//! amplifier is not modelled when the coil current is measured: it is outside the chain then.

use maglab_dataset::data::Measurement;
use maglab_dataset::dataset_info::DatasetInfo;
use maglab_dataset::CurrentBetweenSamples;
use maglab_model::candidates::{
    effect_parameters, model_parameters, Candidate, COMMON_PARAMETER_COUNT, IDENTIFICATION_RANGE,
};
use maglab_model::experiments::{
    describe, dynamic_indices, experiment_data, nominal_for_data, ExperimentInfo,
    QUASI_STATIC_BELOW_HZ,
};
use maglab_model::fit::{FitSettings, ModelSetup};
use maglab_model::nuisance::{estimate_nuisances, lead_in_memory, NuisanceEstimate};
use maglab_model::plan_fit::PlanFitter;
use maglab_model::residual::{offset_of, pooled_rms, systematic};
use maglab_signal::noise;
use serde::Serialize;

/// The identified constants and what was estimated with them.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct DynamicIdentification {
    /// `R_eddy`, Ω.
    pub eddy_resistance_ohm: f64,
    /// `ξ`.
    pub damping_ratio: f64,
    /// `f0`, Hz.
    pub resonance_hz: f64,
    /// What the current does between its samples.
    pub current_between_samples: CurrentBetweenSamples,
    /// Channel skew, samples.
    pub channel_skew_samples: f64,
    /// Sensor offset, m.
    pub sensor_offset_m: f64,
    /// Start state of the experiments not documented in `dataset.json`.
    pub start_state: String,
    /// Experiments whose start `dataset.json` documents.
    pub documented_starts: usize,
    /// RMS residual over every experiment's scored samples, m.
    pub rms_m: f64,
    /// White-noise level of the residual, m.
    pub noise_m: f64,
    /// Systematic part of the residual, m.
    pub systematic_m: f64,
    /// Per experiment: file name and RMS residual / displacement range.
    pub nrmse: Vec<(String, f64)>,
    /// Per experiment: file name and the model's displacement (offset included), m.
    #[serde(skip)]
    pub predictions: Vec<(String, Vec<f64>)>,
    /// Model evaluations.
    pub evaluations: u64,
    /// Highest fundamental of the fitted experiments, Hz (see
    /// [`IdentificationOptions::fit_band_fraction`]).
    pub fitted_up_to_hz: f64,
    /// The instruments modelled with the rod because the base file's datasheet gives their
    /// bandwidth (`maglab_model::priors::Priors::instruments`): each parameter's report name
    /// and fitted value.
    pub instruments: Vec<(String, f64)>,
    /// Electromagnetic substeps per sample of the fit's model ([`IdentificationOptions::substeps`]).
    pub substeps: usize,
}

impl DynamicIdentification {
    /// Where the current belongs to each displacement sample, in samples of `step_s` after the
    /// current's own sample time: the channel skew, less half a sample when the current is held
    /// (a held sample acts, on average, half a sample after its time stamp, as a linear one does
    /// at it), less the instruments' delay on slow signals ([`Self::instrument_delay_s`]).
    pub fn current_read_shift_samples(&self, step_s: f64) -> f64 {
        self.channel_skew_samples
            - self.current_between_samples.mean_delay_samples()
            - self.instrument_delay_s() / step_s
    }

    /// How much the instruments fitted with the rod delay a slow signal, s
    /// ([`instrument_delay_s`]).
    pub fn instrument_delay_s(&self) -> f64 {
        instrument_delay_s(&self.instruments)
    }
}

/// How much `instruments` (report name, fitted value) delay a slow signal, s: a second-order
/// low-pass `ωn² / (s² + 2ζωn s + ωn²)` by its group delay at DC, `2ζ/ωn`, and the sensor by its
/// conversion delay besides. A sensor's delay makes each reading show an earlier displacement, an
/// amplifier's makes the coil carry an earlier command: either way the displacement belongs to an
/// earlier current. 0 without instruments.
pub fn instrument_delay_s(instruments: &[(String, f64)]) -> f64 {
    let value = |effect: &str, name: &str| {
        instruments
            .iter()
            .find(|(n, _)| n == &format!("{effect}.{name}"))
            .map(|(_, v)| *v)
    };
    ["sensor_dynamics", "amplifier_bandwidth"]
        .iter()
        .map(|effect| {
            let group_s = match (value(effect, "natural_hz"), value(effect, "damping_ratio")) {
                (Some(f), Some(zeta)) if f > 0.0 => 2.0 * zeta / (2.0 * std::f64::consts::PI * f),
                _ => 0.0,
            };
            group_s + value(effect, "delay_s").unwrap_or(0.0)
        })
        .sum()
}

/// A substep of the fit's model spans at most this fraction of the period of the highest fitted
/// frequency when the substeps are chosen automatically ([`substeps_for`]).
///
/// The eddy step is backward Euler with Richardson extrapolation, second order in the step: its
/// phase error grows as `(f Δt / S)²`. On a noise-free bench-plant folder (sines 21-398 Hz at
/// 10 kHz, fitted up to 198.5 Hz; `maglab rig --forc-hz 1 --duration-s 0.5
/// --current-between-samples hold --skew-samples 0.13 --offset-m -0.31e-6 --noise-m 0
/// --quantization-m 0 --freq 20.8,50.9,95.4,198.5,313.3,398.2 --amplitude-a 0.176,0.339
/// --bias-a 0.54 --seed 3`) the model with the plant's own parameters and nuisances lags 0.69°,
/// 0.19° and 0.05° less than the recording at 198.5 Hz with 1, 2 and 4 substeps, and the fit,
/// given the plant's own masses, makes up for it with `R_eddy` −2.8 %, −0.24 % and −0.06 % off
/// 0.005 gives 4 substeps there.
pub const SUBSTEP_MAX_CYCLES: f64 = 0.005;

/// The automatic choice never passes this many substeps per sample (the cost of a model
/// evaluation grows about linearly with them).
pub const MAX_AUTO_SUBSTEPS: usize = 16;

/// The substeps per sample the fit's model needs so that one substep spans at most
/// [`SUBSTEP_MAX_CYCLES`] of the period of `top_hz` at the sample step `step_s`: the smallest
/// power of two that does, at most [`MAX_AUTO_SUBSTEPS`], at least 1.
pub fn substeps_for(top_hz: f64, step_s: f64) -> usize {
    let cycles = top_hz * step_s;
    let mut substeps = 1;
    while cycles / (substeps as f64) > SUBSTEP_MAX_CYCLES && substeps < MAX_AUTO_SUBSTEPS {
        substeps *= 2;
    }
    substeps
}

/// Settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IdentificationOptions {
    /// Electromagnetic substeps per sample (Richardson-extrapolated with twice as many); `None`:
    /// [`substeps_for`] the highest fitted frequency.
    pub substeps: Option<usize>,
    /// Fit settings (the refit range is [`IDENTIFICATION_RANGE`]).
    pub fit: FitSettings,
    /// Only the experiments whose fundamental is at most this fraction of the highest one are
    /// fitted (all are predicted and reported): unmodelled dynamics (eddy-current paths, the
    /// amplifier, the sensor, a load) grow with frequency, and a fit that reaches up to them
    /// bends R_eddy, ξ, f0 to mimic them (measured on the bench plant: f0 off by +30-90 % with
    /// them in the fit), which leaves a diagnosis nothing to find. The band above is what
    /// `maglab diagnose` holds out. 1 fits everything.
    pub fit_band_fraction: f64,
    /// The measurements' current is the measured coil current: read linear between samples
    /// (`maglab_model::coil_current`), never held.
    pub measured_current_input: bool,
}

/// Default [`IdentificationOptions::fit_band_fraction`]: up to a little over half the highest
/// frequency (20-200 Hz of a 20-400 Hz sweep).
pub const FIT_BAND_FRACTION: f64 = 0.55;

impl Default for IdentificationOptions {
    fn default() -> Self {
        IdentificationOptions {
            substeps: None,
            fit: FitSettings {
                refit_range: IDENTIFICATION_RANGE,
                patience: 20,
                ..FitSettings::default()
            },
            fit_band_fraction: FIT_BAND_FRACTION,
            measured_current_input: false,
        }
    }
}

/// How far (a factor) the fit may move R_eddy, xi or f0 from the constants the nuisances were
/// estimated with before they are estimated again with the fitted ones.
pub const RE_ESTIMATE_NUISANCES_AFTER: f64 = 1.05;

/// Identifies `R_eddy`, `ξ`, `f0` from the dynamic experiments `measurements`, with the Preisach
/// masses and constants of `params`; `starts` are extra start points (`[R_eddy, ξ, f0]`, for
/// example the phase-lag scheme's result) besides `params`' own values, which also centre the
/// search range ([`IDENTIFICATION_RANGE`]) and the nuisance estimate: the best start by cost is
/// refined (a start in the wrong basin cannot drag the fit there alone). `documented` is the
/// dataset's `dataset.json` when it has one. `measurements` are in recording order (file-name
/// order: an experiment that starts where the previous one ended continues the one before it),
/// and `lead_in` is the record the first of them was recorded right after, if any (a
/// quasi-static reversal sweep, not fitted here): when the experiments continue one another
/// without a reset, the first starts from the memory `lead_in` left, simulated once from its
/// documented start (demagnetized when undocumented; a reversal sweep wipes out its start).
pub fn identify_dynamics(
    params: &actuator_params::ActuatorParams,
    measurements: &[Measurement],
    lead_in: Option<&Measurement>,
    documented: Option<&DatasetInfo>,
    starts: &[[f64; 3]],
    options: &IdentificationOptions,
) -> Result<DynamicIdentification, String> {
    let rate_hz = check_inputs(params, measurements, starts, options)?;
    let core = magctl::params::ActuatorParameters::from_file(params, "base parameters")
        .map_err(|e| e.to_string())?;
    let measure = core.preisach.measure();
    let infos = describe(measurements, rate_hz);
    let nominal = nominal_for_data(params, measurements, &infos);
    let dynamic = dynamic_experiments(&infos)?;
    let fitted_set = fitted_band(&infos, &dynamic, options.fit_band_fraction);
    let fitted_up_to_hz = fitted_set
        .iter()
        .map(|&k| infos[k].fundamental_hz)
        .fold(0.0f64, f64::max);
    let substeps = options
        .substeps
        .unwrap_or_else(|| substeps_for(fitted_up_to_hz, 1.0 / rate_hz));
    let linear = ModelSetup {
        nominal: &nominal,
        measure: &measure,
        step_s: 1.0 / rate_hz,
        interpolation: CurrentBetweenSamples::Linear,
        substeps,
        single_run: false,
    };
    let passes = Passes::new(
        linear,
        Records {
            measurements,
            lead_in,
            documented,
        },
        &infos,
        fitted_set,
        options,
    );
    let base = [
        nominal.eddy_resistance_ohm,
        nominal.damping_ratio,
        nominal.resonance_hz,
    ];
    let chosen = passes.settled(base, starts);
    let residual = residual_of(&passes, &chosen, &dynamic);
    Ok(DynamicIdentification::of_pass(
        &passes,
        &chosen,
        residual,
        fitted_up_to_hz,
        substeps,
    ))
}

/// The experiments R_eddy, ξ, f0 are fitted on: those with a fundamental of at least
/// [`QUASI_STATIC_BELOW_HZ`]; an error when there are none.
fn dynamic_experiments(infos: &[ExperimentInfo]) -> Result<Vec<usize>, String> {
    let dynamic = dynamic_indices(infos);
    if dynamic.is_empty() {
        return Err(format!(
            "no experiment has a fundamental >= {QUASI_STATIC_BELOW_HZ} Hz: R_eddy, xi, f0 need \
             dynamic experiments"
        ));
    }
    Ok(dynamic)
}

impl DynamicIdentification {
    /// The identification the chosen pass gives: its constants, nuisances and instruments, and
    /// the residual on the dynamic experiments.
    fn of_pass(
        passes: &Passes<'_>,
        chosen: &Pass,
        residual: Residual,
        fitted_up_to_hz: f64,
        substeps: usize,
    ) -> Self {
        let v = &chosen.fit.fitted.values;
        DynamicIdentification {
            fitted_up_to_hz,
            instruments: chosen
                .fit
                .fitted
                .report_names()
                .into_iter()
                .zip(v.iter().copied())
                .skip(COMMON_PARAMETER_COUNT)
                .collect(),
            substeps,
            eddy_resistance_ohm: v[0],
            damping_ratio: v[1],
            resonance_hz: v[2],
            current_between_samples: chosen.interpolation,
            channel_skew_samples: v[3],
            sensor_offset_m: residual.offset_m,
            start_state: chosen.start_sets[chosen.fit.plan].0.name().into(),
            documented_starts: passes
                .documented_starts
                .iter()
                .filter(|s| s.is_some())
                .count(),
            rms_m: residual.rms_m,
            noise_m: residual.noise_m,
            systematic_m: systematic(residual.rms_m, residual.noise_m),
            nrmse: residual.nrmse,
            predictions: residual.predictions,
            evaluations: chosen.fit.fitted.evaluations,
        }
    }
}

/// The inputs make sense (a valid base, positive starts, one sampling rate, substeps and band
/// in range); returns the rate, Hz.
fn check_inputs(
    params: &actuator_params::ActuatorParams,
    measurements: &[Measurement],
    starts: &[[f64; 3]],
    options: &IdentificationOptions,
) -> Result<f64, String> {
    params
        .validate("base parameters")
        .map_err(|e| e.to_string())?;
    if measurements.is_empty() {
        return Err("no dynamic experiments to identify R_eddy, xi, f0 from".into());
    }
    if let Some(bad) = starts
        .iter()
        .find(|s| !s.iter().all(|v| v.is_finite() && *v > 0.0))
    {
        return Err(format!("start values must be positive, got {bad:?}"));
    }
    let rate_hz = 1.0 / measurements[0].step_s;
    if let Some(m) = measurements
        .iter()
        .find(|m| (1.0 / m.step_s - rate_hz).abs() > 1e-3 * rate_hz)
    {
        return Err(format!(
            "{}: sampled at {:.3} Hz, the others at {rate_hz:.3} Hz",
            m.path.display(),
            1.0 / m.step_s
        ));
    }
    if options.substeps == Some(0) {
        return Err("substeps must be at least 1, got 0".into());
    }
    if !(options.fit_band_fraction > 0.0 && options.fit_band_fraction <= 1.0) {
        return Err(format!(
            "fit_band_fraction must be in (0, 1], got {}",
            options.fit_band_fraction
        ));
    }
    Ok(rate_hz)
}

/// The fitted experiments: the dynamic ones up to `fraction` of the highest fundamental, when
/// they hold at least two distinct frequencies; else every dynamic experiment.
fn fitted_band(infos: &[ExperimentInfo], dynamic: &[usize], fraction: f64) -> Vec<usize> {
    let top_hz = dynamic
        .iter()
        .map(|&k| infos[k].fundamental_hz)
        .fold(0.0f64, f64::max);
    let in_band: Vec<usize> = dynamic
        .iter()
        .copied()
        .filter(|&k| infos[k].fundamental_hz <= fraction * top_hz)
        .collect();
    let mut band_freqs: Vec<f64> = in_band.iter().map(|&k| infos[k].fundamental_hz).collect();
    band_freqs.sort_by(f64::total_cmp);
    band_freqs.dedup_by(|a, b| (*a - *b).abs() <= 0.05 * *b);
    if band_freqs.len() >= 2 {
        in_band
    } else {
        dynamic.to_vec()
    }
}

/// The file name of a record.
fn file_name(m: &Measurement) -> String {
    m.path
        .file_name()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default()
}

/// What every pass shares: the model, the records, their starts, the fitted experiments.
/// The records a dynamic identification is made from ([`identify_dynamics`]).
#[derive(Clone, Copy)]
struct Records<'a> {
    /// The measurements, in recording order.
    measurements: &'a [Measurement],
    /// The record the first of them was recorded right after, if any.
    lead_in: Option<&'a Measurement>,
    /// The dataset's `dataset.json`, when it has one.
    documented: Option<&'a DatasetInfo>,
}

struct Passes<'a> {
    linear: ModelSetup<'a>,
    measurements: &'a [Measurement],
    lead_in: Option<&'a Measurement>,
    documented: Option<&'a DatasetInfo>,
    documented_starts: Vec<Option<maglab_dataset::StartState>>,
    settles: Vec<usize>,
    probe_lens: Vec<usize>,
    fitted_set: Vec<usize>,
    settings: &'a FitSettings,
    /// The current between samples the nuisance estimate may choose.
    interpolations: &'a [CurrentBetweenSamples],
    /// The instruments fitted with the rod (no effect: the nominal model) and where their
    /// parameters start.
    instruments: Candidate,
    instrument_starts: Vec<f64>,
}

/// One pass's result.
struct Pass {
    start_sets: Vec<(
        maglab_dataset::StartState,
        Vec<(maglab_model::model::ModelStart, bool)>,
    )>,
    interpolation: CurrentBetweenSamples,
    fit: maglab_model::plan_fit::PlanFit,
}

impl<'a> Passes<'a> {
    /// The passes' shared inputs: the records, their documented starts, how much of each the
    /// nuisance estimate probes, the current between samples it may choose and the instruments
    /// the base file's datasheet puts beside the rod (fitted from their datasheet values).
    /// `fitted_set` are the experiments the fit trains on.
    fn new(
        linear: ModelSetup<'a>,
        records: Records<'a>,
        infos: &[ExperimentInfo],
        fitted_set: Vec<usize>,
        options: &'a IdentificationOptions,
    ) -> Self {
        let Records {
            measurements,
            lead_in,
            documented,
        } = records;
        let nominal = linear.nominal;
        let settles: Vec<usize> = infos.iter().map(|i| i.settle_samples).collect();
        let instruments = nominal.priors.instruments(options.measured_current_input);
        Passes {
            linear,
            measurements,
            lead_in,
            documented,
            documented_starts: measurements
                .iter()
                .map(|m| documented.and_then(|d| d.start_of(&file_name(m))))
                .collect(),
            probe_lens: (0..measurements.len())
                .map(|k| (settles[k] + options.fit.max_fit_samples).min(measurements[k].len()))
                .collect(),
            settles,
            fitted_set,
            settings: &options.fit,
            interpolations: if options.measured_current_input {
                &[CurrentBetweenSamples::Linear]
            } else {
                &[CurrentBetweenSamples::Linear, CurrentBetweenSamples::Hold]
            },
            instrument_starts: instruments
                .iter()
                .flat_map(|&e| {
                    let specs = effect_parameters(e, nominal);
                    nominal.priors.start(e, &specs)
                })
                .collect(),
            instruments: Candidate {
                effects: instruments,
            },
        }
    }

    /// The pass the fit settles on from `base` (the base file's constants) and the extra
    /// `starts`.
    ///
    /// The nuisances of the first pass are estimated with the base file's constants. When the
    /// fit moved them far (a datasheet's R_eddy, xi, f0, not this rod's), that estimate is
    /// stale: with f0 20 % high the skew comes out at its +1 limit and f0 settles low to make
    /// up for it. So the nuisances are estimated again with the fitted constants and the fit
    /// repeated from them; the pass with the lower training residual is kept.
    fn settled(&self, base: [f64; 3], starts: &[[f64; 3]]) -> Pass {
        let first_starts: Vec<[f64; 3]> = std::iter::once(base)
            .chain(starts.iter().copied())
            .collect();
        let first = self.run(base, &first_starts);
        let moved = |v: &[f64]| {
            (0..3).any(|i| (v[i] / base[i]).ln().abs() > RE_ESTIMATE_NUISANCES_AFTER.ln())
        };
        if !moved(&first.fit.fitted.values) {
            return first;
        }
        let v = &first.fit.fitted.values;
        let fitted_constants = [v[0], v[1], v[2]];
        let second = self.run(fitted_constants, &[fitted_constants]);
        if second.fit.fitted.training_rms_m < first.fit.fitted.training_rms_m {
            second
        } else {
            first
        }
    }

    /// One pass: the nuisances estimated with the model of `constants`, then the fit from
    /// `fit_starts` with them.
    fn run(&self, constants: [f64; 3], fit_starts: &[[f64; 3]]) -> Pass {
        // The nuisances are estimated with the instruments at their datasheet values: a sensor
        // lag left out of that model would be taken up by the channel skew and the current
        // held between samples, and the fit could not give it back.
        let mut values = vec![constants[0], constants[1], constants[2], 0.0];
        values.extend(&self.instrument_starts);
        let (electro, mech) = model_parameters(&self.instruments, &values);
        // The first experiment, when it continues the record before it, starts from its memory.
        let mut lead_ins = vec![None; self.measurements.len()];
        lead_ins[0] = self.lead_in.map(|record| {
            let start = self.documented.and_then(|d| d.start_of(&file_name(record)));
            lead_in_memory(&self.linear, &electro, record, start)
        });
        let NuisanceEstimate {
            start_sets,
            plan,
            interpolation,
            skew,
            ..
        } = estimate_nuisances(
            &self.linear,
            self.interpolations,
            self.measurements,
            &self.settles,
            &self.fitted_set,
            &self.probe_lens,
            &self.documented_starts,
            &lead_ins,
            &electro,
            &mech,
        );
        let plan_data: Vec<_> = start_sets
            .iter()
            .map(|(_, st)| experiment_data(self.measurements, &self.settles, st))
            .collect();
        let fitter = PlanFitter {
            setup: ModelSetup {
                interpolation,
                ..self.linear
            },
            plan_data: &plan_data,
            training: &self.fitted_set,
            first_plan: plan,
            settings: self.settings,
        };
        let fit = fitter.fit(
            &self.instruments,
            &fit_starts
                .iter()
                .map(|s| {
                    let mut v = vec![s[0], s[1], s[2], skew];
                    v.extend(&self.instrument_starts);
                    v
                })
                .collect::<Vec<_>>(),
        );
        Pass {
            start_sets,
            interpolation,
            fit,
        }
    }
}

/// The chosen pass's residual on every dynamic experiment.
struct Residual {
    offset_m: f64,
    rms_m: f64,
    noise_m: f64,
    nrmse: Vec<(String, f64)>,
    predictions: Vec<(String, Vec<f64>)>,
}

/// The residual of `pass` on the `dynamic` experiments: the sensor offset, the pooled RMS, the
/// white-noise level (median over experiments), each experiment's NRMSE and prediction.
fn residual_of(passes: &Passes<'_>, pass: &Pass, dynamic: &[usize]) -> Residual {
    let measurements = passes.measurements;
    let setup = ModelSetup {
        interpolation: pass.interpolation,
        ..passes.linear
    };
    let plan_data: Vec<_> = pass
        .start_sets
        .iter()
        .map(|(_, st)| experiment_data(measurements, &passes.settles, st))
        .collect();
    let (e, m) = pass.fit.fitted.model();
    let data = &plan_data[pass.fit.plan];
    let preds = setup.predict_all(&e, &m, data, dynamic);
    let items: Vec<(&[f64], &[f64], usize)> = dynamic
        .iter()
        .zip(&preds)
        .map(|(&k, p)| (p.as_slice(), data[k].measured_m, data[k].settle))
        .collect();
    let offset = offset_of(&items);
    let rms = pooled_rms(&items, offset);
    let mut sigmas: Vec<f64> = items
        .iter()
        .map(|(p, y, s)| {
            let r: Vec<f64> = (*s..p.len()).map(|i| y[i] - p[i] - offset).collect();
            noise::white_noise_sigma(&r)
        })
        .collect();
    sigmas.sort_by(f64::total_cmp);
    let nrmse = dynamic
        .iter()
        .zip(&items)
        .map(|(&k, item)| {
            let y = &item.1[item.2..];
            let range = y.iter().cloned().fold(f64::MIN, f64::max)
                - y.iter().cloned().fold(f64::MAX, f64::min);
            (
                file_name(&measurements[k]),
                pooled_rms(std::slice::from_ref(item), offset) / range.max(1e-300),
            )
        })
        .collect();
    let predictions = dynamic
        .iter()
        .zip(&preds)
        .map(|(&k, p)| {
            (
                file_name(&measurements[k]),
                p.iter().map(|v| v + offset).collect(),
            )
        })
        .collect();
    Residual {
        offset_m: offset,
        rms_m: rms,
        noise_m: sigmas[sigmas.len() / 2],
        nrmse,
        predictions,
    }
}
