//! The richer forms in the second stage (module docs of [`super::super`], step 8): an effect
//! with a second term ([`candidates::RICHER_FORM`]: eddy currents with a second path, a load
//! with a second mass) fitted in that form beside a pair's other effect or alone, and one effect
//! preferred to two when it explains as much.

use super::PairWinner;
use crate::diagnosis::rules::MAX_WORSE_SHARE;
use crate::diagnosis::scoring::{sort_by_held_out, Ranked, Scored};
use crate::diagnosis::singles::Stage;
use maglab_model::candidates::{self, Candidate, COMMON_PARAMETER_COUNT};
use maglab_model::effects::EffectName;
use maglab_model::plan_fit::PlanFit;
use rayon::prelude::*;

/// When no pair is named: the pair with an effect that has a richer form
/// ([`candidates::RICHER_FORM`]: eddy currents with a second path, a load with a second mass)
/// that fits the training experiments best, if it fits them at least as well as the best pair,
/// refitted with that effect in its richer form (from the pair's optimum and the effect's
/// library starts). A rod's eddy currents diffuse: one path stretched to cover a ladder of them
/// may fit the training experiments and miss the top band.
pub(super) fn richer_pair(
    stage: &Stage<'_>,
    pairs: &[Ranked],
    base_scored: &Scored,
) -> Option<Ranked> {
    let best_pair_training = pairs.first().map_or(0.0, |p| p.0.training_rms_m);
    let p = (0..pairs.len())
        .filter(|&p| {
            let cand = &pairs[p].1.fitted.candidate;
            cand.effects.len() == 2
                && cand.distinct_effects().len() == 2
                && cand
                    .effects
                    .iter()
                    .any(|e| candidates::RICHER_FORM.contains(e))
        })
        .min_by(|&a, &b| {
            pairs[a]
                .0
                .training_rms_m
                .total_cmp(&pairs[b].0.training_rms_m)
        })
        // Only a pair that fits the training experiments at least as well as the best pair on
        // the held-out ones: its form may be what fails to extrapolate, or the best pair itself
        // may leave too much with its effect's library form stretched.
        .filter(|&p| pairs[p].0.training_rms_m <= best_pair_training)?;
    let f = &pairs[p].1;
    let cand = &f.fitted.candidate;
    let i = cand
        .effects
        .iter()
        .position(|e| candidates::RICHER_FORM.contains(e))?;
    let effect = cand.effects[i];
    let at = candidates::parameter_offset(&cand.effects, i);
    let n = candidates::effect_parameter_count(effect);
    let values = &f.fitted.values;
    let with_first_term = |term: &[f64]| -> Vec<Vec<f64>> {
        candidates::second_term_starts(effect, term)
            .into_iter()
            .map(|second| {
                values[..at]
                    .iter()
                    .chain(term)
                    .chain(&values[at + n..])
                    .chain(&second)
                    .copied()
                    .collect()
            })
            .collect()
    };
    let mut starts = with_first_term(&values[at..at + n]);
    for library in candidates::effect_starts(effect, stage.nominal) {
        starts.extend(with_first_term(&library));
    }
    let g = stage
        .fitter
        .fit_from(&cand.with_richer(effect), &starts, f.plan, false);
    let sc = stage.scorer.predict(&g);
    Some((stage.scorer.result(&g, &sc, base_scored), g, sc))
}

/// The richer effect alone, from a richer pair whose other effect was not needed, judged as a
/// single candidate is (against the refitted nominal model: significant, nothing pinned): named
/// in its richer form when its second term is needed (pushed onto `pairs`); not needed, its
/// library form refitted from there is returned for the single candidates.
pub(super) fn judge_richer_alone(
    stage: &Stage<'_>,
    alone: PlanFit,
    pairs: &mut Vec<Ranked>,
) -> (Option<PairWinner>, Option<PlanFit>) {
    let sc = stage.scorer.predict(&alone);
    let result = stage.scorer.result(&alone, &sc, stage.base);
    if !result.significant {
        return (None, None);
    }
    let (needed, reduced) = stage
        .scorer
        .necessary(&alone, &[], result.systematic_after_m);
    let effect = alone.fitted.candidate.effects[0];
    if needed {
        let winner = (result.clone(), sc.clone(), vec![effect]);
        pairs.push((result, alone, sc));
        (Some(winner), None)
    } else {
        (None, reduced.into_iter().last())
    }
}

/// What the parsimony check found in place of a named pair.
pub(super) enum Parsimony {
    /// One effect of the pair, in its richer form, explains as much: its fit, and the effect.
    Richer(Box<Ranked>, EffectName),
    /// That effect in its library form, refitted from the richer form's optimum, explains as
    /// much (a better optimum of the single candidate).
    Library(PlanFit),
}

