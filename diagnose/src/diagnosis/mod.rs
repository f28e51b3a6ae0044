//! `maglab diagnose`: where the measured data and the nominal model disagree, which unmodelled
//! effect explains it, and how far the gap shrinks once that effect is added.
//!
//! # Steps
//!
//! Each step has its module (private ones named without a link): `recording` (steps 1–5, with
//! `split`), `singles` (6–7), `pairs` (8), `verdict`, `assemble` (the report, with [`grade`] and
//! [`advice`], steps 9–10); `scoring` scores a fit, [`rules`] holds
//! every tuned constant, `report` what `diagnosis.json` holds.
//!
//! 1. **Experiments.** Each record's fundamental (the dominant frequency of its current),
//!    amplitude and bias. Records whose fundamental is below [`maglab_model::experiments::QUASI_STATIC_BELOW_HZ`] (reversal
//!    sweeps, slow loops) are *quasi-static*: they enter the "where" breakdown only. The first
//!    `max(one period, 2 %)` of each record (at most 25 %) is not scored: it holds the start-up
//!    transient.
//! 2. **Nuisances** (estimated, never asked for; the report says what was estimated), with the
//!    parameter file's model:
//!    * the start state of each experiment: as `dataset.json` documents it, else the one of
//!      `switch-on-demagnetized`, `demagnetized`, `negative-saturation`, `positive-saturation`,
//!      `previous` that fits it best (the memory left outside a periodic loop sets a constant
//!      offset of `M`, so a wrong start is a systematic error); an experiment that continues a
//!      quasi-static record (the reversal sweep in front of the sines) starts from the memory
//!      that record leaves, simulated once (`lead_in_memory`), not in every fit;
//!    * the current between samples (held or linear: half a sample of delay apart);
//!    * the sub-sample skew of the displacement channel against the current channel (within
//!      ±1 sample; golden-section search);
//!    * the sensor offset (one per dataset, least squares in closed form);
//!    * not a nuisance but beside them, [`coverage`]: the dynamic loops the parameter file's
//!      masses were not measured on (when `maglab identify` recorded where they were),
//!      reported beside the verdict.
//! 3. **Noise level.** σ is the white-noise level of the residual above 0.3·f_s
//!    ([`maglab_signal::noise::white_noise_sigma`]), median over experiments. The *systematic gap* of a
//!    residual with RMS `e` is `g = √max(e² − σ², 0)`.
//! 4. **Where** ([`crate::breakdown`]): the residual of the parameter file's model (with the
//!    nuisances) per experiment and per frequency band, each band's disagreement measured against
//!    max(2σ, 1 % of the motion).
//! 5. **Split.** Experiments are grouped by fundamental (within 5 %) and amplitude (within 10 %).
//!    Held out: the highest frequency group (outside the training span in frequency) and, with
//!    three or more amplitude groups, the highest amplitude group (outside it in amplitude); with
//!    two amplitude groups, the higher one at every other frequency (so that training still sees
//!    how the response depends on amplitude); with one frequency group, every other amplitude
//!    group, else every other experiment.
//! 6. **Candidates** ([`maglab_model::candidates`], [`maglab_model::fit`]). The nominal model with its dynamic
//!    constants (`R_eddy`, `ξ`, `f0`) and the skew refitted on the training experiments (within
//!    [`ConstantsRange`]: narrow for a file's constants, wide for those `maglab identify` fitted
//!    from data, which may have absorbed an effect), and the
//!    same plus each effect of the library, fitted by Levenberg-Marquardt from a small grid of
//!    starts (the effects in parallel, rayon): the effect's library starts, each with the
//!    refitted constants and the file's, and for a lag (amplifier, sensor, load) on an `f0`
//!    identified from data also with that `f0` raised by the square root of its refit factor
//!    (the identification reads a lag as a lower `f0`; `singles::common_starts`).
//! 7. **Score and verdict** on the held-out experiments, against the *refitted* nominal model:
//!    * `none` when the refitted nominal model's held-out systematic gap is below the resolution
//!      of the gap estimate ([`rules::resolution_floor`] = max(0.35 σ, 0.05 % of the motion)) or
//!      [`rules::MODEL_ERROR_FACTOR`] = 1.5 times the model's own integration error (measured: the
//!      refitted nominal model against itself with twice the substeps,
//!      [`Diagnosis::model_error_m`]; with little noise the integration error, not the noise,
//!      limits what the data can show), or not above [`rules::none_threshold`] = max(σ, 0.2 % of the
//!      motion) (at least that floor) and no candidate explains it;
//!    * a candidate is **significant** when its held-out systematic gap is at most
//!      [`rules::EXPLAINED_RATIO`] = 0.3 of the refitted nominal one (it removes ≥ 91 % of the gap's
//!      energy) — or at most [`rules::WITHIN_NOISE_RATIO`] = 0.5 of it and below [`rules::none_threshold`]
//!      (what is left is within the noise) — and it makes at most a
//!      quarter of the held-out experiments worse (RMS up by more than 5 % + 0.1 σ): the
//!      verdict is the significant candidate with the lowest held-out error, else `unexplained`
//!      — where another significant one comes within [`rules::EQUAL_HELD_OUT`] (1 %), a tie the data do
//!      not resolve, the one that needs fewer of the refitted constants and the skew at an end
//!      of their band (the same rule picks among the pairs of step 8; the tie the verdict's fit
//!      was in is recorded, [`Diagnosis::held_out_tie`]);
//!    * candidates within 10 % of the winner's held-out error are listed as `ambiguous_with`
//!      (and the verdict graded "X or Y", [`grade`], as it is when one fits the training
//!      experiments as well and falls behind on the held-out ones by less than the winner's own
//!      systematic misfit on the training ones);
//!      significant candidates that fit the training experiments as well as a single winner
//!      (training RMS within [`rules::EQUAL_ON_TRAINING`]) as `equal_on_training`: between them only the
//!      extrapolation to the held-out experiments decides;
//!    * the other significant single candidates are listed as `also_significant` (none after
//!      `none`): the data are consistent with them too.
//! 8. **Second stage** (forward selection). When the winner leaves a held-out gap above max(2σ, a
//!    tenth of the refitted nominal gap) — or when no candidate is significant alone but one
//!    removes at least a third of the gap's energy ([`rules::PROMISING`]: two strong effects; a
//!    candidate that pins a parameter counts, as alone it may stretch to a limit to cover both),
//!    or three quarters of the *training* gap's energy ([`rules::PROMISING_TRAINING`]: each of two
//!    effects may fit the training experiments alone and extrapolate only with the other) —
//!    every pair among the [`rules::PAIR_CANDIDATES`] best single candidates and the candidates that fit
//!    one frequency band best (up to two more: a slow and a fast effect each show in their own
//!    bands) is refitted, and so are the best single candidate and the runner-up (the next that
//!    pins nothing) each with every other effect of the library (forward selection: an effect
//!    the first one masks fits badly alone, and the best single may stand in for both). The
//!    best pair is named (the second effect as an `additional_effect`) when its held-out gap is at most
//!    half the first effect's alone and half the refitted nominal one, it makes at most a
//!    quarter of the held-out experiments worse, pins no parameter, and both its effects are
//!    needed: with either switched off and the rest refitted, the gap is at least twice as large.
//!    When the winner leaves less than that but more than [`rules::SMALL_REMAINDER_NOISE`] σ and
//!    [`rules::SMALL_REMAINDER_SHARE`] of the refitted nominal gap, only the winner's forward selection
//!    runs (the winner with each other effect of the library, under the same test): a weak
//!    second effect the winner's fit mostly absorbs (an amplifier lag beside a sensor lag) leaves
//!    a few % of the gap, below twice the noise, and the winner stays in the pair. There the
//!    second effect must also be specific: the next pair (another effect in its place) still
//!    leaves [`rules::SPECIFIC_NEXT_SHARE`] of the winner's remainder and the best pair at most
//!    [`rules::SPECIFIC_SECOND_RATIO`] of what the next leaves; else the remainder is the winner's
//!    form differing from the plant's, not a second effect, and no pair is named.
//!    (No rule on the second effect's share of the *nominal* gap: when the first effect's fit
//!    absorbs most of the second — thermal drift or a lag taking ΔE's amplitude dependence — the
//!    share is small although the second effect removes 90 % of what the first leaves.)
//!    When the best pair fails because one of its effects is not needed, the refit of the other
//!    alone (started from the pair's optimum) replaces that effect's single fit if it fits the
//!    training experiments better — a better optimum of the same candidate — and the verdict is
//!    taken again from the single candidates.
//!    When no pair is named, the pair with an effect that has a richer form
//!    ([`maglab_model::candidates::RICHER_FORM`]: eddy currents with a second path, a load with a
//!    second mass) that fits the training experiments best — if it fits them at least as well
//!    as the best pair (the one best on the held-out experiments), or is that pair — is
//!    refitted with that effect in its richer form (started from the pair's optimum and from
//!    the effect's library starts) and named if it passes the same
//!    test: a rod's eddy currents diffuse, and one path stretched to cover a ladder of them
//!    may fit the training experiments and miss the top band. When that pair fails because its
//!    other effect is not needed, the
//!    richer effect alone (its knock-out refit, from the pair's optimum) is judged as a single
//!    candidate is — significant against the refitted nominal model, nothing pinned — and
//!    named in its richer form when its second term is needed; else its library form refitted
//!    from there is taken up by the single candidates.
//!    **One effect before two.** When a pair is named and one of its effects has a richer form
//!    (a second eddy path or load mass), that effect alone in its richer form is fitted (from its values in
//!    the pair and its single fit, with each library start, one group of starts per start of
//!    the second term, each group refined). If it leaves no more of the held-out gap than the
//!    pair (within the gap estimate's resolution [`rules::resolution_floor`]), pins nothing and makes
//!    at most a quarter of the held-out experiments worse, it replaces the pair: named in its
//!    richer form when its second term is needed, else its library form refitted from the
//!    richer optimum is taken up by the single candidates (a better optimum of the same
//!    candidate, as above): a one-mode fit of a two-mode load can stop in a local minimum, and
//!    an eddy path then mops up the rest.
//! 9. **Grade** ([`grade`]): the verdict as graded — an effect, a pair, "X or Y" when the
//!    experiments cannot separate two, "partly explained by X", `unexplained` or `none`.
//! 10. **Advice** ([`advice`]): for the candidates left unseparated, the recording that would
//!     separate them on this rig, the loops the parameter file's masses lack first.
//!
//! **Significance** (steps 7 and 8) is a knock-out test as well: the candidate's held-out gap
//! must also be at most [`rules::EXPLAINED_RATIO`] of what its own fit gives with its effect switched off (so the
//! improvement is the effect's, not a better optimum of the shared constants), and no effect
//! parameter may be pinned at a physical limit of its range ([`maglab_model::candidates::Edge`]): an
//! explanation that needs an implausible effect is none.

