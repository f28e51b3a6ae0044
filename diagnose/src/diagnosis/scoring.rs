//! Scoring a fitted candidate on the held-out experiments against the refitted nominal model:
//! its predictions, its systematic gap before and after, the knock-out test of significance,
//! the per-band errors, and the order of the fits with ties broken.

use super::recording::Recording;
use super::report::{BandError, CandidateResult, HeldOutTie, TiedFit};
use super::rules::{
    none_threshold, EQUAL_HELD_OUT, EXPLAINED_RATIO, MAX_WORSE_SHARE, NEEDED_FACTOR,
    WITHIN_NOISE_RATIO, WORSE_NOISE_SHARE, WORSE_RMS_FACTOR,
};
use maglab_model::experiments::ExperimentInfo;
use maglab_model::fit::{ExperimentData, Fitted, ModelSetup};
use maglab_model::plan_fit::{PlanFit, PlanFitter};
use maglab_model::residual::{offset_of, pooled_rms, systematic};
use std::collections::BTreeMap;

/// A candidate's predictions on every dynamic experiment, with its training offset.
#[derive(Debug, Clone)]
pub struct Scored {
    /// Prediction per dynamic experiment, m (without the offset).
    pub preds: BTreeMap<usize, Vec<f64>>,
    /// The training experiments' least-squares offset, m.
    pub offset: f64,
}

impl Scored {
    /// The predictions with the offset added.
    pub fn offset_preds(&self) -> BTreeMap<usize, Vec<f64>> {
        self.preds
            .iter()
            .map(|(&k, p)| (k, p.iter().map(|v| v + self.offset).collect()))
            .collect()
    }
}

/// A fit, its result and its predictions, as the ranking holds them.
pub type Ranked = (CandidateResult, PlanFit, Scored);

/// Orders fitted candidates by their held-out RMS error, best first; then, among the `eligible`
/// fits whose held-out error is within [`EQUAL_HELD_OUT`] of the best eligible one's (a tie the
/// data do not resolve), the one with the fewest constants at an end of their band goes to where
/// the best eligible one was (on equal counts the lower held-out error). Nothing else moves.
/// Returns the tie, when two or more eligible fits were in it.
pub fn sort_by_held_out(
    fits: &mut [Ranked],
    eligible: impl Fn(&CandidateResult) -> bool,
) -> Option<HeldOutTie> {
    fits.sort_by(|a, b| {
        a.0.held_out_rms_after_m
            .total_cmp(&b.0.held_out_rms_after_m)
    });
    let results: Vec<&CandidateResult> = fits.iter().map(|f| &f.0).collect();
    let tie = held_out_tie_break(&results, eligible)?;
    let first = tie.tied[0];
    let record = (tie.tied.len() > 1).then(|| HeldOutTie {
        tied: std::iter::once(tie.preferred)
            .chain(tie.tied.iter().copied().filter(|&i| i != tie.preferred))
            .map(|i| TiedFit {
                effect: results[i].effect.clone(),
                held_out_rms_after_m: results[i].held_out_rms_after_m,
                constants_at_range_end: results[i].constants_at_range_end.clone(),
            })
            .collect(),
    });
    fits[first..=tie.preferred].rotate_right(1);
    record
}

/// The outcome of [`held_out_tie_break`], as indices into the ordered results.
#[derive(Debug, PartialEq)]
pub struct TieIndices {
    /// The one preferred (the best eligible one, `tied[0]`, when nothing was preferred to it).
    pub preferred: usize,
    /// The eligible results within [`EQUAL_HELD_OUT`] of the best eligible one's held-out
    /// error, it first, in held-out order.
    pub tied: Vec<usize>,
}

/// For `results` ordered by held-out error: the best eligible one, the one preferred to it —
/// among the eligible results within [`EQUAL_HELD_OUT`] of the best eligible one's held-out
/// error, the one with the fewest [`CandidateResult::constants_at_range_end`] (the earlier on
/// equal counts) — and those tied.
pub fn held_out_tie_break(
    results: &[&CandidateResult],
    eligible: impl Fn(&CandidateResult) -> bool,
) -> Option<TieIndices> {
    let first = results.iter().position(|r| eligible(r))?;
    let limit = EQUAL_HELD_OUT * results[first].held_out_rms_after_m;
    let tied: Vec<usize> = (first..results.len())
        .take_while(|&i| results[i].held_out_rms_after_m <= limit)
        .filter(|&i| eligible(results[i]))
        .collect();
    let preferred = *tied
        .iter()
        .min_by_key(|&&i| (results[i].constants_at_range_end.len(), i))?;
    Some(TieIndices { preferred, tied })
}

