//! The verdict's grade: how much of the gap the named effects account for, and whether the
//! experiments can tell the named effect from another.
//!
//! | grade | when | what it claims |
//! |---|---|---|
//! | `none` | the verdict is `none` | the gap is within the noise or the model's own error |
//! | `effect` | one significant effect, no other as good | that effect explains the gap |
//! | `pair` | a pair named (step 8) | both effects are needed |
//! | `either` | a significant single winner and another significant candidate within [`AMBIGUOUS_HELD_OUT`] of its held-out error, or as good on training and apart on the held-out experiments by less than the winner's own training misfit, or behind it on the training and the held-out experiments each by less than what the winner itself leaves there, or a winner whose term another effect enters as well ([`SAME_TERM`]) | "X or Y": these experiments cannot separate them |
//! | `partly_explained` | no effect explains the gap, but one removes more than half of its energy in every held-out band, and more than half of what its own fit leaves with the effect switched off | "partly explained by X (share ± spread), the rest unexplained"; "by X or Y" when another effect enters X's term ([`SAME_TERM`]) |
//! | `unexplained` | none of these | no library effect accounts for most of the gap |
//!
//! The share threshold ([`PARTIAL_SHARE`]) is definitional, not fitted to cases: a part larger
//! than the rest, in every held-out band (a share that holds in one band only is the refit
//! trading bands, not an effect). Its spread is half the range of the per-band shares.
//!
//! # Effects that enter the same term
//!
//! Some pairs cannot be separated by any displacement record, whatever the fits say: a current
//! amplifier whose loop yields to the rod's back-EMF. The coil's voltage is
//! `v = R i + L_w w'` with `w = H + M` the rod's flux (per μ0 N A), and the eddy ODE (4) reads
//! `w' = c1 (i − H/c0)`. A PI loop with its zero on the coil's pole and crossover `ω_c`,
//! `v = ω_c (τ_L s + 1)/s · (i_cmd − i)`, in units of `R` (`v = i + (τ_L/c0) w'`), leaves
//! `i = T(s) i_cmd − G(s) w'` with
//!
//! ```text
//! D(s) = (1 + ω_c τ_L) s + ω_c,   G(s) = (τ_L/c0) s / D(s),   T(s) = 1 − s / D(s)
//! (1 + c1 G(s)) w' = c1 (T(s) i_cmd − H/c0)
//! ```
//!
//! (substituted into (4); for the bare coil, `M = 0` and `c1 → ∞`, it gives back
//! `i = ω_c/(s + ω_c) i_cmd`). The effective `c1/(1 + c1 G)` falls from `c1` to
//! `c1 (1 + ω_c τ_L)/(1 + ω_c τ_L + κ)` between `ω_c/(1 + ω_c τ_L + κ)` and `ω_c/(1 + ω_c τ_L)`,
//! `κ = τ_L c1/c0 = R_eddy/R_coil` (10–100 for a coil's τ_L of 0.1–1 ms on this rod), while
//! `T` departs from 1 by `|s/D| ≈ ω/ω_c` only. Below the loop's crossover the loop is
//! therefore the eddy ODE with a frequency-dependent `c1` — the `eddy_frequency_dependence`
//! candidate's form (a second eddy path is a frequency-dependent `R_eddy`). Near and above
//! `ω_c/(1 + ω_c τ_L)` the command's lag-lead `T` is a second term, which that candidate
//! lacks. The library's amplifier is this loop (`maglab_model::model::CurrentLoop`: `T` and
//! the EMF term `(1 − T)(τ_L/c0) w'`, with a filter pole), so where `T` shows, the fits can
//! name it; a loop whose `T` stays within a few % of 1 at the top sine is its EMF term alone,
//! an eddy path (docs/diagnosis.md, "A PI loop of low crossover"). With the commanded current the
//! only current a dataset holds, an `eddy_frequency_dependence` verdict is therefore always
//! "eddy_frequency_dependence or amplifier_bandwidth", and so is the part of a gap an eddy path
//! explains when it explains only part ("partly explained by eddy_frequency_dependence or
//! amplifier_bandwidth": the loop's share is the same term's), and a pair that names it says in
//! its reason that the term may be the amplifier's ([`pair_caveat`]); the measured coil current
//! separates them (the eddy path leaves it equal to the command, the loop does not). The
//! converse does not hold: an amplifier that wins has a command response `T` the eddy candidate
//! does not have (at `τ_L = 0` it is that lag alone), so the fits have separated the two.

