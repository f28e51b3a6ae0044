//! The core's reversible part (`PreisachMeasure::with_reversible`:
//! `M = Γ[H] + R(H)`, `R` monotone piecewise linear with a free slope per grid interval) against
//! its definition evaluated independently in f64 (`reference::preisach::reversible_a_per_m`, from
//! the field, no tables) on top of the relay reference, and the exact inverse and solve with it.
//!
//! # Tolerances
//!
//! The tolerances are those of `preisach_nonuniform.rs` (reference discretization, the core's f32
//! rounding, the input-map difference), whose formulas in `host_tests::bounds` carry `R`'s terms
//! (its rounding, `4 u Σρ` per evaluation; the slope `2 λ + ρ_max` along which an input error
//! moves the output; the solve's linear coefficient gaining `ρ_k`). `R` alone is compared with
//! its definition within its rounding plus `ρ_max` times the input-map difference `4 u L`.
//!
//! The dynamic model with `R` is compared with the RK4 reference whose solve of
//! `a·h + Γ(h) + R(h) = r` walks `R`'s linear pieces with the relay operator's exact solve
//! (`reference::dynamics::ReversibleRelayHysteresis`), under the derived budget of `dynamics.rs`.

mod common;

use common::{
    clustered_lines, core_displacements, field_path, max_abs_diff, reference_displacements,
};
use host_tests::bounds::{
    input_rounding_normalized, model_rounding_m, output_rounding_a_per_m,
    output_slope_bound_a_per_m, relay_sum_rounding_a_per_m, reversible_rises_a_per_m,
    reversible_rounding_a_per_m, solve_rounding_a_per_m, F32_UNIT_ROUNDOFF,
};
use host_tests::reference::dynamics::{RelayHysteresis, ReversibleRelayHysteresis};
use host_tests::reference::preisach::{reversible_a_per_m, RelayPreisach, RelayState};
use magctl::params::BAKED_PARAMETERS;
use magctl::preisach::{PreisachMeasure, PreisachState, Saturation, LEVELS};
use rand::rngs::Xoshiro256PlusPlus;
use rand::{RngExt, SeedableRng};
use std::f64::consts::PI;

/// Susceptibility profiles whose reversible part spans `share × Σw` over the grid: a bell
/// (an anhysteretic curve, steep in the middle), a constant (the paper's `χ_r H`), and random.
fn susceptibility(
    profile: &str,
    lines: &[f32; LEVELS + 1],
    share: f64,
    seed: u64,
) -> [f32; LEVELS] {
    let total: f64 = BAKED_PARAMETERS
        .preisach
        .weights_a_per_m
        .iter()
        .map(|&w| w as f64)
        .sum();
    let (lo, hi) = (lines[0] as f64, lines[LEVELS] as f64);
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
    let shape: Vec<f64> = (0..LEVELS)
        .map(|k| {
            let mid = 0.5 * (lines[k] as f64 + lines[k + 1] as f64);
            match profile {
                "bell" => 1.0 / (4.0 * (mid - 0.5 * (lo + hi)) / (hi - lo)).cosh().powi(2),
                "constant" => 1.0,
                _ => rng.random::<f64>() * if rng.random::<f64>() < 0.2 { 0.0 } else { 1.0 },
            }
        })
        .collect();
    let rise: f64 = (0..LEVELS)
        .map(|k| shape[k] * (lines[k + 1] - lines[k]) as f64)
        .sum();
    let scale = 2.0 * share * total / rise;
    std::array::from_fn(|k| (shape[k] * scale) as f32)
}

struct Case {
    measure: PreisachMeasure,
    reference: RelayPreisach,
    lines64: Vec<f64>,
    chi64: Vec<f64>,
}

fn case(power: f64, profile: &str, share: f64, k: usize, seed: u64) -> Case {
    let p = BAKED_PARAMETERS.preisach;
    let lines = clustered_lines(power);
    let chi = susceptibility(profile, &lines, share, seed);
    let measure = PreisachMeasure::with_lines(&p.weights_a_per_m, &lines).with_reversible(&chi);
    let w: Vec<f64> = p.weights_a_per_m.iter().map(|&w| w as f64).collect();
    let lines64: Vec<f64> = lines.iter().map(|&h| h as f64).collect();
    Case {
        reference: RelayPreisach::with_lines(&w, &lines64, k).expect("valid lines"),
        measure,
        lines64,
        chi64: chi.iter().map(|&c| c as f64).collect(),
    }
}

