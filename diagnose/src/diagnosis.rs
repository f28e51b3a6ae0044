//! `maglab diagnose`: where the measured data and the nominal model disagree, which unmodelled
//! effect explains it, and how far the gap shrinks once that effect is added.
//!
//! # Steps
//!
//! 1. **Nominal residual.** Every experiment's current is run through the nominal model
//!    ([`crate::model`], started like the rig: demagnetized memory at equilibrium under the first
//!    current). The first `max(one period, 2 %)` of each record (at most 25 %) is not scored: it
//!    holds the transient of an initial magnetic state the data do not reveal.
//! 2. **Noise level.** σ is the white-noise level of the residual above 0.3·f_s
//!    ([`crate::signal::white_noise_sigma`]), median over experiments. The *systematic gap* of a
//!    residual with RMS `e` is `g = √max(e² − σ², 0)`.
//! 3. **Where** ([`crate::breakdown`]): per experiment and per frequency band.
//! 4. **Split.** Experiments are grouped by fundamental frequency (within 5 %) and amplitude
//!    (within 10 %). With 3+ frequency groups, every third frequency (the 2nd, 5th, …, so the
//!    extremes stay in training) is held out with all its amplitudes; with fewer, every other
//!    amplitude group; else every other experiment. No held-out experiment has a training
//!    experiment at the same frequency and amplitude, and the fit must interpolate between
//!    frequencies rather than copy a neighbour.
//! 5. **Candidates.** Each effect of the library ([`crate::candidates`]) is added to the nominal
//!    model and its parameters fitted on the training experiments only (least squares on the
//!    displacement; the coarse starting points are evaluated, then Nelder-Mead (argmin) refines the
//!    best one, and the second when its cost is within 50 % of the best). Candidates run in parallel (rayon).
//! 6. **Score and verdict.** Held-out RMS before (nominal) and after (augmented).
//!    * `none` when the nominal model's systematic gap over all experiments is not above the noise:
//!      `g0 ≤ σ` (the residual RMS is at most √2 σ).
//!    * Otherwise a candidate is **significant** when, on the held-out experiments, (a) its
//!      systematic gap is at most half the nominal one (`g_after ≤ 0.5 g_before`: it removes at
//!      least 75 % of the gap's energy) and (b) it lowers the error on at least 75 % of the
//!      held-out experiments (a consistent improvement, not one experiment fitted at the cost of
//!      others). The verdict is the significant candidate with the lowest held-out error, else
//!      `unexplained` (the report still ranks the partial explanations).
//!    * Candidates within 10 % of the winner's held-out error are listed as `ambiguous_with`.
//! 7. **Second stage.** When the winner still leaves a held-out gap above 2σ, every other
//!    candidate is refitted on top of it (forward selection) and ranks 2.. are ordered by that
//!    combined held-out error; those passing the same criterion against the winner-only model are
//!    listed as `additional_effects` (two effects at once).

use crate::breakdown::{self, Where};
use crate::candidates;
use crate::effects::EffectName;
use crate::model::{simulate, Augmentation, Nominal};
use crate::signal;
use argmin::core::{CostFunction, Error as ArgminError, Executor, State};
use argmin::solver::neldermead::NelderMead;
use magctl::preisach::PreisachMeasure;
use maglab_identify::data::Measurement;
use rayon::prelude::*;
use serde::Serialize;
use std::collections::BTreeMap;
use std::sync::atomic::{AtomicU64, Ordering};

/// Settings of the diagnosis.
#[derive(Debug, Clone, PartialEq)]
pub struct DiagnoseOptions {
    /// Model substeps per sample.
    pub substeps: usize,
    /// Nelder-Mead iterations per parameter and refined start.
    pub max_iterations: u64,
    /// Highest excitation frequency the nominal parameters were identified on, Hz, when known:
    /// the gap onset is then measured against the agreement reached there
    /// ([`crate::breakdown`], gap-onset rule).
    pub identified_up_to_hz: Option<f64>,
}

impl Default for DiagnoseOptions {
    fn default() -> Self {
        DiagnoseOptions {
            substeps: 2,
            max_iterations: 30,
            identified_up_to_hz: None,
        }
    }
}

