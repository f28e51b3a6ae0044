//! Step 8 of the diagnosis: a second effect on top of the first (forward selection), its
//! richer forms, and one effect preferred to two when it explains as much (module docs of
//! [`super`], step 8).

mod richer;

use super::report::{CandidateResult, HeldOutTie};
use super::rules::{
    BAND_BEST_CANDIDATES, BAND_HELPS, FULL_STAGE_NOISE, FULL_STAGE_SHARE, MAX_WORSE_SHARE,
    PAIR_CANDIDATES, PAIR_RATIO, PROMISING, PROMISING_TRAINING, SMALL_REMAINDER_NOISE,
    SMALL_REMAINDER_SHARE, SPECIFIC_NEXT_SHARE, SPECIFIC_SECOND_RATIO,
};
use super::scoring::{sort_by_held_out, Ranked, Scored};
use super::singles::Stage;
use maglab_model::candidates::{self, Candidate, COMMON_PARAMETER_COUNT};
use maglab_model::effects::EffectName;
use maglab_model::plan_fit::PlanFit;
use maglab_model::residual::systematic;
use rayon::prelude::*;
use richer::{judge_richer_alone, parsimony, richer_pair, Parsimony};

/// A named pair (or one effect in its richer form): its result, its prediction, and its
/// effects, the one that matters more first.
pub type PairWinner = (CandidateResult, Scored, Vec<EffectName>);

/// Whether and how the second stage runs.
#[derive(Debug, Clone, PartialEq)]
pub struct PairPlan {
    /// Pairs are fitted.
    pub run: bool,
    /// Only the winner's forward selection (the winner left a small remainder).
    pub small_remainder: bool,
    /// The single candidate the pairs build on (the winner, else the best).
    pub best_single: usize,
    /// Why, in words (`diagnosis.json`'s `second_stage_reason`).
    pub reason: String,
}

/// What the second stage found.
pub struct SecondStage {
    /// The named pair, if any.
    pub winner: Option<PairWinner>,
    /// The tie among the pairs the named one was in.
    pub tie: Option<HeldOutTie>,
    /// Every pair fitted, best first (`diagnosis.json`'s `second_stage`).
    pub results: Vec<CandidateResult>,
    /// Why it ran, in which form, or why not.
    pub reason: String,
    /// Refits of one effect alone that the single candidates take up when they are better
    /// optima of the same candidate.
    pub single_refits: Vec<PlanFit>,
}

/// Whether the second stage runs (module docs of [`super`], step 8), from the ranked single
/// candidates, the winner's index and the refitted nominal model's training RMS.
pub fn plan(
    stage: &Stage<'_>,
    ranked: &[Ranked],
    winner: Option<usize>,
    nominal_training_rms_m: f64,
) -> PairPlan {
    let (gap0, noise_m) = (stage.gaps.gap0, stage.gaps.noise_m);
    let best_single = winner.unwrap_or(0);
    // What the winner leaves, and the floor above which the full second stage runs; between it
    // and a small remainder only the winner's forward selection runs.
    let winner_left_m = winner.map(|w| ranked[w].0.systematic_after_m);
    let full_stage_floor_m = (FULL_STAGE_NOISE * noise_m).max(FULL_STAGE_SHARE * gap0);
    let small_remainder = winner_left_m.is_some_and(|left| {
        left <= full_stage_floor_m
            && left > (SMALL_REMAINDER_NOISE * noise_m).max(SMALL_REMAINDER_SHARE * gap0)
    });
    let run = small_remainder
        || match winner_left_m {
            Some(left) => left > full_stage_floor_m,
            // No single candidate is significant: a promising one is worth a second effect on
            // top. One that pins a parameter counts: alone it may have stretched to a limit to
            // cover a second effect too, which the pair then need not do (the pair itself must
            // still pin nothing). So does one that fits the training experiments far better than
            // the refitted nominal model although it extrapolates no better: each of two effects
            // may cover the other's training signature alone.
            None => {
                let nominal_training = systematic(nominal_training_rms_m, noise_m);
                ranked.iter().any(|r| {
                    r.0.systematic_after_m <= PROMISING * gap0
                        || systematic(r.0.training_rms_m, noise_m)
                            <= PROMISING_TRAINING * nominal_training
                })
            }
        };
    let reason = if gap0 <= stage.gaps.none_floor {
        "the refitted nominal model's gap is within the gap estimate's resolution or the \
         model's own integration error: no pairs fitted"
            .to_string()
    } else {
        plan_reason(ranked, winner, gap0, noise_m, small_remainder, run)
    };
    PairPlan {
        run: run && gap0 > stage.gaps.none_floor,
        small_remainder,
        best_single,
        reason,
    }
}

