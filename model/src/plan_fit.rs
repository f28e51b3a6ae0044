//! Candidates fitted on the training experiments, each with the start plan that suits it best.

use crate::candidates::Candidate;
use crate::fit::{fit, ExperimentData, FitSettings, Fitted, ModelSetup};
use crate::residual::{offset_of, pooled_rms};
use rayon::prelude::*;

/// A candidate fitted with its own start plan.
#[derive(Debug, Clone)]
pub struct PlanFit {
    pub fitted: Fitted,
    pub plan: usize,
}

/// Fits candidates on the training experiments, each with the start plan that suits it best.
pub struct PlanFitter<'a> {
    pub setup: ModelSetup<'a>,
    pub plan_data: &'a [Vec<ExperimentData<'a>>],
    pub training: &'a [usize],
    pub first_plan: usize,
    pub settings: &'a FitSettings,
}

impl PlanFitter<'_> {
    /// Fits from the nuisance stage's plan, then tries the other plans at the fitted values and
    /// refits with the best if it is better by more than 1 %.
    pub fn fit(&self, candidate: &Candidate, starts: &[Vec<f64>]) -> PlanFit {
        self.fit_from(candidate, starts, self.first_plan, true)
    }

    /// `two_phase`: see [`crate::fit::fit`].
    pub fn fit_from(
        &self,
        candidate: &Candidate,
        starts: &[Vec<f64>],
        plan: usize,
        two_phase: bool,
    ) -> PlanFit {
        let first = fit(
            self.setup,
            &self.plan_data[plan],
            self.training,
            candidate,
            starts,
            self.settings,
            two_phase,
        );
        if self.plan_data.len() <= 1 {
            return PlanFit {
                fitted: first,
                plan,
            };
        }
        let probes: Vec<(usize, f64)> = (0..self.plan_data.len())
            .into_par_iter()
            .filter(|&p| p != plan)
            .map(|p| {
                let data = &self.plan_data[p];
                let (e, m) = first.model();
                let lens: Vec<usize> = self
                    .training
                    .iter()
                    .map(|&k| {
                        (data[k].settle + self.settings.max_fit_samples)
                            .min(data[k].current_a.len())
                    })
                    .collect();
                let preds = self.setup.predict(&e, &m, data, self.training, &lens);
                let items: Vec<(&[f64], &[f64], usize)> = self
                    .training
                    .iter()
                    .zip(&preds)
                    .map(|(&k, p)| (p.as_slice(), data[k].measured_m, data[k].settle))
                    .collect();
                (p, pooled_rms(&items, offset_of(&items)))
            })
            .collect();
        match probes.iter().min_by(|a, b| a.1.total_cmp(&b.1)) {
            Some(&(p, rms)) if rms < 0.99 * first.training_rms_m => {
                let again = fit(
                    self.setup,
                    &self.plan_data[p],
                    self.training,
                    candidate,
                    std::slice::from_ref(&first.values),
                    self.settings,
                    false,
                );
                if again.training_rms_m < first.training_rms_m {
                    PlanFit {
                        fitted: again,
                        plan: p,
                    }
                } else {
                    PlanFit {
                        fitted: first,
                        plan,
                    }
                }
            }
            _ => PlanFit {
                fitted: first,
                plan,
            },
        }
    }
}
