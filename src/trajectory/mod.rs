//! Desired displacement trajectories generated on the chip (paper Section 5).
//!
//! The paper drives its tracking experiments (Figures 7 and 8) with the output of a Van der Pol
//! oscillator instead of a sinusoid, to make the task harder: the limit cycle is a relaxation-like
//! waveform with odd harmonics. [`VanDerPol`] integrates it at the control rate and returns the
//! displacement together with its first two time derivatives, which the dynamic inverse needs.

mod van_der_pol;

pub use van_der_pol::{DesiredMotion, TrajectoryError, VanDerPol, VanDerPolState, MAX_INIT_STEPS};
