//! `maglab-plant`: the bench plant — an independent simulator of a magnetostrictive actuator on
//! a test bench, with the unmodelled effects and the recording nuisances a real rig has.
//!
//! It is the plant behind `maglab rig` (datasets), `maglab track` (the controller against a
//! plant) and the diagnosis' blind test suite. It shares no equations with the model under test
//! beyond the paper's: its own f64 Preisach operator ([`preisach`]), the eddy-current equation in
//! differential form with its own RK4 integrator ([`actuator`]), each effect in a physical form
//! the diagnosis' candidates do not have ([`effects`]), and a recorder with channel skew, sensor
//! offset, noise, quantization and documented start states ([`bench`](mod@bench)).

pub mod actuator;
pub mod bench;
pub mod effects;
mod forms;
pub mod preisach;
pub mod rods;
pub mod suite;

pub use actuator::{Plant, PlantConstants, PLANT_STARTS};
pub use bench::{BenchSettings, CurrentMonitor, Experiment, Recording};
pub use effects::{Effect, EffectSpec, EFFECTS};
pub use rods::{Family, Rod};
