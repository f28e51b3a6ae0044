//! Blind test cases for the diagnosis: datasets from the bench plant with effects drawn at
//! random (shape parameters, nuisances, start state) and magnitudes calibrated to a target gap.
//!
//! **Gap.** An effect's gap is the RMS difference between the plant's noise-free reading with and
//! without the effect (same nuisances, same start), over the scored part (after the first 10 %)
//! of the highest-frequency experiments and, separately, of the lowest-frequency ones, as a
//! fraction of their peak-to-peak displacement, the larger of the two (fast effects show at the
//! top, slow and static ones at the bottom as well). The difference has its mean removed (a
//! constant is a sensor offset, a nuisance) and the effect's reading is shifted by the one time
//! shift within ±1.5 samples that fits both ends best together (a channel skew and a
//! held-vs-linear current are nuisances a diagnosis estimates; a pure delay of that size cannot
//! be told from them).
//! [`calibrate`] finds the effect's magnitude parameter
//! ([`crate::effects::EffectSpec::magnitude`]) that gives a target gap by bisection on a log
//! scale (the gap grows with the magnitude).
//!
//! **A case** ([`draw`]): a sine sweep (6 frequencies from 20 to 400 Hz, ±5 % jitter, two
//! amplitudes, one bias, 0.5 s each at 10 kHz); the current held or linear between samples, a
//! channel skew within ±0.8 samples, a sensor offset, white noise 0.05-0.3 µm, 2 nm quantization;
//! one start state for every experiment, documented in `dataset.json` or not (half the cases);
//! then the effects: one library effect (target gap 5-30 %), a pair of library effects (5-20 %
//! each), one out-of-library effect (5-30 %), or none. Everything is drawn from the case's seed.
//!
//! **Design.** That sweep is [`Design::Standard`], the one every rule of the diagnosis was
//! chosen on. [`Design::Varied`] draws the experiment design as well, from a stream of its own
//! (the same seed gives the same effects, nuisances and start state in either design): 5 to 8
//! frequencies log-spaced from 10-30 Hz up to 250-600 Hz (through the rod's resonance), 2 or 3
//! amplitudes, a bias of 0.3-0.8 A or (a quarter of the cases) none, the current then
//! reversing with 0.4-1.6 A amplitudes, 5, 10 or 20 kHz, 0.3-1 s per experiment (at least five
//! periods of the lowest frequency, and at most 2e5 samples in all where those allow it): a
//! bench's own choice, which a diagnosis must not depend on.

use crate::bench::{record, record_all_on, sine_experiment, BenchSettings, Experiment, Recording};
use crate::effects::{Effect, EFFECTS};
use crate::rods::Rod;
use actuator_params::ActuatorParams;
use maglab_dataset::{CurrentBetweenSamples, StartState};
use rand::{Rng, RngExt, SeedableRng};

/// The experiment design of a case (module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Design {
    /// 6 frequencies 20-400 Hz (±5 %) × 2 amplitudes, 0.5 s each at 10 kHz.
    Standard,
    /// Frequencies, amplitudes, bias, rate and duration drawn from the case's seed.
    Varied,
}

impl Design {
    /// Parses `standard` or `varied`.
    pub fn parse(s: &str) -> Result<Design, String> {
        match s {
            "standard" => Ok(Design::Standard),
            "varied" => Ok(Design::Varied),
            other => Err(format!("design `{other}`: expected `standard` or `varied`")),
        }
    }

    /// The design named by the environment variable `name` (the test harnesses'
    /// `BLIND_DESIGN`, `IDENTIFIED_DESIGN`); [`Design::Standard`] when it is unset.
    pub fn from_env(name: &str) -> Result<Design, String> {
        std::env::var(name).map_or(Ok(Design::Standard), |s| {
            Design::parse(&s).map_err(|e| format!("{name}: {e}"))
        })
    }
}

/// Which physical forms of its effects a case draws ([`crate::effects::EffectSpec::forms`]),
/// from a stream of its own (the same seed gives the same kind, nuisances, start and shape draws
/// in every form set).
///
/// The diagnosis's rules are chosen on [`Forms::Tuning`] (every form of an effect but its last)
/// and scored on [`Forms::HeldOut`] (the last form, which no rule was chosen on);
/// [`Forms::Original`] is form 0 only, the plant the first rules were chosen on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Forms {
    /// Form 0 of every effect.
    Original,
    /// Every form but the last, drawn per effect.
    Tuning,
    /// The last form of every effect.
    HeldOut,
    /// Any form, drawn per effect.
    All,
}

impl Forms {
    /// Parses `original`, `tuning`, `held-out` or `all`.
    pub fn parse(s: &str) -> Result<Forms, String> {
        match s {
            "original" => Ok(Forms::Original),
            "tuning" => Ok(Forms::Tuning),
            "held-out" => Ok(Forms::HeldOut),
            "all" => Ok(Forms::All),
            other => Err(format!(
                "form set `{other}`: expected `original`, `tuning`, `held-out` or `all`"
            )),
        }
    }

    /// The form set named by the environment variable `name` (e.g. `BLIND_FORMS`);
    /// [`Forms::Original`] when it is unset.
    pub fn from_env(name: &str) -> Result<Forms, String> {
        std::env::var(name).map_or(Ok(Forms::Original), |s| {
            Forms::parse(&s).map_err(|e| format!("{name}: {e}"))
        })
    }

    /// The set's name as [`Forms::parse`] reads it.
    pub fn name(&self) -> &'static str {
        match self {
            Forms::Original => "original",
            Forms::Tuning => "tuning",
            Forms::HeldOut => "held-out",
            Forms::All => "all",
        }
    }

    /// The form of an effect with `n_forms` forms, drawn from `rng` among the set's.
    fn draw(&self, n_forms: usize, rng: &mut impl Rng) -> usize {
        match self {
            Forms::Original => 0,
            Forms::Tuning => rng.random_range(0..n_forms - 1),
            Forms::HeldOut => n_forms - 1,
            Forms::All => rng.random_range(0..n_forms),
        }
    }
}

