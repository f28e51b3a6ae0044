//! The candidate effects of the diagnosis and the refitted nominal model: each candidate's free
//! parameters (name, unit, search range, scale, which model stage they act in) and the model
//! parameters a parameter vector stands for.
//!
//! Every candidate — the nominal model included — refits the nominal model's dynamic constants
//! (`R_eddy`, `ξ`, `f0`) and the channel skew together with its own parameters, on the same
//! training experiments, so that a wrong constant in the parameter file is neither taken for an
//! effect nor hides one. The constants move within the uncertainty of an identification
//! ([`REFIT_RANGE`]: `R_eddy` and `ξ` ×/÷ 1.25, `f0` ×/÷ 1.06, several times the 3 % that
//! `maglab identify` reaches): an effect is not a wrong constant, and a constant far from the file's is itself a
//! finding the ranking shows. Each effect's range contains its "off" value (ratio 1, susceptibility 0,
//! …), so a candidate nests the refitted nominal model.
//!
//! | candidate | parameters | form (see [`crate::model`]) |
//! |---|---|---|
//! | `nominal` | — | eqs (4)-(5) |
//! | `eddy_frequency_dependence` | `hf_to_dc_ratio`, `corner_hz`, `anchor` | `R_eddy` going from `R_dc` below the corner to `R_hf = ratio · R_dc` above it (one extra eddy path), the refitted `R` between them: `ln R = ln R_dc + anchor · ln ratio` (a level change is the refit's, not a frequency dependence); its richer form ([`RICHER_FORM`], in a pair of the second stage only) adds a second path, `hf_to_dc_ratio` and `corner_hz` of its own, and the anchor spans the whole step |
//! | `amplifier_bandwidth` | `natural_hz`, `damping_ratio`, `coil_time_constant_s` | a current loop around the coil ([`crate::model::CurrentLoop`]): the command through the closed loop's response `T`, and `1 − T` of the coil's flux EMF `(τ_L/c0) w'` left in the current; at `τ_L = 0` a second-order low-pass on the current |
//! | `sensor_dynamics` | `natural_hz`, `damping_ratio`, `delay_s` | second-order low-pass and a delay on the reading |
//! | `reversible_magnetization` | `susceptibility`, `saturation_field_a_per_m`, `shape` | `χ_r H / (1 + |H/H_s|^p)^(1/p)` |
//! | `thermal_drift` | `time_constant_s`, `lag_s`, `gain_loss_per_a2`, `strain_per_a2` | coil `τ θ' = I² − θ`, rod `τ_l φ' = θ − φ` (carried over between chained experiments); gain `max(0, 1 − g φ)` (the fraction of λ_s the warm rod keeps), strain `e φ`; `τ` at least two periods of the slowest dynamic excitation ([`thermal_time_constant_min_s`]) |
//! | `delta_e_effect` | `stiffness_m2`, `stiffness_m4`, `stiffness_m6`, `stiffness_stress` | `ω² = ω0² (1 + d₁ m² + d₂ m⁴ + d₃ m⁶ + d_σ ε)`, `m = M/M_s`, `ε = (y − u)/stroke` the elastic strain (stress) |
//! | `mechanical_load` | `mass_ratio`, `coupling_hz`, `damping_ratio` | one load mode (a mass coupled to the rod by a spring and a damper; the sensor reads it); its richer form ([`RICHER_FORM`], second stage only) hangs a second mass on it, `mass_ratio` (to the first load mass), `coupling_hz` and `damping_ratio` of its own |
//!
//! Parameters are optimized in an unbounded coordinate `z`: `value = lo + (hi − lo) σ(z)` with
//! the algebraic sigmoid `σ(z) = (1 + z/√(1 + z²))/2` (on `ln value` for log-scaled ones), so
//! Levenberg-Marquardt needs no bounds and a value never leaves its physical range; its tails
//! are polynomial, so a fit that touches a limit still has a gradient to leave it (`tanh` has
//! none). That gradient vanishes with the distance to the limit, so a fit never *starts* there:
//! every start is at least [`START_MARGIN`] of its range inside it
//! ([`ParamSpec::start_coordinate`]).

