//! Clock tree of the STM32F446RE (RM0390 §6): HSE bypass 8 MHz → PLL → SYSCLK 180 MHz,
//! AHB 180 MHz, APB1 45 MHz (TIM2 at 90 MHz), APB2 90 MHz (SPI1), with over-drive and 5 flash
//! wait states as 180 MHz requires (RM0390 §3.4.1, §5.1.4).
//!
//! PLL: `f_VCO = HSE / M · N = 8 MHz / 4 · 180 = 360 MHz` (VCO input 2 MHz, output within
//! 100..432 MHz), `SYSCLK = f_VCO / P = 360 / 2`; Q = 8 and R = 2 are unused outputs kept in range.
//!
//! **No wait without a bound.** Every ready flag is polled at most [`READY_POLLS`] times (at the
//! 16 MHz reset clock, a poll is under 1 µs: ≤ 0.1 s, far inside the start-up watchdog's 2.8 s).
//! When the 8 MHz bypass clock does not come up (no ST-LINK MCO, a broken jumper) the PLL runs
//! from the internal 16 MHz HSI with `M = 8` — the same 2 MHz VCO input and the same clocks, at
//! the HSI's ±1 % accuracy instead of the crystal's — and [`init`] says so
//! ([`ClockSource::Hsi`]); the caller warns. A PLL that does not lock, or an over-drive,
//! flash-latency or clock switch that does not complete, is an error: the caller halts (the DAC
//! has been written 0 A before and the watchdog runs). Register-level (PAC pointers, raw bit
//! values named below): nothing here can panic.

use stm32f4::stm32f446 as pac;

const RCC_CR_HSEON: u32 = 1 << 16;
const RCC_CR_HSERDY: u32 = 1 << 17;
const RCC_CR_HSEBYP: u32 = 1 << 18;
const RCC_CR_PLLON: u32 = 1 << 24;
const RCC_CR_PLLRDY: u32 = 1 << 25;
const PLL_M: u32 = 4;
/// M for the 16 MHz HSI: the same 2 MHz VCO input.
const PLL_M_HSI: u32 = 8;
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

/// Polls of a ready flag before giving up (module docs).
pub const READY_POLLS: u32 = 100_000;

/// What the PLL runs from after [`init`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ClockSource {
    /// The 8 MHz bypass clock (the ST-LINK's MCO).
    Hse,
    /// The internal 16 MHz oscillator: the HSE did not come up within [`READY_POLLS`] polls.
    Hsi,
}

/// A start-up step of the clock tree that did not complete within [`READY_POLLS`] polls.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ClockError {
    /// The PLL did not lock.
    PllLock,
    /// The over-drive did not become ready.
    OverDrive,
    /// The switch to over-drive did not complete.
    OverDriveSwitch,
    /// The flash did not take its 5 wait states.
    FlashLatency,
    /// The system clock did not switch to the PLL.
    SystemSwitch,
}

impl ClockError {
    /// A description for the log.
    pub fn describe(self) -> &'static str {
        match self {
            ClockError::PllLock => "the PLL did not lock",
            ClockError::OverDrive => "the over-drive did not become ready",
            ClockError::OverDriveSwitch => "the switch to over-drive did not complete",
            ClockError::FlashLatency => "the flash did not take its wait states",
            ClockError::SystemSwitch => "the system clock did not switch to the PLL",
        }
    }
}

/// Polls `done` at most [`READY_POLLS`] times, calling `feed` (the watchdog) at each; whether it
/// became true.
/// How [`init`] treats the flags after the HSE's (PLL lock, over-drive, flash latency read-back,
/// clock switch).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LockFlags {
    /// Polled with the bound, as on the chip (the board image always).
    Polled,
    /// Taken as set at once: QEMU's `netduinoplus2` has no RCC, PWR or FLASH model (they read
    /// 0). The emulator build's default; it still runs the HSE's bounded wait, which times out
    /// there, and the HSI fallback after it.
    AssumedSet,
}

