//! The diagnosis model: the nominal model (paper eqs (4)-(5)) with optional augmentations, one
//! per candidate effect, and the nuisances of a recording, simulated on a measured current.
//!
//! It runs in two stages so that a fit can reuse the expensive one:
//!
//! 1. **Electromagnetic stage** ([`run_electro`]; parameters [`Electro`]): command → coil current
//!    (held or linear between samples; `amplifier_bandwidth`: second-order low-pass) → eddy
//!    currents and hysteresis → `M` at every substep. The hysteresis is the core's f32 Preisach
//!    operator (`magctl::preisach`, exact monotone solve of `a·h + Γ(h) = r`). The eddy step is
//!    backward Euler on the integral form (8), `w = H + M`, L-stable and monotone:
//!    `(1 + χ_r + δ/(κ c0 Z_hf)) H⁺ + Γ(H⁺) = w_rev + (δ/κ)(Ī − τ q/(τ + δ))/Z_hf` where the
//!    eddy impedance `Z = 1/c1` may depend on frequency (`eddy_frequency_dependence`:
//!    `Z(s) = Z_hf + (Z_dc − Z_hf)/(1 + sτ)`, one extra path; `q` its state,
//!    `τ q' = (Z_dc − Z_hf) w' − q`, `κ = (τ Z_hf + δ Z_dc)/((τ + δ) Z_hf)`; its richer form has
//!    two paths, `Z(s) = Z_hf + Σ ΔZ_i/(1 + sτ_i)`, each with its own state, `τ q/(τ + δ)`
//!    summed over them and `κ = 1 + Σ δ ΔZ_i/((τ_i + δ) Z_hf)`, see [`eddy_paths`]) and `χ_r` is the
//!    slope of the reversible term at the start of the step (`reversible_magnetization`:
//!    `M_rev = χ_r H / (1 + |H/H_s|^p)^(1/p)`, slope `χ_r (1 + |H/H_s|^p)^(−1/p − 1)`, linearized
//!    over each step). The stage runs
//!    with `S` and `2S` substeps per sample and returns the Richardson combination
//!    `2 M(2S) − M(S)` at the `S` substep ends: backward Euler's error is first order in the
//!    step, so the combination is second order (measured against the bench plant without
//!    effects: see `tests/`).
//! 2. **Mechanical stage** ([`run_mech`]; parameters [`Mech`]): `u = max(0, 1 − g φ)
//!    (l_m λ_s/M_s²) M² + e φ` (`thermal_drift`: the coil `τ θ' = I² − θ` heating the rod
//!    `τ_l φ' = θ − φ`, a gain loss and an expansion with `φ`, both starting from the previous
//!    experiment's end for a chained start; the gain is the fraction of λ_s the warm rod keeps,
//!    which a rod heated past its loss of λ_s cannot take below zero), the rod eq. (5)
//!    (`delta_e_effect`: `ω² = ω0² (1 + d₁ m² + d₂ m⁴ + d₃ m⁶ + d_σ ε)`, ε = (y − u)/stroke the elastic
//!    strain, a first-order stress dependence; `mechanical_load`: a second mass on a
//!    spring, the sensor on it) by RK4 with `u` linear over each substep (without ΔE the step
//!    is linear and applied as its matrix), the sensor
//!    (`sensor_dynamics`: second-order low-pass, then a delay), and the reading at
//!    `t_k + skew − delay` by cubic Hermite interpolation of the sensor's output and its rate.
//!
//! **Start.** [`ModelStart`] is what a bench documents (`maglab_dataset::start`): the
//! core's AC-demagnetized memory at 0 A (switched on at `t = 0`, or brought slowly to the first
//! command), saturation, or the memory the previous experiment of the same simulated chain left
//! (the caller runs the chain in order with the same parameters).
//!
//! Output sample `k` is the displacement the sensor reads at `t_k`, before the current of
//! sample `k` acts on a held command (the recording convention of `maglab rig`).

use magctl::preisach::{PreisachMeasure, PreisachState};
use maglab_dataset::{CurrentBetweenSamples, StartState};
use std::borrow::Cow;
use std::f64::consts::PI;

/// Staircase capacity of the model's Preisach memory (deep histories such as a chain of
/// experiments never merge).
pub const CAPACITY: usize = 256;

/// The model's Preisach memory.
pub type Memory = PreisachState<CAPACITY>;

/// μ0, H/m.
const MU0: f64 = 4.0e-7 * PI;

/// Constants of the nominal model, f64.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Nominal {
    /// `c0`, 1/m.
    pub c0_per_m: f64,
    /// `μ0 N A`, so that `c1 = R / (μ0 N A)`.
    pub mu0_n_a: f64,
    /// `l_m λ_s / M_s²`, m per (A/m)².
    pub displacement_per_m2_m: f64,
    /// `M_s`, A/m.
    pub saturation_a_per_m: f64,
    /// `l_m λ_s`, m.
    pub stroke_m: f64,
    /// The file's `R_eddy`, Ω.
    pub eddy_resistance_ohm: f64,
    /// The file's `ξ`.
    pub damping_ratio: f64,
    /// The file's `f0`, Hz.
    pub resonance_hz: f64,
    /// The largest field the data reach, `c0 max |I|`, A/m (the grid's top until data are
    /// seen): some candidate ranges scale with it.
    pub operating_field_a_per_m: f64,
    /// The longest excitation period among the dynamic experiments, s (0.25 s until data are
    /// seen): a drift must be slow against it to be told from a static nonlinearity.
    pub slowest_period_s: f64,
    /// The fields `(c0 I_lo, c0 I_hi)` the firmware's start-up conditioning sweeps with this
    /// file baked, when it sweeps the reach of a rod the coil cannot saturate
    /// (`magctl::inverse::Conditioning`); `None` when it saturates the rod. A documented start
    /// `conditioned` is that sweep.
    pub conditioning_sweep_a_per_m: Option<(f32, f32)>,
    /// The file's datasheet priors on the candidates' parameters.
    pub priors: crate::priors::Priors,
}

