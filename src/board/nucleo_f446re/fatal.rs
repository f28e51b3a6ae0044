//! Fatal paths of the NUCLEO firmware: panic, HardFault and unexpected interrupts.
//!
//! Each one (1) masks interrupts, so the control interrupt stops (and the watchdog is no longer
//! fed: without a debugger it resets the chip within 15 ms, into the 0 A start-up); (2) drives
//! the DAC to mid-scale, i.e. 0 A into the coil ([`safe_output`], raw register writes that need no driver
//! state and cannot fail); (3) logs the cause over RTT; (4) halts at a breakpoint (`bkpt`): under
//! `probe-rs run` the probe stops, prints the backtrace and exits non-zero; without a probe the
//! breakpoint escalates to a (locked-up) HardFault and the core stays stopped with 0 A commanded.
//!
//! In the emulator build (feature `emulator-netduinoplus2`) step (4) is a semihosting exit with
//! the virtual bench's status instead (`docs/hil.md`: 101 panic, 102 HardFault or an unexpected
//! interrupt), so that a fatal path ends QEMU with that status rather than in a lock-up.
//!
//! With the `panic-never` feature the panic handler instead calls an undefined function, so the
//! image links only if the optimizer proved every panic unreachable (the link-time no-panic
//! proof, the same as for the QEMU board; `cargo xtask test` builds it).

use stm32f4::stm32f446 as pac;

/// Mid-scale frame of the DAC8550: control byte 0 (normal operation), two's-complement code
/// 0x0000 (0 A, also its power-on value).
const ZERO_CURRENT_FRAME: [u8; 3] = [0x00, 0x00, 0x00];
use super::spi::CS_PIN;
/// Bound on the busy-waits of [`safe_output`] (one byte at 11.25 MHz is ~130 core cycles at
/// 180 MHz; this allows far more, then gives up instead of hanging). SR bits: TXE 1, BSY 7;
/// CR1 bit 6 SPE.
const SPIN_LIMIT: u32 = 50_000;

fn spin_until(mut done: impl FnMut() -> bool) {
    let mut n = 0;
    while !done() && n < SPIN_LIMIT {
        n += 1;
    }
}

/// Writes the 0 A frame to the DAC through SPI1 and PB6 directly (whatever the drivers' state),
/// if SPI1 is enabled; otherwise the DAC was never written and still holds its power-on value.
pub fn safe_output() {
    // SAFETY: called with interrupts masked on a fatal path; nothing else runs afterwards.
    let spi = unsafe { &*pac::SPI1::ptr() };
    let gpiob = unsafe { &*(pac::GPIOB::ptr() as *const pac::gpioa::RegisterBlock) };
    if spi.cr1().read().bits() & (1 << 6) == 0 {
        return;
    }
    // Finish a frame the interrupted code may have been sending, then frame ours with CS.
    spin_until(|| spi.sr().read().bits() & (1 << 7) == 0);
    gpiob
        .bsrr()
        .write(|w| unsafe { w.bits(1 << (CS_PIN + 16)) });
    for &byte in &ZERO_CURRENT_FRAME {
        spin_until(|| spi.sr().read().bits() & (1 << 1) != 0);
        spi.dr().write(|w| unsafe { w.bits(byte as u16) });
    }
    spin_until(|| spi.sr().read().bits() & (1 << 1) != 0);
    spin_until(|| spi.sr().read().bits() & (1 << 7) == 0);
    gpiob.bsrr().write(|w| unsafe { w.bits(1 << CS_PIN) });
}

/// Status of a panic under the emulator (`docs/hil.md`).
pub const EXIT_PANIC: u32 = 101;
/// Status of a HardFault or an unexpected interrupt under the emulator.
pub const EXIT_FAULT: u32 = 102;
/// Status of a stack overflow into the guard under the emulator.
pub const EXIT_STACK_OVERFLOW: u32 = 104;

/// Halts for the probe (`status` is the emulator build's exit status).
#[cfg(not(feature = "emulator-netduinoplus2"))]
pub fn stop(_status: u32) -> ! {
    loop {
        cortex_m::asm::bkpt();
    }
}

/// Ends the emulator's run with `status`.
#[cfg(feature = "emulator-netduinoplus2")]
pub fn stop(status: u32) -> ! {
    crate::board::semihosting::exit(status)
}

#[cfg(not(feature = "panic-never"))]
#[panic_handler]
fn panic(_info: &core::panic::PanicInfo) -> ! {
    cortex_m::interrupt::disable();
    safe_output();
    defmt::error!("panic: control stopped, DAC at 0 A");
    stop(EXIT_PANIC)
}

#[cfg(feature = "panic-never")]
#[panic_handler]
fn panic(_info: &core::panic::PanicInfo) -> ! {
    unsafe extern "C" {
        /// Deliberately undefined: referencing it fails the link.
        fn __firmware_contains_a_reachable_panic_path() -> !;
    }
    unsafe { __firmware_contains_a_reachable_panic_path() }
}

/// The stack guard's handler (`board::stack`), on the guard's bytes: 0 A, log, halt.
#[unsafe(no_mangle)]
extern "C" fn __stack_overflow() -> ! {
    cortex_m::interrupt::disable();
    safe_output();
    defmt::error!("stack overflow into the guard: control stopped, DAC at 0 A");
    stop(EXIT_STACK_OVERFLOW)
}

#[cortex_m_rt::exception]
unsafe fn HardFault(frame: &cortex_m_rt::ExceptionFrame) -> ! {
    cortex_m::interrupt::disable();
    safe_output();
    defmt::error!(
        "HardFault at pc {=u32:#x}: control stopped, DAC at 0 A",
        frame.pc()
    );
    stop(EXIT_FAULT)
}

#[cortex_m_rt::exception]
unsafe fn DefaultHandler(irqn: i16) {
    cortex_m::interrupt::disable();
    safe_output();
    defmt::error!(
        "unexpected interrupt {=i16}: control stopped, DAC at 0 A",
        irqn
    );
    stop(EXIT_FAULT)
}
