//! Experiments on the bench plant: the command sequences, how the bench records them (the
//! nuisances a real rig has), and the dataset folder it writes.
//!
//! **What a recording is.** Sample `k` holds the time `t_k = k / rate`, the command `I_k` the
//! controller sent (held over `[t_k, t_{k+1}]` by a DAC, or linear to `I_{k+1}` when the current
//! source interpolates: [`BenchSettings::current_between_samples`]) and the displacement the
//! sensor read at `t_k + skew / rate` ([`BenchSettings::channel_skew_samples`]: the two channels
//! of a logger are rarely sampled at the same instant) plus the sensor's offset, white noise and
//! quantization. None of these bench facts is written into the dataset: only what an
//! experimenter documents, the start state of each experiment (`dataset.json`,
//! `maglab_dataset::dataset_info`). The effects and the nuisances go to a separate manifest.
//!
//! Experiments whose start state is `previous` run after the one before them on the same plant;
//! a dataset without them runs its experiments in parallel (rayon).

use crate::actuator::Plant;
use crate::effects::Effect;
use actuator_params::ActuatorParams;
use maglab_dataset::dataset_info::{DatasetInfo, FileInfo};
use maglab_dataset::{CurrentBetweenSamples, StartState};
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};
use rayon::prelude::*;
use std::f64::consts::PI;
use std::path::{Path, PathBuf};

/// How the bench records (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BenchSettings {
    /// Sampling and command rate, Hz.
    pub rate_hz: f64,
    /// What the current source does between command samples.
    pub current_between_samples: CurrentBetweenSamples,
    /// The displacement of sample `k` is read at `t_k + skew / rate`; |skew| < 1.
    pub channel_skew_samples: f64,
    /// Sensor offset, m.
    pub sensor_offset_m: f64,
    /// White sensor noise, m (standard deviation).
    pub noise_m: f64,
    /// Quantization step of the displacement, m (0: none).
    pub quantization_m: f64,
    /// Seed of the noise (experiment `k` uses `seed + k`).
    pub seed: u64,
    /// The coil-current channel, when the bench records it (`coil_current_a`).
    pub coil_current: Option<CurrentMonitor>,
}

/// A bench's coil-current channel: the amplifier's current-monitor output, sampled on the
/// displacement's trigger (at `t_k + skew / rate`, as the displacement), with its own white
/// noise and quantization (`maglab_dataset::data`, "The two currents").
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CurrentMonitor {
    /// White noise of the reading, A (standard deviation).
    pub noise_a: f64,
    /// Quantization step of the reading, A (0: none).
    pub quantization_a: f64,
}

impl CurrentMonitor {
    /// A typical monitor read by a 12-bit ADC over ±2 A: 1 mA of noise, 1 mA steps.
    pub const TYPICAL: CurrentMonitor = CurrentMonitor {
        noise_a: 1e-3,
        quantization_a: 1e-3,
    };
}

/// The seed stream of the coil current's noise, apart from the displacement's (the same seed
/// gives the same displacement noise with and without the channel).
const CURRENT_NOISE_STREAM: u64 = 0xc011_c0de_0000_0001;

impl Default for BenchSettings {
    fn default() -> Self {
        BenchSettings {
            rate_hz: 10_000.0,
            current_between_samples: CurrentBetweenSamples::Hold,
            channel_skew_samples: 0.0,
            sensor_offset_m: 0.0,
            noise_m: 0.15e-6,
            quantization_m: 2e-9,
            seed: 1,
            coil_current: None,
        }
    }
}

