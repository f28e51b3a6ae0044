//! The vocabulary every measuring and analysing tool of the workspace shares: the dataset folder
//! format and the words it is written in.
//!
//! * [`data`]: a dataset is a folder of measurement files, one experiment per CSV (read and
//!   written here);
//! * [`dataset_info`]: the optional `dataset.json` that documents how each experiment started and
//!   what it excited;
//! * [`start`]: how an experiment starts ([`StartState`]), [`current`]: what the recorded current
//!   does between samples ([`CurrentBetweenSamples`]);
//! * [`excitation`]: the quasi-static reversal sweep (FORC) that identifies the Preisach masses;
//!   [`records`]: the sine and soak records the diagnosis advises;
//! * [`error`]: the error of all of them, naming file, line, column or field.
//!
//! Writers (`maglab rig`, the bench plant, `cargo xtask hil` and `record`) and readers
//! (`maglab identify`, `maglab diagnose`) use this crate, so a folder one writes the other reads.
//! It needs no numerics beyond the excitation's: a tool that only writes datasets (`xtask`, the
//! bench plant) does not compile the identification.

pub mod current;
pub mod data;
pub mod dataset_info;
pub mod error;
pub mod excitation;
pub mod records;
pub mod start;

pub use current::CurrentBetweenSamples;
pub use error::DataError;
pub use start::StartState;
