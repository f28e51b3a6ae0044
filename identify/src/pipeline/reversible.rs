//! Whether the model gets a reversible part `R(H)` beside `Γ` (`--reversible`).
//!
//! `auto` keeps the paper's model (`M = Γ[H]`) unless
//!
//! 1. its masses sum past `M_s` ([`MASS_SUM_PAST_SATURATION`]): the records show more
//!    magnetization than `Γ` saturates at;
//! 2. the masses capped at `M_s` with a piecewise reversible part describe every quasi-static
//!    record within [`quality::QUASI_STATIC_NRMSE_LIMIT`];
//! 3. with dynamic records, `R_eddy`, `ξ`, `f0` identified on either model, the reversible one
//!    predicts the lowest-frequency sines no worse ([`lowest_frequency_nrmse`]). A sensor
//!    whose gain depends on position also lifts the sweep past the stroke, and a reversible
//!    part fits that sweep as well, but it is a change of `M`, not of the reading: it changes
//!    the rod's dynamics, and the sines the sweep's static part should predict come out worse.

use super::dynamic::DynamicStage;
use super::{Base, IdentifyError};
use crate::dynamics::DynamicFit;
use crate::fit::{FitOptions, Reversible};
use crate::masses::{identify_masses, MassIdentification, MassOptions};
use crate::quality;

/// Key of `--reversible auto`'s decision in the identified file's provenance.
pub const PROVENANCE_KEY: &str = "reversible_part";

/// How far past `M_s` the paper's model's masses may sum before `auto` tries a reversible part
/// (identifications of rods without one sum to within 0.02 % of `M_s`; a tenth of the quasi-
/// static NRMSE limit leaves room for noise).
pub const MASS_SUM_PAST_SATURATION: f64 = 1.02;

/// `--reversible`: the paper's model, with a reversible part, or chosen from the data.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ReversiblePart {
    /// `M = Γ[H]`.
    None,
    /// `M = Γ[H] + R(H)`, `R` monotone piecewise linear.
    Piecewise,
    /// Chosen by the rules of the module docs.
    Auto,
}

impl ReversiblePart {
    /// Interface names.
    pub const NAMES: [(&'static str, ReversiblePart); 3] = [
        ("none", ReversiblePart::None),
        ("piecewise", ReversiblePart::Piecewise),
        ("auto", ReversiblePart::Auto),
    ];

    /// Parses an interface name.
    pub fn parse(text: &str) -> Result<Self, String> {
        Self::NAMES
            .iter()
            .find(|(n, _)| *n == text)
            .map(|(_, r)| *r)
            .ok_or_else(|| format!("`{text}`: expected `none`, `piecewise` or `auto`"))
    }

    /// The interface name.
    pub fn name(self) -> &'static str {
        Self::NAMES
            .iter()
            .find(|(_, r)| *r == self)
            .map_or("?", |(n, _)| n)
    }

    /// The mass fit's setting for the first identification (`auto` starts without one).
    pub fn first_fit(self) -> Reversible {
        match self {
            ReversiblePart::Piecewise => Reversible::PiecewiseNoOffset,
            ReversiblePart::None | ReversiblePart::Auto => Reversible::None,
        }
    }
}

