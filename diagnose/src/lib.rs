//! `maglab-diagnose`: where and why measured data disagree with the nominal actuator model.
//!
//! * [`diagnosis`]: nuisances, split, fits, scores, verdict (`maglab diagnose`), on the model of
//!   `maglab-model` (the one the identification fits too);
//! * [`breakdown`]: where the residual lies, and the plain-language summary.
//!
//! The diagnosis never sees the plant that made its test data: its tests run it on the bench
//! plant of `maglab-plant`, whose equations it does not share.

pub mod breakdown;
pub mod diagnosis;