use crate::effects::EffectName;
use crate::model::{Electro, Mech, Nominal};

/// Which model stage a parameter acts in (stage-B parameters reuse a cached stage-A run).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stage {
    /// Electromagnetic (expensive).
    Electro,
    /// Mechanical and sensor (cheap).
    Mech,
}

/// One free parameter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ParamSpec {
    /// Name in the report.
    pub name: &'static str,
    /// Lower end of the range.
    pub lo: f64,
    /// Upper end.
    pub hi: f64,
    /// Log scale (`lo > 0`).
    pub log: bool,
    /// Stage.
    pub stage: Stage,
    /// Bounds that are the limits of the effect's physical range (a fit pinned there explains
    /// the data with an implausible effect; see [`ParamSpec::pinned`]); bounds where the effect
    /// switches off (a delay of 0) are not among them.
    pub edge: Edge,
}

/// Which bounds of a parameter are physical limits.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Edge {
    /// Neither.
    None,
    /// The lower bound.
    Low,
    /// The upper bound.
    High,
    /// Both.
    Both,
}

impl ParamSpec {
    /// The fitted coordinate `z` sits within 1 % of the range at a physical limit.
    pub fn pinned(&self, z: f64) -> bool {
        let s = sigmoid(z);
        (s < 0.01 && matches!(self.edge, Edge::Low | Edge::Both))
            || (s > 0.99 && matches!(self.edge, Edge::High | Edge::Both))
    }

    /// The fitted coordinate `z` sits within 1 % of the range at either end, physical limit or
    /// not: for a refitted constant or the channel skew, the end of the band the file's value
    /// allows (the fit wanted a value beyond it).
    pub fn at_range_end(&self, z: f64) -> bool {
        let s = sigmoid(z);
        !(0.01..=0.99).contains(&s)
    }

    /// Value at the unbounded coordinate `z`.
    pub fn value(&self, z: f64) -> f64 {
        let s = sigmoid(z);
        if self.log {
            (self.lo.ln() + s * (self.hi.ln() - self.lo.ln())).exp()
        } else {
            self.lo + s * (self.hi - self.lo)
        }
    }

    /// Coordinate of `v` (clamped just inside the range).
    pub fn coordinate(&self, v: f64) -> f64 {
        self.coordinate_within(v, 1e-4)
    }

    /// Coordinate of `v` as a fit's start: at least [`START_MARGIN`] of the range inside it.
    ///
    /// At the end of its range (`s = 1e-4`, `z ≈ ±50`) a parameter has no gradient: the
    /// sigmoid's slope there is `1/(2(1 + z²)^{3/2}) ≈ 4e-6`, a Jacobian step of 1e-3 in `z`
    /// moves the value by 4e-9 of its range, and Levenberg-Marquardt never brings it back. Starts
    /// come from the nuisance estimate (a channel skew at its ±1 sample limit when the file's
    /// model needs a lag), from refitted constants at the end of their band, from a single
    /// candidate's optimum pinned at a limit: each would freeze that parameter for the whole fit.
    /// At `s = 0.02` (`z ≈ ±3.4`) the slope is 0.011, about 3000× larger, and a fit that needs
    /// the limit runs back to it (test `a_start_at_a_limit_is_inside_it_and_has_a_gradient`).
    pub fn start_coordinate(&self, v: f64) -> f64 {
        self.coordinate_within(v, START_MARGIN)
    }

    fn coordinate_within(&self, v: f64, margin: f64) -> f64 {
        let s = if self.log {
            (v.max(self.lo).ln() - self.lo.ln()) / (self.hi.ln() - self.lo.ln())
        } else {
            (v - self.lo) / (self.hi - self.lo)
        };
        let u = 2.0 * s.clamp(margin, 1.0 - margin) - 1.0;
        u / (1.0 - u * u).sqrt()
    }
}