impl Nominal {
    /// From a parameter file.
    pub fn from_params(p: &actuator_params::ActuatorParams) -> Self {
        let a = &p.actuator;
        Nominal {
            c0_per_m: a.coil_factor_per_m,
            mu0_n_a: MU0 * a.coil_turns * a.rod_area_m2,
            displacement_per_m2_m: a.rod_length_m * a.saturation_magnetostriction
                / (a.saturation_magnetization_a_per_m * a.saturation_magnetization_a_per_m),
            saturation_a_per_m: a.saturation_magnetization_a_per_m,
            stroke_m: a.rod_length_m * a.saturation_magnetostriction,
            eddy_resistance_ohm: a.eddy_resistance_ohm,
            damping_ratio: a.damping_ratio,
            resonance_hz: a.resonance_hz,
            operating_field_a_per_m: p
                .preisach
                .h_max_a_per_m
                .abs()
                .max(p.preisach.h_min_a_per_m.abs()),
            slowest_period_s: 0.25,
            conditioning_sweep_a_per_m: conditioning_sweep_a_per_m(p),
            priors: crate::priors::Priors::from_params(p),
        }
    }
}

/// How a simulated experiment starts.
#[derive(Debug, Clone, PartialEq)]
pub enum ModelStart {
    /// A start state a bench documents ([`StartState::BENCH`]); `previous` is where the
    /// previous experiment of the same simulated chain ended (no reset between experiments):
    /// its memory, then the first command applied at `t = 0`. The model simulates the bench
    /// states; any other starts demagnetized.
    State(StartState),
    /// Where a record outside the simulated set left the memory (computed once, before any fit:
    /// a quasi-static reversal sweep recorded right before the first experiment of a chain),
    /// then the first command applied at `t = 0`.
    After(std::sync::Arc<Memory>),
}

impl ModelStart {
    /// Continues the previous experiment of the simulated chain.
    pub fn is_previous(&self) -> bool {
        *self == ModelStart::State(StartState::Previous)
    }
}

/// Parameters of the electromagnetic stage.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Electro {
    /// `R_eddy` at low frequency, Ω.
    pub eddy_resistance_ohm: f64,
    /// Second-order low-pass on the current: `(natural frequency Hz, damping ratio)`.
    pub amplifier: Option<(f64, f64)>,
    /// One extra eddy path: `(R_hf / R_dc, corner Hz)`.
    pub eddy_path: Option<(f64, f64)>,
    /// A second extra eddy path (the richer form of `eddy_frequency_dependence`, see
    /// [`crate::candidates::RICHER_FORM`]): `(its own R step, corner Hz)`; with both paths `R`
    /// steps up by each path's factor at its corner ([`eddy_paths`]).
    pub second_eddy_path: Option<(f64, f64)>,
    /// Reversible term: `(χ_r, H_s A/m, shape p)`.
    pub reversible: Option<(f64, f64, f64)>,
}

impl Electro {
    /// Only `R_eddy`.
    pub fn nominal(eddy_resistance_ohm: f64) -> Self {
        Electro {
            eddy_resistance_ohm,
            amplifier: None,
            eddy_path: None,
            second_eddy_path: None,
            reversible: None,
        }
    }
}

/// Parameters of the mechanical stage.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Mech {
    /// `ξ`.
    pub damping_ratio: f64,
    /// `f0`, Hz.
    pub resonance_hz: f64,
    /// Thermal drift: `(τ s, rod lag τ_l s, gain loss per A², strain per A² as a fraction of
    /// the stroke)`.
    pub thermal: Option<(f64, f64, f64, f64)>,
    /// Δ-E: `(d₁, d₂)` in `ω² = ω0² (1 + d₁ m² + d₂ m⁴)`, `m = M/M_s`.
    pub delta_e: Option<(f64, f64, f64, f64)>,
    /// Load mode: `(mass ratio, coupling Hz, damping ratio)`.
    pub load: Option<(f64, f64, f64)>,
    /// A second load mass hanging on the first (the load's richer form, [`crate::candidates::RICHER_FORM`]):
    /// `(its mass / the first load mass, coupling Hz, damping ratio)`; only with `load`.
    pub second_load: Option<(f64, f64, f64)>,
    /// Sensor: `(natural frequency Hz, damping ratio, delay s)`.
    pub sensor: Option<(f64, f64, f64)>,
    /// The displacement channel is read `skew` samples after the current's sample time.
    pub skew_samples: f64,
}

impl Mech {
    /// Only `ξ` and `f0`.
    pub fn nominal(damping_ratio: f64, resonance_hz: f64) -> Self {
        Mech {
            damping_ratio,
            resonance_hz,
            thermal: None,
            delta_e: None,
            load: None,
            second_load: None,
            sensor: None,
            skew_samples: 0.0,
        }
    }
}

/// The electromagnetic stage's result for one experiment.
#[derive(Debug, Clone)]
pub struct ElectroRun {
    /// Substeps per sample of the result.
    pub substeps: usize,
    /// `M` at the start and at every substep end (`1 + n S` values), A/m.
    pub m_a_per_m: Vec<f64>,
    /// Mean squared coil current over every substep (`n S` values), A².
    pub current_sq_a2: Vec<f64>,
    /// The memory at the end (for a following experiment).
    pub end_memory: Box<Memory>,
}

/// The reversible term `χ H q^(−1/p)` with `q = 1 + |H/H_s|^p`, and its slope `χ q^(−1/p − 1)`.
///
/// Evaluated once per substep, so written with two `exp` and two logarithms instead of three
/// `powf`, which were 12 % of the blind suite's time (`perf` on `blind_suite 1 12`); the slope
/// reuses `q^(−1/p)`. Within 1e-13 (relative) of the `powf` form (test
/// `reversible_term_matches_the_powf_form`).
#[doc(hidden)] // public for tests/internals.rs only
pub fn reversible(rev: Option<(f64, f64, f64)>, h: f64) -> (f64, f64) {
    match rev {
        Some((chi, hs, p)) if chi > 0.0 => {
            let x = (h / hs).abs();
            // |H/H_s|^p = exp(p ln|H/H_s|); 0^p = 0 for the p > 0 of the candidate's range.
            let a = if x > 0.0 { (p * x.ln()).exp() } else { 0.0 };
            let q = 1.0 + a;
            let damped = (-a.ln_1p() / p).exp();
            (chi * h * damped, chi * damped / q)
        }
        _ => (0.0, 0.0),
    }
}