/// What a case contains.
#[derive(Debug, Clone, PartialEq)]
pub enum Kind {
    /// One library effect.
    Single(&'static str),
    /// Two library effects.
    Pair(&'static str, &'static str),
    /// One effect outside the diagnosis library.
    OutOfLibrary(&'static str),
    /// Noise and nuisances only.
    NoiseOnly,
}

impl Kind {
    /// The verdicts a correct diagnosis gives: the named set (`verdict` plus
    /// `additional_effects`), `["unexplained"]` or `["none"]`.
    pub fn expected(&self) -> Vec<&'static str> {
        match self {
            Kind::Single(e) => vec![e],
            Kind::Pair(a, b) => {
                let mut v = vec![*a, *b];
                v.sort();
                v
            }
            Kind::OutOfLibrary(_) => vec!["unexplained"],
            Kind::NoiseOnly => vec!["none"],
        }
    }

    /// Right under the strict scoring: the named set (sorted) is [`Kind::expected`].
    pub fn strictly_right(&self, named: &[String]) -> bool {
        named.iter().map(String::as_str).eq(self.expected())
    }

    /// Right under the graded scoring: the truth is in the verdict and it names at most two
    /// effects. A single effect X: X named alone or beside one other (a pair, or X with the rest
    /// `unexplained`), "partly explained by X" (or "by X or Y", or "by Y or X"), or "X or Y"; a
    /// pair: both named; an out-of-library effect: `unexplained` (in either of its grades: no
    /// library effect named as the explanation); noise only: `none`.
    pub fn graded_right(&self, said: &Said) -> bool {
        match self {
            Kind::Single(e) => {
                (said.named.len() <= 2 && said.named.iter().any(|n| n == e))
                    || said.partly_explained == Some(*e)
                    || said.either.iter().any(|n| n == e)
            }
            Kind::Pair(..) => self.strictly_right(said.named),
            Kind::OutOfLibrary(_) => said.verdict == "unexplained",
            Kind::NoiseOnly => said.verdict == "none" && said.grade == "none",
        }
    }

    /// A short label for tables: the effect, `a+b`, `(backlash)`, `noise`.
    pub fn label(&self) -> String {
        match self {
            Kind::Single(e) => e.to_string(),
            Kind::Pair(a, b) => format!("{a}+{b}"),
            Kind::OutOfLibrary(e) => format!("({e})"),
            Kind::NoiseOnly => "noise only".into(),
        }
    }
}

/// What a diagnosis said, as its report (`diagnosis.json`) writes it: what the scorings read.
#[derive(Debug, Clone, Copy)]
pub struct Said<'a> {
    /// The verdict.
    pub verdict: &'a str,
    /// The verdict and the additional effects, sorted.
    pub named: &'a [String],
    /// The grade's name (`none`, `effect`, `pair`, `either`, `partly_explained`, `unexplained`).
    pub grade: &'a str,
    /// The effect of a `partly_explained` grade.
    pub partly_explained: Option<&'a str>,
    /// The two effects of an `either` grade, or of a `partly_explained` one by "X or Y" (empty
    /// otherwise).
    pub either: &'a [String],
}

impl Said<'_> {
    /// The verdict as graded: `partly X`, `partly X or Y`, `X or Y`, else the named set joined
    /// by `+`.
    pub fn label(&self) -> String {
        match (self.partly_explained, self.either) {
            (Some(_), [a, b]) => format!("partly {a} or {b}"),
            (Some(p), _) => format!("partly {p}"),
            (None, [a, b]) => format!("{a} or {b}"),
            _ => self.named.join("+"),
        }
    }
}

/// A drawn case.
#[derive(Debug, Clone)]
pub struct Case {
    /// Seed it was drawn from.
    pub seed: u64,
    /// What it contains.
    pub kind: Kind,
    /// The effects, calibrated.
    pub effects: Vec<Effect>,
    /// Target gap of each effect.
    pub target_gaps: Vec<f64>,
    /// Gap each effect reaches after calibration.
    pub gaps: Vec<f64>,
    /// Recording settings (nuisances).
    pub settings: BenchSettings,
    /// Start state of every experiment.
    pub start: StartState,
    /// Whether `dataset.json` documents the start state.
    pub documented: bool,
    /// The experiments.
    pub experiments: Vec<Experiment>,
    /// The experiment design and, for [`Design::Varied`], its sweep in words.
    pub design: Design,
    /// The sweep in words (empty for [`Design::Standard`]).
    pub sweep: String,
    /// The rod's own Preisach measure (`crate::rods`), when the case is drawn on one instead of
    /// the parameter file's grid and masses ([`draw_on`]).
    pub rod: Option<Rod>,
    /// The form set its effects' forms were drawn from.
    pub forms: Forms,
}

/// Seeds the forms' stream (`seed ^ FORM_STREAM`), apart from the case's own.
const FORM_STREAM: u64 = 0x0f0e_5eed_f04d_0001;

/// An effect has reached its target gap when its calibrated gap is at least this share of the
/// target ([`calibrate`]'s bisection stops within 8 % on a log scale, `e^−0.08 ≈ 0.92` of it). An
/// effect whose every drawn shape falls short (the gap stops growing, or the magnitude meets the
/// end of its plausible range, before the target) keeps the shape that came closest.
pub const REACHED_SHARE: f64 = 0.9;

impl Case {
    /// Whether effect `i` reached its target gap ([`REACHED_SHARE`]); `false` for an effect it
    /// does not have.
    pub fn reached(&self, i: usize) -> bool {
        match (self.gaps.get(i), self.target_gaps.get(i)) {
            (Some(g), Some(t)) => *g >= REACHED_SHARE * t,
            _ => false,
        }
    }

