//! The displacement sensor on ADC1 channel 0 (PA0, Arduino A0), one conversion per control tick
//! (RM0390 §13); with a current monitor (the parameter file's `current_monitor`, measurement
//! image), the amplifier's current-monitor output on ADC2 channel 1 (PA1, Arduino A1), converted
//! at the same instant: dual regular simultaneous mode (ADC_CCR MULTI = 00110), ADC1 the master
//! whose software start triggers both, the same 15-cycle sample time on both channels (required
//! in simultaneous mode), each result in its own ADC's data register.
//!
//! The control interrupt starts a conversion (software start) and waits for it — bounded by
//! [`MAX_EOC_POLLS`] — before the control step, so each command is computed from a sample taken
//! at the start of its own period. ADC clock PCLK2/4 = 22.5 MHz; 12 bits with a 15-cycle sample
//! time: 27 ADC cycles = 1.2 µs (216 core cycles of waiting). A conversion that does not finish
//! in time is a [`SensorFault::Missing`] (the control loop latches it and ramps to 0 A).

use crate::sensor::SensorFault;
use stm32f4::stm32f446 as pac;

const AHB1ENR_GPIOAEN: u32 = 1 << 0;
const APB2ENR_ADC1EN: u32 = 1 << 8;
const APB2ENR_ADC2EN: u32 = 1 << 9;
/// ADC_CCR MULTI = 00110: dual mode, regular simultaneous only.
const CCR_MULTI_DUAL_REGULAR_SIMULTANEOUS: u32 = 0b00110;
/// ADC_CCR ADCPRE = 01: PCLK2 / 4.
const CCR_ADCPRE_DIV4: u32 = 0b01 << 16;
/// CR2: ADON (bit 0), SWSTART (bit 30).
const CR2_ADON: u32 = 1 << 0;
const CR2_SWSTART: u32 = 1 << 30;
/// SR: EOC (bit 1), OVR (bit 5).
const SR_EOC: u32 = 1 << 1;
/// SMPR2 SMP0 = 001: 15 cycles.
const SMPR2_SMP0_15: u32 = 0b001;
/// SMPR2 SMP1 = 001: 15 cycles.
const SMPR2_SMP1_15: u32 = 0b001 << 3;
/// SQR3 SQ1 = 1: the regular sequence's first (only) conversion is channel 1.
const SQR3_SQ1_CHANNEL1: u32 = 1;
/// Status reads before a conversion counts as missing (≥ 4 cycles each: ≥ 8 µs, 7× the
/// conversion time).
pub const MAX_EOC_POLLS: u32 = 400;

/// ADC1 converting channel 0, and ADC2 channel 1 with it when the board has a current monitor.
pub struct DisplacementAdc {
    regs: &'static pac::adc1::RegisterBlock,
    monitor: Option<&'static pac::adc1::RegisterBlock>,
}

// SAFETY: the handle is ADC1's only user; moving it to the control interrupt moves that
// ownership.
unsafe impl Send for DisplacementAdc {}

impl DisplacementAdc {
    /// Clocks GPIOA and ADC1, makes PA0 analog, sets the clock, sample time and a one-channel
    /// regular sequence (channel 0), and switches the ADC on.
    pub fn new(rcc: &pac::RCC) -> Self {
        // SAFETY: fixed peripheral addresses; this is their only user (PA0 is otherwise unused).
        let regs: &'static pac::adc1::RegisterBlock = unsafe { &*pac::ADC1::ptr() };
        let common: &'static pac::adc_common::RegisterBlock = unsafe { &*pac::ADC_COMMON::ptr() };
        let gpioa: &'static pac::gpioa::RegisterBlock = unsafe { &*pac::GPIOA::ptr() };
        // SAFETY (all `bits` writes): field values from RM0390, documented above.
        rcc.ahb1enr()
            .modify(|r, w| unsafe { w.bits(r.bits() | AHB1ENR_GPIOAEN) });
        rcc.apb2enr()
            .modify(|r, w| unsafe { w.bits(r.bits() | APB2ENR_ADC1EN) });
        gpioa
            .moder()
            .modify(|r, w| unsafe { w.bits(r.bits() | 0b11) });
        common.ccr().write(|w| unsafe { w.bits(CCR_ADCPRE_DIV4) });
        regs.cr1().write(|w| unsafe { w.bits(0) });
        regs.smpr2().write(|w| unsafe { w.bits(SMPR2_SMP0_15) });
        regs.sqr1().write(|w| unsafe { w.bits(0) });
        regs.sqr3().write(|w| unsafe { w.bits(0) });
        regs.cr2().write(|w| unsafe { w.bits(CR2_ADON) });
        DisplacementAdc {
            regs,
            monitor: None,
        }
    }

