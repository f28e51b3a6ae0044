//! Board support for the firmware. The two boards are behind their features (and only make sense
//! for `target_os = "none"`); [`polled_spi`], [`handoff`], [`capture_phase`] and
//! [`command_line`] and [`tick_mailbox`] are board-independent and tested on the host.
//!
//! * `mps2_an386` (feature `board-mps2-an386`): QEMU's `mps2-an386` (Cortex-M4F, 25 MHz):
//!   CMSDK TIMER0 (IRQ 8) as the control timer, TIMER1 and SysTick for measurement, a PL022 SPI
//!   controller driving the DAC, semihosting for the capture stream, logs (defmt) and exit codes.
//! * `nucleo_f446re` (feature `board-nucleo-f446re`): NUCLEO-F446RE (STM32F446RE, Cortex-M4F,
//!   180 MHz): TIM2 as the control timer, SPI1 driving the DAC, defmt over RTT, fatal paths that
//!   command 0 A and halt for the probe. Its emulator build (feature `emulator-netduinoplus2`)
//!   runs the same code on QEMU's `netduinoplus2` (STM32F405) with the plant link on USART2.
//! * `semihosting`: semihosting calls and the defmt logger over them, for both QEMU machines.
//!
//! Linker files live in `boards/<board>/` (selected by `build.rs` from the feature).

pub mod capture_phase;
pub mod command_line;
pub mod handoff;
#[cfg(all(target_os = "none", feature = "board-mps2-an386"))]
pub mod mps2_an386;
#[cfg(all(target_os = "none", feature = "board-nucleo-f446re"))]
pub mod nucleo_f446re;
pub mod polled_spi;
#[cfg(all(
    target_os = "none",
    any(feature = "board-mps2-an386", feature = "emulator-netduinoplus2")
))]
pub mod semihosting;
#[cfg(target_os = "none")]
pub mod stack;
pub mod tick_mailbox;