/// Scores fits against the refitted nominal model on the held-out experiments.
pub struct Scorer<'a> {
    /// The model.
    pub setup: ModelSetup<'a>,
    /// The fitter of the knock-out refits (none: the knock-out is not refitted).
    pub fitter: Option<&'a PlanFitter<'a>>,
    /// Every start plan's view of the experiments.
    pub plan_data: &'a [Vec<ExperimentData<'a>>],
    /// The dynamic experiments.
    pub dynamic: &'a [usize],
    /// The training experiments.
    pub training: &'a [usize],
    /// The held-out experiments.
    pub held_out: &'a [usize],
    /// The experiments' descriptions (frequency groups, held out or not).
    pub infos: &'a [ExperimentInfo],
    /// White-noise level σ, m.
    pub noise_m: f64,
    /// [`super::rules::none_threshold`] of the dataset, m.
    pub none_threshold_m: f64,
}

impl<'a> Scorer<'a> {
    /// The scorer of a recording's experiments (`rec`, its start plans' views `plan_data`) in
    /// the model `setup`, refitting knock-outs with `fitter`.
    pub fn of_recording(
        setup: ModelSetup<'a>,
        fitter: &'a PlanFitter<'a>,
        plan_data: &'a [Vec<ExperimentData<'a>>],
        rec: &'a Recording,
    ) -> Scorer<'a> {
        Scorer {
            setup,
            fitter: Some(fitter),
            plan_data,
            dynamic: &rec.dynamic,
            training: &rec.training,
            held_out: &rec.held_out,
            infos: &rec.infos,
            noise_m: rec.noise_m,
            none_threshold_m: none_threshold(rec.noise_m, rec.range_m),
        }
    }
}