    /// As [`DisplacementAdc::new`], and ADC2 converting channel 1 (PA1) simultaneously with
    /// ADC1's channel 0 on every start (module docs).
    pub fn with_current_monitor(rcc: &pac::RCC) -> Self {
        let adc = Self::new(rcc);
        // SAFETY: fixed peripheral addresses; this is their only user (PA1 is otherwise unused).
        let monitor: &'static pac::adc1::RegisterBlock = unsafe { &*pac::ADC2::ptr() };
        let common: &'static pac::adc_common::RegisterBlock = unsafe { &*pac::ADC_COMMON::ptr() };
        let gpioa: &'static pac::gpioa::RegisterBlock = unsafe { &*pac::GPIOA::ptr() };
        // SAFETY (all `bits` writes): field values from RM0390, documented above.
        rcc.apb2enr()
            .modify(|r, w| unsafe { w.bits(r.bits() | APB2ENR_ADC2EN) });
        gpioa
            .moder()
            .modify(|r, w| unsafe { w.bits(r.bits() | (0b11 << 2)) });
        monitor.cr1().write(|w| unsafe { w.bits(0) });
        monitor.smpr2().write(|w| unsafe { w.bits(SMPR2_SMP1_15) });
        monitor.sqr1().write(|w| unsafe { w.bits(0) });
        monitor
            .sqr3()
            .write(|w| unsafe { w.bits(SQR3_SQ1_CHANNEL1) });
        monitor.cr2().write(|w| unsafe { w.bits(CR2_ADON) });
        common
            .ccr()
            .write(|w| unsafe { w.bits(CCR_ADCPRE_DIV4 | CCR_MULTI_DUAL_REGULAR_SIMULTANEOUS) });
        DisplacementAdc {
            monitor: Some(monitor),
            ..adc
        }
    }

    /// Converts once and returns the count (bounded wait), or [`SensorFault::Missing`].
    #[inline(always)]
    pub fn sample(&mut self) -> Result<u32, SensorFault> {
        // SAFETY: SWSTART with ADON kept set starts one regular conversion.
        self.regs
            .cr2()
            .write(|w| unsafe { w.bits(CR2_ADON | CR2_SWSTART) });
        for _ in 0..MAX_EOC_POLLS {
            if self.regs.sr().read().bits() & SR_EOC != 0 {
                // Reading DR clears EOC.
                return Ok(self.regs.dr().read().bits() & 0xFFFF);
            }
        }
        Err(SensorFault::Missing)
    }

    /// Converts once — both channels at the same instant with a current monitor — and returns
    /// the sensor's count (or [`SensorFault::Missing`]) and the monitor's (`None`: no monitor, or
    /// its conversion did not finish within [`MAX_EOC_POLLS`]). Both waits are bounded.
    #[inline(always)]
    pub fn sample_with_monitor(&mut self) -> (Result<u32, SensorFault>, Option<u32>) {
        let sensor = self.sample();
        let Some(monitor) = self.monitor else {
            return (sensor, None);
        };
        for _ in 0..MAX_EOC_POLLS {
            if monitor.sr().read().bits() & SR_EOC != 0 {
                return (sensor, Some(monitor.dr().read().bits() & 0xFFFF));
            }
        }
        (sensor, None)
    }
}
