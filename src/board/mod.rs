//! Board support for the firmware (built only for `target_os = "none"`).
//!
//! * [`mps2_an386`] (feature `board-mps2-an386`): QEMU's `mps2-an386` (Cortex-M4F, 25 MHz):
//!   CMSDK TIMER0 (IRQ 8) as the control timer, TIMER1 and SysTick for measurement, a PL022 SPI
//!   controller driving the DAC, semihosting for the capture stream, logs (defmt) and exit codes.
//! * NUCLEO-F446RE: not written yet (its linker file `boards/nucleo-f446re/memory.x` and the
//!   `build.rs` selection for a `board-nucleo-f446re` feature are in place).
//!
//! Linker files live in `boards/<board>/` (selected by `build.rs` from the feature).

#[cfg(feature = "board-mps2-an386")]
pub mod mps2_an386;
