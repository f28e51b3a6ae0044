//! The diagnosis model: the nominal model (paper eqs (4)-(5)) with optional augmentations, one
//! per candidate effect, and the nuisances of a recording, simulated on a measured current.
//!
//! It runs in two stages so that a fit can reuse the expensive one:
//!
//! 1. **Electromagnetic stage** ([`run_electro`]; parameters [`Electro`]): command → coil current
//!    (held or linear between samples; `amplifier_bandwidth`: a current loop around the coil,
//!    [`CurrentLoop`], whose command response filters it and whose EMF term joins `Z`) → eddy
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

use crate::fit::ModelSetup;
use magctl::preisach::{PreisachMeasure, PreisachState};
use maglab_dataset::{CurrentBetweenSamples, StartState};
use std::borrow::Cow;
use std::f64::consts::PI;

mod current_loop;
mod rod;
pub use current_loop::CurrentLoop;
pub use rod::{track_mech, track_mech_lanes};

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
    /// The current loop ([`CurrentLoop`]): `(natural frequency Hz, damping ratio, coil time
    /// constant τ_L s)`; at `τ_L = 0` a second-order low-pass on the current.
    pub amplifier: Option<(f64, f64, f64)>,
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

/// What one run of the electromagnetic stage is driven by and starts from.
#[derive(Debug, Clone, Copy)]
pub struct ElectroDrive<'a> {
    /// The coil current per sample, A: the command, or the measured coil current.
    pub currents_a: &'a [f64],
    /// The experiment's start.
    pub start: &'a ModelStart,
    /// The memory the previous experiment of a chain left, for a chained start.
    pub previous: Option<&'a Memory>,
}

/// One electromagnetic run with `s` substeps per sample (`setup`'s own substeps are not used):
/// `(M at substep ends, mean I², end memory)`.
fn electro_once(
    setup: &ModelSetup<'_>,
    e: &Electro,
    drive: ElectroDrive<'_>,
    s: usize,
) -> (Vec<f64>, Vec<f64>, Memory) {
    // The second eddy path is a compile-time switch: as a run-time one it cost the substep loop
    // of every other model about 18 % of a diagnosis' time (measured on the blind suite).
    // So is the current loop's EMF term (an amplifier with `τ_L > 0`; at `τ_L = 0` the loop only
    // filters the command).
    let emf = matches!(e.amplifier, Some((_, _, tau_l)) if tau_l > 0.0);
    let run = match (e.second_eddy_path.is_some(), emf) {
        (false, false) => electro_steps::<false, false>,
        (true, false) => electro_steps::<true, false>,
        (false, true) => electro_steps::<false, true>,
        (true, true) => electro_steps::<true, true>,
    };
    run(setup, e, drive, s)
}

/// The eddy step's constants for substeps of `δ` (module docs): the implicit side's drive
/// `δ/(κ Z_hf + Z_loop)` (`Z_loop` the current loop's EMF impedance) and each extra path's
/// `(τ, ΔZ)` with the share `τ/(τ + δ)` of its state a substep keeps.
struct EddyStep {
    drive: f64,
    paths: [Option<(f64, f64)>; 2],
    keeps: [f64; 2],
}

impl EddyStep {
    fn new(nominal: &Nominal, e: &Electro, loop_impedance: f64, delta: f64) -> Self {
        let z_dc = nominal.mu0_n_a / e.eddy_resistance_ohm.max(1e-9);
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
        let keep = |p: Option<(f64, f64)>| p.map_or(0.0, |(tau, _)| tau / (tau + delta));
        EddyStep {
            drive: delta / (kappa * z_hf + loop_impedance),
            paths,
            keeps: [keep(paths[0]), keep(paths[1])],
        }
    }
}

/// The coil current over one substep with the command going linearly from `u0` to `u1`: through
/// the current loop's command response when there is an amplifier (advancing its state `x`),
/// the command itself otherwise. Returns its mean and mean square over the substep (exact for
/// a current linear over it).
fn substep_current(
    amplifier: Option<&CurrentLoop>,
    x: &mut [f64; 2],
    u0: f64,
    u1: f64,
) -> (f64, f64) {
    let (before, after) = match amplifier {
        Some(l) => {
            let before = l.output(*x);
            *x = l.advance(*x, u0, u1);
            (before, l.output(*x))
        }
        None => (u0, u1),
    };
    (
        0.5 * (before + after),
        (before * before + before * after + after * after) / 3.0,
    )
}

