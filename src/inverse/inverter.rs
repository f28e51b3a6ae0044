//! The Preisach inverse `H = Γ⁻¹(M)` behind a small trait, so the same controller runs with the
//! fast exact inverse (Everett tables, [`PreisachMeasure::invert`]) or with the naive baseline
//! (bisection over a cell-by-cell forward, [`PreisachMeasure::naive_solve`]) used for the
//! instruction-count comparison in the QEMU run.

use crate::preisach::baselines::{everett_bisection_invert, RelayGrid};
use crate::preisach::naive::NaiveState;
use crate::preisach::{PreisachMeasure, PreisachState, Saturation, SolveError};

/// One committed inverse step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Inverted {
    /// The field reached, A/m.
    pub h_a_per_m: f32,
    /// The magnetization reached, A/m.
    pub m_a_per_m: f32,
    /// The target was outside the operator's range and was clamped.
    pub saturated: bool,
}

/// Inverts the Preisach operator from its current memory and commits the memory.
pub trait PreisachInverter {
    /// The input `H` with `Γ(H) = m_target_a_per_m`, reached monotonically from the current memory.
    fn invert_to(&mut self, m_target_a_per_m: f32) -> Result<Inverted, SolveError>;
}

/// The exact inverse of the core (O(grid lines crossed + reversals wiped out)).
pub struct FastInverter<'a, const N: usize> {
    /// Coefficients.
    pub measure: &'a PreisachMeasure,
    /// Memory.
    pub state: &'a mut PreisachState<N>,
}

impl<const N: usize> PreisachInverter for FastInverter<'_, N> {
    #[inline]
    fn invert_to(&mut self, m_target_a_per_m: f32) -> Result<Inverted, SolveError> {
        let s = self.measure.invert(self.state, m_target_a_per_m)?;
        Ok(Inverted {
            h_a_per_m: s.h_a_per_m,
            m_a_per_m: s.m_a_per_m,
            saturated: s.saturation != Saturation::None,
        })
    }
}

/// The naive baseline: 32-step bisection, each trial a full 325-cell forward evaluation.
pub struct NaiveInverter<'a, const N: usize> {
    /// Coefficients.
    pub measure: &'a PreisachMeasure,
    /// Memory.
    pub state: &'a mut NaiveState<N>,
}

impl<const N: usize> PreisachInverter for NaiveInverter<'_, N> {
    fn invert_to(&mut self, m_target_a_per_m: f32) -> Result<Inverted, SolveError> {
        if !m_target_a_per_m.is_finite() {
            return Err(SolveError::NonFinite);
        }
        let (h, m) = self.measure.naive_solve(self.state, 0.0, m_target_a_per_m);
        // Bisection clamps to the field range: a target beyond ±Σw ends at a range end.
        let saturated = m_target_a_per_m > self.measure.saturation_a_per_m()
            || m_target_a_per_m < -self.measure.saturation_a_per_m();
        Ok(Inverted {
            h_a_per_m: h,
            m_a_per_m: m,
            saturated,
        })
    }
}

/// Baseline: the exact operator inverted by bisection, each trial a forward Everett evaluation
/// on a copy of the memory (`preisach::baselines`, the openCFS approach).
pub struct EverettBisectionInverter<'a, const N: usize> {
    /// Coefficients.
    pub measure: &'a PreisachMeasure,
    /// Memory.
    pub state: &'a mut PreisachState<N>,
}

impl<const N: usize> PreisachInverter for EverettBisectionInverter<'_, N> {
    fn invert_to(&mut self, m_target_a_per_m: f32) -> Result<Inverted, SolveError> {
        if !m_target_a_per_m.is_finite() {
            return Err(SolveError::NonFinite);
        }
        let (h, m) = everett_bisection_invert(self.measure, self.state, m_target_a_per_m);
        let saturation = self.measure.saturation_a_per_m();
        Ok(Inverted {
            h_a_per_m: h,
            m_a_per_m: m,
            saturated: m_target_a_per_m.abs() > saturation,
        })
    }
}

/// Baseline: a relay grid (one state per relay, one weighted sum per evaluation) inverted by
/// bisection (`preisach::baselines`, the mavasbel/matlab-preisach-model approach).
pub struct RelayGridInverter<'a, 'm> {
    /// The relays and their states.
    pub grid: &'a mut RelayGrid<'m>,
}

impl PreisachInverter for RelayGridInverter<'_, '_> {
    fn invert_to(&mut self, m_target_a_per_m: f32) -> Result<Inverted, SolveError> {
        if !m_target_a_per_m.is_finite() {
            return Err(SolveError::NonFinite);
        }
        let (h, m) = self.grid.invert(m_target_a_per_m);
        Ok(Inverted {
            h_a_per_m: h,
            m_a_per_m: m,
            saturated: false,
        })
    }
}
