//! Steps 9 and 10 put together with the rest: the verdict as the report names it (with the
//! effects the parameter file already models), the candidates listed beside it, its grade, the
//! reason with the grade's and the coverage's caveats, the advice, and what `diagnosis.json`
//! holds, with the traces for the plots.

use super::advice;
use super::coverage::{self, UnmeasuredLoop};
use super::grade;
use super::pairs::SecondStage;
use super::recording::{self, Recording};
use super::report::{AlsoSignificant, CandidateResult, ConstantsRange, Diagnosis, DiagnosisRun};
use super::report::{HeldOutTie, Trace};
use super::rules::CRITERION;
use super::scoring::Ranked;
use super::verdict::{self, also_significant, effects_identified_into, equal_on_training};
use super::{Candidates, DiagnoseOptions};
use maglab_dataset::data::Measurement;
use maglab_model::experiments::ExperimentInfo;
use std::collections::BTreeMap;

/// What [`assemble`] puts together.
pub(super) struct Assembly<'a> {
    pub params: &'a actuator_params::ActuatorParams,
    pub measurements: &'a [Measurement],
    pub options: &'a DiagnoseOptions,
    pub rec: Recording,
    pub candidates: Candidates,
    pub verdict: verdict::Verdict,
    pub held_out_tie: Option<HeldOutTie>,
    pub refit_result: CandidateResult,
    pub constants_range: ConstantsRange,
    pub model_error_m: f64,
    pub unmeasured_loops: Vec<UnmeasuredLoop>,
}

/// The report and the traces: the verdict with the effects the parameter file models, the
/// lists around it, and every step's results.
pub(super) fn assemble(a: Assembly<'_>) -> DiagnosisRun {
    let coil_current_measured = a.options.measured_current_input;
    let Candidates {
        ranked,
        winner,
        second,
        ..
    } = a.candidates;
    let named = Named::of(a.params, &a.verdict, &second);
    let beside = Beside::of(&ranked, winner, &named);
    let graded = grade::grade(
        &named.verdict,
        &named.additional_effects,
        &ranked.iter().map(|r| r.0.clone()).collect::<Vec<_>>(),
        (a.rec.noise_m, a.rec.range_m),
        coil_current_measured,
    );
    let unmeasured_loops_warning = coverage::warning(&a.unmeasured_loops, a.rec.dynamic.len());
    let reason = with_coverage_caveat(
        with_grade(
            named.reason.clone(),
            &graded,
            &named.effects(),
            coil_current_measured,
        ),
        &named.verdict,
        unmeasured_loops_warning.is_some(),
        a.unmeasured_loops.len(),
        a.rec.dynamic.len(),
    );
    let advice = what_to_record(
        &named
            .effects()
            .into_iter()
            .chain(graded.partly.iter().map(|p| p.effect.clone()))
            .collect::<Vec<_>>(),
        &graded,
        &beside.listed(),
        &ranked,
        &a.unmeasured_loops,
        a.options
            .commanded_experiments
            .as_deref()
            .unwrap_or(&a.rec.infos),
        rig(
            a.params,
            &a.constants_range,
            a.rec.rate_hz,
            coil_current_measured,
        ),
    );
    let traces = traces(a.measurements, &a.rec, &a.verdict.predictions);
    // (A `none` the parameter file's own effects replaced is not `none`.)
    let none_by_model_error = a.verdict.none_by_model_error && named.verdict == "none";
    DiagnosisRun {
        diagnosis: Diagnosis {
            verdict: named.verdict,
            verdict_reason: reason,
            grade: graded.grade,
            partly_explained: graded.partly,
            either: graded.either,
            advice,
            ambiguous_with: beside.ambiguous_with,
            equal_on_training: beside.equal_on_training,
            held_out_tie: a.held_out_tie,
            additional_effects: named.additional_effects,
            second_stage: second.results,
            second_stage_reason: second.reason,
            criterion: CRITERION.to_string(),
            noise_m: a.rec.noise_m,
            displacement_range_m: a.rec.range_m,
            nominal_rms_m: a.rec.nominal_rms_m,
            nominal_systematic_m: recording::nominal_systematic_m(&a.rec),
            model_error_m: a.model_error_m,
            substeps: a.options.substeps,
            substeps_raised: None,
            none_by_model_error,
            also_significant: beside.also_significant,
            constants_range: a.constants_range,
            effects_in_parameter_file: named.effects_in_parameter_file,
            parameter_file_warnings: a
                .params
                .provenance
                .warnings()
                .into_iter()
                .map(String::from)
                .collect(),
            unmeasured_loops: a.unmeasured_loops,
            unmeasured_loops_warning,
            datasheet_priors: maglab_model::priors::uses_of(a.params)
                .iter()
                .map(|u| u.to_json())
                .collect(),
            coil_current: None,
            refitted_nominal: a.refit_result,
            nuisance: a.rec.nuisance,
            experiments: a.rec.infos,
            ranking: ranked.into_iter().map(|r| r.0).collect(),
            where_: a.rec.where_,
        },
        traces,
    }
}

