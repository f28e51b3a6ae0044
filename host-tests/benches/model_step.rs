//! Cost of one dynamic-model step (`magctl::model::DynamicModel::step`) on the host.
//!
//! Drives the model with a biased 200 Hz sine at 10 kHz (reversals every 25 steps, the rate-
//! dependent regime the model exists for) and a band-limited random current. Throughput target
//! ≥ 5 million steps/s on one core.
//!
//! Run: `cargo bench -p host-tests --bench model_step`.

use criterion::{criterion_group, criterion_main, BatchSize, Criterion, Throughput};
use magctl::model::{DynamicModel, StaticModel};
use magctl::params::{BAKED_MEASURE, BAKED_PARAMETERS};
use std::hint::black_box;

const STEPS: usize = 10_000;

fn currents_sine() -> Vec<f32> {
    (0..STEPS)
        .map(|k| 0.5 + 0.45 * (2.0 * std::f32::consts::PI * 200.0 * k as f32 * 1e-4).sin())
        .collect()
}

fn currents_random() -> Vec<f32> {
    let mut s = 0x1234_5678_u32;
    let mut x = 0.5f32;
    (0..STEPS)
        .map(|_| {
            s ^= s << 13;
            s ^= s >> 17;
            s ^= s << 5;
            let r = (s as f32 / u32::MAX as f32) - 0.5;
            x = (0.95 * x + 0.05 * (0.5 + 0.9 * r)).clamp(0.0, 1.0);
            x
        })
        .collect()
}

fn bench(c: &mut Criterion) {
    let actuator = &BAKED_PARAMETERS.actuator;
    let model = DynamicModel::new(&BAKED_MEASURE, actuator, 1e-4);
    let statics = StaticModel::new(&BAKED_MEASURE, actuator);
    let mut group = c.benchmark_group("model_step");
    group.throughput(Throughput::Elements(STEPS as u64));
    for (name, currents) in [
        ("dynamic_sine_200hz", currents_sine()),
        ("dynamic_random", currents_random()),
    ] {
        let start = model.equilibrium::<64>(BAKED_MEASURE.demagnetized(), 0.5);
        group.bench_function(name, |b| {
            b.iter_batched_ref(
                || start.clone(),
                |state| {
                    for &i in &currents {
                        black_box(model.step(state, black_box(i)));
                    }
                },
                BatchSize::SmallInput,
            )
        });
    }
    let start = model.equilibrium::<64>(BAKED_MEASURE.demagnetized(), 0.5);
    let currents = currents_sine();
    group.bench_function("static_sine_200hz", |b| {
        b.iter_batched_ref(
            || start.clone(),
            |state| {
                for &i in &currents {
                    black_box(statics.step(state, black_box(i)));
                }
            },
            BatchSize::SmallInput,
        )
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