/// No reversible part (all `χ = 0`) is the measure without one, bit for bit, in every operation.
#[test]
fn zero_susceptibility_changes_nothing() {
    let p = BAKED_PARAMETERS.preisach;
    let plain = PreisachMeasure::new(&p.weights_a_per_m, p.h_min_a_per_m, p.h_max_a_per_m);
    let zero = plain.clone().with_reversible(&[0.0; LEVELS]);
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(5);
    let (mut a, mut b): (PreisachState, PreisachState) =
        (plain.demagnetized(), zero.demagnetized());
    let w = plain.saturation_a_per_m();
    assert_eq!(w.to_bits(), zero.saturation_a_per_m().to_bits());
    for (n, h) in field_path(&mut rng, &plain).into_iter().enumerate() {
        let (ma, mb) = (
            plain.apply(&mut a, h).unwrap(),
            zero.apply(&mut b, h).unwrap(),
        );
        assert_eq!(ma.to_bits(), mb.to_bits(), "apply {h}");
        let r = w * (2.0 * rng.random::<f32>() - 1.0);
        let slope = if n % 2 == 0 { 0.0 } else { 30.0 };
        let (sa, sb) = (
            plain.solve(&mut a, slope, r).unwrap(),
            zero.solve(&mut b, slope, r).unwrap(),
        );
        assert_eq!(sa.h_a_per_m.to_bits(), sb.h_a_per_m.to_bits());
        assert_eq!(sa.m_a_per_m.to_bits(), sb.m_a_per_m.to_bits());
        assert_eq!(a, b);
    }
}

/// `R` alone (no masses) is its definition: at every grid line, between lines, beyond the grid.
#[test]
fn the_reversible_part_is_its_definition() {
    for (power, profile) in [(1.0, "bell"), (1.7, "random"), (0.7, "constant")] {
        let c = case(power, profile, 0.3, 1, 9);
        let rises = reversible_rises_a_per_m(&c.measure);
        let rise_max = rises.iter().cloned().fold(0.0, f64::max);
        let tol = reversible_rounding_a_per_m(&c.measure) + rise_max * input_rounding_normalized();
        let (lo, hi) = (c.lines64[0], c.lines64[LEVELS]);
        let mut fields: Vec<f64> = c.lines64.clone();
        fields
            .extend((0..=2000).map(|n| lo - 0.1 * (hi - lo) + 1.2 * (hi - lo) * n as f64 / 2000.0));
        for h in fields {
            let core = c.measure.reversible_a_per_m(h as f32) as f64;
            let reference = reversible_a_per_m(&c.lines64, &c.chi64, (h as f32) as f64);
            assert!(
                (core - reference).abs() <= tol,
                "{profile}, h = {h}: core {core}, definition {reference}"
            );
        }
        // Saturation: Σw + ½Σρ.
        let expected = c.reference.saturation_a_per_m() + 0.5 * rises.iter().sum::<f64>();
        assert!(
            (c.measure.saturation_a_per_m() as f64 - expected).abs()
                <= 4.0 * F32_UNIT_ROUNDOFF * expected
        );
    }
}

/// Forward in the field: core `Γ + R` against the relay reference plus `R`'s definition.
#[test]
fn forward_matches_the_reference_plus_the_definition() {
    for (power, profile, seed) in [(1.0, "bell", 1), (1.6, "random", 2), (0.7, "constant", 3)] {
        let c = case(power, profile, 0.4, 8, seed);
        let bound = c.reference.discretization_bound_a_per_m();
        let slope = output_slope_bound_a_per_m(&c.measure);
        let total = c.reference.saturation_a_per_m();
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed + 100);
        let mut worst = 0.0f64;
        let (mut core, mut relay): (PreisachState, RelayState) =
            (c.measure.demagnetized(), c.reference.demagnetized());
        for h in field_path(&mut rng, &c.measure) {
            let m_core = c.measure.apply(&mut core, h).expect("finite") as f64;
            let h64 = h as f64;
            let m_ref = c
                .reference
                .apply_normalized(&mut relay, c.reference.normalize(h64))
                + reversible_a_per_m(&c.lines64, &c.chi64, h64);
            let tol = bound
                + output_rounding_a_per_m(&c.measure, core.len())
                + relay_sum_rounding_a_per_m(
                    total,
                    relay.switch_count(),
                    c.reference.relay_count(),
                )
                + slope * input_rounding_normalized() * (core.len() + 1) as f64;
            let error = (m_core - m_ref).abs();
            assert!(
                error <= tol,
                "{profile}, h {h}: core {m_core}, reference {m_ref}, {error} > {tol}"
            );
            worst = worst.max(error / tol);
        }
        println!("lines power {power}, {profile} χ: worst error / tolerance {worst:.3}");
    }
}