use super::report::CandidateResult;
use super::rules::{resolution_floor, AMBIGUOUS_HELD_OUT, MAX_WORSE_SHARE, PARTIAL_SHARE};
use serde::Serialize;

/// Winners whose term of the model another effect enters as well (module docs), with that
/// effect and why, for datasets that record the commanded current only.
pub const SAME_TERM: [(&str, &str, &str); 1] = [(
    "eddy_frequency_dependence",
    "amplifier_bandwidth",
    "a current loop that yields to the rod's back-EMF acts on the same H' + M' term of the \
     eddy ODE (4) as a frequency-dependent R_eddy; only a measured coil current separates them",
)];

/// The grade of a verdict (module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Grade {
    /// Within the noise.
    None,
    /// One effect.
    Effect,
    /// Two effects, both needed.
    Pair,
    /// One of two effects the experiments cannot separate.
    Either,
    /// One effect accounts for most of the gap, the rest is unexplained.
    PartlyExplained,
    /// No library effect accounts for most of the gap.
    Unexplained,
}

impl Grade {
    /// The grade's name as `diagnosis.json` writes it.
    pub fn name(&self) -> &'static str {
        match self {
            Grade::None => "none",
            Grade::Effect => "effect",
            Grade::Pair => "pair",
            Grade::Either => "either",
            Grade::PartlyExplained => "partly_explained",
            Grade::Unexplained => "unexplained",
        }
    }
}

/// The part of the gap one effect accounts for when it does not explain all of it.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct PartialExplanation {
    /// The effect.
    pub effect: String,
    /// Share of the refitted nominal model's held-out systematic gap energy it removes.
    pub share_of_gap: f64,
    /// Half the range of that share over the held-out bands.
    pub share_spread: f64,
    /// The smallest share of any held-out band.
    pub lowest_band_share: f64,
}

/// What [`grade`] decided.
#[derive(Debug, Clone, PartialEq)]
pub struct Graded {
    /// The grade.
    pub grade: Grade,
    /// For [`Grade::PartlyExplained`].
    pub partly: Option<PartialExplanation>,
    /// For [`Grade::Either`]: the two effects, the verdict's first; for
    /// [`Grade::PartlyExplained`] by an effect another enters the same term as
    /// ([`SAME_TERM`]): that effect and the other.
    pub either: Vec<String>,
    /// Why the experiments cannot separate the two of `either`.
    pub either_reason: String,
}

/// Grades `verdict` (with `additional_effects`) from the single candidates `ranking` (best
/// first); `noise_m`, `range_m` as the diagnosis measured them; `coil_current_measured`: the
/// dataset records the coil current, which separates the [`SAME_TERM`] pairs.
pub fn grade(
    verdict: &str,
    additional_effects: &[String],
    ranking: &[CandidateResult],
    (noise_m, range_m): (f64, f64),
    coil_current_measured: bool,
) -> Graded {
    let graded = |grade| Graded {
        grade,
        partly: None,
        either: Vec::new(),
        either_reason: String::new(),
    };
    match verdict {
        "none" => graded(Grade::None),
        "unexplained" => match partial(ranking, noise_m, range_m) {
            Some(p) => {
                // The part an effect explains is as much the other's when both enter the same
                // term (module docs): "partly explained by X or Y".
                let (either, either_reason) = match same_term(&p.effect, coil_current_measured) {
                    Some((other, why)) => (vec![p.effect.clone(), other.to_string()], why.into()),
                    None => (Vec::new(), String::new()),
                };
                Graded {
                    grade: Grade::PartlyExplained,
                    partly: Some(p),
                    either,
                    either_reason,
                }
            }
            None => graded(Grade::Unexplained),
        },
        _ if !additional_effects.is_empty() => graded(Grade::Pair),
        winner => match rival(winner, ranking, (noise_m, range_m)) {
            Some((other, why)) => Graded {
                either: vec![winner.to_string(), other.clone()],
                either_reason: match why {
                    Rivalry::HeldOut => format!(
                        "{other} fits the held-out experiments within {:.0} % as well",
                        100.0 * (AMBIGUOUS_HELD_OUT - 1.0)
                    ),
                    Rivalry::WithinTrainingMisfit => format!(
                        "{other} fits the training experiments as well, and falls behind on the \
                         held-out ones by less than {winner}'s own misfit on the training ones"
                    ),
                    Rivalry::WithinOwnRemainder => format!(
                        "{other} falls behind on the training and the held-out experiments by \
                         less than {winner} itself leaves unexplained there: the difference is \
                         within the model's own error"
                    ),
                },
                ..graded(Grade::Either)
            },
            None => match same_term(winner, coil_current_measured) {
                Some((other, why)) => Graded {
                    either: vec![winner.to_string(), other.to_string()],
                    either_reason: why.to_string(),
                    ..graded(Grade::Either)
                },
                None => graded(Grade::Effect),
            },
        },
    }
}