/// Excitation properties read from the current of one experiment.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct ExperimentInfo {
    /// File name.
    pub name: String,
    /// Fundamental (dominant) frequency of the current, Hz.
    pub fundamental_hz: f64,
    /// Half the peak-to-peak current, A.
    pub amplitude_a: f64,
    /// Mean current, A.
    pub bias_a: f64,
    /// Samples before scoring starts.
    pub settle_samples: usize,
    /// Held out (`true`) or training.
    pub held_out: bool,
    /// Frequency group index (sorted by frequency).
    pub frequency_group: usize,
}

/// Held-out error by frequency band.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct BandError {
    /// Band (frequency group) centre, Hz.
    pub frequency_hz: f64,
    /// RMS residual of the nominal model, m.
    pub before_m: f64,
    /// RMS residual with the candidate, m.
    pub after_m: f64,
    /// Whether the band's experiments were held out.
    pub held_out: bool,
}

/// One candidate's result.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct CandidateResult {
    /// Effect name.
    pub effect: String,
    /// Fitted parameters (physical units, names as in [`crate::candidates::parameters`]).
    pub parameters: BTreeMap<String, f64>,
    /// Training RMS before / after, m.
    pub training_rms_before_m: f64,
    /// See above.
    pub training_rms_after_m: f64,
    /// Held-out RMS before (nominal), m.
    pub held_out_rms_before_m: f64,
    /// Held-out RMS after (augmented), m.
    pub held_out_rms_after_m: f64,
    /// `before / after` on held-out data.
    pub held_out_reduction: f64,
    /// Held-out systematic gap before / after (noise removed), m.
    pub systematic_before_m: f64,
    /// See above.
    pub systematic_after_m: f64,
    /// Held-out experiments whose error went down.
    pub improved_experiments: usize,
    /// Held-out experiments.
    pub held_out_experiments: usize,
    /// Passes the significance criterion.
    pub significant: bool,
    /// Errors per frequency band, all experiments.
    pub per_band: Vec<BandError>,
    /// Model evaluations spent on the fit.
    pub evaluations: u64,
    /// Second stage (only when the winner leaves a gap above 2σ): held-out RMS with this
    /// candidate refitted on top of the winner, m.
    pub held_out_rms_with_best_m: Option<f64>,
    /// Parameters of the second-stage fit.
    pub parameters_with_best: Option<BTreeMap<String, f64>>,
}

/// The machine-readable diagnosis (`diagnosis.json`).
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct Diagnosis {
    /// An effect name, `none` or `unexplained`.
    pub verdict: String,
    /// Why, in one sentence.
    pub verdict_reason: String,
    /// Candidates whose held-out error is within 10 % of the winner's.
    pub ambiguous_with: Vec<String>,
    /// Further effects found by the second stage: refitted on top of the winner, each removes at
    /// least half of the remaining held-out systematic gap on at least 75 % of held-out experiments.
    pub additional_effects: Vec<String>,
    /// The significance criterion, in words.
    pub criterion: String,
    /// Estimated white-noise level σ, m.
    pub noise_m: f64,
    /// Measured displacement range over the dataset, m.
    pub displacement_range_m: f64,
    /// Nominal RMS residual over all experiments, m.
    pub nominal_rms_m: f64,
    /// Nominal systematic gap over all experiments, m.
    pub nominal_systematic_m: f64,
    /// Experiments and the split.
    pub experiments: Vec<ExperimentInfo>,
    /// Candidates, best first (by held-out RMS after).
    pub ranking: Vec<CandidateResult>,
    /// Where the nominal residual lies.
    #[serde(rename = "where")]
    pub where_: Where,
}

/// Per-experiment traces for the report's plots.
#[derive(Debug, Clone, PartialEq)]
pub struct Trace {
    /// File name.
    pub name: String,
    /// Sampling rate, Hz.
    pub rate_hz: f64,
    /// Current, A.
    pub current_a: Vec<f64>,
    /// Measured displacement, m.
    pub measured_m: Vec<f64>,
    /// Nominal model, m.
    pub nominal_m: Vec<f64>,
    /// Best candidate's model (nominal when the verdict is `none`), m.
    pub augmented_m: Vec<f64>,
}

/// Diagnosis plus traces.
#[derive(Debug, Clone, PartialEq)]
pub struct DiagnosisRun {
    /// The result.
    pub diagnosis: Diagnosis,
    /// The traces.
    pub traces: Vec<Trace>,
}

struct Prepared<'a> {
    measurements: &'a [Measurement],
    infos: Vec<ExperimentInfo>,
    rate_hz: f64,
}

