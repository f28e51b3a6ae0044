//! The independent watchdog (IWDG, RM0390 §20), fed by the control interrupt.
//!
//! The IWDG runs from the 32 kHz LSI, independent of the main clock, and resets the chip when it
//! is not fed within its timeout. It is fed only at the end of the control interrupt, after the
//! DAC frame: if the control loop stalls (an interrupt that never returns, a HardFault that
//! locks up, a masked timer, a clock failure), the chip resets, and reset puts 0 A on the coil
//! (the start-up sequence in `docs/safety.md`: the DAC is written 0 A before anything else).
//!
//! Timeout: LSI/4 with a reload of [`RELOAD`] counts. The LSI is 17–47 kHz over voltage and
//! temperature (datasheet DS10693, LSI characteristics), so the timeout lies between
//! [`TIMEOUT_MIN_MS`] = 5.4 ms and [`TIMEOUT_MAX_MS`] = 15.1 ms: ≥ 54 control periods at 10 kHz,
//! so jitter and overruns never trip it; after a stall the coil holds its last (limited) current
//! at most ~15 ms before the reset.
//!
//! While the core is halted by a debugger the watchdog is frozen (DBGMCU_APB1_FZ.DBG_IWDG_STOP),
//! so probe-rs can show a fatal path's backtrace; without a debugger a halted core is reset.
//! Once started, the IWDG cannot be stopped except by a reset.

use stm32f4::stm32f446 as pac;

const KEY_UNLOCK: u16 = 0x5555;
const KEY_FEED: u16 = 0xAAAA;
const KEY_START: u16 = 0xCCCC;
/// Prescaler code 0: LSI / 4.
const PR_DIV4: u16 = 0;
/// Prescaler code 3: LSI / 32 (the start-up timeout).
const PR_DIV32: u16 = 3;
/// Reload value of the start-up timeout (the largest).
const BOOT_RELOAD: u16 = 4095;
/// Shortest start-up timeout, ms: 4096 × 32 / 47 kHz = 2.8 s (the start-up's bounded waits take
/// well under this: the HSE wait is bounded by `clocks::HSE_READY_POLLS`).
pub const BOOT_TIMEOUT_MIN_MS: f32 = (BOOT_RELOAD as f32 + 1.0) * 32.0 / 47.0;
/// Longest start-up timeout, ms: 4096 × 32 / 17 kHz = 7.7 s.
pub const BOOT_TIMEOUT_MAX_MS: f32 = (BOOT_RELOAD as f32 + 1.0) * 32.0 / 17.0;
/// Reload value: the counter runs down from here.
pub const RELOAD: u16 = 63;
/// Shortest timeout (fastest LSI, 47 kHz), ms: (63 + 1) × 4 / 47 kHz = 5.4 ms.
pub const TIMEOUT_MIN_MS: f32 = (RELOAD + 1) as f32 * 4.0 / 47.0;
/// Longest timeout (slowest LSI, 17 kHz), ms: (63 + 1) × 4 / 17 kHz = 15.1 ms.
pub const TIMEOUT_MAX_MS: f32 = (RELOAD + 1) as f32 * 4.0 / 17.0;
/// SR bits: prescaler / reload update in progress.
const SR_PVU_RVU: u16 = 0b11;
/// DBGMCU_APB1_FZ bit 12: IWDG stopped while the core is halted.
#[cfg(not(feature = "emulator-netduinoplus2"))]
const DBG_IWDG_STOP: u32 = 1 << 12;
/// RCC_CSR bit 29: the last reset came from the IWDG; bit 24 RMVF clears the reset flags.
const CSR_IWDGRSTF: u32 = 1 << 29;
const CSR_RMVF: u32 = 1 << 24;
/// Status reads before giving up on the register update (a few LSI cycles, ~6 × 125 µs).
const SR_POLL_LIMIT: u32 = 1_000_000;

/// The running watchdog (the handle feeds it).
pub struct Watchdog {
    regs: &'static pac::iwdg::RegisterBlock,
}

/// Whether the last reset was a watchdog reset; clears the reset flags. Call once at start-up.
pub fn take_reset_was_watchdog(rcc: &pac::RCC) -> bool {
    let csr = rcc.csr().read().bits();
    // SAFETY: RMVF only clears the reset flags.
    rcc.csr()
        .modify(|r, w| unsafe { w.bits(r.bits() | CSR_RMVF) });
    csr & CSR_IWDGRSTF != 0
}

// SAFETY: the handle is the only user of its peripheral's registers (see its constructor);
// moving it to the interrupt that uses it (through `HandOff`) moves that ownership.
unsafe impl Send for Watchdog {}

impl Watchdog {
    /// Starts the IWDG with the start-up timeout ([`BOOT_TIMEOUT_MIN_MS`]..[`BOOT_TIMEOUT_MAX_MS`])
    /// and freezes it under a debugger halt: the first thing after the DAC's 0 A, so that every
    /// later start-up step (the clocks' bounded waits, the controller's set-up, the ramp) runs
    /// under it and a stall resets the chip, which writes 0 A again. The flag is false if the
    /// prescaler/reload update did not complete in time (the watchdog then runs with its reset
    /// values, a 512 ms timeout, and is fed the same way; the caller logs it).
    pub fn start_for_boot(dbgmcu: &pac::DBGMCU) -> (Self, bool) {
        // SAFETY: fixed peripheral address; only this handle writes the IWDG.
        let regs: &'static pac::iwdg::RegisterBlock = unsafe { &*pac::IWDG::ptr() };
        // SAFETY (all `bits` writes): key and field values from RM0390 §20.4.
        // DBGMCU is absent from QEMU's `netduinoplus2` (an access there is logged as unassigned).
        #[cfg(not(feature = "emulator-netduinoplus2"))]
        dbgmcu
            .apb1_fz()
            .modify(|r, w| unsafe { w.bits(r.bits() | DBG_IWDG_STOP) });
        #[cfg(feature = "emulator-netduinoplus2")]
        let _ = dbgmcu;
        regs.kr().write(|w| unsafe { w.bits(KEY_START) });
        let dog = Watchdog { regs };
        let configured = dog.configure(PR_DIV32, BOOT_RELOAD);
        (dog, configured)
    }

    /// Shortens the timeout to the control loop's ([`TIMEOUT_MIN_MS`]..[`TIMEOUT_MAX_MS`]): call
    /// last before the control interrupt takes over the feeding. False if the update did not
    /// complete in time (the start-up timeout then stays; the caller logs it).
    pub fn set_run_timeout(&self) -> bool {
        self.configure(PR_DIV4, RELOAD)
    }

    /// Writes the prescaler and reload (unlocked), waits a bounded time for the update, feeds.
    fn configure(&self, prescaler: u16, reload: u16) -> bool {
        // SAFETY (all `bits` writes): key and field values from RM0390 §20.4.
        self.regs.kr().write(|w| unsafe { w.bits(KEY_UNLOCK) });
        self.regs.pr().write(|w| unsafe { w.bits(prescaler) });
        self.regs.rlr().write(|w| unsafe { w.bits(reload) });
        let mut configured = false;
        for _ in 0..SR_POLL_LIMIT {
            if self.regs.sr().read().bits() & SR_PVU_RVU == 0 {
                configured = true;
                break;
            }
        }
        self.feed();
        configured
    }

    /// Reloads the counter (one register write).
    #[inline(always)]
    pub fn feed(&self) {
        self.regs.kr().write(|w| unsafe { w.bits(KEY_FEED) });
    }
}