impl BenchSettings {
    /// Checks the settings, naming the field.
    pub fn check(&self) -> Result<(), String> {
        if !(self.rate_hz.is_finite() && self.rate_hz > 0.0) {
            return Err(format!("bench `rate_hz` must be > 0, got {}", self.rate_hz));
        }
        if !(self.channel_skew_samples.is_finite() && self.channel_skew_samples.abs() < 1.0) {
            return Err(format!(
                "bench `channel_skew_samples` must be in (-1, 1), got {}",
                self.channel_skew_samples
            ));
        }
        for (name, v) in [
            ("noise_m", self.noise_m),
            ("quantization_m", self.quantization_m),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(format!("bench `{name}` must be >= 0, got {v}"));
            }
        }
        if !self.sensor_offset_m.is_finite() {
            return Err("bench `sensor_offset_m` must be finite".into());
        }
        if let Some(m) = self.coil_current {
            for (name, v) in [("noise_a", m.noise_a), ("quantization_a", m.quantization_a)] {
                if !(v.is_finite() && v >= 0.0) {
                    return Err(format!("bench `coil_current.{name}` must be >= 0, got {v}"));
                }
            }
        }
        Ok(())
    }
}

/// One experiment: a command sequence and how it starts.
#[derive(Debug, Clone, PartialEq)]
pub struct Experiment {
    /// File stem.
    pub name: String,
    /// Start state.
    pub start: StartState,
    /// Command at every sample, A.
    pub current_a: Vec<f64>,
    /// What the command is (documented in `dataset.json`).
    pub description: String,
}

/// A recorded experiment.
#[derive(Debug, Clone, PartialEq)]
pub struct Recording {
    /// File stem.
    pub name: String,
    /// Start state.
    pub start: StartState,
    /// What the command is.
    pub description: String,
    /// `t_k`, s.
    pub t_s: Vec<f64>,
    /// Command, A.
    pub current_a: Vec<f64>,
    /// Recorded displacement, m.
    pub displacement_m: Vec<f64>,
    /// The same without noise and quantization (for tests and calibration), m.
    pub clean_displacement_m: Vec<f64>,
    /// The measured coil current, when the bench records it ([`BenchSettings::coil_current`]), A.
    pub coil_current_a: Option<Vec<f64>>,
}

/// `bias + amplitude sin(2π f t_k)` for `duration_s`.
pub fn sine(
    bias_a: f64,
    amplitude_a: f64,
    freq_hz: f64,
    duration_s: f64,
    rate_hz: f64,
) -> Vec<f64> {
    let n = (duration_s * rate_hz).round() as usize;
    (0..n)
        .map(|k| bias_a + amplitude_a * (2.0 * PI * freq_hz * k as f64 / rate_hz).sin())
        .collect()
}

/// A quasi-static sweep with nested reversals between `low_a` and `high_a`: up to `high_a`,
/// down to `low_a`, then `levels` narrowing pairs (`high − k d`, `low + k d`,
/// `d = (high − low) / (2 levels)`), at one constant speed so that the whole path takes
/// `duration_s` (the reversal curves inside the coil's reach a bench can run on any rod).
pub fn reversal_sweep(
    low_a: f64,
    high_a: f64,
    levels: usize,
    duration_s: f64,
    rate_hz: f64,
) -> Vec<f64> {
    let d = (high_a - low_a) / (2.0 * levels.max(1) as f64);
    let mut points = vec![low_a, high_a, low_a];
    for k in 1..levels {
        points.push(high_a - k as f64 * d);
        points.push(low_a + k as f64 * d);
    }
    let length: f64 = points.windows(2).map(|w| (w[1] - w[0]).abs()).sum();
    let n = (duration_s * rate_hz).round().max(2.0) as usize;
    let per_sample = length / (n - 1) as f64;
    let mut out = Vec::with_capacity(n);
    let (mut segment, mut at) = (1, low_a);
    out.push(at);
    while out.len() < n && segment < points.len() {
        let mut step = per_sample;
        while step > 0.0 && segment < points.len() {
            let goal = points[segment];
            let left = (goal - at).abs();
            if left <= step {
                at = goal;
                step -= left;
                segment += 1;
            } else {
                at += step * (goal - at).signum();
                step = 0.0;
            }
        }
        out.push(at);
    }
    out.resize(n, at);
    out
}