/// The significance criterion in words (also in `diagnosis.json`).
pub const CRITERION: &str = "a candidate is named when, on held-out experiments, it removes at \
least 75 % of the systematic gap's energy (noise-corrected RMS gap after <= 0.5 x before) and \
lowers the error on at least 75 % of the held-out experiments; `none` when the nominal model's \
systematic gap is not above the white-noise level (RMS residual <= sqrt(2) x noise)";

/// Runs the diagnosis on `measurements` with the nominal parameters.
pub fn diagnose(
    params: &actuator_params::ActuatorParams,
    measurements: &[Measurement],
    options: &DiagnoseOptions,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<DiagnosisRun, String> {
    params
        .validate("nominal parameters")
        .map_err(|e| e.to_string())?;
    if measurements.len() < 2 {
        return Err(format!(
            "the diagnosis needs at least 2 experiments (training and held-out), got {}",
            measurements.len()
        ));
    }
    if let Some(f) = options.identified_up_to_hz {
        if !(f.is_finite() && f > 0.0) {
            return Err(format!(
                "option `identified_up_to_hz` must be a positive frequency in Hz, got {f}"
            ));
        }
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
    let core = crate::rig::to_core(params)?;
    let measure = PreisachMeasure::new(
        &core.preisach.weights_a_per_m,
        core.preisach.h_min_a_per_m,
        core.preisach.h_max_a_per_m,
    );
    let nominal = Nominal::from_params(params);
    let prepared = prepare(measurements, rate_hz)?;
    let step_s = 1.0 / rate_hz;
    let sim = |aug: &Augmentation, k: usize| {
        simulate(
            &nominal,
            &measure,
            aug,
            &measurements[k].current_a,
            step_s,
            options.substeps,
        )
    };
    let nominal_runs: Vec<Vec<f64>> = (0..measurements.len())
        .into_par_iter()
        .map(|k| sim(&Augmentation::default(), k))
        .collect();
    progress(1);

    // Noise and nominal errors.
    let residuals: Vec<Vec<f64>> = nominal_runs
        .iter()
        .zip(measurements)
        .map(|(y, m)| m.displacement_m.iter().zip(y).map(|(a, b)| a - b).collect())
        .collect();
    let mut sigmas: Vec<f64> = residuals
        .iter()
        .zip(&prepared.infos)
        .map(|(r, info)| signal::white_noise_sigma(&r[info.settle_samples..]))
        .collect();
    sigmas.sort_by(f64::total_cmp);
    let noise_m = sigmas[sigmas.len() / 2];
    let all: Vec<usize> = (0..measurements.len()).collect();
    let nominal_rms = pooled_rms(&prepared, &nominal_runs, &all);
    let nominal_systematic = systematic(nominal_rms, noise_m);
    let range = displacement_range(measurements);
    let where_ = breakdown::analyse(
        measurements,
        &nominal_runs,
        &prepared.infos,
        noise_m,
        prepared.rate_hz,
        options.identified_up_to_hz,
    );

    let training: Vec<usize> = all
        .iter()
        .copied()
        .filter(|&k| !prepared.infos[k].held_out)
        .collect();
    let held_out: Vec<usize> = all
        .iter()
        .copied()
        .filter(|&k| prepared.infos[k].held_out)
        .collect();

    // Fit every candidate (in parallel).
    let mut ranking: Vec<(CandidateResult, Augmentation)> = EffectName::LIBRARY
        .par_iter()
        .map(|&effect| {
            let (values, evaluations) = fit_candidate(
                effect, &nominal, &prepared, &training, &sim, options, noise_m, progress,
            );
            let aug = candidates::augmentation(effect, &values);
            let runs: Vec<Vec<f64>> = (0..measurements.len())
                .into_par_iter()
                .map(|k| sim(&aug, k))
                .collect();
            let specs = candidates::parameters(effect, &nominal);
            let parameters = specs
                .iter()
                .zip(&values)
                .map(|(s, v)| (s.name.to_string(), *v))
                .collect();
            let before_h = pooled_rms(&prepared, &nominal_runs, &held_out);
            let after_h = pooled_rms(&prepared, &runs, &held_out);
            let improved = held_out
                .iter()
                .filter(|&&k| {
                    pooled_rms(&prepared, &runs, &[k]) < pooled_rms(&prepared, &nominal_runs, &[k])
                })
                .count();
            let sys_before = systematic(before_h, noise_m);
            let sys_after = systematic(after_h, noise_m);
            let significant =
                sys_after <= 0.5 * sys_before && improved as f64 >= 0.75 * held_out.len() as f64;
            let per_band = bands(&prepared, &nominal_runs, &runs);
            (
                CandidateResult {
                    effect: effect.name().to_string(),
                    parameters,
                    training_rms_before_m: pooled_rms(&prepared, &nominal_runs, &training),
                    training_rms_after_m: pooled_rms(&prepared, &runs, &training),
                    held_out_rms_before_m: before_h,
                    held_out_rms_after_m: after_h,
                    held_out_reduction: before_h / after_h.max(1e-300),
                    systematic_before_m: sys_before,
                    systematic_after_m: sys_after,
                    improved_experiments: improved,
                    held_out_experiments: held_out.len(),
                    significant,
                    per_band,
                    evaluations,
                    held_out_rms_with_best_m: None,
                    parameters_with_best: None,
                },
                aug,
            )
        })
        .collect();
    ranking.sort_by(|a, b| {
        a.0.held_out_rms_after_m
            .total_cmp(&b.0.held_out_rms_after_m)
    });

    // Second stage: when the winner leaves a gap above twice the noise, refit every other
    // candidate on top of it (forward selection) and rank the rest by the combined held-out error.
    let mut additional_effects = Vec::new();
    if ranking[0].0.significant && ranking[0].0.systematic_after_m > 2.0 * noise_m {
        let best_aug = ranking[0].1;
        let best_runs: Vec<Vec<f64>> = (0..measurements.len())
            .into_par_iter()
            .map(|k| sim(&best_aug, k))
            .collect();
        let base_rms = pooled_rms(&prepared, &best_runs, &held_out);
        let base_sys = systematic(base_rms, noise_m);
        let stacked = |a: &Augmentation, k: usize| sim(&merge(&best_aug, a), k);
        let second: Vec<(usize, f64, BTreeMap<String, f64>, bool)> = (1..ranking.len())
            .into_par_iter()
            .map(|r| {
                let effect = EffectName::parse(&ranking[r].0.effect).expect("library name");
                let (values, _) = fit_candidate(
                    effect, &nominal, &prepared, &training, &stacked, options, noise_m, progress,
                );
                let aug = candidates::augmentation(effect, &values);
                let runs: Vec<Vec<f64>> = (0..measurements.len())
                    .into_par_iter()
                    .map(|k| stacked(&aug, k))
                    .collect();
                let after = pooled_rms(&prepared, &runs, &held_out);
                let improved = held_out
                    .iter()
                    .filter(|&&k| {
                        pooled_rms(&prepared, &runs, &[k]) < pooled_rms(&prepared, &best_runs, &[k])
                    })
                    .count();
                let significant = systematic(after, noise_m) <= 0.5 * base_sys
                    && improved as f64 >= 0.75 * held_out.len() as f64;
                let specs = candidates::parameters(effect, &nominal);
                let params = specs
                    .iter()
                    .zip(&values)
                    .map(|(s, v)| (s.name.to_string(), *v))
                    .collect();
                (r, after, params, significant)
            })
            .collect();
        for (r, after, params, significant) in second {
            ranking[r].0.held_out_rms_with_best_m = Some(after);
            ranking[r].0.parameters_with_best = Some(params);
            if significant {
                additional_effects.push(ranking[r].0.effect.clone());
            }
        }
        ranking[1..].sort_by(|a, b| {
            let key = |c: &CandidateResult| c.held_out_rms_with_best_m.unwrap_or(f64::MAX);
            key(&a.0).total_cmp(&key(&b.0))
        });
        additional_effects.sort_by_key(|e| ranking.iter().position(|(c, _)| &c.effect == e));
    }

    let (verdict, reason, best_aug) = if nominal_systematic <= noise_m {
        (
            "none".to_string(),
            format!(
                "the nominal model fits within the noise: RMS residual {:.3e} m against a noise \
                 level of {:.3e} m (systematic gap {:.3e} m <= noise)",
                nominal_rms, noise_m, nominal_systematic
            ),
            Augmentation::default(),
        )
    } else {
        match ranking.iter().find(|(c, _)| c.significant) {
            Some((c, aug)) if std::ptr::eq(c, &ranking[0].0) => (
                c.effect.clone(),
                format!(
                    "adding {} cuts the held-out error from {:.3e} m to {:.3e} m ({:.1}x) and \
                     improves {}/{} held-out experiments",
                    c.effect,
                    c.held_out_rms_before_m,
                    c.held_out_rms_after_m,
                    c.held_out_reduction,
                    c.improved_experiments,
                    c.held_out_experiments
                ),
                *aug,
            ),
            _ => {
                let best = &ranking[0].0;
                (
                    "unexplained".to_string(),
                    format!(
                        "no candidate removes the gap: the best, {}, leaves a held-out systematic \
                         gap of {:.3e} m of {:.3e} m ({:.0} %) and improves {}/{} held-out \
                         experiments",
                        best.effect,
                        best.systematic_after_m,
                        best.systematic_before_m,
                        100.0 * best.systematic_after_m / best.systematic_before_m.max(1e-300),
                        best.improved_experiments,
                        best.held_out_experiments
                    ),
                    ranking[0].1,
                )
            }
        }
    };
    let ambiguous_with = if verdict != "none" && verdict != "unexplained" {
        let best = ranking[0].0.held_out_rms_after_m;
        ranking[1..]
            .iter()
            .filter(|(c, _)| c.held_out_rms_after_m <= 1.1 * best)
            .map(|(c, _)| c.effect.clone())
            .collect()
    } else {
        Vec::new()
    };
    let traces = (0..measurements.len())
        .into_par_iter()
        .map(|k| Trace {
            name: prepared.infos[k].name.clone(),
            rate_hz,
            current_a: measurements[k].current_a.clone(),
            measured_m: measurements[k].displacement_m.clone(),
            nominal_m: nominal_runs[k].clone(),
            augmented_m: sim(&best_aug, k),
        })
        .collect();
    Ok(DiagnosisRun {
        diagnosis: Diagnosis {
            verdict,
            verdict_reason: reason,
            ambiguous_with,
            additional_effects,
            criterion: CRITERION.to_string(),
            noise_m,
            displacement_range_m: range,
            nominal_rms_m: nominal_rms,
            nominal_systematic_m: nominal_systematic,
            experiments: prepared.infos.clone(),
            ranking: ranking.into_iter().map(|(c, _)| c).collect(),
            where_,
        },
        traces,
    })
}

/// Both augmentations at once (candidates use disjoint fields; `a` wins on overlap).
fn merge(a: &Augmentation, b: &Augmentation) -> Augmentation {
    Augmentation {
        amplifier_corner_hz: a.amplifier_corner_hz.or(b.amplifier_corner_hz),
        eddy: a.eddy.or(b.eddy),
        sensor_corner_hz: a.sensor_corner_hz.or(b.sensor_corner_hz),
        sensor_delay_s: a.sensor_delay_s.or(b.sensor_delay_s),
        susceptibility: a.susceptibility.or(b.susceptibility),
        thermal: a.thermal.or(b.thermal),
        delta_e: a.delta_e.or(b.delta_e),
        load: a.load.or(b.load),
    }
}

/// Noise-corrected systematic part of an RMS error.
pub fn systematic(rms: f64, noise: f64) -> f64 {
    (rms * rms - noise * noise).max(0.0).sqrt()
}

fn displacement_range(measurements: &[Measurement]) -> f64 {
    let (lo, hi) = measurements
        .iter()
        .flat_map(|m| m.displacement_m.iter())
        .fold((f64::MAX, f64::MIN), |(lo, hi), &v| (lo.min(v), hi.max(v)));
    (hi - lo).max(0.0)
}

/// Reads fundamental, amplitude and bias from each current; groups and splits.
fn prepare(measurements: &[Measurement], rate_hz: f64) -> Result<Prepared<'_>, String> {
    let mut infos: Vec<ExperimentInfo> = measurements
        .iter()
        .map(|m| {
            let n = m.len();
            let f =
                signal::dominant_frequency_hz(&m.current_a, rate_hz).unwrap_or(rate_hz / n as f64);
            let (lo, hi) = m
                .current_a
                .iter()
                .fold((f64::MAX, f64::MIN), |(lo, hi), &v| (lo.min(v), hi.max(v)));
            let settle = ((rate_hz / f).max(0.02 * n as f64) as usize).min(n / 4);
            ExperimentInfo {
                name: m
                    .path
                    .file_name()
                    .map(|s| s.to_string_lossy().into_owned())
                    .unwrap_or_default(),
                fundamental_hz: f,
                amplitude_a: 0.5 * (hi - lo),
                bias_a: m.current_a.iter().sum::<f64>() / n as f64,
                settle_samples: settle,
                held_out: false,
                frequency_group: 0,
            }
        })
        .collect();
    // Frequency groups (within 5 %), sorted.
    let mut order: Vec<usize> = (0..infos.len()).collect();
    order.sort_by(|&a, &b| infos[a].fundamental_hz.total_cmp(&infos[b].fundamental_hz));
    let mut group = 0usize;
    let mut anchor = infos[order[0]].fundamental_hz;
    for &k in &order {
        if infos[k].fundamental_hz > anchor * 1.05 {
            group += 1;
            anchor = infos[k].fundamental_hz;
        }
        infos[k].frequency_group = group;
    }
    let frequency_groups = group + 1;
    // Amplitude groups (within 10 %).
    let mut amps: Vec<f64> = infos.iter().map(|i| i.amplitude_a).collect();
    amps.sort_by(f64::total_cmp);
    let mut amp_anchors: Vec<f64> = Vec::new();
    for a in amps {
        if amp_anchors.last().is_none_or(|&l| a > l * 1.10 + 1e-12) {
            amp_anchors.push(a);
        }
    }
    let amp_group = |a: f64| {
        amp_anchors
            .iter()
            .rposition(|&l| a >= l - 1e-12)
            .unwrap_or(0)
    };
    if frequency_groups >= 3 {
        for i in infos.iter_mut() {
            i.held_out = i.frequency_group % 3 == 1;
        }
    } else if amp_anchors.len() >= 2 {
        for i in infos.iter_mut() {
            i.held_out = amp_group(i.amplitude_a) % 2 == 1;
        }
    } else {
        for (r, &k) in order.iter().enumerate() {
            infos[k].held_out = r % 2 == 1;
        }
    }
    if infos.iter().all(|i| i.held_out) || infos.iter().all(|i| !i.held_out) {
        return Err("could not split the experiments into training and held-out sets".into());
    }
    Ok(Prepared {
        measurements,
        infos,
        rate_hz,
    })
}

/// Pooled RMS residual over the scored samples of experiments `which`.
fn pooled_rms(p: &Prepared, runs: &[Vec<f64>], which: &[usize]) -> f64 {
    let mut sum = 0.0;
    let mut count = 0usize;
    for &k in which {
        let m = &p.measurements[k].displacement_m;
        let s = p.infos[k].settle_samples;
        for (a, b) in m[s..].iter().zip(&runs[k][s..]) {
            sum += (a - b) * (a - b);
        }
        count += m.len() - s;
    }
    if count == 0 {
        0.0
    } else {
        (sum / count as f64).sqrt()
    }
}

fn bands(p: &Prepared, before: &[Vec<f64>], after: &[Vec<f64>]) -> Vec<BandError> {
    let groups = p.infos.iter().map(|i| i.frequency_group).max().unwrap_or(0) + 1;
    (0..groups)
        .filter_map(|g| {
            let which: Vec<usize> = (0..p.infos.len())
                .filter(|&k| p.infos[k].frequency_group == g)
                .collect();
            if which.is_empty() {
                return None;
            }
            let f = which
                .iter()
                .map(|&k| p.infos[k].fundamental_hz)
                .sum::<f64>()
                / which.len() as f64;
            Some(BandError {
                frequency_hz: f,
                before_m: pooled_rms(p, before, &which),
                after_m: pooled_rms(p, after, &which),
                held_out: p.infos[which[0]].held_out,
            })
        })
        .collect()
}

struct FitProblem<'a, F: Fn(&Augmentation, usize) -> Vec<f64> + Sync> {
    effect: EffectName,
    specs: Vec<candidates::ParamSpec>,
    prepared: &'a Prepared<'a>,
    training: &'a [usize],
    sim: &'a F,
    scale_m: f64,
    evaluations: &'a AtomicU64,
    progress: &'a (dyn Fn(u64) + Sync),
}

