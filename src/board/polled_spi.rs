//! Blocking, byte-at-a-time SPI: the one `embedded_hal::spi::SpiBus` implementation the boards'
//! SPI controllers share (PL022 on mps2-an386, SPI1 on the STM32F446). A controller only says how
//! to exchange one byte and whether it is still busy ([`ByteExchange`]);
//! [`impl_polled_spi_bus!`](crate::impl_polled_spi_bus) writes the `SpiBus` impl on top.
//!
//! Cost: one exchange per byte, busy-waiting on the controller's status flags (a 3-byte DAC frame
//! per control interrupt). Never fails (`Error = Infallible`), never panics.

/// One SPI controller in master mode: full-duplex single-byte exchange.
pub trait ByteExchange {
    /// Sends `byte` and returns the byte received at the same time (waits for both).
    fn exchange(&mut self, byte: u8) -> u8;
    /// Whether the controller is still shifting.
    fn busy(&self) -> bool;
}

/// Implements `embedded_hal::spi::{ErrorType, SpiBus<u8>}` for a [`ByteExchange`] type (a blanket
/// impl over the trait is not allowed for a foreign trait, hence the macro).
#[macro_export]
macro_rules! impl_polled_spi_bus {
    ($ty:ty) => {
        impl embedded_hal::spi::ErrorType for $ty {
            type Error = core::convert::Infallible;
        }

        impl embedded_hal::spi::SpiBus<u8> for $ty {
            fn read(&mut self, words: &mut [u8]) -> Result<(), core::convert::Infallible> {
                for w in words.iter_mut() {
                    *w = $crate::board::polled_spi::ByteExchange::exchange(self, 0);
                }
                Ok(())
            }

            fn write(&mut self, words: &[u8]) -> Result<(), core::convert::Infallible> {
                for &w in words {
                    let _ = $crate::board::polled_spi::ByteExchange::exchange(self, w);
                }
                Ok(())
            }

            fn transfer(
                &mut self,
                read: &mut [u8],
                write: &[u8],
            ) -> Result<(), core::convert::Infallible> {
                for i in 0..read.len().max(write.len()) {
                    let out = write.get(i).copied().unwrap_or(0);
                    let inp = $crate::board::polled_spi::ByteExchange::exchange(self, out);
                    if let Some(r) = read.get_mut(i) {
                        *r = inp;
                    }
                }
                Ok(())
            }

            fn transfer_in_place(
                &mut self,
                words: &mut [u8],
            ) -> Result<(), core::convert::Infallible> {
                for w in words.iter_mut() {
                    *w = $crate::board::polled_spi::ByteExchange::exchange(self, *w);
                }
                Ok(())
            }

            fn flush(&mut self) -> Result<(), core::convert::Infallible> {
                while $crate::board::polled_spi::ByteExchange::busy(self) {}
                Ok(())
            }
        }
    };
}