    /// One line describing the case.
    pub fn describe(&self) -> String {
        let fx: Vec<String> = self
            .effects
            .iter()
            .zip(&self.gaps)
            .map(|(e, g)| format!("{e} gap {:.1} %", 100.0 * g))
            .collect();
        format!(
            "seed {} {}: {}; current {}, skew {:+.2}, offset {:.2} um, noise {:.3} um, start {}{}",
            self.seed,
            self.kind.label(),
            if fx.is_empty() {
                "no effect".into()
            } else {
                fx.join("; ")
            },
            match self.settings.current_between_samples {
                CurrentBetweenSamples::Hold => "hold",
                CurrentBetweenSamples::Linear => "linear",
            },
            self.settings.channel_skew_samples,
            self.settings.sensor_offset_m * 1e6,
            self.settings.noise_m * 1e6,
            self.start.name(),
            if self.documented { " (documented)" } else { "" }
        ) + &self
            .rod
            .as_ref()
            .map_or(String::new(), |r| format!("; rod {}", r.label()))
            + &if self.sweep.is_empty() {
                String::new()
            } else {
                format!("; {}", self.sweep)
            }
    }

    /// Records the case's dataset (on its rod when it has one).
    pub fn record(&self, params: &ActuatorParams) -> Result<Vec<Recording>, String> {
        let plant = plant_for(
            params,
            self.rod.as_ref(),
            &self.effects,
            self.settings.rate_hz,
        )?;
        record_all_on(plant, &self.experiments, &self.settings)
    }
}

/// The bench plant of `params` with `effects`, on `rod`'s own Preisach measure when given.
fn plant_for(
    params: &ActuatorParams,
    rod: Option<&Rod>,
    effects: &[Effect],
    rate_hz: f64,
) -> Result<crate::Plant, String> {
    match rod {
        Some(r) => crate::Plant::with_rod(params, r, effects, rate_hz),
        None => crate::Plant::new(params, effects, rate_hz),
    }
}

fn log_uniform(rng: &mut impl Rng, lo: f64, hi: f64) -> f64 {
    (rng.random_range(lo.ln()..hi.ln())).exp()
}

/// Draws the shape parameters of `name` (not its magnitude) in `form`: those every form reads
/// from `rng`, those of one form only from `form_rng` (so that form 0's cases stay what they
/// were before the other forms existed). `peak_current_a` is the largest command of the
/// experiments (a voltage-limited amplifier's compliance lies a few % above it, so that it is
/// reached once the coil warms); `eddy_rate_per_s` is the rod's `c1/c0` (a PI loop's coil sees
/// the rod's eddy resistance reflected as `κ = τ_L c1/c0` times its own, so its voltage limit is
/// sized on `(1 + κ)` times the peak current: it binds in fast transients, not at every peak).
fn shaped(
    name: &str,
    form: usize,
    (peak_current_a, eddy_rate_per_s): (f64, f64),
    rng: &mut impl Rng,
    form_rng: &mut impl Rng,
) -> Result<Effect, String> {
    let e = Effect::default_for(name)?.with("form", form as f64)?;
    let e = match name {
        "amplifier_bandwidth" => {
            let tau_l_s = log_uniform(form_rng, 1e-4, 1e-3);
            let kappa = tau_l_s * eddy_rate_per_s;
            let e = e.with("coil_time_constant_s", tau_l_s)?.with(
                "voltage_limit_a",
                (peak_current_a * (1.0 + kappa) * form_rng.random_range(1.0..2.0)).clamp(1.0, 1e4),
            )?;
            // A loop tuned on a datasheet's L/R within a factor 2 of the wound coil's, its
            // current sensed through a filter 5 to 20 times above the crossover.
            if form == 3 {
                e.with("zero_to_coil_ratio", log_uniform(form_rng, 0.5, 2.0))?
                    .with("sense_to_crossover", log_uniform(form_rng, 5.0, 20.0))?
            } else {
                e
            }
        }
        "thermal_drift" => e.with(
            "compliance_a",
            (peak_current_a * form_rng.random_range(1.02..1.08)).clamp(0.1, 100.0),
        )?,
        "delta_e_effect" => e.with("field_scale_a_per_m", log_uniform(form_rng, 5e3, 2e4))?,
        "backlash" => e.with("follower_hz", log_uniform(form_rng, 1e3, 5e3))?,
        "stick_slip" => e
            .with("stribeck_speed_m_per_s", log_uniform(form_rng, 3e-4, 3e-3))?
            .with("presliding_m", log_uniform(form_rng, 0.05e-6, 0.5e-6))?,
        _ => e,
    };
    Ok(match name {
        "eddy_frequency_dependence" => e
            .with("first_corner_hz", log_uniform(rng, 80.0, 600.0))?
            .with("paths", rng.random_range(3..=6) as f64)?,
        "amplifier_bandwidth" => e
            .with("damping_ratio", rng.random_range(0.5..1.0))?
            .with("slew_a_per_s", log_uniform(rng, 2e3, 2e4))?,
        "sensor_dynamics" => e
            .with("damping_ratio", rng.random_range(0.5..1.0))?
            .with("delay_s", rng.random_range(0.0..1e-4))?,
        "reversible_magnetization" => {
            e.with("saturation_field_a_per_m", log_uniform(rng, 8e3, 4e4))?
        }
        "thermal_drift" => e
            .with("coil_time_constant_s", log_uniform(rng, 0.3, 2.0))?
            .with("rod_time_constant_s", log_uniform(rng, 0.2, 1.5))?
            .with("magnetostriction_loss_per_k", rng.random_range(5e-3..2e-2))?
            .with("expansion_m_per_k", rng.random_range(0.0..1e-6))?,
        "delta_e_effect" => e.with("stress_stiffening", rng.random_range(0.0..1.0))?,
        "mechanical_load" => e
            .with("mass_ratio", log_uniform(rng, 0.1, 1.0))?
            .with("damping_ratio", rng.random_range(0.05..0.3))?
            .with("second_mass_ratio", rng.random_range(0.2..1.0))?
            .with("second_coupling_hz", log_uniform(rng, 1500.0, 4000.0))?
            .with("second_damping_ratio", rng.random_range(0.03..0.2))?,
        "stick_slip" => e.with("kinetic_ratio", rng.random_range(0.5..0.9))?,
        "creep" => e.with("time_constant_s", log_uniform(rng, 0.002, 0.03))?,
        "sensor_nonlinearity" => {
            let sign = if rng.random_bool(0.5) { 1.0 } else { -1.0 };
            e.with("gain_change", sign * 0.1)?
                .with("null_m", rng.random_range(20e-6..30e-6))?
                .with("range_m", rng.random_range(15e-6..25e-6))?
        }
        _ => e,
    })
}

