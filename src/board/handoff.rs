//! Handing the control state from `main` to the interrupt, soundly.
//!
//! `main` builds the state (controller, Preisach memory, DAC driver, timer) and the control
//! interrupt owns it afterwards. A plain `static mut` written in `main` before `NVIC::unmask`
//! relies on the compiler not moving the write past the unmask, which nothing guarantees. A
//! [`HandOff`] publishes the value with a release store of its state word and the interrupt reads
//! it with an acquire load: the interrupt either sees no value (and returns) or the whole value.
//!
//! Cost in the interrupt: one load and one compare (the acquire is free on a single-core
//! Cortex-M; the compiler keeps the order).

use core::cell::UnsafeCell;
use core::mem::MaybeUninit;
use core::sync::atomic::{AtomicU8, Ordering};

const EMPTY: u8 = 0;
const WRITING: u8 = 1;
const READY: u8 = 2;

/// A value given once by one context (thread mode) and then used by one other (the interrupt).
/// The value is never dropped: it lives as long as the program.
pub struct HandOff<T> {
    state: AtomicU8,
    value: UnsafeCell<MaybeUninit<T>>,
}

// SAFETY: the value is written once, before `state` becomes READY (release), and only accessed
// after an acquire load sees READY, by the single owner `get_mut`'s contract names.
unsafe impl<T: Send> Sync for HandOff<T> {}

impl<T> HandOff<T> {
    /// An empty hand-over slot (for a `static`).
    pub const fn new() -> Self {
        HandOff {
            state: AtomicU8::new(EMPTY),
            value: UnsafeCell::new(MaybeUninit::uninit()),
        }
    }

    /// Publishes `value`. Call before enabling the interrupt that uses it. A second call (or a
    /// concurrent one) gets its value back.
    pub fn give(&self, value: T) -> Result<(), T> {
        if self
            .state
            .compare_exchange(EMPTY, WRITING, Ordering::Acquire, Ordering::Relaxed)
            .is_err()
        {
            return Err(value);
        }
        // SAFETY: the WRITING state makes this the only access until READY is published.
        unsafe { (*self.value.get()).write(value) };
        self.state.store(READY, Ordering::Release);
        Ok(())
    }

    /// Whether a value has been given.
    pub fn is_ready(&self) -> bool {
        self.state.load(Ordering::Acquire) == READY
    }

    /// The value, once given; `None` before.
    ///
    /// # Safety
    /// One context at a time may hold the reference: the control interrupt while it runs, or
    /// thread mode once that interrupt is masked or can no longer fire.
    #[allow(clippy::mut_from_ref)]
    #[inline(always)]
    pub unsafe fn get_mut(&self) -> Option<&mut T> {
        if self.state.load(Ordering::Acquire) == READY {
            // SAFETY: READY means the write happened before (release/acquire); exclusivity is
            // the caller's contract.
            Some(unsafe { (*self.value.get()).assume_init_mut() })
        } else {
            None
        }
    }
}

impl<T> Default for HandOff<T> {
    fn default() -> Self {
        Self::new()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_value_appears_only_after_it_is_given_and_only_once() {
        static SLOT: HandOff<[u32; 4]> = HandOff::new();
        assert!(!SLOT.is_ready());
        assert!(unsafe { SLOT.get_mut() }.is_none());
        assert_eq!(SLOT.give([1, 2, 3, 4]), Ok(()));
        assert!(SLOT.is_ready());
        assert_eq!(SLOT.give([9; 4]), Err([9; 4]), "a second value is refused");
        let v = unsafe { SLOT.get_mut() }.unwrap();
        assert_eq!(*v, [1, 2, 3, 4]);
        v[0] = 7;
        assert_eq!(unsafe { SLOT.get_mut() }.unwrap()[0], 7);
    }

    #[test]
    fn a_reader_on_another_thread_sees_either_nothing_or_the_whole_value() {
        extern crate std;
        static SLOT: HandOff<[u64; 16]> = HandOff::new();
        let reader = std::thread::spawn(|| loop {
            // SAFETY: this thread is the only one that dereferences the value.
            if let Some(v) = unsafe { SLOT.get_mut() } {
                assert!(v.iter().all(|&x| x == 0xDEAD_BEEF), "torn value");
                return;
            }
            std::hint::spin_loop();
        });
        assert_eq!(SLOT.give([0xDEAD_BEEF; 16]), Ok(()));
        reader.join().unwrap();
    }
}
