//! The core's states and output for rods the coil cannot saturate, against the independent relay
//! reference: the AC-demagnetized state about any field (`PreisachMeasure::demagnetized_at`)
//! against the ideal region `α + β < 2c`, and the offset `M_off` (`PreisachMeasure::with_offset`),
//! which must move the output and nothing else — the exact inverse stays exact.
//!
//! The ideal demagnetized output is computed here cell by cell, `Σ w_ij (2 a_ij − 1)` with `a_ij`
//! the fraction of cell `(i, j)` below the line `α + β = 2c`, integrated by the midpoint rule on
//! [`STRIPS`] strips per cell (the integrand is piecewise linear with at most two kinks per cell,
//! so the error is at most `2 / STRIPS²` of a cell's area, far below the f32 rounding). Tolerance:
//! the core's f32 output rounding, plus, for a centre neither on a grid line nor in the middle of
//! an interval, the documented `(⌊L/2⌋ + 2) ρ_max / 4`.

mod common;

use common::{baked_measure, field_of};
use host_tests::bounds::output_rounding_a_per_m;
use magctl::preisach::{PreisachMeasure, PreisachState, LEVELS};

/// Midpoint strips per cell side for the ideal state's areas.
const STRIPS: usize = 2000;

/// The output of the ideal demagnetized state `P₊ = {α + β < 2c}` (normalized `c`), A/m.
fn ideal_demagnetized_a_per_m(measure: &PreisachMeasure, c: f64) -> f64 {
    let mut m = 0.0;
    for j in 0..LEVELS {
        for i in 0..=j {
            let w = measure.cell_mass_a_per_m(i, j) as f64;
            if w == 0.0 {
                continue;
            }
            let (area, mut below) = (if i == j { 0.5 } else { 1.0 }, 0.0);
            for s in 0..STRIPS {
                let beta = i as f64 + (s as f64 + 0.5) / STRIPS as f64;
                let bottom = if i == j { beta } else { j as f64 };
                let top = (2.0 * c - beta).min(j as f64 + 1.0);
                below += (top - bottom).max(0.0) / STRIPS as f64;
            }
            m += w * (2.0 * below / area - 1.0);
        }
    }
    m
}

/// `|core − ideal|` for the demagnetized state about normalized `c`, and the tolerance.
fn demagnetized_error(c: f64, extra_a_per_m: f64) -> (f64, f64) {
    let measure = baked_measure();
    let core: PreisachState<256> = measure.demagnetized_at(field_of(&measure, c));
    let c_core = core.input_normalized() as f64;
    assert!((c_core - c).abs() < 1e-4, "input {c_core}, wanted {c}");
    let ideal = ideal_demagnetized_a_per_m(&measure, c_core);
    let error = (measure.output_a_per_m(&core) as f64 - ideal).abs();
    let integration = 2.0 / (STRIPS * STRIPS) as f64 * measure.saturation_a_per_m() as f64;
    let tolerance = output_rounding_a_per_m(&measure, core.len()) + integration + extra_a_per_m;
    (error, tolerance)
}

#[test]
fn demagnetized_about_a_grid_line_or_a_mid_interval_is_the_ideal_state() {
    for c in [0.0, 1.0, 3.0, 12.0, 24.0, 25.0, 0.5, 7.5, 12.5, 20.5] {
        let (error, tolerance) = demagnetized_error(c, 0.0);
        assert!(
            error <= tolerance,
            "c = {c}: error {error:.3} A/m > {tolerance:.3}"
        );
    }
}

#[test]
fn demagnetized_about_any_other_field_is_within_the_documented_bound() {
    let measure = baked_measure();
    let cut_bound = ((LEVELS / 2) as f64 + 2.0) * measure.max_density_a_per_m() as f64 / 4.0;
    for c in [0.3, 3.3, 9.71, 17.2, 24.9] {
        let (error, tolerance) = demagnetized_error(c, cut_bound);
        assert!(
            error <= tolerance,
            "c = {c}: error {error:.3} A/m > {tolerance:.3}"
        );
    }
}

#[test]
fn the_offset_moves_the_output_and_the_inverse_stays_exact() {
    let plain = baked_measure();
    let offset_a_per_m = 0.37 * plain.saturation_a_per_m();
    let shifted = baked_measure().with_offset(offset_a_per_m);
    let (lo, hi) = shifted.output_range_a_per_m();
    assert_eq!(lo, offset_a_per_m - plain.saturation_a_per_m());
    assert_eq!(hi, offset_a_per_m + plain.saturation_a_per_m());
    let mut a: PreisachState<64> = plain.demagnetized();
    let mut b: PreisachState<64> = shifted.demagnetized();
    let rounding = 4.0 * f32::EPSILON as f64 * (plain.saturation_a_per_m() + offset_a_per_m) as f64;
    for x in [3.0, 20.0, 7.5, 15.0, 11.0, 24.0, 0.5, 13.0] {
        let h = field_of(&plain, x);
        let ma = plain.apply(&mut a, h).unwrap();
        let mb = shifted.apply(&mut b, h).unwrap();
        assert!(
            ((mb - ma) as f64 - offset_a_per_m as f64).abs() <= rounding,
            "x = {x}: {mb} vs {ma} + {offset_a_per_m}"
        );
    }
    // The inverse of the shifted operator reaches the target from the same memory as the
    // plain one reaches the target less the offset.
    for fraction in [0.2f32, -0.5, 0.9, 0.0, 0.6] {
        let target = offset_a_per_m + fraction * plain.saturation_a_per_m();
        let sa = plain.invert(&mut a, target - offset_a_per_m).unwrap();
        let sb = shifted.invert(&mut b, target).unwrap();
        assert!((sb.m_a_per_m - target).abs() as f64 <= 2.0 * rounding);
        assert!(
            (sb.h_a_per_m - sa.h_a_per_m).abs() <= 1e-3 * plain.cell_width_a_per_m(),
            "{fraction}: {} vs {}",
            sb.h_a_per_m,
            sa.h_a_per_m
        );
    }
}