/// `auto`'s decision: the choice, why, and the figures it rests on.
#[derive(Debug, Clone, PartialEq)]
pub struct ReversibleChoice {
    /// `none` or `piecewise`.
    pub chosen: &'static str,
    /// Why, in one sentence.
    pub reason: String,
    /// The paper's model's mass sum over `M_s`.
    pub mass_sum_over_saturation_without: f64,
    /// The figures the decision compared (name, value).
    pub figures: Vec<(&'static str, f64)>,
}

impl ReversibleChoice {
    /// The provenance record.
    pub fn provenance(&self) -> serde_json::Value {
        let mut d = serde_json::json!({"chosen": self.chosen, "reason": self.reason,
            "mass_sum_over_saturation_without": self.mass_sum_over_saturation_without});
        for &(key, value) in &self.figures {
            d[key] = serde_json::json!(value);
        }
        d
    }
}

/// What [`choose`] decided, and what the identification goes on with.
pub struct Decided {
    /// The decision.
    pub choice: ReversibleChoice,
    /// The chosen model's masses.
    pub masses: MassIdentification,
    /// The mass options that give them.
    pub options: MassOptions,
    /// The chosen model's first-pass dynamic fit, when step 3 ran.
    pub first_pass: Option<DynamicFit>,
}

/// The worst quasi-static record's displacement NRMSE (0 without any).
fn worst_quasi_static_nrmse(id: &MassIdentification) -> f64 {
    id.files
        .iter()
        .filter_map(|f| f.nrmse_displacement)
        .fold(0.0, f64::max)
}

/// The mean NRMSE of the final dynamic fit over the sines at the lowest frequency (within
/// 10 %): the ones a static part of the model shows in most and unmodelled dynamics least.
pub fn lowest_frequency_nrmse(fit: &DynamicFit) -> Option<f64> {
    let lowest = fit
        .experiments
        .iter()
        .map(|e| e.frequency_hz)
        .fold(f64::INFINITY, f64::min);
    let values: Vec<f64> = fit
        .experiments
        .iter()
        .filter(|e| e.frequency_hz <= 1.1 * lowest)
        .filter_map(|e| e.nrmse_refined)
        .collect();
    (!values.is_empty()).then(|| values.iter().sum::<f64>() / values.len() as f64)
}

/// `auto` (module docs), from the paper's model's masses `without`.
pub fn choose(
    stage: &DynamicStage<'_>,
    base: Base<'_>,
    options: &MassOptions,
    without: MassIdentification,
) -> Result<Decided, IdentifyError> {
    let ms = base.params.actuator.saturation_magnetization_a_per_m;
    let choosing = Choosing {
        options,
        mass_ratio: without.fit.weights.iter().sum::<f64>() / ms,
    };
    let mass_ratio = choosing.mass_ratio;
    // Rule 1.
    if mass_ratio <= MASS_SUM_PAST_SATURATION {
        let choice = choosing.decision(
            "none",
            format!(
                "none: the masses of the paper's model sum to {mass_ratio:.4} x M_s (<= {MASS_SUM_PAST_SATURATION})"
            ),
            &[],
        );
        return Ok(choosing.keep_without(choice, without, None));
    }
    // Rule 2.
    let with_options = MassOptions {
        fit: FitOptions {
            reversible: Reversible::PiecewiseNoOffset,
            ..options.fit
        },
        ..options.clone()
    };
    let dataset = stage.dataset.split.quasi_static_dataset();
    let with = identify_masses(&dataset, base.params, base.name, &with_options)
        .map_err(|e| IdentifyError::step("Preisach masses with a reversible part", e))?;
    let sweep_with = worst_quasi_static_nrmse(&with);
    let limit = quality::QUASI_STATIC_NRMSE_LIMIT;
    if sweep_with > limit {
        let choice = choosing.decision(
            "none",
            format!(
                "none: {}, but with a reversible part the quasi-static records are missed by \
                 {:.2} % NRMSE (> {:.0} %)",
                choosing.past(),
                100.0 * sweep_with,
                100.0 * limit
            ),
            &[("worst_quasi_static_nrmse_with", sweep_with)],
        );
        return Ok(choosing.keep_without(choice, without, None));
    }
    let with = Candidate {
        masses: with,
        options: with_options,
        sweep_nrmse: sweep_with,
    };
    if stage.dataset.split.dynamic.is_empty() || !stage.options.waveform_fit {
        let reason = format!(
            "piecewise: {}; with a reversible part the masses sum to at most M_s and the \
             quasi-static records are met within {:.2} % NRMSE (no sines to check it on)",
            choosing.past(),
            100.0 * sweep_with
        );
        let choice = choosing.decision("piecewise", reason, &with.sweep_figure());
        return Ok(with.chosen(choice, None));
    }
    // Rule 3.
    choosing.by_the_sines(stage, without, with)
}

/// What every decision of [`choose`] shares: the mass options, and the paper's model's mass
/// sum over `M_s`.
struct Choosing<'a> {
    options: &'a MassOptions,
    mass_ratio: f64,
}