/// How far inside its range a fit's start is put, as a fraction of the range (in the fitted
/// coordinate): see [`ParamSpec::start_coordinate`].
pub const START_MARGIN: f64 = 0.02;

/// `(1 + z/√(1 + z²))/2`.
fn sigmoid(z: f64) -> f64 {
    0.5 * (1.0 + z / (1.0 + z * z).sqrt())
}

/// A candidate: the nominal model refitted, or it plus one or more effects.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Candidate {
    /// The effects added (empty: the refitted nominal model).
    pub effects: Vec<EffectName>,
}

impl Candidate {
    /// The refitted nominal model.
    pub fn nominal() -> Self {
        Candidate {
            effects: Vec::new(),
        }
    }

    /// One effect.
    pub fn single(effect: EffectName) -> Self {
        Candidate {
            effects: vec![effect],
        }
    }

    /// Its name (`nominal` or the effect names joined by `+`; an effect listed twice, in its
    /// richer form, as [`richer_form_name`]).
    pub fn name(&self) -> String {
        if self.effects.is_empty() {
            return "nominal".into();
        }
        self.distinct_effects()
            .into_iter()
            .map(|e| {
                if self.effects.iter().filter(|&&x| x == e).count() > 1 {
                    richer_form_name(e)
                } else {
                    e.name().to_string()
                }
            })
            .collect::<Vec<_>>()
            .join("+")
    }

    /// The effects, each once, in the order first listed.
    pub fn distinct_effects(&self) -> Vec<EffectName> {
        let mut out: Vec<EffectName> = Vec::new();
        for &e in &self.effects {
            if !out.contains(&e) {
                out.push(e);
            }
        }
        out
    }

    /// The same candidate with `effect`'s richer form (the effect listed once more, at the end).
    pub fn with_richer(&self, effect: EffectName) -> Candidate {
        let mut effects = self.effects.clone();
        effects.push(effect);
        Candidate { effects }
    }

    /// The same candidate without `effect` (every listing of it).
    pub fn without(&self, effect: EffectName) -> Candidate {
        Candidate {
            effects: self
                .effects
                .iter()
                .copied()
                .filter(|&e| e != effect)
                .collect(),
        }
    }
}

/// Effects whose library form is the first term of a series that an actuator may show more of,
/// and which a candidate may therefore list twice (still one effect, in a richer form):
/// * a second extra eddy path (the eddy currents of a rod diffuse from the surface inwards, so
///   the effective resistance rises over a wide band rather than at one corner; one path
///   follows that over about a decade);
/// * a second load mass hanging on the first (a fixture or a payload on a flexible mount has a
///   mode of its own above the coupling's).
///
/// Tried in the second stage of the diagnosis (`maglab_diagnose::diagnosis`): a second effect is not
/// missed because the first one's library form was too narrow, and a second effect is not
/// named for what a richer form of the first (or a better optimum of its library form)
/// explains.
pub const RICHER_FORM: [EffectName; 2] = [
    EffectName::EddyFrequencyDependence,
    EffectName::MechanicalLoad,
];

/// The report name of an effect's richer form.
pub fn richer_form_name(effect: EffectName) -> String {
    match effect {
        EffectName::EddyFrequencyDependence => format!("{}(2 paths)", effect.name()),
        EffectName::MechanicalLoad => format!("{}(2 modes)", effect.name()),
        _ => effect.name().to_string(),
    }
}

/// How far the refit may move `R_eddy`, `ξ`, `f0` from the file's values: factors (module docs).
pub const REFIT_RANGE: [f64; 3] = [1.25, 1.25, 1.06];

