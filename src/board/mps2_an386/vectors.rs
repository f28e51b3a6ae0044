//! The device part of the vector table for `mps2-an386` (32 external interrupts). Only TIMER0
//! (IRQ 8) is used; every other entry goes to cortex-m-rt's `DefaultHandler`. cortex-m-rt places
//! this array right after the 16 core exception vectors (its `device` feature).

/// One vector-table entry.
#[repr(C)]
pub union Vector {
    handler: unsafe extern "C" fn(),
    reserved: usize,
}

unsafe extern "C" {
    /// The control interrupt, defined by the firmware binary (`#[no_mangle] extern "C" fn TIMER0`).
    fn TIMER0();
    /// cortex-m-rt's default handler.
    fn DefaultHandler();
}

const D: Vector = Vector {
    handler: DefaultHandler,
};

/// IRQ 0..31 of the AN386 image.
#[unsafe(link_section = ".vector_table.interrupts")]
#[unsafe(no_mangle)]
pub static __INTERRUPTS: [Vector; 32] = [
    D,
    D,
    D,
    D,
    D,
    D,
    D,
    D,                          // 0-7: UARTs, PORT0/1, watchdog
    Vector { handler: TIMER0 }, // 8: TIMER0
    D,
    D,
    D,
    D,
    D,
    D,
    D, // 9-15
    D,
    D,
    D,
    D,
    D,
    D,
    D,
    D, // 16-23
    D,
    D,
    D,
    D,
    D,
    D,
    D,
    D, // 24-31
];

/// Keeps the reserved-entry form documented (all entries of this image are populated).
pub const RESERVED: Vector = Vector { reserved: 0 };
