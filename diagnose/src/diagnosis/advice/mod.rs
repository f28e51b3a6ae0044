//! What to record next: for the candidates a diagnosis leaves side by side, the recording whose
//! physics separates them, and the `maglab excite` command that writes its current.
//!
//! A displacement record constrains an effect only where the effect is large against the others.
//! Each library effect acts at one place of the chain `command → amplifier → coil current → H, M
//! (eq. 4) → strain (eq. 5) → rod and load → sensor`, and each has a regime in which it is the
//! only one left:
//!
//! | recording | what it isolates, and why |
//! |---|---|
//! | the coil current (the amplifier's current monitor) | the amplifier's lag is the only candidate that changes the current itself; every other acts after it, so a measured current equal to the command rules it out, and one that is not measures it (a current loop yielding to the back-EMF included: [`super::grade`]) |
//! | a thermal soak (a sine, a hold at high current, the same sine again) | the thermal drift is the only candidate with a memory of the dissipated `I²` over seconds: the two sines differ by it alone |
//! | quasi-static loops at the dynamic records' amplitudes | eddy currents (4), the rod's, the load's and the sensor's dynamics vanish at 1 Hz; a reversible part does not (it is a static term of `M`) |
//! | the same sines at a second bias | the eddy lag goes with `1 + dM/dH` along the loop (4) and the ΔE effect with `M`: both change with the bias; a sensor's lag, a load's mode and the library's amplifier do not |
//! | sines through and above the resonance (0.5 f0 to 2.5 times the highest f0 the refit's range allows — an f0 identified from data with a lag in them reads low —, as far as the sampling resolves), at two biases | a load adds a mode of its own (a second peak or anti-resonance), the ΔE effect moves the one resonance with the bias, a sensor adds phase without a peak, distributed eddy paths bend the response smoothly above their corners |
//!
//! For a pair `(X, Y)` the first rule that applies gives the recording: the amplifier in it → the
//! coil current; thermal drift → the soak; a reversible part against eddy currents, the sensor or
//! a load → quasi-static loops; eddy currents or the ΔE effect against the sensor → a second bias;
//! the rest (eddy currents, the sensor, a load, the ΔE effect among themselves, and the ΔE effect
//! against a reversible part) → sines through the resonance at two biases. A single candidate (the
//! best of a `none`, the part of a `partly explained`) gets the recording in which it is largest:
//! its row above, eddy currents and the sensor and a load the sines through the resonance.
//!
//! Which candidates: the `either` pair; a named effect against the one that enters the same
//! term of the model ([`super::grade::SAME_TERM`]: only the coil current separates them, whatever
//! the fits say); the verdict's effects against the best two other single
//! candidates (the runners-up of the ranking, also when the verdict is clear: a confident
//! verdict can be wrong, and the runners-up are what it was chosen over) and every other
//! candidate the report lists as equally good (`ambiguous_with`, `also_significant`,
//! `equal_on_training`); for `none`, each of the two best candidates against nothing; for
//! `unexplained`, the best against the next and against nothing. When no candidate explains
//! all of the gap (`unexplained`, `partly explained`) the coil current comes last: it splits the
//! chain at the coil, so whatever the rest is, it says whether it arises before the coil (the
//! amplifier) or after it (the rod, a load, the sensor). At most [`MAX_ADVICE`] recordings,
//! distinct, in that order.

mod design;

#[doc(hidden)]
pub use design::Design;
use design::{push_distinct, round3};

use super::coverage::UnmeasuredLoop;
use super::grade::{Grade, SAME_TERM};
use maglab_model::effects::EffectName;
use maglab_model::experiments::ExperimentInfo;
use serde::Serialize;

/// Most recordings one report advises.
pub const MAX_ADVICE: usize = 3;

/// A recording that separates candidates (module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Recording {
    /// The measured coil current beside the displacement.
    CoilCurrent,
    /// A sine, a hold at high current, the same sine again.
    ThermalSoak,
    /// 1 Hz loops at the dynamic records' amplitudes and bias.
    QuasiStaticLoops,
    /// The dynamic records' sines at a second bias.
    SecondBias,
    /// Sines from half the resonance to three times it, at two biases.
    ThroughResonance,
    /// 1 Hz loops on the dynamic loops the parameter file's masses were not measured on, to
    /// identify the file again ([`super::coverage`]).
    MeasuredLoops,
}

impl Recording {
    /// What to record, in words.
    pub fn description(self) -> &'static str {
        match self {
            Recording::CoilCurrent => {
                "the coil current: the amplifier's current-monitor output, sampled on the \
                 displacement's trigger"
            }
            Recording::ThermalSoak => {
                "a thermal soak: a sine, a hold at high current for minutes, the same sine again"
            }
            Recording::QuasiStaticLoops => {
                "quasi-static loops (1 Hz) at the amplitudes and bias of the dynamic records"
            }
            Recording::SecondBias => "the same sines at a second bias current",
            Recording::ThroughResonance => {
                "sines through and above the rod's resonance (from 0.5 f0 to 2.5 times the \
                 highest f0 the refit allows), at two biases"
            }
            Recording::MeasuredLoops => {
                "quasi-static loops (1 Hz) between the currents of the dynamic loops the \
                 parameter file's masses were not measured on, then `maglab identify` on the \
                 dataset with them"
            }
        }
    }
}

