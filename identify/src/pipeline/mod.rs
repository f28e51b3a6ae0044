//! The whole identification of a recorded dataset: [`identify`] turns a dataset folder and a
//! base parameter file into the identified parameter file, what `maglab identify` writes.
//!
//! Steps, each in its own module:
//!
//! 1. **Masses** ([`crate::masses`]): the Preisach cell masses from the quasi-static records,
//!    corrected for the base file's lags of `R_eddy`, `ξ`, `f0`; with `--reversible auto`,
//!    with or without a reversible part ([`reversible`]).
//! 2. **Dynamics** ([`dynamic`]): `R_eddy`, `ξ` by the paper's phase-lag scheme, then `R_eddy`,
//!    `ξ`, `f0` by a waveform fit with the recording's nuisances estimated (the model of
//!    `maglab-model`, the one `maglab diagnose` refits: an identified file is what the
//!    diagnosis' refit gives on the same data).
//! 3. **Alternation** ([`passes`]): the masses depend on the lags, the lags on the masses; the
//!    two are fitted in turn until the constants settle, and the pass that fits the sines best
//!    is kept.
//! 4. **Checks** ([`checks`]): does the result describe the data it came from? Each failed
//!    check is a warning in the result and in `provenance.warnings`.
//!
//! Without dynamic records `R_eddy`, `ξ`, `f0` are the base file's, and the provenance says so.

pub mod checks;
pub mod dynamic;
pub mod passes;
pub mod reversible;

use crate::dynamics::{DynamicFit, DynamicOptions, Progress};
use crate::experiments::{load_split_dataset, ClassifyOptions, DynamicExperiment, SplitDataset};
use crate::masses::{identify_masses, MassIdentification, MassOptions};
use actuator_params::{ActuatorParams, ParamsError};
use maglab_dataset::data::Measurement;
use maglab_dataset::dataset_info::DatasetInfo;
use maglab_dataset::DataError;
use maglab_model::coil_current::{self, AmplifierJudgement};
use std::fmt;
use std::path::Path;

pub use passes::{ChosenPass, PassRecord};
pub use reversible::{ReversibleChoice, ReversiblePart};

/// A recorded dataset as the identification reads it: the files split into quasi-static and
/// dynamic experiments, and the folder's `dataset.json` when it has one.
#[derive(Debug, Clone)]
pub struct RecordedDataset {
    /// The experiments as recorded (`current_a` the command): their classification, the reach,
    /// the masses and the checks go by what the bench drove.
    pub split: SplitDataset,
    /// What the bench documented.
    pub documented: Option<DatasetInfo>,
    /// The amplifier judged on the commanded against the measured current, when the dataset
    /// records it (`None`: the commanded current is the model's input).
    pub amplifier: Option<AmplifierJudgement>,
    /// With the coil current recorded, the dynamic experiments with the measured current, its
    /// monitor noise taken out, as their `current_a`
    /// (`maglab_model::coil_current::coil_current_input`): the dynamic
    /// model's input, so that the rod is identified from the current in its coil, whatever the
    /// amplifier made of the command.
    dynamic_on_measured_current: Option<Vec<DynamicExperiment>>,
    /// With the coil current recorded, the quasi-static experiments with the coil current at
    /// their sample instants (`maglab_model::coil_current::coil_current_at_samples`): what the
    /// masses are fitted on.
    quasi_static_on_coil_current: Option<Vec<Measurement>>,
}

impl RecordedDataset {
    /// Reads the folder `dir` (errors name the file, line, column or field).
    pub fn load(dir: &Path, classify: &ClassifyOptions) -> Result<Self, DataError> {
        let split = load_split_dataset(dir, classify)?;
        let (amplifier, dynamic_on_measured_current, quasi_static_on_coil_current) =
            match on_coil_current_channel(&split)? {
                Some((a, d, q)) => (Some(a), Some(d), Some(q)),
                None => (None, None, None),
            };
        Ok(RecordedDataset {
            documented: DatasetInfo::load(dir)?,
            split,
            amplifier,
            dynamic_on_measured_current,
            quasi_static_on_coil_current,
        })
    }

    /// The quasi-static experiments as the masses are fitted on them: with the coil current
    /// recorded, the coil current at their sample instants; else as recorded.
    pub fn quasi_static_input(&self) -> maglab_dataset::data::Dataset {
        let mut dataset = self.split.quasi_static_dataset();
        if let Some(q) = &self.quasi_static_on_coil_current {
            dataset.measurements = q.clone();
        }
        dataset
    }

