//! The Preisach properties of the paper's Theorem 1 and Mayergoyz's characterization, checked on
//! the f32 core from random states: wiping-out, congruency of minor loops, rate independence,
//! order preservation, piecewise monotonicity and strong (Lipschitz) continuity.
//!
//! Each property is an identity or inequality of the exact operator; the tolerances are the
//! core's derived rounding budgets (`host_tests::bounds`):
//! * comparing two outputs of unrelated staircases: `E(len₁) + E(len₂)` with
//!   `E(len) = (50 len + 2) u Σw` ([`output_rounding_a_per_m`]);
//! * comparing output increments measured from a shared stored reversal point:
//!   `2 × (50 terms + 2) u Σw` ([`increment_rounding_a_per_m`]), independent of the history.

mod common;

use common::{baked_measure, core_apply, field_of, sample_path, turning_points};
use host_tests::bounds::{
    increment_rounding_a_per_m, line_density_bound_a_per_m, output_rounding_a_per_m,
};
use magctl::preisach::{PreisachMeasure, PreisachState, LEVELS};
use proptest::prelude::*;

const L: f64 = LEVELS as f64;

fn config() -> ProptestConfig {
    ProptestConfig {
        cases: 128,
        failure_persistence: None,
        ..ProptestConfig::default()
    }
}