/// The fields the firmware's conditioning sweeps with `p` baked (the core's own rule, so the
/// model and the firmware agree), `None` when it saturates the rod or the file cannot be baked.
fn conditioning_sweep_a_per_m(p: &actuator_params::ActuatorParams) -> Option<(f32, f32)> {
    use magctl::inverse::{Conditioning, OutputLimiter, Sweep};
    let core = magctl::params::ActuatorParameters::from_file(p, "parameter file").ok()?;
    let limiter = OutputLimiter::new(&core.control).ok()?;
    let measure = core.preisach.measure();
    let c0 = core.actuator.coil_factor_per_m;
    let conditioning = Conditioning::new(
        &limiter,
        c0,
        &measure,
        core.preisach.reach_a_per_m,
        core.control.sample_rate_hz,
    )
    .ok()?;
    match conditioning.sweep() {
        Sweep::Saturate { .. } => None,
        Sweep::Reach { low_a, high_a } => Some((low_a * c0, high_a * c0)),
    }
}

/// The memory a start puts the model in (before the move to the first command); a chained
/// start without a previous memory starts demagnetized.
fn start_memory(
    nominal: &Nominal,
    measure: &PreisachMeasure,
    start: &ModelStart,
    previous: Option<&Memory>,
) -> Memory {
    match (start, previous) {
        (ModelStart::State(StartState::Conditioned), _) => match nominal.conditioning_sweep_a_per_m
        {
            Some((low, high)) => measure.conditioned(low, high),
            None => measure.negative_saturation(),
        },
        (ModelStart::State(StartState::NegativeSaturation), _) => measure.negative_saturation(),
        (ModelStart::State(StartState::PositiveSaturation), _) => measure.positive_saturation(),
        (ModelStart::State(StartState::Previous), Some(m)) => m.clone(),
        (ModelStart::After(m), _) => (**m).clone(),
        _ => measure.demagnetized_at(0.0),
    }
}

/// The eddy impedance `Z(s) = Z_hf + Σ ΔZ_i/(1 + s τ_i)` (Foster form, one term per extra
/// path) from `Z_dc` and the paths `(R step factor, corner Hz)`: `R = 1/Z` steps up by each
/// path's factor at its corner, the lower corner first, so that `Z_hf = Z_dc/(r₁ r₂)`, the
/// lower-corner path carries `Z_dc − Z_dc/r_low` and the other `Z_dc/r_low − Z_hf`. Returns
/// `Z_hf` and each path's `(τ, ΔZ)` in the order given.
pub fn eddy_paths(
    z_dc: f64,
    first: Option<(f64, f64)>,
    second: Option<(f64, f64)>,
) -> (f64, [Option<(f64, f64)>; 2]) {
    let tau = |corner_hz: f64| 1.0 / (2.0 * PI * corner_hz);
    match (first, second) {
        (Some((ratio, corner)), None) => {
            let z_hf = z_dc / ratio;
            (z_hf, [Some((tau(corner), z_dc - z_hf)), None])
        }
        (Some((r1, c1)), Some((r2, c2))) => {
            let z_hf = z_dc / (r1 * r2);
            let (low_ratio, first_is_low) = if c1 <= c2 { (r1, true) } else { (r2, false) };
            let z_mid = z_dc / low_ratio;
            let (dz1, dz2) = if first_is_low {
                (z_dc - z_mid, z_mid - z_hf)
            } else {
                (z_mid - z_hf, z_dc - z_mid)
            };
            (z_hf, [Some((tau(c1), dz1)), Some((tau(c2), dz2))])
        }
        _ => (z_dc, [None, None]),
    }
}

/// One electromagnetic run with `s` substeps per sample: `(M at substep ends, mean I², end memory)`.
#[allow(clippy::too_many_arguments)]
fn electro_once(
    nominal: &Nominal,
    measure: &PreisachMeasure,
    e: &Electro,
    currents_a: &[f64],
    step_s: f64,
    interp: CurrentBetweenSamples,
    start: &ModelStart,
    previous: Option<&Memory>,
    s: usize,
) -> (Vec<f64>, Vec<f64>, Memory) {
    // The second eddy path is a compile-time switch: as a run-time one it cost the substep loop
    // of every other model about 18 % of a diagnosis' time (measured on the blind suite).
    let run = if e.second_eddy_path.is_some() {
        electro_steps::<true>
    } else {
        electro_steps::<false>
    };
    run(
        nominal, measure, e, currents_a, step_s, interp, start, previous, s,
    )
}

