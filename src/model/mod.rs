//! The rate-dependent actuator model of the paper (Section 3): eddy-current equation (4) coupled
//! with the Preisach operator, the magnetoelastic dynamics (5), and the static limit (6), stepped
//! at the fixed control period.
//!
//! * [`eddy`]: one implicit step of (4), solved exactly with the Preisach monotone solve.
//! * [`magnetoelastic`]: the exact discretization of (5) for an `M²` that is linear over a step.
//! * [`dynamic`]: the coupled model `step(current_a)`.
//! * [`static_model`]: model (6), the quasi-static limit.
//!
//! Conventions: the current passed to `step` is the amplifier output *held over the coming
//! step* (what a DAC does), so the model advances from `t_k` to `t_k + h` under `I(t) = I_k`.

pub mod dynamic;
pub mod eddy;
pub mod magnetoelastic;
pub mod static_model;

pub use dynamic::{DynamicModel, ModelFaults, ModelOutput, ModelState};
pub use eddy::EddyCurrentStep;
pub use magnetoelastic::MagnetoelasticStep;
pub use static_model::StaticModel;