/// The effect with its magnitude parameter set to `value` (keeping its sign for signed ones).
fn with_magnitude(e: &Effect, value: f64) -> Result<Effect, String> {
    let (key, _) = e.spec.magnitude;
    let sign = if e.magnitude() < 0.0 { -1.0 } else { 1.0 };
    e.clone().with(key, sign * value)
}

/// Noise-free recordings of the lowest- and highest-frequency experiments (run as the dataset
/// runs them: each on its own plant, or the whole chain on one when experiments start where the
/// previous one ended).
pub struct GapRuns {
    runs: Vec<(Recording, bool)>,
}

impl GapRuns {
    /// Runs `experiments` on a plant with `effects` (on `rod` when given), keeping the
    /// extreme-frequency ones.
    pub fn new(
        params: &ActuatorParams,
        rod: Option<&Rod>,
        effects: &[Effect],
        experiments: &[Experiment],
        settings: &BenchSettings,
    ) -> Result<Self, String> {
        let freqs: Vec<f64> = experiments
            .iter()
            .map(|e| frequency_of(&e.description))
            .collect();
        let top = freqs.iter().cloned().fold(0.0, f64::max);
        let bottom = freqs.iter().cloned().fold(f64::MAX, f64::min);
        let keep = |f: f64| f >= 0.999 * top || f <= 1.001 * bottom;
        let quiet = BenchSettings {
            noise_m: 0.0,
            quantization_m: 0.0,
            ..*settings
        };
        let chained = experiments.iter().any(|e| e.start == StartState::Previous);
        let runs = if chained {
            let mut plant = plant_for(params, rod, effects, quiet.rate_hz)?;
            let mut out = Vec::new();
            for (e, &f) in experiments.iter().zip(&freqs) {
                let r = record(&mut plant, e, &quiet, 0)?;
                if keep(f) {
                    out.push((r, f >= 0.999 * top));
                }
            }
            out
        } else {
            experiments
                .iter()
                .zip(&freqs)
                .filter(|(_, &f)| keep(f))
                .map(|(e, &f)| {
                    let mut plant = plant_for(params, rod, effects, quiet.rate_hz)?;
                    Ok((record(&mut plant, e, &quiet, 0)?, f >= 0.999 * top))
                })
                .collect::<Result<Vec<_>, String>>()?
        };
        Ok(GapRuns { runs })
    }
}

/// Catmull-Rom interpolation of uniformly sampled `y` at fractional index `x` (clamped).
fn interpolate(y: &[f64], x: f64) -> f64 {
    let n = y.len();
    if n < 4 {
        return y[x.round().clamp(0.0, (n - 1) as f64) as usize];
    }
    let x = x.clamp(0.0, (n - 1) as f64);
    let i = (x.floor() as usize).min(n - 2);
    let t = x - i as f64;
    let p0 = y[i.saturating_sub(1)];
    let (p1, p2) = (y[i], y[i + 1]);
    let p3 = y[(i + 2).min(n - 1)];
    0.5 * (2.0 * p1
        + (p2 - p0) * t
        + (2.0 * p0 - 5.0 * p1 + 4.0 * p2 - p3) * t * t
        + (3.0 * p1 - p0 - 3.0 * p2 + p3) * t * t * t)
}

/// The gap (module docs) of `with` against `without` (the same experiments).
pub fn gap_between(with: &GapRuns, without: &GapRuns) -> f64 {
    // Mean-removed RMS of the difference over the top (or the other) experiments, with the
    // effect's reading shifted by `shift` samples (interpolated between its samples).
    let rms = |shift: f64, top: bool| -> f64 {
        let (mut sum, mut sum2, mut n) = (0.0, 0.0, 0usize);
        for ((a, is_top), (b, _)) in with.runs.iter().zip(&without.runs) {
            if *is_top != top {
                continue;
            }
            let skip = a.t_s.len() / 10;
            for k in skip..a.t_s.len() {
                let d = interpolate(&a.clean_displacement_m, k as f64 + shift)
                    - b.clean_displacement_m[k];
                sum += d;
                sum2 += d * d;
                n += 1;
            }
        }
        let n = n.max(1) as f64;
        (sum2 / n - (sum / n) * (sum / n)).max(0.0).sqrt()
    };
    // The common shift: the best for the lowest and highest frequencies together.
    let joint = |shift: f64| rms(shift, true).powi(2) + rms(shift, false).powi(2);
    let best = maglab_signal::golden::golden_section_min(
        -NUISANCE_SHIFT_SAMPLES,
        NUISANCE_SHIFT_SAMPLES,
        30,
        joint,
    );
    let shift = if joint(best) < joint(0.0) { best } else { 0.0 };
    let span = |top: bool| {
        let (lo, hi) = without
            .runs
            .iter()
            .filter(|r| r.1 == top)
            .flat_map(|(r, _)| r.clean_displacement_m.iter())
            .fold((f64::MAX, f64::MIN), |(a, b), &v| (a.min(v), b.max(v)));
        (hi - lo).max(1e-300)
    };
    // The larger of the two ends: a fast effect (eddy paths, amplifier, sensor, load) shows at the
    // top frequency, a slow or static one (creep, reversible part, sensor gain) at the bottom too.
    let top = rms(shift, true) / span(true);
    let bottom = if without.runs.iter().any(|r| !r.1) {
        rms(shift, false) / span(false)
    } else {
        0.0
    };
    top.max(bottom)
}

