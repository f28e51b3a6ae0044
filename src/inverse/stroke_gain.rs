//! The stroke gain: a one-number estimate, from the first trajectory cycles, of how much larger
//! the rod's displacement is than the model's for the same command, divided out of the target
//! before the inverse sees it.
//!
//! # Why
//!
//! The harmonic learning ([`super::feedback`]) corrects a fraction `γ` of each harmonic's error
//! per cycle and needs a whole cycle of data before its first update, so the first cycles run on
//! the feedforward alone. The model errors that leave the largest open-loop error are errors of
//! the stroke's *scale*: by (5) the displacement is `y = (l_m λ_s / M_s²) · M²` filtered by the
//! magnetoelastic stage, so a wrong `λ_s`, a wrong `M_s` or Preisach masses scaled by `k`
//! (`M → k M`, `y → k² y`) multiply the static displacement by one number `g`. For such a plant
//! `y_rod(t) = g · y_model(t)` whatever the command, so `g` is found by least squares through the
//! origin from the samples and the model's targets,
//!
//! ```text
//! ĝ_k = (w + Σ_{j≤k} y_j ŷ_j) / (w + Σ_{j≤k} ŷ_j²)
//! ```
//!
//! (`y_j` the sample, `ŷ_j` the model's target at the sample's time `t_j − d`, `w` a prior
//! weight pulling towards `g = 1`), and the target handed to the inverse is `(ȳ + δ) / ĝ` with its
//! derivatives (`δ` the feedback's correction). The estimate is not a feedback loop: for a plant
//! that is the model times `g`, every pair satisfies `y_j = g ŷ_j` whatever `ĝ` was when `ŷ_j` was
//! commanded, so `ĝ_k` is the least-squares answer from the first sample on and does not depend on
//! its own history. Errors of the dynamics (R_eddy, ξ, f0, unmodelled effects) make the
//! regression pick the gain that best explains the samples, a few percent from 1, and the learning
//! corrects the rest, its convergence condition `|1 − γ P_n| < 1 − λ` now holding with
//! `P_n ≈ g / ĝ ≈ 1` in place of `g`.
//!
//! The sums run over the first [`StrokeGainLaw::cycles`] trajectory cycles and the estimate is
//! then frozen: after that the learning has converged and owns every slower change (thermal
//! drift, the ΔE effect), and the sums stay far from f32's limits. `ĝ` is clamped to
//! `[1/MAX_RATIO, MAX_RATIO]`. Ticks whose previous command was limited (the rod did not get the
//! target) and a latched sensor fault (the feedforward alone: `ĝ = 1`) add nothing.
//!
//! # Cost
//!
//! Per tick while estimating (the conditioning's hold and the first 3 cycles): the sample's
//! model displacement, 2 multiply-adds, one division, the clamp; afterwards a compare and one
//! multiply per component of the target (three). Measured in the whole handler under QEMU
//! (docs/model.md, the interrupt on rods the baked file does not describe).

use crate::trajectory::DesiredMotion;

/// Largest factor the estimate may put between rod and model, either way.
pub const MAX_RATIO: f32 = 2.0;

/// Coefficients of the stroke-gain estimate (`&self`; the sums are in [`StrokeGainState`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StrokeGainLaw {
    /// Prior weight `w`, m²: as many samples at the trajectory's mid-band displacement as
    /// [`StrokeGainLaw::PRIOR_SAMPLES`].
    prior_m2: f32,
    /// Ticks over which the sums run.
    estimate_ticks: u32,
    /// The sensor's sample delay `d`, s.
    delay_s: f32,
    /// Whether the estimate runs at all (off: `ĝ = 1`).
    enabled: bool,
}

/// The estimate's sums and the current gain.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StrokeGainState {
    /// `w + Σ y ŷ`, m².
    sum_product_m2: f32,
    /// `w + Σ ŷ²`, m².
    sum_model_sq_m2: f32,
    /// Ticks summed so far.
    ticks: u32,
    /// `ĝ`.
    pub gain: f32,
    /// `1 / ĝ`.
    inverse_gain: f32,
    /// The model's target handed to the inverse at the last tick (the coming sample's).
    pub last_target: DesiredMotion,
}

impl StrokeGainLaw {
    /// Samples the prior weighs: one sample at mid-band, so that an estimate with no data is 1
    /// and the first samples (the conditioning's hold at the first current, 25 of them) decide.
    pub const PRIOR_SAMPLES: f32 = 1.0;

    /// Coefficients for a trajectory band `[y_min, y_max]` (m), `cycles` cycles of `period_steps`
    /// ticks summed, the sensor's delay `delay_s` (s).
    pub fn new(
        band_m: (f32, f32),
        period_steps: f32,
        cycles: u32,
        delay_s: f32,
        enabled: bool,
    ) -> Self {
        let mid = 0.5 * (band_m.0 + band_m.1);
        StrokeGainLaw {
            prior_m2: Self::PRIOR_SAMPLES * mid * mid,
            estimate_ticks: (cycles as f32 * period_steps) as u32,
            delay_s,
            enabled,
        }
    }

    /// Whether the estimate runs.
    #[inline(always)]
    pub fn enabled(&self) -> bool {
        self.enabled
    }

    /// The same law, estimating nothing (`ĝ = 1` for good).
    pub fn off(&self) -> Self {
        StrokeGainLaw {
            enabled: false,
            ..*self
        }
    }

    /// The state before the first sample, the first target `first` (model coordinates).
    pub fn init(&self, first: &DesiredMotion) -> StrokeGainState {
        StrokeGainState {
            sum_product_m2: self.prior_m2,
            sum_model_sq_m2: self.prior_m2,
            ticks: 0,
            gain: 1.0,
            inverse_gain: 1.0,
            last_target: *first,
        }
    }