/// How far an identification may move `R_eddy`, `ξ`, `f0` from its start: factors. The
/// identification is where the constants are found, not checked; the diagnosis refits
/// constants a file lists as identified within the same range (what the identification could
/// have absorbed into them, it may take back out).
pub const IDENTIFICATION_RANGE: [f64; 3] = [10.0, 5.0, 2.0];

/// How many parameters every candidate shares, first in its value vector:
/// [`common_parameters`] (`R_eddy`, `ξ`, `f0`, skew); an effect's own parameters follow.
pub const COMMON_PARAMETER_COUNT: usize = 4;

/// The refitted nominal constants and the skew: `R_eddy`, `ξ`, `f0` (within `range` of the
/// nominal values, factors), `skew`.
pub fn common_parameters(nominal: &Nominal, range: &[f64; 3]) -> Vec<ParamSpec> {
    let (r, xi, f0) = (
        nominal.eddy_resistance_ohm,
        nominal.damping_ratio,
        nominal.resonance_hz,
    );
    let [kr, kx, kf] = *range;
    vec![
        ParamSpec {
            name: "eddy_resistance_ohm",
            lo: r / kr,
            hi: r * kr,
            log: true,
            stage: Stage::Electro,
            edge: Edge::None,
        },
        ParamSpec {
            name: "damping_ratio",
            lo: xi / kx,
            hi: xi * kx,
            log: true,
            stage: Stage::Mech,
            edge: Edge::None,
        },
        ParamSpec {
            name: "resonance_hz",
            lo: f0 / kf,
            hi: f0 * kf,
            log: true,
            stage: Stage::Mech,
            edge: Edge::None,
        },
        ParamSpec {
            name: "channel_skew_samples",
            lo: -1.0,
            hi: 1.0,
            log: false,
            stage: Stage::Mech,
            edge: Edge::None,
        },
    ]
}

/// The thermal candidate's shortest time constant: two periods of the slowest dynamic
/// excitation (0.5 s until data are seen), s.
pub fn thermal_time_constant_min_s(nominal: &Nominal) -> f64 {
    2.0 * nominal.slowest_period_s
}

/// A parameter's spec in one line (the table of [`effect_parameters`]).
const fn spec(
    name: &'static str,
    lo: f64,
    hi: f64,
    log: bool,
    stage: Stage,
    edge: Edge,
) -> ParamSpec {
    ParamSpec {
        name,
        lo,
        hi,
        log,
        stage,
        edge,
    }
}

/// The effect's own parameters: the library's ranges ([`library_parameters`]) with the file's
/// datasheet priors in place of those they bound ([`crate::priors`]).
pub fn effect_parameters(effect: EffectName, nominal: &Nominal) -> Vec<ParamSpec> {
    let mut specs = library_parameters(effect, nominal);
    nominal.priors.narrow(effect, &mut specs);
    specs
}

