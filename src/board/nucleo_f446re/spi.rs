//! SPI1 (master, 8-bit frames, mode 1) on PA5/PA7 as an embedded-hal [`SpiBus`], and PB6 as the
//! DAC's chip select ([`OutputPin`]) — the board side of `magctl::output::SpiDac`, which wraps
//! them in `embedded_hal_bus::spi::ExclusiveDevice` (RM0390 §26 SPI, §7 GPIO).
//!
//! SPI1 runs from APB2 (90 MHz) divided by 8: 11.25 MHz (the DAC8550 accepts up to 30 MHz), so a
//! 24-bit frame takes 2.1 µs. Every byte is exchanged (written, then its received byte read), so
//! the receive side never overruns; MISO is not connected (PA6 stays a plain input).

use crate::board::polled_spi::{wait_until, ByteExchange, SpiTimeout};
use core::convert::Infallible;
use embedded_hal::digital::{ErrorType as PinErrorType, OutputPin};
use stm32f4::stm32f446 as pac;

const AHB1ENR_GPIOAEN: u32 = 1 << 0;
const AHB1ENR_GPIOBEN: u32 = 1 << 1;
const APB2ENR_SPI1EN: u32 = 1 << 12;
/// Alternate function 5 = SPI1 on PA5 (SCK) and PA7 (MOSI).
const AF_SPI1: u32 = 5;
const SCK_PIN: u32 = 5;
const MOSI_PIN: u32 = 7;
/// Chip-select pin on port B.
pub const CS_PIN: u32 = 6;
/// CPHA = 1 (mode 1), MSTR, BR = 0b010 (f_PCLK2 / 8), SSM + SSI (software slave select).
const CR1_MODE1_MASTER_DIV8: u16 = (1 << 0) | (1 << 2) | (0b010 << 3) | (1 << 8) | (1 << 9);
const CR1_SPE: u16 = 1 << 6;
const SR_RXNE: u16 = 1 << 0;
const SR_TXE: u16 = 1 << 1;
const SR_BSY: u16 = 1 << 7;

/// SPI bit rate, Hz.
pub const SPI_HZ: u32 = super::clocks::PCLK2_HZ / 8;

/// SPI1 in master mode.
pub struct Spi1 {
    regs: &'static pac::spi1::RegisterBlock,
}

/// PB6 as a push-pull output.
pub struct ChipSelect {
    gpiob: &'static pac::gpioa::RegisterBlock,
}

/// Sets a pin's 2-bit field in MODER / OSPEEDR.
fn two_bits(reg: u32, pin: u32, value: u32) -> u32 {
    (reg & !(0b11 << (2 * pin))) | (value << (2 * pin))
}