    /// Adds the sample `measured_m` against the last target. `usable` false (the last command
    /// was limited, or the sample is not valid) adds nothing.
    #[inline]
    pub fn observe(&self, state: &mut StrokeGainState, measured_m: f32, usable: bool) {
        // Frozen (the usual case after the first cycles): nothing to compute.
        if !usable || !self.enabled || state.ticks >= self.estimate_ticks {
            return;
        }
        // The model's displacement at the sample's time t_k − d (Taylor from t_k).
        let t = &state.last_target;
        let d = self.delay_s;
        let model_m =
            t.displacement_m - d * t.velocity_m_per_s + 0.5 * d * d * t.acceleration_m_per_s2;
        self.add(state, measured_m, model_m);
    }

    /// Adds a sample taken with the rod at rest on the conditioning's last hold, where the model
    /// is at its static displacement `model_m` (the first samples of the estimate: tracking then
    /// starts with the gain already found).
    #[inline]
    pub fn observe_at_rest(&self, state: &mut StrokeGainState, measured_m: f32, model_m: f32) {
        self.add(state, measured_m, model_m);
    }

    #[inline(always)]
    fn add(&self, state: &mut StrokeGainState, measured_m: f32, model_m: f32) {
        if !self.enabled
            || state.ticks >= self.estimate_ticks
            || !(measured_m.is_finite() && model_m.is_finite())
        {
            return;
        }
        state.sum_product_m2 += measured_m * model_m;
        state.sum_model_sq_m2 += model_m * model_m;
        state.ticks += 1;
        let g = state.sum_product_m2 / state.sum_model_sq_m2;
        state.gain = if g > MAX_RATIO {
            MAX_RATIO
        } else if g < 1.0 / MAX_RATIO {
            1.0 / MAX_RATIO
        } else if g.is_nan() {
            1.0
        } else {
            g
        };
        state.inverse_gain = 1.0 / state.gain;
    }

    /// The model's target for the rod's `desired` motion: divided by `ĝ` (by 1 once `fell_back`),
    /// kept as the coming sample's.
    #[inline]
    pub fn apply(
        &self,
        state: &mut StrokeGainState,
        desired: &DesiredMotion,
        fell_back: bool,
    ) -> DesiredMotion {
        let target = if fell_back || !self.enabled {
            *desired
        } else {
            let k = state.inverse_gain;
            DesiredMotion {
                displacement_m: desired.displacement_m * k,
                velocity_m_per_s: desired.velocity_m_per_s * k,
                acceleration_m_per_s2: desired.acceleration_m_per_s2 * k,
            }
        };
        state.last_target = target;
        target
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn motion(y: f32) -> DesiredMotion {
        DesiredMotion {
            displacement_m: y,
            velocity_m_per_s: 0.0,
            acceleration_m_per_s2: 0.0,
        }
    }

    fn law(cycles: u32) -> StrokeGainLaw {
        StrokeGainLaw::new((10e-6, 40e-6), 100.0, cycles, 0.0, true)
    }

    #[test]
    fn a_rod_that_is_the_model_times_g_gives_g_whatever_the_gain_it_was_commanded_with() {
        let l = law(3);
        for g in [0.8f32, 1.2, 1.56] {
            let mut s = l.init(&motion(12e-6));
            for k in 0..300 {
                let rod_target = 10e-6 + 15e-6 * (1.0 - libm::cosf(k as f32 * 0.0628));
                let model = l.apply(&mut s, &motion(rod_target), false);
                // The rod moves g times the model's displacement.
                l.observe(&mut s, g * model.displacement_m, true);
            }
            // Only the prior (one sample at mid-band against ~300 real ones) stands between.
            assert!((s.gain - g).abs() < 0.01 * g, "{g}: {}", s.gain);
            // The rod then gets its target: the model's target is divided by ĝ.
            let model = l.apply(&mut s, &motion(30e-6), false);
            assert!((g * model.displacement_m - 30e-6).abs() < 0.01 * 30e-6);
        }
    }

    #[test]
    fn the_estimate_freezes_after_its_cycles_is_clamped_and_ignores_unusable_samples() {
        let l = law(1);
        let mut s = l.init(&motion(20e-6));
        for _ in 0..100 {
            let model = l.apply(&mut s, &motion(20e-6), false);
            l.observe(&mut s, 1.2 * model.displacement_m, true);
        }
        let frozen = s.gain;
        assert!((frozen - 1.2).abs() < 0.01, "{frozen}");
        l.apply(&mut s, &motion(20e-6), false);
        l.observe(&mut s, 40e-6, true);
        assert_eq!(s.gain, frozen, "past its cycles the estimate holds");
        // Limited ticks, non-finite samples and a huge mismatch.
        let mut s = l.init(&motion(20e-6));
        l.observe(&mut s, 80e-6, false);
        l.observe(&mut s, f32::NAN, true);
        assert_eq!(s.gain, 1.0);
        for _ in 0..50 {
            l.observe(&mut s, 400e-6, true);
        }
        assert_eq!(s.gain, MAX_RATIO);
        // After a sensor fault the feedforward alone: the model gets the rod's target.
        let t = l.apply(&mut s, &motion(20e-6), true);
        assert_eq!(t.displacement_m, 20e-6);
    }

    #[test]
    fn switched_off_it_estimates_nothing() {
        let l = law(3).off();
        let mut s = l.init(&motion(20e-6));
        for _ in 0..50 {
            l.observe_at_rest(&mut s, 30e-6, 20e-6);
        }
        assert_eq!(s.gain, 1.0);
        assert_eq!(l.apply(&mut s, &motion(20e-6), false).displacement_m, 20e-6);
    }
}