/// The inverse and the solve stay exact with `R`: the residual `|a·h + M − r|` within the
/// derived rounding, the committed input's field returned, re-applying it lands on the same
/// input, and targets beyond `±(Σw + ½Σρ)` saturate.
#[test]
fn inverse_and_solve_stay_exact() {
    for (power, profile, seed) in [
        (1.0, "bell", 11),
        (1.6, "random", 12),
        (1.0, "constant", 13),
    ] {
        let c = case(power, profile, 0.4, 1, seed);
        let measure = &c.measure;
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
        let w = measure.saturation_a_per_m() as f64;
        for trial in 0..2000 {
            let mut state: PreisachState = measure.demagnetized();
            for h in field_path(&mut rng, measure).into_iter().take(30) {
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
            assert_eq!(sol.saturation, Saturation::None);
            let (h, m) = (sol.h_a_per_m as f64, sol.m_a_per_m as f64);
            let tol = solve_rounding_a_per_m(measure, a, r, h);
            assert!(
                (a * h + m - r).abs() <= tol,
                "{profile} trial {trial}: a {a}, r {r}: residual {} > {tol}",
                (a * h + m - r).abs()
            );
            assert_eq!(sol.h_a_per_m, measure.input_a_per_m(&state));
            let mut again = original.clone();
            let m_again = measure.apply(&mut again, sol.h_a_per_m).expect("finite") as f64;
            let dx = (again.input_normalized() - state.input_normalized()).abs() as f64;
            assert!(
                dx <= input_rounding_normalized(),
                "re-applied input off by {dx}"
            );
            assert!(
                (m_again - m).abs() <= tol,
                "re-applied output {m_again} vs {m}"
            );
        }
        // Beyond reach: clamped to ±(Σw + ½Σρ) and reported.
        let mut state: PreisachState = measure.demagnetized();
        let high = measure.invert(&mut state, 1.5 * w as f32).unwrap();
        assert_eq!(high.saturation, Saturation::High);
        assert!((high.m_a_per_m as f64 - w).abs() <= 1e-5 * w);
        let low = measure.invert(&mut state, -1.5 * w as f32).unwrap();
        assert_eq!(low.saturation, Saturation::Low);
        assert!((low.m_a_per_m as f64 + w).abs() <= 1e-5 * w);
    }
}

const CONTROL_RATE_HZ: f64 = 10_000.0;

fn run_reference(c: &Case, field: &RelayPreisach, currents: &[f64]) -> Vec<f64> {
    let hysteresis = ReversibleRelayHysteresis::new(
        RelayHysteresis {
            field,
            state: field.demagnetized(),
        },
        c.lines64.clone(),
        c.chi64.clone(),
    );
    reference_displacements(hysteresis, currents, CONTROL_RATE_HZ, 100)
}

/// The dynamic model `H' + M' = c1 (I − H/c0)` with `M = Γ[H] + R(H)` against the RK4
/// reference, budget as in `dynamics.rs`: the core's time error from the half step (first order:
/// `2.35 |y(h) − y(h/2)|`), the reference's relay discretization (`2 |y_16 − y_32|`), f32.
#[test]
fn dynamic_model_with_a_reversible_part_matches_the_reference() {
    let c = case(1.0, "bell", 0.3, 1, 21);
    let p = BAKED_PARAMETERS.preisach;
    let w: Vec<f64> = p.weights_a_per_m.iter().map(|&w| w as f64).collect();
    let (lo, hi) = (p.h_min_a_per_m as f64, p.h_max_a_per_m as f64);
    let coarse = RelayPreisach::new(&w, lo, hi, 16).expect("relay field");
    let fine = RelayPreisach::new(&w, lo, hi, 32).expect("relay field");
    let n = (0.04 * CONTROL_RATE_HZ) as usize;
    let currents: Vec<f64> = (0..n)
        .map(|k| 0.5 + 0.45 * (2.0 * PI * 100.0 * k as f64 / CONTROL_RATE_HZ).sin())
        .collect();
    let core = core_displacements(&c.measure, &currents, CONTROL_RATE_HZ, 1);
    let core_half = core_displacements(&c.measure, &currents, CONTROL_RATE_HZ, 2);
    let reference = run_reference(&c, &fine, &currents);
    let reference_coarse = run_reference(&c, &coarse, &currents);
    let stroke = BAKED_PARAMETERS.actuator.stroke_m() as f64;
    let f32_term = model_rounding_m(&BAKED_PARAMETERS.actuator, CONTROL_RATE_HZ);
    let error = max_abs_diff(&core, &reference);
    let budget = 2.35 * max_abs_diff(&core, &core_half)
        + 2.0 * max_abs_diff(&reference_coarse, &reference)
        + f32_term;
    // The reversible part matters here: without it the core is far from this reference.
    let plain = PreisachMeasure::new(&p.weights_a_per_m, p.h_min_a_per_m, p.h_max_a_per_m);
    let without = max_abs_diff(
        &core_displacements(&plain, &currents, CONTROL_RATE_HZ, 1),
        &reference,
    );
    println!(
        "with R: |y_core - y_ref| = {:.3e} m ({:.3} % of stroke), budget {:.3e} m; the core without R: {:.3e} m",
        error,
        100.0 * error / stroke,
        budget,
        without
    );
    assert!(
        error <= budget,
        "error {error:.3e} m > budget {budget:.3e} m"
    );
    assert!(
        without > 5.0 * budget,
        "R changes the motion by only {without:.3e} m"
    );
}
