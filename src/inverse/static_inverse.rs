//! The static-model inverse: the baseline controller of the paper's Figure 8.
//!
//! Model (6): `H = c0 I`, `M = Γ[H]`, `y = l_m λ_s M² / M_s²`. Inverse: `M = M_s √(y / (l_m λ_s))`
//! on the branch `M >= 0` (the actuator is biased so that the magnetization never changes sign;
//! `y` is even in `M`), `H = Γ⁻¹(M)` with the exact inverse, `I = H / c0`.

use crate::params::Actuator;
use crate::preisach::{PreisachMeasure, PreisachState, Saturation, SolveError};

/// Coefficients of the static inverse.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StaticInverse {
    coil_factor_per_m: f32,
    saturation_magnetization_a_per_m: f32,
    stroke_m: f32,
}

/// One output of the static inverse.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StaticInverseOutput {
    /// Coil current command, A.
    pub current_a: f32,
    /// Field the inverse drives to, A/m.
    pub h_a_per_m: f32,
    /// Magnetization reached, A/m.
    pub m_a_per_m: f32,
    /// The desired displacement was outside `[0, l_m λ_s]` or the magnetization outside the
    /// operator's range, and was clamped.
    pub clamped: bool,
}

impl StaticInverse {
    /// Coefficients from the actuator constants.
    pub fn new(actuator: &Actuator) -> Self {
        StaticInverse {
            coil_factor_per_m: actuator.coil_factor_per_m,
            saturation_magnetization_a_per_m: actuator.saturation_magnetization_a_per_m,
            stroke_m: actuator.stroke_m(),
        }
    }

    /// Current that holds displacement `displacement_m` in the static model, committing the
    /// Preisach memory. A non-finite displacement is rejected and the state left unchanged.
    pub fn current_for_displacement<const N: usize>(
        &self,
        measure: &PreisachMeasure,
        state: &mut PreisachState<N>,
        displacement_m: f32,
    ) -> Result<StaticInverseOutput, SolveError> {
        if !displacement_m.is_finite() {
            return Err(SolveError::NonFinite);
        }
        let ratio = displacement_m / self.stroke_m;
        let clamped_ratio = ratio.clamp(0.0, 1.0);
        let m_target = self.saturation_magnetization_a_per_m * crate::sqrt::sqrt_f32(clamped_ratio);
        let solution = measure.invert(state, m_target)?;
        Ok(StaticInverseOutput {
            current_a: solution.h_a_per_m / self.coil_factor_per_m,
            h_a_per_m: solution.h_a_per_m,
            m_a_per_m: solution.m_a_per_m,
            clamped: clamped_ratio != ratio || solution.saturation != Saturation::None,
        })
    }
}
