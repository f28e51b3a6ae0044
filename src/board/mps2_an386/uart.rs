//! CMSDK APB UART (ARM AN386; QEMU `cmsdk-apb-uart`): a one-byte transmit and a one-byte receive
//! buffer, polled. Registers: DATA +0x00, STATE +0x04 (bit 0 TX buffer full, bit 1 RX buffer
//! full), CTRL +0x08 (bit 0 TX enable, bit 1 RX enable), INTSTATUS/INTCLEAR +0x0C, BAUDDIV +0x10
//! (≥ 16; QEMU ignores a UART whose divider is smaller).
//!
//! Every wait is bounded by a poll count: the firmware never waits for the link without a bound
//! (a silent or stuck plant becomes [`UartTimeout`], which the caller turns into a link fault).

use core::ptr::{read_volatile, write_volatile};

const DATA: usize = 0x00;
const STATE: usize = 0x04;
const CTRL: usize = 0x08;
const BAUDDIV: usize = 0x10;
const STATE_TX_FULL: u32 = 1;
const STATE_RX_FULL: u32 = 2;

/// UART0's base address on mps2-an386 (QEMU's first `-serial`).
pub const UART0_BASE: usize = 0x4000_4000;

/// A bounded wait ran out.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct UartTimeout;

/// One CMSDK UART.
pub struct CmsdkUart {
    base: usize,
}

impl CmsdkUart {
    /// The UART at `base`, transmitter and receiver enabled at `bauddiv` (clamped to ≥ 16).
    ///
    /// # Safety
    /// `base` must be a CMSDK UART's address and this must be its only owner.
    pub unsafe fn new(base: usize, bauddiv: u32) -> Self {
        let u = CmsdkUart { base };
        unsafe {
            write_volatile(u.reg(BAUDDIV), bauddiv.max(16));
            write_volatile(u.reg(CTRL), 0b11);
        }
        u
    }

    #[inline(always)]
    fn reg(&self, offset: usize) -> *mut u32 {
        (self.base + offset) as *mut u32
    }

    /// A received byte, if one is waiting.
    #[inline]
    pub fn try_read(&mut self) -> Option<u8> {
        unsafe {
            if read_volatile(self.reg(STATE)) & STATE_RX_FULL != 0 {
                Some(read_volatile(self.reg(DATA)) as u8)
            } else {
                None
            }
        }
    }

    /// Writes `bytes`, waiting at most `max_polls` status reads for each byte's buffer slot.
    pub fn write_all(&mut self, bytes: &[u8], max_polls: u32) -> Result<(), UartTimeout> {
        for &b in bytes {
            let mut polls = 0u32;
            while unsafe { read_volatile(self.reg(STATE)) } & STATE_TX_FULL != 0 {
                polls += 1;
                if polls >= max_polls {
                    return Err(UartTimeout);
                }
            }
            unsafe { write_volatile(self.reg(DATA), b as u32) };
        }
        Ok(())
    }

    /// Waits (at most `max_polls` status reads) until the last byte written has left the
    /// transmit buffer: QEMU keeps TX-full set while its character backend has not taken the
    /// byte, and a semihosting exit before that loses it.
    pub fn flush(&mut self, max_polls: u32) -> Result<(), UartTimeout> {
        let mut polls = 0u32;
        while unsafe { read_volatile(self.reg(STATE)) } & STATE_TX_FULL != 0 {
            polls += 1;
            if polls >= max_polls {
                return Err(UartTimeout);
            }
        }
        Ok(())
    }
}
