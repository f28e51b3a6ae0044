//! The dynamic-model inverse (paper Section 5), the controller of the paper's Figure 7.
//!
//! From the desired `ȳ, ẏ, ÿ` at the end of the coming control period:
//!
//! 1. invert the magnetoelastic dynamics (5):
//!    `u = M_s² / (ω0² l_m λ_s) · (ÿ + 2 ξ ω0 ẏ + ω0² ȳ)` (u plays the role of `M²`);
//! 2. project onto the attainable set `0 <= u <= M_s²` (the paper's projection onto D([0, T]),
//!    done pointwise); a clamp raises [`RawCommand::clamped`] and is counted by the control loop;
//! 3. `M = √u` (branch `M >= 0`: the actuator is biased so that M never changes sign, and (5) is
//!    even in M);
//! 4. `H = Γ⁻¹(M)` with the exact inverse (commits the Preisach memory);
//! 5. invert the eddy-current equation (4), `Ḣ + Ṁ = c1 (I - H/c0)`:
//!    `I = (ΔH/h + ΔM/h) / c1 + H/c0`, `c1 = R_eddy / (μ0 N_m A_m)`.
//!    (The paper's Section 5 prints `I = (1/c1)(Ḣ + Ṁ + H/c0)`; solving (4) for `I` puts the
//!    `1/c1` on the rate terms only — the printed form is not dimensionally consistent, since
//!    `c1` has unit 1/(m·s) and `H/c0` is already a current.)
//!
//! # Timing convention and why the backward difference is exact for the core model
//!
//! The current computed at tick `k` is held by the DAC over `[t_k, t_k + h]` and the targets are
//! the trajectory's values at `t_{k+1}` (the trajectory is generated on the chip, so one step of
//! preview is free). `ΔH = H_{k+1} - H_k`, `ΔM = M_{k+1} - M_k`. This is exactly the implicit step
//! of (4) used by [`crate::model`] — `(H⁺ - H)/h + (M⁺ - M)/h = c1 (I - H⁺/c0)` — solved for `I`,
//! so on the core model the field and magnetization follow `H̄, M̄` to rounding, and the
//! displacement then follows `ȳ` up to the first-order-hold error of `M²` in (5).

use super::inverter::PreisachInverter;
use super::{InverseMemory, RawCommand};
use crate::params::Actuator;
use crate::preisach::SolveError;
use crate::trajectory::DesiredMotion;

/// Coefficients of the dynamic inverse at a fixed control period.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DynamicInverse {
    /// M_s² / (ω0² l_m λ_s), (A/m)² per (m/s²).
    u_per_accel: f32,
    /// 2 ξ ω0, 1/s.
    damping_per_s: f32,
    /// ω0², 1/s².
    stiffness_per_s2: f32,
    /// M_s², (A/m)².
    u_max: f32,
    /// 1 / (c1 h), A·m per (A/m).
    inv_c1_h: f32,
    /// 1 / c0: A per (A/m).
    inv_c0: f32,
}

impl DynamicInverse {
    /// Coefficients for the actuator constants and the control period `step_s`, s.
    pub fn new(actuator: &Actuator, step_s: f32) -> Self {
        let omega0 = 2.0 * core::f32::consts::PI * actuator.resonance_hz;
        let ms = actuator.saturation_magnetization_a_per_m;
        let c1 = actuator.eddy_coefficient_per_m_s();
        DynamicInverse {
            u_per_accel: ms * ms / (omega0 * omega0 * actuator.stroke_m()),
            damping_per_s: 2.0 * actuator.damping_ratio * omega0,
            stiffness_per_s2: omega0 * omega0,
            u_max: ms * ms,
            inv_c1_h: 1.0 / (c1 * step_s),
            inv_c0: 1.0 / actuator.coil_factor_per_m,
        }
    }

    /// `u = M²` demanded by (5) for the desired motion, before the projection.
    #[inline]
    pub fn demanded_u(&self, desired: &DesiredMotion) -> f32 {
        self.u_per_accel
            * (desired.acceleration_m_per_s2
                + self.damping_per_s * desired.velocity_m_per_s
                + self.stiffness_per_s2 * desired.displacement_m)
    }

    /// Steps 1-5 of the module documentation. Commits the Preisach memory (through `inverter`) and
    /// `memory`. A non-finite desired motion is rejected before anything is changed.
    #[inline]
    pub fn raw_command<P: PreisachInverter>(
        &self,
        inverter: &mut P,
        memory: &mut InverseMemory,
        desired: &DesiredMotion,
    ) -> Result<RawCommand, SolveError> {
        if !desired.is_finite() {
            return Err(SolveError::NonFinite);
        }
        let u = self.demanded_u(desired);
        let (u, u_clamped) = if u < 0.0 {
            (0.0, true)
        } else if u > self.u_max {
            (self.u_max, true)
        } else {
            (u, false)
        };
        let m_target = libm::sqrtf(u);
        let inv = inverter.invert_to(m_target)?;
        let dh = inv.h_a_per_m - memory.h_a_per_m;
        let dm = inv.m_a_per_m - memory.m_a_per_m;
        let current_a = self.inv_c1_h * (dh + dm) + self.inv_c0 * inv.h_a_per_m;
        memory.h_a_per_m = inv.h_a_per_m;
        memory.m_a_per_m = inv.m_a_per_m;
        Ok(RawCommand {
            current_a,
            h_a_per_m: inv.h_a_per_m,
            m_a_per_m: inv.m_a_per_m,
            clamped: u_clamped || inv.saturated,
        })
    }
}
