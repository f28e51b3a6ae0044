//! Clock tree of the STM32F446RE (RM0390 §6): HSE bypass 8 MHz → PLL → SYSCLK 180 MHz,
//! AHB 180 MHz, APB1 45 MHz (TIM2 at 90 MHz), APB2 90 MHz (SPI1), with over-drive and 5 flash
//! wait states as 180 MHz requires (RM0390 §3.4.1, §5.1.4).
//!
//! PLL: `f_VCO = HSE / M · N = 8 MHz / 4 · 180 = 360 MHz` (VCO input 2 MHz, output within
//! 100..432 MHz), `SYSCLK = f_VCO / P = 360 / 2`; Q = 8 and R = 2 are unused outputs kept in range.
//!
//! Register-level (PAC pointers, raw bit values named below): nothing here can panic. The waits
//! for the ready flags spin until the hardware sets them (a missing HSE input hangs here, before
//! the control interrupt is enabled, with the DAC never written).

use stm32f4::stm32f446 as pac;

const RCC_CR_HSEON: u32 = 1 << 16;
const RCC_CR_HSERDY: u32 = 1 << 17;
const RCC_CR_HSEBYP: u32 = 1 << 18;
const RCC_CR_PLLON: u32 = 1 << 24;
const RCC_CR_PLLRDY: u32 = 1 << 25;
const PLL_M: u32 = 4;
const PLL_N: u32 = 180;
/// P = 2 is encoded as 0.
const PLL_P_BITS: u32 = 0;
const PLL_Q: u32 = 8;
const PLL_R: u32 = 2;
const PLLCFGR_SRC_HSE: u32 = 1 << 22;
/// SW = PLL_P, HPRE = /1, PPRE1 = /4 (0b101), PPRE2 = /2 (0b100).
const CFGR_SW_PLL: u32 = 0b10;
const CFGR_SWS_MASK: u32 = 0b11 << 2;
const CFGR_SWS_PLL: u32 = 0b10 << 2;
const CFGR_PPRE1_DIV4: u32 = 0b101 << 10;
const CFGR_PPRE2_DIV2: u32 = 0b100 << 13;
const APB1ENR_PWREN: u32 = 1 << 28;
const PWR_CR_VOS_SCALE1: u32 = 0b11 << 14;
const PWR_CR_ODEN: u32 = 1 << 16;
const PWR_CR_ODSWEN: u32 = 1 << 17;
const PWR_CSR_ODRDY: u32 = 1 << 16;
const PWR_CSR_ODSWRDY: u32 = 1 << 17;
/// 5 wait states (180 MHz at 2.7-3.6 V), prefetch, instruction and data caches.
const FLASH_ACR: u32 = 5 | (1 << 8) | (1 << 9) | (1 << 10);

/// Core clock after [`init`], Hz.
pub const SYSCLK_HZ: u32 = 180_000_000;
/// APB1 clock, Hz.
pub const PCLK1_HZ: u32 = SYSCLK_HZ / 4;
/// APB2 clock, Hz.
pub const PCLK2_HZ: u32 = SYSCLK_HZ / 2;
/// Clock of the APB1 timers (TIM2): twice PCLK1 because the APB1 prescaler is not 1.
pub const TIM2_CLOCK_HZ: u32 = 2 * PCLK1_HZ;

fn spin_until(done: impl Fn() -> bool) {
    while !done() {}
}

/// Switches the system to the 180 MHz PLL clock. Call once, first thing in `main`.
pub fn init(rcc: &pac::RCC, pwr: &pac::PWR, flash: &pac::FLASH) {
    // SAFETY (all `bits` writes): values from RM0390 for these registers, documented above.
    rcc.apb1enr()
        .modify(|r, w| unsafe { w.bits(r.bits() | APB1ENR_PWREN) });
    pwr.cr()
        .modify(|r, w| unsafe { w.bits(r.bits() | PWR_CR_VOS_SCALE1) });
    rcc.cr()
        .modify(|r, w| unsafe { w.bits(r.bits() | RCC_CR_HSEBYP | RCC_CR_HSEON) });
    spin_until(|| rcc.cr().read().bits() & RCC_CR_HSERDY != 0);
    rcc.pllcfgr().write(|w| unsafe {
        w.bits(
            PLL_M
                | (PLL_N << 6)
                | (PLL_P_BITS << 16)
                | PLLCFGR_SRC_HSE
                | (PLL_Q << 24)
                | (PLL_R << 28),
        )
    });
    rcc.cr()
        .modify(|r, w| unsafe { w.bits(r.bits() | RCC_CR_PLLON) });
    spin_until(|| rcc.cr().read().bits() & RCC_CR_PLLRDY != 0);
    // Over-drive for 180 MHz (RM0390 §5.1.4: after PLL on, before the switch).
    pwr.cr()
        .modify(|r, w| unsafe { w.bits(r.bits() | PWR_CR_ODEN) });
    spin_until(|| pwr.csr().read().bits() & PWR_CSR_ODRDY != 0);
    pwr.cr()
        .modify(|r, w| unsafe { w.bits(r.bits() | PWR_CR_ODSWEN) });
    spin_until(|| pwr.csr().read().bits() & PWR_CSR_ODSWRDY != 0);
    flash.acr().write(|w| unsafe { w.bits(FLASH_ACR) });
    spin_until(|| flash.acr().read().bits() & 0xF == FLASH_ACR & 0xF);
    rcc.cfgr()
        .write(|w| unsafe { w.bits(CFGR_PPRE1_DIV4 | CFGR_PPRE2_DIV2 | CFGR_SW_PLL) });
    spin_until(|| rcc.cfgr().read().bits() & CFGR_SWS_MASK == CFGR_SWS_PLL);
}
