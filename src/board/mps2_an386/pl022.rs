//! ARM PrimeCell PL022 SSP as an embedded-hal [`SpiBus`] (8-bit frames, Motorola SPI).
//! Registers: CR0 +0x00, CR1 +0x04, DR +0x08, SR +0x0C (TFE bit 0, TNF bit 1, RNE bit 2, BSY bit 4),
//! CPSR +0x10.

use crate::board::polled_spi::{wait_until, ByteExchange, SpiTimeout};
use core::ptr::{read_volatile, write_volatile};

const CR0: usize = 0x00;
const CR1: usize = 0x04;
const DR: usize = 0x08;
const SR: usize = 0x0C;
const CPSR: usize = 0x10;
const SR_TFE: u32 = 1 << 0;
const SR_TNF: u32 = 1 << 1;
const SR_RNE: u32 = 1 << 2;
const SR_BSY: u32 = 1 << 4;
/// Entries of each FIFO.
const FIFO_DEPTH: usize = 8;

/// A PL022 in master mode.
pub struct Pl022 {
    base: usize,
}

impl Pl022 {
    /// Configures the controller at `base`: 8-bit frames, SPI mode 1 (CPOL 0, CPHA 1), bit rate
    /// `clock / (cpsdvsr · (1 + scr))` with CPSDVSR = 2, SCR = 0 (12.5 MHz at 25 MHz), enabled.
    ///
    /// # Safety
    /// `base` must be a PL022's address and this must be its only owner.
    pub unsafe fn new(base: usize) -> Self {
        let s = Pl022 { base };
        unsafe {
            write_volatile(s.reg(CR1), 0);
            write_volatile(s.reg(CPSR), 2);
            // DSS = 7 (8 bits), FRF = 0 (Motorola), SPO = 0, SPH = 1, SCR = 0.
            write_volatile(s.reg(CR0), 0x7 | (1 << 7));
            write_volatile(s.reg(CR1), 1 << 1);
        }
        s
    }

    #[inline(always)]
    fn reg(&self, offset: usize) -> *mut u32 {
        (self.base + offset) as *mut u32
    }

    #[inline(always)]
    fn sr(&self) -> u32 {
        unsafe { read_volatile(self.reg(SR)) }
    }
}

impl ByteExchange for Pl022 {
    #[inline(always)]
    fn exchange(&mut self, byte: u8) -> Result<u8, SpiTimeout> {
        wait_until(|| self.sr() & SR_TNF != 0)?;
        unsafe { write_volatile(self.reg(DR), byte as u32) };
        wait_until(|| self.sr() & SR_RNE != 0)?;
        Ok(unsafe { read_volatile(self.reg(DR)) as u8 })
    }
    fn busy(&self) -> bool {
        self.sr() & SR_BSY != 0
    }

    /// Fills the 8-entry transmit FIFO, waits until the shifter is idle, then empties the receive
    /// FIFO (bounded by its depth). A frame that fits the FIFO while it is empty (TFE, one status
    /// read) is written without a poll per byte, and its bytes, all received once the shifter is
    /// idle, are read back without one either (the DAC frame: 3 bytes); otherwise each byte waits
    /// for room (TNF).
    #[inline(always)]
    fn write_all(&mut self, words: &[u8]) -> Result<(), SpiTimeout> {
        let fits = words.len() <= FIFO_DEPTH && self.sr() & SR_TFE != 0;
        if fits {
            for &w in words {
                unsafe { write_volatile(self.reg(DR), w as u32) };
            }
        } else {
            for &w in words {
                wait_until(|| self.sr() & SR_TNF != 0)?;
                unsafe { write_volatile(self.reg(DR), w as u32) };
            }
        }
        wait_until(|| self.sr() & SR_BSY == 0)?;
        if fits {
            for _ in words {
                unsafe { read_volatile(self.reg(DR)) };
            }
        }
        for _ in 0..FIFO_DEPTH {
            if self.sr() & SR_RNE == 0 {
                break;
            }
            unsafe { read_volatile(self.reg(DR)) };
        }
        Ok(())
    }
}

crate::impl_polled_spi_bus!(Pl022);