/// The caveat of a pair verdict (`named`: its effects) on a dataset without the coil current
/// when one of them is a term another effect enters as well ([`SAME_TERM`]): the pair's fits
/// needed that term, but what put it there may be the other effect, which no displacement
/// record tells apart. The grade stays `pair`. `None` when no named effect is such a term or the
/// coil current was measured.
pub fn pair_caveat(named: &[String], coil_current_measured: bool) -> Option<String> {
    let caveats: Vec<String> = named
        .iter()
        .filter_map(|n| {
            same_term(n, coil_current_measured)
                .map(|(other, why)| format!("the {n} term may be {other} instead: {why}"))
        })
        .collect();
    (!caveats.is_empty()).then(|| caveats.join("; "))
}

/// The effect that enters the same term of the model as `effect` ([`SAME_TERM`]) and why, when
/// the dataset does not record the coil current that separates them.
fn same_term(effect: &str, coil_current_measured: bool) -> Option<(&'static str, &'static str)> {
    SAME_TERM
        .iter()
        .find(|(e, ..)| *e == effect && !coil_current_measured)
        .map(|&(_, other, why)| (other, why))
}

/// The best other significant candidate the held-out experiments do not separate from
/// `winner`: within [`AMBIGUOUS_HELD_OUT`] of its held-out error, or one that fits the training
/// experiments as well ([`super::verdict::equal_on_training`]) and whose held-out systematic energy exceeds the
/// winner's by no more than the systematic energy the winner leaves on its own training
/// experiments (noise `noise_m` removed from each). That training misfit is the model's error
/// where it was fitted (masses not measured on the dynamic loops, an effect's form other than the
/// library's); its extrapolation to the held-out experiments errs at least as much, so a smaller
/// held-out difference between two fits that the training experiments cannot tell apart ranks
/// the model's error, not the effects. Or one behind it by less than its own remainder
/// ([`behind_by_less_than_own_remainder`]); `range_m` the motion, for the estimate's resolution.
fn rival(
    winner: &str,
    ranking: &[CandidateResult],
    (noise_m, range_m): (f64, f64),
) -> Option<(String, Rivalry)> {
    let w = ranking.iter().find(|c| c.effect == winner)?;
    let floor = resolution_floor(noise_m, range_m);
    let held_out = |c: &CandidateResult| systematic_energy(c.held_out_rms_after_m, noise_m);
    let training_misfit = systematic_energy(w.training_rms_m, noise_m);
    let equal_on_training = super::verdict::equal_on_training(w, ranking.iter());
    ranking
        .iter()
        .filter(|c| c.effect != winner && c.significant)
        .find_map(|c| {
            if c.held_out_rms_after_m <= AMBIGUOUS_HELD_OUT * w.held_out_rms_after_m {
                Some((c.effect.clone(), Rivalry::HeldOut))
            } else if equal_on_training.contains(&c.effect)
                && held_out(c) - held_out(w) <= training_misfit
            {
                Some((c.effect.clone(), Rivalry::WithinTrainingMisfit))
            } else if behind_by_less_than_own_remainder(w, c, noise_m, floor) {
                Some((c.effect.clone(), Rivalry::WithinOwnRemainder))
            } else {
                None
            }
        })
}

