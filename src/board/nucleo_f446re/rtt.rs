//! defmt global logger over SEGGER RTT, written without any panic path (so the `panic-never`
//! link-time proof holds for the whole NUCLEO image; the `defmt-rtt` crate panics on re-entry).
//!
//! RTT: a control block `_SEGGER_RTT` in RAM (id string, one up channel) that the debug probe
//! finds through the ELF symbol and reads over SWD while the core runs. The up channel's ring
//! buffer is written here (`write` index) and drained by the probe (`read` index); probe-rs decodes
//! the bytes with the ELF's defmt table (`probe-rs run`, docs/firmware.md).
//!
//! Policy: **never block**. A frame that does not fit in the free space is truncated and the
//! dropped bytes counted in [`DROPPED_BYTES`] (defmt-rtt's default non-blocking mode behaves the
//! same until a probe attaches). A frame is encoded with interrupts disabled (the control
//! interrupt never logs, so this only delays it by the length of one frame in thread mode). A
//! nested log from a fault handler while a frame is open is dropped, never interleaved.

use core::cell::UnsafeCell;
use core::sync::atomic::{AtomicU32, AtomicUsize, Ordering};

/// Size of the up-channel ring buffer, bytes: 1 KiB for the status lines; 16 KiB in the
/// measurement image (feature `measurement-mode`: 90 kB/s of record at 10 kHz, so ~180 ms of
/// slack for the probe's polling).
#[cfg(not(feature = "measurement-mode"))]
pub const BUFFER_BYTES: usize = 1024;
/// See above.
#[cfg(feature = "measurement-mode")]
pub const BUFFER_BYTES: usize = 16 * 1024;

/// Bytes dropped because the ring was full or a log was nested.
pub static DROPPED_BYTES: AtomicU32 = AtomicU32::new(0);

#[repr(C)]
struct UpChannel {
    name: *const u8,
    buffer: *mut u8,
    size: u32,
    write: AtomicU32,
    read: AtomicU32,
    flags: AtomicU32,
}

#[repr(C)]
struct ControlBlock {
    id: [u8; 16],
    max_up_channels: u32,
    max_down_channels: u32,
    up: UpChannel,
}

// SAFETY: the raw pointers are fixed addresses of statics; the indices are atomics.
unsafe impl Sync for ControlBlock {}

struct Buffer(UnsafeCell<[u8; BUFFER_BYTES]>);
// SAFETY: written only by the logger while it holds the frame (interrupts disabled), read by the
// probe over the debug port.
unsafe impl Sync for Buffer {}

#[unsafe(link_section = ".uninit.magctl-rtt.BUFFER")]
static BUFFER: Buffer = Buffer(UnsafeCell::new([0; BUFFER_BYTES]));

static NAME: [u8; 6] = *b"defmt\0";

/// RTT mode "no block, trim": the probe leaves it so; this logger never waits anyway.
const MODE_NO_BLOCK_TRIM: u32 = 1;

#[unsafe(no_mangle)]
static _SEGGER_RTT: ControlBlock = ControlBlock {
    id: *b"SEGGER RTT\0\0\0\0\0\0",
    max_up_channels: 1,
    max_down_channels: 0,
    up: UpChannel {
        name: NAME.as_ptr(),
        buffer: BUFFER.0.get() as *mut u8,
        size: BUFFER_BYTES as u32,
        write: AtomicU32::new(0),
        read: AtomicU32::new(0),
        flags: AtomicU32::new(MODE_NO_BLOCK_TRIM),
    },
};

struct State {
    encoder: defmt::Encoder,
    restore_interrupts: bool,
}

struct Shared(UnsafeCell<State>);
// SAFETY: touched only by the outermost acquire/write/release, with interrupts disabled.
unsafe impl Sync for Shared {}

static STATE: Shared = Shared(UnsafeCell::new(State {
    encoder: defmt::Encoder::new(),
    restore_interrupts: false,
}));
/// Nesting depth of `acquire` (1 = the frame being written; > 1 = a nested, dropped log).
static DEPTH: AtomicUsize = AtomicUsize::new(0);

/// Free bytes in the ring now (the probe may free more at any time): thread mode logs a record
/// batch only when it fits, so that no frame is ever truncated.
pub fn free_bytes() -> usize {
    let ch = &_SEGGER_RTT.up;
    let read = ch.read.load(Ordering::Acquire) as usize % BUFFER_BYTES;
    let write = ch.write.load(Ordering::Relaxed) as usize % BUFFER_BYTES;
    (read + BUFFER_BYTES - write - 1) % BUFFER_BYTES
}

/// Appends bytes to the ring, dropping what does not fit.
fn push(bytes: &[u8]) {
    let ch = &_SEGGER_RTT.up;
    let read = ch.read.load(Ordering::Acquire) as usize % BUFFER_BYTES;
    let mut write = ch.write.load(Ordering::Relaxed) as usize % BUFFER_BYTES;
    // One slot stays empty to tell "full" from "empty".
    let mut free = (read + BUFFER_BYTES - write - 1) % BUFFER_BYTES;
    let buf = unsafe { &mut *BUFFER.0.get() };
    for &b in bytes {
        if free == 0 {
            DROPPED_BYTES.fetch_add(1, Ordering::Relaxed);
            continue;
        }
        if let Some(slot) = buf.get_mut(write) {
            *slot = b;
        }
        write = (write + 1) % BUFFER_BYTES;
        free -= 1;
    }
    ch.write.store(write as u32, Ordering::Release);
}

#[defmt::global_logger]
struct RttLogger;

unsafe impl defmt::Logger for RttLogger {
    fn acquire() {
        let interrupts_were_enabled = cortex_m::register::primask::read().is_active();
        cortex_m::interrupt::disable();
        if DEPTH.fetch_add(1, Ordering::Acquire) != 0 {
            // Nested (a fault handler logging inside an open frame): dropped in `write`.
            return;
        }
        let st = unsafe { &mut *STATE.0.get() };
        st.restore_interrupts = interrupts_were_enabled;
        st.encoder.start_frame(push);
    }

    unsafe fn flush() {}

    unsafe fn release() {
        if DEPTH.fetch_sub(1, Ordering::Release) != 1 {
            return;
        }
        let st = unsafe { &mut *STATE.0.get() };
        st.encoder.end_frame(push);
        if st.restore_interrupts {
            unsafe { cortex_m::interrupt::enable() };
        }
    }

    unsafe fn write(bytes: &[u8]) {
        if DEPTH.load(Ordering::Relaxed) != 1 {
            DROPPED_BYTES.fetch_add(bytes.len() as u32, Ordering::Relaxed);
            return;
        }
        let st = unsafe { &mut *STATE.0.get() };
        st.encoder.write(bytes, push);
    }
}