/// One piece of advice.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Advice {
    /// The candidates it separates (effect names; `none` for "the effect or nothing").
    pub candidates: Vec<String>,
    /// The recording.
    pub recording: Recording,
    /// What to record, in words.
    pub what: String,
    /// Why it separates them (the physics, module docs).
    pub why: String,
    /// How to produce it: a `maglab excite` command with this dataset's numbers, or, for the
    /// coil current, what to connect.
    pub how: String,
    /// This dataset already holds such records (they did not separate the candidates at this
    /// noise: longer or repeated records lower it).
    pub in_dataset: bool,
}

impl Advice {
    /// What the recording is for, in words: `to separate X from Y`, or, for
    /// [`Recording::MeasuredLoops`], to measure the file's masses where the data run.
    pub fn purpose(&self) -> String {
        match self.recording {
            Recording::MeasuredLoops => format!(
                "to measure the parameter file's masses on the loops it was not identified on \
                 (the first: {})",
                self.candidates[1]
            ),
            _ => format!(
                "to separate {} from {}",
                self.candidates[0], self.candidates[1]
            ),
        }
    }
}

/// What the advice needs to know of the dataset and the rig.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rig {
    /// The rod's resonance, Hz (the refitted or the parameter file's f0).
    pub resonance_hz: f64,
    /// How far the true resonance may lie from `resonance_hz`, a factor (the refit's range of
    /// `f0`, [`super::constants_range`]): an `f0` identified from data that hold a lag is read
    /// low (a sensor's or a load's phase taken for the resonance's), so the sweep through the
    /// resonance must reach past the whole range, not past the identified value.
    pub resonance_factor: f64,
    /// The coil current limit, A.
    pub current_limit_a: f64,
    /// The dataset's sampling rate, Hz (the advised records' too).
    pub sample_rate_hz: f64,
    /// The dataset records the coil current: it needs no advice to, and the amplifier was
    /// judged on it.
    pub coil_current_measured: bool,
}

/// The recording that separates `a` from `b` (`None`: from nothing, i.e. makes `a` largest) and
/// why (module docs).
pub fn separating(a: EffectName, b: Option<EffectName>) -> (Recording, &'static str) {
    use EffectName as E;
    let has = |e: E| a == e || b == Some(e);
    let other = |e: E| if a == e { b } else { Some(a) };
    // A pair whose effects enter the same term of the model: the grade's derivation says why.
    let is_pair = |x: &str, y: &str| {
        b.is_some_and(|b| [a.name(), b.name()] == [x, y] || [b.name(), a.name()] == [x, y])
    };
    if let Some((_, _, reason)) = SAME_TERM.iter().find(|(x, y, _)| is_pair(x, y)) {
        return (Recording::CoilCurrent, reason);
    }
    if has(E::AmplifierBandwidth) {
        return (
            Recording::CoilCurrent,
            "the amplifier's lag is the only candidate that changes the coil current itself; \
             every other acts after it, so the measured current equals the command unless the \
             amplifier lags",
        );
    }
    if has(E::ThermalDrift) {
        return (
            Recording::ThermalSoak,
            "the thermal drift is the only candidate with a memory of the dissipated I² over \
             seconds: the sine before and after the soak differs by it alone",
        );
    }
    if has(E::ReversibleMagnetization) && other(E::ReversibleMagnetization) != Some(E::DeltaEEffect)
    {
        return (
            Recording::QuasiStaticLoops,
            "eddy currents (eq. 4), the rod's, the load's and the sensor's dynamics vanish at \
             1 Hz; a reversible part of M does not",
        );
    }
    let bias_dependent = |e: E| matches!(e, E::EddyFrequencyDependence | E::DeltaEEffect);
    if let Some(b) = b {
        if (bias_dependent(a) && b == E::SensorDynamics)
            || (bias_dependent(b) && a == E::SensorDynamics)
        {
            return (
                Recording::SecondBias,
                "the eddy lag goes with 1 + dM/dH along the loop (eq. 4) and the ΔE effect with \
                 M: both change with the bias, the sensor's lag does not",
            );
        }
    } else if a == E::DeltaEEffect {
        return (
            Recording::SecondBias,
            "the ΔE effect changes the rod's stiffness with M: the same sines at another bias \
             change resonance and stroke by it",
        );
    }
    (
        Recording::ThroughResonance,
        "a load adds a mode of its own, the ΔE effect moves the one resonance with the bias, a \
         sensor adds phase without a peak, distributed eddy paths bend the response smoothly \
         above their corners: these shapes differ most through and above the resonance",
    )
}

/// The effect of a name (`None` for `none`, `unexplained`, `nominal` or an unknown name).
fn effect_named(name: &str) -> Option<EffectName> {
    EffectName::LIBRARY.into_iter().find(|e| e.name() == name)
}

