//! FPGAIO MISC register (+0x4C) bit used as the DAC's active-low chip select, as an
//! embedded-hal [`OutputPin`].

use core::convert::Infallible;
use core::ptr::{read_volatile, write_volatile};
use embedded_hal::digital::{ErrorType, OutputPin};

const MISC: usize = 0x4C;

/// One bit of FPGAIO MISC.
pub struct MiscPin {
    reg: *mut u32,
    mask: u32,
}

// SAFETY: the pin owns its bit of a memory-mapped register (the constructor's contract); moving
// it to the interrupt that uses it (through `HandOff`) moves that ownership.
unsafe impl Send for MiscPin {}

impl MiscPin {
    /// Bit `bit` of the MISC register of the FPGAIO block at `base`, driven high (deselected).
    ///
    /// # Safety
    /// `base` must be the FPGAIO block and no one else may write that bit.
    pub unsafe fn new(base: usize, bit: u32) -> Self {
        let mut p = MiscPin {
            reg: (base + MISC) as *mut u32,
            mask: 1 << (bit & 31),
        };
        let _ = p.set_high();
        p
    }
}

impl ErrorType for MiscPin {
    type Error = Infallible;
}

impl OutputPin for MiscPin {
    fn set_low(&mut self) -> Result<(), Infallible> {
        unsafe { write_volatile(self.reg, read_volatile(self.reg) & !self.mask) };
        Ok(())
    }

    fn set_high(&mut self) -> Result<(), Infallible> {
        unsafe { write_volatile(self.reg, read_volatile(self.reg) | self.mask) };
        Ok(())
    }
}