    /// Whether the dynamic model's input is the measured coil current.
    pub fn measured_current_input(&self) -> bool {
        self.dynamic_on_measured_current.is_some()
    }

    /// The dynamic experiments as the dynamic model takes them: with the measured coil current
    /// when the dataset records it, else as recorded.
    pub fn dynamic_input(&self) -> &[DynamicExperiment] {
        self.dynamic_on_measured_current
            .as_deref()
            .unwrap_or(&self.split.dynamic)
    }
}

/// With the coil current recorded in every file of both sub-folders
/// (`maglab_dataset::data::coil_current_recorded`, an error when only some have it): the
/// amplifier judged on the command against it, the dynamic experiments with the measured current
/// as their current (its monitor noise taken out:
/// `maglab_model::coil_current::coil_current_input`), and the quasi-static ones with it at their
/// sample instants (`maglab_model::coil_current::coil_current_at_samples`).
#[allow(clippy::type_complexity)]
fn on_coil_current_channel(
    split: &SplitDataset,
) -> Result<Option<(AmplifierJudgement, Vec<DynamicExperiment>, Vec<Measurement>)>, DataError> {
    let all: Vec<&Measurement> = split
        .quasi_static
        .iter()
        .chain(split.dynamic.iter().map(|d| &d.measurement))
        .collect();
    if !maglab_dataset::data::coil_current_recorded(&all)? {
        return Ok(None);
    }
    let owned: Vec<Measurement> = all.into_iter().cloned().collect();
    let Some(judgement) = coil_current::judge(&owned) else {
        return Ok(None);
    };
    // Each record as `maglab_model::coil_current::with_measured_current` takes it: a dynamic one
    // with its interval means kept, a quasi-static one (the masses are fitted on them) at its
    // sample instants.
    let taken = |m: &Measurement, slow: bool| {
        coil_current::on_measured_current(m, slow, &judgement).unwrap_or_else(|| m.clone())
    };
    let dynamic = split
        .dynamic
        .iter()
        .map(|d| DynamicExperiment {
            measurement: taken(&d.measurement, false),
            ..d.clone()
        })
        .collect();
    let quasi_static = split.quasi_static.iter().map(|m| taken(m, true)).collect();
    Ok(Some((judgement, dynamic, quasi_static)))
}

/// The base parameter file: the grid, the constants the data do not give, the prior masses and
/// the start of every search.
#[derive(Debug, Clone, Copy)]
pub struct Base<'a> {
    /// The file's contents.
    pub params: &'a ActuatorParams,
    /// Where it came from, for the provenance.
    pub name: &'a str,
}

/// Settings of [`identify`].
#[derive(Debug, Clone, PartialEq)]
pub struct IdentifyOptions {
    /// The mass fit (its lag correction and current timing are set by the passes).
    pub masses: MassOptions,
    /// Whether the model gets a reversible part.
    pub reversible: ReversiblePart,
    /// The phase-lag scheme.
    pub dynamics: DynamicOptions,
    /// Fit `R_eddy`, `ξ`, `f0` to the waveforms after the phase-lag scheme (`false`: the
    /// scheme's `R_eddy`, `ξ` and the base `f0` are written).
    pub waveform_fit: bool,
    /// Electromagnetic substeps per sample of the waveform fit's model (`None`: enough for the
    /// highest fitted frequency, `crate::dynamics::waveform::substeps_for`).
    pub substeps: Option<usize>,
}

impl Default for IdentifyOptions {
    /// `maglab identify`'s defaults: the sign of `M` and each record's start from the data, a
    /// 1 % zero band, smoothness 1e-8 (a Terfenol-like density is sharply peaked; a stronger
    /// prior biases the central masses), unexcited cells kept at the base file's masses, the
    /// reversible part decided from the data, the waveform fit on.
    fn default() -> Self {
        let reversible = ReversiblePart::Auto;
        IdentifyOptions {
            masses: MassOptions {
                branch: None,
                initial: None,
                documented: None,
                zero_band_fraction: 0.01,
                fit: crate::fit::FitOptions {
                    smoothness: 1e-8,
                    unexcited: crate::fit::Unexcited::KeepPrior,
                    reversible: reversible.first_fit(),
                    ..crate::fit::FitOptions::default()
                },
                lag_correction: None,
                current_shift_samples: 0.0,
                reach: None,
            },
            reversible,
            dynamics: DynamicOptions::default(),
            waveform_fit: true,
            substeps: None,
        }
    }
}

