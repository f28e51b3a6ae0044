//! TIM2 (32-bit, clocked at 90 MHz) as the control-rate interrupt source (RM0390 §18).
//!
//! Period: `ARR + 1 = TIM2_CLOCK_HZ / rate` counts (9,000 at 10 kHz, exact); the update event at
//! every overflow raises UIF and, with UIE, the TIM2 interrupt. The control rate must divide into
//! a whole number of counts between 2 and 2³²; [`ControlTimer::new`] rejects anything else.

use super::clocks::TIM2_CLOCK_HZ;
use stm32f4::stm32f446 as pac;

const APB1ENR_TIM2EN: u32 = 1 << 0;
const CR1_CEN: u32 = 1 << 0;
/// Only counter overflow raises UIF (not the UG that loads the registers).
const CR1_URS: u32 = 1 << 2;
const DIER_UIE: u32 = 1 << 0;
const SR_UIF: u32 = 1 << 0;
const EGR_UG: u32 = 1 << 0;

/// TIM2 running at the control rate.
pub struct ControlTimer {
    regs: &'static pac::tim2::RegisterBlock,
}

// SAFETY: the handle is the only user of its peripheral's registers (see its constructor);
// moving it to the interrupt that uses it (through `HandOff`) moves that ownership.
unsafe impl Send for ControlTimer {}

impl ControlTimer {
    /// Configures and starts TIM2 with its update interrupt enabled (the NVIC line is unmasked by
    /// the caller). `None` if `rate_hz` is not a whole divisor of the timer clock in range.
    pub fn new(rcc: &pac::RCC, rate_hz: u32) -> Option<Self> {
        let counts = TIM2_CLOCK_HZ.checked_div(rate_hz)?;
        if counts < 2 || counts.checked_mul(rate_hz)? != TIM2_CLOCK_HZ {
            return None;
        }
        // SAFETY: fixed peripheral address; TIM2 has no other user.
        let regs: &'static pac::tim2::RegisterBlock = unsafe { &*pac::TIM2::ptr() };
        rcc.apb1enr()
            .modify(|r, w| unsafe { w.bits(r.bits() | APB1ENR_TIM2EN) });
        // SAFETY (all `bits` writes): field values from RM0390, documented above.
        regs.cr1().write(|w| unsafe { w.bits(CR1_URS) });
        regs.psc().write(|w| unsafe { w.bits(0) });
        regs.arr().write(|w| unsafe { w.bits(counts - 1) });
        regs.egr().write(|w| unsafe { w.bits(EGR_UG) });
        regs.sr().write(|w| unsafe { w.bits(0) });
        regs.dier().write(|w| unsafe { w.bits(DIER_UIE) });
        regs.cr1().write(|w| unsafe { w.bits(CR1_URS | CR1_CEN) });
        Some(ControlTimer { regs })
    }

    /// Acknowledges the update interrupt (clears UIF; the other flags are rc_w0, write 1 keeps).
    #[inline(always)]
    pub fn clear(&mut self) {
        self.regs.sr().write(|w| unsafe { w.bits(!SR_UIF) });
    }

    /// Whether the next update is already pending (an overrun when asked at the end of the
    /// handler).
    #[inline(always)]
    pub fn pending(&self) -> bool {
        self.regs.sr().read().bits() & SR_UIF != 0
    }

    /// Emulator build: stops the counter (the update interrupt is then pended by software,
    /// `firmware-nucleo`'s `bench` module says why); the registers stay configured.
    #[cfg(feature = "emulator-netduinoplus2")]
    pub fn stopped(self) -> Self {
        // SAFETY: URS without CEN: the counter stops, nothing else changes.
        self.regs.cr1().write(|w| unsafe { w.bits(CR1_URS) });
        self
    }
}
