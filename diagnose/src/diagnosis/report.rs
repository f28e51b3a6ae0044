//! What a diagnosis reports (`diagnosis.json`): the verdict, every candidate's scores, the
//! nuisances, the experiments and the split.

use crate::breakdown::Where;
use maglab_model::experiments::ExperimentInfo;
use serde::Serialize;
use std::collections::BTreeMap;

pub use super::refit::ConstantsRange;

/// The nuisances estimated (step 2).
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct Nuisance {
    /// `hold` or `linear`.
    pub current_between_samples: String,
    /// RMS residual of the parameter file's model with a held and with a linear current, m.
    pub rms_hold_m: f64,
    /// See above.
    pub rms_linear_m: f64,
    /// Skew of the displacement channel, samples (positive: read after the current sample).
    pub channel_skew_samples: f64,
    /// Sensor offset, m.
    pub sensor_offset_m: f64,
    /// What was estimated, in words.
    pub estimated: Vec<String>,
}

/// Held-out error by frequency band.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct BandError {
    /// Band (frequency group) centre, Hz.
    pub frequency_hz: f64,
    /// RMS residual of the refitted nominal model, m.
    pub before_m: f64,
    /// RMS residual with the candidate, m.
    pub after_m: f64,
    /// Whether the band's experiments were held out.
    pub held_out: bool,
}

/// One candidate's result.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct CandidateResult {
    /// Effect name(s) (`nominal` for the refitted nominal model).
    pub effect: String,
    /// Fitted parameters (physical units), the refitted nominal constants included.
    pub parameters: BTreeMap<String, f64>,
    /// Training RMS of the fit, m.
    pub training_rms_m: f64,
    /// Held-out RMS of the refitted nominal model, m.
    pub held_out_rms_before_m: f64,
    /// Held-out RMS with the candidate, m.
    pub held_out_rms_after_m: f64,
    /// `before / after`.
    pub held_out_reduction: f64,
    /// Held-out systematic gap before / after (noise removed), m.
    pub systematic_before_m: f64,
    /// See above.
    pub systematic_after_m: f64,
    /// Held-out experiments whose error went down.
    pub improved_experiments: usize,
    /// Held-out experiments made worse (RMS up by more than 5 % + 0.1 σ).
    pub worse_experiments: usize,
    /// Held-out experiments.
    pub held_out_experiments: usize,
    /// Held-out RMS of this fit with its (last) effect switched off, m: what remains of the
    /// improvement without the effect itself.
    pub knocked_out_rms_m: f64,
    /// Effect parameters pinned at a physical limit of their range (an implausible explanation).
    pub pinned: Vec<String>,
    /// The refitted constants and the channel skew that ended at an end of their band
    /// ([`maglab_model::fit::Fitted::shared_at_range_end`]): the candidate needed them beyond what the
    /// parameter file allows. Breaks a tie on the held-out experiments ([`super::rules::EQUAL_HELD_OUT`]).
    pub constants_at_range_end: Vec<String>,
    /// Passes the significance criterion.
    pub significant: bool,
    /// Errors per frequency band, every dynamic experiment.
    pub per_band: Vec<BandError>,
    /// Model evaluations spent on the fit.
    pub evaluations: u64,
}

/// A tie on the held-out experiments ([`super::rules::EQUAL_HELD_OUT`]) among the fits that decided the
/// verdict (the significant single candidates, or the pairs of step 8), broken by the constants
/// at an end of their band (module docs, step 7).
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct HeldOutTie {
    /// Every fit in the tie: first the one it went to (the verdict's), then the others in
    /// held-out order.
    pub tied: Vec<TiedFit>,
}

/// One fit of a [`HeldOutTie`].
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct TiedFit {
    /// Effect name(s).
    pub effect: String,
    /// Held-out RMS, m.
    pub held_out_rms_after_m: f64,
    /// As in [`CandidateResult::constants_at_range_end`].
    pub constants_at_range_end: Vec<String>,
}