impl<F: Fn(&Augmentation, usize) -> Vec<f64> + Sync> FitProblem<'_, F> {
    fn values(&self, z: &[f64]) -> Vec<f64> {
        self.specs.iter().zip(z).map(|(s, &z)| s.value(z)).collect()
    }

    fn evaluate(&self, z: &[f64]) -> f64 {
        let aug = candidates::augmentation(self.effect, &self.values(z));
        let runs: Vec<(usize, Vec<f64>)> = self
            .training
            .par_iter()
            .map(|&k| (k, (self.sim)(&aug, k)))
            .collect();
        let mut all = vec![Vec::new(); self.prepared.infos.len()];
        for (k, r) in runs {
            all[k] = r;
        }
        self.evaluations.fetch_add(1, Ordering::Relaxed);
        (self.progress)(1);
        let rms = pooled_rms(self.prepared, &all, self.training) / self.scale_m;
        // Excursions outside the normalized box are clamped by `values`; a small penalty keeps
        // the simplex from drifting there.
        let outside: f64 = z.iter().map(|&v| (v - v.clamp(0.0, 1.0)).powi(2)).sum();
        let cost = rms * rms + outside;
        if cost.is_finite() {
            cost
        } else {
            f64::MAX
        }
    }
}

impl<F: Fn(&Augmentation, usize) -> Vec<f64> + Sync> CostFunction for FitProblem<'_, F> {
    type Param = Vec<f64>;
    type Output = f64;
    fn cost(&self, z: &Self::Param) -> Result<f64, ArgminError> {
        Ok(self.evaluate(z))
    }
}

