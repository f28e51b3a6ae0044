//! Step 3 of the identification: the masses and `R_eddy`, `ξ`, `f0` fitted in turn.
//!
//! The masses of a pass are fitted to the quasi-static records corrected for the lags (eddy
//! currents, eq. (4); mechanics, eq. (5)) of the pass before and read with its current timing
//! (channel skew, current between samples); `R_eddy`, `ξ`, `f0` are then fitted on those masses,
//! started (with the phase-lag scheme's result) from the base file's values and, after the
//! second pass, from the pass before's too, always within the search around the base file's
//! values that the first pass had. Each pass's masses depend on the constants the pass before
//! left, so one correction is not enough when the base file is far off (a datasheet's `R_eddy`
//! 40 % high takes three or four passes to settle within 3 %).
//!
//! The alternation stops when a pass moved no constant by more than [`PASSES_SETTLED`], when a
//! pass's fit left a residual [`PASSES_DIVERGING`] times the lowest so far (with an effect the
//! model lacks, the alternation can walk away from the data: each pass bends the masses toward
//! the constants that absorbed the effect), or after [`MAX_PASSES`].
//!
//! The pass kept: when the alternation settled, the settled pass — the fixed point of the
//! alternation, where the masses were corrected with the lags of the constants they give —
//! unless a pass before it fit the sines better by more than [`PASSES_SETTLED`] of its RMS NRMSE
//! (a walk away from the data shows as a residual that grows by more than that). Otherwise, and
//! when the alternation stopped diverging or ran out of passes, the pass whose dynamic fit left
//! the lowest RMS NRMSE on the sines. Near the fixed point the sines' residual is flat (it is
//! quadratic in the constants' move, and the constants absorb what the masses miss on the sines'
//! loops): on a noise-only folder passes 3 % apart in `R_eddy` fit within 0.3 % of each other, so
//! the lowest of such residuals does not say which constants are right, while the settled pass
//! is the one whose masses saw its own lags. The first pass, with the base file's lags, is
//! never a candidate: its masses were corrected with lags nobody measured.

use super::dynamic::{current_shift_samples, fit_constants, rms_nrmse, DynamicStage};
use super::{Base, IdentifyError};
use crate::dynamics::DynamicFit;
use crate::masses::{identify_masses, MassIdentification, MassOptions};
use crate::quality;
use actuator_params::ActuatorParams;
use maglab_model::candidates::IDENTIFICATION_RANGE;
use serde_json::json;

/// Passes of the alternation, the first included.
pub const MAX_PASSES: usize = 6;

/// The alternation stops when a pass moved none of `R_eddy`, `ξ`, `f0` by more than this
/// fraction (a sixth of the 3 % an identification is asked to reach).
pub const PASSES_SETTLED: f64 = 0.005;

/// The alternation stops when a pass's RMS NRMSE on the sines exceeds the lowest so far by this
/// factor (the sines' residual grows as the masses follow constants that absorbed an effect).
pub const PASSES_DIVERGING: f64 = 1.25;

/// `[R_eddy, ξ, f0]` of a parameter file (the search's centre).
pub fn constants_of(params: &ActuatorParams) -> [f64; 3] {
    let a = &params.actuator;
    [a.eddy_resistance_ohm, a.damping_ratio, a.resonance_hz]
}

/// One pass of the alternation.
#[derive(Debug, Clone, PartialEq)]
pub struct PassRecord {
    /// 1-based; pass 1 corrects the masses with the base file's lags.
    pub pass: usize,
    /// `[R_eddy, ξ, f0]` the masses' lag correction used.
    pub lags: [f64; 3],
    /// The constants whose base-file value the correction kept because the sines' value lay at
    /// an end of the search.
    pub base_value_kept_for: Vec<&'static str>,
    /// Where the masses read the current, samples after its own time stamp.
    pub current_shift_samples: f64,
    /// `[R_eddy, ξ, f0]` the sines gave on these masses.
    pub fitted: [f64; 3],
    /// RMS NRMSE of that fit on the sines.
    pub rms_nrmse: f64,
    /// Largest relative move of a constant from the pass before (none for pass 1).
    pub moved_from_pass_before: Option<f64>,
}