/// The verdict as the report names it: the decision's first effect (or `none`,
/// `unexplained`), with the pair's second effect and the effects the parameter file already
/// models added.
struct Named {
    /// The verdict's first effect, `none` or `unexplained`.
    verdict: String,
    /// Why, before the grade's and the coverage's caveats.
    reason: String,
    /// The pair's second effect, then the file's own effects ([`verdict::add_file_effects`]).
    additional_effects: Vec<String>,
    /// The effects the parameter file was identified with ([`effects_identified_into`]).
    effects_in_parameter_file: Vec<String>,
}

impl Named {
    fn of(
        params: &actuator_params::ActuatorParams,
        decided: &verdict::Verdict,
        second: &SecondStage,
    ) -> Named {
        let mut additional_effects: Vec<String> = second
            .winner
            .iter()
            .flat_map(|(_, _, names)| names.iter().skip(1).map(|n| n.name().to_string()))
            .collect();
        let effects_in_parameter_file = effects_identified_into(params);
        let (mut verdict, mut reason) = (decided.name.clone(), decided.reason.clone());
        verdict::add_file_effects(
            &effects_in_parameter_file,
            &mut verdict,
            &mut reason,
            &mut additional_effects,
        );
        Named {
            verdict,
            reason,
            additional_effects,
            effects_in_parameter_file,
        }
    }

    /// The effects the verdict names: the first, then the pair's second or the file's own.
    fn effects(&self) -> Vec<String> {
        std::iter::once(self.verdict.clone())
            .chain(self.additional_effects.iter().cloned())
            .collect()
    }
}

/// The candidates the report lists beside the verdict.
struct Beside {
    /// Within 10 % of the winner on the held-out experiments ([`verdict::ambiguous_with`]).
    ambiguous_with: Vec<String>,
    /// As good as a single winner on the training experiments ([`equal_on_training`]).
    equal_on_training: Vec<String>,
    /// The other significant single candidates ([`also_significant`]).
    also_significant: Vec<AlsoSignificant>,
}

impl Beside {
    fn of(ranked: &[Ranked], winner: Option<usize>, named: &Named) -> Beside {
        let ambiguous_with = verdict::ambiguous_with(ranked, winner, &named.verdict);
        let equal_on_training = match winner {
            Some(w) if named.verdict == ranked[w].0.effect => {
                equal_on_training(&ranked[w].0, ranked.iter().map(|r| &r.0))
            }
            _ => Vec::new(),
        };
        let verdict_effects = named.effects();
        let also_significant = also_significant(
            &ranked.iter().map(|r| &r.0).collect::<Vec<_>>(),
            &verdict_effects
                .iter()
                .map(String::as_str)
                .collect::<Vec<_>>(),
        );
        Beside {
            ambiguous_with,
            equal_on_training,
            also_significant,
        }
    }

    /// Every effect listed: as good on the held-out experiments, as good on the training ones,
    /// significant as well.
    fn listed(&self) -> Vec<String> {
        self.ambiguous_with
            .iter()
            .chain(&self.equal_on_training)
            .cloned()
            .chain(self.also_significant.iter().map(|a| a.effect.clone()))
            .collect()
    }
}

