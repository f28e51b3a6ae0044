//! Fatal paths of the QEMU firmware: they end the QEMU process with a non-zero status through
//! semihosting, never hang.
//!
//! * panic → exit status [`EXIT_PANIC`] (101);
//! * HardFault → exit status [`EXIT_HARDFAULT`] (102);
//! * any other unexpected exception or interrupt (`DefaultHandler`) → [`EXIT_UNEXPECTED_IRQ`];
//! * a stack overflow into the guard (`board::stack::guard`) → [`EXIT_STACK_OVERFLOW`] (104).
//!
//! With the `panic-never` feature the panic handler instead calls a function that does not exist,
//! so the image links only if the optimizer proved every panic unreachable (the link-time no-panic
//! proof; `cargo xtask qemu` builds it, and builds the `panic-never-canary` variant, which must
//! fail to link).

use crate::board::semihosting::exit;

/// Exit status after a panic.
pub const EXIT_PANIC: u32 = 101;
/// Exit status after a HardFault.
pub const EXIT_HARDFAULT: u32 = 102;
/// Exit status after an unexpected exception or interrupt.
pub const EXIT_UNEXPECTED_IRQ: u32 = 103;
/// Exit status after a stack overflow into the guard.
pub const EXIT_STACK_OVERFLOW: u32 = 104;

/// The stack guard's handler (`board::stack`), on the guard's bytes: the DAC has no fault
/// output of its own here, the run ends with [`EXIT_STACK_OVERFLOW`].
#[unsafe(no_mangle)]
extern "C" fn __stack_overflow() -> ! {
    cortex_m::interrupt::disable();
    defmt::error!(
        "stack overflow into the guard: exiting QEMU with status {=u32}",
        EXIT_STACK_OVERFLOW
    );
    exit(EXIT_STACK_OVERFLOW)
}

#[cfg(not(feature = "panic-never"))]
#[panic_handler]
fn panic(_info: &core::panic::PanicInfo) -> ! {
    cortex_m::interrupt::disable();
    defmt::error!("panic: exiting QEMU with status {=u32}", EXIT_PANIC);
    exit(EXIT_PANIC)
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

#[cortex_m_rt::exception]
unsafe fn HardFault(_frame: &cortex_m_rt::ExceptionFrame) -> ! {
    exit(EXIT_HARDFAULT)
}

#[cortex_m_rt::exception]
unsafe fn DefaultHandler(_irqn: i16) {
    exit(EXIT_UNEXPECTED_IRQ)
}
