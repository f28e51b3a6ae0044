//! `maglab-diagnose`: where and why measured data disagree with the nominal actuator model.
//!
//! * [`effects`]: the names of the unmodelled effects of the candidate library.
//! * [`model`]: the nominal model (4)-(5) with one optional augmentation per candidate effect and
//!   the recording's nuisances, in two stages (electromagnetic, mechanical).
//! * [`candidates`]: each candidate's free parameters (the refitted nominal constants included),
//!   ranges and starting points.
//! * [`fit`]: Levenberg-Marquardt fits on training experiments with the electromagnetic stage
//!   cached.
//! * [`signal`]: fundamentals, spectra (rustfft), the noise level, branch labels.
//! * [`breakdown`]: where the residual lies, and the plain-language summary.
//! * [`diagnosis`]: nuisances, split, fits, scores, verdict (`maglab diagnose`).
//! * [`identification`]: `R_eddy`, `ξ`, `f0` with the same model and nuisance estimate, for
//!   `maglab identify` (an identified file is what the diagnosis' refit gives on the same data).
//!
//! The diagnosis never sees the plant that made its test data: its tests run it on the bench
//! plant of `maglab-plant`, whose equations it does not share.

pub mod breakdown;
pub mod candidates;
pub mod diagnosis;
pub mod effects;
pub mod fit;
pub mod identification;
pub mod model;
pub mod signal;
