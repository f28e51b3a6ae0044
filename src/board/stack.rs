//! The stack's high-water mark, measured: the free RAM between the statics and the stack pointer
//! is painted with [`PAINT`] at start-up, and the deepest word no longer holding it is how far
//! the stack has grown since.
//!
//! cortex-m-rt places the stack at the top of RAM (`_stack_start`) growing down toward the end of
//! the statics (`_stack_end`); nothing else lives between them (no heap). [`paint`] fills that
//! region up to [`PAINT_MARGIN_BYTES`] below the current stack pointer (the frames of `main`'s
//! callers and of `paint` itself are live); [`high_water_bytes`] scans up from `_stack_end` for
//! the first word that is not the pattern. A word the program happened to write with the
//! pattern's value would be missed only at the very bottom of what it used, so the figure is
//! exact to a word unless the program stores `0xC0DE_57AC` at its deepest stack slot.
//!
//! Cost: `paint` one store per word (tens of KiB: well under a millisecond), `high_water_bytes`
//! one load per unused word; both in thread mode, never in an interrupt.

/// The pattern of an unused stack word.
pub const PAINT: u32 = 0xC0DE_57AC;
/// Bytes below the stack pointer [`paint`] leaves alone (its own frame and any red zone).
pub const PAINT_MARGIN_BYTES: usize = 256;

extern "C" {
    static mut _stack_end: u32;
    static mut _stack_start: u32;
}

fn bounds() -> (usize, usize) {
    // (Linker symbols: only their addresses are taken, which needs no `unsafe`.)
    (
        core::ptr::addr_of!(_stack_end) as usize,
        core::ptr::addr_of!(_stack_start) as usize,
    )
}

/// The stack region's size, bytes: from the end of the statics to the top of RAM.
pub fn region_bytes() -> usize {
    let (bottom, top) = bounds();
    top - bottom
}

/// Paints the unused stack (module docs). Call once, first thing in `main`.
#[inline(never)]
pub fn paint() {
    let (bottom, _) = bounds();
    let sp = cortex_m::register::msp::read() as usize;
    let end = sp.saturating_sub(PAINT_MARGIN_BYTES) & !3;
    let mut at = bottom;
    while at < end {
        // SAFETY: `[bottom, end)` is RAM below the live stack that nothing else uses (module
        // docs); word-aligned (cortex-m-rt aligns `_stack_end` to 4).
        unsafe { core::ptr::write_volatile(at as *mut u32, PAINT) };
        at += 4;
    }
}

/// The deepest the stack has been since [`paint`], bytes below the top of RAM.
pub fn high_water_bytes() -> usize {
    let (bottom, top) = bounds();
    let mut at = bottom;
    // SAFETY: reads of RAM words in the stack region (module docs).
    while at < top && unsafe { core::ptr::read_volatile(at as *const u32) } == PAINT {
        at += 4;
    }
    top - at
}