/// The machine-readable diagnosis (`diagnosis.json`).
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct Diagnosis {
    /// An effect name, `none` or `unexplained`.
    pub verdict: String,
    /// Why, in one sentence.
    pub verdict_reason: String,
    /// How much of the gap the verdict accounts for ([`super::grade`]): `none`, `effect`,
    /// `pair`, `either` ("X or Y"), `partly_explained` (with [`Diagnosis::partly_explained`]) or
    /// `unexplained`.
    pub grade: super::grade::Grade,
    /// For the grade `partly_explained`: the effect, its share of the gap and the share's spread
    /// over the held-out bands; the verdict stays `unexplained` (the rest is).
    pub partly_explained: Option<super::grade::PartialExplanation>,
    /// For the grade `either`: the verdict's effect and the one the experiments cannot separate
    /// from it; for `partly_explained`, the partly explaining effect and the one that enters the
    /// same term of the model when the dataset does not record the coil current
    /// ([`super::grade::SAME_TERM`]): "partly explained by X or Y".
    pub either: Vec<String>,
    /// What to record next to separate the verdict from the candidates beside it
    /// ([`super::advice`]): the recording, why it separates them, the command that writes it.
    pub advice: Vec<super::advice::Advice>,
    /// Candidates whose held-out error is within 10 % of the winner's.
    pub ambiguous_with: Vec<String>,
    /// Significant single candidates whose training RMS is within [`super::rules::EQUAL_ON_TRAINING`] of a
    /// single winner's: the training experiments cannot tell them from the verdict, only the
    /// held-out ones rank them.
    pub equal_on_training: Vec<String>,
    /// The tie on the held-out experiments that the verdict's fit was in (none when its
    /// held-out error was more than [`super::rules::EQUAL_HELD_OUT`] from every other eligible fit's).
    pub held_out_tie: Option<HeldOutTie>,
    /// Further effects found by the second stage.
    pub additional_effects: Vec<String>,
    /// The second stage: every other candidate refitted on top of the winner (empty when it did
    /// not run), scored against the winner alone.
    pub second_stage: Vec<CandidateResult>,
    /// Why the second stage ran, in which form, or why not (step 8), in words; after a small
    /// remainder also why its best pair was not named when its second effect was not specific.
    pub second_stage_reason: String,
    /// The significance criterion, in words.
    pub criterion: String,
    /// Estimated white-noise level σ, m.
    pub noise_m: f64,
    /// Measured displacement range over the dynamic experiments, m.
    pub displacement_range_m: f64,
    /// RMS residual of the parameter file's model (with the nuisances), dynamic experiments, m.
    pub nominal_rms_m: f64,
    /// Its systematic gap, m.
    pub nominal_systematic_m: f64,
    /// The model's own integration error on the held-out experiments, m: the RMS difference
    /// (mean removed) between the refitted nominal model's prediction with the diagnosis's
    /// substeps and with twice as many. A gap up to [`super::rules::MODEL_ERROR_FACTOR`] times it is `none`.
    pub model_error_m: f64,
    /// Electromagnetic substeps per sample of this diagnosis's model (Richardson-extrapolated
    /// with twice as many).
    pub substeps: usize,
    /// Why the substeps were raised above the requested ones, if they were.
    pub substeps_raised: Option<String>,
    /// The verdict is `none` only because the gap is within the model's integration error (the
    /// noise-based rule alone would not have said `none`; `--substeps` gives a finer model).
    pub none_by_model_error: bool,
    /// How far the refit could move the constants, and why (step 6).
    pub constants_range: ConstantsRange,
    /// The other single candidates that meet the naming criterion alone, best first: the
    /// data are consistent with them too; the verdict is the one with the lowest held-out
    /// error ([`super::verdict::also_significant`]).
    pub also_significant: Vec<AlsoSignificant>,
    /// Effects beyond the paper's model that the parameter file models because its
    /// identification found them in the data (`provenance.identified`: a reversible part
    /// `maglab identify --reversible auto` kept). They are part of the verdict: the rig
    /// differs from the paper's model by them, though not from the file's.
    pub effects_in_parameter_file: Vec<String>,
    /// The warnings `maglab identify` recorded in the parameter file (`provenance.warnings`:
    /// its model did not describe the data it was identified from), repeated so that a verdict
    /// is never read without them.
    pub parameter_file_warnings: Vec<String>,
    /// The dataset's dynamic loops that the parameter file's masses were not measured on
    /// ([`super::coverage`]): there the model predicts by the identification's smoothness
    /// alone, and a gap may be the masses'.
    pub unmeasured_loops: Vec<super::coverage::UnmeasuredLoop>,
    /// The warning for them, repeated next to the verdict (`None`: every loop measured, or a
    /// file that does not record where its masses were measured).
    pub unmeasured_loops_warning: Option<String>,
    /// The parameter file's datasheet values and the candidate parameter each bounds
    /// (`maglab_model::priors`; empty without a `datasheet` section).
    pub datasheet_priors: Vec<serde_json::Value>,
    /// What the coil-current channel said of the amplifier, when the dataset records it
    /// ([`super::coil_current`]); then every candidate below was fitted on the measured current.
    pub coil_current: Option<super::coil_current::AmplifierJudgement>,
    /// The refitted nominal model (step 6).
    pub refitted_nominal: CandidateResult,
    /// The nuisances (step 2).
    pub nuisance: Nuisance,
    /// Experiments and the split.
    pub experiments: Vec<ExperimentInfo>,
    /// Candidates, best first (held-out RMS).
    pub ranking: Vec<CandidateResult>,
    /// Where the parameter file's model disagrees.
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
    /// The parameter file's model with the nuisances, m.
    pub nominal_m: Vec<f64>,
    /// The verdict's model (the refitted nominal one for `none` / `unexplained`), m.
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

/// A single candidate that meets the naming criterion alone but is not the verdict's
/// ([`Diagnosis::also_significant`]).
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct AlsoSignificant {
    /// Effect name.
    pub effect: String,
    /// Its held-out reduction (refitted nominal RMS / with the effect).
    pub held_out_reduction: f64,
}
