//! `maglab-diagnose`: where and why measured data disagree with the nominal actuator model.
//!
//! * [`effects`]: the unmodelled effects (names are part of the interface) and their rig
//!   parameters.
//! * [`rig`]: the virtual test rig (`maglab rig`): datasets from the f64 reference plant with
//!   effects switched on, plus sensor noise and quantization.
//! * [`model`]: the nominal model (4)-(5) with one optional augmentation per candidate effect.
//! * [`candidates`]: each candidate's free parameters, ranges and starting points.
//! * [`signal`]: fundamentals, spectra (rustfft), the noise level, branch labels.
//! * [`breakdown`]: where the residual lies, and the plain-language summary.
//! * [`diagnosis`]: split, fit, score, verdict (`maglab diagnose`).

pub mod breakdown;
pub mod candidates;
pub mod diagnosis;
pub mod effects;
pub mod model;
pub mod rig;
pub mod signal;
