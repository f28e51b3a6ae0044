//! A 16-bit SPI DAC behind embedded-hal's `SpiDevice` (chip select handled by the device).
//!
//! Frame (TI DAC8550, two's-complement twin of the DAC8551, same frame): 24 bits, MSB first — one control byte (`0x00`:
//! normal operation, power-down bits clear) followed by the 16-bit code, MSB first. SPI mode 1
//! (CPOL = 0, CPHA = 1); up to 30 MHz.

use super::{CurrentOutput, DacScale};
use embedded_hal::spi::SpiDevice;

/// The DAC and its current scale.
pub struct SpiDac<D> {
    device: D,
    scale: DacScale,
}

impl<D: SpiDevice> SpiDac<D> {
    /// Control byte: normal operation.
    pub const CONTROL_NORMAL: u8 = 0x00;

    /// A DAC on `device` whose full range maps to `scale`.
    pub fn new(device: D, scale: DacScale) -> Self {
        SpiDac { device, scale }
    }

    /// The frame for a code.
    #[inline]
    pub fn frame(code: u16) -> [u8; 3] {
        let [hi, lo] = code.to_be_bytes();
        [Self::CONTROL_NORMAL, hi, lo]
    }

    /// Gives the device back.
    pub fn release(self) -> D {
        self.device
    }
}

impl<D: SpiDevice> CurrentOutput for SpiDac<D> {
    type Error = D::Error;

    #[inline]
    fn write_current(&mut self, current_a: f32) -> Result<u16, D::Error> {
        let code = self.scale.code(current_a);
        self.device.write(&Self::frame(code))?;
        Ok(code)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use embedded_hal::spi::{ErrorType, Operation};

    /// Records every transaction's written bytes (no std: a fixed array).
    struct Recorder {
        frames: [[u8; 3]; 4],
        n: usize,
    }

    impl ErrorType for Recorder {
        type Error = core::convert::Infallible;
    }

    impl SpiDevice for Recorder {
        fn transaction(&mut self, ops: &mut [Operation<'_, u8>]) -> Result<(), Self::Error> {
            for op in ops {
                if let Operation::Write(bytes) = op {
                    self.frames[self.n].copy_from_slice(bytes);
                    self.n += 1;
                }
            }
            Ok(())
        }
    }

    #[test]
    fn writes_one_24_bit_frame_per_command() {
        let mut dac = SpiDac::new(
            Recorder {
                frames: [[0; 3]; 4],
                n: 0,
            },
            DacScale::new(2.0).unwrap(),
        );
        assert_eq!(dac.write_current(0.0), Ok(0x0000));
        assert_eq!(dac.write_current(-2.0), Ok(0x8000));
        assert_eq!(dac.write_current(1.0), Ok(0x4000));
        let rec = dac.release();
        assert_eq!(rec.n, 3);
        assert_eq!(rec.frames[0], [0x00, 0x00, 0x00]);
        assert_eq!(rec.frames[1], [0x00, 0x80, 0x00]);
        assert_eq!(rec.frames[2], [0x00, 0x40, 0x00]);
    }
}