/// [`electro_once`] with or without the second eddy path's state.
#[allow(clippy::too_many_arguments)]
fn electro_steps<const SECOND_PATH: bool>(
    nominal: &Nominal,
    measure: &PreisachMeasure,
    e: &Electro,
    currents_a: &[f64],
    step_s: f64,
    interp: CurrentBetweenSamples,
    start: &ModelStart,
    previous: Option<&Memory>,
    s: usize,
) -> (Vec<f64>, Vec<f64>, Memory) {
    let n = currents_a.len();
    let delta = step_s / s as f64;
    let c0 = nominal.c0_per_m;
    let z_dc = nominal.mu0_n_a / e.eddy_resistance_ohm.max(1e-9);
    // Eddy impedance: Z_hf and the extra paths (module docs).
    let (z_hf, paths) = eddy_paths(z_dc, e.eddy_path, e.second_eddy_path);
    let kappa = match paths {
        [Some((tau, dz)), None] => (tau * z_hf + delta * (z_hf + dz)) / ((tau + delta) * z_hf),
        _ => {
            1.0 + paths
                .iter()
                .flatten()
                .map(|(tau, dz)| delta * dz / ((tau + delta) * z_hf))
                .sum::<f64>()
        }
    };
    let drive = delta / (kappa * z_hf);
    let [path, second_path] = paths;
    let keep = |p: Option<(f64, f64)>| p.map_or(0.0, |(tau, _)| tau / (tau + delta));
    let (q_keep, second_q_keep) = (keep(path), keep(second_path));
    // Amplifier: exact discretization of i'' = ω²(c − i) − 2ζω i' for c linear over a substep.
    let amp = e
        .amplifier
        .map(|(f, zeta)| second_order(2.0 * PI * f, zeta, delta));
    let mut memory = start_memory(nominal, measure, start, previous);
    let first = currents_a[0];
    let (i_start, h0) = match start {
        ModelStart::State(StartState::SwitchOnDemagnetized) => (0.0, 0.0),
        _ => (first, c0 * first),
    };
    let g0 = match measure.apply(&mut memory, h0 as f32) {
        Ok(m) => m as f64,
        Err(_) => measure.output_a_per_m(&memory) as f64,
    };
    let mut h = h0;
    // The reversible term and its slope at the current `h` (carried from one substep to the next).
    let mut rev_at_h = reversible(e.reversible, h);
    let mut m = g0 + rev_at_h.0;
    let (mut q, mut second_q) = (0.0f64, 0.0f64);
    let mut amp_state = [i_start, 0.0f64];
    let mut m_out = Vec::with_capacity(1 + n * s);
    let mut i2_out = Vec::with_capacity(n * s);
    m_out.push(m);
    for k in 0..n {
        let c_a = currents_a[k];
        let c_b = match interp {
            CurrentBetweenSamples::Hold => c_a,
            CurrentBetweenSamples::Linear => currents_a[(k + 1).min(n - 1)],
        };
        for j in 0..s {
            let fa = j as f64 / s as f64;
            let fb = (j + 1) as f64 / s as f64;
            let (u0, u1) = (c_a + (c_b - c_a) * fa, c_a + (c_b - c_a) * fb);
            // Coil current: its mean and mean square over the substep.
            let (i_mean, i2) = match &amp {
                Some(a) => {
                    let before = amp_state[0];
                    amp_state = a.step(amp_state, u0, u1);
                    let mean = 0.5 * (before + amp_state[0]);
                    (
                        mean,
                        (before * before + before * amp_state[0] + amp_state[0] * amp_state[0])
                            / 3.0,
                    )
                }
                None => ((u0 + u1) * 0.5, (u0 * u0 + u0 * u1 + u1 * u1) / 3.0),
            };
            let (mrev, chi) = rev_at_h;
            // w_rev = (1 + χ) H + Γ(H) with the reversible part linearized at H.
            let gamma = m - mrev;
            let eddy = if SECOND_PATH {
                q_keep * q + second_q_keep * second_q
            } else {
                q_keep * q
            };
            let rhs = (1.0 + chi) * h + gamma + drive * (i_mean - eddy);
            let slope = (1.0 + chi + drive / c0) as f32;
            let (h_new, g_new) = match measure.solve(&mut memory, slope, rhs as f32) {
                Ok(sol) => (sol.h_a_per_m as f64, sol.m_a_per_m as f64),
                Err(_) => (h, gamma),
            };
            rev_at_h = reversible(e.reversible, h_new);
            let w_change = (h_new - h) + (g_new - gamma) + (rev_at_h.0 - mrev);
            if let Some((tau, dz)) = path {
                q = (tau * q + dz * w_change) / (tau + delta);
            }
            if let (true, Some((tau, dz))) = (SECOND_PATH, second_path) {
                second_q = (tau * second_q + dz * w_change) / (tau + delta);
            }
            h = h_new;
            m = g_new + rev_at_h.0;
            m_out.push(m);
            i2_out.push(i2);
        }
    }
    (m_out, i2_out, memory)
}

/// The electromagnetic stage (module docs): Richardson combination of runs with `substeps` and
/// `2 substeps` substeps per sample (the coarse one is [`run_electro_single`]'s).
#[allow(clippy::too_many_arguments)]
pub fn run_electro(
    nominal: &Nominal,
    measure: &PreisachMeasure,
    e: &Electro,
    currents_a: &[f64],
    step_s: f64,
    interp: CurrentBetweenSamples,
    start: &ModelStart,
    previous: Option<&Memory>,
    substeps: usize,
) -> ElectroRun {
    let coarse = run_electro_single(
        nominal, measure, e, currents_a, step_s, interp, start, previous, substeps,
    );
    let (fine, _, end) = electro_once(
        nominal,
        measure,
        e,
        currents_a,
        step_s,
        interp,
        start,
        previous,
        2 * coarse.substeps,
    );
    let m = coarse
        .m_a_per_m
        .iter()
        .enumerate()
        .map(|(j, c)| 2.0 * fine[2 * j] - c)
        .collect();
    ElectroRun {
        m_a_per_m: m,
        end_memory: Box::new(end),
        ..coarse
    }
}

/// The electromagnetic stage from one run with `substeps` substeps per sample, without the
/// Richardson pair: first order in the step, about a third of [`run_electro`]'s cost. Only the
/// fit's Jacobian uses it (`crate::fit`'s module docs): a slope, never a residual.
#[allow(clippy::too_many_arguments)]
pub fn run_electro_single(
    nominal: &Nominal,
    measure: &PreisachMeasure,
    e: &Electro,
    currents_a: &[f64],
    step_s: f64,
    interp: CurrentBetweenSamples,
    start: &ModelStart,
    previous: Option<&Memory>,
    substeps: usize,
) -> ElectroRun {
    let s = substeps.max(1);
    let (m, i2, end) = electro_once(
        nominal, measure, e, currents_a, step_s, interp, start, previous, s,
    );
    ElectroRun {
        substeps: s,
        m_a_per_m: m,
        current_sq_a2: i2,
        end_memory: Box::new(end),
    }
}

/// Exact discretization of a linear system `x' = A x + B c` over a step `δ` with the input `c`
/// linear over it (first-order hold): `x(δ) = Φ x(0) + Γ₀ c(0) + Γ₁ (c(δ) − c(0))`.
///
/// `Φ, Γ₀, Γ₁` are blocks of `exp` of the augmented matrix `[[Aδ, Bδ, 0], [0, 0, 1], [0, 0, 0]]`
/// (state `[x, c, c(δ) − c(0)]` in the time `t/δ`), computed by nalgebra's Padé
/// scaling-and-squaring (Al-Mohy & Higham), accurate to a few ulps of the entries.
#[derive(Debug, Clone, Copy)]
#[doc(hidden)] // public for tests/internals.rs only
pub struct LinearStep<const N: usize> {
    phi: [[f64; N]; N],
    g0: [f64; N],
    g1: [f64; N],
}

impl<const N: usize> LinearStep<N> {
    fn new(a: [[f64; N]; N], b: [f64; N], delta: f64) -> Self {
        let mut aug = nalgebra::DMatrix::<f64>::zeros(N + 2, N + 2);
        for i in 0..N {
            for j in 0..N {
                aug[(i, j)] = a[i][j] * delta;
            }
            aug[(i, N)] = b[i] * delta;
        }
        aug[(N, N + 1)] = 1.0;
        let e = aug.exp();
        let mut step = LinearStep {
            phi: [[0.0; N]; N],
            g0: [0.0; N],
            g1: [0.0; N],
        };
        for i in 0..N {
            for j in 0..N {
                step.phi[i][j] = e[(i, j)];
            }
            step.g0[i] = e[(i, N)];
            step.g1[i] = e[(i, N + 1)];
        }
        step
    }

