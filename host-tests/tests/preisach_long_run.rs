//! 10⁶ random input steps on a bounded staircase: it never overflows, every merge stays within
//! `merge_error_bound_a_per_m(N)`, and the output stays within the accumulated merge error of an
//! (effectively) unbounded memory, `PreisachState<4096>`, driven by the same input.
//!
//! # Input
//!
//! A random walk in normalized units: each step reverses direction with probability 0.3 and moves
//! by a log-uniform amount in `[10⁻⁶, 1]` cells; 1 % of steps jump up to the whole range
//! (past an end it stops up to 0.01 cell beyond, saturating, and turns back); a fraction (10⁻⁴ for
//! the 10⁶-step run, 10⁻³ for the small capacities) starts a burst of 40-150 decaying reversals
//! (each amplitude 0.9-0.99 times the last), which nests that many minor loops and overflows the
//! capacity.
//!
//! # Tolerances
//!
//! A merge removes one corner rectangle from `P₊` (or adds it) and accounts `2 μ(rect)` exactly
//! in `merge_error_a_per_m`. Afterwards each relay either is switched by later input (then both
//! memories agree on it) or keeps its state, so the region where the two memories differ only
//! shrinks: `|M_N - M_big| <= Σ merge errors` since the two last agreed. They agree exactly
//! whenever the input reaches the end of the range (both memories are then the bare anchor), so
//! the sum is taken since the last saturation. Rounding (see `host_tests::bounds`):
//! `E(len_N) + E(len_big)` for the two outputs, plus `2 · 2 u Σw` per merge since the last
//! saturation (each merge shifts the later running sums by a rounded difference, two roundings),
//! plus `2 u` times the accumulated f32 merge-error sum per merge for its own accumulation.
//!
//! Each single merge: `2 |Δμ| <= 2 ρ_max (2L / (N - 2))²` (the core's documented bound), its
//! computed value off by at most `2 E(len)` plus the shift roundings above.

mod common;

use common::baked_measure;
use host_tests::bounds::{output_rounding_a_per_m, F32_UNIT_ROUNDOFF};
use magctl::preisach::{cell_of_index, PreisachMeasure, PreisachState, CELL_COUNT, LEVELS};
use rand::rngs::Xoshiro256PlusPlus;
use rand::{RngExt, SeedableRng};

const L: f64 = LEVELS as f64;

/// The random input generator described in the module docs.
struct RandomInput {
    rng: Xoshiro256PlusPlus,
    x: f64,
    up: bool,
    burst: Option<(f64, f64, f64, u32)>, // centre, amplitude, ratio, remaining
    burst_probability: f64,
}

impl RandomInput {
    fn new(seed: u64, burst_probability: f64) -> Self {
        RandomInput {
            rng: Xoshiro256PlusPlus::seed_from_u64(seed),
            x: 0.5 * L,
            up: true,
            burst: None,
            burst_probability,
        }
    }

    fn next(&mut self) -> f64 {
        if let Some((centre, amplitude, ratio, remaining)) = self.burst {
            self.x = centre
                + if remaining % 2 == 0 {
                    amplitude
                } else {
                    -amplitude
                };
            self.burst =
                (remaining > 1).then_some((centre, amplitude * ratio, ratio, remaining - 1));
            return self.x;
        }
        let roll: f64 = self.rng.random();
        if roll < self.burst_probability {
            let centre = self.rng.random_range(3.0..L - 3.0);
            let amplitude = self.rng.random_range(0.5..3.0);
            let ratio = self.rng.random_range(0.9..0.99);
            let count = self.rng.random_range(40..150);
            self.burst = Some((centre, amplitude, ratio, count));
            return self.next();
        }
        if self.rng.random_bool(0.3) {
            self.up = !self.up;
        }
        let size = if roll < 0.01 + self.burst_probability {
            self.rng.random_range(0.0..L + 2.0)
        } else {
            10f64.powf(self.rng.random_range(-6.0..0.0))
        };
        self.x += if self.up { size } else { -size };
        // Past an end of the range the memory saturates: stop at a point up to 0.01 cell beyond
        // it and turn back.
        if self.x > L || self.x < 0.0 {
            let overshoot = self.rng.random_range(0.0..0.01);
            self.x = if self.x > L {
                L + overshoot
            } else {
                -overshoot
            };
            self.up = self.x < 0.0;
        }
        self.x
    }
}

struct RunStats {
    merges: u32,
    max_deviation: f64,
    max_merge_error: f64,
    max_len_big: usize,
    saturations: u32,
}

