//! One step of the eddy-current equation (4), `H' + M' = c1 (I - H / c0)`, `M = Γ[H]`.
//!
//! # Why implicit
//!
//! The paper's existence proof uses the Euler polygon (9), explicit in `H` on the right:
//! `H⁺ + M⁺ = H + M + h c1 (I - H / c0)`. Linearize around a state with local Preisach slope
//! `χ = dM/dH >= 0`: `w = H + M` obeys `w' = -(c1 / c0) w / (1 + χ) + c1 I`, so (9) multiplies
//! deviations by `1 - h c1 / (c0 (1 + χ))`. Right after every input reversal the Preisach slope
//! is zero (no hysteron switches yet), and with the paper's values `c1 / c0 ≈ 9.8·10⁴ 1/s`:
//! at 10 kHz the factor is `1 - 9.8`, unstable. The control rate cannot be raised 50× to fix it.
//!
//! The implicit (backward Euler) step evaluates the right side at the new time:
//!
//! `(1 + h c1 / c0) H⁺ + Γ(H⁺) = H + M + h c1 I`
//!
//! Its deviation factor is `1 / (1 + h c1 / (c0 (1 + χ)))`, in `(0, 1]` for every `h > 0` and every
//! `χ >= 0`: unconditionally stable and monotone (L-stable), so it never produces the spurious
//! reversals an oscillating scheme (e.g. trapezoidal) would add to the Preisach memory. The left
//! side is strictly increasing in `H⁺` (slope `>= 1 + h c1 / c0`), so the solution is unique, and
//! [`crate::preisach::PreisachMeasure::solve`] finds it exactly (piecewise quadratic, no iteration).
//! Accuracy is first order in `h`: the local error is `½ h² |H''|`, tested against the fine-step
//! reference in `host-tests`.
//!
//! With the current held over the step (DAC output), `∫ c1 I dt = h c1 I` is exact; only the
//! `H / c0` term is approximated.

use crate::params::Actuator;
use crate::preisach::{PreisachMeasure, PreisachState, SolveError};

/// Coefficients of the implicit eddy-current step at a fixed period.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EddyCurrentStep {
    /// `1 + h c1 / c0`, the slope of the linear part of the implicit equation.
    pub(crate) slope: f32,
    /// `h c1`, A/m per A of current.
    pub(crate) step_c1_per_m: f32,
}

impl EddyCurrentStep {
    /// Coefficients for period `step_s` (s).
    pub fn new(actuator: &Actuator, step_s: f32) -> Self {
        let c1 = actuator.eddy_coefficient_per_m_s() as f64;
        let h = step_s as f64;
        EddyCurrentStep {
            slope: (1.0 + h * c1 / actuator.coil_factor_per_m as f64) as f32,
            step_c1_per_m: (h * c1) as f32,
        }
    }

    /// `h · c1 / c0`, the stiffness of the step (≈ 9.8 at 10 kHz with the paper's values).
    pub fn stiffness(&self) -> f32 {
        self.slope - 1.0
    }

    /// Advances `(H, M)` by one step under current `current_a` held over the step. Returns
    /// `(H⁺, M⁺)`; the Preisach memory is committed to `H⁺`.
    ///
    /// Cost: one monotone solve (O(grid lines crossed + reversal points wiped out)).
    pub fn step<const N: usize>(
        &self,
        measure: &PreisachMeasure,
        preisach: &mut PreisachState<N>,
        h_a_per_m: f32,
        m_a_per_m: f32,
        current_a: f32,
    ) -> Result<(f32, f32), SolveError> {
        let r = h_a_per_m + m_a_per_m + self.step_c1_per_m * current_a;
        let solution = measure.solve(preisach, self.slope, r)?;
        Ok((solution.h_a_per_m, solution.m_a_per_m))
    }
}