/// The gap (module docs) of `effects`.
pub fn gap(
    params: &ActuatorParams,
    effects: &[Effect],
    experiments: &[Experiment],
    settings: &BenchSettings,
) -> Result<f64, String> {
    let with = GapRuns::new(params, None, effects, experiments, settings)?;
    let without = GapRuns::new(params, None, &[], experiments, settings)?;
    Ok(gap_between(&with, &without))
}

/// The time shift of the reading a diagnosis absorbs as nuisances (a channel skew under one
/// sample, a held or linear current: half a sample), samples.
pub const NUISANCE_SHIFT_SAMPLES: f64 = 1.5;

fn frequency_of(description: &str) -> f64 {
    description
        .strip_prefix("sine ")
        .and_then(|r| r.split_whitespace().next())
        .and_then(|f| f.parse().ok())
        .unwrap_or(0.0)
}

/// Sets `effect`'s magnitude so that its gap alone is `target`: the smallest magnitude that
/// reaches it (from the default, steps of ×3 towards a smaller or larger effect until the target
/// is bracketed, then bisection on a log scale); returns the effect and the gap reached (below
/// the target when the gap stops growing before the target, or at the end of the parameter's
/// range). `without`: the same experiments without any effect ([`GapRuns::new`] with no effects),
/// run once by the caller for every effect and draw of a case.
pub fn calibrate(
    params: &ActuatorParams,
    rod: Option<&Rod>,
    effect: &Effect,
    target: f64,
    experiments: &[Experiment],
    settings: &BenchSettings,
    without: &GapRuns,
) -> Result<(Effect, f64), String> {
    let (key, increasing) = effect.spec.magnitude;
    let (_, _, lo, hi, _) = *effect
        .spec
        .keys
        .iter()
        .find(|k| k.0 == key)
        .ok_or("magnitude key missing")?;
    // The magnitude on a log scale, in the direction that makes the effect larger.
    let limit_big = if increasing {
        hi.abs().max(lo.abs())
    } else {
        lo.abs().max(1e-12)
    };
    let limit_small = if increasing {
        limit_big * 1e-6
    } else {
        hi.abs()
    };
    let gap_at = |m: f64| -> Result<(Effect, f64), String> {
        let e = with_magnitude(effect, m)?;
        let with = GapRuns::new(params, rod, std::slice::from_ref(&e), experiments, settings)?;
        Ok((e, gap_between(&with, without)))
    };
    let toward_big = |m: f64| {
        if increasing {
            (m * 3.0).min(limit_big)
        } else {
            (m / 3.0).max(limit_big)
        }
    };
    let toward_small = |m: f64| {
        if increasing {
            (m / 3.0).max(limit_small)
        } else {
            (m * 3.0).min(limit_small)
        }
    };
    let mut m = effect
        .magnitude()
        .abs()
        .clamp(limit_small.min(limit_big), limit_small.max(limit_big));
    let (mut e, mut g) = gap_at(m)?;
    // Bracket: (small side below the target, big side at or above it).
    let (mut small, mut big);
    if g >= target {
        big = (m, e.clone(), g);
        loop {
            let next = toward_small(m);
            if next == m {
                return Ok((e, g));
            }
            m = next;
            (e, g) = gap_at(m)?;
            if g < target {
                small = m;
                break;
            }
            big = (m, e.clone(), g);
        }
    } else {
        loop {
            let next = toward_big(m);
            if next == m {
                return Ok((e, g));
            }
            small = m;
            m = next;
            let (e2, g2) = gap_at(m)?;
            if g2 >= target {
                big = (m, e2, g2);
                break;
            }
            if g2 < 1.05 * g {
                // The gap no longer grows with the magnitude: the target is out of this
                // effect's reach; keep the smallest magnitude of the plateau.
                return Ok((e, g));
            }
            (e, g) = (e2, g2);
        }
    }
    // Bisection (log scale) between the bracket's ends.
    for _ in 0..8 {
        let mid = (small.ln() * 0.5 + big.0.ln() * 0.5).exp();
        let (e, g) = gap_at(mid)?;
        if (g / target).ln().abs() < 0.08 {
            return Ok((e, g));
        }
        if g >= target {
            big = (mid, e, g);
        } else {
            small = mid;
        }
    }
    Ok((big.1, big.2))
}

/// Draws and calibrates a case of `kind` from `seed`.
pub fn draw(params: &ActuatorParams, seed: u64, kind: Kind) -> Result<Case, String> {
    draw_with(params, seed, kind, Design::Standard)
}

/// The sine sweep of a [`Design::Varied`] case, drawn from its own stream: `(rate_hz, bias_a,
/// amplitudes_a, frequencies_hz, duration_s)`.
fn varied_design(seed: u64) -> (f64, f64, Vec<f64>, Vec<f64>, f64) {
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed ^ 0xde51_9a11_7e5e_ed00);
    let rate_hz = [5_000.0, 10_000.0, 20_000.0][rng.random_range(0..3)];
    let bias_a: f64 = rng.random_range(0.3..0.8);
    let count = rng.random_range(2..=3);
    let a_lo: f64 = rng.random_range(0.1..0.2);
    let a_hi = (a_lo * rng.random_range(1.8f64..2.2)).min(bias_a - 0.05);
    let amplitudes_a: Vec<f64> = (0..count)
        .map(|i| a_lo + (a_hi - a_lo) * i as f64 / (count - 1) as f64)
        .collect();
    let n = rng.random_range(5..=8);
    let (f_lo, f_hi) = (
        log_uniform(&mut rng, 10.0, 30.0),
        log_uniform(&mut rng, 250.0, 600.0),
    );
    let frequencies_hz: Vec<f64> = (0..n)
        .map(|i| {
            let f = f_lo * (f_hi / f_lo).powf(i as f64 / (n - 1) as f64);
            f * rng.random_range(0.95..1.05)
        })
        .collect();
    let drawn_s: f64 = rng.random_range(0.3..1.0);
    let budget_s = 2e5 / (rate_hz * (n * count) as f64);
    let duration_s = drawn_s.min(budget_s).max(5.0 / f_lo);
    // A quarter of the benches drive the coil without a bias (drawn last, so the other draws
    // stay those of a biased bench): the current reverses, the magnetostriction (even in M)
    // doubles the frequency, and the amplitudes span about the same fields, 0.4-1.6 A.
    if rng.random_bool(0.25) {
        let bipolar: Vec<f64> = amplitudes_a.iter().map(|a| (4.0 * a).min(1.6)).collect();
        return (rate_hz, 0.0, bipolar, frequencies_hz, duration_s);
    }
    (rate_hz, bias_a, amplitudes_a, frequencies_hz, duration_s)
}