/// The effect's own parameters with the library's ranges.
pub fn library_parameters(effect: EffectName, nominal: &Nominal) -> Vec<ParamSpec> {
    let f0 = nominal.resonance_hz;
    // A reversible term that saturates well inside the operating range is a constant
    // magnetization there (the start state's offset), not a susceptibility.
    let h_s_min = (0.5 * nominal.operating_field_a_per_m).max(2e3);
    use Stage::{Electro as A, Mech as B};
    match effect {
        EffectName::EddyFrequencyDependence => vec![
            spec("hf_to_dc_ratio", 1.0 / 16.0, 16.0, true, A, Edge::Both),
            spec("corner_hz", 10.0, 5000.0, true, A, Edge::None),
            spec("anchor", 0.0, 1.0, false, A, Edge::None),
        ],
        EffectName::AmplifierBandwidth => vec![
            spec("natural_hz", 50.0, 50_000.0, true, A, Edge::Low),
            spec("damping_ratio", 0.3, 3.0, true, A, Edge::None),
            // From an ideal current source (0) to a coil L/R of 2 ms, a large coil's for a rod
            // of this size; linear, so the ideal source is inside the range.
            spec("coil_time_constant_s", 0.0, 2e-3, false, A, Edge::None),
        ],
        EffectName::SensorDynamics => vec![
            spec("natural_hz", 100.0, 50_000.0, true, B, Edge::Low),
            spec("damping_ratio", 0.3, 3.0, true, B, Edge::None),
            spec("delay_s", 0.0, 1e-3, false, B, Edge::High),
        ],
        EffectName::ReversibleMagnetization => vec![
            spec("susceptibility", 0.0, 30.0, false, A, Edge::High),
            spec(
                "saturation_field_a_per_m",
                h_s_min,
                50.0 * h_s_min,
                true,
                A,
                Edge::Low,
            ),
            spec("shape", 0.7, 4.0, true, A, Edge::None),
        ],
        EffectName::ThermalDrift => vec![
            // Below two periods of the slowest excitation the candidate would follow the
            // excitation itself (the I² ripple passes with less than 12x attenuation) and become a
            // static output nonlinearity: that is the range's physical limit, read from the data
            // (a small coil's time constant is well under a second, a large one's minutes).
            spec(
                "time_constant_s",
                thermal_time_constant_min_s(nominal),
                1000.0,
                true,
                B,
                Edge::Low,
            ),
            spec("lag_s", 0.01, 100.0, true, B, Edge::None),
            spec("gain_loss_per_a2", -5.0, 5.0, false, B, Edge::Both),
            spec("strain_per_a2", -5.0, 5.0, false, B, Edge::Both),
        ],
        EffectName::DeltaEEffect => vec![
            spec("stiffness_m2", -0.8, 10.0, false, B, Edge::Both),
            spec("stiffness_m4", -10.0, 10.0, false, B, Edge::Both),
            spec("stiffness_m6", -10.0, 10.0, false, B, Edge::Both),
            spec("stiffness_stress", -10.0, 10.0, false, B, Edge::Both),
        ],
        EffectName::MechanicalLoad => vec![
            // Both ends are physical limits. At the low end the load no longer loads the rod:
            // a mass of 2 % of the rod's on a spring and a damper, the sensor reading it, is a
            // second-order low-pass on the reading — the sensor's mount, the form of
            // `sensor_dynamics` — and a load fit that runs there is a sensor lag in disguise
            // (seen with identified files, f0 free x/ 2).
            spec("mass_ratio", 0.02, 10.0, true, B, Edge::Both),
            spec("coupling_hz", 0.5 * f0, 20.0 * f0, true, B, Edge::Low),
            spec("damping_ratio", 0.02, 3.0, true, B, Edge::None),
        ],
    }
}

/// Every parameter of a candidate: the common ones (within `range`), then each effect's.
pub fn parameters(candidate: &Candidate, nominal: &Nominal, range: &[f64; 3]) -> Vec<ParamSpec> {
    let mut specs = common_parameters(nominal, range);
    for (i, &e) in candidate.effects.iter().enumerate() {
        if is_repeat(&candidate.effects, i) {
            specs.extend(second_term_parameters(e, nominal));
        } else {
            specs.extend(effect_parameters(e, nominal));
        }
    }
    specs
}

/// Whether `effects[i]` is listed before: the second term of its richer form.
pub fn is_repeat(effects: &[EffectName], i: usize) -> bool {
    effects[..i].contains(&effects[i])
}

/// Where `effects[i]`'s parameters start in a candidate's value vector (after the common ones
/// and those of the effects listed before it).
pub fn parameter_offset(effects: &[EffectName], i: usize) -> usize {
    COMMON_PARAMETER_COUNT
        + (0..i)
            .map(|k| parameter_count_at(effects, k))
            .sum::<usize>()
}

