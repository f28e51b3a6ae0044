//! `magctl`: the no_std core of a rate-dependent hysteresis controller for a magnetostrictive
//! (Terfenol-D) actuator, after Tan & Baras, "Modeling and Control of a Magnetostrictive
//! Actuator" (paper in `../shared/paper/`).
//!
//! * [`preisach`]: the Preisach operator `M = Γ[H]` on a fixed 25-level grid with a density uniform
//!   inside each cell (paper Section 4), its memory staircase, forward evaluation, the exact inverse
//!   and the monotone solve `a·h + Γ(h) = r`.
//! * [`model`]: the dynamic model (4)-(5) stepped at the control rate, and the static model (6).
//! * [`inverse`]: inverse control (paper Section 5): the dynamic-model and static-model inverses,
//!   output limits, and the control loop one timer interrupt runs.
//! * [`params`]: the actuator parameters baked in at build time from the JSON file.
//! * [`trajectory`]: the Van der Pol desired trajectory integrated on the chip.
//! * [`sensor`]: the displacement sample of every tick, scaled and checked.
//! * [`programme`]: the identification programme the firmware plays in measurement mode, and
//!   [`coil_heat`] the coil temperature estimate its pauses follow.
//! * [`record`]: the measurement record the firmware streams while it plays it (queue, batches).
//! * [`link`]: the frames of the lock-step plant link of the virtual bench (`docs/hil.md`).
//! * [`sqrt`]: the square root, on the FPU's `VSQRT.F32` on the Cortex-M4F.
//! * [`output`]: current command → DAC code (fixed point) → SPI DAC through embedded-hal.
//! * [`board`]: QEMU mps2-an386 and NUCLEO-F446RE support (behind their `board-*` features,
//!   firmware only), plus the board-independent pieces the host tests too: the bounded-wait SPI
//!   bus and the hand-over of the interrupt's state.
//!
//! Everything here builds for the host and for `thumbv7em-none-eabihf`; it never allocates and
//! never panics on its update paths (errors are values).
#![no_std]
#![deny(missing_docs)]

// Host tools only (feature `host`): run-time parameter-file conversion needs `String`.
#[cfg(feature = "host")]
extern crate std;

pub mod board;
pub mod coil_heat;
pub mod inverse;
pub mod link;
pub mod model;
pub mod output;
pub mod params;
pub mod preisach;
pub mod programme;
pub mod record;
pub mod select;
pub mod sensor;
pub mod sqrt;
pub mod trajectory;
