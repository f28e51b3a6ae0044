//! The static model (6), the quasi-static limit of (4)-(5): `H = c0 I`, `M = Γ[H]`,
//! `y = l_m λ_s M² / M_s²`. Setting the time derivatives of (4) and (5) to zero gives it.

use super::dynamic::{ModelOutput, ModelState};
use crate::params::Actuator;
use crate::preisach::PreisachMeasure;

/// Coefficients of the static model.
#[derive(Debug, Clone, Copy)]
pub struct StaticModel<'m> {
    measure: &'m PreisachMeasure,
    coil_factor_per_m: f32,
    displacement_per_m2_m: f32,
}

impl<'m> StaticModel<'m> {
    /// Coefficients from the actuator constants.
    pub fn new(measure: &'m PreisachMeasure, actuator: &Actuator) -> Self {
        let m_s = actuator.saturation_magnetization_a_per_m;
        StaticModel {
            measure,
            coil_factor_per_m: actuator.coil_factor_per_m,
            displacement_per_m2_m: actuator.stroke_m() / (m_s * m_s),
        }
    }

    /// Applies `current_a`: `H = c0 I`, `M = Γ(H)`, `y = l_m λ_s M² / M_s²`, velocity 0. A
    /// non-finite current is rejected (last valid current held, counted).
    pub fn step<const N: usize>(&self, state: &mut ModelState<N>, current_a: f32) -> ModelOutput {
        let current_rejected = !state.accept_current(current_a);
        let h = self.coil_factor_per_m * state.current_a;
        if let Ok(m) = self.measure.apply(&mut state.preisach, h) {
            state.h_a_per_m = h;
            state.m_a_per_m = m;
        }
        state.displacement_m = self.displacement_per_m2_m * state.m_a_per_m * state.m_a_per_m;
        state.velocity_m_per_s = 0.0;
        ModelOutput {
            current_a: state.current_a,
            h_a_per_m: state.h_a_per_m,
            m_a_per_m: state.m_a_per_m,
            displacement_m: state.displacement_m,
            velocity_m_per_s: 0.0,
            current_rejected,
        }
    }
}
