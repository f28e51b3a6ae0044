//! The static-model inverse (6) through the generic [`PreisachInverter`], so the firmware can
//! switch between it and the dynamic inverse (and run it with the naive operator too). Same math
//! as [`super::StaticInverse`] (a host test checks the two agree bit for bit):
//! `M = M_s √(ȳ / (l_m λ_s))` on `0 <= ȳ <= l_m λ_s`, `H = Γ⁻¹(M)`, `I = H / c0`.

use super::inverter::PreisachInverter;
use super::{InverseMemory, RawCommand};
use crate::params::Actuator;
use crate::preisach::SolveError;
use crate::trajectory::DesiredMotion;

/// Coefficients of the static inverse.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StaticMode {
    saturation_magnetization_a_per_m: f32,
    stroke_m: f32,
    coil_factor_per_m: f32,
}

impl StaticMode {
    /// Coefficients from the actuator constants.
    pub fn new(actuator: &Actuator) -> Self {
        StaticMode {
            saturation_magnetization_a_per_m: actuator.saturation_magnetization_a_per_m,
            stroke_m: actuator.stroke_m(),
            coil_factor_per_m: actuator.coil_factor_per_m,
        }
    }

    /// One static-inverse command for the desired displacement (derivatives ignored: that is the
    /// point of the baseline). Commits the memory.
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
        let ratio = desired.displacement_m / self.stroke_m;
        let clamped_ratio = ratio.clamp(0.0, 1.0);
        let m_target = self.saturation_magnetization_a_per_m * crate::sqrt::sqrt_f32(clamped_ratio);
        let inv = inverter.invert_to(m_target)?;
        memory.h_a_per_m = inv.h_a_per_m;
        memory.m_a_per_m = inv.m_a_per_m;
        Ok(RawCommand {
            current_a: inv.h_a_per_m / self.coil_factor_per_m,
            h_a_per_m: inv.h_a_per_m,
            m_a_per_m: inv.m_a_per_m,
            clamped: clamped_ratio != ratio || inv.saturated,
        })
    }
}
