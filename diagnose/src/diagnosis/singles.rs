//! Steps 6 and 7 for one effect at a time: the nominal model refitted on the training
//! experiments, each library effect fitted on top, and the ranking on the held-out ones.

use super::report::HeldOutTie;
use super::rules::{none_threshold, resolution_floor, MODEL_ERROR_FACTOR};
use super::scoring::{sort_by_held_out, Ranked, Scored, Scorer};
use maglab_model::candidates::{self, Candidate, COMMON_PARAMETER_COUNT};
use maglab_model::effects::EffectName;
use maglab_model::model::Nominal;
use maglab_model::plan_fit::{PlanFit, PlanFitter};
use rayon::prelude::*;

/// The sizes every verdict compares against, m.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Gaps {
    /// The refitted nominal model's held-out systematic gap.
    pub gap0: f64,
    /// The gap estimate's resolution ([`resolution_floor`]).
    pub floor: f64,
    /// Below it the verdict is `none` outright: the resolution or [`MODEL_ERROR_FACTOR`] times
    /// the model's own integration error.
    pub none_floor: f64,
    /// White-noise level σ.
    pub noise_m: f64,
    /// Displacement range of the dynamic experiments.
    pub range_m: f64,
}

impl Gaps {
    /// The gaps of a refitted nominal model that leaves `gap0` with an integration error of
    /// `model_error_m`.
    pub fn new(gap0: f64, model_error_m: f64, noise_m: f64, range_m: f64) -> Self {
        let floor = resolution_floor(noise_m, range_m);
        Gaps {
            gap0,
            floor,
            // A gap the model's own integration error can account for is no effect: below the
            // larger floor the verdict is `none` outright, and the threshold is at least that
            // floor.
            none_floor: floor.max(MODEL_ERROR_FACTOR * model_error_m),
            noise_m,
            range_m,
        }
    }

    /// [`none_threshold`] of the dataset.
    pub fn none_threshold(&self) -> f64 {
        none_threshold(self.noise_m, self.range_m)
    }

    /// The gap is above the noise-based threshold but within the model's own integration
    /// error: `none` only because of the model, whatever the candidates do.
    pub fn only_the_model_error_says_none(&self) -> bool {
        self.gap0 > self.floor.max(self.none_threshold()) && self.gap0 <= self.none_floor
    }
}

/// What every step after the refit shares: the fitter, the scorer, the nominal constants, the
/// refitted nominal model's prediction and the gaps.
pub struct Stage<'a> {
    /// Fits candidates on the training experiments.
    pub fitter: &'a PlanFitter<'a>,
    /// Scores them on the held-out ones.
    pub scorer: &'a Scorer<'a>,
    /// The parameter file's constants with what the data give.
    pub nominal: &'a Nominal,
    /// The refitted nominal model's prediction.
    pub base: &'a Scored,
    /// The gaps.
    pub gaps: Gaps,
}

/// The starting values of the shared parameters: the file's `R_eddy`, `ξ`, `f0` and the
/// estimated skew.
pub fn common_start(nominal: &Nominal, skew: f64) -> Vec<f64> {
    vec![
        nominal.eddy_resistance_ohm,
        nominal.damping_ratio,
        nominal.resonance_hz,
        skew,
    ]
}

/// The nominal model with `R_eddy`, `ξ`, `f0` and the skew refitted (step 6).
pub fn refit_nominal(fitter: &PlanFitter<'_>, common_start: &[f64]) -> PlanFit {
    fitter.fit(&Candidate::nominal(), &[common_start.to_vec()])
}

/// Every effect of `library` fitted on top of the nominal model, scored and ranked best first on the
/// held-out experiments (steps 6 and 7); the tie the best significant one was in, if any.
pub fn fit_library(
    stage: &Stage<'_>,
    refit: &PlanFit,
    common_start: &[f64],
    library: &[EffectName],
    progress: &(dyn Fn(u64) + Sync),
) -> (Vec<Ranked>, Option<HeldOutTie>) {
    let fitted: Vec<PlanFit> = library
        .par_iter()
        .map(|&effect| {
            let commons = common_starts(
                &refit.fitted.values[..COMMON_PARAMETER_COUNT],
                common_start,
                stage.fitter.settings.refit_range[2],
                effect,
            );
            let starts: Vec<Vec<f64>> = candidates::effect_starts(effect, stage.nominal)
                .into_iter()
                .flat_map(|s| {
                    commons
                        .iter()
                        .map(move |c| c.iter().copied().chain(s.clone()).collect())
                })
                .collect();
            let f = stage.fitter.fit(&Candidate::single(effect), &starts);
            progress(1);
            f
        })
        .collect();
    let mut ranked: Vec<Ranked> = fitted
        .into_par_iter()
        .map(|f| {
            let s = stage.scorer.predict(&f);
            (stage.scorer.result(&f, &s, stage.base), f, s)
        })
        .collect();
    let tie = sort_by_held_out(&mut ranked, |r| r.significant);
    (ranked, tie)
}

