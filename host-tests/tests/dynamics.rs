//! The core's fixed-step dynamic model (`magctl::model`) against the independent f64 reference
//! (`host_tests::reference::dynamics`: RK4 on the integral form (8) with 100 substeps per period,
//! relay-level Preisach operator).
//!
//! # Error budget (derived, not tuned)
//!
//! Both simulate the same physical input: the current held constant over each 10 kHz period.
//! `|y_core(h) - y_ref|` has three parts:
//!
//! 1. The core's time discretization. Backward Euler on (4) is first order: `e(h) = C h + O(h²)`,
//!    so from two step sizes `e(h) = d / (1 - 2^{-p})` with `d = y(h) - y(h/2)` and `p` the
//!    observed order. The convergence test below checks `p >= 0.8` on the same signals, so
//!    `|e(h)| <= d / (1 - 2^{-0.8}) = 2.35 d`.
//! 2. The reference's relay discretization: first order in `1/k` (centre-point relays, see
//!    `reference::preisach`), so `|y_ref(k) - y_exact| <= |y_ref(k/2) - y_ref(k)|` up to `O(1/k²)`;
//!    we compare with `k = 32` and charge `2 |y_ref(16) - y_ref(32)|`.
//! 3. f32 rounding in the core: about 16 roundings of relative size `ε = 2⁻²⁴` per step on values
//!    bounded by the stroke, damped by the mechanical contraction `e^{-ξ ω0 h}` per step, so at most
//!    `16 ε · stroke / (ξ ω0 h)`.
//!
//! The RK4 reference's own time error (`(δ c1 / c0)⁴ ≈ 10⁻⁴` relative per fast-mode substep, with
//! `δ = h / 100`) is far below all three.

mod common;

use common::{baked_file_params, core_displacements, max_abs_diff, reference_displacements};
use host_tests::bounds::model_rounding_m;
use host_tests::reference::dynamics::RelayHysteresis;
use host_tests::reference::preisach::RelayPreisach;
use magctl::model::{DynamicModel, StaticModel};
use magctl::params::{BAKED_MEASURE, BAKED_PARAMETERS};
use std::f64::consts::PI;

const CONTROL_RATE_HZ: f64 = 10_000.0;
const SUBSTEPS: usize = 100;
const BIAS_A: f64 = 0.5;
const AMPLITUDE_A: f64 = 0.45;

fn stroke_m() -> f64 {
    BAKED_PARAMETERS.actuator.stroke_m() as f64
}

/// Zero-order-held sine with DC bias at 10 kHz, `periods` periods (at least `min_s` seconds).
fn sine_currents(freq_hz: f64, periods: f64, min_s: f64) -> Vec<f64> {
    let n = ((periods / freq_hz).max(min_s) * CONTROL_RATE_HZ).round() as usize;
    (0..n)
        .map(|k| BIAS_A + AMPLITUDE_A * (2.0 * PI * freq_hz * k as f64 / CONTROL_RATE_HZ).sin())
        .collect()
}

/// A band-limited random current: 12 sinusoids with random frequencies in 5..300 Hz and phases
/// (fixed seed), scaled to the same bias and peak amplitude.
fn random_band_limited_currents(duration_s: f64, seed: u64) -> Vec<f64> {
    let mut state = seed;
    let mut next = move || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let tones: Vec<(f64, f64, f64)> = (0..12)
        .map(|_| (5.0 + 295.0 * next(), 2.0 * PI * next(), 0.3 + next()))
        .collect();
    let n = (duration_s * CONTROL_RATE_HZ) as usize;
    let raw: Vec<f64> = (0..n)
        .map(|k| {
            let t = k as f64 / CONTROL_RATE_HZ;
            tones
                .iter()
                .map(|&(f, ph, a)| a * (2.0 * PI * f * t + ph).sin())
                .sum()
        })
        .collect();
    let peak = raw.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    raw.iter()
        .map(|v| BIAS_A + AMPLITUDE_A * v / peak)
        .collect()
}

