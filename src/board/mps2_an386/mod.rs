//! QEMU `mps2-an386`: Cortex-M4F at 25 MHz with the CMSDK APB peripherals.
//!
//! Memory map used here (ARM AN386 / QEMU `hw/arm/mps2.c`): TIMER0 `0x4000_0000` (IRQ 8), TIMER1
//! `0x4000_1000` (IRQ 9, used as a free-running 32-bit clock, no interrupt), PL022 SPI
//! `0x4002_0000`, FPGAIO `0x4002_8000` (its MISC register drives the DAC chip select).

pub mod capture;
pub mod fpgaio;
pub mod logger;
pub mod panic;
pub mod pl022;
pub mod semihosting;
pub mod timer;
pub mod uart;
pub mod vectors;

/// System clock (TIMER0/1 and SysTick count it), Hz.
pub const SYSTEM_CLOCK_HZ: u32 = 25_000_000;
/// TIMER0 base address.
pub const TIMER0_BASE: usize = 0x4000_0000;
/// TIMER1 base address.
pub const TIMER1_BASE: usize = 0x4000_1000;
/// First PL022 SPI controller.
pub const SPI0_BASE: usize = 0x4002_0000;
/// FPGA I/O block.
pub const FPGAIO_BASE: usize = 0x4002_8000;
/// TIMER0's interrupt number.
pub const TIMER0_IRQ: u16 = 8;