/// [`draw`] in a given experiment design (module docs).
pub fn draw_with(
    params: &ActuatorParams,
    seed: u64,
    kind: Kind,
    design: Design,
) -> Result<Case, String> {
    draw_on(params, None, seed, kind, design, Forms::Original)
}

/// [`draw_with`] on `rod`'s own Preisach measure (the parameter file's constants, the rod's
/// measure on the plant's grid: `crate::rods`), each effect in a form of `forms`; the effects
/// are calibrated on that plant.
///
/// The case's stream gives, in this order, the bench's nuisances, the start state, the standard
/// sweep and each effect's magnitude and shape; the forms' stream each effect's form and the
/// keys of one form only (`shaped`).
pub fn draw_on(
    params: &ActuatorParams,
    rod: Option<&Rod>,
    seed: u64,
    kind: Kind,
    design: Design,
    forms: Forms,
) -> Result<Case, String> {
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    let mut form_rng = rand::rngs::StdRng::seed_from_u64(seed ^ FORM_STREAM);
    let varied = (design == Design::Varied).then(|| varied_design(seed));
    let settings = bench_settings(&mut rng, seed, varied.as_ref().map_or(10_000.0, |v| v.0));
    let starts = [
        StartState::SwitchOnDemagnetized,
        StartState::Demagnetized,
        StartState::NegativeSaturation,
        StartState::PositiveSaturation,
        StartState::Previous,
    ];
    let start = starts[rng.random_range(0..starts.len())];
    let documented = rng.random_bool(0.5);
    // The varied design replaces the sweep; the standard one is still drawn, so that the
    // effects, nuisances and start state are the standard design's.
    let standard = standard_sweep(&mut rng, start);
    let experiments = match &varied {
        Some(v) => varied_sweep(v, start),
        None => standard,
    };
    let drawn = draw_effects(
        (params, rod),
        &kind,
        forms,
        (&experiments, &settings),
        (&mut rng, &mut form_rng),
    )?;
    Ok(Case {
        seed,
        kind,
        effects: drawn.effects,
        target_gaps: drawn.target_gaps,
        gaps: drawn.gaps,
        settings,
        start,
        documented,
        experiments,
        design,
        sweep: varied.map_or(String::new(), |v| describe_varied(&v)),
        rod: rod.cloned(),
        forms,
    })
}

/// The bench's nuisances (the current between samples, the channel skew, the sensor offset,
/// the noise) drawn from `rng`, at `rate_hz`.
fn bench_settings(rng: &mut impl Rng, seed: u64, rate_hz: f64) -> BenchSettings {
    let current_between_samples = if rng.random_bool(0.5) {
        CurrentBetweenSamples::Hold
    } else {
        CurrentBetweenSamples::Linear
    };
    let channel_skew_samples = rng.random_range(-0.8..0.8);
    let sensor_offset_m = rng.random_range(-2e-6..2e-6);
    let noise_m = log_uniform(rng, 0.05e-6, 0.3e-6);
    BenchSettings {
        rate_hz,
        current_between_samples,
        channel_skew_samples,
        sensor_offset_m,
        noise_m,
        quantization_m: 2e-9,
        seed: seed.wrapping_mul(31).wrapping_add(7),
        coil_current: None,
    }
}

/// The standard design's sweep (module docs): 6 frequencies from 20 to 400 Hz (each ±5 %) × 2
/// amplitudes on one bias, 0.5 s each at 10 kHz, every record from `start`.
fn standard_sweep(rng: &mut impl Rng, start: StartState) -> Vec<Experiment> {
    let bias: f64 = rng.random_range(0.45..0.6);
    let a1: f64 = rng.random_range(0.12..0.2);
    let a2 = (a1 * rng.random_range(1.8f64..2.2)).min(bias - 0.05);
    let mut experiments = Vec::new();
    for f in [20.0, 50.0, 100.0, 200.0, 300.0, 400.0] {
        let f = f * rng.random_range(0.95..1.05);
        for a in [a1, a2] {
            experiments.push(sine_experiment(
                experiments.len(),
                start,
                bias,
                a,
                f,
                0.5,
                1e4,
            ));
        }
    }
    experiments
}

/// A varied design's sweep ([`varied_design`]'s `(rate_hz, bias_a, amplitudes_a,
/// frequencies_hz, duration_s)`), every record from `start`.
fn varied_sweep(
    (rate_hz, bias_a, amplitudes_a, frequencies_hz, duration_s): &(
        f64,
        f64,
        Vec<f64>,
        Vec<f64>,
        f64,
    ),
    start: StartState,
) -> Vec<Experiment> {
    let mut experiments = Vec::new();
    for &f in frequencies_hz {
        for &a in amplitudes_a {
            experiments.push(sine_experiment(
                experiments.len(),
                start,
                *bias_a,
                a,
                f,
                *duration_s,
                *rate_hz,
            ));
        }
    }
    experiments
}

