//! CMSDK APB timer (32-bit down counter at the system clock; reloads and raises its interrupt at
//! zero). Registers: CTRL +0x00 (bit 0 enable, bit 3 interrupt enable), VALUE +0x04, RELOAD
//! +0x08, INTSTATUS/INTCLEAR +0x0C.

use core::ptr::{read_volatile, write_volatile};

/// One CMSDK timer.
pub struct CmsdkTimer {
    base: usize,
}

const CTRL: usize = 0x00;
const VALUE: usize = 0x04;
const RELOAD: usize = 0x08;
const INT: usize = 0x0C;

impl CmsdkTimer {
    /// The timer at `base`.
    ///
    /// # Safety
    /// `base` must be a CMSDK timer's address and this must be its only owner.
    pub const unsafe fn new(base: usize) -> Self {
        CmsdkTimer { base }
    }

    #[inline(always)]
    fn reg(&self, offset: usize) -> *mut u32 {
        (self.base + offset) as *mut u32
    }

    /// Stops the timer, sets the reload (and current value) to `period_ticks - 1`, clears a
    /// pending interrupt, and starts it with or without its interrupt.
    pub fn start(&mut self, period_ticks: u32, interrupt: bool) {
        let reload = period_ticks.saturating_sub(1);
        unsafe {
            write_volatile(self.reg(CTRL), 0);
            write_volatile(self.reg(RELOAD), reload);
            write_volatile(self.reg(VALUE), reload);
            write_volatile(self.reg(INT), 1);
            write_volatile(self.reg(CTRL), if interrupt { 0b1001 } else { 0b0001 });
        }
    }

    /// Stops the timer.
    pub fn stop(&mut self) {
        unsafe { write_volatile(self.reg(CTRL), 0) }
    }

    /// Current counter value (counts down).
    #[inline(always)]
    pub fn value(&self) -> u32 {
        unsafe { read_volatile(self.reg(VALUE)) }
    }

    /// Whether the timer has expired since the last clear.
    #[inline(always)]
    pub fn pending(&self) -> bool {
        unsafe { read_volatile(self.reg(INT)) & 1 != 0 }
    }

    /// Clears the expiry flag (and the interrupt request).
    #[inline(always)]
    pub fn clear(&mut self) {
        unsafe { write_volatile(self.reg(INT), 1) }
    }
}
