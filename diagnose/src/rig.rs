//! The virtual test rig (`maglab rig`): runs the f64 reference plant with effects
//! ([`host_tests::reference::rig`]) on sine sweeps with DC bias and Van der Pol tracking runs,
//! passes the sampled displacement through the sensor chain (backlash, low-pass, delay, noise,
//! quantization) and writes a dataset in the measurement format (`t_s,current_a,displacement_m`).
//!
//! What the rig records as `current_a` is the *command* (what the controller sends to the
//! amplifier), as a rig whose current is not measured separately would; the coil current itself
//! lags it when `amplifier_bandwidth` is on. Every experiment starts from the AC-demagnetized
//! memory at equilibrium under its first current, at ambient temperature (the rig waits for the
//! coil to cool between experiments).
//!
//! Experiments run in parallel (rayon); the noise of experiment `k` uses seed `seed + k`, so a
//! dataset is reproducible.
//!
//! **Hysteresis of the rig.** The parameter file defines a Preisach measure with a density
//! uniform per grid cell. By default the rig evaluates it exactly (the core's Everett-table
//! operator, [`ExactHysteresis`]), so that a rig without effects *is* the nominal model up to
//! time discretization and the diagnosis sees only the effects switched on. The relay field of
//! `host_tests::reference::preisach` (`relay_subdivision = k > 0`) is an independent
//! discretization of the same measure, but its error is frozen at every reversal point (a relay
//! row cut by the memory curve counts fully on or off): on a minor loop of amplitude `A` cells it
//! shifts the loop's level by up to about `1 / (k A)` of its swing, measured 1-4 % of the motion
//! for 0.2 A sines at k = 32 and 0.3-1.7 % at k = 64, far above a sensor's noise, and the
//! diagnosis would rightly report it as a DC-level gap. Use relays only to check the
//! diagnosis against an implementation that shares no code with the model.

use crate::effects::{split_effects, RigEffect};
use actuator_params::ActuatorParams;
use host_tests::reference::dynamics::{MonotoneHysteresis, RelayHysteresis};
use host_tests::reference::preisach::RelayPreisach;
use host_tests::reference::rig::{sensor_chain, RigConstants, RigPlant};
use magctl::preisach::{PreisachMeasure, PreisachState};
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};
use rayon::prelude::*;
use std::f64::consts::PI;
use std::path::{Path, PathBuf};

/// One excitation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Excitation {
    /// `I = bias + amplitude · sin(2π f t)`, held over each sample.
    Sine {
        /// Frequency, Hz.
        freq_hz: f64,
        /// DC bias, A.
        bias_a: f64,
        /// Amplitude, A.
        amplitude_a: f64,
    },
    /// The current commanded by the dynamic-inverse tracking loop (`magctl::inverse::ControlLoop`)
    /// following a Van der Pol trajectory, open loop.
    VanDerPol {
        /// Frequency scale of the oscillator, Hz.
        frequency_scale_hz: f64,
        /// μ of the oscillator.
        mu: f64,
    },
}

impl Excitation {
    /// File stem of the experiment.
    pub fn file_stem(&self, index: usize) -> String {
        match *self {
            Excitation::Sine {
                freq_hz,
                amplitude_a,
                bias_a,
            } => format!("{index:02}_sine_{freq_hz:07.1}hz_amp{amplitude_a:.3}a_bias{bias_a:.3}a"),
            Excitation::VanDerPol {
                frequency_scale_hz,
                mu,
            } => {
                format!("{index:02}_vdp_{frequency_scale_hz:07.1}hz_mu{mu:.2}")
            }
        }
    }
}

/// Rig settings.
#[derive(Debug, Clone, PartialEq)]
pub struct RigOptions {
    /// Sampling (and DAC) rate, Hz.
    pub rate_hz: f64,
    /// Duration of each experiment, s.
    pub duration_s: f64,
    /// RK4 substeps per sample.
    pub substeps: usize,
    /// Relays per Preisach cell side; 0 = the exact cell-uniform operator (module docs).
    pub relay_subdivision: usize,
    /// Gaussian sensor noise, m (standard deviation).
    pub noise_m: f64,
    /// Quantization step of the displacement, m (0 = none).
    pub quantization_m: f64,
    /// Seed of the noise.
    pub seed: u64,
}

impl Default for RigOptions {
    fn default() -> Self {
        RigOptions {
            rate_hz: 10_000.0,
            duration_s: 1.0,
            substeps: 20,
            relay_subdivision: 0,
            noise_m: 0.15e-6,
            quantization_m: 2e-9,
            seed: 1,
        }
    }
}

/// One generated experiment.
#[derive(Debug, Clone, PartialEq)]
pub struct RigExperiment {
    /// File stem.
    pub name: String,
    /// Time, s.
    pub t_s: Vec<f64>,
    /// Commanded current, A.
    pub current_a: Vec<f64>,
    /// Measured displacement, m.
    pub displacement_m: Vec<f64>,
    /// Displacement before noise and quantization (for tests), m.
    pub clean_displacement_m: Vec<f64>,
}