/// Drives a capacity-`N` state and a capacity-4096 state with `steps` inputs, checking the
/// overflow, per-merge and deviation bounds at every step.
fn run<const N: usize>(
    measure: &PreisachMeasure,
    steps: usize,
    seed: u64,
    burst_probability: f64,
) -> RunStats {
    let mut input = RandomInput::new(seed, burst_probability);
    let mut small: PreisachState<N> = measure.demagnetized();
    let mut big: PreisachState<4096> = measure.demagnetized();
    let u = F32_UNIT_ROUNDOFF;
    let w = measure.saturation_a_per_m() as f64;
    let bound = measure.merge_error_bound_a_per_m(N) as f64;
    let (mut merges_at_sync, mut error_at_sync) = (0u32, 0.0f64);
    let mut stats = RunStats {
        merges: 0,
        max_deviation: 0.0,
        max_merge_error: 0.0,
        max_len_big: 0,
        saturations: 0,
    };
    for step in 0..steps {
        let x = input.next();
        let h = (measure.h_min_a_per_m() as f64 + x * measure.cell_width_a_per_m() as f64) as f32;
        let (merges_before, error_before) = (small.merges(), small.merge_error_a_per_m() as f64);
        let len_before = small.len();
        let m_small = measure.apply(&mut small, h).expect("finite") as f64;
        let m_big = measure.apply(&mut big, h).expect("finite") as f64;
        assert!(small.len() <= N, "step {step}: staircase overflow");
        assert_eq!(big.merges(), 0, "step {step}: the reference memory merged");
        stats.max_len_big = stats.max_len_big.max(big.len());
        let merges_now = small.merges();
        let error_now = small.merge_error_a_per_m() as f64;
        let since_sync = (merges_now - merges_at_sync) as f64;
        let shift_rounding = 4.0 * u * w * since_sync;
        let accumulation_rounding = 2.0 * u * error_now * since_sync.max(1.0);
        assert!(
            merges_now - merges_before <= 1,
            "one reversal, at most one merge"
        );
        if merges_now > merges_before {
            let e = error_now - error_before;
            let tol = 2.0 * output_rounding_a_per_m(measure, len_before.max(small.len()))
                + shift_rounding
                + 2.0 * u * error_now;
            assert!(
                e <= bound + tol,
                "step {step}: one merge changed M by {e} > bound {bound} (+{tol})"
            );
            stats.max_merge_error = stats.max_merge_error.max(e);
        }
        let deviation = (m_small - m_big).abs();
        let tol = (error_now - error_at_sync)
            + accumulation_rounding
            + shift_rounding
            + output_rounding_a_per_m(measure, small.len())
            + output_rounding_a_per_m(measure, big.len());
        assert!(
            deviation <= tol,
            "step {step}: |M_{N} - M_4096| = {deviation} > accumulated merge error {} (+rounding)",
            error_now - error_at_sync
        );
        stats.max_deviation = stats.max_deviation.max(deviation);
        let x_core = small.input_normalized();
        if x_core <= 0.0 || x_core >= LEVELS as f32 {
            // Saturated: both memories are the bare anchor (checked), the outputs agree again.
            assert_eq!(small.len(), 1);
            assert_eq!(big.len(), 1);
            merges_at_sync = merges_now;
            error_at_sync = error_now;
            stats.saturations += 1;
        }
    }
    stats.merges = small.merges();
    stats
}

/// The default capacity (64) with the baked measure, 10⁶ steps.
#[test]
fn million_steps_capacity_64_never_overflows_and_stays_within_merge_error() {
    let measure = baked_measure();
    let stats = run::<64>(&measure, 1_000_000, 0x1e6, 1e-4);
    println!(
        "N = 64: {} merges, max single merge {:.3} A/m (bound {:.1}), max |M_64 - M_4096| {:.3} A/m, \
         deepest unbounded staircase {} vertices, {} saturations",
        stats.merges,
        stats.max_merge_error,
        measure.merge_error_bound_a_per_m(64),
        stats.max_deviation,
        stats.max_len_big,
        stats.saturations
    );
    // The bursts must actually overflow 64 and the walk must reach saturation to resynchronize,
    // or the test has not exercised what it claims.
    assert!(stats.merges > 100, "only {} merges", stats.merges);
    assert!(stats.max_len_big > 64);
    assert!(stats.saturations > 10);
}

/// A uniform density (every point of the plane weighs the same), for which a merge's error is
/// exactly `2 ρ · area`: the bound then tests the choice of the smallest rectangle itself.
fn uniform_measure() -> PreisachMeasure {
    let mut w = [0.0f32; CELL_COUNT];
    for (idx, m) in w.iter_mut().enumerate() {
        let (i, j) = cell_of_index(idx).expect("index in range");
        *m = if i == j { 500.0 } else { 1000.0 };
    }
    PreisachMeasure::new(&w, -3.0e4, 3.0e4)
}

/// Small capacities merge on almost every burst reversal: the per-merge bound and the
/// deviation bound hold there too (baked and uniform densities).
#[test]
fn small_capacities_merge_often_within_bound() {
    for (name, measure) in [("baked", baked_measure()), ("uniform", uniform_measure())] {
        let s8 = run::<8>(&measure, 200_000, 8, 1e-3);
        let s16 = run::<16>(&measure, 200_000, 16, 1e-3);
        for (n, s) in [(8usize, &s8), (16, &s16)] {
            println!(
                "{name}, N = {n}: {} merges, max single merge {:.1} A/m (bound {:.1}), \
                 max |M_N - M_4096| {:.1} A/m",
                s.merges,
                s.max_merge_error,
                measure.merge_error_bound_a_per_m(n),
                s.max_deviation
            );
            assert!(s.merges > 1000, "{name}, N = {n}: only {} merges", s.merges);
        }
    }
}