/// [`PairPlan::reason`] when the gap is above the none floor.
fn plan_reason(
    ranked: &[Ranked],
    winner: Option<usize>,
    gap0: f64,
    noise_m: f64,
    small_remainder: bool,
    run: bool,
) -> String {
    match winner {
        Some(w) => {
            let left = ranked[w].0.systematic_after_m;
            let amount = format!(
                "{} leaves {:.2} σ of held-out systematic gap ({:.1} % of the refitted nominal \
                 model's)",
                ranked[w].0.effect,
                left / noise_m.max(f64::MIN_POSITIVE),
                100.0 * left / gap0.max(f64::MIN_POSITIVE)
            );
            if small_remainder {
                format!(
                    "{amount}: below max(2 σ, 10 %), above max({SMALL_REMAINDER_NOISE} σ, {} %): \
                     only {} with each other effect was fitted",
                    100.0 * SMALL_REMAINDER_SHARE,
                    ranked[w].0.effect
                )
            } else if run {
                format!("{amount}, above max(2 σ, 10 %): the pairs were fitted")
            } else {
                format!(
                    "{amount}, at most max({SMALL_REMAINDER_NOISE} σ, {} %): no second effect \
                     looked for",
                    100.0 * SMALL_REMAINDER_SHARE
                )
            }
        }
        None if run => "no single candidate is significant, but one removes a good part \
             of the held-out or training gap: the pairs were fitted"
            .to_string(),
        None => "no single candidate is significant or promising: no pairs fitted".to_string(),
    }
}

/// The pairs to fit, as indices into `ranked`: every pair among the best candidates that pin
/// nothing and the band-best ones, then the best single candidate and the runner-up each with
/// every other effect (forward selection: an effect whose signature the first one mostly masks
/// fits badly alone and would never rank among the best singles; the runner-up leads too, as
/// the best single may be a stand-in that covers part of both effects). After a small remainder
/// only the winner leads.
fn pairs_to_fit(ranked: &[Ranked], plan: &PairPlan) -> Vec<(usize, usize)> {
    let mut tops: Vec<usize> = (0..ranked.len())
        .filter(|&i| ranked[i].0.pinned.is_empty())
        .take(if plan.small_remainder {
            0
        } else {
            PAIR_CANDIDATES
        })
        .collect();
    // Two effects of different speed each show in their own bands (a slow drift at the low
    // frequencies, a lag at the top): the candidate that fits a band best joins too, even when
    // its whole-dataset score ranks it lower, and even when its single fit pinned a parameter.
    let bands = if plan.small_remainder {
        0
    } else {
        ranked.first().map_or(0, |r| r.0.per_band.len())
    };
    for b in 0..bands {
        let best_in_band = (0..ranked.len()).min_by(|&i, &j| {
            ranked[i].0.per_band[b]
                .after_m
                .total_cmp(&ranked[j].0.per_band[b].after_m)
        });
        if let Some(i) = best_in_band {
            let helps =
                ranked[i].0.per_band[b].after_m < BAND_HELPS * ranked[i].0.per_band[b].before_m;
            if helps && !tops.contains(&i) && tops.len() < PAIR_CANDIDATES + BAND_BEST_CANDIDATES {
                tops.push(i);
            }
        }
    }
    let mut combos = Vec::new();
    for (a, &i) in tops.iter().enumerate() {
        for &j in &tops[a + 1..] {
            combos.push((i, j));
        }
    }
    let best_single = plan.best_single;
    let runner_up = (0..ranked.len())
        .find(|&i| i != best_single && ranked[i].0.pinned.is_empty())
        .filter(|_| !plan.small_remainder);
    for lead in std::iter::once(best_single).chain(runner_up) {
        for j in 0..ranked.len() {
            let listed = combos.iter().any(|&p| p == (lead, j) || p == (j, lead));
            if j != lead && !listed {
                combos.push((lead, j));
            }
        }
    }
    combos
}

