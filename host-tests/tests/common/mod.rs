//! Helpers shared by the `preisach_*` integration tests: the baked measure and input generators.
#![allow(dead_code)] // each test binary uses a different subset

use magctl::params::BAKED_PARAMETERS;
use magctl::preisach::{PreisachMeasure, PreisachState, LEVELS};
use proptest::prelude::*;

/// The measure baked into this build.
pub fn baked_measure() -> PreisachMeasure {
    BAKED_PARAMETERS.preisach.measure()
}

/// Field (A/m, f32) of normalized input `x` for `measure`.
pub fn field_of(measure: &PreisachMeasure, x: f64) -> f32 {
    (measure.h_min_a_per_m() as f64 + x * measure.cell_width_a_per_m() as f64) as f32
}

/// Turning points of a piecewise-monotone input, normalized units; a little beyond `[0, L]` on
/// both sides so saturation (and the core's clamping) is exercised.
pub fn turning_points(max_len: usize) -> impl Strategy<Value = Vec<f64>> {
    let l = LEVELS as f64;
    let free = proptest::collection::vec(-1.0..(l + 1.0), 1..max_len);
    // Decaying oscillations build deep staircases of nested minor loops.
    let nested = (
        2.0..(l - 2.0),
        0.5..12.0f64,
        0.5..0.98f64,
        2..max_len,
        any::<bool>(),
    )
        .prop_map(move |(centre, amplitude, ratio, count, up)| {
            let mut a = amplitude;
            let mut sign = if up { 1.0 } else { -1.0 };
            let mut v = Vec::with_capacity(count);
            for _ in 0..count {
                v.push((centre + sign * a).clamp(-1.0, l + 1.0));
                a *= ratio;
                sign = -sign;
            }
            v
        });
    prop_oneof![free, nested]
}

/// The samples of the piecewise-linear input through `points`, starting from `start`, with
/// `samples` evenly spaced samples per monotone piece (the last one exactly the turning point, so
/// paths sampled at different rates share their turning points bit for bit).
pub fn sample_path(start: f64, points: &[f64], samples: usize) -> Vec<f64> {
    let mut out = Vec::with_capacity(points.len() * samples);
    let mut from = start;
    for &to in points {
        for n in 1..samples {
            out.push(from + (to - from) * n as f64 / samples as f64);
        }
        out.push(to);
        from = to;
    }
    out
}

/// Applies a normalized input (through its f32 field value) and returns `(x_core, M_core)`.
pub fn core_apply<const N: usize>(
    measure: &PreisachMeasure,
    state: &mut PreisachState<N>,
    x: f64,
) -> (f64, f64) {
    let m = measure
        .apply(state, field_of(measure, x))
        .expect("finite input");
    (state.input_normalized() as f64, m as f64)
}
