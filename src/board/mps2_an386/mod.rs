//! QEMU `mps2-an386`: Cortex-M4F at 25 MHz with the CMSDK APB peripherals.
//!
//! Memory map used here (ARM AN386 / QEMU `hw/arm/mps2.c`): TIMER0 `0x4000_0000` (IRQ 8), TIMER1
//! `0x4000_1000` (IRQ 9, used as a free-running 32-bit clock, no interrupt), PL022 SPI
//! `0x4002_0000`, FPGAIO `0x4002_8000` (its MISC register drives the DAC chip select).

pub mod capture;
pub mod fpgaio;
pub mod panic;
pub mod pl022;
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

/// TIMER0's interrupt, for `cortex_m::peripheral::NVIC` (unmask, mask, pend).
#[derive(Clone, Copy)]
pub struct Timer0Irq;

// SAFETY: 8 is TIMER0's interrupt number on mps2-an386.
unsafe impl cortex_m::interrupt::InterruptNumber for Timer0Irq {
    fn number(self) -> u16 {
        TIMER0_IRQ
    }
}

/// The coil's DAC: on the PL022 SPI0 with the FPGAIO MISC pin 1 as its chip select.
pub type Dac = crate::output::SpiDac<
    embedded_hal_bus::spi::ExclusiveDevice<
        pl022::Pl022,
        fpgaio::MiscPin,
        embedded_hal_bus::spi::NoDelay,
    >,
>;

/// The coil's DAC driver with `scale` (call once; it writes nothing).
///
/// # Safety
/// Takes ownership of SPI0 and FPGAIO MISC pin 1: there must be no other owner.
pub unsafe fn take_dac(scale: crate::output::DacScale) -> Dac {
    let spi = unsafe { pl022::Pl022::new(SPI0_BASE) };
    let cs = unsafe { fpgaio::MiscPin::new(FPGAIO_BASE, 1) };
    let Ok(device) = embedded_hal_bus::spi::ExclusiveDevice::new_no_delay(spi, cs);
    crate::output::SpiDac::new(device, scale)
}