pub mod advice;
mod assemble;
pub mod coil_current;
pub mod coverage;
pub mod grade;
mod pairs;
mod recording;
mod refit;
mod report;
pub mod rules;
mod scoring;
mod singles;
mod split;
mod verdict;

pub use refit::constants_range;
pub use report::{
    AlsoSignificant, BandError, CandidateResult, ConstantsRange, Diagnosis, DiagnosisRun,
    HeldOutTie, Nuisance, TiedFit, Trace,
};
pub use rules::{
    none_threshold, resolution_floor, CRITERION, IDENTIFIED_REFIT_RANGE, MODEL_ERROR_FACTOR,
};
pub use scoring::{held_out_tie_break, TieIndices};
pub use verdict::{also_significant, effects_identified_into, equal_on_training, LAG_EFFECTS};

use maglab_dataset::data::Measurement;
use maglab_dataset::dataset_info::DatasetInfo;
use maglab_model::effects::EffectName;
use maglab_model::experiments::{experiment_data, ExperimentInfo};
use maglab_model::fit::{ExperimentData, FitSettings};
use maglab_model::plan_fit::{PlanFit, PlanFitter};
use rules::MAX_SUBSTEPS_FACTOR;
use scoring::Scorer;
use singles::{Gaps, Stage};

/// Settings of the diagnosis.
#[derive(Debug, Clone, PartialEq)]
pub struct DiagnoseOptions {
    /// Electromagnetic substeps per sample (Richardson-extrapolated with twice as many).
    pub substeps: usize,
    /// Fit settings.
    pub fit: FitSettings,
    /// The candidate effects (the whole library by default; without the amplifier when the
    /// dataset records the coil current, [`coil_current`]).
    pub library: Vec<EffectName>,
    /// The measurements' `current_a` is the measured coil current, not the command
    /// ([`coil_current`]): a sampled continuous signal, read linear between samples (a held
    /// reading would be half a sample of delay that no amplifier or DAC makes), with the
    /// SAME_TERM pairs separated and no advice to record it.
    pub measured_current_input: bool,
    /// With the measured current as the input, the experiments as commanded: the advised
    /// recordings are commands, so their amplitudes and biases are the command's, not the coil
    /// current's, which an amplifier's lag shrinks at high frequencies (`None`: the input is the
    /// command, the advice reads the experiments the diagnosis fits).
    pub commanded_experiments: Option<Vec<ExperimentInfo>>,
}

