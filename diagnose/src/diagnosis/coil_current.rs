//! The coil-current channel in the diagnosis: the amplifier judged on the commanded against the
//! measured current (`maglab_model::coil_current`), the rod on the measured current against the
//! displacement ([`super::diagnose`]), and the two put together here.

pub use maglab_model::coil_current::{judge, with_measured_current, AmplifierJudgement};

use super::grade::Grade;
use super::Diagnosis;
use maglab_model::effects::EffectName;

/// Puts the amplifier's judgement `judgement` and the diagnosis `d` of the displacement on the
/// measured current together: the amplifier joins whatever the rest names (alone after `none`,
/// as a second effect beside a named one, beside an `unexplained` rest), and the reason says
/// what the current showed either way.
pub fn combine(judgement: AmplifierJudgement, d: &mut Diagnosis) {
    let amplifier = EffectName::AmplifierBandwidth.name().to_string();
    if judgement.amplifier_named {
        match d.verdict.as_str() {
            "none" => {
                d.verdict_reason = format!(
                    "{}; with the measured current as the model's input the rod's model fits \
                     within the noise ({})",
                    judgement.reason, d.verdict_reason
                );
                d.verdict = amplifier;
                d.grade = Grade::Effect;
            }
            _ => {
                d.verdict_reason = format!(
                    "{}; on the measured current: {}",
                    judgement.reason, d.verdict_reason
                );
                d.additional_effects.push(amplifier);
                if d.verdict != "unexplained" && d.additional_effects.len() == 1 {
                    d.grade = Grade::Pair;
                    d.either.clear();
                }
            }
        }
    } else {
        d.verdict_reason = format!("{}; {}", d.verdict_reason, judgement.reason);
    }
    d.coil_current = Some(judgement);
}