/// The current of a Van der Pol oscillator `x'' − μ (1 − x²) x' + (2π f)² x = 0` on its limit
/// cycle (amplitude ≈ 2), scaled to `bias_a ± amplitude_a` (RK4 at 16 steps per sample).
pub fn van_der_pol_current(
    bias_a: f64,
    amplitude_a: f64,
    freq_hz: f64,
    mu: f64,
    duration_s: f64,
    rate_hz: f64,
) -> Vec<f64> {
    let w = 2.0 * PI * freq_hz;
    // In time τ = ω t: x'' − μ (1 − x²) x' + x = 0.
    let f = |x: f64, v: f64| (v, mu * (1.0 - x * x) * v - x);
    let dt = w / rate_hz / 16.0;
    let step = |(x, v): (f64, f64)| {
        let (k1x, k1v) = f(x, v);
        let (k2x, k2v) = f(x + 0.5 * dt * k1x, v + 0.5 * dt * k1v);
        let (k3x, k3v) = f(x + 0.5 * dt * k2x, v + 0.5 * dt * k2v);
        let (k4x, k4v) = f(x + dt * k3x, v + dt * k3v);
        (
            x + dt / 6.0 * (k1x + 2.0 * k2x + 2.0 * k3x + k4x),
            v + dt / 6.0 * (k1v + 2.0 * k2v + 2.0 * k3v + k4v),
        )
    };
    // Onto the limit cycle first: 20 periods from x = 2.
    let mut s = (2.0, 0.0);
    for _ in 0..(20.0 * 2.0 * PI / dt) as usize {
        s = step(s);
    }
    let n = (duration_s * rate_hz).round() as usize;
    (0..n)
        .map(|_| {
            let i = bias_a + amplitude_a * 0.5 * s.0;
            for _ in 0..16 {
                s = step(s);
            }
            i
        })
        .collect()
}

/// The quasi-static reversal sweep of `maglab excite` (first-order reversal curves reaching every
/// Preisach cell, a full-range triangle at `sweep_hz`), from negative saturation: the
/// identification record a dataset for `maglab identify` starts with.
pub fn forc_experiment(
    params: &ActuatorParams,
    sweep_hz: f64,
    rate_hz: f64,
) -> Result<Experiment, String> {
    let e =
        maglab_dataset::excitation::forc_excitation(&maglab_dataset::excitation::ExciteOptions {
            h_min_a_per_m: params.preisach.h_min_a_per_m,
            h_max_a_per_m: params.preisach.h_max_a_per_m,
            coil_factor_per_m: params.actuator.coil_factor_per_m,
            sweep_rate_hz: sweep_hz,
            sample_rate_hz: rate_hz,
            overdrive: 0.05,
        })
        .map_err(|e| e.to_string())?;
    Ok(Experiment {
        name: "00_forc".into(),
        start: StartState::NegativeSaturation,
        current_a: e.current_a,
        description: format!("FORC reversal sweep, {sweep_hz} Hz full-range triangle rate"),
    })
}

/// A sine experiment with a descriptive name.
pub fn sine_experiment(
    index: usize,
    start: StartState,
    bias_a: f64,
    amplitude_a: f64,
    freq_hz: f64,
    duration_s: f64,
    rate_hz: f64,
) -> Experiment {
    Experiment {
        name: format!("{index:02}_sine_{freq_hz:07.1}hz_amp{amplitude_a:.3}a_bias{bias_a:.3}a"),
        start,
        current_a: sine(bias_a, amplitude_a, freq_hz, duration_s, rate_hz),
        description: format!("sine {freq_hz} Hz, {bias_a} ± {amplitude_a} A"),
    }
}

