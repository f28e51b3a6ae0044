//! The core on a grid with unequal intervals (`PreisachMeasure::with_lines`) against
//! the independent f64 relay reference built on the same lines (`RelayPreisach::with_lines`),
//! driven **in the field** (A/m), so the two maps between the field and the normalized input —
//! the core's f32 piecewise-affine `normalize`/`denormalize`, the reference's f64 one — are part
//! of what is compared.
//!
//! # Tolerances
//!
//! * Input map: the core's normalized input of a field is within `4 u L`
//!   ([`input_rounding_normalized`]) of the reference's (one subtraction, one multiplication by
//!   the stored inverse width, one addition: three roundings of values `<= L`, and the f32
//!   inverse width's own rounding).
//! * Output: the reference's discretization bound (k relays per cell side) plus the core's
//!   rounding ([`output_rounding_a_per_m`]) plus the reference's running-sum rounding, plus the
//!   effect of the input-map difference: every stored reversal point and the current input may
//!   sit `4 u L` apart in the two operators, each moving the output by at most
//!   `2 λ · 4 u L` (λ = [`line_density_bound_a_per_m`], the largest mass per unit normalized
//!   length along a grid line), so `2 λ · 4 u L · (len + 1)`.
//! * Inverse and solve: the residual `|a·h + M − r|` within [`solve_rounding_a_per_m`] (whose
//!   `aΔ` term takes the widest interval), and the field returned maps back to the committed
//!   normalized input within `4 u L`.

mod common;

use common::{clustered_lines, field_path};
use host_tests::bounds::{
    input_rounding_normalized, line_density_bound_a_per_m, output_rounding_a_per_m,
    relay_sum_rounding_a_per_m, solve_rounding_a_per_m,
};
use host_tests::reference::preisach::{RelayPreisach, RelayState};
use magctl::params::BAKED_PARAMETERS;
use magctl::preisach::{PreisachMeasure, PreisachState, LEVELS};
use rand::rngs::Xoshiro256PlusPlus;
use rand::{RngExt, SeedableRng};

fn measures(power: f64, k: usize) -> (PreisachMeasure, RelayPreisach) {
    let p = BAKED_PARAMETERS.preisach;
    let lines = clustered_lines(power);
    let measure = PreisachMeasure::with_lines(&p.weights_a_per_m, &lines);
    let w: Vec<f64> = p.weights_a_per_m.iter().map(|&w| w as f64).collect();
    let lines64: Vec<f64> = lines.iter().map(|&h| h as f64).collect();
    let reference = RelayPreisach::with_lines(&w, &lines64, k).expect("valid lines");
    (measure, reference)
}

#[test]
fn equally_spaced_lines_give_the_uniform_grid_bit_for_bit() {
    let p = BAKED_PARAMETERS.preisach;
    let uniform = PreisachMeasure::new(&p.weights_a_per_m, p.h_min_a_per_m, p.h_max_a_per_m);
    let width = (p.h_max_a_per_m as f64 - p.h_min_a_per_m as f64) / LEVELS as f64;
    let mut lines = [0.0f32; LEVELS + 1];
    for (k, line) in lines.iter_mut().enumerate() {
        *line = (p.h_min_a_per_m as f64 + k as f64 * width) as f32;
    }
    let same = PreisachMeasure::with_lines(&p.weights_a_per_m, &lines);
    assert!(same.is_uniform());
    assert_eq!(same, uniform);
    let clustered = PreisachMeasure::with_lines(&p.weights_a_per_m, &clustered_lines(1.6));
    assert!(!clustered.is_uniform());
    assert!(clustered.narrowest_interval_a_per_m() < 0.5 * uniform.cell_width_a_per_m());
}

