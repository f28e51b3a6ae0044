//! `host-tests`: the std-side check of the no_std core.
//!
//! This crate owns an **independent f64 reference simulator** ([`reference`](mod@reference)) that shares no
//! algorithm code with `magctl` (it only reads the grid size and the baked parameters), and the
//! integration tests and benchmarks that compare the core with it (`tests/`, `benches/`). It exists
//! so that every claim the core makes (exactness of the Everett algebra, wiping-out, the merge
//! bound, the exact inverse) is checked against a second, deliberately naive implementation of
//! the paper's definitions rather than against itself.

pub mod bounds;
pub mod reference;
pub mod tracking;