/// `effect` of the named pair fitted alone in its richer form, from its values in the pair, its
/// single fit and each library start, one group of starts per start of the second term (a
/// lightly damped mode has a basin of its own around every resonance), each group refined; the
/// best group by training RMS, scored against `base_scored`.
fn richer_single(
    stage: &Stage<'_>,
    ranked: &[Ranked],
    pair_fit: &PlanFit,
    effect: EffectName,
    base_scored: &Scored,
) -> Option<Ranked> {
    let cand = &pair_fit.fitted.candidate;
    let i = cand.effects.iter().position(|&e| e == effect)?;
    let at = candidates::parameter_offset(&cand.effects, i);
    let n = candidates::effect_parameter_count(effect);
    let values = &pair_fit.fitted.values;
    let single = ranked.iter().find(|r| r.0.effect == effect.name())?;
    let from_pair: Vec<f64> = values[..COMMON_PARAMETER_COUNT]
        .iter()
        .chain(&values[at..at + n])
        .copied()
        .collect();
    let mut firsts = vec![from_pair.clone(), single.1.fitted.values.clone()];
    for library in candidates::effect_starts(effect, stage.nominal) {
        firsts.push(
            from_pair[..COMMON_PARAMETER_COUNT]
                .iter()
                .chain(&library)
                .copied()
                .collect(),
        );
    }
    let mut groups: Vec<Vec<Vec<f64>>> = Vec::new();
    for first in &firsts {
        for (g, second) in candidates::second_term_starts(effect, &first[COMMON_PARAMETER_COUNT..])
            .into_iter()
            .enumerate()
        {
            if groups.len() <= g {
                groups.push(Vec::new());
            }
            groups[g].push(first.iter().chain(&second).copied().collect());
        }
    }
    let richer = Candidate::single(effect).with_richer(effect);
    let g = groups
        .par_iter()
        .map(|starts| stage.fitter.fit_from(&richer, starts, pair_fit.plan, false))
        .min_by(|a, b| a.fitted.training_rms_m.total_cmp(&b.fitted.training_rms_m))?;
    let sc = stage.scorer.predict(&g);
    Some((stage.scorer.result(&g, &sc, base_scored), g, sc))
}

/// One effect before two (module docs of [`super`], step 8): when the named pair contains an
/// effect with a richer form, that effect alone in its richer form replaces the pair when it
/// leaves no more of the held-out gap than the pair does (within the resolution floor), pins
/// nothing and makes at most [`MAX_WORSE_SHARE`] of the held-out experiments worse. Its second
/// term needed: named in its richer form; not needed: the library form's refit from the richer
/// optimum goes to the single candidates, when it is significant, explains as much and fits
/// the training experiments better than the single fit it replaces.
pub(super) fn parsimony(
    stage: &Stage<'_>,
    ranked: &[Ranked],
    pair_winner: &PairWinner,
    pairs: &[Ranked],
    base_scored: &Scored,
) -> Option<Parsimony> {
    let (pair, _, names) = pair_winner;
    if names.len() != 2 {
        return None;
    }
    let pair_fit = &pairs.iter().find(|p| p.0.effect == pair.effect)?.1;
    let mut tried: Vec<Ranked> = names
        .par_iter()
        .filter(|e| candidates::RICHER_FORM.contains(e))
        .filter_map(|&effect| richer_single(stage, ranked, pair_fit, effect, base_scored))
        .collect();
    sort_by_held_out(&mut tried, |_| true);
    let best = tried.into_iter().next()?;
    let floor = stage.gaps.floor;
    let plausible = best.0.pinned.is_empty()
        && best.0.systematic_after_m <= pair.systematic_after_m + floor
        && best.0.worse_experiments as f64 <= MAX_WORSE_SHARE * best.0.held_out_experiments as f64;
    if !plausible {
        return None;
    }
    let (needed, reduced) = stage
        .scorer
        .necessary(&best.1, &[], best.0.systematic_after_m);
    let effect = best.1.fitted.candidate.effects[0];
    if needed {
        return Some(Parsimony::Richer(Box::new(best), effect));
    }
    let library = reduced.into_iter().last()?;
    let sc = stage.scorer.predict(&library);
    let result = stage.scorer.result(&library, &sc, stage.base);
    let single_training = ranked
        .iter()
        .find(|r| r.0.effect == result.effect)
        .map_or(f64::INFINITY, |r| r.0.training_rms_m);
    (result.significant
        && result.systematic_after_m <= pair.systematic_after_m + floor
        && result.training_rms_m < single_training)
        .then_some(Parsimony::Library(library))
}