/// The model with a reversible part, once it met the quasi-static records (rule 2).
struct Candidate {
    masses: MassIdentification,
    options: MassOptions,
    /// Its worst quasi-static record's NRMSE.
    sweep_nrmse: f64,
}

impl Candidate {
    /// The figure rule 2 rests on, for the provenance.
    fn sweep_figure(&self) -> [(&'static str, f64); 1] {
        [("worst_quasi_static_nrmse_with", self.sweep_nrmse)]
    }

    /// The decision to keep the reversible part (`first_pass`: its dynamic fit, when rule 3 ran).
    fn chosen(self, choice: ReversibleChoice, first_pass: Option<DynamicFit>) -> Decided {
        Decided {
            choice,
            masses: self.masses,
            options: self.options,
            first_pass,
        }
    }
}

impl Choosing<'_> {
    /// The decision record: `chosen`, why, and the figures it compared.
    fn decision(
        &self,
        chosen: &'static str,
        reason: String,
        figures: &[(&'static str, f64)],
    ) -> ReversibleChoice {
        ReversibleChoice {
            chosen,
            reason,
            mass_sum_over_saturation_without: self.mass_ratio,
            figures: figures.to_vec(),
        }
    }

    /// The decision to keep the paper's model (`first_pass`: its dynamic fit, when rule 3 ran).
    fn keep_without(
        &self,
        choice: ReversibleChoice,
        without: MassIdentification,
        first_pass: Option<DynamicFit>,
    ) -> Decided {
        Decided {
            choice,
            masses: without,
            options: self.options.clone(),
            first_pass,
        }
    }

    /// Rule 1's finding, the start of every later reason.
    fn past(&self) -> String {
        format!(
            "the masses of the paper's model sum to {:.4} x M_s",
            self.mass_ratio
        )
    }

    /// Rule 3: `R_eddy`, `ξ`, `f0` identified on either model; the reversible part is kept when
    /// it predicts the lowest-frequency sines no worse.
    fn by_the_sines(
        &self,
        stage: &DynamicStage<'_>,
        without: MassIdentification,
        with: Candidate,
    ) -> Result<Decided, IdentifyError> {
        let fit_without = stage.fit(&without.params, None)?;
        let fit_with = stage.fit(&with.masses.params, None)?;
        let (low_without, low_with) = (
            lowest_frequency_nrmse(&fit_without).unwrap_or(f64::INFINITY),
            lowest_frequency_nrmse(&fit_with).unwrap_or(f64::INFINITY),
        );
        let figures = [
            with.sweep_figure()[0],
            ("lowest_frequency_sine_nrmse_without", low_without),
            ("lowest_frequency_sine_nrmse_with", low_with),
        ];
        let sines = format!(
            "the lowest-frequency sines are predicted within {:.2} % NRMSE with a reversible \
             part, {:.2} % without",
            100.0 * low_with,
            100.0 * low_without
        );
        if low_with <= low_without {
            let reason = format!(
                "piecewise: {}; with a reversible part they sum to at most M_s, the \
                 quasi-static records are met within {:.2} % NRMSE and {sines}",
                self.past(),
                100.0 * with.sweep_nrmse
            );
            let choice = self.decision("piecewise", reason, &figures);
            Ok(with.chosen(choice, Some(fit_with)))
        } else {
            let choice = self.decision(
                "none",
                format!(
                    "none: {}, but {sines}: the excess is not a change of M",
                    self.past()
                ),
                &figures,
            );
            Ok(self.keep_without(choice, without, Some(fit_without)))
        }
    }
}