    pub fn step(&self, x: [f64; N], c0: f64, c1: f64) -> [f64; N] {
        let d = c1 - c0;
        let mut out = [0.0; N];
        for (i, o) in out.iter_mut().enumerate() {
            let mut acc = self.g0[i] * c0 + self.g1[i] * d;
            for (p, xj) in self.phi[i].iter().zip(x.iter()) {
                acc += p * xj;
            }
            *o = acc;
        }
        out
    }
}

/// Exact discretization of `x'' = ω²(c − x) − 2ζω x'` (state `[x, x']`) over a step `δ` with
/// `c` linear over it: the amplifier and the sensor low-pass.
#[doc(hidden)] // public for tests/internals.rs only
pub fn second_order(omega: f64, zeta: f64, delta: f64) -> LinearStep<2> {
    LinearStep::new(
        [[0.0, 1.0], [-omega * omega, -2.0 * zeta * omega]],
        [0.0, omega * omega],
        delta,
    )
}

/// The mechanical stage (module docs): the displacement the sensor reads at every sample time
/// (no offset), m. The same as [`observe`] of [`track_mech`].
pub fn run_mech(
    nominal: &Nominal,
    mech: &Mech,
    run: &ElectroRun,
    n_samples: usize,
    step_s: f64,
    theta0: (f64, f64),
) -> Vec<f64> {
    let track = track_mech(nominal, mech, run, n_samples, step_s, theta0);
    observe(mech, &track, n_samples, step_s)
}

/// The observed motion at every substep point of one run of the mechanical stage: the position
/// and rate of the rod (of the first load mass when there is a load), before the sensor.
#[derive(Debug, Clone)]
pub struct MechTrack {
    /// Substeps per sample.
    pub substeps: usize,
    /// Position at every substep point, m.
    pub pos_m: Vec<f64>,
    /// Rate at every substep point, m/s.
    pub rate_m_per_s: Vec<f64>,
}

impl Mech {
    /// The parameters [`track_mech`] depends on: the sensor and the channel skew switched off
    /// (they act on the track afterwards, in [`observe`]). Two parameter sets with the same
    /// key have the same track.
    pub fn track_key(&self) -> Mech {
        Mech {
            sensor: None,
            skew_samples: 0.0,
            ..*self
        }
    }
}

/// The rod and load integrated over the first `n_samples` samples of `run` (the part of
/// [`run_mech`] before the sensor; it does not depend on the sensor or the skew).
pub fn track_mech(
    nominal: &Nominal,
    mech: &Mech,
    run: &ElectroRun,
    n_samples: usize,
    step_s: f64,
    theta0: (f64, f64),
) -> MechTrack {
    let mut tracks = track_mech_lanes(nominal, &[*mech], run, n_samples, step_s, &[theta0]);
    tracks.pop().expect("one track per parameter set")
}

/// [`track_mech`] of several parameter sets on the same run, each with its starting temperature
/// (`theta0[i]` for `mechs[i]`), integrated side by side (see `mech_states`): the same tracks
/// as one at a time, in less time when the rod is nonlinear (ΔE).
pub fn track_mech_lanes(
    nominal: &Nominal,
    mechs: &[Mech],
    run: &ElectroRun,
    n_samples: usize,
    step_s: f64,
    theta0: &[(f64, f64)],
) -> Vec<MechTrack> {
    assert_eq!(mechs.len(), theta0.len(), "one start temperature per set");
    // The load's states exist only when it is switched on (a compile-time size: the rod alone
    // keeps two states, one load mode four; the states of an absent load would stay at rest
    // and only cost arithmetic). Sets of different sizes run in groups of their size.
    let states = |m: &Mech| {
        if m.second_load.is_some() {
            6
        } else if m.load.is_some() {
            4
        } else {
            2
        }
    };
    let mut tracks: Vec<Option<MechTrack>> = vec![None; mechs.len()];
    for n in [2, 4, 6] {
        let group: Vec<usize> = (0..mechs.len())
            .filter(|&i| states(&mechs[i]) == n)
            .collect();
        if group.is_empty() {
            continue;
        }
        let sets: Vec<&Mech> = group.iter().map(|&i| &mechs[i]).collect();
        let starts: Vec<(f64, f64)> = group.iter().map(|&i| theta0[i]).collect();
        let states = match n {
            6 => mech_states::<6>(nominal, &sets, run, n_samples, step_s, &starts),
            4 => mech_states::<4>(nominal, &sets, run, n_samples, step_s, &starts),
            _ => mech_states::<2>(nominal, &sets, run, n_samples, step_s, &starts),
        };
        for (&i, (pos_m, rate_m_per_s)) in group.iter().zip(states) {
            tracks[i] = Some(MechTrack {
                substeps: run.substeps,
                pos_m,
                rate_m_per_s,
            });
        }
    }
    tracks
        .into_iter()
        .map(|t| t.expect("every set is in one group"))
        .collect()
}

/// The sensor's reading of `track` at the first `n_samples` sample times (the part of
/// [`run_mech`] after the rod and load).
pub fn observe(mech: &Mech, track: &MechTrack, n_samples: usize, step_s: f64) -> Vec<f64> {
    observe_with_sensor(
        mech,
        &track.pos_m,
        &track.rate_m_per_s,
        n_samples,
        step_s,
        track.substeps,
    )
}