impl Default for DiagnoseOptions {
    fn default() -> Self {
        DiagnoseOptions {
            substeps: 1,
            fit: FitSettings::default(),
            library: EffectName::LIBRARY.to_vec(),
            measured_current_input: false,
            commanded_experiments: None,
        }
    }
}

/// Runs the diagnosis on `measurements` with the nominal parameters; `documented` is the
/// dataset's `dataset.json` when it has one.
///
/// When the dataset records the coil current the chain is split at the coil
/// ([`coil_current`]): the amplifier is judged on the commanded against the measured current,
/// the rest of the library on the measured current against the displacement
/// ([`diagnose_displacement`] with the measured current as the input and no amplifier
/// candidate), and the two verdicts are put together.
pub fn diagnose(
    params: &actuator_params::ActuatorParams,
    measurements: &[Measurement],
    documented: Option<&DatasetInfo>,
    options: &DiagnoseOptions,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<DiagnosisRun, String> {
    let Some(judgement) = coil_current::judge(measurements) else {
        return diagnose_displacement(params, measurements, documented, options, progress);
    };
    let step_s = measurements.first().map_or(1.0, |m| m.step_s);
    let commanded = maglab_model::experiments::describe(measurements, 1.0 / step_s);
    let quasi_static: Vec<bool> = commanded.iter().map(|i| i.quasi_static).collect();
    let on_current = coil_current::with_measured_current(measurements, &quasi_static, &judgement)
        .ok_or("the coil current is recorded in some experiments only")?;
    let without_amplifier = DiagnoseOptions {
        library: options
            .library
            .iter()
            .copied()
            .filter(|e| *e != EffectName::AmplifierBandwidth)
            .collect(),
        measured_current_input: true,
        commanded_experiments: Some(commanded),
        ..options.clone()
    };
    let mut run = diagnose_displacement(
        params,
        &on_current,
        documented,
        &without_amplifier,
        progress,
    )?;
    coil_current::combine(judgement, &mut run.diagnosis);
    Ok(run)
}

/// The diagnosis of the displacement against the current the measurements hold.
///
/// When the refitted nominal model's held-out gap is above the noise-based `none` threshold but
/// within [`MODEL_ERROR_FACTOR`] times the model's own integration error (little noise, or a low
/// sample rate against the excitation), the model cannot tell an effect of that size from its own
/// error: the diagnosis starts again with twice the substeps (each time, up to
/// [`rules::MAX_SUBSTEPS_FACTOR`] times the requested ones; about twice the time per doubling) and says
/// so in [`Diagnosis::substeps_raised`]. A gap between the noise-based floor and threshold that a
/// candidate would explain but the model's error covers is `none`
/// ([`Diagnosis::none_by_model_error`]), without more substeps: below that threshold the rules
/// name an effect only on a candidate's explanation, which the model's error makes unsure.
pub fn diagnose_displacement(
    params: &actuator_params::ActuatorParams,
    measurements: &[Measurement],
    documented: Option<&DatasetInfo>,
    options: &DiagnoseOptions,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<DiagnosisRun, String> {
    let requested = options.substeps.max(1);
    let mut substeps = requested;
    let mut raised: Vec<String> = Vec::new();
    loop {
        let at = DiagnoseOptions {
            substeps,
            ..options.clone()
        };
        let may_raise = substeps * 2 <= requested * MAX_SUBSTEPS_FACTOR;
        let mut run = match diagnose_at(params, measurements, documented, &at, may_raise, progress)?
        {
            Attempt::Done(run) => *run,
            Attempt::Refine {
                gap_m,
                model_error_m,
            } => {
                raised.push(format!(
                    "at {substeps} substep(s) per sample the held-out gap ({gap_m:.3e} m) was \
                     within {MODEL_ERROR_FACTOR} x the model's integration error \
                     ({model_error_m:.3e} m) but not within the noise"
                ));
                substeps *= 2;
                continue;
            }
        };
        if !raised.is_empty() {
            run.diagnosis.substeps_raised = Some(format!(
                "substeps raised from {requested} to {substeps}: {}",
                raised.join("; ")
            ));
        }
        return Ok(run);
    }
}

/// What one [`diagnose_at`] gave.
enum Attempt {
    /// The diagnosis.
    Done(Box<DiagnosisRun>),
    /// The refitted nominal model's held-out gap is above the noise-based `none` threshold but
    /// within [`MODEL_ERROR_FACTOR`] times the model's integration error: `none` only because of
    /// the model, whatever the candidates do; [`diagnose`] runs again with more substeps.
    Refine { gap_m: f64, model_error_m: f64 },
}

/// [`diagnose`] with `options.substeps` as given; `may_refine`: stop at [`Attempt::Refine`]
/// before fitting the candidates when the model's error alone decides.
fn diagnose_at(
    params: &actuator_params::ActuatorParams,
    measurements: &[Measurement],
    documented: Option<&DatasetInfo>,
    options: &DiagnoseOptions,
    may_refine: bool,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<Attempt, String> {
    // Steps 1-5.
    let rec = recording::analyse(params, measurements, documented, options, progress)?;
    let unmeasured_loops = coverage::unmeasured_loops(params, measurements, &rec.infos)?;
    let plan_data: Vec<Vec<ExperimentData<'_>>> = rec
        .start_sets
        .iter()
        .map(|(_, st)| experiment_data(measurements, &rec.settles, st))
        .collect();
    let constants_range = constants_range(params, options.fit.refit_range);
    let fit_settings = FitSettings {
        refit_range: constants_range.factors,
        ..options.fit
    };
    let setup = rec.setup(options.substeps);
    let fitter = PlanFitter {
        setup,
        plan_data: &plan_data,
        training: &rec.training,
        first_plan: rec.plan,
        settings: &fit_settings,
    };
    // Step 6: the refitted nominal model.
    let common_start = singles::common_start(&rec.nominal, rec.skew);
    let scorer = Scorer::of_recording(setup, &fitter, &plan_data, &rec);
    let RefittedNominal {
        fit: refit,
        base,
        result: refit_result,
        model_error_m,
        gaps,
    } = refitted_nominal(&fitter, &scorer, &common_start, (rec.noise_m, rec.range_m));
    progress(1);
    if may_refine && gaps.only_the_model_error_says_none() {
        // No need to fit the candidates at these substeps.
        return Ok(Attempt::Refine {
            gap_m: gaps.gap0,
            model_error_m,
        });
    }
    let stage = Stage {
        fitter: &fitter,
        scorer: &scorer,
        nominal: &rec.nominal,
        base: &base,
        gaps,
    };
    // Steps 6-8: the candidates.
    let candidates = candidates(
        &stage,
        &refit,
        &common_start,
        &options.library,
        refit_result.training_rms_m,
        progress,
    );
    let (verdict, held_out_tie) = decide(
        &candidates,
        (&refit.fitted.values, &refit_result, &base),
        &gaps,
        model_error_m,
    );
    let run = assemble::assemble(assemble::Assembly {
        params,
        measurements,
        options,
        rec,
        candidates,
        verdict,
        held_out_tie,
        refit_result,
        constants_range,
        model_error_m,
        unmeasured_loops,
    });
    Ok(Attempt::Done(Box::new(run)))
}

/// Step 6's refitted nominal model: the reference every candidate is scored against.
struct RefittedNominal {
    /// The fit (`R_eddy`, `ξ`, `f0` and the skew on the training experiments).
    fit: PlanFit,
    /// Its prediction.
    base: scoring::Scored,
    /// Its scores (against itself).
    result: CandidateResult,
    /// The model's own integration error at its parameters, m.
    model_error_m: f64,
    /// The gaps the rules compare with.
    gaps: Gaps,
}

/// Step 6: the nominal model refitted from `common_start` on the training experiments, scored
/// on the held-out ones, with the model's integration error there and the gaps, for a recording
/// of noise level and motion `(noise_m, range_m)`.
fn refitted_nominal(
    fitter: &PlanFitter<'_>,
    scorer: &Scorer<'_>,
    common_start: &[f64],
    (noise_m, range_m): (f64, f64),
) -> RefittedNominal {
    let fit = singles::refit_nominal(fitter, common_start);
    let base = scorer.predict(&fit);
    let result = scorer.result(&fit, &base, &base);
    let model_error_m = scorer.discretization_error(&fit, &base);
    let gaps = Gaps::new(result.systematic_before_m, model_error_m, noise_m, range_m);
    RefittedNominal {
        fit,
        base,
        result,
        model_error_m,
        gaps,
    }
}

/// What the candidate steps give the verdict.
struct Candidates {
    /// The single candidates, best on the held-out experiments first (after any better optima
    /// the second stage found).
    ranked: Vec<scoring::Ranked>,
    /// The significant best single candidate's index in `ranked`.
    winner: Option<usize>,
    /// The pairs.
    second: pairs::SecondStage,
    /// The held-out tie among the single candidates, if any.
    singles_tie: Option<HeldOutTie>,
}

/// Steps 6–8: each library effect fitted alone and scored against the refitted nominal model
/// (`refit`, whose training RMS is `nominal_training_rms_m`), then the second stage; when no
/// pair is named, the refits of one effect alone it made replace that effect's single fit where
/// they are a better optimum of it, and the single candidates are ranked again.
fn candidates(
    stage: &Stage<'_>,
    refit: &PlanFit,
    common_start: &[f64],
    library: &[EffectName],
    nominal_training_rms_m: f64,
    progress: &(dyn Fn(u64) + Sync),
) -> Candidates {
    let (mut ranked, mut singles_tie) =
        singles::fit_library(stage, refit, common_start, library, progress);
    progress(1);
    let mut winner = ranked.iter().position(|r| r.0.significant);
    let plan = pairs::plan(stage, &ranked, winner, nominal_training_rms_m);
    let second = pairs::second_stage(stage, &ranked, plan);
    if second.winner.is_none()
        && !second.single_refits.is_empty()
        && singles::take_better_optima(stage, &mut ranked, second.single_refits.clone())
    {
        singles_tie = scoring::sort_by_held_out(&mut ranked, |r| r.significant);
        winner = ranked.iter().position(|r| r.0.significant);
    }
    Candidates {
        ranked,
        winner,
        second,
        singles_tie,
    }
}

/// Step 7's verdict from the candidates, the refitted nominal model (its fitted values, scores
/// and prediction) and the gaps, with the held-out tie the verdict's fit was in.
fn decide(
    c: &Candidates,
    refitted_nominal: (&[f64], &CandidateResult, &scoring::Scored),
    gaps: &Gaps,
    model_error_m: f64,
) -> (verdict::Verdict, Option<HeldOutTie>) {
    let verdict = verdict::decide(
        &c.ranked,
        c.winner,
        c.second.winner.as_ref(),
        refitted_nominal,
        gaps,
        model_error_m,
    );
    let held_out_tie = verdict::tie_of(
        &verdict.name,
        c.second.winner.as_ref(),
        c.second.tie.clone(),
        c.singles_tie.clone(),
        c.winner.map(|w| c.ranked[w].0.effect.as_str()),
    );
    (verdict, held_out_tie)
}
