//! The f32 core against the independent f64 relay reference (`host_tests::reference::preisach`)
//! on random piecewise-monotone inputs.
//!
//! # Tolerance
//!
//! Both operators receive exactly the same normalized input sequence: the core is driven in A/m
//! and the reference is given the core's own normalized input `state.input_normalized()` (exact
//! in f64), so the reversal points are identical and the comparison isolates
//!
//! 1. the reference's discretization: `|M_exact - M_relay| <= 2 · max_path Σ μ(S)`, the heaviest
//!    monotone chain of `1/k`-sub-squares the memory curve can cut (each cut sub-square off by at
//!    most `2 μ(S)`; derivation in the reference's module docs), evaluated by dynamic programming
//!    (`discretization_bound_a_per_m`, itself `<= 2 (2kL - 1) ρ_max / k²`, so `O(1/k)`);
//! 2. the core's f32 rounding: `(50 len + 2) u Σw` for a staircase of `len` vertices
//!    (`host_tests::bounds::output_rounding_a_per_m`, derived there);
//! 3. the reference's f64 running sum: `2 (switches + relays) 2⁻⁵³ Σw`.
//!
//! The tolerance at every sample is the sum of the three. The capacity (64) is kept above the
//! reversal count so the core never merges (asserted), which would add the merge error.

mod common;

use common::{baked_measure, core_apply, sample_path, turning_points};
use host_tests::bounds::{output_rounding_a_per_m, relay_sum_rounding_a_per_m};
use host_tests::reference::preisach::{RelayPreisach, RelayState};
use magctl::preisach::{PreisachMeasure, PreisachState, CELL_COUNT, LEVELS};
use proptest::prelude::*;
use rand::rngs::Xoshiro256PlusPlus;
use rand::{RngExt, SeedableRng};
use std::sync::OnceLock;

/// Relay references of the baked measure for k = 4, 8, 16, with their discretization bounds.
fn baked_references() -> &'static [(RelayPreisach, f64)] {
    static REFS: OnceLock<Vec<(RelayPreisach, f64)>> = OnceLock::new();
    REFS.get_or_init(|| {
        [4, 8, 16]
            .iter()
            .map(|&k| {
                let r = RelayPreisach::from_baked(k).expect("baked parameters are valid");
                let bound = r.discretization_bound_a_per_m();
                (r, bound)
            })
            .collect()
    })
}

/// Runs one input sequence through the core and the reference from matching initial states,
/// asserting the derived tolerance at every sample; returns the largest observed error.
fn compare_run(
    measure: &PreisachMeasure,
    reference: &RelayPreisach,
    discretization_bound: f64,
    demagnetized: bool,
    path: &[f64],
) -> Result<f64, TestCaseError> {
    let (mut core, mut relay): (PreisachState, RelayState) = if demagnetized {
        (measure.demagnetized(), reference.demagnetized())
    } else {
        (
            measure.negative_saturation(),
            reference.negative_saturation(),
        )
    };
    let total = reference.saturation_a_per_m();
    let tolerance = |core: &PreisachState, relay: &RelayState| {
        discretization_bound
            + output_rounding_a_per_m(measure, core.len())
            + relay_sum_rounding_a_per_m(total, relay.switch_count(), reference.relay_count())
    };
    let first = (measure.output_a_per_m(&core) as f64 - reference.output_a_per_m(&relay)).abs();
    prop_assert!(
        first <= tolerance(&core, &relay),
        "initial state: error {first}"
    );
    let mut max_error = first;
    for (n, &x) in path.iter().enumerate() {
        let (x_core, m_core) = core_apply(measure, &mut core, x);
        let m_ref = reference.apply_normalized(&mut relay, x_core);
        let error = (m_core - m_ref).abs();
        let tol = tolerance(&core, &relay);
        prop_assert!(
            error <= tol,
            "k {}: sample {n} x {x_core}: core {m_core}, reference {m_ref}, error {error} > {tol}",
            reference.subdivision()
        );
        max_error = max_error.max(error);
    }
    prop_assert_eq!(
        core.merges(),
        0,
        "capacity exceeded: the test must not merge"
    );
    Ok(max_error)
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, failure_persistence: None, ..ProptestConfig::default() })]

    /// Baked measure, k = 4, 8, 16, from negative saturation and from the demagnetized state.
    #[test]
    fn core_matches_relay_reference_on_random_inputs(
        points in turning_points(36),
        samples in 1usize..4,
        demagnetized in any::<bool>(),
    ) {
        let measure = baked_measure();
        let start = if demagnetized { 0.5 * LEVELS as f64 } else { 0.0 };
        let path = sample_path(start, &points, samples);
        for (reference, bound) in baked_references() {
            compare_run(&measure, reference, *bound, demagnetized, &path)?;
        }
    }
}

