//! NUCLEO-F446RE (STM32F446RE, Cortex-M4F with FPU, 512 KiB flash, 128 KiB SRAM).
//!
//! Clocks: the 8 MHz HSE input is the ST-LINK's MCO (bypass mode, as the board ships), PLL to
//! SYSCLK = 180 MHz, APB1 = 45 MHz (TIM2 counts at 90 MHz), APB2 = 90 MHz (SPI1).
//!
//! Wiring of the DAC (Arduino header, SPI1): SCK = PA5 (D13, shared with the green LED LD2),
//! MOSI = PA7 (D11), chip select = PB6 (D10, active low), MISO unused. The DAC (16-bit,
//! DAC8550, two's complement, 24-bit frame, SPI mode 1, see `magctl::output::SpiDac`) drives the coil's
//! transconductance amplifier (full scale `control.current_limit_a`).
//!
//! * [`adc`]: the displacement sensor on ADC1 channel 0 (PA0, A0), one conversion per tick.
//! * [`clocks`]: HSE bypass → PLL → 180 MHz, register level.
//! * [`spi`]: SPI1 as an embedded-hal `SpiBus` and PB6 as the chip-select `OutputPin`.
//! * [`timer`]: TIM2 at the control rate, with overrun detection.
//! * [`fatal`]: panic, HardFault and unexpected-interrupt handlers: they mask interrupts (the
//!   control interrupt stops), drive the DAC to mid-scale (0 A), log over RTT and halt at a
//!   breakpoint (probe-rs reports it and exits non-zero).
//! * [`watchdog`]: the independent watchdog, fed by the control interrupt (a stalled loop resets
//!   the chip into the 0 A start-up state).
//! * [`rtt`]: the defmt global logger over RTT (SEGGER RTT up-channel 0), panic-free; in the
//!   emulator build the logger is `board::semihosting::logger` instead.
//! * [`emulator`] (feature `emulator-netduinoplus2`): the plant link on USART2 that stands in for
//!   the ADC under QEMU's `netduinoplus2`.
//!
//! Everything is programmed at register level through the `stm32f4` PAC (not `stm32f4xx-hal`,
//! whose clock set-up has panic paths): the whole image links with `--features panic-never`.

pub mod adc;
pub mod clocks;
#[cfg(feature = "emulator-netduinoplus2")]
pub mod emulator;
pub mod fatal;
#[cfg(not(feature = "emulator-netduinoplus2"))]
pub mod rtt;
pub mod spi;
pub mod timer;
pub mod watchdog;

/// Log bytes the image's defmt logger has dropped (ring full, nested or overlong frames).
pub fn log_bytes_dropped() -> u32 {
    use core::sync::atomic::Ordering;
    #[cfg(not(feature = "emulator-netduinoplus2"))]
    let dropped = rtt::DROPPED_BYTES.load(Ordering::Relaxed);
    #[cfg(feature = "emulator-netduinoplus2")]
    let dropped = crate::board::semihosting::logger::DROPPED_BYTES.load(Ordering::Relaxed);
    dropped
}