/// The core model at `multiplier × 10 kHz` on the held current; displacement at the end of
/// every 10 kHz period.
fn run_core(currents: &[f64], multiplier: usize) -> Vec<f64> {
    core_displacements(&BAKED_MEASURE, currents, CONTROL_RATE_HZ, multiplier)
}

fn run_reference(currents: &[f64], field: &RelayPreisach) -> Vec<f64> {
    let hysteresis = RelayHysteresis {
        field,
        state: field.demagnetized(),
    };
    reference_displacements(hysteresis, currents, CONTROL_RATE_HZ, SUBSTEPS)
}

fn f32_budget_m() -> f64 {
    model_rounding_m(&BAKED_PARAMETERS.actuator, CONTROL_RATE_HZ)
}

struct Fields {
    coarse: RelayPreisach,
    fine: RelayPreisach,
}

fn fields() -> Fields {
    let p = baked_file_params();
    let w = &p.preisach.weights_a_per_m;
    let (lo, hi) = (p.preisach.h_min_a_per_m, p.preisach.h_max_a_per_m);
    Fields {
        coarse: RelayPreisach::new(w, lo, hi, 16).expect("valid relay field"),
        fine: RelayPreisach::new(w, lo, hi, 32).expect("valid relay field"),
    }
}

/// Checks the core against the reference on one current sequence; returns the error and the
/// budget relative to the stroke.
fn check_against_reference(name: &str, currents: &[f64], fields: &Fields) -> (f64, f64) {
    let core = run_core(currents, 1);
    let core_half = run_core(currents, 2);
    let reference = run_reference(currents, &fields.fine);
    let reference_coarse = run_reference(currents, &fields.coarse);
    let error = max_abs_diff(&core, &reference);
    let time_term = 2.35 * max_abs_diff(&core, &core_half);
    let relay_term = 2.0 * max_abs_diff(&reference_coarse, &reference);
    let budget = time_term + relay_term + f32_budget_m();
    let stroke = stroke_m();
    println!(
        "{name}: |y_core - y_ref| = {:.3e} m ({:.3} % of stroke); budget {:.3e} m = time {:.3e} + relay {:.3e} + f32 {:.1e}",
        error,
        100.0 * error / stroke,
        budget,
        time_term,
        relay_term,
        f32_budget_m()
    );
    assert!(
        error <= budget,
        "{name}: error {error:.3e} m exceeds the derived budget {budget:.3e} m"
    );
    (error / stroke, budget / stroke)
}

#[test]
fn core_matches_reference_for_biased_sines_at_10khz() {
    let fields = fields();
    let mut worst = 0.0f64;
    for freq in [1.0, 50.0, 100.0, 200.0, 400.0] {
        let currents = sine_currents(freq, 3.0, 0.02);
        let currents = if freq < 10.0 {
            sine_currents(freq, 1.0, 0.0)
        } else {
            currents
        };
        let (error, _) = check_against_reference(&format!("{freq} Hz"), &currents, &fields);
        worst = worst.max(error);
    }
    // The figure docs/model.md and BENCHMARKS.md quote: the worst error relative to the stroke.
    println!(
        "worst error over 1..400 Hz at 10 kHz: {:.3} % of stroke",
        100.0 * worst
    );
}

#[test]
fn core_matches_reference_for_random_band_limited_current() {
    let fields = fields();
    let currents = random_band_limited_currents(0.2, 0x5eed);
    check_against_reference("band-limited random", &currents, &fields);
}

