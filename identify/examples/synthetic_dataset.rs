//! Writes the synthetic identification dataset of `tests/dynamics.rs` to a folder, for
//! `maglab identify` (docs/identification.md):
//!
//! ```sh
//! cargo run --release -p maglab-identify --example synthetic_dataset -- out/synthetic-dataset
//! ```
//!
//! Truth: the default Preisach masses with R_eddy = 55 Ω, ξ = 0.65, f0 = 420 Hz (not the
//! defaults), simulated by the independent f64 reference plant (RK4 on (8), relay operator with
//! 128 relays per cell side), every experiment from negative saturation, LVDT noise σ = 0.1 % of
//! the stroke. Files: `forc.csv` (quasi-static FORC sweep of `maglab excite`, static model (6)),
//! `sine_001.0hz.csv` (the operating loop at 1 Hz after a ramp from 0 A), and sines with DC bias
//! 0.5 A, amplitude 0.35 A at 20, 40, 70, 100, 140, 200 Hz sampled at 10 kHz.

use host_tests::reference::dynamics::{PlantConstants, ReferencePlant, RelayHysteresis};
use host_tests::reference::preisach::RelayPreisach;
use maglab_dataset::data::write_measurement;
use maglab_dataset::excitation::{forc_excitation, ExciteOptions};
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};
use rayon::prelude::*;
use std::f64::consts::PI;

/// (frequency, times, currents, displacements) of one experiment.
type Run = (f64, Vec<f64>, Vec<f64>, Vec<f64>);

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let dir = std::env::args()
        .nth(1)
        .ok_or("usage: synthetic_dataset OUTPUT_DIR")?;
    let dir = std::path::PathBuf::from(dir);
    std::fs::create_dir_all(&dir)?;
    let mut p = actuator_params::paper_defaults();
    p.actuator.eddy_resistance_ohm = 55.0;
    p.actuator.damping_ratio = 0.65;
    p.actuator.resonance_hz = 420.0;
    let field = RelayPreisach::new(
        &p.preisach.weights_a_per_m,
        p.preisach.h_min_a_per_m,
        p.preisach.h_max_a_per_m,
        128,
    )?;
    let a = &p.actuator;
    let stroke = a.rod_length_m * a.saturation_magnetostriction;
    let gain = stroke / (a.saturation_magnetization_a_per_m * a.saturation_magnetization_a_per_m);
    let noise = Normal::new(0.0, 1e-3 * stroke)?;

    let e = forc_excitation(&ExciteOptions {
        h_min_a_per_m: p.preisach.h_min_a_per_m,
        h_max_a_per_m: p.preisach.h_max_a_per_m,
        coil_factor_per_m: a.coil_factor_per_m,
        sweep_rate_hz: 1.0,
        sample_rate_hz: 1000.0,
        overdrive: 0.01,
    })?;
    let mut rng = rand::rngs::StdRng::seed_from_u64(11);
    let mut state = field.negative_saturation();
    let y: Vec<f64> = e
        .current_a
        .iter()
        .map(|i| {
            let m = field.apply_a_per_m(&mut state, i * a.coil_factor_per_m);
            gain * m * m + noise.sample(&mut rng)
        })
        .collect();
    write_measurement(&dir.join("forc.csv"), &e.t_s, &e.current_a, &y, None)?;

    // (frequency, sample rate, duration, ramp from 0 A)
    let mut jobs: Vec<(f64, f64, f64, f64)> = [20.0f64, 40.0, 70.0, 100.0, 140.0, 200.0]
        .iter()
        .map(|&f| (f, 10_000.0, (8.0 / f).max(0.15), 0.0))
        .collect();
    jobs.push((1.0, 1000.0, 3.0, 0.25));
    let constants = PlantConstants::from_params(&p);
    let runs: Vec<Run> = jobs
        .par_iter()
        .map(|&(f, rate, duration, ramp)| {
            let current = move |t: f64| {
                if t < ramp {
                    0.5 * t / ramp
                } else {
                    0.5 + 0.35 * (2.0 * PI * f * (t - ramp)).sin()
                }
            };
            let mut plant = ReferencePlant::equilibrium(
                constants,
                RelayHysteresis {
                    field: &field,
                    state: field.negative_saturation(),
                },
                current(0.0),
            );
            let n = ((ramp + duration) * rate).round() as usize;
            let substeps = (200_000.0 / rate).round() as usize;
            let mut y = vec![plant.sample().displacement_m];
            for _ in 1..n {
                y.push(plant.advance(1.0 / rate, substeps, &current).displacement_m);
            }
            let t: Vec<f64> = (0..n).map(|k| k as f64 / rate).collect();
            let i: Vec<f64> = t.iter().map(|&t| current(t)).collect();
            (f, t, i, y)
        })
        .collect();
    for (k, (f, t, i, y)) in runs.into_iter().enumerate() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(100 + k as u64);
        let y: Vec<f64> = y.iter().map(|v| v + noise.sample(&mut rng)).collect();
        let path = dir.join(format!("sine_{f:05.1}hz.csv"));
        write_measurement(&path, &t, &i, &y, None)?;
        println!("wrote {}", path.display());
    }
    println!("wrote {}", dir.join("forc.csv").display());
    Ok(())
}
