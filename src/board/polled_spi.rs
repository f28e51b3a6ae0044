//! Byte-at-a-time SPI with bounded waits: the one `embedded_hal::spi::SpiBus` implementation the
//! boards' SPI controllers share (PL022 on mps2-an386, SPI1 on the STM32F446). A controller only
//! says how to exchange one byte and whether it is still busy ([`ByteExchange`]);
//! [`impl_polled_spi_bus!`](crate::impl_polled_spi_bus) writes the `SpiBus` impl on top.
//!
//! Every wait on a status flag is bounded by [`MAX_STATUS_POLLS`] reads ([`wait_until`]): a
//! controller that never becomes ready (clock gated, peripheral in reset, a hardware fault) makes
//! the transfer fail with [`SpiTimeout`] instead of hanging the control interrupt. The firmware
//! counts these and the next interrupt tries again.
//!
//! Cost: one exchange per byte (a 3-byte DAC frame per control interrupt); at most
//! `2 × MAX_STATUS_POLLS` status reads per byte when the controller is dead. Never panics.

/// Status-register reads before a wait gives up. Each poll is at least a load, a test and a
/// branch (≥ 3 instructions, ≥ 4 cycles), so the bound is ≥ 2,000 cycles: 11 µs at 180 MHz,
/// 15× the 0.71 µs one byte takes at the NUCLEO's 11.25 MHz SPI clock; on mps2-an386 (QEMU's
/// PL022 completes at once) it never waits. A dead controller costs the interrupt at most
/// ~1,500 extra instructions before the error is returned.
pub const MAX_STATUS_POLLS: u32 = 500;

/// A wait on the SPI controller exceeded [`MAX_STATUS_POLLS`] status reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SpiTimeout;

impl embedded_hal::spi::Error for SpiTimeout {
    fn kind(&self) -> embedded_hal::spi::ErrorKind {
        embedded_hal::spi::ErrorKind::Other
    }
}

/// Polls `ready` until it returns true, at most [`MAX_STATUS_POLLS`] times.
#[inline(always)]
pub fn wait_until(mut ready: impl FnMut() -> bool) -> Result<(), SpiTimeout> {
    for _ in 0..MAX_STATUS_POLLS {
        if ready() {
            return Ok(());
        }
    }
    Err(SpiTimeout)
}

/// One SPI controller in master mode: full-duplex single-byte exchange.
pub trait ByteExchange {
    /// Sends `byte` and returns the byte received at the same time (waits, bounded by
    /// [`wait_until`], for room in the transmit buffer and for the received byte).
    fn exchange(&mut self, byte: u8) -> Result<u8, SpiTimeout>;
    /// Whether the controller is still shifting.
    fn busy(&self) -> bool;
    /// Sends `words`, discarding what comes back, and returns when the last bit is out. The
    /// default exchanges byte by byte; a controller with a transmit FIFO or buffer overrides it
    /// to keep the shifter busy (the DAC frame of every control interrupt goes through here).
    fn write_all(&mut self, words: &[u8]) -> Result<(), SpiTimeout> {
        for &w in words {
            self.exchange(w)?;
        }
        Ok(())
    }
}

/// Implements `embedded_hal::spi::{ErrorType, SpiBus<u8>}` for a [`ByteExchange`] type (a blanket
/// impl over the trait is not allowed for a foreign trait, hence the macro). A transfer stops at
/// the first byte that times out.
#[macro_export]
macro_rules! impl_polled_spi_bus {
    ($ty:ty) => {
        impl embedded_hal::spi::ErrorType for $ty {
            type Error = $crate::board::polled_spi::SpiTimeout;
        }

        impl embedded_hal::spi::SpiBus<u8> for $ty {
            fn read(
                &mut self,
                words: &mut [u8],
            ) -> Result<(), $crate::board::polled_spi::SpiTimeout> {
                for w in words.iter_mut() {
                    *w = $crate::board::polled_spi::ByteExchange::exchange(self, 0)?;
                }
                Ok(())
            }

            fn write(&mut self, words: &[u8]) -> Result<(), $crate::board::polled_spi::SpiTimeout> {
                $crate::board::polled_spi::ByteExchange::write_all(self, words)
            }

            fn transfer(
                &mut self,
                read: &mut [u8],
                write: &[u8],
            ) -> Result<(), $crate::board::polled_spi::SpiTimeout> {
                for i in 0..read.len().max(write.len()) {
                    let out = write.get(i).copied().unwrap_or(0);
                    let inp = $crate::board::polled_spi::ByteExchange::exchange(self, out)?;
                    if let Some(r) = read.get_mut(i) {
                        *r = inp;
                    }
                }
                Ok(())
            }

            fn transfer_in_place(
                &mut self,
                words: &mut [u8],
            ) -> Result<(), $crate::board::polled_spi::SpiTimeout> {
                for w in words.iter_mut() {
                    *w = $crate::board::polled_spi::ByteExchange::exchange(self, *w)?;
                }
                Ok(())
            }

            fn flush(&mut self) -> Result<(), $crate::board::polled_spi::SpiTimeout> {
                $crate::board::polled_spi::wait_until(|| {
                    !$crate::board::polled_spi::ByteExchange::busy(self)
                })
            }
        }
    };
}

#[cfg(test)]
mod tests {
    use super::*;
    use embedded_hal::spi::SpiBus;

    /// A controller that completes `working_bytes` exchanges, then never becomes ready again.
    struct Flaky {
        working_bytes: usize,
        sent: [u8; 8],
        n: usize,
        status_reads: core::cell::Cell<u32>,
    }

    impl ByteExchange for Flaky {
        fn exchange(&mut self, byte: u8) -> Result<u8, SpiTimeout> {
            let alive = self.n < self.working_bytes;
            wait_until(|| {
                self.status_reads.set(self.status_reads.get() + 1);
                alive
            })?;
            self.sent[self.n] = byte;
            self.n += 1;
            Ok(!byte)
        }
        fn busy(&self) -> bool {
            self.status_reads.set(self.status_reads.get() + 1);
            self.n >= self.working_bytes
        }
    }

    crate::impl_polled_spi_bus!(Flaky);

    fn flaky(working_bytes: usize) -> Flaky {
        Flaky {
            working_bytes,
            sent: [0; 8],
            n: 0,
            status_reads: core::cell::Cell::new(0),
        }
    }

    #[test]
    fn a_working_controller_transfers_every_byte() {
        let mut bus = flaky(8);
        let mut read = [0u8; 3];
        assert_eq!(bus.transfer(&mut read, &[1, 2, 3]), Ok(()));
        assert_eq!(read, [!1, !2, !3]);
        assert_eq!(&bus.sent[..3], &[1, 2, 3]);
        assert_eq!(bus.flush(), Ok(()));
    }

    #[test]
    fn a_dead_controller_times_out_after_the_poll_bound_instead_of_hanging() {
        let mut bus = flaky(1);
        assert_eq!(bus.write(&[0x00, 0x12, 0x34]), Err(SpiTimeout));
        assert_eq!(
            bus.n, 1,
            "the transfer stops at the first byte that times out"
        );
        // One poll for the good byte, then exactly MAX_STATUS_POLLS for the dead one.
        assert_eq!(bus.status_reads.get(), 1 + MAX_STATUS_POLLS);
        assert_eq!(bus.flush(), Err(SpiTimeout));
        assert_eq!(bus.status_reads.get(), 1 + 2 * MAX_STATUS_POLLS);
    }
}
