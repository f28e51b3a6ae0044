//! Reference simulators: straightforward f64 implementations of the paper's definitions, written
//! without the core's algorithms, for the host tests to compare against.
//!
//! * [`preisach`]: the Preisach operator (paper eqs. (1)-(3)) as a field of elementary relays.
//! * [`rig`]: the virtual test rig's plant, the reference dynamics with unmodelled effects.

pub mod dynamics;
pub mod preisach;
pub mod rig;
