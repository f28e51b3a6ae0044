//! Inverse control (paper Section 5). This part: the static-model inverse (6), the
//! baseline the dynamic inverse is compared with.

mod static_inverse;

pub use static_inverse::{StaticInverse, StaticInverseOutput};