/// Clocks GPIOA, GPIOB and SPI1, muxes PA5/PA7 to SPI1, makes PB6 a high (deselected) output and
/// enables SPI1. Call once after [`super::clocks::init`]; returns the bus and the chip select.
pub fn init(rcc: &pac::RCC) -> (Spi1, ChipSelect) {
    // SAFETY: fixed peripheral addresses; this function is the only user of these pins and SPI1
    // (the fatal handlers touch them only after masking interrupts, for a last 0 A frame).
    let gpioa: &'static pac::gpioa::RegisterBlock = unsafe { &*pac::GPIOA::ptr() };
    let gpiob: &'static pac::gpioa::RegisterBlock =
        unsafe { &*(pac::GPIOB::ptr() as *const pac::gpioa::RegisterBlock) };
    let spi: &'static pac::spi1::RegisterBlock = unsafe { &*pac::SPI1::ptr() };
    rcc.ahb1enr()
        .modify(|r, w| unsafe { w.bits(r.bits() | AHB1ENR_GPIOAEN | AHB1ENR_GPIOBEN) });
    rcc.apb2enr()
        .modify(|r, w| unsafe { w.bits(r.bits() | APB2ENR_SPI1EN) });
    // SAFETY (all `bits` writes): field values from RM0390, documented above.
    gpioa.afrl().modify(|r, w| unsafe {
        let mut v = r.bits();
        for pin in [SCK_PIN, MOSI_PIN] {
            v = (v & !(0xF << (4 * pin))) | (AF_SPI1 << (4 * pin));
        }
        w.bits(v)
    });
    gpioa.ospeedr().modify(|r, w| unsafe {
        w.bits(two_bits(two_bits(r.bits(), SCK_PIN, 0b11), MOSI_PIN, 0b11))
    });
    gpioa.moder().modify(|r, w| unsafe {
        w.bits(two_bits(two_bits(r.bits(), SCK_PIN, 0b10), MOSI_PIN, 0b10))
    });
    gpiob.bsrr().write(|w| unsafe { w.bits(1 << CS_PIN) });
    gpiob
        .ospeedr()
        .modify(|r, w| unsafe { w.bits(two_bits(r.bits(), CS_PIN, 0b11)) });
    gpiob
        .moder()
        .modify(|r, w| unsafe { w.bits(two_bits(r.bits(), CS_PIN, 0b01)) });
    spi.cr1()
        .write(|w| unsafe { w.bits(CR1_MODE1_MASTER_DIV8) });
    spi.cr1()
        .write(|w| unsafe { w.bits(CR1_MODE1_MASTER_DIV8 | CR1_SPE) });
    (Spi1 { regs: spi }, ChipSelect { gpiob })
}

// SAFETY: the handle is the only user of its peripheral's registers (see its constructor);
// moving it to the interrupt that uses it (through `HandOff`) moves that ownership.
unsafe impl Send for Spi1 {}

impl Spi1 {
    #[inline(always)]
    fn sr(&self) -> u16 {
        self.regs.sr().read().bits()
    }
}

impl ByteExchange for Spi1 {
    #[inline(always)]
    fn exchange(&mut self, byte: u8) -> Result<u8, SpiTimeout> {
        wait_until(|| self.sr() & SR_TXE != 0)?;
        self.regs.dr().write(|w| unsafe { w.bits(byte as u16) });
        wait_until(|| self.sr() & SR_RXNE != 0)?;
        Ok(self.regs.dr().read().bits() as u8)
    }
    fn busy(&self) -> bool {
        self.sr() & SR_BSY != 0
    }

    /// Writes each byte as soon as the transmit buffer is empty (so the shifter never idles
    /// between bytes), waits until the last bit is out, then reads DR and SR once: that clears
    /// RXNE and the overrun flag the unread received bytes raised (RM0390 §26.3.10).
    #[inline(always)]
    fn write_all(&mut self, words: &[u8]) -> Result<(), SpiTimeout> {
        for &w in words {
            wait_until(|| self.sr() & SR_TXE != 0)?;
            self.regs.dr().write(|r| unsafe { r.bits(w as u16) });
        }
        wait_until(|| self.sr() & SR_TXE != 0)?;
        wait_until(|| self.sr() & SR_BSY == 0)?;
        let _ = self.regs.dr().read().bits();
        let _ = self.sr();
        Ok(())
    }
}

crate::impl_polled_spi_bus!(Spi1);

// SAFETY: the handle is the only user of its peripheral's registers (see its constructor);
// moving it to the interrupt that uses it (through `HandOff`) moves that ownership.
unsafe impl Send for ChipSelect {}

impl PinErrorType for ChipSelect {
    type Error = Infallible;
}

impl OutputPin for ChipSelect {
    fn set_low(&mut self) -> Result<(), Infallible> {
        self.gpiob
            .bsrr()
            .write(|w| unsafe { w.bits(1 << (CS_PIN + 16)) });
        Ok(())
    }

    fn set_high(&mut self) -> Result<(), Infallible> {
        self.gpiob.bsrr().write(|w| unsafe { w.bits(1 << CS_PIN) });
        Ok(())
    }
}