/// Number of parameters of `effects[i]`: the effect's own, or its second term's when it is a
/// repeat ([`RICHER_FORM`]).
pub fn parameter_count_at(effects: &[EffectName], i: usize) -> usize {
    if is_repeat(effects, i) {
        second_term_parameter_count(effects[i])
    } else {
        effect_parameter_count(effects[i])
    }
}

/// The second term of an effect's richer form ([`RICHER_FORM`]; none for the others): a second
/// eddy path (its own step of `R` and corner; the first path's `anchor` places the refitted
/// `R` within the whole step).
pub fn second_term_parameters(effect: EffectName, nominal: &Nominal) -> Vec<ParamSpec> {
    match effect {
        EffectName::EddyFrequencyDependence => library_parameters(effect, nominal)
            .into_iter()
            .take(2)
            .collect(),
        // Its mass is relative to the first load mass: the datasheet's load mass bounds the
        // first.
        EffectName::MechanicalLoad => library_parameters(effect, nominal),
        _ => Vec::new(),
    }
}

/// The report's name for the second term of an effect's richer form (its parameters read
/// `effect.label.parameter`).
pub fn second_term_label(effect: EffectName) -> &'static str {
    match effect {
        EffectName::MechanicalLoad => "second_mode",
        _ => "second_path",
    }
}

/// Number of parameters of an effect's second term.
pub fn second_term_parameter_count(effect: EffectName) -> usize {
    match effect {
        EffectName::EddyFrequencyDependence => 2,
        EffectName::MechanicalLoad => 3,
        _ => 0,
    }
}

/// Starts for an effect's second term, given the first term's fitted values: the second eddy
/// path a decade below and above the first one's corner, stepping `R` up by 2.
pub fn second_term_starts(effect: EffectName, first: &[f64]) -> Vec<Vec<f64>> {
    match (effect, first) {
        (EffectName::EddyFrequencyDependence, [_, corner, ..]) => [0.1, 10.0]
            .iter()
            .map(|k| vec![2.0, (corner * k).clamp(12.0, 4000.0)])
            .collect(),
        (EffectName::MechanicalLoad, [_, coupling, ..]) => [0.3, 1.0]
            .iter()
            .flat_map(|&mass| [2.0, 4.0, 8.0].map(|k| vec![mass, coupling * k, 0.1]))
            .collect(),
        _ => Vec::new(),
    }
}

/// Starting values of an effect's parameters (physical units): a small grid over the most
/// influential ones; each start is evaluated and the best refined. The reversible term's
/// saturation field spans 0.8 to 6.4 times the operating field and its shape both sides of
/// `tanh`'s (≈ 2): from one field and one shape, a tanh-like term of the bench plant was fitted
/// with `H_s` five times too large and the shared constants at their limits (a quarter of the
/// gap left; 2–4 % from the grid).
pub fn effect_starts(effect: EffectName, nominal: &Nominal) -> Vec<Vec<f64>> {
    let f0 = nominal.resonance_hz;
    let mut out = Vec::new();
    match effect {
        EffectName::EddyFrequencyDependence => {
            for (ratio, anchor) in [(3.0, 0.8), (1.0 / 3.0, 0.8), (3.0, 0.2)] {
                for corner in [60.0, 250.0, 1000.0] {
                    out.push(vec![ratio, corner, anchor]);
                }
            }
        }
        EffectName::AmplifierBandwidth => {
            // An ideal current source and a coil of 0.5 ms (the middle of 0.1–1 ms, a bench
            // coil's on this rod): from the ideal source alone the command's lag can settle
            // where it fits part of a PI loop's gap and never reach the loop's EMF term.
            for f in [300.0, 1000.0, 3000.0] {
                for tau_l in [0.0, 5e-4] {
                    out.push(vec![f, 0.7, tau_l]);
                }
            }
        }
        EffectName::SensorDynamics => {
            for f in [500.0, 1500.0, 5000.0] {
                for delay in [0.0, 1.5e-4] {
                    out.push(vec![f, 0.7, delay]);
                }
            }
        }
        EffectName::ReversibleMagnetization => {
            let h_op = nominal.operating_field_a_per_m.max(4e3);
            for chi in [1.0, 4.0, 12.0] {
                // Inside the range (its low end, half the operating field, is a physical limit).
                for k in [0.8, 1.6, 3.2, 6.4] {
                    for p in [1.5, 3.0] {
                        out.push(vec![chi, k * h_op, p]);
                    }
                }
            }
        }
        EffectName::ThermalDrift => {
            let tau_min = thermal_time_constant_min_s(nominal);
            for tau in [2.0 * tau_min, 5.0, 30.0] {
                for g in [-0.05, 0.05] {
                    out.push(vec![tau, 0.3, g, 0.0]);
                }
            }
        }
        EffectName::DeltaEEffect => {
            for d in [-0.3, 0.5, 2.0] {
                out.push(vec![d, 0.0, 0.0, 0.0]);
            }
        }
        EffectName::MechanicalLoad => {
            for ratio in [0.3, 1.0] {
                for c in [1.5, 3.0, 6.0] {
                    out.push(vec![ratio, c * f0, 0.2]);
                }
            }
        }
    }
    out
}