impl Scorer<'_> {
    /// `f`'s predictions on every dynamic experiment, with its training offset.
    pub fn predict(&self, f: &PlanFit) -> Scored {
        let (e, m) = f.fitted.model();
        let data = &self.plan_data[f.plan];
        let preds: BTreeMap<usize, Vec<f64>> = self
            .dynamic
            .iter()
            .copied()
            .zip(self.setup.predict_all(&e, &m, data, self.dynamic))
            .collect();
        let items: Vec<(&[f64], &[f64], usize)> = self
            .training
            .iter()
            .map(|&k| (preds[&k].as_slice(), data[k].measured_m, data[k].settle))
            .collect();
        let offset = offset_of(&items);
        Scored { preds, offset }
    }

    /// Both effects of a pair fit are needed: with either switched off and the rest refitted
    /// (from the pair's values and from that effect's single fit), the held-out gap is at least
    /// twice `gap`. Also returns those refits of one effect alone (the first that fails ends
    /// the test): started from a pair's optimum, such a refit may reach a better optimum of the
    /// single candidate than its own grid of starts did.
    pub fn necessary(
        &self,
        pair: &PlanFit,
        singles: &[&PlanFit],
        gap: f64,
    ) -> (bool, Vec<PlanFit>) {
        let Some(fitter) = self.fitter else {
            return (true, Vec::new());
        };
        let f = &pair.fitted;
        let distinct = f.candidate.distinct_effects();
        // Each effect switched off (all its terms); for one effect in its richer form, its
        // second term.
        let reductions: Vec<Fitted> = if distinct.len() == 1 {
            vec![f.knocked_out(f.candidate.effects.len().saturating_sub(1))]
        } else {
            distinct.iter().map(|&e| f.without(e)).collect()
        };
        let mut reduced = Vec::new();
        for kept in reductions {
            let mut starts = vec![kept.values.clone()];
            if let Some(single) = singles
                .iter()
                .find(|s| s.fitted.candidate == kept.candidate)
            {
                starts.push(single.fitted.values.clone());
            }
            let refit = fitter.fit_from(&kept.candidate, &starts, pair.plan, false);
            let remaining =
                systematic(self.rms(&self.predict(&refit), self.held_out), self.noise_m);
            reduced.push(refit);
            if remaining < NEEDED_FACTOR * gap {
                return (false, reduced);
            }
        }
        (true, reduced)
    }

    /// The model's own numerical error on the held-out experiments at `f`'s parameters
    /// (`base` its prediction): the RMS difference, its mean removed, between the prediction
    /// with the setup's substeps and with twice as many.
    pub fn discretization_error(&self, f: &PlanFit, base: &Scored) -> f64 {
        let finer_setup = ModelSetup {
            substeps: 2 * self.setup.substeps,
            ..self.setup
        };
        let (e, m) = f.fitted.model();
        let data = &self.plan_data[f.plan];
        let finer = finer_setup.predict_all(&e, &m, data, self.held_out);
        let items: Vec<(&[f64], &[f64], usize)> = self
            .held_out
            .iter()
            .zip(&finer)
            .map(|(&k, fine)| (base.preds[&k].as_slice(), fine.as_slice(), data[k].settle))
            .collect();
        pooled_rms(&items, offset_of(&items))
    }

    /// Pooled RMS error of `s` over the experiments `which`, m.
    pub fn rms(&self, s: &Scored, which: &[usize]) -> f64 {
        let items: Vec<(&[f64], &[f64], usize)> = which
            .iter()
            .map(|&k| {
                let x = &self.plan_data[0][k];
                (s.preds[&k].as_slice(), x.measured_m, x.settle)
            })
            .collect();
        pooled_rms(&items, s.offset)
    }

    /// The scores of `plan_fit` (predictions `s`) against the refitted nominal model's `base`.
    pub fn result(&self, plan_fit: &PlanFit, s: &Scored, base: &Scored) -> CandidateResult {
        let f = &plan_fit.fitted;
        let before = self.rms(base, self.held_out);
        let after = self.rms(s, self.held_out);
        let (improved, worse) = self.improved_and_worse(s, base);
        let sys_before = systematic(before, self.noise_m);
        let sys_after = systematic(after, self.noise_m);
        let pinned: Vec<String> = f.pinned();
        let effects = f.candidate.effects.len();
        let passes = |knocked_out: f64| {
            effects > 0
                && pinned.is_empty()
                && {
                    let gap = sys_before.min(systematic(knocked_out, self.noise_m));
                    sys_after <= EXPLAINED_RATIO * gap
                        || (sys_after <= WITHIN_NOISE_RATIO * gap
                            && sys_after <= self.none_threshold_m)
                }
                && worse as f64 <= MAX_WORSE_SHARE * self.held_out.len() as f64
        };
        let (knocked_out, significant) = self.knock_out(plan_fit, before, passes);
        CandidateResult {
            effect: f.candidate.name(),
            parameters: f
                .report_names()
                .into_iter()
                .zip(f.values.iter().copied())
                .collect(),
            training_rms_m: f.training_rms_m,
            held_out_rms_before_m: before,
            held_out_rms_after_m: after,
            held_out_reduction: before / after.max(1e-300),
            systematic_before_m: sys_before,
            systematic_after_m: sys_after,
            improved_experiments: improved,
            worse_experiments: worse,
            held_out_experiments: self.held_out.len(),
            knocked_out_rms_m: knocked_out,
            pinned,
            constants_at_range_end: f.shared_at_range_end(),
            significant,
            per_band: self.per_band(s, base),
            evaluations: f.evaluations,
        }
    }

    /// How many held-out experiments `s` fits better than `base`, and how many it makes worse
    /// (RMS up by more than [`WORSE_RMS_FACTOR`] and [`WORSE_NOISE_SHARE`] σ).
    fn improved_and_worse(&self, s: &Scored, base: &Scored) -> (usize, usize) {
        let (mut improved, mut worse) = (0, 0);
        for &k in self.held_out {
            let (b, a) = (self.rms(base, &[k]), self.rms(s, &[k]));
            if a < b {
                improved += 1;
            }
            if a > WORSE_RMS_FACTOR * b + WORSE_NOISE_SHARE * self.noise_m {
                worse += 1;
            }
        }
        (improved, worse)
    }

    /// The knock-out test: the held-out RMS of the fit with its last effect switched off
    /// (`before`, the refitted nominal model's, for the nominal candidate itself) and whether the
    /// candidate `passes` against it. When it passes and the fitter is at hand, the knocked-out
    /// model is also refitted from this fit's own values and the lower of the two knock-out
    /// errors (the stricter test) decides: if the refit reaches what the candidate reaches, the
    /// candidate only found a better optimum of the shared parameters.
    fn knock_out(
        &self,
        plan_fit: &PlanFit,
        before: f64,
        passes: impl Fn(f64) -> bool,
    ) -> (f64, bool) {
        let f = &plan_fit.fitted;
        let effects = f.candidate.effects.len();
        let knocked_out = if effects == 0 {
            before
        } else {
            let k = PlanFit {
                fitted: f.knocked_out(effects - 1),
                plan: plan_fit.plan,
            };
            self.rms(&self.predict(&k), self.held_out)
        };
        match self.fitter {
            Some(fitter) if passes(knocked_out) => {
                let k = f.knocked_out(effects - 1);
                let again = fitter.fit_from(
                    &k.candidate,
                    std::slice::from_ref(&k.values),
                    plan_fit.plan,
                    false,
                );
                let refitted = self.rms(&self.predict(&again), self.held_out);
                let worst = knocked_out.min(refitted);
                (worst, passes(worst))
            }
            _ => (knocked_out, passes(knocked_out)),
        }
    }

    /// The RMS errors of `base` and `s` per frequency group of the dynamic experiments, with the
    /// group's mean fundamental and whether it is held out.
    fn per_band(&self, s: &Scored, base: &Scored) -> Vec<BandError> {
        let groups = self
            .dynamic
            .iter()
            .map(|&k| self.infos[k].frequency_group)
            .max()
            .unwrap_or(0)
            + 1;
        (0..groups)
            .filter_map(|g| {
                let which: Vec<usize> = self
                    .dynamic
                    .iter()
                    .copied()
                    .filter(|&k| self.infos[k].frequency_group == g)
                    .collect();
                if which.is_empty() {
                    return None;
                }
                Some(BandError {
                    frequency_hz: which
                        .iter()
                        .map(|&k| self.infos[k].fundamental_hz)
                        .sum::<f64>()
                        / which.len() as f64,
                    before_m: self.rms(base, &which),
                    after_m: self.rms(s, &which),
                    held_out: self.infos[which[0]].held_out,
                })
            })
            .collect()
    }
}