/// Random non-negative cell masses (about a third of them zero) and a random field range.
fn random_measure() -> impl Strategy<Value = (Vec<f32>, f32, f32)> {
    (
        proptest::collection::vec(
            prop_oneof![1 => Just(0.0f32), 2 => 0.0f32..2.0e3],
            CELL_COUNT,
        ),
        -5.0e4f32..0.0,
        1.0e3f32..1.0e5,
    )
        .prop_map(|(w, h_min, width)| (w, h_min, h_min + width))
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 16, failure_persistence: None, ..ProptestConfig::default() })]

    /// Random measures (k = 8): the Everett tables are right for any non-negative masses, not
    /// just the smooth default.
    #[test]
    fn core_matches_relay_reference_for_random_measures(
        (weights, h_min, h_max) in random_measure(),
        points in turning_points(36),
        samples in 1usize..3,
        demagnetized in any::<bool>(),
    ) {
        let w32: [f32; CELL_COUNT] = weights.clone().try_into().expect("CELL_COUNT weights");
        prop_assume!(w32.iter().any(|&w| w > 0.0));
        let measure = PreisachMeasure::new(&w32, h_min, h_max);
        let w64: Vec<f64> = weights.iter().map(|&w| w as f64).collect();
        let reference = RelayPreisach::new(&w64, h_min as f64, h_max as f64, 8)
            .expect("valid random measure");
        let bound = reference.discretization_bound_a_per_m();
        let start = if demagnetized { 0.5 * LEVELS as f64 } else { 0.0 };
        let path = sample_path(start, &points, samples);
        compare_run(&measure, &reference, bound, demagnetized, &path)?;
    }
}

/// The observed error shrinks as the reference is refined (k = 4, 8, 16, 32), and stays within
/// each k's derived bound, on one long deterministic input (180 reversals, mixing free random
/// turning points with decaying nested oscillations, wiping out and saturating along the way).
#[test]
fn observed_error_shrinks_as_k_grows() {
    let measure = baked_measure();
    let l = LEVELS as f64;
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(0x5eed_0002);
    let mut points = Vec::new();
    while points.len() < 180 {
        if rng.random_bool(0.5) {
            points.push(rng.random_range(-0.5..l + 0.5));
        } else {
            // A burst of 6-20 nested reversals around a random centre (depth <= 20 + the rest,
            // below the capacity of 64).
            let centre = rng.random_range(4.0..l - 4.0);
            let mut amplitude = rng.random_range(1.0..10.0);
            let ratio = rng.random_range(0.55..0.95);
            let mut sign = 1.0;
            for _ in 0..rng.random_range(6..20) {
                points.push(centre + sign * amplitude);
                amplitude *= ratio;
                sign = -sign;
            }
        }
    }
    let path = sample_path(0.0, &points, 3);
    let mut rows = Vec::new();
    for k in [4usize, 8, 16, 32] {
        let reference = RelayPreisach::from_baked(k).expect("baked parameters are valid");
        let bound = reference.discretization_bound_a_per_m();
        let closed_form = reference.discretization_bound_closed_form_a_per_m();
        assert!(bound <= closed_form * (1.0 + 1e-12));
        let mut max_error = 0.0f64;
        for demagnetized in [false, true] {
            let e = compare_run(&measure, &reference, bound, demagnetized, &path)
                .unwrap_or_else(|e| panic!("{e}"));
            max_error = max_error.max(e);
        }
        println!(
            "k = {k:2}: max |M_core - M_relay| = {max_error:9.2} A/m, DP bound {bound:10.2} A/m, \
             closed form 2(2kL-1)ρ_max/k² = {closed_form:10.2} A/m"
        );
        rows.push((k, max_error));
    }
    for pair in rows.windows(2) {
        let ((k0, e0), (k1, e1)) = (pair[0], pair[1]);
        // The bound halves when k doubles; the observed maximum must shrink too.
        assert!(
            e1 < e0,
            "max error did not shrink from k = {k0} ({e0}) to k = {k1} ({e1})"
        );
    }
}
