//! The verdict (steps 7 and 8 decided): `none`, an effect (with a second one), or
//! `unexplained`, why, and the lists around it: ambiguous, equal on training, also
//! significant, the effects the parameter file itself models.

use super::pairs::PairWinner;
use super::report::{AlsoSignificant, CandidateResult, HeldOutTie};
use super::rules::{AMBIGUOUS_HELD_OUT, EQUAL_ON_TRAINING, MODEL_ERROR_FACTOR};
use super::scoring::{Ranked, Scored};
use super::singles::Gaps;
use maglab_model::effects::EffectName;
use std::collections::BTreeMap;

/// What the verdict step decided.
pub struct Verdict {
    /// `none`, an effect name or `unexplained`.
    pub name: String,
    /// Why, in one sentence.
    pub reason: String,
    /// The verdict's model's predictions (offset added), per dynamic experiment.
    pub predictions: BTreeMap<usize, Vec<f64>>,
    /// `none` only because of the model's integration error.
    pub none_by_model_error: bool,
}

/// The verdict from the single candidates (`ranked`, `winner` the significant best), the pair
/// stage's `pair_winner`, the refitted nominal model (`refit_values` its fitted values,
/// `refit_result` its scores, `base` its prediction) and the gaps (module docs of [`super`],
/// step 7).
pub fn decide(
    ranked: &[Ranked],
    winner: Option<usize>,
    pair_winner: Option<&PairWinner>,
    (refit_values, refit_result, base): (&[f64], &CandidateResult, &Scored),
    gaps: &Gaps,
    model_error_m: f64,
) -> Verdict {
    let Gaps {
        gap0,
        floor,
        none_floor,
        ..
    } = *gaps;
    let threshold = gaps.none_threshold().max(none_floor);
    let explained = pair_winner.is_some() || winner.is_some();
    // `none` only because of the model's integration error: the noise-based rule alone would
    // have named an effect or `unexplained` ([`super::diagnose`] then runs again with more
    // substeps).
    let none = gap0 <= none_floor || (gap0 <= threshold && !explained);
    let noise_none = gap0 <= floor || (gap0 <= gaps.none_threshold() && !explained);
    let none_by_model_error = none && !noise_none;
    let (name, reason, predictions) = if none {
        none_verdict(refit_values, gaps, model_error_m, threshold, base)
    } else if let Some((pair, pair_scored, names)) = pair_winner {
        pair_verdict(pair, pair_scored, names, refit_result, gap0)
    } else if let Some(w) = winner {
        single_verdict(&ranked[w])
    } else {
        unexplained_verdict(&ranked[0].0, base)
    };
    Verdict {
        name,
        reason,
        predictions,
        none_by_model_error,
    }
}

/// `none`: within the noise or the model's own integration error.
fn none_verdict(
    refit_values: &[f64],
    gaps: &Gaps,
    model_error_m: f64,
    threshold: f64,
    base: &Scored,
) -> (String, String, BTreeMap<usize, Vec<f64>>) {
    let (gap0, floor) = (gaps.gap0, gaps.floor);
    let within = if gap0 <= MODEL_ERROR_FACTOR * model_error_m && gap0 > floor {
        format!(
            "within the model's own integration error: systematic gap {gap0:.3e} m <= \
             {:.3e} m ({MODEL_ERROR_FACTOR} x the {model_error_m:.3e} m by which the model \
             with twice the substeps differs)",
            MODEL_ERROR_FACTOR * model_error_m
        )
    } else {
        format!(
            "within the noise: systematic gap {gap0:.3e} m <= {threshold:.3e} m (max of the \
             noise level, 0.2 % of the motion and {MODEL_ERROR_FACTOR} x the model's own \
             integration error)"
        )
    };
    (
        "none".to_string(),
        format!(
            "the nominal model with R_eddy, xi, f0 refitted ({:.2} ohm, {:.4}, {:.1} Hz) fits the \
             held-out experiments {within}",
            refit_values[0], refit_values[1], refit_values[2]
        ),
        base.offset_preds(),
    )
}

/// A named pair (or one effect in its richer form).
fn pair_verdict(
    pair: &CandidateResult,
    pair_scored: &Scored,
    names: &[EffectName],
    refit_result: &CandidateResult,
    gap0: f64,
) -> (String, String, BTreeMap<usize, Vec<f64>>) {
    let what = if names.len() > 1 {
        "each effect is needed (without either, refitted, the gap is at least twice as large)"
    } else {
        "its second term is needed (in its library form, refitted, the gap is at least twice \
         as large)"
    };
    (
        names
            .first()
            .map(|n| n.name())
            .unwrap_or_default()
            .to_string(),
        format!(
            "adding {} cuts the held-out error of the refitted nominal model from {:.3e} m to \
             {:.3e} m (systematic gap {:.3e} -> {:.3e} m); {what}",
            pair.effect.replace('+', " and "),
            refit_result.held_out_rms_after_m,
            pair.held_out_rms_after_m,
            gap0,
            pair.systematic_after_m,
        ),
        pair_scored.offset_preds(),
    )
}

/// The significant single candidate with the lowest held-out error.
fn single_verdict((c, _, scored): &Ranked) -> (String, String, BTreeMap<usize, Vec<f64>>) {
    (
        c.effect.clone(),
        format!(
            "adding {} cuts the held-out error of the refitted nominal model from {:.3e} m to \
             {:.3e} m ({:.1}x; systematic gap {:.3e} -> {:.3e} m) and makes {}/{} held-out \
             experiments worse",
            c.effect,
            c.held_out_rms_before_m,
            c.held_out_rms_after_m,
            c.held_out_reduction,
            c.systematic_before_m,
            c.systematic_after_m,
            c.worse_experiments,
            c.held_out_experiments
        ),
        scored.offset_preds(),
    )
}