/// Observed order of the time discretization from 10, 20 and 40 kHz runs, and the error against
/// the reference shrinking at 10, 20 and 50 kHz.
#[test]
fn discretization_error_converges_first_order() {
    let fields = fields();
    for freq in [100.0, 400.0] {
        let currents = sine_currents(freq, 3.0, 0.02);
        let y1 = run_core(&currents, 1);
        let y2 = run_core(&currents, 2);
        let y4 = run_core(&currents, 4);
        let order = (max_abs_diff(&y1, &y2) / max_abs_diff(&y2, &y4)).log2();
        println!("{freq} Hz: observed order {order:.3}");
        assert!(
            (0.8..=1.25).contains(&order),
            "{freq} Hz: observed order {order} is not first order"
        );
        let reference = run_reference(&currents, &fields.fine);
        let errors: Vec<f64> = [1, 2, 5]
            .iter()
            .map(|&m| max_abs_diff(&run_core(&currents, m), &reference))
            .collect();
        println!("{freq} Hz: error vs reference at 10/20/50 kHz: {errors:?}");
        assert!(
            errors[0] > errors[1] && errors[1] > errors[2],
            "{freq} Hz: error does not shrink with h: {errors:?}"
        );
        // First order: 50 kHz should be ≈ 5× better than 10 kHz; allow the relay floor.
        let relay_floor = 2.0 * max_abs_diff(&run_reference(&currents, &fields.coarse), &reference);
        assert!(
            errors[2] <= errors[0] / 5.0 * 1.25 + relay_floor,
            "{freq} Hz: {errors:?}"
        );
    }
}

/// Largest `dM/dH` of the measure along any monotone path: `|dM/dx| <= 2 λ` in normalized input
/// (`λ` the largest line density, `host_tests::bounds`), and `dx/dH = 1 / Δ`.
fn max_preisach_slope() -> f64 {
    2.0 * host_tests::bounds::line_density_bound_a_per_m(&BAKED_MEASURE)
        / BAKED_MEASURE.cell_width_a_per_m() as f64
}

/// At 1 Hz the dynamic model is in its quasi-static limit and agrees with the static model (6).
///
/// Budget, from first-order quasi-static expansions (the next terms are `(ωτ)²` smaller,
/// `ωτ < 10⁻²` here): (4) gives `H - c0 I = -(c0 / c1)(H' + M')` with
/// `|H' + M'| <= (1 + χ_max) c0 |I'|`, so `|ΔM| <= χ_max |ΔH|` and `|Δy| <= 2 (y_s / M_s²) M_max |ΔM|`;
/// (5) lags its input by `|y - u| <= (2ξ / ω0) |u'|`.
#[test]
fn one_hertz_dynamic_agrees_with_static_model() {
    let a = &BAKED_PARAMETERS.actuator;
    let currents = sine_currents(1.0, 1.0, 0.0);
    let dynamic = run_core(&currents, 1);
    let model = StaticModel::new(&BAKED_MEASURE, a);
    let mut state = DynamicModel::new(&BAKED_MEASURE, a, 1e-4)
        .equilibrium::<64>(BAKED_MEASURE.demagnetized(), currents[0] as f32);
    let statics: Vec<f64> = currents
        .iter()
        .map(|&i| model.step(&mut state, i as f32).displacement_m as f64)
        .collect();
    let diff = max_abs_diff(&dynamic, &statics);

    let c0 = a.coil_factor_per_m as f64;
    let c1 = a.eddy_coefficient_per_m_s() as f64;
    let chi = max_preisach_slope();
    let i_rate = AMPLITUDE_A * 2.0 * PI * 1.0;
    let dh = (c0 / c1) * (1.0 + chi) * c0 * i_rate;
    let m_s = a.saturation_magnetization_a_per_m as f64;
    let eddy_term = 2.0 * stroke_m() / (m_s * m_s) * m_s * chi * dh;
    let u_rate = statics
        .windows(2)
        .fold(0.0f64, |m, w| m.max((w[1] - w[0]).abs()))
        * CONTROL_RATE_HZ;
    let mech_term = 2.0 * a.damping_ratio as f64 / (2.0 * PI * a.resonance_hz as f64) * u_rate;
    let budget = eddy_term + mech_term + f32_budget_m();
    println!(
        "1 Hz: |y_dynamic - y_static| = {diff:.3e} m ({:.4} % of stroke), budget {budget:.3e} (eddy {eddy_term:.2e}, mech {mech_term:.2e}; chi_max {chi:.1})",
        100.0 * diff / stroke_m()
    );
    assert!(diff <= budget);
}