/// A varied design's sweep in one line (the case's `sweep`).
fn describe_varied(
    (rate_hz, bias_a, amps, freqs, duration_s): &(f64, f64, Vec<f64>, Vec<f64>, f64),
) -> String {
    format!(
        "{} frequencies {:.0}-{:.0} Hz x {} amplitudes {:.3}-{:.3} A on {bias_a:.3} A, {:.2} s each at {:.0} kHz",
        freqs.len(),
        freqs[0],
        freqs[freqs.len() - 1],
        amps.len(),
        amps[0],
        amps[amps.len() - 1],
        duration_s,
        rate_hz / 1e3
    )
}

/// A case's effects, each calibrated to the gap drawn for it.
struct DrawnEffects {
    effects: Vec<Effect>,
    /// The gaps drawn, one per effect.
    target_gaps: Vec<f64>,
    /// The gaps reached.
    gaps: Vec<f64>,
}

/// The effects of `kind`, each in a form of `forms`, its shape drawn and its magnitude
/// calibrated on the plant `(params, rod)` to a gap drawn log-uniform in 5–30 % (5–20 % for each
/// of a pair) on the case's `(experiments, settings)`; the case's and the forms' streams in
/// `rngs`.
fn draw_effects(
    (params, rod): (&ActuatorParams, Option<&Rod>),
    kind: &Kind,
    forms: Forms,
    (experiments, settings): (&[Experiment], &BenchSettings),
    (rng, form_rng): (&mut impl Rng, &mut impl Rng),
) -> Result<DrawnEffects, String> {
    let names: Vec<&'static str> = match kind {
        Kind::Single(e) | Kind::OutOfLibrary(e) => vec![e],
        Kind::Pair(a, b) => vec![a, b],
        Kind::NoiseOnly => vec![],
    };
    let (lo, hi) = if matches!(kind, Kind::Pair(..)) {
        (0.05, 0.20)
    } else {
        (0.05, 0.30)
    };
    let mut drawn = DrawnEffects {
        effects: Vec::new(),
        target_gaps: Vec::new(),
        gaps: Vec::new(),
    };
    // The plant without effects, the reference of every calibration below (none: noise only).
    let without = if names.is_empty() {
        GapRuns { runs: Vec::new() }
    } else {
        GapRuns::new(params, rod, &[], experiments, settings)?
    };
    let peak_current_a = experiments
        .iter()
        .flat_map(|e| e.current_a.iter())
        .fold(0.0f64, |m, v| m.max(v.abs()));
    let constants = crate::PlantConstants::from_params(params);
    let eddy_rate_per_s = constants.c1_per_m_s / constants.c0_per_m;
    for name in names {
        let form = forms.draw(Effect::spec(name)?.forms.len(), form_rng);
        let target = log_uniform(rng, lo, hi);
        // An effect whose plausible range cannot reach the target gets a new shape (up to eight
        // draws; then the one that came closest is kept).
        let mut result: Option<(Effect, f64)> = None;
        for _ in 0..8 {
            let e = shaped(name, form, (peak_current_a, eddy_rate_per_s), rng, form_rng)?;
            let (e, g) = calibrate(params, rod, &e, target, experiments, settings, &without)?;
            let reached = g >= REACHED_SHARE * target;
            if result.as_ref().is_none_or(|(_, best)| g > *best) {
                result = Some((e, g));
            }
            if reached {
                break;
            }
        }
        let (e, g) = result.ok_or("no draw")?;
        drawn.effects.push(e);
        drawn.target_gaps.push(target);
        drawn.gaps.push(g);
    }
    Ok(drawn)
}

/// The effects of the plant by library membership.
pub fn names(in_library: bool) -> Vec<&'static str> {
    EFFECTS
        .iter()
        .filter(|s| s.in_library == in_library)
        .map(|s| s.name)
        .collect()
}

