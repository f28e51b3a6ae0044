//! `maglab-model`: the nuisance-aware model of a recorded dataset and its fit — the one model
//! that both the identification (`maglab-identify`: R_eddy, ξ, f0 with every experiment fitted)
//! and the diagnosis (`maglab-diagnose`: candidates scored on held-out experiments) fit.
//!
//! * [`model`]: the nominal model (4)-(5) with one optional augmentation per candidate effect,
//!   simulated on a measured current in two stages (electromagnetic, mechanical);
//! * [`effects`]: the names of the unmodelled effects of the candidate library;
//! * [`candidates`]: each candidate's free parameters (the refitted nominal constants included),
//!   ranges and starting points;
//! * [`fit`]: Levenberg-Marquardt fits on training experiments with the electromagnetic stage
//!   cached; [`plan_fit`]: the same with the start plan that suits each candidate;
//! * [`coil_current`]: the amplifier judged on the commanded against the measured coil current,
//!   and the measured current as the model's input;
//! * [`coverage`]: which minor loops a file's Preisach masses were measured on;
//! * [`drift`]: whether a quasi-static record returns to the same state with the same reading
//!   (a time-dependent effect or friction otherwise: a warning of `maglab identify`, a finding
//!   of `maglab diagnose`);
//! * [`experiments`]: each record's fundamental, amplitude, bias, settling; quasi-static or not;
//! * [`nuisance`]: the recording's start states, current between samples and channel skew,
//!   estimated with a given model; the memory a lead-in record leaves;
//! * [`residual`]: pooled RMS, the sensor offset, the systematic part of an error.
//!
//! The model never sees the plant that made its test data: its tests and the diagnosis's run
//! it on the bench plant of `maglab-plant`, whose equations it does not share.

pub mod candidates;
pub mod coil_current;
pub mod coverage;
pub mod drift;
pub mod effects;
pub mod experiments;
pub mod fit;
pub mod model;
pub mod nuisance;
pub mod plan_fit;
pub mod priors;
pub mod residual;
