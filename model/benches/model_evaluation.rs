//! Cost of one evaluation of the diagnosis's model (`maglab_model::model::simulate`: the
//! electromagnetic stage twice for Richardson's extrapolation, the rod and load, the sensor's
//! reading), the unit every candidate fit repeats thousands of times.
//!
//! One experiment: a biased 300 Hz sine at 10 kHz, 3,000 samples (the fit's cap per experiment,
//! `FitSettings::max_fit_samples`), from the demagnetized state, the current linear between
//! samples, one substep per sample (the diagnosis's setting). One evaluation per candidate form:
//! the nominal model and each library effect at a typical magnitude; the amplifier twice, without
//! and with the coil's time constant (the loop's EMF path). The ΔE form integrates the
//! rod step by step (its stiffness depends on the state); every other form steps the rod and
//! load as a precomputed linear map.
//!
//! The second group is the mechanical stage of a Jacobian's mechanical columns: eight ΔE and
//! load parameter sets (each one coefficient moved by a forward-difference step) on one
//! electromagnetic run, one by one (`track_mech` each) and side by side (`track_mech_lanes`,
//! the same tracks bit for bit).
//!
//! Run: `cargo bench -p maglab-model --bench model_evaluation`.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use maglab_dataset::{CurrentBetweenSamples, StartState};
use maglab_model::fit::ModelSetup;
use maglab_model::model::{
    run_electro, simulate, track_mech, track_mech_lanes, Electro, ElectroDrive, Mech, ModelStart,
    Nominal,
};
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
                amplifier: Some((800.0, 0.7, 0.0)),
                ..electro
            },
            mech,
        ),
        (
            // The current loop around a 0.5 ms coil: the flux EMF it does not reject is stepped
            // too (the `EMF` path of `electro_steps`).
            "amplifier_bandwidth, coil 0.5 ms",
            Electro {
                amplifier: Some((800.0, 0.7, 5e-4)),
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
    let setup = ModelSetup {
        nominal: &nominal,
        measure: &measure,
        step_s: STEP_S,
        interpolation: CurrentBetweenSamples::Linear,
        substeps: 1,
        single_run: false,
    };
    let start = ModelStart::State(StartState::Demagnetized);
    let mut group = c.benchmark_group("diagnosis model, 3,000 samples");
    group.throughput(Throughput::Elements(SAMPLES as u64));
    for (name, electro, mech) in &forms {
        group.bench_function(*name, |b| {
            b.iter(|| {
                simulate(
                    &setup,
                    black_box(electro),
                    black_box(mech),
                    black_box(&currents_a),
                    &start,
                )
            })
        });
    }
    group.finish();

    // The Jacobian's mechanical columns of a ΔE + load pair.
    let drive = ElectroDrive {
        currents_a: &currents_a,
        start: &start,
        previous: None,
    };
    let run = run_electro(&setup, &electro, drive);
    let base = Mech {
        delta_e: Some((0.5, -0.3, 0.2, 0.1)),
        load: Some((0.3, 900.0, 0.2)),
        ..mech
    };
    let columns: Vec<Mech> = (0..8)
        .map(|k| {
            let (mut d, mut load) = (base.delta_e.expect("ΔE"), base.load.expect("load"));
            let step = 1.001;
            match k {
                0 => d.0 *= step,
                1 => d.1 *= step,
                2 => d.2 *= step,
                3 => d.3 *= step,
                4 => load.0 *= step,
                5 => load.1 *= step,
                6 => load.2 *= step,
                _ => {}
            }
            Mech {
                delta_e: Some(d),
                load: Some(load),
                damping_ratio: if k == 7 {
                    base.damping_ratio * 1.001
                } else {
                    base.damping_ratio
                },
                ..base
            }
        })
        .collect();
    let starts = vec![(0.0, 0.0); columns.len()];
    let mut group =
        c.benchmark_group("Jacobian's mechanical columns, ΔE + load, 8 x 3,000 samples");
    group.throughput(Throughput::Elements((SAMPLES * columns.len()) as u64));
    group.bench_function("one by one", |b| {
        b.iter(|| {
            columns
                .iter()
                .map(|m| track_mech(&nominal, black_box(m), &run, SAMPLES, STEP_S, (0.0, 0.0)))
                .collect::<Vec<_>>()
        })
    });
    group.bench_function("side by side", |b| {
        b.iter(|| {
            track_mech_lanes(
                &nominal,
                black_box(&columns),
                &run,
                SAMPLES,
                STEP_S,
                &starts,
            )
        })
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