/// The kinds of a suite of `count` cases from `seed`: every library effect twice, every
/// out-of-library effect twice, random pairs, and noise-only cases, in an order drawn from the
/// seed (`count` ≥ 24 keeps every kind; fewer is a random subset).
pub fn kinds(seed: u64, count: usize) -> Vec<Kind> {
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed ^ 0x5eed);
    let library = names(true);
    let outside = names(false);
    let mut kinds = Vec::new();
    for _ in 0..2 {
        kinds.extend(library.iter().map(|e| Kind::Single(e)));
        kinds.extend(outside.iter().map(|e| Kind::OutOfLibrary(e)));
    }
    let noise = (count / 8).max(1);
    let pairs = count.saturating_sub(kinds.len() + noise).max(1);
    for _ in 0..pairs {
        let a = rng.random_range(0..library.len());
        let mut b = rng.random_range(0..library.len() - 1);
        if b >= a {
            b += 1;
        }
        kinds.push(Kind::Pair(library[a.min(b)], library[a.max(b)]));
    }
    for _ in 0..noise {
        kinds.push(Kind::NoiseOnly);
    }
    // Fisher-Yates with the seed.
    for i in (1..kinds.len()).rev() {
        let j = rng.random_range(0..=i);
        kinds.swap(i, j);
    }
    // Fewer than 24 cases: a random subset of the kinds.
    kinds.truncate(count.max(1));
    kinds
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The two scorings on each grade a diagnosis gives.
    #[test]
    fn the_graded_scoring_counts_the_truth_in_a_verdict_of_at_most_two_effects() {
        const AMP: &str = "amplifier_bandwidth";
        const SENSOR: &str = "sensor_dynamics";
        const NONE: &str = "none";
        const UNEXPLAINED: &str = "unexplained";
        let list = |joined: &str| -> Vec<String> {
            joined
                .split('+')
                .filter(|n| !n.is_empty())
                .map(String::from)
                .collect()
        };
        // `named` and `either` joined by `+` (sorted as a report's named set is); `partly` empty
        // for none. Checks both scorings of what was said against `kind`.
        let check = |kind: Kind,
                     (verdict, named, grade): (&str, &str, &str),
                     (partly, either): (&str, &str),
                     (strict, graded): (bool, bool)| {
            let (named, either) = (list(named), list(either));
            let said = Said {
                verdict,
                named: &named,
                grade,
                partly_explained: (!partly.is_empty()).then_some(partly),
                either: &either,
            };
            assert_eq!(kind.strictly_right(&named), strict, "{kind:?} {named:?}");
            assert_eq!(
                kind.graded_right(&said),
                graded,
                "{kind:?} {named:?} {grade}"
            );
        };
        let amp = || Kind::Single(AMP);
        let pair = || Kind::Pair(SENSOR, AMP);
        let amp_rest = "amplifier_bandwidth+unexplained";
        let both = "amplifier_bandwidth+sensor_dynamics";
        check(amp(), (AMP, AMP, "effect"), ("", ""), (true, true));
        // The amplifier beside an unexplained rest: named, at most two.
        check(
            amp(),
            (UNEXPLAINED, amp_rest, UNEXPLAINED),
            ("", ""),
            (false, true),
        );
        check(amp(), (SENSOR, SENSOR, "either"), ("", both), (false, true));
        check(
            amp(),
            (UNEXPLAINED, UNEXPLAINED, "partly_explained"),
            (AMP, ""),
            (false, true),
        );
        check(
            amp(),
            (UNEXPLAINED, UNEXPLAINED, "partly_explained"),
            (SENSOR, ""),
            (false, false),
        );
        // Partly explained by "X or Y" (the two enter one term): right when the truth is either.
        let eddy = "eddy_frequency_dependence";
        let eddy_or_amp = "amplifier_bandwidth+eddy_frequency_dependence";
        check(
            amp(),
            (UNEXPLAINED, UNEXPLAINED, "partly_explained"),
            (eddy, eddy_or_amp),
            (false, true),
        );
        check(
            Kind::Single(SENSOR),
            (UNEXPLAINED, UNEXPLAINED, "partly_explained"),
            (eddy, eddy_or_amp),
            (false, false),
        );
        check(amp(), (SENSOR, SENSOR, "effect"), ("", ""), (false, false));
        // A pair needs both, whatever the grade.
        check(pair(), (AMP, both, "pair"), ("", ""), (true, true));
        check(
            pair(),
            (UNEXPLAINED, amp_rest, UNEXPLAINED),
            ("", ""),
            (false, false),
        );
        let backlash = || Kind::OutOfLibrary("backlash");
        let load = "mechanical_load";
        check(
            backlash(),
            (UNEXPLAINED, UNEXPLAINED, "partly_explained"),
            (load, ""),
            (true, true),
        );
        check(backlash(), (load, load, "effect"), ("", ""), (false, false));
        check(Kind::NoiseOnly, (NONE, NONE, NONE), ("", ""), (true, true));
        check(
            Kind::NoiseOnly,
            (UNEXPLAINED, UNEXPLAINED, UNEXPLAINED),
            ("", ""),
            (false, false),
        );
    }

    #[test]
    fn a_varied_design_stays_within_its_documented_bounds() {
        let mut bipolar = 0;
        for seed in 0..500u64 {
            let (rate_hz, bias_a, amps, freqs, duration_s) = varied_design(seed);
            assert!(
                [5e3, 1e4, 2e4].contains(&rate_hz),
                "seed {seed}: {rate_hz} Hz"
            );
            assert!((2..=3).contains(&amps.len()) && (5..=8).contains(&freqs.len()));
            assert!(
                amps.windows(2).all(|w| w[0] < w[1]),
                "seed {seed}: {amps:?}"
            );
            if bias_a == 0.0 {
                bipolar += 1;
                assert!(
                    amps[0] >= 0.4 && amps[amps.len() - 1] <= 1.6,
                    "seed {seed}: {amps:?}"
                );
            } else {
                // On a bias the current never reverses its sign.
                assert!((0.3..0.8).contains(&bias_a), "seed {seed}: bias {bias_a}");
                assert!(amps[0] >= 0.1 && amps[amps.len() - 1] <= bias_a - 0.05 + 1e-12);
            }
            assert!(
                freqs.windows(2).all(|w| w[0] < w[1]),
                "seed {seed}: {freqs:?}"
            );
            assert!(freqs[0] >= 0.95 * 10.0 && freqs[freqs.len() - 1] <= 1.05 * 600.0);
            assert!(freqs[freqs.len() - 1] >= 0.95 * 250.0 && freqs[0] <= 1.05 * 30.0);
            assert!(duration_s >= 5.0 / freqs[0] / 1.05 - 1e-12 && duration_s <= 1.0);
            let samples = duration_s * rate_hz * (amps.len() * freqs.len()) as f64;
            assert!(samples <= 2e5 + 1.0 || duration_s * freqs[0] <= 5.0 * 1.05 + 1e-9);
        }
        assert!(
            (90..160).contains(&bipolar),
            "{bipolar} of 500 without a bias"
        );
    }

    #[test]
    fn the_design_changes_the_sweep_only() {
        let params = actuator_params::paper_defaults();
        for seed in [1u64, 2, 12_021] {
            let standard = draw(&params, seed, Kind::NoiseOnly).unwrap();
            let varied = draw_with(&params, seed, Kind::NoiseOnly, Design::Varied).unwrap();
            assert_eq!(standard.start, varied.start);
            assert_eq!(standard.documented, varied.documented);
            assert_eq!(
                standard.settings.channel_skew_samples,
                varied.settings.channel_skew_samples
            );
            assert_eq!(standard.settings.noise_m, varied.settings.noise_m);
            assert_eq!(standard.experiments.len(), 12);
            assert!(standard.sweep.is_empty() && !varied.sweep.is_empty());
            let (rate_hz, _, amps, freqs, _) = varied_design(seed);
            assert_eq!(varied.settings.rate_hz, rate_hz);
            assert_eq!(varied.experiments.len(), amps.len() * freqs.len());
        }
    }
}