fn spin_until_locked(flags: LockFlags, feed: &mut impl FnMut(), done: impl Fn() -> bool) -> bool {
    flags == LockFlags::AssumedSet || spin_until(feed, done)
}

fn spin_until(feed: &mut impl FnMut(), done: impl Fn() -> bool) -> bool {
    for _ in 0..READY_POLLS {
        if done() {
            return true;
        }
        feed();
    }
    done()
}

/// Switches the system to the 180 MHz PLL clock, from the HSE or, when it does not come up, the
/// HSI (module docs); `flags` is [`LockFlags::Polled`] on the chip; `feed` is called while
/// waiting (the start-up watchdog). Call once, after the DAC's 0 A and the watchdog's start.
pub fn init(
    rcc: &pac::RCC,
    pwr: &pac::PWR,
    flash: &pac::FLASH,
    flags: LockFlags,
    mut feed: impl FnMut(),
) -> Result<ClockSource, ClockError> {
    let feed = &mut feed;
    // SAFETY (all `bits` writes): values from RM0390 for these registers, documented above.
    rcc.apb1enr()
        .modify(|r, w| unsafe { w.bits(r.bits() | APB1ENR_PWREN) });
    pwr.cr()
        .modify(|r, w| unsafe { w.bits(r.bits() | PWR_CR_VOS_SCALE1) });
    rcc.cr()
        .modify(|r, w| unsafe { w.bits(r.bits() | RCC_CR_HSEBYP | RCC_CR_HSEON) });
    let source = if spin_until(feed, || rcc.cr().read().bits() & RCC_CR_HSERDY != 0) {
        ClockSource::Hse
    } else {
        // The HSI has run since reset (HSION, HSIRDY are reset values).
        rcc.cr()
            .modify(|r, w| unsafe { w.bits(r.bits() & !(RCC_CR_HSEON | RCC_CR_HSEBYP)) });
        ClockSource::Hsi
    };
    let (m, src) = match source {
        ClockSource::Hse => (PLL_M, PLLCFGR_SRC_HSE),
        ClockSource::Hsi => (PLL_M_HSI, 0),
    };
    rcc.pllcfgr().write(|w| unsafe {
        w.bits(m | (PLL_N << 6) | (PLL_P_BITS << 16) | src | (PLL_Q << 24) | (PLL_R << 28))
    });
    rcc.cr()
        .modify(|r, w| unsafe { w.bits(r.bits() | RCC_CR_PLLON) });
    if !spin_until_locked(flags, feed, || rcc.cr().read().bits() & RCC_CR_PLLRDY != 0) {
        return Err(ClockError::PllLock);
    }
    // Over-drive for 180 MHz (RM0390 §5.1.4: after PLL on, before the switch).
    pwr.cr()
        .modify(|r, w| unsafe { w.bits(r.bits() | PWR_CR_ODEN) });
    if !spin_until_locked(flags, feed, || pwr.csr().read().bits() & PWR_CSR_ODRDY != 0) {
        return Err(ClockError::OverDrive);
    }
    pwr.cr()
        .modify(|r, w| unsafe { w.bits(r.bits() | PWR_CR_ODSWEN) });
    if !spin_until_locked(flags, feed, || {
        pwr.csr().read().bits() & PWR_CSR_ODSWRDY != 0
    }) {
        return Err(ClockError::OverDriveSwitch);
    }
    flash.acr().write(|w| unsafe { w.bits(FLASH_ACR) });
    if !spin_until_locked(flags, feed, || {
        flash.acr().read().bits() & 0xF == FLASH_ACR & 0xF
    }) {
        return Err(ClockError::FlashLatency);
    }
    rcc.cfgr()
        .write(|w| unsafe { w.bits(CFGR_PPRE1_DIV4 | CFGR_PPRE2_DIV2 | CFGR_SW_PLL) });
    if !spin_until_locked(flags, feed, || {
        rcc.cfgr().read().bits() & CFGR_SWS_MASK == CFGR_SWS_PLL
    }) {
        return Err(ClockError::SystemSwitch);
    }
    Ok(source)
}
