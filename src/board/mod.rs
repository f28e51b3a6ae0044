//! Board support for the firmware (built only for `target_os = "none"`).
//!
//! * [`mps2_an386`] (feature `board-mps2-an386`): QEMU's `mps2-an386` (Cortex-M4F, 25 MHz):
//!   CMSDK TIMER0 (IRQ 8) as the control timer, TIMER1 and SysTick for measurement, a PL022 SPI
//!   controller driving the DAC, semihosting for the capture stream, logs (defmt) and exit codes.
//! * [`nucleo_f446re`] (feature `board-nucleo-f446re`): NUCLEO-F446RE (STM32F446RE, Cortex-M4F,
//!   180 MHz): TIM2 as the control timer, SPI1 driving the DAC, defmt over RTT, fatal paths that
//!   command 0 A and halt for the probe.
//!
//! Linker files live in `boards/<board>/` (selected by `build.rs` from the feature).

#[cfg(feature = "board-mps2-an386")]
pub mod mps2_an386;
#[cfg(feature = "board-nucleo-f446re")]
pub mod nucleo_f446re;
pub mod polled_spi;
