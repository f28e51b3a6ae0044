//! Current (A) → 16-bit two's-complement DAC code, in fixed point.
//!
//! Two's complement because the DAC (TI DAC8550) powers up, and stays until the first valid
//! write, at mid-scale, which is code 0x0000 in its two's-complement coding: 0 A into the coil
//! before the firmware has run a single instruction (its binary-coded twin DAC8551 powers up at
//! zero-scale, i.e. −I_fs through a bipolar amplifier).

use fixed::types::I1F15;

/// Full-scale current of the amplifier and the conversion to DAC codes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DacScale {
    inv_full_scale_per_a: f32,
}

impl DacScale {
    /// The code for 0 A: the DAC's mid-scale, also its power-on value.
    pub const ZERO_CURRENT_CODE: u16 = 0x0000;

    /// Conversion for an amplifier with full scale `±full_scale_a` (finite, > 0; anything else
    /// returns `None`).
    pub fn new(full_scale_a: f32) -> Option<Self> {
        if full_scale_a.is_finite() && full_scale_a > 0.0 {
            Some(DacScale {
                inv_full_scale_per_a: 1.0 / full_scale_a,
            })
        } else {
            None
        }
    }

    /// The code for `current_a`: normalized to `[-1, 1)`, rounded to the nearest Q1.15 step
    /// (1 LSB = full scale / 32768, ties away from zero), saturated at the ends; the Q1.15 bits
    /// are the two's-complement code. NaN maps to [`DacScale::ZERO_CURRENT_CODE`] (0 A) — the
    /// controller never produces one (its limiter holds the last valid current), this only
    /// keeps the conversion total.
    ///
    /// Cost: a multiply, an add, one `VCVT` (Rust's float → integer `as` truncates and
    /// saturates, NaN → 0) and a clamp, ~10 instructions; `I1F15::checked_from_num` did the
    /// same rounding in ~100 instructions of integer code (measured by the QEMU run's stage
    /// breakdown). Exact: `|steps| ≤ 2¹⁵` is far inside f32's 2²⁴ integer range, so adding ½
    /// rounds nothing.
    #[inline]
    pub fn code(&self, current_a: f32) -> u16 {
        let steps = current_a * self.inv_full_scale_per_a * 32768.0;
        let rounded = (steps + 0.5f32.copysign(steps)) as i32;
        let q = I1F15::from_bits(rounded.clamp(i16::MIN as i32, i16::MAX as i32) as i16);
        q.to_bits() as u16
    }

    /// The current a code stands for, A (inverse of [`DacScale::code`] up to 1/2 LSB).
    pub fn current_a(&self, code: u16) -> f32 {
        let q = I1F15::from_bits(code as i16);
        q.to_num::<f32>() / self.inv_full_scale_per_a
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn codes_are_twos_complement_and_round_trip_within_half_an_lsb() {
        let s = DacScale::new(2.0).unwrap();
        assert_eq!(s.code(0.0), 0x0000);
        assert_eq!(s.code(0.0), DacScale::ZERO_CURRENT_CODE);
        assert_eq!(s.code(-2.0), 0x8000);
        assert_eq!(s.code(2.0), 0x7FFF); // +full scale saturates at the top code
        assert_eq!(s.code(5.0), 0x7FFF);
        assert_eq!(s.code(-5.0), 0x8000);
        assert_eq!(s.code(-1.0), 0xC000);
        assert_eq!(s.code(f32::NAN), 0x0000);
        assert_eq!(s.code(f32::INFINITY), 0x7FFF);
        assert_eq!(s.code(f32::NEG_INFINITY), 0x8000);
        // Rounding to the nearest step, ties away from zero (one LSB = 2 A / 32768).
        let lsb = 2.0f32 / 32768.0;
        assert_eq!(s.code(0.49 * lsb), 0);
        assert_eq!(s.code(0.51 * lsb), 1);
        assert_eq!(s.code(-0.51 * lsb), 0xFFFF);
        assert_eq!(s.code(1.5 * lsb), 2);
        let lsb = 2.0 / 32768.0;
        let mut i = -1.99f32;
        while i < 1.99 {
            let back = s.current_a(s.code(i));
            // Rounding to the nearest step: |error| <= LSB/2 (plus f32 rounding of the product).
            assert!(
                (back - i).abs() <= 0.5 * lsb + 4.0 * f32::EPSILON * 2.0,
                "{i} -> {back}"
            );
            i += 0.0137;
        }
        assert!(DacScale::new(0.0).is_none() && DacScale::new(f32::INFINITY).is_none());
    }
}