/// The implicit step is unconditionally stable: over 10 s of random band-limited current at 10,
/// 20 and 50 kHz the state stays finite and inside its invariant set. Backward Euler on (4) is
/// monotone: if `H⁺ > c0 I_max >= H` then `(H⁺ - H) + (M⁺ - M) = h c1 (I - H⁺ / c0) < 0`, while
/// `H⁺ - H` and `M⁺ - M` share a sign, a contradiction; so `H` stays within `c0 [I_min, I_max]`
/// (plus the initial value). `y` stays within `[-o, (1 + o)]·stroke`, `o` the overshoot of (5)
/// (`e^{-πξ/√(1-ξ²)}` for a step; a bounded input cannot exceed the `L¹` norm of the impulse
/// response, `1 + 2o` times the input range).
#[test]
fn implicit_step_is_stable_for_10_seconds_at_10_20_50_khz() {
    let a = &BAKED_PARAMETERS.actuator;
    let xi = a.damping_ratio as f64;
    let overshoot = (-PI * xi / (1.0 - xi * xi).sqrt()).exp();
    let currents = random_band_limited_currents(10.0, 0xbadc0de);
    let (i_min, i_max) = currents
        .iter()
        .fold((f64::MAX, f64::MIN), |(lo, hi), &i| (lo.min(i), hi.max(i)));
    let c0 = a.coil_factor_per_m as f64;
    for multiplier in [1usize, 2, 5] {
        let step_s = (1.0 / (CONTROL_RATE_HZ * multiplier as f64)) as f32;
        let model = DynamicModel::new(&BAKED_MEASURE, a, step_s);
        let mut state = model.equilibrium::<64>(BAKED_MEASURE.demagnetized(), currents[0] as f32);
        let tol_h = 1e-5 * c0 * i_max.abs().max(i_min.abs());
        let (y_lo, y_hi) = (
            -(1.0 + 2.0 * overshoot) * stroke_m() * overshoot,
            (1.0 + 2.0 * overshoot) * stroke_m(),
        );
        for &i in &currents {
            for _ in 0..multiplier {
                let out = model.step(&mut state, i as f32);
                let h = out.h_a_per_m as f64;
                let y = out.displacement_m as f64;
                assert!(h.is_finite() && y.is_finite() && out.velocity_m_per_s.is_finite());
                assert!(
                    h >= c0 * i_min - tol_h && h <= c0 * i_max + tol_h,
                    "H = {h} left c0·[{i_min}, {i_max}]"
                );
                assert!(y >= y_lo && y <= y_hi, "y = {y} left [{y_lo}, {y_hi}]");
            }
        }
        let faults = state.faults;
        assert_eq!(faults.non_finite_current + faults.solver_rejected, 0);
        println!(
            "{} kHz: 10 s stable, {} staircase merges",
            10 * multiplier,
            state.preisach.merges()
        );
    }
}

/// A NaN or infinite current never enters the state: the last valid current is held and counted.
#[test]
fn non_finite_current_is_held_and_flagged() {
    let model = DynamicModel::new(&BAKED_MEASURE, &BAKED_PARAMETERS.actuator, 1e-4);
    let mut state = model.equilibrium::<64>(BAKED_MEASURE.demagnetized(), 0.5);
    let mut twin = state.clone();
    for _ in 0..10 {
        model.step(&mut state, 0.7);
        model.step(&mut twin, 0.7);
    }
    let bad = [f32::NAN, f32::INFINITY, f32::NEG_INFINITY];
    for (k, &i) in bad.iter().enumerate() {
        let out = model.step(&mut state, i);
        let good = model.step(&mut twin, 0.7);
        assert!(out.current_rejected);
        assert_eq!(out.current_a, 0.7);
        assert_eq!(out.displacement_m, good.displacement_m, "step {k}");
    }
    assert_eq!(state.faults.non_finite_current, 3);
}
