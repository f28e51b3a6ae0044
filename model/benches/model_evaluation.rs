//! Cost of one evaluation of the diagnosis's model (`maglab_model::model::simulate`: the
//! electromagnetic stage twice for Richardson's extrapolation, the rod and load, the sensor's
//! reading), the unit every candidate fit repeats thousands of times.
//!
//! One experiment: a biased 300 Hz sine at 10 kHz, 3,000 samples (the fit's cap per experiment,
//! `FitSettings::max_fit_samples`), from the demagnetized state, the current linear between
//! samples, one substep per sample (the diagnosis's setting). One evaluation per candidate form:
//! the nominal model and each library effect at a typical magnitude. The ΔE form integrates the
//! rod step by step (its stiffness depends on the state); every other form steps the rod and
//! load as a precomputed linear map.
//!
//! Run: `cargo bench -p maglab-model --bench model_evaluation`.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use maglab_dataset::{CurrentBetweenSamples, StartState};
use maglab_model::model::{simulate, Electro, Mech, ModelStart, Nominal};
use std::f64::consts::PI;
use std::hint::black_box;

const SAMPLES: usize = 3_000;
const STEP_S: f64 = 1e-4;

fn bench(c: &mut Criterion) {
    let params = actuator_params::paper_defaults();
    let core = magctl::params::ActuatorParameters::from_file(&params, "paper defaults")
        .expect("the paper's defaults are a valid parameter file");
    let measure = core.preisach.measure();
    let nominal = Nominal::from_params(&params);
    let currents_a: Vec<f64> = (0..SAMPLES)
        .map(|k| 0.5 + 0.45 * (2.0 * PI * 300.0 * k as f64 * STEP_S).sin())
        .collect();
    let electro = Electro::nominal(params.actuator.eddy_resistance_ohm);
    let mech = Mech::nominal(params.actuator.damping_ratio, params.actuator.resonance_hz);
    let forms: Vec<(&str, Electro, Mech)> = vec![
        ("nominal", electro, mech),
        (
            "eddy_frequency_dependence",
            Electro {
                eddy_path: Some((2.0, 300.0)),
                ..electro
            },
            mech,
        ),
        (
            "amplifier_bandwidth",
            Electro {
                amplifier: Some((800.0, 0.7)),
                ..electro
            },
            mech,
        ),
        (
            "reversible_magnetization",
            Electro {
                reversible: Some((0.3, 20_000.0, 2.0)),
                ..electro
            },
            mech,
        ),
        (
            "delta_e_effect",
            electro,
            Mech {
                delta_e: Some((0.5, 0.0, 0.0, 0.2)),
                ..mech
            },
        ),
        (
            "mechanical_load",
            electro,
            Mech {
                load: Some((0.3, 900.0, 0.2)),
                ..mech
            },
        ),
        (
            "sensor_dynamics",
            electro,
            Mech {
                sensor: Some((900.0, 0.7, 2e-5)),
                skew_samples: 0.3,
                ..mech
            },
        ),
    ];
    let mut group = c.benchmark_group("diagnosis model, 3,000 samples");
    group.throughput(Throughput::Elements(SAMPLES as u64));
    for (name, electro, mech) in &forms {
        group.bench_function(*name, |b| {
            b.iter(|| {
                simulate(
                    &nominal,
                    &measure,
                    black_box(electro),
                    black_box(mech),
                    black_box(&currents_a),
                    STEP_S,
                    CurrentBetweenSamples::Linear,
                    &ModelStart::State(StartState::Demagnetized),
                    1,
                )
            })
        });
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
