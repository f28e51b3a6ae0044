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

use crate::effects::{split_effects, RigEffect};
use actuator_params::ActuatorParams;
use host_tests::reference::dynamics::RelayHysteresis;
use host_tests::reference::preisach::RelayPreisach;
use host_tests::reference::rig::{sensor_chain, RigConstants, RigPlant};
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
    /// Relays per Preisach cell side.
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
            relay_subdivision: 64,
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

/// The core's f32 parameter struct from a validated file (the narrowing `build.rs` does).
pub fn to_core(file: &ActuatorParams) -> Result<magctl::params::ActuatorParameters, String> {
    use magctl::params::*;
    let a = &file.actuator;
    let p = &file.preisach;
    if p.weights_a_per_m.len() != magctl::preisach::CELL_COUNT {
        return Err(format!(
            "field `preisach.weights_a_per_m`: the core needs {} weights, the file has {}",
            magctl::preisach::CELL_COUNT,
            p.weights_a_per_m.len()
        ));
    }
    let mut w = [0.0f32; magctl::preisach::CELL_COUNT];
    for (d, s) in w.iter_mut().zip(&p.weights_a_per_m) {
        *d = *s as f32;
    }
    Ok(ActuatorParameters {
        actuator: Actuator {
            coil_turns: a.coil_turns as f32,
            rod_area_m2: a.rod_area_m2 as f32,
            rod_length_m: a.rod_length_m as f32,
            coil_factor_per_m: a.coil_factor_per_m as f32,
            saturation_magnetization_a_per_m: a.saturation_magnetization_a_per_m as f32,
            saturation_magnetostriction: a.saturation_magnetostriction as f32,
            resonance_hz: a.resonance_hz as f32,
            eddy_resistance_ohm: a.eddy_resistance_ohm as f32,
            damping_ratio: a.damping_ratio as f32,
        },
        preisach: PreisachGrid {
            h_min_a_per_m: p.h_min_a_per_m as f32,
            h_max_a_per_m: p.h_max_a_per_m as f32,
            weights_a_per_m: w,
        },
        control: Control {
            sample_rate_hz: file.control.sample_rate_hz as f32,
            current_limit_a: file.control.current_limit_a as f32,
            current_slew_limit_a_per_s: file.control.current_slew_limit_a_per_s as f32,
        },
        trajectory: Trajectory {
            van_der_pol_mu: file.trajectory.van_der_pol_mu as f32,
            frequency_scale_hz: file.trajectory.frequency_scale_hz as f32,
            displacement_min_m: file.trajectory.displacement_min_m as f32,
            displacement_max_m: file.trajectory.displacement_max_m as f32,
        },
    })
}

/// Runs one experiment on the rig.
pub fn run_experiment(
    params: &ActuatorParams,
    field: &RelayPreisach,
    effects: &[RigEffect],
    currents_a: &[f64],
    options: &RigOptions,
    seed: u64,
) -> Result<(Vec<f64>, Vec<f64>), String> {
    let (plant_effects, sensor) = split_effects(effects)?;
    let step_s = 1.0 / options.rate_hz;
    let constants = RigConstants::from_params(params);
    let hysteresis = RelayHysteresis {
        field,
        state: field.demagnetized(),
    };
    let mut plant = RigPlant::equilibrium(constants, plant_effects, hysteresis, currents_a[0]);
    // Sample k is the displacement at t_k = k h, before the command of sample k acts.
    let mut y = Vec::with_capacity(currents_a.len());
    y.push(plant.output_m());
    for &i in &currents_a[..currents_a.len() - 1] {
        y.push(plant.advance_held(step_s, options.substeps, i));
    }
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
    let p = &params.preisach;
    let field = RelayPreisach::new(
        &p.weights_a_per_m,
        p.h_min_a_per_m,
        p.h_max_a_per_m,
        options.relay_subdivision,
    )
    .map_err(|e| e.to_string())?;
    excitations
        .par_iter()
        .enumerate()
        .map(|(k, exc)| {
            let currents = command_current(params, exc, options.rate_hz, options.duration_s)?;
            let (y, clean) = run_experiment(
                params,
                &field,
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
