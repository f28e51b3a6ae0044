//! The capture stream: one fixed-size record per control interrupt, pushed by the interrupt into
//! a lock-free single-producer/single-consumer ring and written to a host file by the main loop.
//!
//! Record layout (little-endian, [`RECORD_BYTES`] = 40 bytes; `cargo xtask qemu` parses it):
//!
//! | offset | type | field |
//! |---|---|---|
//! | 0 | u32 | phase (bits 0-7: 1 dynamic, 2 static, 3 naive dynamic) · flags (bits 8-15, `CommandFlags`) |
//! | 4 | u32 | tick index within the phase (0-based) |
//! | 8 | u32 | elapsed SysTick ticks from handler entry to the last measurement point |
//! | 12 | f32 | current command, A |
//! | 16 | f32 | desired displacement ȳ, m |
//! | 20 | f32 | ẏ, m/s |
//! | 24 | f32 | ÿ, m/s² |
//! | 28 | f32 | H target, A/m |
//! | 32 | f32 | M target, A/m |
//! | 36 | u16 | DAC code · u16 overruns so far (saturating) |

use core::cell::UnsafeCell;
use core::sync::atomic::{AtomicU32, Ordering};

/// Bytes per record.
pub const RECORD_BYTES: usize = 40;
/// Ring capacity in records (power of two).
pub const RING_RECORDS: usize = 256;

/// One encoded record.
pub type Record = [u8; RECORD_BYTES];

/// The SPSC ring.
pub struct Ring {
    slots: UnsafeCell<[Record; RING_RECORDS]>,
    /// Records written (producer index, wrapping).
    head: AtomicU32,
    /// Records consumed (consumer index, wrapping).
    tail: AtomicU32,
    /// Records dropped because the ring was full.
    pub dropped: AtomicU32,
}

// SAFETY: one producer (the control interrupt) writes only the slot at `head` before publishing
// it with a Release store; one consumer (thread mode) reads only slots below `head` (Acquire) and
// publishes `tail` after copying them out.
unsafe impl Sync for Ring {}

impl Ring {
    /// An empty ring.
    pub const fn new() -> Self {
        Ring {
            slots: UnsafeCell::new([[0; RECORD_BYTES]; RING_RECORDS]),
            head: AtomicU32::new(0),
            tail: AtomicU32::new(0),
            dropped: AtomicU32::new(0),
        }
    }

    /// Producer side: appends a record, or counts it as dropped if the ring is full.
    #[inline(always)]
    pub fn push(&self, record: &Record) {
        let head = self.head.load(Ordering::Relaxed);
        let tail = self.tail.load(Ordering::Acquire);
        if head.wrapping_sub(tail) as usize >= RING_RECORDS {
            self.dropped.fetch_add(1, Ordering::Relaxed);
            return;
        }
        let slot = (head as usize) & (RING_RECORDS - 1);
        unsafe {
            if let Some(dst) = (*self.slots.get()).get_mut(slot) {
                *dst = *record;
            }
        }
        self.head.store(head.wrapping_add(1), Ordering::Release);
    }

    /// Consumer side: copies up to `out.len()` records into `out`, returns how many.
    pub fn pop_into(&self, out: &mut [Record]) -> usize {
        let tail = self.tail.load(Ordering::Relaxed);
        let head = self.head.load(Ordering::Acquire);
        let available = head.wrapping_sub(tail) as usize;
        let n = available.min(out.len());
        for (k, dst) in out.iter_mut().take(n).enumerate() {
            let slot = (tail as usize).wrapping_add(k) & (RING_RECORDS - 1);
            unsafe {
                if let Some(src) = (*self.slots.get()).get(slot) {
                    *dst = *src;
                }
            }
        }
        self.tail
            .store(tail.wrapping_add(n as u32), Ordering::Release);
        n
    }

    /// Whether nothing is waiting.
    pub fn is_empty(&self) -> bool {
        self.head.load(Ordering::Acquire) == self.tail.load(Ordering::Relaxed)
    }
}

impl Default for Ring {
    fn default() -> Self {
        Self::new()
    }
}

/// Encodes one record (layout in the module docs).
#[allow(clippy::too_many_arguments)]
#[inline(always)]
pub fn encode(
    phase: u8,
    flags: u8,
    index: u32,
    ticks: u32,
    floats: [f32; 6],
    dac_code: u16,
    overruns: u16,
) -> Record {
    let mut r = [0u8; RECORD_BYTES];
    let words: [u32; 10] = [
        phase as u32 | (flags as u32) << 8,
        index,
        ticks,
        floats[0].to_bits(),
        floats[1].to_bits(),
        floats[2].to_bits(),
        floats[3].to_bits(),
        floats[4].to_bits(),
        floats[5].to_bits(),
        dac_code as u32 | (overruns as u32) << 16,
    ];
    for (chunk, w) in r.chunks_exact_mut(4).zip(words.iter()) {
        chunk.copy_from_slice(&w.to_le_bytes());
    }
    r
}