/// A bench's standard identification dataset, for a rod the coil may not saturate: a reversal
/// sweep from 0 to 1.4 A with ten nested reversals, biased sines 1–400 Hz at 0.3 and 0.6 A
/// around 0.8 A (the 1 Hz ones quasi-static data on the loops the fast ones run on), two Van der
/// Pol currents; every experiment switched on from a demagnetized rod.
pub fn identification_design(rate_hz: f64) -> Vec<Experiment> {
    let start = StartState::SwitchOnDemagnetized;
    let mut out = vec![Experiment {
        name: "00_reversals".into(),
        start,
        current_a: reversal_sweep(0.0, 1.4, 10, 2.0, rate_hz),
        description: "reversal sweep 0-1.4 A".into(),
    }];
    let mut index = 1;
    for (freq_hz, duration_s) in [
        (1.0, 3.0),
        (20.0, 0.5),
        (50.0, 0.5),
        (100.0, 0.5),
        (150.0, 0.5),
        (200.0, 0.5),
        (300.0, 0.5),
        (400.0, 0.5),
    ] {
        for amplitude_a in [0.3, 0.6] {
            out.push(sine_experiment(
                index,
                start,
                0.8,
                amplitude_a,
                freq_hz,
                duration_s,
                rate_hz,
            ));
            index += 1;
        }
    }
    for freq_hz in [20.0, 100.0] {
        out.push(Experiment {
            name: format!("{index:02}_vdp_{freq_hz}hz"),
            start,
            current_a: van_der_pol_current(0.8, 0.6, freq_hz, 1.0, 0.5, rate_hz),
            description: format!("Van der Pol current {freq_hz} Hz, mu 1"),
        });
        index += 1;
    }
    out
}

/// The loops `experiments` run: each one's `(bias, amplitude)` in A, the centre and half the
/// span of its current over its second half (past the start's transient), each loop once
/// (within `tolerance_a`), in the order first met.
pub fn operating_loops(experiments: &[Experiment], tolerance_a: f64) -> Vec<(f64, f64)> {
    let mut loops: Vec<(f64, f64)> = Vec::new();
    for e in experiments {
        let steady = &e.current_a[e.current_a.len() / 2..];
        let (lo, hi) = steady
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &i| {
                (a.min(i), b.max(i))
            });
        if hi < lo {
            continue;
        }
        let found = (0.5 * (hi + lo), 0.5 * (hi - lo));
        let seen = loops
            .iter()
            .any(|(b, a)| (b - found.0).abs() <= tolerance_a && (a - found.1).abs() <= tolerance_a);
        if !seen {
            loops.push(found);
        }
    }
    loops
}

/// [`identification_design`] with a quasi-static (1 Hz, 3 s) sine on each of `loops` (`(bias,
/// amplitude)`, A) as well: the masses are measured on the loops a later dataset runs
/// (`maglab_identify::coverage`; docs/model.md "Not on every design"), as a bench identifies
/// its rod on the operating range it then uses.
pub fn identification_design_covering(rate_hz: f64, loops: &[(f64, f64)]) -> Vec<Experiment> {
    let mut design = identification_design(rate_hz);
    for &(bias_a, amplitude_a) in loops {
        let index = design.len();
        design.push(sine_experiment(
            index,
            StartState::SwitchOnDemagnetized,
            bias_a,
            amplitude_a,
            1.0,
            3.0,
            rate_hz,
        ));
    }
    design
}

/// Runs one experiment on `plant` (started as the experiment says).
pub fn record(
    plant: &mut Plant,
    experiment: &Experiment,
    settings: &BenchSettings,
    seed: u64,
) -> Result<Recording, String> {
    settings.check()?;
    let cmd = &experiment.current_a;
    if cmd.len() < 3 {
        return Err(format!("{}: needs at least 3 samples", experiment.name));
    }
    if let Some((k, v)) = cmd.iter().enumerate().find(|(_, v)| !v.is_finite()) {
        return Err(format!("{}: command sample {k} is {v}", experiment.name));
    }
    plant
        .start(experiment.start, cmd[0])
        .map_err(|e| format!("{}: {e}", experiment.name))?;
    let n = cmd.len();
    for k in 0..n {
        let end = match settings.current_between_samples {
            CurrentBetweenSamples::Hold => cmd[k],
            CurrentBetweenSamples::Linear => cmd[(k + 1).min(n - 1)],
        };
        plant.advance(cmd[k], end);
    }
    let h = 1.0 / settings.rate_hz;
    let t_s: Vec<f64> = (0..n).map(|k| k as f64 * h).collect();
    let clean: Vec<f64> = t_s
        .iter()
        .map(|&t| plant.sensor_at(t + settings.channel_skew_samples * h) + settings.sensor_offset_m)
        .collect();
    let y = noisy(
        clean.clone(),
        settings.noise_m,
        settings.quantization_m,
        seed,
    )?;
    let coil_current_a = match settings.coil_current {
        Some(monitor) => {
            let clean: Vec<f64> = t_s
                .iter()
                .map(|&t| plant.coil_current_at(t + settings.channel_skew_samples * h))
                .collect();
            Some(noisy(
                clean,
                monitor.noise_a,
                monitor.quantization_a,
                seed ^ CURRENT_NOISE_STREAM,
            )?)
        }
        None => None,
    };
    Ok(Recording {
        name: experiment.name.clone(),
        start: experiment.start,
        description: experiment.description.clone(),
        t_s,
        current_a: cmd.clone(),
        displacement_m: y,
        clean_displacement_m: clean,
        coil_current_a,
    })
}

