//! Simulation of one dynamic experiment with the core's f32 model (4)-(5)
//! (`magctl::model::DynamicModel`), driven by the *measured* current samples, on the measurement's
//! time base.
//!
//! * **Initial conditions** ([`DYNAMIC_STARTS`]): the experiment starts at rest, in equilibrium under its
//!   first current, reached from the given Preisach memory (default: AC-demagnetized, the core's
//!   documented demagnetized state — what `maglab rig` does). The paper insists the simulated
//!   initial state be the experiment's: the memory left outside the periodic minor loop sets a
//!   constant offset of `M`, hence of the `M²` gain.
//! * **Current between samples** ([`CurrentBetweenSamples`]): `Hold` when the file records a
//!   command held over each sample (a DAC; `maglab rig`), `Linear` when it records samples of a
//!   continuous current (a current probe): the current is interpolated linearly between samples.
//!   Getting this wrong shifts the input by half a sample: `π f h` rad, 3.6° at 200 Hz and 10 kHz.
//! * **Substeps**: each sample interval is split into `n = ceil(h / max_substep_s)` model steps.
//!   The eddy step is backward Euler (first order, see `magctl::model::eddy`): on a mode with time
//!   constant `τ` it behaves like `τ + δ/2` for a step `δ`. The slow mode of (4) has
//!   `τ = (1 + χ) c0 / c1` (χ = dM/dH); with the paper's `c1/c0 ≈ 10⁵ /s` and `χ ≈ 50` on the
//!   DC-biased loops, `τ ≈ 0.5 ms`, so `δ = 5 µs` biases `τ` (and the identified `R_eddy`) by
//!   ≈ 0.5 %. The magnetoelastic step is exact for `M²` linear over a step.
//!
//! Sample `k` of the output is the state at `t_k`, before the current of sample `k` acts (the
//! measurement's alignment: `y[0]` is the initial equilibrium).

use actuator_params::ActuatorParams;
use magctl::model::DynamicModel;
use magctl::params::{Actuator, ActuatorParameters};
use magctl::preisach::{PreisachMeasure, PreisachState, DEFAULT_CAPACITY};
use maglab_dataset::data::Measurement;
use maglab_dataset::{CurrentBetweenSamples, StartState};

/// The start states the phase-lag scheme's simulation reproduces: at rest under the first
/// current, reached from demagnetization or saturation.
pub const DYNAMIC_STARTS: [StartState; 3] = [
    StartState::Demagnetized,
    StartState::NegativeSaturation,
    StartState::PositiveSaturation,
];

/// The Preisach memory `start` leaves before the move to the first current (one of
/// [`DYNAMIC_STARTS`]; any other starts demagnetized).
fn start_memory(start: StartState, measure: &PreisachMeasure) -> PreisachState<DEFAULT_CAPACITY> {
    match start {
        StartState::NegativeSaturation => measure.negative_saturation(),
        StartState::PositiveSaturation => measure.positive_saturation(),
        _ => measure.demagnetized_at(0.0),
    }
}

/// The three dynamic parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DynamicParams {
    /// R_eddy, Ω.
    pub eddy_resistance_ohm: f64,
    /// ξ.
    pub damping_ratio: f64,
    /// f0, Hz.
    pub resonance_hz: f64,
}

impl DynamicParams {
    /// The values of a parameter file.
    pub fn of(params: &ActuatorParams) -> Self {
        DynamicParams {
            eddy_resistance_ohm: params.actuator.eddy_resistance_ohm,
            damping_ratio: params.actuator.damping_ratio,
            resonance_hz: params.actuator.resonance_hz,
        }
    }
}

/// The core's f32 actuator constants `base` with the dynamic parameters replaced.
pub fn core_actuator(base: &Actuator, p: &DynamicParams) -> Actuator {
    Actuator {
        resonance_hz: p.resonance_hz as f32,
        eddy_resistance_ohm: p.eddy_resistance_ohm as f32,
        damping_ratio: p.damping_ratio as f32,
        ..*base
    }
}

/// The core's f32 parameters of `params` (the narrowing `build.rs` applies).
pub fn core_params(params: &ActuatorParams) -> Result<ActuatorParameters, super::DynamicError> {
    ActuatorParameters::from_file(params, "base parameters")
        .map_err(|e| super::DynamicError(e.to_string()))
}

/// How to simulate an experiment.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimulationOptions {
    /// Initial memory.
    pub start: StartState,
    /// Current between samples.
    pub current: CurrentBetweenSamples,
    /// Longest model step, s (see the module docs).
    pub max_substep_s: f64,
}

impl Default for SimulationOptions {
    fn default() -> Self {
        SimulationOptions {
            start: StartState::Demagnetized,
            current: CurrentBetweenSamples::Linear,
            max_substep_s: 5e-6,
        }
    }
}

/// Model steps per sample interval for `step_s`.
pub fn substeps(step_s: f64, options: &SimulationOptions) -> usize {
    ((step_s / options.max_substep_s).ceil() as usize).max(1)
}

/// A simulated experiment, on the measurement's samples.
#[derive(Debug, Clone, PartialEq)]
pub struct Simulated {
    /// Magnetization, A/m.
    pub m_a_per_m: Vec<f64>,
    /// Displacement, m.
    pub displacement_m: Vec<f64>,
}

/// Simulates `measurement`'s current through (4)-(5) with `measure`, the constants `base` and
/// the dynamic parameters `p`.
pub fn simulate(
    measure: &PreisachMeasure,
    base: &Actuator,
    p: &DynamicParams,
    measurement: &Measurement,
    options: &SimulationOptions,
) -> Simulated {
    let actuator = core_actuator(base, p);
    let n = substeps(measurement.step_s, options);
    let model = DynamicModel::new(measure, &actuator, (measurement.step_s / n as f64) as f32);
    let current = &measurement.current_a;
    let mut state = model.equilibrium(start_memory(options.start, measure), current[0] as f32);
    let mut m_a_per_m = Vec::with_capacity(current.len());
    let mut displacement_m = Vec::with_capacity(current.len());
    m_a_per_m.push(state.m_a_per_m as f64);
    displacement_m.push(state.displacement_m as f64);
    for k in 0..current.len() - 1 {
        let (i0, i1) = (current[k], current[k + 1]);
        for s in 0..n {
            let i = match options.current {
                CurrentBetweenSamples::Hold => i0,
                // The substep holds the interpolated current at its midpoint (second order).
                CurrentBetweenSamples::Linear => i0 + (s as f64 + 0.5) / n as f64 * (i1 - i0),
            };
            model.step(&mut state, i as f32);
        }
        m_a_per_m.push(state.m_a_per_m as f64);
        displacement_m.push(state.displacement_m as f64);
    }
    Simulated {
        m_a_per_m,
        displacement_m,
    }
}