/// The pair of `ranked[i]`'s and `ranked[j]`'s effects, fitted from their single fits and
/// scored against `base_scored` (the best single candidate).
fn fit_pair(
    stage: &Stage<'_>,
    ranked: &[Ranked],
    (i, j): (usize, usize),
    base_scored: &Scored,
) -> Option<Ranked> {
    let (first, second) = (
        EffectName::parse(&ranked[i].0.effect).ok()?,
        EffectName::parse(&ranked[j].0.effect).ok()?,
    );
    let cand = Candidate {
        effects: vec![first, second],
    };
    let fitted = |r: usize| ranked[r].1.fitted.values.as_slice();
    let own = |r: usize| &fitted(r)[COMMON_PARAMETER_COUNT..];
    let first_fit_with = |second_values: &[f64]| -> Vec<f64> {
        fitted(i).iter().chain(second_values).copied().collect()
    };
    // Starts: the first's fit plus the second's own fitted values; the second's common values
    // plus both effects' own; the first's fit plus the second's first library start (its own
    // single fit may have stretched to mimic the first effect).
    let mut starts = vec![
        first_fit_with(own(j)),
        fitted(j)[..COMMON_PARAMETER_COUNT]
            .iter()
            .chain(own(i))
            .chain(own(j))
            .copied()
            .collect(),
    ];
    if let Some(library_start) = candidates::effect_starts(second, stage.nominal).first() {
        starts.push(first_fit_with(library_start));
    }
    let f = stage
        .fitter
        .fit_from(&cand, &starts, ranked[i].1.plan, false);
    let sc = stage.scorer.predict(&f);
    Some((stage.scorer.result(&f, &sc, base_scored), f, sc))
}

/// The pair `candidate` is named when it leaves at most [`PAIR_RATIO`] of what the best single
/// candidate (`base_gap`) and the refitted nominal model leave, pins nothing, makes at most
/// [`MAX_WORSE_SHARE`] of the held-out experiments worse and needs each of its effects. Also
/// returns the knock-out test's refits of one effect alone (none when it did not run).
fn accept(
    stage: &Stage<'_>,
    ranked: &[Ranked],
    base_gap: f64,
    (r, f, sc): &Ranked,
) -> (Option<PairWinner>, Vec<PlanFit>) {
    let singles: Vec<&PlanFit> = ranked.iter().map(|r| &r.1).collect();
    let plausible = r.pinned.is_empty()
        && r.systematic_after_m <= PAIR_RATIO * base_gap.min(stage.gaps.gap0)
        && r.worse_experiments as f64 <= MAX_WORSE_SHARE * r.held_out_experiments as f64;
    let (accepted, reduced) = if plausible {
        stage.scorer.necessary(f, &singles, r.systematic_after_m)
    } else {
        (false, Vec::new())
    };
    let winner = accepted.then(|| {
        // The verdict is the effect that matters more: its single fit is the better one.
        let mut names: Vec<EffectName> = f.fitted.candidate.distinct_effects();
        names.sort_by_key(|n| {
            ranked
                .iter()
                .position(|x| x.0.effect == n.name())
                .unwrap_or(usize::MAX)
        });
        (r.clone(), sc.clone(), names)
    });
    (winner, reduced)
}

