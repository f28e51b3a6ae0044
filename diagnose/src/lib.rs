//! `maglab-diagnose`: where and why measured data disagree with the nominal actuator model.
//!
//! * [`effects`]: the unmodelled effects (names are part of the interface) and their rig
//!   parameters.
//! * [`rig`]: the virtual test rig (`maglab rig`): datasets from the f64 reference plant with
//!   effects switched on, plus sensor noise and quantization.
//! * [`model`]: the nominal model (4)-(5) with one optional augmentation per candidate effect.

pub mod effects;
pub mod model;
pub mod rig;