/// A state reached by a random history from negative saturation or the demagnetized state.
fn state_after(
    measure: &PreisachMeasure,
    demagnetized: bool,
    history: &[f64],
) -> PreisachState<128> {
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

fn reversal_points<const N: usize>(s: &PreisachState<N>) -> Vec<f32> {
    s.reversal_points_normalized().collect()
}

proptest! {
    #![proptest_config(config())]

    /// Wiping-out: after a history ending at `x₀`, any excursion that stays strictly between `x₀`
    /// and a later extremum `e` and then reaches `e` leaves exactly the memory (and output) of
    /// going from `x₀` to `e` directly; the same future input then gives the same outputs.
    #[test]
    fn wiping_out_erases_inner_loops(
        demagnetized in any::<bool>(),
        history in turning_points(30),
        rising in any::<bool>(),
        reach in 0.05f64..1.0,
        inner in proptest::collection::vec(0.001f64..0.999, 1..30),
        future in turning_points(20),
    ) {
        let measure = baked_measure();
        let base = state_after(&measure, demagnetized, &history);
        let x0 = base.input_normalized() as f64;
        // The dominating extremum e, above x₀ (rising) or below it (falling), inside the range.
        let e = if rising { x0 + reach * (L - x0) } else { x0 - reach * x0 };
        prop_assume!((e - x0).abs() > 1e-3);
        let mut with_loops = base.clone();
        for &f in &inner {
            core_apply(&measure, &mut with_loops, x0 + f * (e - x0));
        }
        let (_, m_loops) = core_apply(&measure, &mut with_loops, e);
        let mut direct = base.clone();
        let (_, m_direct) = core_apply(&measure, &mut direct, e);
        prop_assert_eq!(reversal_points(&with_loops), reversal_points(&direct));
        let tol = |a: &PreisachState<128>, b: &PreisachState<128>| {
            output_rounding_a_per_m(&measure, a.len()) + output_rounding_a_per_m(&measure, b.len())
        };
        prop_assert!((m_loops - m_direct).abs() <= tol(&with_loops, &direct),
            "after the excursion: {} vs {}", m_loops, m_direct);
        for x in sample_path(e, &future, 2) {
            let (_, a) = core_apply(&measure, &mut with_loops, x);
            let (_, b) = core_apply(&measure, &mut direct, x);
            prop_assert!((a - b).abs() <= tol(&with_loops, &direct), "future x {}: {} vs {}", x, a, b);
        }
    }

    /// Congruency of minor loops: two different histories, each leaving the input at `u₁` with
    /// the last reversal beyond `u₂` (so the loop region {u₁ <= β <= α <= u₂} is in the same state
    /// in both), traverse the same loop u₁ → u₂ → u₁ at the same samples. The output increments
    /// `M(p) - M(u₁)` agree along both branches (the loops are congruent), and the loop closes.
    #[test]
    fn minor_loops_between_the_same_extrema_are_congruent(
        history_a in turning_points(30),
        history_b in turning_points(30),
        demag_a in any::<bool>(),
        demag_b in any::<bool>(),
        ends in (0.0f64..L, 0.0f64..L),
        overshoot in (0.01f64..1.0, 0.01f64..1.0),
        upward in any::<bool>(),
        samples in 2usize..12,
    ) {
        let measure = baked_measure();
        let (lo, hi) = (ends.0.min(ends.1), ends.0.max(ends.1));
        prop_assume!(hi - lo > 1e-3);
        // Upward loop: start at u₁ = lo after a reversal above hi; downward: start at hi after a
        // reversal below lo.
        let (start, turn) = if upward { (lo, hi) } else { (hi, lo) };
        let prepare = |history: &[f64], demag: bool, over: f64| {
            let mut s = state_after(&measure, demag, history);
            let beyond = if upward { hi + over * (L - hi) } else { lo - over * lo };
            core_apply(&measure, &mut s, beyond);
            core_apply(&measure, &mut s, start);
            s
        };
        let mut a = prepare(&history_a, demag_a, overshoot.0);
        let mut b = prepare(&history_b, demag_b, overshoot.1);
        // The last reversal must lie strictly beyond the turn as the core stores it (an equal
        // one would be wiped out at the turn: a different, equally exact, evaluation path).
        let turn_core = {
            let mut probe: PreisachState = measure.negative_saturation();
            core_apply(&measure, &mut probe, turn).0 as f32
        };
        for s in [&a, &b] {
            let last = *reversal_points(s).last().expect("anchor");
            prop_assume!(if upward { last > turn_core } else { last < turn_core });
        }
        let (m0_a, m0_b) = (measure.output_a_per_m(&a) as f64, measure.output_a_per_m(&b) as f64);
        let loop_path = sample_path(start, &[turn, start], samples);
        for (n, &x) in loop_path.iter().enumerate() {
            let (_, ma) = core_apply(&measure, &mut a, x);
            let (_, mb) = core_apply(&measure, &mut b, x);
            // Rising branch: one fresh term on the stored start; falling branch: the stored turn
            // (start + one term) minus one more term: 2 terms. Two histories: twice that.
            let terms = if n < samples { 1 } else { 2 };
            let tol = 2.0 * increment_rounding_a_per_m(&measure, terms);
            let (da, db) = (ma - m0_a, mb - m0_b);
            prop_assert!((da - db).abs() <= tol,
                "sample {} x {}: increments {} vs {} (tol {})", n, x, da, db, tol);
        }
        // Back at u₁ the loop is closed: the state is the one it started from.
        let close_tol = 2.0 * increment_rounding_a_per_m(&measure, 1);
        prop_assert!((measure.output_a_per_m(&a) as f64 - m0_a).abs() <= close_tol);
        prop_assert!((measure.output_a_per_m(&b) as f64 - m0_b).abs() <= close_tol);
    }

    /// Rate independence (Theorem 1.1): the same piecewise-monotone input sampled at different
    /// rates — including held (repeated) samples, i.e. any increasing reparametrization — gives the
    /// same memory and the same outputs at the shared points (the turning points).
    #[test]
    fn output_is_rate_independent(
        demagnetized in any::<bool>(),
        points in turning_points(40),
        coarse in 1usize..4,
        fine in 4usize..40,
        holds in proptest::collection::vec(0usize..4, 40),
    ) {
        let measure = baked_measure();
        let start = if demagnetized { 0.5 * L } else { 0.0 };
        let mut slow: PreisachState<128> = state_after(&measure, demagnetized, &[]);
        let mut fast = slow.clone();
        let slow_path = sample_path(start, &points, fine);
        let fast_path = sample_path(start, &points, coarse);
        for (k, &turn) in points.iter().enumerate() {
            // Slow: `fine` samples per piece, the turning point held `holds[k]` extra times.
            for &x in &slow_path[k * fine..(k + 1) * fine] {
                core_apply(&measure, &mut slow, x);
            }
            for _ in 0..holds[k % holds.len()] {
                core_apply(&measure, &mut slow, turn);
            }
            for &x in &fast_path[k * coarse..(k + 1) * coarse] {
                core_apply(&measure, &mut fast, x);
            }
            prop_assert_eq!(reversal_points(&slow), reversal_points(&fast));
            let (ms, mf) = (measure.output_a_per_m(&slow) as f64, measure.output_a_per_m(&fast) as f64);
            // Same stored vertices, one fresh Everett term each.
            let tol = 2.0 * increment_rounding_a_per_m(&measure, 1);
            prop_assert!((ms - mf).abs() <= tol, "turning point {}: {} vs {}", k, ms, mf);
        }
    }

    /// Order preservation (Theorem 1.4): from the same state, inputs `u₁ <= u₂` at every sample
    /// (hence along the piecewise-linear interpolations) give `Γ[u₁] <= Γ[u₂]` at every sample.
    #[test]
    fn order_is_preserved(
        demagnetized in any::<bool>(),
        history in turning_points(20),
        lower in proptest::collection::vec(-1.0f64..(L + 1.0), 1..120),
        gaps in proptest::collection::vec(prop_oneof![Just(0.0f64), 0.0f64..3.0], 120),
    ) {
        let measure = baked_measure();
        let mut s1 = state_after(&measure, demagnetized, &history);
        let mut s2 = s1.clone();
        for (n, &x1) in lower.iter().enumerate() {
            let x2 = x1 + gaps[n];
            let (_, m1) = core_apply(&measure, &mut s1, x1);
            let (_, m2) = core_apply(&measure, &mut s2, x2);
            let tol = output_rounding_a_per_m(&measure, s1.len())
                + output_rounding_a_per_m(&measure, s2.len());
            prop_assert!(m1 <= m2 + tol, "sample {}: u1 {} -> {}, u2 {} -> {}", n, x1, m1, x2, m2);
        }
    }

    /// Piecewise monotonicity (Theorem 1.3) and strong continuity (Theorem 1.2, here Lipschitz):
    /// along every monotone piece the output moves the same way as the input, and by at most
    /// `2 λ |Δx|` (λ = largest line mass of the density, see `bounds`).
    #[test]
    fn output_is_piecewise_monotone_and_lipschitz(
        demagnetized in any::<bool>(),
        history in turning_points(20),
        points in turning_points(20),
        samples in 2usize..30,
    ) {
        let measure = baked_measure();
        let lambda = line_density_bound_a_per_m(&measure);
        let mut s = state_after(&measure, demagnetized, &history);
        let mut x_prev = s.input_normalized() as f64;
        let mut m_prev = measure.output_a_per_m(&s) as f64;
        for x in sample_path(x_prev, &points, samples) {
            let len_before = s.len();
            let (x_now, m_now) = core_apply(&measure, &mut s, x);
            // The two outputs may come from different stored vertices (a wipe-out in between).
            let tol = output_rounding_a_per_m(&measure, len_before)
                + output_rounding_a_per_m(&measure, s.len());
            let dx = x_now - x_prev;
            let dm = m_now - m_prev;
            prop_assert!(dm * dx.signum() >= -tol, "x {} -> {}: M {} -> {}", x_prev, x_now, m_prev, m_now);
            prop_assert!(dm.abs() <= 2.0 * lambda * dx.abs() + tol,
                "x {} -> {}: |ΔM| {} > 2λ|Δx| {}", x_prev, x_now, dm.abs(), 2.0 * lambda * dx.abs());
            x_prev = x_now;
            m_prev = m_now;
        }
    }
}

/// The normalized input the core stores is the f64 normalization of the f32 field to within the
/// derived `4 u L` (`host_tests::bounds::input_rounding_normalized`).
#[test]
fn input_normalization_is_accurate() {
    let measure = baked_measure();
    let mut s: PreisachState = measure.negative_saturation();
    let (h_min, delta) = (
        measure.h_min_a_per_m() as f64,
        measure.cell_width_a_per_m() as f64,
    );
    // cell_width is itself one f32 rounding of (h_max - h_min)/L: use the exact range instead.
    let delta_exact = (measure.h_max_a_per_m() as f64 - h_min) / L;
    assert!((delta - delta_exact).abs() <= delta_exact * f32::EPSILON as f64);
    for n in 0..=1000 {
        let x = n as f64 * L / 1000.0;
        let h = field_of(&measure, x);
        core_apply(&measure, &mut s, x);
        let exact = (h as f64 - h_min) / delta_exact;
        let got = s.input_normalized() as f64;
        assert!(
            (got - exact.clamp(0.0, L)).abs() <= host_tests::bounds::input_rounding_normalized(),
            "x {x}: core {got}, exact {exact}"
        );
    }
}
