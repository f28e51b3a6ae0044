//! Helpers shared by the integration tests: the baked measure, input generators (normalized
//! proptest paths, random field paths, clustered grid lines) and the core model vs reference
//! plant runs on a held current.
#![allow(dead_code)] // each test binary uses a different subset

use host_tests::reference::dynamics::{
    simulate_held, MonotoneHysteresis, PlantConstants, ReferencePlant,
};
use magctl::model::DynamicModel;
use magctl::params::{BAKED_PARAMETERS, BAKED_PARAMETERS_SOURCE};
use magctl::preisach::{PreisachMeasure, PreisachState, LEVELS};
use proptest::prelude::*;
use rand::rngs::Xoshiro256PlusPlus;
use rand::RngExt;

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

/// Grid lines over the baked range, dense around the middle (where a biased actuator's loops
/// reverse) for `power > 1`, equal for `power = 1`, dense at the ends for `power < 1`:
/// `h(t) = c + r · sign(s) |s|^p`, `s = 2t − 1`.
pub fn clustered_lines(power: f64) -> [f32; LEVELS + 1] {
    let p = BAKED_PARAMETERS.preisach;
    let (lo, hi) = (p.h_min_a_per_m as f64, p.h_max_a_per_m as f64);
    let (c, r) = (0.5 * (lo + hi), 0.5 * (hi - lo));
    let mut lines = [0.0f32; LEVELS + 1];
    for (k, line) in lines.iter_mut().enumerate() {
        let s = 2.0 * k as f64 / LEVELS as f64 - 1.0;
        *line = (c + r * s.signum() * s.abs().powf(power)) as f32;
    }
    lines[0] = p.h_min_a_per_m;
    lines[LEVELS] = p.h_max_a_per_m;
    lines
}

/// A piecewise-monotone field path (A/m) with random turning points, some beyond the range, and
/// decaying oscillations around random centres (deep staircases), sampled along each segment.
pub fn field_path(rng: &mut Xoshiro256PlusPlus, measure: &PreisachMeasure) -> Vec<f32> {
    let (lo, hi) = (
        measure.h_min_a_per_m() as f64,
        measure.h_max_a_per_m() as f64,
    );
    let span = hi - lo;
    let mut turning = Vec::new();
    for _ in 0..12 {
        if rng.random::<f64>() < 0.5 {
            turning.push(lo - 0.05 * span + 1.1 * span * rng.random::<f64>());
        } else {
            let centre = lo + span * (0.3 + 0.4 * rng.random::<f64>());
            let mut amplitude = 0.3 * span * rng.random::<f64>();
            let mut sign = 1.0;
            for _ in 0..8 {
                turning.push(centre + sign * amplitude);
                amplitude *= 0.7;
                sign = -sign;
            }
        }
    }
    let mut path = Vec::new();
    let mut from = lo;
    for &to in &turning {
        for n in 1..=6 {
            path.push((from + (to - from) * n as f64 / 6.0) as f32);
        }
        from = to;
    }
    path
}

/// The baked parameter file (f64), read from the path build.rs baked.
pub fn baked_file_params() -> actuator_params::ActuatorParams {
    actuator_params::ActuatorParams::load(std::path::Path::new(BAKED_PARAMETERS_SOURCE))
        .expect("the baked parameter file is readable")
}

/// The core's dynamic model on `measure` at `multiplier × rate_hz`, the current held over each
/// `1 / rate_hz` period, from equilibrium at the first current (demagnetized memory); the
/// displacement at the end of every period.
pub fn core_displacements(
    measure: &PreisachMeasure,
    currents: &[f64],
    rate_hz: f64,
    multiplier: usize,
) -> Vec<f64> {
    let step_s = (1.0 / (rate_hz * multiplier as f64)) as f32;
    let model = DynamicModel::new(measure, &BAKED_PARAMETERS.actuator, step_s);
    let mut state = model.equilibrium::<64>(measure.demagnetized(), currents[0] as f32);
    currents
        .iter()
        .map(|&i| {
            let mut y = 0.0;
            for _ in 0..multiplier {
                y = model.step(&mut state, i as f32).displacement_m as f64;
            }
            y
        })
        .collect()
}

/// The reference plant (the baked file's constants) with `hysteresis`, from equilibrium at the
/// first current, `substeps` RK4 substeps per period; the displacement at the end of every
/// period.
pub fn reference_displacements<P: MonotoneHysteresis + Clone>(
    hysteresis: P,
    currents: &[f64],
    rate_hz: f64,
    substeps: usize,
) -> Vec<f64> {
    let consts = PlantConstants::from_params(&baked_file_params());
    let mut plant = ReferencePlant::equilibrium(consts, hysteresis, currents[0]);
    simulate_held(&mut plant, 1.0 / rate_hz, substeps, currents)
        .iter()
        .map(|s| s.displacement_m)
        .collect()
}

/// Largest absolute difference of two sequences.
pub fn max_abs_diff(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()))
}