/// The pass the alternation kept, with the record of every pass.
#[derive(Debug, Clone)]
pub struct ChosenPass {
    /// Its masses.
    pub masses: MassIdentification,
    /// Its dynamic fit.
    pub fit: DynamicFit,
    /// Which pass it was (1-based).
    pub pass: usize,
    /// Kept as the pass the alternation settled on (otherwise: the lowest RMS NRMSE).
    pub settled: bool,
    /// Every pass, in order.
    pub passes: Vec<PassRecord>,
}

impl ChosenPass {
    /// The provenance record (`masses_lag_correction`): the kept pass's lags and every pass.
    pub fn provenance(&self) -> serde_json::Value {
        let mut record = pass_json(&self.passes[self.pass - 1]);
        record["kept_because"] = json!(if self.settled {
            "settled"
        } else {
            "lowest_rms_nrmse"
        });
        record["passes"] = self.passes.iter().map(pass_json).collect();
        record
    }
}

/// A pass as the provenance records it (the keys the provenance always used).
fn pass_json(p: &PassRecord) -> serde_json::Value {
    let mut v = json!({
        "pass": p.pass,
        "eddy_resistance_ohm": p.lags[0],
        "damping_ratio": p.lags[1],
        "resonance_hz": p.lags[2],
        "fitted": p.fitted,
        "rms_nrmse": p.rms_nrmse,
    });
    if p.pass > 1 {
        v["base_file_value_kept_for"] = json!(p.base_value_kept_for);
        v["current_shift_samples"] = json!(p.current_shift_samples);
        v["moved_from_pass_before"] = json!(p.moved_from_pass_before);
    }
    v
}

/// The lags pass `pass` corrects the masses with: the sines' constants of the pass before,
/// except those at an end of their search. There they have absorbed something the model lacks
/// (or the base is far off), and the base file's value is kept: with a lag in the sines R_eddy
/// lands on its floor, and a sweep corrected for that 10-fold eddy time constant gives masses
/// off by a third of their sum or more.
fn lags_for(sines: [f64; 3], based: [f64; 3]) -> ([f64; 3], Vec<&'static str>) {
    let lags: [f64; 3] = std::array::from_fn(|k| {
        if quality::at_search_bound(sines[k], based[k], IDENTIFICATION_RANGE[k]).is_some() {
            based[k]
        } else {
            sines[k]
        }
    });
    let kept = (0..3)
        .filter(|&k| lags[k] != sines[k])
        .map(|k| quality::DYNAMIC_CONSTANT_NAMES[k])
        .collect();
    (lags, kept)
}

/// What the alternation does with a pass (module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Decision {
    /// The pass replaces the one kept so far.
    keep: bool,
    /// It is kept as the settled pass.
    settled: bool,
    /// The alternation stops after it.
    stop: bool,
}

/// The decision on a pass whose sines' fit left `rms` and moved the constants by `moved`
/// (relative), with `best_rms` the lowest residual of the passes before it (none for the second
/// pass, which is kept whatever its residual, a non-finite one included, until a later pass
/// does better).
fn decide(best_rms: Option<f64>, rms: f64, moved: f64) -> Decision {
    let Some(best_rms) = best_rms else {
        return Decision {
            keep: true,
            settled: moved <= PASSES_SETTLED,
            stop: moved <= PASSES_SETTLED,
        };
    };
    let diverging = rms > PASSES_DIVERGING * best_rms;
    let settled = !diverging && moved <= PASSES_SETTLED;
    let keep = rms < best_rms || (settled && rms <= (1.0 + PASSES_SETTLED) * best_rms);
    Decision {
        keep,
        settled: keep && settled,
        stop: diverging || settled,
    }
}