/// The candidate pairs to advise on, most important first: `(named, other)` with `other`
/// `None` for "the effect or nothing" (module docs). `named`: the verdict's effects (and the
/// part of a `partly explained`); `runners_up`: the best single candidates the verdict does not
/// name, best first; `grade`: the verdict's.
pub fn candidate_pairs(
    named: &[String],
    either: &[String],
    runners_up: &[&str],
    also_listed: &[String],
    grade: Grade,
) -> Vec<(EffectName, Option<EffectName>)> {
    let named: Vec<EffectName> = named.iter().filter_map(|n| effect_named(n)).collect();
    let mut pairs = Vec::new();
    if let [x, y] = either {
        if let (Some(x), Some(y)) = (effect_named(x), effect_named(y)) {
            pairs.push((x, Some(y)));
        }
    }
    // A named effect whose term another enters as well: only one recording separates them.
    for &n in &named {
        for (a, b, _) in SAME_TERM {
            if n.name() == a {
                pairs.extend(effect_named(b).map(|b| (n, Some(b))));
            }
        }
    }
    let others: Vec<EffectName> = runners_up
        .iter()
        .copied()
        .chain(also_listed.iter().map(String::as_str))
        .filter_map(effect_named)
        .filter(|e| !named.contains(e))
        .collect();
    match (named.first(), others.as_slice()) {
        (Some(&first), _) => pairs.extend(others.iter().map(|&o| (first, Some(o)))),
        // `none`: each leading candidate against nothing (what would make it visible).
        (None, _) if grade == Grade::None => pairs.extend(others.iter().map(|&o| (o, None))),
        // `unexplained`: the best candidate against the next, then against nothing.
        (None, [best, next, ..]) => pairs.extend([(*best, Some(*next)), (*best, None)]),
        (None, [best]) => pairs.push((*best, None)),
        (None, []) => {}
    }
    // No candidate explains all of the gap: the coil current splits the chain at the coil and
    // says on which side the rest arises (module docs).
    if matches!(grade, Grade::Unexplained | Grade::PartlyExplained) {
        let best = named.first().or(others.first()).copied();
        match best {
            Some(b) if b != EffectName::AmplifierBandwidth => {
                pairs.push((b, Some(EffectName::AmplifierBandwidth)))
            }
            _ => {}
        }
    }
    if pairs.is_empty() {
        if let Some(&first) = named.first() {
            pairs.push((first, None));
        }
    }
    pairs
}

/// The advice for `pairs` (at most [`MAX_ADVICE`], one per recording) on a dataset whose
/// experiments are `infos`.
pub fn advise(
    pairs: &[(EffectName, Option<EffectName>)],
    infos: &[ExperimentInfo],
    rig: Rig,
) -> Vec<Advice> {
    let design = Design::of(infos, rig);
    let mut out: Vec<Advice> = Vec::new();
    // With the coil current recorded the amplifier was judged on it: nothing to separate.
    let judged = |e: EffectName| rig.coil_current_measured && e == EffectName::AmplifierBandwidth;
    for &(a, b) in pairs {
        if judged(a) || b.is_some_and(judged) {
            continue;
        }
        let (recording, why) = separating(a, b);
        if out.iter().any(|x| x.recording == recording) {
            continue;
        }
        out.push(Advice {
            candidates: vec![
                a.name().to_string(),
                b.map_or("none".to_string(), |b| b.name().to_string()),
            ],
            recording,
            what: recording.description().to_string(),
            why: why.to_string(),
            how: design.command(recording),
            in_dataset: design.holds(recording),
        });
        if out.len() == MAX_ADVICE {
            break;
        }
    }
    out
}

/// The advice for the dynamic loops the parameter file's masses were not measured on (`None`
/// when there are none): 1 Hz sines between the same currents, to identify the file again.
/// It comes before any about effects: an effect is judged against a model that must hold where
/// the data run.
pub fn measure_loops(loops: &[UnmeasuredLoop], rig: Rig) -> Option<Advice> {
    let first = loops.first()?;
    let (mut biases_a, mut amplitudes_a) = (Vec::new(), Vec::new());
    for l in loops {
        let (bias_a, amplitude_a) = l.bias_and_amplitude_a();
        push_distinct(&mut biases_a, round3(bias_a), 0.02);
        push_distinct(&mut amplitudes_a, round3(amplitude_a), 0.02);
    }
    let list = |v: &[f64]| {
        v.iter()
            .map(|x| format!("{x}"))
            .collect::<Vec<_>>()
            .join(",")
    };
    Some(Advice {
        candidates: vec!["parameter file's masses".into(), first.file.clone()],
        recording: Recording::MeasuredLoops,
        what: Recording::MeasuredLoops.description().to_string(),
        why: "a minor loop's stroke is the sum of the masses of the cells it switches (eq. 2); \
              a quasi-static loop reversing at the same currents measures that sum, which the \
              identification's records did not"
            .to_string(),
        how: format!(
            "maglab excite --design sines --freq-hz 1 --amplitude-a {} --bias-a {} \
             --duration-s 3 --sample-rate-hz {} -o measured_loops",
            list(&amplitudes_a),
            list(&biases_a),
            rig.sample_rate_hz.round()
        ),
        in_dataset: false,
    })
}