/// The model parameters a candidate's values (physical units, [`parameters`] order) stand for.
pub fn model_parameters(candidate: &Candidate, values: &[f64]) -> (Electro, Mech) {
    let mut e = Electro::nominal(values[0]);
    let mut m = Mech::nominal(values[1], values[2]);
    m.skew_samples = values[3];
    let mut k = COMMON_PARAMETER_COUNT;
    let mut eddy_anchor = None;
    for (i, &effect) in candidate.effects.iter().enumerate() {
        let v = &values[k..];
        if is_repeat(&candidate.effects, i) {
            // The second term of a richer form ([`RICHER_FORM`]).
            match effect {
                EffectName::EddyFrequencyDependence => e.second_eddy_path = Some((v[0], v[1])),
                EffectName::MechanicalLoad => m.second_load = Some((v[0], v[1], v[2])),
                _ => {}
            }
            k += parameter_count_at(&candidate.effects, i);
            continue;
        }
        match effect {
            EffectName::EddyFrequencyDependence => {
                e.eddy_path = Some((v[0], v[1]));
                eddy_anchor = Some(v[2]);
            }
            EffectName::AmplifierBandwidth => e.amplifier = Some((v[0], v[1], v[2])),
            EffectName::SensorDynamics => m.sensor = Some((v[0], v[1], v[2])),
            EffectName::ReversibleMagnetization => e.reversible = Some((v[0], v[1], v[2])),
            EffectName::ThermalDrift => m.thermal = Some((v[0], v[1], v[2], v[3])),
            EffectName::DeltaEEffect => m.delta_e = Some((v[0], v[1], v[2], v[3])),
            EffectName::MechanicalLoad => m.load = Some((v[0], v[1], v[2])),
        }
        k += effect_parameter_count(effect);
    }
    // R_dc from the refitted R and the anchor: ln R = ln R_dc + anchor · ln(total R step).
    if let (Some(anchor), Some((ratio, _))) = (eddy_anchor, e.eddy_path) {
        let log_step = match e.second_eddy_path {
            Some((second, _)) => ratio.ln() + second.ln(),
            None => ratio.ln(),
        };
        e.eddy_resistance_ohm = values[0] * (-anchor * log_step).exp();
    }
    (e, m)
}

/// Number of parameters of an effect.
pub fn effect_parameter_count(effect: EffectName) -> usize {
    match effect {
        EffectName::EddyFrequencyDependence
        | EffectName::AmplifierBandwidth
        | EffectName::ReversibleMagnetization
        | EffectName::SensorDynamics
        | EffectName::MechanicalLoad => 3,
        EffectName::ThermalDrift | EffectName::DeltaEEffect => 4,
    }
}