/// Whether the identification reads `effect`'s lag as a lower `f0` (the phase of eq. (5)'s
/// second-order section grows as `f0` falls): the [`super::verdict::LAG_EFFECTS`] but the eddy
/// path, whose lag an identification absorbs into `R_eddy`, the constant of eq. (4) it shares a
/// term with.
fn read_as_lower_f0(effect: EffectName) -> bool {
    effect != EffectName::EddyFrequencyDependence && super::verdict::LAG_EFFECTS.contains(&effect)
}

/// The shared parameters (`R_eddy`, `ξ`, `f0`, skew) `effect`'s fit starts from: the `refitted`
/// ones and the file's `common_start` (the refitted ones may have stretched to mimic the
/// effect). When the file's `f0` was identified from data (its refit factor `f0_factor` widened,
/// [`super::rules::IDENTIFIED_REFIT_RANGE`]) and `effect`'s lag is [`read_as_lower_f0`], also
/// the file's with `f0` raised by the square root of that factor: the effect's optimum lies above
/// the identified `f0`, and a start from below stops in the valley where the effect and a low
/// `f0` share the lag.
fn common_starts(
    refitted: &[f64],
    common_start: &[f64],
    f0_factor: f64,
    effect: EffectName,
) -> Vec<Vec<f64>> {
    let mut commons = vec![refitted.to_vec(), common_start.to_vec()];
    if read_as_lower_f0(effect) && f0_factor > candidates::REFIT_RANGE[2] {
        let mut raised = common_start.to_vec();
        raised[2] *= f0_factor.sqrt();
        commons.push(raised);
    }
    commons
}

/// The knock-out refits of one effect alone (started from a pair's optimum) that fit the
/// training experiments better than that effect's own single fit replace it: a better optimum
/// of the same candidate, chosen by the training fit, never by the held-out score (a two-mode
/// load's single fit can stop in a local minimum that the fit of the load with another effect
/// escapes). Returns whether any replaced one.
pub fn take_better_optima(stage: &Stage<'_>, ranked: &mut [Ranked], refits: Vec<PlanFit>) -> bool {
    let mut replaced = false;
    for refit in refits {
        let scored = stage.scorer.predict(&refit);
        let result = stage.scorer.result(&refit, &scored, stage.base);
        if let Some(k) = ranked.iter().position(|r| r.0.effect == result.effect) {
            if result.training_rms_m < ranked[k].0.training_rms_m {
                ranked[k] = (result, refit, scored);
                replaced = true;
            }
        }
    }
    replaced
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_lag_on_an_identified_f0_also_starts_from_f0_raised() {
        let (refitted, file) = ([60.0, 0.7, 250.0, 0.1], [70.0, 0.6, 240.0, 0.1]);
        let identified = candidates::IDENTIFICATION_RANGE[2];
        let lags = [
            EffectName::SensorDynamics,
            EffectName::MechanicalLoad,
            EffectName::AmplifierBandwidth,
        ];
        for effect in lags {
            let starts = common_starts(&refitted, &file, identified, effect);
            assert_eq!(starts.len(), 3, "{effect:?}");
            assert_eq!(starts[..2], [refitted.to_vec(), file.to_vec()]);
            let raised = [70.0, 0.6, 240.0 * identified.sqrt(), 0.1];
            assert_eq!(starts[2], raised);
            // The file's own constants: no reason to expect a lag absorbed into f0.
            let given = candidates::REFIT_RANGE[2];
            assert_eq!(common_starts(&refitted, &file, given, effect).len(), 2);
        }
        // Not a lag: ΔE, thermal drift and the others keep the two starts.
        for effect in [EffectName::DeltaEEffect, EffectName::ThermalDrift] {
            assert_eq!(common_starts(&refitted, &file, identified, effect).len(), 2);
        }
    }
}
