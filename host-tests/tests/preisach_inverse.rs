//! The exact inverse `Γ⁻¹` and the solve `a·h + Γ(h) = r` of the core, from random states.
//!
//! Tolerances (derived in `host_tests::bounds`):
//! * residual of the solve / inverse: [`solve_rounding_a_per_m`]
//!   `= 200 u Σw + (2λ + aΔ)(L + 8) u + 4 u a |h|max + 2 u |r|` — the solver measures `M` and the
//!   target gap from the same stored vertex, so the staircase's own rounding cancels;
//! * re-applying the returned `h` to the original state: the f32 round trip `h → x` moves the
//!   input by at most `4 u L` + `u L` (the committed `x₀ + σ`), so the output by `2 λ` times that,
//!   plus two fresh Everett terms on the same stored vertex — or, if that tiny move crosses a
//!   wipe-out threshold (different stored vertices), the general `E(len₁) + E(len₂)`.

mod common;

use common::{baked_measure, core_apply, turning_points};
use host_tests::bounds::{
    increment_rounding_a_per_m, input_rounding_normalized, line_density_bound_a_per_m,
    output_rounding_a_per_m, solve_rounding_a_per_m, F32_UNIT_ROUNDOFF,
};
use magctl::preisach::{
    InputError, PreisachMeasure, PreisachState, Saturation, SolveError, LEVELS,
};
use proptest::prelude::*;

fn state_after(measure: &PreisachMeasure, demagnetized: bool, history: &[f64]) -> PreisachState {
    let mut s = if demagnetized {
        measure.demagnetized()
    } else {
        measure.negative_saturation()
    };
    for &x in history {
        core_apply(measure, &mut s, x);
    }
    s
}

/// Checks one solve from `state` and returns the committed state.
fn check_solve(
    measure: &PreisachMeasure,
    state: &PreisachState,
    a: f32,
    r: f32,
    future: &[f64],
) -> Result<(), TestCaseError> {
    let mut solved = state.clone();
    let sol = measure
        .solve(&mut solved, a, r)
        .map_err(|e| TestCaseError::fail(format!("solve rejected finite input: {e:?}")))?;
    let (a64, r64) = (a as f64, r as f64);
    let (h, m) = (sol.h_a_per_m as f64, sol.m_a_per_m as f64);
    let w = measure.saturation_a_per_m() as f64;
    // The returned M is the committed state's output.
    prop_assert_eq!(sol.m_a_per_m, measure.output_a_per_m(&solved));
    let tol = solve_rounding_a_per_m(measure, a64, r64, h);
    // A target within the solve's rounding of ±Σw may land on either side of saturation: the
    // largest output the f32 sums reach can lie a few ulps below Σw.
    let within_rounding_of_saturation = a == 0.0 && (r64.abs() - w).abs() <= tol;
    if within_rounding_of_saturation && sol.saturation != Saturation::None {
        prop_assert!((m - w * r64.signum()).abs() <= tol, "clamped M {}", m);
    } else if a == 0.0 && r64.abs() >= w {
        // Out of reach: clamped and reported.
        let expect = if r64 > 0.0 {
            Saturation::High
        } else {
            Saturation::Low
        };
        prop_assert_eq!(sol.saturation, expect);
        prop_assert!((m - w * r64.signum()).abs() <= tol, "clamped M {}", m);
        prop_assert_eq!(solved.len(), 1, "saturation wipes the whole memory");
    } else {
        prop_assert_eq!(sol.saturation, Saturation::None);
        let residual = a64 * h + m - r64;
        prop_assert!(
            residual.abs() <= tol,
            "a {} r {}: h {} M {} residual {} > {}",
            a,
            r,
            h,
            m,
            residual,
            tol
        );
    }
    // Re-applying h to the original state reproduces M (the solve committed what apply would).
    // Beyond the grid (a > 0 saturated solutions) apply clamps h, with the same saturated state.
    let mut replay = state.clone();
    let fwd = measure
        .apply(&mut replay, sol.h_a_per_m)
        .map_err(|e| TestCaseError::fail(format!("{e:?}")))? as f64;
    let same_vertices = replay
        .reversal_points_normalized()
        .eq(solved.reversal_points_normalized());
    let lambda = line_density_bound_a_per_m(measure);
    let dx = input_rounding_normalized() + F32_UNIT_ROUNDOFF * LEVELS as f64;
    let replay_tol = 2.0 * lambda * dx
        + if same_vertices {
            2.0 * increment_rounding_a_per_m(measure, 1)
        } else {
            output_rounding_a_per_m(measure, replay.len())
                + output_rounding_a_per_m(measure, solved.len())
        };
    prop_assert!(
        (fwd - m).abs() <= replay_tol,
        "replaying h {}: {} vs {} (tol {})",
        h,
        fwd,
        m,
        replay_tol
    );
    // And the committed memory behaves like the replayed one afterwards.
    for &x in future {
        let (_, p) = core_apply(measure, &mut solved, x);
        let (_, q) = core_apply(measure, &mut replay, x);
        let t = 2.0 * lambda * dx
            + output_rounding_a_per_m(measure, solved.len())
            + output_rounding_a_per_m(measure, replay.len());
        prop_assert!(
            (p - q).abs() <= t,
            "after the solve, x {}: {} vs {}",
            x,
            p,
            q
        );
    }
    Ok(())
}