/// What [`identify`] found.
#[derive(Debug, Clone)]
pub struct Identified {
    /// The identified parameter file, validated, its provenance complete (warnings included).
    pub params: ActuatorParams,
    /// The masses of the kept pass and how they fit each quasi-static record.
    pub masses: MassIdentification,
    /// The dynamic identification of the kept pass (none without dynamic records or with the
    /// waveform fit off and no dynamic records).
    pub dynamic: Option<DynamicFit>,
    /// The alternation (none without dynamic records or without the waveform fit).
    pub passes: Option<ChosenPass>,
    /// `--reversible auto`'s decision (none for `none` and `piecewise`).
    pub reversible: Option<ReversibleChoice>,
    /// Every check the result failed (also in `provenance.warnings`).
    pub warnings: Vec<String>,
}

/// Why an identification could not be made.
#[derive(Debug)]
pub enum IdentifyError {
    /// The dataset cannot be identified from (no quasi-static records, ...).
    Dataset(String),
    /// A step failed; the text names it.
    Step(String),
    /// The identified parameters do not validate.
    Invalid(ParamsError),
}

impl fmt::Display for IdentifyError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            IdentifyError::Dataset(s) | IdentifyError::Step(s) => f.write_str(s),
            IdentifyError::Invalid(_) => f.write_str("the identified parameters do not validate"),
        }
    }
}

impl std::error::Error for IdentifyError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            IdentifyError::Invalid(e) => Some(e),
            _ => None,
        }
    }
}

impl IdentifyError {
    /// A failed step: `what` and the error.
    pub fn step(what: &str, error: impl fmt::Display) -> Self {
        IdentifyError::Step(format!("{what}: {error}"))
    }
}

/// The provenance entry of the amplifier judged on the coil-current channel.
pub const AMPLIFIER_KEY: &str = "coil_current";

/// The provenance entry of the datasheet priors the fits used (`maglab_model::priors`).
pub const PRIORS_KEY: &str = "datasheet_priors";

/// Identifies `dataset` from `base` (see the module docs); `progress` reports the phase-lag
/// scheme's grid (called from worker threads).
pub fn identify(
    dataset: &RecordedDataset,
    base: Base<'_>,
    options: &IdentifyOptions,
    progress: &Progress<'_>,
) -> Result<Identified, IdentifyError> {
    let split = &dataset.split;
    if split.quasi_static.is_empty() {
        return Err(IdentifyError::Dataset(format!(
            "{}: no quasi-static files: the Preisach masses need quasi-static data (a FORC sweep \
             from `maglab excite`, slow loops); see docs/identification.md",
            split.dir.display()
        )));
    }
    let dynamic_stage = dynamic::DynamicStage {
        dataset,
        options,
        progress,
    };
    let quasi_static = dataset.quasi_static_input();
    let FirstMasses {
        masses,
        options: mass_options,
        first_pass,
        reversible,
    } = first_masses(&dynamic_stage, base, &quasi_static)?;
    let (masses, dynamic, chosen) =
        fit_dynamics(&dynamic_stage, base, &mass_options, masses, first_pass)?;
    let mut params = masses.params.clone();
    if let Some(fit) = &dynamic {
        crate::dynamics::record::record(&mut params, fit, split);
        params
            .validate("identified parameters")
            .map_err(IdentifyError::Invalid)?;
    }
    record_provenance(
        &mut params,
        (chosen.as_ref(), reversible.as_ref()),
        dataset,
        base,
        &quasi_static,
    );
    let warnings = checks::warnings(
        &masses,
        dynamic.as_ref(),
        base.params,
        &quasi_static,
        &split.dynamic,
    );
    if !warnings.is_empty() {
        params.provenance.details.insert(
            actuator_params::Provenance::WARNINGS.into(),
            serde_json::json!(warnings),
        );
    }
    Ok(Identified {
        params,
        masses,
        dynamic,
        passes: chosen,
        reversible,
        warnings,
    })
}