/// `x` with white noise of `sigma` (seeded) and quantized to steps of `step` (0: none).
fn noisy(mut x: Vec<f64>, sigma: f64, step: f64, seed: u64) -> Result<Vec<f64>, String> {
    if sigma > 0.0 {
        let normal = Normal::new(0.0, sigma).map_err(|e| format!("noise: {e}"))?;
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        for v in x.iter_mut() {
            *v += normal.sample(&mut rng);
        }
    }
    if step > 0.0 {
        for v in x.iter_mut() {
            *v = (*v / step).round() * step;
        }
    }
    Ok(x)
}

/// Records every experiment on a plant of `params` with `effects` (see the module docs for the
/// order).
pub fn record_all(
    params: &ActuatorParams,
    effects: &[Effect],
    experiments: &[Experiment],
    settings: &BenchSettings,
) -> Result<Vec<Recording>, String> {
    settings.check()?;
    record_all_on(
        Plant::new(params, effects, settings.rate_hz)?,
        experiments,
        settings,
    )
}

/// Records every experiment on `plant` (as [`record_all`] does: a chain in order, else each on
/// its own copy in parallel).
pub fn record_all_on(
    plant: Plant,
    experiments: &[Experiment],
    settings: &BenchSettings,
) -> Result<Vec<Recording>, String> {
    settings.check()?;
    let chained = experiments.iter().any(|e| e.start == StartState::Previous);
    if chained {
        let mut plant = plant;
        experiments
            .iter()
            .enumerate()
            .map(|(k, e)| {
                record(
                    &mut plant,
                    e,
                    settings,
                    settings.seed.wrapping_add(k as u64),
                )
            })
            .collect()
    } else {
        experiments
            .par_iter()
            .enumerate()
            .map(|(k, e)| {
                let mut p = plant.clone();
                record(&mut p, e, settings, settings.seed.wrapping_add(k as u64))
            })
            .collect()
    }
}

/// Writes `dir/<name>.csv` for every recording and `dir/dataset.json` with the start states
/// and excitations; returns the CSV paths.
pub fn write_dataset(dir: &Path, recordings: &[Recording]) -> Result<Vec<PathBuf>, String> {
    std::fs::create_dir_all(dir).map_err(|e| format!("cannot create {}: {e}", dir.display()))?;
    let mut info = DatasetInfo::default();
    let mut paths = Vec::new();
    for r in recordings {
        let file = format!("{}.csv", r.name);
        let path = dir.join(&file);
        maglab_dataset::data::write_measurement(
            &path,
            &r.t_s,
            &r.current_a,
            &r.displacement_m,
            r.coil_current_a.as_deref(),
        )
        .map_err(|e| e.to_string())?;
        info.files.insert(
            file,
            FileInfo {
                start_state: Some(r.start),
                excitation: Some(r.description.clone()),
            },
        );
        paths.push(path);
    }
    info.write(dir).map_err(|e| e.to_string())?;
    Ok(paths)
}
