//! Inverse control (paper Section 5).
//!
//! * [`StaticInverse`]: the static-model inverse (6), the baseline of the paper's Figure 8.
//! * [`DynamicInverse`] (`dynamic`): the dynamic-model inverse of (4)-(5), Figure 7.
//! * [`StaticMode`]: the static inverse through the same generic interface as the dynamic one.
//! * [`PreisachInverter`]: `H = Γ⁻¹(M)` with the fast exact inverse or the naive baseline.
//! * [`OutputLimiter`]: output safety (±I_max, slew limit, hold on NaN/inf) in front of the DAC.
//! * [`Conditioning`]: the start-up sequence that puts the rod's memory where the controller
//!   assumes it (negative saturation, then a monotone rise to the first current).
//! * [`ControlLoop`]: one control interrupt (trajectory → inverse → limiter), switchable between
//!   the dynamic and the static inverse with [`InverseKind`]; shared by firmware and host.

mod conditioning;
mod control_loop;
mod dynamic;
pub mod feedback;
mod inverter;
mod limiter;
mod static_inverse;
mod static_mode;
mod stroke_gain;

pub use conditioning::{
    Conditioning, ConditioningError, ConditioningState, Sweep, HOLD_S, RAMP_FULL_SCALE_S,
};
pub use control_loop::{
    ControlLoop, InverseKind, LoopCore, LoopCounters, LoopError, LoopState, NaiveLoopState,
    TickOutput, MEMORY_RESOLUTION_CELLS2,
};
pub use dynamic::DynamicInverse;
pub use feedback::{FeedbackError, FeedbackLaw, FeedbackState};
pub use inverter::{
    EverettBisectionInverter, FastInverter, Inverted, NaiveInverter, PreisachInverter,
    RelayGridInverter, INVERSE_PIECES_PER_TICK, UNBOUNDED,
};
pub use limiter::{CommandFlags, LimiterError, OutputLimiter};
pub use static_inverse::{StaticInverse, StaticInverseOutput};
pub use static_mode::StaticMode;
pub use stroke_gain::{StrokeGainLaw, StrokeGainState, MAX_RATIO as STROKE_GAIN_MAX_RATIO};

/// The previous targets of an inverse (`H_k`, `M_k`), for the differences of (4).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct InverseMemory {
    /// H_k, A/m.
    pub h_a_per_m: f32,
    /// M_k, A/m.
    pub m_a_per_m: f32,
}

/// An inverse's output before the output limiter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RawCommand {
    /// Current, A.
    pub current_a: f32,
    /// Field target reached by the inverse, A/m.
    pub h_a_per_m: f32,
    /// Magnetization reached, A/m.
    pub m_a_per_m: f32,
    /// `u`, the displacement or `M` was clamped to the attainable set.
    pub clamped: bool,
}
