//! The fast operator (Everett tables) against the naive one (per-cell area integration) on the
//! same inputs: both compute the same exact operator, so they agree to f32 rounding.

use magctl::params::BAKED_PARAMETERS;
use magctl::preisach::naive::NaiveState;
use magctl::preisach::{PreisachMeasure, PreisachState};

fn measure() -> PreisachMeasure {
    let p = BAKED_PARAMETERS.preisach;
    PreisachMeasure::new(&p.weights_a_per_m, p.h_min_a_per_m, p.h_max_a_per_m)
}

/// f32 tolerance: the naive sum accumulates ~400 products of magnitude <= Σ w; the fast path a
/// handful. 2⁻²⁴ · 400 · Σ w is a conservative bound on the rounding difference.
fn tolerance(m: &PreisachMeasure) -> f32 {
    400.0 * f32::EPSILON * 0.5 * m.saturation_a_per_m()
}

#[test]
fn saturation_states_give_plus_minus_total() {
    let m = measure();
    let mut s: PreisachState = m.negative_saturation();
    assert!((m.output_a_per_m(&s) + m.saturation_a_per_m()).abs() < 1.0);
    let out = m.apply(&mut s, 1.0e9).unwrap();
    assert!((out - m.saturation_a_per_m()).abs() < 1.0, "{out}");
    let out = m.apply(&mut s, -1.0e9).unwrap();
    assert!((out + m.saturation_a_per_m()).abs() < 1.0, "{out}");
}

#[test]
fn fast_matches_naive_on_nested_loops() {
    let m = measure();
    let mut fast: PreisachState = m.negative_saturation();
    let mut naive: NaiveState = NaiveState::negative_saturation();
    let tol = tolerance(&m);
    let inputs = [
        25e3, -20e3, 15e3, -10e3, 8e3, -3e3, 5e3, 1e3, 2.7e3, -2.1e4, 3e4, 4e4, -1.3e4, 1.2e3,
        7.77e3, -29e3, 0.0,
    ];
    for (k, &h) in inputs.iter().enumerate() {
        // Sweep there in small steps so every piece is exercised.
        let start = m.input_a_per_m(&fast);
        for step in 1..=37 {
            let hh = start + (h - start) * step as f32 / 37.0;
            let a = m.apply(&mut fast, hh).unwrap();
            let b = m.naive_apply(&mut naive, hh);
            assert!(
                (a - b).abs() <= tol,
                "input {k} step {step}: fast {a} naive {b} (tol {tol})"
            );
        }
    }
}

#[test]
fn inverse_round_trips() {
    let m = measure();
    let mut s: PreisachState = m.demagnetized();
    let targets = [1e5, -3e5, 2e5, 1.5e5, 1.7e5, -7e5, 7.86e5, 0.0, 3.3e5, -1.0];
    for &t in &targets {
        let before = s.clone();
        let sol = m.invert(&mut s, t).unwrap();
        assert!(
            (sol.m_a_per_m - t).abs() <= 8.0 * f32::EPSILON * m.saturation_a_per_m(),
            "target {t}: {sol:?}"
        );
        let mut check = before.clone();
        let fwd = m.apply(&mut check, sol.h_a_per_m).unwrap();
        assert!(
            (fwd - t).abs() <= 16.0 * f32::EPSILON * m.saturation_a_per_m(),
            "target {t}: forward {fwd}"
        );
    }
}

#[test]
fn demagnetized_output_is_zero_for_symmetric_measure() {
    let m = measure();
    let s: PreisachState = m.demagnetized();
    // The baked default measure is symmetric about the middle of the range, so the ideal
    // demagnetized output is 0, and the history reproduces the ideal state exactly: only the f32
    // rounding of one output with the demagnetized staircase remains.
    let out = m.output_a_per_m(&s);
    let tol = host_tests::bounds::output_rounding_a_per_m(&m, s.len()) as f32;
    assert!(out.abs() <= tol, "demag output {out} A/m, tolerance {tol}");
}