/// [`electro_once`] with or without the second eddy path's state and the current loop's EMF
/// term ([`CurrentLoop`]; `EMF` only when `τ_L > 0`, where the term is not zero).
fn electro_steps<const SECOND_PATH: bool, const EMF: bool>(
    setup: &ModelSetup<'_>,
    e: &Electro,
    drive: ElectroDrive<'_>,
    s: usize,
) -> (Vec<f64>, Vec<f64>, Memory) {
    let ModelSetup {
        nominal,
        measure,
        step_s,
        interpolation: interp,
        ..
    } = *setup;
    let ElectroDrive {
        currents_a,
        start,
        previous,
    } = drive;
    let n = currents_a.len();
    let delta = step_s / s as f64;
    let c0 = nominal.c0_per_m;
    // The amplifier: its command response `T` and, with `EMF`, its EMF filter ([`CurrentLoop`]).
    let amplifier = e
        .amplifier
        .map(|(f, zeta, tau_l)| CurrentLoop::new(f, zeta, tau_l, c0, delta));
    let loop_impedance = match (EMF, &amplifier) {
        (true, Some(l)) => l.implicit_impedance(),
        _ => 0.0,
    };
    let eddy = EddyStep::new(nominal, e, loop_impedance, delta);
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
    let mut amp_state = amplifier.map_or([0.0; 2], |l| l.rest(i_start));
    let mut emf_state = [0.0f64; 2];
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
            let (i_mean, i2) = substep_current(amplifier.as_ref(), &mut amp_state, u0, u1);
            let (mrev, chi) = rev_at_h;
            // w_rev = (1 + χ) H + Γ(H) with the reversible part linearized at H.
            let gamma = m - mrev;
            let eddy_current = if SECOND_PATH {
                eddy.keeps[0] * q + eddy.keeps[1] * second_q
            } else {
                eddy.keeps[0] * q
            };
            let loop_current = match (EMF, &amplifier) {
                (true, Some(l)) => l.explicit_current(emf_state),
                _ => 0.0,
            };
            let rhs = (1.0 + chi) * h + gamma + eddy.drive * (i_mean - eddy_current + loop_current);
            let slope = (1.0 + chi + eddy.drive / c0) as f32;
            let (h_new, g_new) = match measure.solve(&mut memory, slope, rhs as f32) {
                Ok(sol) => (sol.h_a_per_m as f64, sol.m_a_per_m as f64),
                Err(_) => (h, gamma),
            };
            rev_at_h = reversible(e.reversible, h_new);
            let w_change = (h_new - h) + (g_new - gamma) + (rev_at_h.0 - mrev);
            if let Some((tau, dz)) = eddy.paths[0] {
                q = (tau * q + dz * w_change) / (tau + delta);
            }
            if let (true, Some((tau, dz))) = (SECOND_PATH, eddy.paths[1]) {
                second_q = (tau * second_q + dz * w_change) / (tau + delta);
            }
            // The EMF current the loop leaves, constant over the substep (backward Euler):
            // `E[(i − g)²] = E[i²] − 2 g E[i] + g²`.
            let i2 = match (EMF, &amplifier) {
                (true, Some(l)) => {
                    let w_rate = w_change / delta;
                    let g = l.emf_current(emf_state, w_rate);
                    emf_state = l.advance(emf_state, w_rate, w_rate);
                    i2 - 2.0 * g * i_mean + g * g
                }
                _ => i2,
            };
            h = h_new;
            m = g_new + rev_at_h.0;
            m_out.push(m);
            i2_out.push(i2);
        }
    }
    (m_out, i2_out, memory)
}

/// The electromagnetic stage (module docs): Richardson combination of runs with
/// `setup.substeps` and twice as many substeps per sample (the coarse one is
/// [`run_electro_single`]'s).
pub fn run_electro(setup: &ModelSetup<'_>, e: &Electro, drive: ElectroDrive<'_>) -> ElectroRun {
    let coarse = run_electro_single(setup, e, drive);
    let (fine, _, end) = electro_once(setup, e, drive, 2 * coarse.substeps);
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

/// The electromagnetic stage from one run with `setup.substeps` substeps per sample, without
/// the Richardson pair: first order in the step, about a third of [`run_electro`]'s cost. Only
/// the fit's Jacobian uses it (`crate::fit`'s module docs): a slope, never a residual.
pub fn run_electro_single(
    setup: &ModelSetup<'_>,
    e: &Electro,
    drive: ElectroDrive<'_>,
) -> ElectroRun {
    let s = setup.substeps.max(1);
    let (m, i2, end) = electro_once(setup, e, drive, s);
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
/// `c` linear over it: the sensor's low-pass.
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
pub fn simulate(
    setup: &ModelSetup<'_>,
    electro: &Electro,
    mech: &Mech,
    currents_a: &[f64],
    start: &ModelStart,
) -> Vec<f64> {
    let drive = ElectroDrive {
        currents_a,
        start,
        previous: None,
    };
    let run = run_electro(setup, electro, drive);
    run_mech(
        setup.nominal,
        mech,
        &run,
        currents_a.len(),
        setup.step_s,
        (0.0, 0.0),
    )
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
