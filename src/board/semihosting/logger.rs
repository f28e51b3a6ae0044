//! defmt global logger over semihosting (host stdout), without panics: a frame is encoded into a
//! 256-byte buffer inside a critical section and written with one `SYS_WRITE` at release. A
//! re-entrant log (impossible here: the control interrupt never logs) or an overlong frame drops
//! bytes and counts them instead of panicking. `cargo xtask qemu` decodes the stream with the
//! ELF's defmt table.

use super::{stdout, HostFile};
use core::cell::UnsafeCell;
use core::sync::atomic::{AtomicBool, AtomicU32, Ordering};

struct State {
    encoder: defmt::Encoder,
    buf: [u8; 256],
    len: usize,
    out: Option<HostFile>,
    restore: bool,
}

struct Shared(UnsafeCell<State>);
// SAFETY: accessed only between acquire and release, inside a critical section (PRIMASK set),
// and guarded by TAKEN against re-entry.
unsafe impl Sync for Shared {}

static STATE: Shared = Shared(UnsafeCell::new(State {
    encoder: defmt::Encoder::new(),
    buf: [0; 256],
    len: 0,
    out: None,
    restore: false,
}));
static TAKEN: AtomicBool = AtomicBool::new(false);
/// Log bytes dropped (re-entry or frame overflow).
pub static DROPPED_BYTES: AtomicU32 = AtomicU32::new(0);

fn append(buf: &mut [u8; 256], len: &mut usize, bytes: &[u8]) {
    for &b in bytes {
        match buf.get_mut(*len) {
            Some(slot) => {
                *slot = b;
                *len += 1;
            }
            None => {
                DROPPED_BYTES.fetch_add(1, Ordering::Relaxed);
            }
        }
    }
}

#[defmt::global_logger]
struct SemihostingLogger;

unsafe impl defmt::Logger for SemihostingLogger {
    fn acquire() {
        let primask_was_active = cortex_m::register::primask::read().is_active();
        cortex_m::interrupt::disable();
        if TAKEN.swap(true, Ordering::Acquire) {
            // Re-entry: leave the owner alone; our writes are dropped (see `write`).
            if primask_was_active {
                unsafe { cortex_m::interrupt::enable() };
            }
            return;
        }
        let st = unsafe { &mut *STATE.0.get() };
        st.restore = primask_was_active;
        st.len = 0;
        let State {
            encoder, buf, len, ..
        } = st;
        encoder.start_frame(|b| append(buf, len, b));
    }

    unsafe fn flush() {}

    unsafe fn release() {
        let st = unsafe { &mut *STATE.0.get() };
        {
            let State {
                encoder, buf, len, ..
            } = &mut *st;
            encoder.end_frame(|b| append(buf, len, b));
        }
        if st.out.is_none() {
            st.out = stdout();
        }
        if let (Some(out), Some(frame)) = (st.out, st.buf.get(..st.len)) {
            let _ = out.write_all(frame);
        }
        st.len = 0;
        let restore = st.restore;
        TAKEN.store(false, Ordering::Release);
        if restore {
            unsafe { cortex_m::interrupt::enable() };
        }
    }

    unsafe fn write(bytes: &[u8]) {
        let st = unsafe { &mut *STATE.0.get() };
        let State {
            encoder, buf, len, ..
        } = st;
        encoder.write(bytes, |b| append(buf, len, b));
    }
}