/// Fits one candidate on the training experiments; returns its physical parameter values and
/// the number of model evaluations.
///
/// The simplex stops after `max_iterations` per parameter, or earlier once the costs at its
/// vertices differ by less than `10⁻³ (σ / scale)²` (standard deviation), σ the white-noise
/// level: the training RMS² then varies across the simplex by a thousandth of the noise's
/// energy, far below what the held-out scoring can resolve.
#[allow(clippy::too_many_arguments)]
fn fit_candidate<F: Fn(&Augmentation, usize) -> Vec<f64> + Sync>(
    effect: EffectName,
    nominal: &Nominal,
    prepared: &Prepared,
    training: &[usize],
    sim: &F,
    options: &DiagnoseOptions,
    noise_m: f64,
    progress: &(dyn Fn(u64) + Sync),
) -> (Vec<f64>, u64) {
    let evaluations = AtomicU64::new(0);
    let scale_m = displacement_range(prepared.measurements).max(1e-12);
    let problem = FitProblem {
        effect,
        specs: candidates::parameters(effect, nominal),
        prepared,
        training,
        sim,
        scale_m,
        evaluations: &evaluations,
        progress,
    };
    let mut starts: Vec<(f64, Vec<f64>)> = candidates::starts(effect, nominal)
        .into_iter()
        .map(|z| (problem.evaluate(&z), z))
        .collect();
    starts.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut best = starts[0].clone();
    // Refine the best start, and the second one too when it is nearly as good (within 50 %):
    // a second basin worth a look.
    let refine = if starts.len() > 1 && starts[1].0 <= 1.5 * starts[0].0 {
        2
    } else {
        1
    };
    for (_, z0) in starts.iter().take(refine) {
        let dim = z0.len();
        let mut simplex = vec![z0.clone()];
        for i in 0..dim {
            let mut v = z0.clone();
            v[i] += if v[i] > 0.85 { -0.12 } else { 0.12 };
            simplex.push(v);
        }
        let tolerance = (1e-3 * (noise_m / scale_m).powi(2)).max(1e-15);
        let Ok(solver) = NelderMead::new(simplex).with_sd_tolerance(tolerance) else {
            continue;
        };
        let problem = problem_ref(&problem);
        let result = Executor::new(problem, solver)
            .configure(|s| s.max_iters(options.max_iterations * dim as u64))
            .run();
        if let Ok(res) = result {
            let state = res.state();
            if let Some(z) = state.get_best_param() {
                let c = state.get_best_cost();
                if c < best.0 {
                    best = (c, z.clone());
                }
            }
        }
    }
    let values = problem.values(&best.1);
    (values, evaluations.load(Ordering::Relaxed))
}

fn problem_ref<'a, F: Fn(&Augmentation, usize) -> Vec<f64> + Sync>(
    p: &FitProblem<'a, F>,
) -> FitProblem<'a, F> {
    FitProblem {
        effect: p.effect,
        specs: p.specs.clone(),
        prepared: p.prepared,
        training: p.training,
        sim: p.sim,
        scale_m: p.scale_m,
        evaluations: p.evaluations,
        progress: p.progress,
    }
}
