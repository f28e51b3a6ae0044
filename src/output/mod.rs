//! The output stage: current command → DAC code → DAC.
//!
//! The coil is driven by a bipolar transconductance amplifier whose input is a 16-bit DAC; the
//! amplifier maps the DAC's full range linearly onto `[-I_fs, +I_fs]` (two's complement: 0x8000
//! is `-I_fs`, 0x0000 is 0 A, 0x7FFF is `+I_fs - 1 LSB`). The DAC (TI DAC8550) powers up at
//! mid-scale = code 0x0000 = 0 A; the power-up, reset and fault sequence is in
//! `docs/safety.md`.
//!
//! * [`DacScale`]: the current → code conversion, in fixed point with the `fixed` crate
//!   (`I1F15`: the normalized current in `[-1, 1)` is a signed Q1.15 number, whose bits are the
//!   two's-complement code).
//! * [`SpiDac`]: a 16-bit SPI DAC (TI DAC8550, 24-bit frame) driven through embedded-hal's
//!   [`SpiDevice`](embedded_hal::spi::SpiDevice), used on both boards.
//! * [`CurrentOutput`]: what the control interrupt calls.

mod dac_scale;
mod spi_dac;

pub use dac_scale::DacScale;
pub use spi_dac::SpiDac;

/// A sink for current commands.
pub trait CurrentOutput {
    /// Transport error.
    type Error;
    /// Converts and writes one current command (A); returns the DAC code written.
    fn write_current(&mut self, current_a: f32) -> Result<u16, Self::Error>;
}