/// The alternation from the dynamic fit `first` (made on masses corrected with the base file's
/// lags; see the module docs).
pub fn alternate(
    stage: &DynamicStage<'_>,
    base: Base<'_>,
    options: &MassOptions,
    first: DynamicFit,
) -> Result<ChosenPass, IdentifyError> {
    let dataset = stage.dataset.quasi_static_input();
    let based = constants_of(base.params);
    let mut passes = vec![PassRecord {
        pass: 1,
        lags: based,
        base_value_kept_for: Vec::new(),
        current_shift_samples: 0.0,
        fitted: fit_constants(&first),
        rms_nrmse: rms_nrmse(&first),
        moved_from_pass_before: None,
    }];
    let mut previous = first;
    let mut chosen: Option<(usize, MassIdentification, DynamicFit)> = None;
    let mut kept_settled = false;
    for pass in 2..=MAX_PASSES {
        let sines = fit_constants(&previous);
        let (lags, kept) = lags_for(sines, based);
        // The channel skew and the current between samples the sines' fit estimated: the
        // masses must see the timing the model they go into sees.
        let shift = current_shift_samples(&previous);
        let again = MassOptions {
            lag_correction: Some(lags),
            current_shift_samples: shift,
            ..options.clone()
        };
        let masses = identify_masses(&dataset, base.params, base.name, &again)
            .map_err(|e| IdentifyError::step(&format!("Preisach masses, pass {pass}"), e))?;
        // After the second pass the dynamic fit also starts from the pass before. Its search
        // stays where the first pass's was, around the base file's constants (the masses' file
        // keeps them until `record` writes the fit's): re-centred on each pass, the search
        // walks on with an effect the model lacks, into constants a diagnosis cannot take the
        // effect back out of.
        let fit = stage.fit(&masses.params, (pass > 2).then_some(sines))?;
        let fitted = fit_constants(&fit);
        let moved = (0..3)
            .map(|k| (fitted[k] / sines[k] - 1.0).abs())
            .fold(0.0, f64::max);
        passes.push(PassRecord {
            pass,
            lags,
            base_value_kept_for: kept,
            current_shift_samples: shift,
            fitted,
            rms_nrmse: rms_nrmse(&fit),
            moved_from_pass_before: Some(moved),
        });
        let best_rms = chosen.as_ref().map(|(_, _, best)| rms_nrmse(best));
        let decision = decide(best_rms, rms_nrmse(&fit), moved);
        if decision.keep {
            chosen = Some((pass, masses, fit.clone()));
            kept_settled = decision.settled;
        }
        if decision.stop {
            break;
        }
        previous = fit;
    }
    let (pass, masses, fit) = chosen
        .ok_or_else(|| IdentifyError::Step("the alternation ran no pass after the first".into()))?;
    Ok(ChosenPass {
        masses,
        fit,
        pass,
        settled: kept_settled,
        passes,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_settled_pass_is_kept_unless_an_earlier_one_fit_clearly_better() {
        // Settled within the tolerance of the best residual: the fixed point is kept.
        let d = decide(Some(0.01373), 0.01377, 0.0050);
        assert_eq!(
            d,
            Decision {
                keep: true,
                settled: true,
                stop: true
            }
        );
        // Settled, but an earlier pass fit 1 % better: that one stays.
        let d = decide(Some(0.0100), 0.0101, 0.001);
        assert_eq!(
            d,
            Decision {
                keep: false,
                settled: false,
                stop: true
            }
        );
        // Not settled, better: kept, the alternation goes on.
        let d = decide(Some(0.0200), 0.0150, 0.10);
        assert_eq!(
            d,
            Decision {
                keep: true,
                settled: false,
                stop: false
            }
        );
        // Diverging: not kept, and the alternation stops even though it moved little.
        let d = decide(Some(0.0200), 0.0260, 0.001);
        assert_eq!(
            d,
            Decision {
                keep: false,
                settled: false,
                stop: true
            }
        );
        // The second pass is kept whatever its residual.
        assert!(decide(None, f64::NAN, 0.2).keep);
        assert!(decide(None, 0.03, 0.001).settled);
    }
}
