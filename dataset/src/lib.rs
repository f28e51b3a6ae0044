//! The dataset folder format every measuring and analysing tool of the workspace shares.
//!
//! A dataset is a folder of measurement files, one experiment per CSV ([`data`]), and an
//! optional `dataset.json` that documents how each experiment started and what it excited
//! ([`dataset_info`]). Writers (`maglab rig`, `cargo xtask hil` and `record`) and readers
//! (`maglab identify`, `maglab diagnose`) use this crate, so a folder one writes the other reads.
//!
//! It is a crate of its own, apart from the identification (`maglab-identify`, which re-exports
//! both modules), so that a tool that only writes datasets (`xtask`) does not compile the
//! numerics of the identification: the format needs `csv` and `serde_json` only.

pub mod data;
pub mod dataset_info;