/// The rod and load integrated over every substep of `run`: the observed position and rate at
/// each substep point. State `[y1, v1]` (the rod) with `N = 2`, `[y1, v1, y2, v2]` (rod, first
/// load mass) with `N = 4`, and with `N = 6` the second load mass `[y3, v3]` hanging on the
/// first.
///
/// Several parameter sets on the same run (`mechs`, each with its starting temperature in
/// `theta0`) advance side by side, one substep point at a time; those with ΔE in groups of up
/// to four with the same `sub`, their RK4 stages interleaved ([`rk4_substep_lanes`]). Each is
/// the integration it would be alone, bit for bit, but one alone waits on each stage's result
/// (a chain of dependent multiplications), which four independent chains fill: the Jacobian's
/// mechanical columns ([`track_mech_lanes`]) of a ΔE and load pair on another simulator's
/// dataset took 26.0 s of its diagnosis one by one, 19.3 s in groups of four, 20.7 s in groups
/// of eight (the states no longer fit the registers).
fn mech_states<const N: usize>(
    nominal: &Nominal,
    mechs: &[&Mech],
    run: &ElectroRun,
    n_samples: usize,
    step_s: f64,
    theta0: &[(f64, f64)],
) -> Vec<(Vec<f64>, Vec<f64>)> {
    let delta = step_s / run.substeps as f64;
    let m0 = run.m_a_per_m[0];
    // A run may be longer than the samples asked for (a chained experiment is simulated whole).
    let total = run.m_a_per_m.len().min(1 + n_samples * run.substeps);
    let mut lanes: Vec<Lane<N>> = mechs
        .iter()
        .zip(theta0)
        .map(|(mech, &theta0)| Lane::at_rest(Rod::new(nominal, mech, delta), theta0, m0, total))
        .collect();
    // The nonlinear lanes (ΔE) in groups of up to four with the same `sub`; the linear ones
    // one by one (a matrix-vector product each).
    let mut groups: Vec<Vec<usize>> = Vec::new();
    for (i, lane) in lanes.iter().enumerate() {
        if lane.rod.linear.is_some() {
            continue;
        }
        match groups
            .iter_mut()
            .find(|g| g.len() < 4 && lanes[g[0]].rod.sub == lane.rod.sub)
        {
            Some(g) => g.push(i),
            None => groups.push(vec![i]),
        }
    }
    for j in 1..total {
        for lane in lanes.iter_mut().filter(|l| l.rod.linear.is_some()) {
            lane.advance_linear(run, j);
        }
        for g in &groups {
            match g.len() {
                1 => advance_group::<N, 1>(&mut lanes, g, run, j),
                2 => advance_group::<N, 2>(&mut lanes, g, run, j),
                3 => advance_group::<N, 3>(&mut lanes, g, run, j),
                _ => advance_group::<N, 4>(&mut lanes, g, run, j),
            }
        }
    }
    lanes.into_iter().map(|l| (l.pos, l.rate)).collect()
}

/// One parameter set's rod (and load) on substeps of `δ`: the constants of its RK4 substep,
/// read once from a [`Mech`].
struct Rod<const N: usize> {
    /// Mechanical sub-substeps per substep, their length `δ/sub`, and `1/sub`.
    sub: usize,
    dm: f64,
    inv_sub: f64,
    /// `2 ζ ω0` and `ω0²`.
    damp: f64,
    om0_sq: f64,
    inv_stroke: f64,
    inv_ms2: f64,
    /// `l_m λ_s / M_s²`.
    k_u: f64,
    /// Each load mode as `(mass ratio, ω², 2 ζ ω)`.
    load: Option<(f64, f64, f64)>,
    second: Option<(f64, f64, f64)>,
    delta_e: Option<(f64, f64, f64, f64)>,
    /// `(coil decay, rod decay, gain loss, expansion · stroke)` per substep.
    thermal: Option<(f64, f64, f64, f64)>,
    /// Without ΔE, the substep as its matrix (see [`Rod::new`]).
    linear: Option<LinearStep<N>>,
}

impl<const N: usize> Rod<N> {
    fn new(nominal: &Nominal, mech: &Mech, delta: f64) -> Self {
        let om0 = 2.0 * PI * mech.resonance_hz;
        let damp = 2.0 * mech.damping_ratio * om0;
        let mode = |(r, f, z): (f64, f64, f64)| {
            let w = 2.0 * PI * f;
            (r, w * w, 2.0 * z * w)
        };
        let load = if N >= 4 { mech.load.map(mode) } else { None };
        let second = if N == 6 {
            mech.second_load.map(mode)
        } else {
            None
        };
        // Mechanical sub-substeps so that RK4 resolves the fastest mode, oscillatory or damped
        // (rate · δ_m ≤ 0.5).
        let mut rate_max = om0
            * (1.0
                + mech.delta_e.map_or(0.0, |(a, b, c, e)| {
                    a.max(0.0) + b.max(0.0) + c.max(0.0) + e.abs()
                }))
            .sqrt();
        rate_max = rate_max.max(damp);
        if let Some((r, w2, c2)) = load {
            rate_max = rate_max.max((w2 * (1.0 + r)).sqrt()).max(c2 * (1.0 + r));
            // With the second mass on the first: Gershgorin's bound on the chain's stiffness
            // and damping rows (per unit mass).
            if let Some((r3, w3, c3)) = second {
                rate_max = rate_max
                    .max((2.0 * (w2 + r3 * w3)).sqrt())
                    .max((2.0 * w3).sqrt())
                    .max(2.0 * (c2 + r3 * c3))
                    .max(2.0 * c3);
            }
        }
        let sub = ((rate_max * delta / 0.5).ceil() as usize).clamp(1, 10_000);
        let thermal = mech.thermal.map(|(tau, lag, g, e)| {
            (
                (-delta / tau).exp(),
                (-delta / lag).exp(),
                g,
                e * nominal.stroke_m,
            )
        });
        let mut rod = Rod {
            sub,
            dm: delta / sub as f64,
            inv_sub: 1.0 / sub as f64,
            damp,
            om0_sq: om0 * om0,
            inv_stroke: 1.0 / nominal.stroke_m.max(1e-12),
            inv_ms2: 1.0 / (nominal.saturation_a_per_m * nominal.saturation_a_per_m),
            k_u: nominal.displacement_per_m2_m,
            load,
            second,
            delta_e: mech.delta_e,
            thermal,
            linear: None,
        };
        // Without ΔE the rod and load are linear and time-invariant, so the RK4 substep is an
        // affine map of the state and the two end values of `u`: its matrix is read once by
        // stepping the unit vectors, and every substep is then one matrix-vector product — the
        // same integrator, about 2.5x cheaper (the mechanical stage was half of a diagnosis'
        // time).
        if rod.delta_e.is_none() {
            let mut phi = [[0.0; N]; N];
            for i in 0..N {
                let mut e = [0.0; N];
                e[i] = 1.0;
                let column = rod.rk4_substep(e, 0.0, 0.0, 0.0, 0.0);
                for (r, c) in column.iter().enumerate() {
                    phi[r][i] = *c;
                }
            }
            let from_prev = rod.rk4_substep([0.0; N], 1.0, 0.0, 0.0, 0.0);
            let from_next = rod.rk4_substep([0.0; N], 0.0, 1.0, 0.0, 0.0);
            rod.linear = Some(LinearStep {
                phi,
                g0: std::array::from_fn(|r| from_prev[r] + from_next[r]),
                g1: from_next,
            });
        }
        rod
    }