/// After a small remainder the second effect must be specific: the next pair (another second
/// effect in its place) still leaves [`SPECIFIC_NEXT_SHARE`] of the winner's remainder, and the
/// best pair at most [`SPECIFIC_SECOND_RATIO`] of what the next leaves. A remainder that other
/// effects remove too is the first effect's form not matching the rig's, not a second effect.
/// Returns whether it is, and, when it is not, why (appended to the stage's reason).
fn specific(
    pairs: &[Ranked],
    small_remainder: bool,
    base_gap: f64,
    first_effect: &str,
) -> (bool, Option<String>) {
    if !small_remainder {
        return (true, None);
    }
    let (Some(best), Some(next)) = (pairs.first(), pairs.get(1)) else {
        return (true, None);
    };
    let is = next.0.systematic_after_m >= SPECIFIC_NEXT_SHARE * base_gap
        && best.0.systematic_after_m <= SPECIFIC_SECOND_RATIO * next.0.systematic_after_m;
    let why = (!is).then(|| {
        format!(
            "; no pair named: {} is not specific ({} leaves {:.0} % of the remainder, {} \
             {:.0} %; named only when the next leaves >= {:.0} % and the best <= {:.0} % \
             of the next): the remainder is the form of {} differing from the rig's, not a \
             second effect",
            best.0.effect,
            best.0.effect,
            100.0 * best.0.systematic_after_m / base_gap.max(f64::MIN_POSITIVE),
            next.0.effect,
            100.0 * next.0.systematic_after_m / base_gap.max(f64::MIN_POSITIVE),
            100.0 * SPECIFIC_NEXT_SHARE,
            100.0 * SPECIFIC_SECOND_RATIO,
            first_effect,
        )
    });
    (is, why)
}

/// Step 8: the pairs on top of the ranked single candidates, as `plan` says.
pub fn second_stage(stage: &Stage<'_>, ranked: &[Ranked], plan: PairPlan) -> SecondStage {
    let mut out = SecondStage {
        winner: None,
        tie: None,
        results: Vec::new(),
        reason: plan.reason.clone(),
        single_refits: Vec::new(),
    };
    if !plan.run {
        return out;
    }
    let best_single = plan.best_single;
    let base_scored = ranked[best_single].2.clone();
    let base_gap = ranked[best_single].0.systematic_after_m;
    let mut pairs: Vec<Ranked> = pairs_to_fit(ranked, &plan)
        .par_iter()
        .filter_map(|&c| fit_pair(stage, ranked, c, &base_scored))
        .collect();
    out.tie = sort_by_held_out(&mut pairs, |_| true);
    let (is_specific, why) = specific(
        &pairs,
        plan.small_remainder,
        base_gap,
        &ranked[best_single].0.effect,
    );
    if let Some(why) = why {
        out.reason.push_str(&why);
    }
    if let Some(best) = pairs.first().filter(|_| is_specific) {
        (out.winner, out.single_refits) = accept(stage, ranked, base_gap, best);
    }
    let mut richer_alone: Option<PlanFit> = None;
    if out.winner.is_none() && is_specific {
        if let Some(extended) = richer_pair(stage, &pairs, &base_scored) {
            // The first pair's refits stay the ones offered to the single candidates.
            let (winner, reduced) = accept(stage, ranked, base_gap, &extended);
            out.winner = winner;
            if out.winner.is_none() {
                // Its other effect not needed: the knock-out refit of the richer effect alone,
                // in its richer form.
                richer_alone = reduced.into_iter().find(|r| {
                    let c = &r.fitted.candidate;
                    c.effects.len() == 2 && c.distinct_effects().len() == 1
                });
            }
            pairs.push(extended);
            out.tie = sort_by_held_out(&mut pairs, |_| true);
        }
    }
    if let Some(alone) = richer_alone {
        let (winner, library) = judge_richer_alone(stage, alone, &mut pairs);
        if winner.is_some() {
            out.winner = winner;
            out.tie = sort_by_held_out(&mut pairs, |_| true);
        }
        out.single_refits.extend(library);
    }
    let parsimonious = out
        .winner
        .as_ref()
        .and_then(|w| parsimony(stage, ranked, w, &pairs, &base_scored));
    match parsimonious {
        Some(Parsimony::Richer(best, effect)) => {
            out.winner = Some((best.0.clone(), best.2.clone(), vec![effect]));
            pairs.push(*best);
            out.tie = sort_by_held_out(&mut pairs, |_| true);
        }
        Some(Parsimony::Library(refit)) => {
            // Taken up by the single candidates, as a knock-out refit is.
            out.winner = None;
            out.single_refits = vec![refit];
        }
        None => {}
    }
    out.results = pairs.into_iter().map(|p| p.0).collect();
    out
}
