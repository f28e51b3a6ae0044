//! Reference simulators: straightforward f64 implementations of the paper's definitions, written
//! without the core's algorithms, for the host tests to compare against.
//!
//! * [`preisach`]: the Preisach operator (paper eqs. (1)-(3)) as a field of elementary relays.
//! * [`dynamics`]: the dynamic model (4)-(5) integrated in the integral form (8) by RK4.
//!
//! The bench plant with unmodelled effects is the product crate `maglab-plant`.

pub mod dynamics;
pub mod preisach;