/// The masses from the quasi-static records before the dynamics are fitted, with the options
/// they were fitted with and `--reversible auto`'s decision (and the dynamic fit it made).
struct FirstMasses {
    masses: MassIdentification,
    options: MassOptions,
    first_pass: Option<DynamicFit>,
    reversible: Option<ReversibleChoice>,
}

/// The first fit of the masses (their lags corrected with the base file's constants), and with
/// `--reversible auto` the choice of the reversible part ([`reversible::choose`]).
fn first_masses(
    stage: &dynamic::DynamicStage<'_>,
    base: Base<'_>,
    quasi_static: &maglab_dataset::data::Dataset,
) -> Result<FirstMasses, IdentifyError> {
    let options = stage.options;
    let mut mass_options = MassOptions {
        documented: stage.dataset.documented.clone(),
        lag_correction: Some(passes::constants_of(base.params)),
        current_shift_samples: 0.0,
        reach: stage
            .dataset
            .split
            .reach(base.params.actuator.coil_factor_per_m),
        ..options.masses.clone()
    };
    mass_options.fit.reversible = options.reversible.first_fit();
    let masses = identify_masses(quasi_static, base.params, base.name, &mass_options)
        .map_err(|e| IdentifyError::step("Preisach masses", e))?;
    if options.reversible != ReversiblePart::Auto {
        return Ok(FirstMasses {
            masses,
            options: mass_options,
            first_pass: None,
            reversible: None,
        });
    }
    let decided = reversible::choose(stage, base, &mass_options, masses)?;
    Ok(FirstMasses {
        masses: decided.masses,
        options: decided.options,
        first_pass: decided.first_pass,
        reversible: Some(decided.choice),
    })
}

/// R_eddy, ξ, f0 and the instruments from the dynamic records, `(masses, dynamic fit, kept
/// pass)`: with the waveform fit, the alternation of masses and constants from the first pass
/// ([`passes::alternate`]), whose kept pass gives the masses; without it, one fit on `masses`.
/// Without dynamic records, `masses` alone.
fn fit_dynamics(
    stage: &dynamic::DynamicStage<'_>,
    base: Base<'_>,
    mass_options: &MassOptions,
    masses: MassIdentification,
    first_pass: Option<DynamicFit>,
) -> Result<(MassIdentification, Option<DynamicFit>, Option<ChosenPass>), IdentifyError> {
    if stage.dataset.split.dynamic.is_empty() {
        return Ok((masses, None, None));
    }
    if !stage.options.waveform_fit {
        let fit = stage.fit(&masses.params, None)?;
        return Ok((masses, Some(fit), None));
    }
    let first = match first_pass {
        Some(fit) => fit,
        None => stage.fit(&masses.params, None)?,
    };
    let kept = passes::alternate(stage, base, mass_options, first)?;
    Ok((kept.masses.clone(), Some(kept.fit.clone()), Some(kept)))
}

/// The identified file's provenance: the masses' lag correction of the kept pass, the
/// reversible part's decision, the amplifier judged on the coil current, the datasheet priors
/// used and the loops the quasi-static records measured.
fn record_provenance(
    params: &mut ActuatorParams,
    (chosen, reversible): (Option<&ChosenPass>, Option<&ReversibleChoice>),
    dataset: &RecordedDataset,
    base: Base<'_>,
    quasi_static: &maglab_dataset::data::Dataset,
) {
    let details = &mut params.provenance.details;
    if let Some(kept) = chosen {
        details.insert("masses_lag_correction".into(), kept.provenance());
    }
    if let Some(choice) = reversible {
        details.insert(reversible::PROVENANCE_KEY.into(), choice.provenance());
    }
    if let Some(amplifier) = &dataset.amplifier {
        details.insert(
            AMPLIFIER_KEY.into(),
            serde_json::json!({
                "input": "the measured coil current (coil_current_a): the rod was identified from \
                          the current in its coil, the amplifier from the command against it",
                "judgement": amplifier,
            }),
        );
    }
    let priors = maglab_model::priors::uses_of(base.params);
    if !priors.is_empty() {
        details.insert(
            PRIORS_KEY.into(),
            serde_json::Value::Array(priors.iter().map(|u| u.to_json()).collect()),
        );
    }
    if let Some(measured) = crate::coverage::measured_loops(quasi_static, &dataset.split.dynamic) {
        details.insert(
            crate::coverage::MeasuredLoops::PROVENANCE_KEY.into(),
            measured.to_json(),
        );
    }
}
