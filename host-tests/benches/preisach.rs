//! Forward update and inverse of the fast core (Everett tables + staircase) against the naive
//! baseline (`naive_apply`: integrate `P₊` over all 325 cells; `naive_solve`: 32-step bisection,
//! each trial a naive forward) on the same input sequence.
//!
//! Run: `cargo bench -p host-tests --bench preisach`. Each benchmark processes a whole sequence
//! per iteration and reports per-element throughput; the ratios are in `BENCHMARKS.md`.
//!
//! The input: 2000 samples of a piecewise-monotone field (free random turning points mixed with
//! decaying bursts of nested reversals, 5-20 samples per monotone piece), staircase depth kept
//! below the capacity (64) so neither side merges. The inverse benchmarks take every 10th output
//! of the forward pass as targets (200 targets), first for `a = 0` (the plain inverse `Γ⁻¹`), then
//! for `a = 10` (the dynamic model's implicit step, `a·h + Γ(h) = r`).

use criterion::{criterion_group, criterion_main, BatchSize, Criterion, Throughput};
use magctl::params::BAKED_PARAMETERS;
use magctl::preisach::baselines::{everett_bisection_invert, RelayGrid};
use magctl::preisach::naive::NaiveState;
use magctl::preisach::{PreisachMeasure, PreisachState, DEMAGNETIZATION_HISTORY, LEVELS};
use rand::rngs::Xoshiro256PlusPlus;
use rand::{RngExt, SeedableRng};
use std::hint::black_box;
use std::time::Duration;

fn measure() -> PreisachMeasure {
    let p = BAKED_PARAMETERS.preisach;
    PreisachMeasure::new(&p.weights_a_per_m, p.h_min_a_per_m, p.h_max_a_per_m)
}

/// The input sequence (A/m), deterministic.
fn inputs(measure: &PreisachMeasure, count: usize) -> Vec<f32> {
    let l = LEVELS as f64;
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(0xbe4c);
    let mut turning = Vec::new();
    while turning.len() < count {
        if rng.random_bool(0.6) {
            turning.push(rng.random_range(0.0..l));
        } else {
            let centre = rng.random_range(4.0..l - 4.0);
            let mut amplitude = rng.random_range(1.0..4.0);
            let mut sign = 1.0;
            for _ in 0..rng.random_range(4..20) {
                turning.push(centre + sign * amplitude);
                amplitude *= 0.85;
                sign = -sign;
            }
        }
    }
    let mut out = Vec::with_capacity(count);
    let mut x = 0.5 * l;
    for to in turning {
        let samples = rng.random_range(5..20);
        for n in 1..=samples {
            let xn = x + (to - x) * n as f64 / samples as f64;
            out.push(
                (measure.h_min_a_per_m() as f64 + xn * measure.cell_width_a_per_m() as f64) as f32,
            );
        }
        x = to;
        if out.len() >= count {
            break;
        }
    }
    out.truncate(count);
    out
}

fn naive_demagnetized(measure: &PreisachMeasure) -> NaiveState {
    // The same history `PreisachMeasure::demagnetized` documents, applied to the naive memory.
    let mut s = NaiveState::negative_saturation();
    let field = |x: f32| measure.h_min_a_per_m() + x * measure.cell_width_a_per_m();
    for &x in DEMAGNETIZATION_HISTORY.iter() {
        measure.naive_apply(&mut s, field(x));
    }
    s
}

fn relay_demagnetized(measure: &PreisachMeasure) -> RelayGrid<'_> {
    let mut g = RelayGrid::new(measure);
    let field = |x: f32| measure.h_min_a_per_m() + x * measure.cell_width_a_per_m();
    for &x in DEMAGNETIZATION_HISTORY.iter() {
        g.apply(field(x));
    }
    g
}

fn bench_forward(c: &mut Criterion) {
    let m = measure();
    let h = inputs(&m, 2000);
    let fast0: PreisachState = m.demagnetized();
    let naive0 = naive_demagnetized(&m);
    let mut group = c.benchmark_group("preisach_forward");
    group.throughput(Throughput::Elements(h.len() as u64));
    group.bench_function("fast_apply", |b| {
        b.iter_batched_ref(
            || fast0.clone(),
            |s| {
                for &x in &h {
                    black_box(m.apply(s, black_box(x)).ok());
                }
            },
            BatchSize::SmallInput,
        )
    });
    group.bench_function("naive_apply", |b| {
        b.iter_batched_ref(
            || naive0.clone(),
            |s| {
                for &x in &h {
                    black_box(m.naive_apply(s, black_box(x)));
                }
            },
            BatchSize::SmallInput,
        )
    });
    group.finish();
}

fn bench_inverse(c: &mut Criterion) {
    let m = measure();
    let h = inputs(&m, 2000);
    let mut s: PreisachState = m.demagnetized();
    let outputs: Vec<f32> = h
        .iter()
        .map(|&x| m.apply(&mut s, x).unwrap_or(0.0))
        .collect();
    let targets: Vec<f32> = outputs.iter().step_by(10).copied().collect();
    let fast0: PreisachState = m.demagnetized();
    let naive0 = naive_demagnetized(&m);
    for a in [0.0f32, 10.0] {
        // For a > 0 the targets are r = a·h + M at the same sampled points.
        let r: Vec<f32> = targets
            .iter()
            .zip(h.iter().step_by(10))
            .map(|(&mm, &hh)| a * hh + mm)
            .collect();
        let mut group = c.benchmark_group(format!("preisach_solve_a{a}"));
        group.throughput(Throughput::Elements(r.len() as u64));
        group.bench_function("fast_solve", |b| {
            b.iter_batched_ref(
                || fast0.clone(),
                |s| {
                    for &t in &r {
                        black_box(m.solve(s, a, black_box(t)).ok());
                    }
                },
                BatchSize::SmallInput,
            )
        });
        group.bench_function("naive_bisection", |b| {
            b.iter_batched_ref(
                || naive0.clone(),
                |s| {
                    for &t in &r {
                        black_box(m.naive_solve(s, a, black_box(t)));
                    }
                },
                BatchSize::SmallInput,
            )
        });
        if a == 0.0 {
            // What peers do (`magctl::preisach::baselines`): the plain inverse only.
            group.bench_function("everett_bisection", |b| {
                b.iter_batched_ref(
                    || fast0.clone(),
                    |s| {
                        for &t in &r {
                            black_box(everett_bisection_invert(&m, s, black_box(t)));
                        }
                    },
                    BatchSize::SmallInput,
                )
            });
            let relay0 = relay_demagnetized(&m);
            group.bench_function("relay_grid_bisection", |b| {
                b.iter_batched_ref(
                    || relay0.clone(),
                    |g| {
                        for &t in &r {
                            black_box(g.invert(black_box(t)));
                        }
                    },
                    BatchSize::SmallInput,
                )
            });
        }
        group.finish();
    }
}

criterion_group! {
    name = benches;
    config = Criterion::default()
        .sample_size(30)
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(3));
    targets = bench_forward, bench_inverse
}
criterion_main!(benches);