fn config() -> ProptestConfig {
    ProptestConfig {
        cases: 256,
        failure_persistence: None,
        ..ProptestConfig::default()
    }
}

proptest! {
    #![proptest_config(config())]

    /// Γ(Γ⁻¹(m)) = m over random states and targets anywhere in (-Σw, Σw), plus targets just
    /// beyond ±Σw (clamped, reported).
    #[test]
    fn inverse_round_trips(
        demagnetized in any::<bool>(),
        history in turning_points(40),
        fraction in prop_oneof![8 => -0.9999f64..0.9999, 1 => 1.0001f64..1.5, 1 => -1.5f64..-1.0001],
        future in turning_points(8),
    ) {
        let measure = baked_measure();
        let state = state_after(&measure, demagnetized, &history);
        let target = (fraction * measure.saturation_a_per_m() as f64) as f32;
        check_solve(&measure, &state, 0.0, target, &future)?;
    }

    /// Targets close to the current output (tiny inverse steps, as in a control loop).
    #[test]
    fn inverse_small_steps(
        demagnetized in any::<bool>(),
        history in turning_points(40),
        step in -2.0e3f64..2.0e3,
    ) {
        let measure = baked_measure();
        let state = state_after(&measure, demagnetized, &history);
        let target = (measure.output_a_per_m(&state) as f64 + step) as f32;
        check_solve(&measure, &state, 0.0, target, &[])?;
    }

    /// The solve a·h + Γ(h) = r for a ∈ [0, 100] (and the dynamic model's a ≈ 10) and r covering
    /// the grid and beyond it.
    #[test]
    fn solve_round_trips(
        demagnetized in any::<bool>(),
        history in turning_points(40),
        a in prop_oneof![0.0f32..100.0, 9.0f32..11.0, Just(0.0f32), Just(100.0f32)],
        r_fraction in -1.5f64..1.5,
        future in turning_points(8),
    ) {
        let measure = baked_measure();
        let state = state_after(&measure, demagnetized, &history);
        // r spans g(h_min) .. g(h_max) and half as much again beyond both ends.
        let h_abs = measure.h_max_a_per_m().abs().max(measure.h_min_a_per_m().abs()) as f64;
        let span = a as f64 * h_abs + measure.saturation_a_per_m() as f64;
        let r = (r_fraction * span) as f32;
        check_solve(&measure, &state, a, r, &future)?;
    }
}

/// Non-finite inputs and negative slopes are rejected with the state unchanged.
#[test]
fn bad_inputs_leave_the_state_unchanged() {
    let measure = baked_measure();
    let mut s: PreisachState = measure.demagnetized();
    for x in [3.0, 20.0, 7.0, 15.0, 9.5] {
        core_apply(&measure, &mut s, x);
    }
    let before = s.clone();
    for h in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
        assert_eq!(measure.apply(&mut s, h), Err(InputError::NonFinite));
        assert_eq!(s, before);
    }
    for m in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
        assert_eq!(measure.invert(&mut s, m), Err(SolveError::NonFinite));
        assert_eq!(s, before);
    }
    for (a, r) in [
        (f32::NAN, 0.0),
        (f32::INFINITY, 0.0),
        (1.0, f32::NAN),
        (1.0, f32::NEG_INFINITY),
    ] {
        assert_eq!(measure.solve(&mut s, a, r), Err(SolveError::NonFinite));
        assert_eq!(s, before);
    }
    assert_eq!(
        measure.solve(&mut s, -1.0, 0.0),
        Err(SolveError::NegativeSlope)
    );
    assert_eq!(s, before);
}