#[test]
fn the_field_maps_agree_with_the_reference_and_invert_each_other() {
    let (measure, reference) = measures(1.6, 4);
    let lines = measure.grid_lines_a_per_m();
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(13);
    let tolerance = input_rounding_normalized();
    let mut fields: Vec<f32> = lines.to_vec();
    fields.extend((0..5000).map(|_| {
        let (lo, hi) = (lines[0] as f64, lines[LEVELS] as f64);
        (lo - 0.1 * (hi - lo) + 1.2 * (hi - lo) * rng.random::<f64>()) as f32
    }));
    for h in fields {
        let mut state: PreisachState = measure.negative_saturation();
        measure.apply(&mut state, h).expect("finite");
        let x_core = state.input_normalized() as f64;
        let x_ref = reference.normalize(h as f64).clamp(0.0, LEVELS as f64);
        assert!(
            (x_core - x_ref).abs() <= tolerance,
            "h = {h}: core x {x_core}, reference x {x_ref}"
        );
        // Back to the field: the committed input's field is h within the same rounding.
        let back = measure.input_a_per_m(&state) as f64;
        let expected = reference.field_of(x_core);
        let width = measure.widest_interval_a_per_m() as f64;
        assert!(
            (back - expected).abs() <= tolerance * width,
            "x = {x_core}: core field {back}, reference {expected}"
        );
    }
}

fn compare_forward(power: f64, k: usize, seed: u64) -> f64 {
    let (measure, reference) = measures(power, k);
    let bound = reference.discretization_bound_a_per_m();
    let lambda = line_density_bound_a_per_m(&measure);
    let total = reference.saturation_a_per_m();
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
    let mut worst = 0.0f64;
    for demagnetized in [false, true] {
        let (mut core, mut relay): (PreisachState, RelayState) = if demagnetized {
            (measure.demagnetized(), reference.demagnetized())
        } else {
            (
                measure.negative_saturation(),
                reference.negative_saturation(),
            )
        };
        for h in field_path(&mut rng, &measure) {
            let m_core = measure.apply(&mut core, h).expect("finite") as f64;
            let x_ref = reference.normalize(h as f64);
            let m_ref = reference.apply_normalized(&mut relay, x_ref);
            let tol = bound
                + output_rounding_a_per_m(&measure, core.len())
                + relay_sum_rounding_a_per_m(total, relay.switch_count(), reference.relay_count())
                + 2.0 * lambda * input_rounding_normalized() * (core.len() + 1) as f64;
            let error = (m_core - m_ref).abs();
            assert!(
                error <= tol,
                "power {power}, k {k}, h {h}: core {m_core}, reference {m_ref}, error {error} > {tol}"
            );
            assert!(
                core.merges() == 0,
                "the staircase merged: the test needs more capacity"
            );
            worst = worst.max(error / tol);
        }
    }
    worst
}

#[test]
fn forward_in_the_field_matches_the_relay_reference() {
    for (power, k, seed) in [(1.6, 4, 1), (1.6, 16, 2), (2.5, 8, 3), (0.7, 8, 4)] {
        let worst = compare_forward(power, k, seed);
        println!(
            "lines power {power}, {k} relays per cell side: worst error / tolerance {worst:.3}"
        );
    }
}

#[test]
fn inverse_and_solve_hold_on_a_nonuniform_grid() {
    let (measure, _) = measures(1.6, 4);
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(7);
    let w = measure.saturation_a_per_m() as f64;
    for trial in 0..2000 {
        let mut state: PreisachState = measure.demagnetized();
        for h in field_path(&mut rng, &measure).into_iter().take(40) {
            measure.apply(&mut state, h).expect("finite");
        }
        let a = if trial % 2 == 0 {
            0.0
        } else {
            40.0 * rng.random::<f64>()
        };
        let r = (2.0 * rng.random::<f64>() - 1.0) * 0.98 * w;
        let original = state.clone();
        let sol = measure
            .solve(&mut state, a as f32, r as f32)
            .expect("finite");
        let (h, m) = (sol.h_a_per_m as f64, sol.m_a_per_m as f64);
        let tol = solve_rounding_a_per_m(&measure, a, r, h);
        assert!(
            (a * h + m - r).abs() <= tol,
            "trial {trial}: a {a}, r {r}: a·h + M = {}, residual {} > {tol}",
            a * h + m,
            (a * h + m - r).abs()
        );
        // The field returned is the committed input's field.
        assert_eq!(sol.h_a_per_m, measure.input_a_per_m(&state));
        // Applying it to the original state lands on the same normalized input.
        let mut again = original.clone();
        measure.apply(&mut again, sol.h_a_per_m).expect("finite");
        let dx = (again.input_normalized() - state.input_normalized()).abs() as f64;
        assert!(
            dx <= input_rounding_normalized(),
            "trial {trial}: re-applied input off by {dx}"
        );
    }
}