/// Does `rival` fall behind `winner` on the training and on the held-out experiments each by
/// less systematic energy than `winner` leaves there itself (noise `noise_m` removed; energies
/// below the estimate's resolution `floor_m` count as `floor_m`)? The winner's remainder is
/// the model's error with the winner's effect in it (a form of the effect other than the
/// rig's, masses not measured on the dynamic loops): a direct measure, on these experiments,
/// of how far a right explanation may miss. A rival that misses by less than twice that may be
/// the right effect in a form further from the library's; the data then rank the model's
/// errors, not the effects. The bound is definitional — the difference must exceed what is
/// left unexplained, [`PARTIAL_SHARE`]'s "more than the rest" —, not a constant fitted to
/// cases.
fn behind_by_less_than_own_remainder(
    winner: &CandidateResult,
    rival: &CandidateResult,
    noise_m: f64,
    floor_m: f64,
) -> bool {
    let energy = |rms_m: f64| systematic_energy(rms_m, noise_m).max(floor_m * floor_m);
    let within =
        |winner_m: f64, rival_m: f64| energy(rival_m) - energy(winner_m) <= energy(winner_m);
    within(winner.training_rms_m, rival.training_rms_m)
        && within(winner.held_out_rms_after_m, rival.held_out_rms_after_m)
}

/// Why [`rival`] found the held-out experiments unable to separate two candidates.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Rivalry {
    /// Their held-out errors are within [`AMBIGUOUS_HELD_OUT`].
    HeldOut,
    /// Equal on training, apart on the held-out ones by less than the training misfit.
    WithinTrainingMisfit,
    /// Behind on training and held out by less than the winner leaves on each
    /// ([`behind_by_less_than_own_remainder`]).
    WithinOwnRemainder,
}

/// The systematic part of an RMS error `rms_m` over noise `noise_m`, squared.
fn systematic_energy(rms_m: f64, noise_m: f64) -> f64 {
    (rms_m * rms_m - noise_m * noise_m).max(0.0)
}

/// The best candidate (held-out order) that accounts for more than [`PARTIAL_SHARE`] of the gap
/// in every held-out band whose gap is above the estimate's resolution, and of what its fit
/// leaves without its effect; nothing pinned, at most [`MAX_WORSE_SHARE`] of the held-out
/// experiments worse.
fn partial(ranking: &[CandidateResult], noise_m: f64, range_m: f64) -> Option<PartialExplanation> {
    let floor = resolution_floor(noise_m, range_m);
    ranking.iter().find_map(|c| {
        if !c.pinned.is_empty()
            || c.worse_experiments as f64 > MAX_WORSE_SHARE * c.held_out_experiments as f64
        {
            return None;
        }
        let before = c.systematic_before_m * c.systematic_before_m;
        let after = c.systematic_after_m * c.systematic_after_m;
        let knocked_out = systematic_energy(c.knocked_out_rms_m, noise_m);
        if before <= 0.0 || knocked_out <= 0.0 {
            return None;
        }
        let share = 1.0 - after / before;
        let own = 1.0 - after / knocked_out;
        let bands: Vec<f64> = c
            .per_band
            .iter()
            .filter(|b| b.held_out && systematic_energy(b.before_m, noise_m) > floor * floor)
            .map(|b| {
                1.0 - systematic_energy(b.after_m, noise_m) / systematic_energy(b.before_m, noise_m)
            })
            .collect();
        let lowest = bands.iter().cloned().fold(f64::INFINITY, f64::min);
        let highest = bands.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
        (!bands.is_empty()
            && share > PARTIAL_SHARE
            && own > PARTIAL_SHARE
            && lowest > PARTIAL_SHARE)
            .then(|| PartialExplanation {
                effect: c.effect.clone(),
                share_of_gap: share,
                share_spread: 0.5 * (highest - lowest),
                lowest_band_share: lowest,
            })
    })
}
