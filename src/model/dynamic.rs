//! The coupled dynamic model: eddy-current equation (4) with `M = Γ[H]`, then the magnetoelastic
//! dynamics (5) driven by `M²`, advanced by one fixed control period per [`DynamicModel::step`].
//!
//! Per step: the implicit eddy step ([`super::eddy`]) gives `(H⁺, M⁺)` exactly; then the exact
//! first-order-hold step of (5) ([`super::magnetoelastic`]) moves `(y, y')` with the static
//! displacement `u = l_m λ_s M² / M_s²` going from its old to its new value.
//!
//! A non-finite current never enters the state: the last valid current is held, the step still
//! runs (the plant keeps evolving), and the event is counted in [`ModelFaults`].

use super::eddy::EddyCurrentStep;
use super::magnetoelastic::MagnetoelasticStep;
use crate::params::Actuator;
use crate::preisach::{PreisachMeasure, PreisachState, DEFAULT_CAPACITY};

/// Counters of rejected inputs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct ModelFaults {
    /// Steps whose current was NaN or infinite (the last valid current was held instead).
    pub non_finite_current: u32,
    /// Steps whose eddy solve rejected its input (only possible if the state was corrupted).
    pub solver_rejected: u32,
}

/// State of the dynamic model.
#[derive(Debug, Clone, PartialEq)]
pub struct ModelState<const N: usize = DEFAULT_CAPACITY> {
    /// Preisach memory (the magnetization history).
    pub preisach: PreisachState<N>,
    /// Field H, A/m.
    pub h_a_per_m: f32,
    /// Magnetization M, A/m.
    pub m_a_per_m: f32,
    /// Displacement y, m.
    pub displacement_m: f32,
    /// Velocity y', m/s.
    pub velocity_m_per_s: f32,
    /// Last valid current, A (held when an invalid one arrives).
    pub current_a: f32,
    /// Rejected-input counters.
    pub faults: ModelFaults,
}

impl<const N: usize> ModelState<N> {
    /// Takes `current_a` as the current held over the coming step if it is finite; otherwise
    /// keeps the last valid one and counts the fault. Returns whether it was accepted.
    pub(crate) fn accept_current(&mut self, current_a: f32) -> bool {
        if current_a.is_finite() {
            self.current_a = current_a;
            true
        } else {
            self.faults.non_finite_current = self.faults.non_finite_current.saturating_add(1);
            false
        }
    }
}

/// What one step produced.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ModelOutput {
    /// Current actually applied over the step, A.
    pub current_a: f32,
    /// Field H at the end of the step, A/m.
    pub h_a_per_m: f32,
    /// Magnetization M at the end of the step, A/m.
    pub m_a_per_m: f32,
    /// Displacement y at the end of the step, m.
    pub displacement_m: f32,
    /// Velocity y' at the end of the step, m/s.
    pub velocity_m_per_s: f32,
    /// The requested current was rejected (non-finite) and the last valid one held.
    pub current_rejected: bool,
}

/// Coefficients of the dynamic model at a fixed control period.
#[derive(Debug, Clone, Copy)]
pub struct DynamicModel<'m> {
    measure: &'m PreisachMeasure,
    eddy: EddyCurrentStep,
    mechanics: MagnetoelasticStep,
    coil_factor_per_m: f32,
    step_s: f32,
}

impl<'m> DynamicModel<'m> {
    /// Coefficients for the actuator constants and control period `step_s` (s). Computes the
    /// exact discretization of (5) (a 4×4 matrix exponential in f64): call once, at init.
    pub fn new(measure: &'m PreisachMeasure, actuator: &Actuator, step_s: f32) -> Self {
        DynamicModel {
            measure,
            eddy: EddyCurrentStep::new(actuator, step_s),
            mechanics: MagnetoelasticStep::new(actuator, step_s),
            coil_factor_per_m: actuator.coil_factor_per_m,
            step_s,
        }
    }

    /// The control period, s.
    pub fn step_s(&self) -> f32 {
        self.step_s
    }

    /// The Preisach measure.
    pub fn measure(&self) -> &'m PreisachMeasure {
        self.measure
    }

    /// The eddy-current step coefficients.
    pub fn eddy(&self) -> &EddyCurrentStep {
        &self.eddy
    }

    /// The magnetoelastic step coefficients.
    pub fn mechanics(&self) -> &MagnetoelasticStep {
        &self.mechanics
    }

    /// The equilibrium state under a constant current `current_a` reached from the given Preisach
    /// memory: `H = c0 I` (applied to the memory), `M = Γ(H)`, `y` at its static value, at rest.
    pub fn equilibrium<const N: usize>(
        &self,
        mut preisach: PreisachState<N>,
        current_a: f32,
    ) -> ModelState<N> {
        let current_a = if current_a.is_finite() {
            current_a
        } else {
            0.0
        };
        let h = self.coil_factor_per_m * current_a;
        let m = match self.measure.apply(&mut preisach, h) {
            Ok(m) => m,
            Err(_) => self.measure.output_a_per_m(&preisach),
        };
        ModelState {
            preisach,
            h_a_per_m: h,
            m_a_per_m: m,
            displacement_m: self.mechanics.static_displacement_m(m),
            velocity_m_per_s: 0.0,
            current_a,
            faults: ModelFaults::default(),
        }
    }

    /// Advances the model by one period with `current_a` held over it.
    ///
    /// Cost: one Preisach monotone solve plus ~20 flops. Never panics, never allocates.
    pub fn step<const N: usize>(&self, state: &mut ModelState<N>, current_a: f32) -> ModelOutput {
        let current_rejected = !state.accept_current(current_a);
        let u_start = self.mechanics.static_displacement_m(state.m_a_per_m);
        match self.eddy.step(
            self.measure,
            &mut state.preisach,
            state.h_a_per_m,
            state.m_a_per_m,
            state.current_a,
        ) {
            Ok((h, m)) => {
                state.h_a_per_m = h;
                state.m_a_per_m = m;
            }
            Err(_) => {
                state.faults.solver_rejected = state.faults.solver_rejected.saturating_add(1);
            }
        }
        let u_end = self.mechanics.static_displacement_m(state.m_a_per_m);
        let (y, v) =
            self.mechanics
                .step(state.displacement_m, state.velocity_m_per_s, u_start, u_end);
        state.displacement_m = y;
        state.velocity_m_per_s = v;
        ModelOutput {
            current_a: state.current_a,
            h_a_per_m: state.h_a_per_m,
            m_a_per_m: state.m_a_per_m,
            displacement_m: y,
            velocity_m_per_s: v,
            current_rejected,
        }
    }
}
