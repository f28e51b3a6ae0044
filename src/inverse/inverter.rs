//! The Preisach inverse `H = Γ⁻¹(M)` behind a small trait, so the same controller runs with the
//! fast exact inverse (Everett tables, [`PreisachMeasure::invert`]) or with the naive baseline
//! (bisection over a cell-by-cell forward, [`PreisachMeasure::naive_solve`]) used for the
//! instruction-count comparison in the QEMU run.

use crate::preisach::baselines::{everett_bisection_invert, RelayGrid};
use crate::preisach::naive::NaiveState;
use crate::preisach::{PreisachMeasure, PreisachState, Saturation, SolveError};

/// The most pieces (grid intervals or wiped-out reversal points along the input's path) the
/// control interrupt's exact inverse walks in one tick. Each costs one Everett evaluation and the
/// bookkeeping of the walk, about 60 instructions; at 8 the inverse stays under ~500
/// instructions whatever the target, so the whole handler with the feedback stays within its
/// 1,500-instruction goal under any model error (measured: `cargo xtask hil --interrupt-matrix`,
/// docs/firmware.md). On the model's own plant a tick walks 1–4 pieces: the budget only binds
/// when the target jumps (a wrong model, a sensor glitch the feedback acts on), and then the
/// field moves toward the target at 8 pieces a tick.
pub const INVERSE_PIECES_PER_TICK: usize = 3;

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

/// The exact inverse of the core (O(grid lines crossed + reversals wiped out)), walking at most
/// `MAX_PIECES` pieces ([`PreisachMeasure::invert_within`]): [`INVERSE_PIECES_PER_TICK`] in the
/// control interrupt (the default), [`UNBOUNDED`] at start-up.
pub struct FastInverter<'a, const N: usize, const MAX_PIECES: usize = INVERSE_PIECES_PER_TICK> {
    /// Coefficients.
    pub measure: &'a PreisachMeasure,
    /// Memory.
    pub state: &'a mut PreisachState<N>,
}

/// A piece budget no walk reaches: the exact `invert`.
pub const UNBOUNDED: usize = usize::MAX;

impl<const N: usize, const MAX_PIECES: usize> PreisachInverter for FastInverter<'_, N, MAX_PIECES> {
    /// The exact inverse within the piece budget: a target further than that along the path is
    /// approached and reported as saturated (the next tick continues).
    #[inline]
    fn invert_to(&mut self, m_target_a_per_m: f32) -> Result<Inverted, SolveError> {
        let s = self
            .measure
            .invert_within::<N, MAX_PIECES>(self.state, m_target_a_per_m)?;
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
        // Bisection clamps to the field range: a target beyond the output range ends at an end.
        let (low, high) = self.measure.output_range_a_per_m();
        let saturated = m_target_a_per_m > high || m_target_a_per_m < low;
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
        let (low, high) = self.measure.output_range_a_per_m();
        Ok(Inverted {
            h_a_per_m: h,
            m_a_per_m: m,
            saturated: m_target_a_per_m > high || m_target_a_per_m < low,
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