    /// The rod's drive `u` at magnetization `m` and rod temperature `φ`.
    fn u_of(&self, m: f64, phi: f64) -> f64 {
        match self.thermal {
            // The gain is the fraction of λ_s the warm rod keeps: it cannot fall below zero.
            Some((_, _, g, e)) => (1.0 - g * phi).max(0.0) * self.k_u * m * m + e * phi,
            None => self.k_u * m * m,
        }
    }

    /// ΔE: the stiffness depends on the magnetization and on the stress (the elastic strain
    /// (y − u)/stroke), so it is evaluated inside the mechanical step. Its magnetization part
    /// `1 + d₁ r + d₂ r² + d₃ r³` (r = m²/M_s²) depends on the input only: it is evaluated once
    /// per point of the substep (here), the stress part per RK4 stage ([`Rod::om2_of`]).
    /// (Reciprocals instead of divisions: the two divisions per stage were a fifth of a
    /// diagnosis' time on an out-of-library case.)
    fn stiffening(&self, m: f64) -> f64 {
        match self.delta_e {
            Some((d1, d2, d3, _)) => {
                let r = m * m * self.inv_ms2;
                1.0 + r * (d1 + r * (d2 + r * d3))
            }
            None => 1.0,
        }
    }

    fn om2_of(&self, stiffening: f64, strain: f64) -> f64 {
        match self.delta_e {
            Some((_, _, _, d_stress)) => self.om0_sq * (stiffening + d_stress * strain).max(0.05),
            None => self.om0_sq,
        }
    }

    /// The state's time derivative at `x`, with the rod's drive `u` and the magnetization's
    /// stiffening `st`.
    fn derivative(&self, x: &[f64; N], u: f64, st: f64) -> [f64; N] {
        let mut d = [0.0; N];
        let om2 = self.om2_of(st, (x[0] - u) * self.inv_stroke);
        d[0] = x[1];
        d[1] = -self.damp * x[1] - om2 * (x[0] - u);
        if let Some((r, w2, c2)) = self.load {
            let coupling = w2 * (x[0] - x[2]) + c2 * (x[1] - x[3]);
            d[1] -= r * coupling;
            d[2] = x[3];
            d[3] = coupling;
            if let Some((r3, w3, c3)) = self.second {
                let coupling3 = w3 * (x[2] - x[4]) + c3 * (x[3] - x[5]);
                d[3] -= r3 * coupling3;
                d[4] = x[5];
                d[5] = coupling3;
            }
        }
        d
    }

    /// One substep of RK4 (`sub` steps of `δ/sub`) from `x`, `u` and `M` linear over it.
    fn rk4_substep(&self, x: [f64; N], u_prev: f64, u_next: f64, m_a: f64, m_b: f64) -> [f64; N] {
        let [x] = rk4_substep_lanes(&[self], [x], [u_prev], [u_next], m_a, m_b);
        x
    }
}

/// [`Rod::rk4_substep`] of `L` rods with the same `sub` (and so the same `δ/sub`), stage by
/// stage across the rods: the arithmetic of each is that of one alone, but the `L` chains of
/// dependent stages run interleaved, where one alone waits on each stage's result.
fn rk4_substep_lanes<const N: usize, const L: usize>(
    rods: &[&Rod<N>; L],
    x: [[f64; N]; L],
    u_prev: [f64; L],
    u_next: [f64; L],
    m_a: f64,
    m_b: f64,
) -> [[f64; N]; L] {
    let mut x = x;
    let shifted = |x: &[f64; N], k: &[f64; N], h: f64| -> [f64; N] {
        std::array::from_fn(|i| x[i] + h * k[i])
    };
    let (sub, dm, inv_sub) = (rods[0].sub, rods[0].dm, rods[0].inv_sub);
    debug_assert!(rods.iter().all(|r| r.sub == sub));
    let hd = 0.5 * dm;
    let d6 = dm / 6.0;
    let point = |f: f64| -> [(f64, f64); L] {
        std::array::from_fn(|l| {
            (
                u_prev[l] + (u_next[l] - u_prev[l]) * f,
                rods[l].stiffening(m_a + (m_b - m_a) * f),
            )
        })
    };
    let mut start = point(0.0);
    for q in 0..sub {
        let half = point((q as f64 + 0.5) * inv_sub);
        let end = point((q as f64 + 1.0) * inv_sub);
        let k1: [[f64; N]; L] =
            std::array::from_fn(|l| rods[l].derivative(&x[l], start[l].0, start[l].1));
        let k2: [[f64; N]; L] = std::array::from_fn(|l| {
            rods[l].derivative(&shifted(&x[l], &k1[l], hd), half[l].0, half[l].1)
        });
        let k3: [[f64; N]; L] = std::array::from_fn(|l| {
            rods[l].derivative(&shifted(&x[l], &k2[l], hd), half[l].0, half[l].1)
        });
        let k4: [[f64; N]; L] = std::array::from_fn(|l| {
            rods[l].derivative(&shifted(&x[l], &k3[l], dm), end[l].0, end[l].1)
        });
        for l in 0..L {
            for i in 0..N {
                x[l][i] += d6 * (k1[l][i] + 2.0 * k2[l][i] + 2.0 * k3[l][i] + k4[l][i]);
            }
        }
        start = end;
    }
    x
}

/// One parameter set's integration in progress: its rod, state, temperatures, the drive at the
/// last point, and the observed motion so far.
struct Lane<const N: usize> {
    rod: Rod<N>,
    x: [f64; N],
    theta: f64,
    phi: f64,
    u_prev: f64,
    /// The observed mass's position index in `x` (the first load mass when there is a load:
    /// the sensor sits on it).
    observed: usize,
    pos: Vec<f64>,
    rate: Vec<f64>,
}

impl<const N: usize> Lane<N> {
    /// At rest at the drive's initial displacement: every mass at `u0`, no velocity.
    fn at_rest(rod: Rod<N>, theta0: (f64, f64), m0: f64, total: usize) -> Self {
        let (theta, phi) = if rod.thermal.is_some() {
            theta0
        } else {
            (0.0, 0.0)
        };
        let u0 = rod.u_of(m0, phi);
        let x: [f64; N] = std::array::from_fn(|i| if i % 2 == 0 { u0 } else { 0.0 });
        let observed = if rod.load.is_some() { 2 } else { 0 };
        let mut pos = Vec::with_capacity(total);
        let mut rate = Vec::with_capacity(total);
        pos.push(x[observed]);
        rate.push(x[observed + 1]);
        Lane {
            rod,
            x,
            theta,
            phi,
            u_prev: u0,
            observed,
            pos,
            rate,
        }
    }

