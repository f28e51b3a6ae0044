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
//!
//! **The guard.** [`guard`] makes the bottom [`GUARD_BYTES`] of the stack region (aligned up to
//! their size) an MPU region with no access, the rest of memory keeping the default map: a stack
//! that grows into it faults on its first word there, before it can reach the statics, instead
//! of silently overwriting them. The fault is a MemManage exception, at the highest configurable
//! priority (its reset value, 0), whose handler is a few
//! instructions of assembly that switch the MPU off before anything is pushed (its own stacking
//! into the guard was refused, so the stack pointer already points into the guard) and then
//! call the board's `__stack_overflow` handler, which runs on the guard's [`GUARD_BYTES`]: it
//! commands 0 A and ends in the board's fault state (under QEMU: exit status 104; on the
//! NUCLEO: halted at 0 A, `docs/safety.md`). An overflow inside the control interrupt, which
//! also runs at priority 0, cannot preempt it and escalates to HardFault instead, whose handler
//! commands 0 A too (`cargo xtask qemu` tests the thread-mode path: `stack-overflow-canary`).
//! The paint and the measure start above the guard.

/// The pattern of an unused stack word.
pub const PAINT: u32 = 0xC0DE_57AC;
/// Bytes below the stack pointer [`paint`] leaves alone (its own frame and any red zone).
pub const PAINT_MARGIN_BYTES: usize = 256;

extern "C" {
    static mut _stack_end: u32;
    static mut _stack_start: u32;
}

/// Bytes at the bottom of the stack region the MPU guards (a power of two ≥ 32, aligned to its
/// size; also the fault handler's stack).
pub const GUARD_BYTES: usize = 1024;

/// The guard's base: the end of the statics rounded up to [`GUARD_BYTES`].
fn guard_base() -> usize {
    let bottom = core::ptr::addr_of!(_stack_end) as usize;
    (bottom + GUARD_BYTES - 1) & !(GUARD_BYTES - 1)
}

/// The measured region: from above the guard to the top of RAM.
fn bounds() -> (usize, usize) {
    // (Linker symbols: only their addresses are taken, which needs no `unsafe`.)
    (
        guard_base() + GUARD_BYTES,
        core::ptr::addr_of!(_stack_start) as usize,
    )
}

/// MPU_RASR: execute-never, no access (AP = 0), enabled, SIZE = log2(bytes) − 1.
const RASR_GUARD: u32 = (1 << 28) | ((GUARD_BYTES.trailing_zeros() - 1) << 1) | 1;
/// MPU_CTRL: the default memory map for privileged code outside the regions, MPU on.
const CTRL_PRIVDEFENA_ENABLE: u32 = (1 << 2) | 1;
/// SCB_SHCSR: MemManage exception enabled.
const SHCSR_MEMFAULTENA: u32 = 1 << 16;

/// Installs the guard (module docs). Call once, early in `main`, after [`paint`].
pub fn guard() {
    // SAFETY: the MPU and SCB are configured here only, before any interrupt is unmasked; region
    // 0 covers the guard alone (aligned to its size), the default map stays in force elsewhere.
    unsafe {
        let mpu = &*cortex_m::peripheral::MPU::PTR;
        mpu.rnr.write(0);
        mpu.rbar.write(guard_base() as u32);
        mpu.rasr.write(RASR_GUARD);
        // MemManage keeps its reset priority, 0: the highest configurable one.
        (*cortex_m::peripheral::SCB::PTR)
            .shcsr
            .modify(|v| v | SHCSR_MEMFAULTENA);
        mpu.ctrl.write(CTRL_PRIVDEFENA_ENABLE);
    }
    cortex_m::asm::dsb();
    cortex_m::asm::isb();
}

// The MemManage handler: MPU off (MPU_CTRL = 0 at 0xE000_ED94) before any push, then the board's
// handler. Nothing here touches the stack.
core::arch::global_asm!(
    ".section .text.MemoryManagement,\"ax\",%progbits",
    ".global MemoryManagement",
    ".type MemoryManagement,%function",
    ".thumb_func",
    "MemoryManagement:",
    "ldr r0, =0xE000ED94",
    "movs r1, #0",
    "str r1, [r0]",
    "dsb",
    "isb",
    "b __stack_overflow",
    ".ltorg",
);

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