/// The command current of an excitation at `rate_hz` for `duration_s`.
pub fn command_current(
    params: &ActuatorParams,
    excitation: &Excitation,
    rate_hz: f64,
    duration_s: f64,
) -> Result<Vec<f64>, String> {
    let n = (duration_s * rate_hz).round() as usize;
    if n < 3 {
        return Err(format!(
            "duration {duration_s} s at {rate_hz} Hz gives {n} samples; need at least 3"
        ));
    }
    match *excitation {
        Excitation::Sine {
            freq_hz,
            bias_a,
            amplitude_a,
        } => {
            if !(freq_hz > 0.0 && freq_hz < 0.5 * rate_hz) {
                return Err(format!(
                    "sine frequency {freq_hz} Hz must be in (0, {}) (below Nyquist)",
                    0.5 * rate_hz
                ));
            }
            Ok((0..n)
                .map(|k| bias_a + amplitude_a * (2.0 * PI * freq_hz * k as f64 / rate_hz).sin())
                .collect())
        }
        Excitation::VanDerPol {
            frequency_scale_hz,
            mu,
        } => {
            let mut core = to_core(params)?;
            core.control.sample_rate_hz = rate_hz as f32;
            core.trajectory.frequency_scale_hz = frequency_scale_hz as f32;
            core.trajectory.van_der_pol_mu = mu as f32;
            let p = &core.preisach;
            let measure = magctl::preisach::PreisachMeasure::new(
                &p.weights_a_per_m,
                p.h_min_a_per_m,
                p.h_max_a_per_m,
            );
            let control = magctl::inverse::ControlLoop::new(&measure, &core)
                .map_err(|e| format!("Van der Pol tracking loop: {e:?}"))?;
            let kind = magctl::inverse::InverseKind::Dynamic;
            let mut state = control.init::<64>(kind);
            Ok((0..n)
                .map(|_| control.tick(kind, &mut state).current_a as f64)
                .collect())
        }
    }
}

/// The core's f32 parameter struct from a validated file (the narrowing `build.rs` does; one
/// shared conversion, `magctl` feature `host`).
pub fn to_core(file: &ActuatorParams) -> Result<magctl::params::ActuatorParameters, String> {
    magctl::params::ActuatorParameters::from_file(file, "parameter file").map_err(|e| e.to_string())
}

/// The exact cell-uniform Preisach operator (the core's, f32 Everett tables) as the rig's
/// hysteresis. Its f32 rounding (relative 6e-8 of `M_s` in `M`) is far below any sensor noise.
#[derive(Debug, Clone)]
pub struct ExactHysteresis<'a> {
    /// The measure (coefficients).
    pub measure: &'a PreisachMeasure,
    /// Its memory.
    pub state: PreisachState<64>,
}

impl MonotoneHysteresis for ExactHysteresis<'_> {
    fn output_a_per_m(&self) -> f64 {
        self.measure.output_a_per_m(&self.state) as f64
    }
    fn input_a_per_m(&self) -> f64 {
        self.measure.input_a_per_m(&self.state) as f64
    }
    fn preview_solve(&self, a: f64, r: f64) -> (f64, f64) {
        let mut state = self.state.clone();
        match self.measure.solve(&mut state, a as f32, r as f32) {
            Ok(s) => (s.h_a_per_m as f64, s.m_a_per_m as f64),
            // Only a non-finite right-hand side fails; stay where the memory is.
            Err(_) => (self.input_a_per_m(), self.output_a_per_m()),
        }
    }
    fn commit(&mut self, h_a_per_m: f64) -> f64 {
        match self.measure.apply(&mut self.state, h_a_per_m as f32) {
            Ok(m) => m as f64,
            Err(_) => self.output_a_per_m(),
        }
    }
}

/// The rig's Preisach operator (module docs).
pub enum RigHysteresis {
    /// Exact cell-uniform operator (boxed: its Everett tables are 10 kB).
    Exact(Box<PreisachMeasure>),
    /// Relay field with `k` relays per cell side.
    Relays(RelayPreisach),
}

impl RigHysteresis {
    /// Builds the operator `options.relay_subdivision` asks for.
    pub fn new(params: &ActuatorParams, relay_subdivision: usize) -> Result<Self, String> {
        if relay_subdivision == 0 {
            let core = to_core(params)?;
            let p = &core.preisach;
            Ok(RigHysteresis::Exact(Box::new(PreisachMeasure::new(
                &p.weights_a_per_m,
                p.h_min_a_per_m,
                p.h_max_a_per_m,
            ))))
        } else {
            let p = &params.preisach;
            RelayPreisach::new(
                &p.weights_a_per_m,
                p.h_min_a_per_m,
                p.h_max_a_per_m,
                relay_subdivision,
            )
            .map(RigHysteresis::Relays)
            .map_err(|e| e.to_string())
        }
    }
}