    /// The coil and rod temperatures over substep `j − 1` of `run` (when the rod heats), and the
    /// drive at point `j`.
    fn heat(&mut self, run: &ElectroRun, j: usize) -> f64 {
        if let Some((decay, lag_decay, _, _)) = self.rod.thermal {
            let i2 = run.current_sq_a2[j - 1];
            let before = self.theta;
            self.theta = i2 + (self.theta - i2) * decay;
            self.phi =
                0.5 * (before + self.theta) + (self.phi - 0.5 * (before + self.theta)) * lag_decay;
        }
        self.rod.u_of(run.m_a_per_m[j], self.phi)
    }

    /// The state `x` at the next point, reached with the drive `u_next`.
    fn record(&mut self, x: [f64; N], u_next: f64) {
        self.x = x;
        self.u_prev = u_next;
        self.pos.push(x[self.observed]);
        self.rate.push(x[self.observed + 1]);
    }

    /// From substep point `j − 1` of `run` to point `j` with the linear map (no ΔE; a lane with
    /// ΔE is advanced by [`advance_group`]).
    fn advance_linear(&mut self, run: &ElectroRun, j: usize) {
        let u_next = self.heat(run, j);
        if let Some(map) = &self.rod.linear {
            let x = map.step(self.x, self.u_prev, u_next);
            self.record(x, u_next);
        }
    }
}

/// The lanes `group` (`L` of them, ΔE, the same `sub`) from substep point `j − 1` of `run` to
/// point `j`, their RK4 stages interleaved ([`rk4_substep_lanes`]).
fn advance_group<const N: usize, const L: usize>(
    lanes: &mut [Lane<N>],
    group: &[usize],
    run: &ElectroRun,
    j: usize,
) {
    let at: [usize; L] = std::array::from_fn(|l| group[l]);
    let u_next: [f64; L] = std::array::from_fn(|l| lanes[at[l]].heat(run, j));
    let u_prev: [f64; L] = std::array::from_fn(|l| lanes[at[l]].u_prev);
    let x: [[f64; N]; L] = std::array::from_fn(|l| lanes[at[l]].x);
    let rods: [&Rod<N>; L] = std::array::from_fn(|l| &lanes[at[l]].rod);
    let next = rk4_substep_lanes(
        &rods,
        x,
        u_prev,
        u_next,
        run.m_a_per_m[j - 1],
        run.m_a_per_m[j],
    );
    for l in 0..L {
        lanes[at[l]].record(next[l], u_next[l]);
    }
}

/// The sensor's reading of the observed motion at every sample time: its low-pass (when
/// switched on), delay and the channel skew.
fn observe_with_sensor(
    mech: &Mech,
    pos: &[f64],
    rate: &[f64],
    n_samples: usize,
    step_s: f64,
    substeps: usize,
) -> Vec<f64> {
    let total = pos.len();
    let delta = step_s / substeps as f64;
    // Sensor low-pass (exact for its input linear over a substep; the rate of the input is
    // the observed rate).
    let (out, out_rate) = match mech.sensor {
        Some((f, zeta, _)) => {
            let lp = second_order(2.0 * PI * f, zeta, delta);
            let mut x = [pos[0], 0.0];
            let mut o = Vec::with_capacity(total);
            let mut orate = Vec::with_capacity(total);
            o.push(x[0]);
            orate.push(x[1]);
            for j in 1..total {
                x = lp.step(x, pos[j - 1], pos[j]);
                o.push(x[0]);
                orate.push(x[1]);
            }
            (Cow::Owned(o), Cow::Owned(orate))
        }
        None => (Cow::Borrowed(pos), Cow::Borrowed(rate)),
    };
    let delay_s = mech.sensor.map_or(0.0, |s| s.2);
    (0..n_samples)
        .map(|k| {
            hermite(
                &out,
                &out_rate,
                delta,
                k as f64 * step_s + mech.skew_samples * step_s - delay_s,
            )
        })
        .collect()
}

/// Cubic Hermite interpolation of `(value, rate)` samples spaced `delta`, at time `t` (clamped
/// to the sampled span).
#[doc(hidden)] // public for tests/internals.rs only
pub fn hermite(value: &[f64], rate: &[f64], delta: f64, t: f64) -> f64 {
    let last = value.len() - 1;
    let pos = (t / delta).clamp(0.0, last as f64);
    let i = (pos.floor() as usize).min(last.saturating_sub(1));
    if last == 0 {
        return value[0];
    }
    let u = pos - i as f64;
    let (p0, p1) = (value[i], value[i + 1]);
    let (m0, m1) = (rate[i] * delta, rate[i + 1] * delta);
    let u2 = u * u;
    let u3 = u2 * u;
    (2.0 * u3 - 3.0 * u2 + 1.0) * p0
        + (u3 - 2.0 * u2 + u) * m0
        + (-2.0 * u3 + 3.0 * u2) * p1
        + (u3 - u2) * m1
}

/// Convenience: the whole model on one current (no offset), m.
#[allow(clippy::too_many_arguments)]
pub fn simulate(
    nominal: &Nominal,
    measure: &PreisachMeasure,
    electro: &Electro,
    mech: &Mech,
    currents_a: &[f64],
    step_s: f64,
    interp: CurrentBetweenSamples,
    start: &ModelStart,
    substeps: usize,
) -> Vec<f64> {
    let run = run_electro(
        nominal, measure, electro, currents_a, step_s, interp, start, None, substeps,
    );
    run_mech(nominal, mech, &run, currents_a.len(), step_s, (0.0, 0.0))
}

/// The thermal state `(θ, φ)` (A²) at the start of an experiment whose predecessors `history`
/// (oldest first) ran without a pause since a cold start: the coil and rod equations through
/// their currents (a held command's square over each sample).
pub fn chained_temperature(mech: &Mech, history: &[&[f64]], step_s: f64) -> (f64, f64) {
    let Some((tau, lag, _, _)) = mech.thermal else {
        return (0.0, 0.0);
    };
    let decay = (-step_s / tau).exp();
    let lag_decay = (-step_s / lag).exp();
    let (mut theta, mut phi) = (0.0, 0.0);
    for currents in history {
        for &i in currents.iter() {
            let before = theta;
            theta = i * i + (theta - i * i) * decay;
            phi = 0.5 * (before + theta) + (phi - 0.5 * (before + theta)) * lag_decay;
        }
    }
    (theta, phi)
}