/// The verdict's `reason` with what its grade adds: the share a partly explaining effect
/// accounts for, why "X or Y" cannot be separated, and for a pair (`verdict_effects`) on the
/// commanded current alone the effect its term may be instead ([`grade::pair_caveat`]).
fn with_grade(
    mut reason: String,
    graded: &grade::Graded,
    verdict_effects: &[String],
    coil_current_measured: bool,
) -> String {
    if let Some(p) = &graded.partly {
        reason = format!(
            "{reason}; partly explained by {} ({:.0} ± {:.0} % of the gap's energy, at least \
             {:.0} % in every held-out band), the rest unexplained",
            p.effect,
            100.0 * p.share_of_gap,
            100.0 * p.share_spread,
            100.0 * p.lowest_band_share
        );
    }
    if let [a, b] = graded.either.as_slice() {
        reason = format!(
            "{reason}; {a} or {b}: {}, these experiments cannot separate them",
            graded.either_reason
        );
    }
    if graded.grade == grade::Grade::Pair {
        if let Some(caveat) = grade::pair_caveat(verdict_effects, coil_current_measured) {
            reason = format!("{reason}; {caveat}");
        }
    }
    reason
}

/// The `reason` of a verdict other than `none` with the coverage's caveat when the parameter
/// file's masses were not measured on some of the dynamic loops ([`coverage::warning`]): part
/// of the gap may be theirs.
fn with_coverage_caveat(
    reason: String,
    verdict: &str,
    warned: bool,
    unmeasured_count: usize,
    dynamic_count: usize,
) -> String {
    if !warned || verdict == "none" {
        return reason;
    }
    format!(
        "{reason}; the parameter file's masses were not measured on {unmeasured_count} of the \
         {dynamic_count} dynamic loops (unmeasured_loops): part of the gap may be theirs, not an \
         effect's"
    )
}

/// The rig the advice is for: its resonance and how far the diagnosis let it move, its current
/// limit and sampling, and whether it records the coil current.
fn rig(
    params: &actuator_params::ActuatorParams,
    constants_range: &ConstantsRange,
    sample_rate_hz: f64,
    coil_current_measured: bool,
) -> advice::Rig {
    advice::Rig {
        resonance_hz: params.actuator.resonance_hz,
        resonance_factor: constants_range.factors[2],
        current_limit_a: params.control.current_limit_a,
        sample_rate_hz,
        coil_current_measured,
    }
}

/// Step 10, the advice: the loops the masses lack first, then for each pair of candidates the
/// report could not separate — the named effects (`named`, the partly explaining one included)
/// against the `either` pair, the two best runners-up and the effects `also_listed` beside the
/// verdict — the recording that separates them on this rig, at most [`advice::MAX_ADVICE`].
fn what_to_record(
    named: &[String],
    graded: &grade::Graded,
    also_listed: &[String],
    ranked: &[Ranked],
    unmeasured_loops: &[UnmeasuredLoop],
    experiments: &[ExperimentInfo],
    rig: advice::Rig,
) -> Vec<advice::Advice> {
    let runners_up: Vec<&str> = ranked
        .iter()
        .map(|r| r.0.effect.as_str())
        .filter(|e| !named.iter().any(|n| n == e) && *e != "nominal")
        .take(2)
        .collect();
    let mut advice: Vec<advice::Advice> = advice::measure_loops(unmeasured_loops, rig)
        .into_iter()
        .collect();
    advice.extend(advice::advise(
        &advice::candidate_pairs(
            named,
            &graded.either,
            &runners_up,
            also_listed,
            graded.grade,
        ),
        experiments,
        rig,
    ));
    advice.truncate(advice::MAX_ADVICE);
    advice
}

/// Each experiment's measured, nominal and verdict-model traces for the plots
/// (`predictions`: the verdict's model, by experiment; the nominal model's where it has none).
fn traces(
    measurements: &[Measurement],
    rec: &Recording,
    predictions: &BTreeMap<usize, Vec<f64>>,
) -> Vec<Trace> {
    (0..measurements.len())
        .map(|k| Trace {
            name: rec.infos[k].name.clone(),
            rate_hz: rec.rate_hz,
            current_a: measurements[k].current_a.clone(),
            measured_m: measurements[k].displacement_m.clone(),
            nominal_m: rec.nominal_preds[k].clone(),
            augmented_m: predictions
                .get(&k)
                .cloned()
                .unwrap_or_else(|| rec.nominal_preds[k].clone()),
        })
        .collect()
}