/// No candidate removes the gap.
fn unexplained_verdict(
    best: &CandidateResult,
    base: &Scored,
) -> (String, String, BTreeMap<usize, Vec<f64>>) {
    (
        "unexplained".to_string(),
        format!(
            "no candidate removes the gap: the best, {}, leaves a held-out systematic gap of \
             {:.3e} m of the refitted nominal model's {:.3e} m ({:.0} %) and makes {}/{} \
             held-out experiments worse",
            best.effect,
            best.systematic_after_m,
            best.systematic_before_m,
            100.0 * best.systematic_after_m / best.systematic_before_m.max(1e-300),
            best.worse_experiments,
            best.held_out_experiments
        ),
        base.offset_preds(),
    )
}

/// The tie the verdict's fit was in, if any: recorded where it was broken
/// ([`super::scoring::sort_by_held_out`]).
pub fn tie_of(
    verdict: &str,
    pair_winner: Option<&PairWinner>,
    pairs_tie: Option<HeldOutTie>,
    singles_tie: Option<HeldOutTie>,
    named_single: Option<&str>,
) -> Option<HeldOutTie> {
    if verdict == "none" || verdict == "unexplained" {
        None
    } else if let Some((pair, _, _)) = pair_winner {
        pairs_tie.filter(|t| t.tied[0].effect == pair.effect)
    } else {
        singles_tie.filter(|t| Some(t.tied[0].effect.as_str()) == named_single)
    }
}

/// Effects the identification found in the data and put into the parameter file (module docs
/// of [`super`]): named with the diagnosis's own, first when the diagnosis names none.
pub fn add_file_effects(
    effects: &[String],
    verdict: &mut String,
    reason: &mut String,
    additional_effects: &mut Vec<String>,
) {
    for effect in effects {
        let why = format!(
            "{effect} is in the parameter file: its identification found it in the data \
             (provenance.identified), and the paper's model lacks it"
        );
        if verdict == "none" {
            *verdict = effect.clone();
            *reason = format!("{why}; with it, {reason}");
        } else {
            additional_effects.push(effect.clone());
            *reason = format!("{reason}; {why}");
        }
    }
}

/// Significant candidates other than the winner whose held-out error is within
/// [`AMBIGUOUS_HELD_OUT`] of the winner's (none after `none`).
pub fn ambiguous_with(ranked: &[Ranked], winner: Option<usize>, verdict: &str) -> Vec<String> {
    match winner {
        Some(w) if verdict != "none" => {
            let best = ranked[w].0.held_out_rms_after_m;
            ranked
                .iter()
                .enumerate()
                .filter(|(i, r)| {
                    *i != w
                        && r.0.significant
                        && r.0.held_out_rms_after_m <= AMBIGUOUS_HELD_OUT * best
                })
                .map(|(_, r)| r.0.effect.clone())
                .collect()
        }
        _ => Vec::new(),
    }
}

/// Effects beyond the paper's model that `params` models and lists as identified from data:
/// a reversible part (`preisach.reversible_susceptibility` in `provenance.identified`).
pub fn effects_identified_into(params: &actuator_params::ActuatorParams) -> Vec<String> {
    let identified = params.provenance.identified_fields();
    let reversible = params
        .preisach
        .reversible_susceptibility
        .as_ref()
        .is_some_and(|chi| chi.iter().any(|&c| c > 0.0));
    if reversible && identified.contains(&"preisach.reversible_susceptibility") {
        vec![EffectName::ReversibleMagnetization.name().to_string()]
    } else {
        Vec::new()
    }
}

/// The library's effects that, below the rod's resonance, change the response's phase and
/// amplitude with frequency much as `R_eddy`, `ξ` and `f0` do, so that constants identified
/// from the same data absorb part of them: identify → diagnose takes them for one another.
pub const LAG_EFFECTS: [EffectName; 4] = [
    EffectName::AmplifierBandwidth,
    EffectName::SensorDynamics,
    EffectName::MechanicalLoad,
    EffectName::EddyFrequencyDependence,
];

/// The significant single candidates of `ranking` (best first) whose effect is not among
/// `named` (the verdict's effects); none when the verdict is `none`: a gap within the noise
/// needs no effect, though a candidate may pass the criterion's within-the-noise branch there by
/// removing a sliver of it (the bench folder of `lab/tests/identify_then_diagnose.rs`, chained:
/// thermal drift at 1.02x).
pub fn also_significant(ranking: &[&CandidateResult], named: &[&str]) -> Vec<AlsoSignificant> {
    if named.contains(&"none") {
        return Vec::new();
    }
    ranking
        .iter()
        .filter(|c| c.significant && !named.contains(&c.effect.as_str()))
        .map(|c| AlsoSignificant {
            effect: c.effect.clone(),
            held_out_reduction: c.held_out_reduction,
        })
        .collect()
}

/// The significant candidates other than `winner` whose training RMS is within
/// [`EQUAL_ON_TRAINING`] of the winner's ([`super::Diagnosis::equal_on_training`]).
pub fn equal_on_training<'a>(
    winner: &CandidateResult,
    candidates: impl Iterator<Item = &'a CandidateResult>,
) -> Vec<String> {
    candidates
        .filter(|c| {
            c.effect != winner.effect
                && c.significant
                && c.training_rms_m <= EQUAL_ON_TRAINING * winner.training_rms_m
        })
        .map(|c| c.effect.clone())
        .collect()
}