/// Runs one experiment on the rig.
pub fn run_experiment(
    params: &ActuatorParams,
    hysteresis: &RigHysteresis,
    effects: &[RigEffect],
    currents_a: &[f64],
    options: &RigOptions,
    seed: u64,
) -> Result<(Vec<f64>, Vec<f64>), String> {
    let (plant_effects, sensor) = split_effects(effects)?;
    let step_s = 1.0 / options.rate_hz;
    let constants = RigConstants::from_params(params);
    let mut y = match hysteresis {
        RigHysteresis::Exact(measure) => {
            let h = ExactHysteresis {
                measure,
                state: measure.demagnetized(),
            };
            let plant = RigPlant::equilibrium(constants, plant_effects, h, currents_a[0]);
            plant_output(plant, currents_a, step_s, options.substeps)
        }
        RigHysteresis::Relays(field) => {
            let h = RelayHysteresis {
                field,
                state: field.demagnetized(),
            };
            let plant = RigPlant::equilibrium(constants, plant_effects, h, currents_a[0]);
            plant_output(plant, currents_a, step_s, options.substeps)
        }
    };
    if let Some(width) = sensor.backlash_m {
        y = sensor_chain::backlash(&y, width);
    }
    if let Some(corner) = sensor.low_pass_hz {
        y = sensor_chain::low_pass(&y, step_s, corner);
    }
    if let Some(delay) = sensor.delay_s {
        y = sensor_chain::delay(&y, step_s, delay);
    }
    let clean = y.clone();
    if options.noise_m > 0.0 {
        let normal = Normal::new(0.0, options.noise_m).map_err(|e| format!("noise: {e}"))?;
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        for v in y.iter_mut() {
            *v += normal.sample(&mut rng);
        }
    }
    if options.quantization_m > 0.0 {
        y = sensor_chain::quantize(&y, options.quantization_m);
    }
    Ok((y, clean))
}

/// The sampled displacement of a plant: sample `k` is the displacement at `t_k = k h`, before
/// the command of sample `k` acts.
fn plant_output<P: MonotoneHysteresis + Clone>(
    mut plant: RigPlant<P>,
    currents_a: &[f64],
    step_s: f64,
    substeps: usize,
) -> Vec<f64> {
    let mut y = Vec::with_capacity(currents_a.len());
    y.push(plant.output_m());
    for &i in &currents_a[..currents_a.len() - 1] {
        y.push(plant.advance_held(step_s, substeps, i));
    }
    y
}

/// Runs every excitation (in parallel); `progress` is called with the number of samples done.
pub fn generate(
    params: &ActuatorParams,
    effects: &[RigEffect],
    excitations: &[Excitation],
    options: &RigOptions,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<Vec<RigExperiment>, String> {
    params
        .validate("rig parameters")
        .map_err(|e| e.to_string())?;
    split_effects(effects)?;
    for (name, v) in [
        ("rate_hz", options.rate_hz),
        ("duration_s", options.duration_s),
    ] {
        if !(v.is_finite() && v > 0.0) {
            return Err(format!(
                "rig option `{name}` must be a positive number, got {v}"
            ));
        }
    }
    if !(options.noise_m >= 0.0 && options.quantization_m >= 0.0) {
        return Err("rig options `noise_m` and `quantization_m` must be >= 0".into());
    }
    if options.substeps == 0 {
        return Err("rig option `substeps` must be at least 1".into());
    }
    let hysteresis = RigHysteresis::new(params, options.relay_subdivision)?;
    excitations
        .par_iter()
        .enumerate()
        .map(|(k, exc)| {
            let currents = command_current(params, exc, options.rate_hz, options.duration_s)?;
            let (y, clean) = run_experiment(
                params,
                &hysteresis,
                effects,
                &currents,
                options,
                options.seed.wrapping_add(k as u64),
            )?;
            progress(currents.len() as u64);
            let t_s = (0..currents.len())
                .map(|i| i as f64 / options.rate_hz)
                .collect();
            Ok(RigExperiment {
                name: exc.file_stem(k),
                t_s,
                current_a: currents,
                displacement_m: y,
                clean_displacement_m: clean,
            })
        })
        .collect()
}

/// Writes the experiments as `dir/<name>.csv`; returns the paths.
pub fn write_dataset(dir: &Path, experiments: &[RigExperiment]) -> Result<Vec<PathBuf>, String> {
    std::fs::create_dir_all(dir).map_err(|e| format!("cannot create {}: {e}", dir.display()))?;
    experiments
        .iter()
        .map(|e| {
            let path = dir.join(format!("{}.csv", e.name));
            maglab_identify::data::write_measurement(
                &path,
                &e.t_s,
                &e.current_a,
                &e.displacement_m,
            )
            .map_err(|err| err.to_string())?;
            Ok(path)
        })
        .collect()
}

/// A sine sweep: every frequency at every amplitude, same bias.
pub fn sine_sweep(freqs_hz: &[f64], amplitudes_a: &[f64], bias_a: f64) -> Vec<Excitation> {
    let mut out = Vec::new();
    for &f in freqs_hz {
        for &a in amplitudes_a {
            out.push(Excitation::Sine {
                freq_hz: f,
                bias_a,
                amplitude_a: a,
            });
        }
    }
    out
}
