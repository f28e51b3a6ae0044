//! `min`, `max` and `clamp` of f32 as one compare and one conditional move.
//!
//! On `thumbv7em-none-eabihf` `f32::min` / `f32::max` are calls to `fminf` / `fmaxf` (ARMv7E-M has
//! no `VMINNM`/`VMAXNM`; those are ARMv8): 11–13 instructions each with the call, where a compare
//! and a select take 3–4 (`VCMP`, `VMRS`, `IT`, `VMOV`). The Preisach solve used five of them per
//! control interrupt. They differ from the std functions only when the **second** operand is NaN
//! (std returns the first operand, these return the NaN); every caller passes a finite constant
//! or a finite bound as the second operand. A NaN first operand gives the second operand, as
//! std does.

/// `a.min(b)` for a non-NaN `b`.
#[inline(always)]
pub fn min_f32(a: f32, b: f32) -> f32 {
    if a < b {
        a
    } else {
        b
    }
}

/// `a.max(b)` for a non-NaN `b`.
#[inline(always)]
pub fn max_f32(a: f32, b: f32) -> f32 {
    if a > b {
        a
    } else {
        b
    }
}

/// `x` limited to `[lo, hi]` for non-NaN `lo <= hi`; a NaN `x` gives `lo` (std's `clamp`
/// returns the NaN and asserts `lo <= hi`).
#[inline(always)]
pub fn clamp_f32(x: f32, lo: f32, hi: f32) -> f32 {
    min_f32(max_f32(x, lo), hi)
}

#[cfg(test)]
mod tests {
    use super::{clamp_f32, max_f32, min_f32};

    /// Equal to std on every pair of a sweep that includes ±0, ±∞, subnormals and NaN first
    /// operands (ties of ±0 may pick either zero, as IEEE allows: compared by value).
    #[test]
    fn agree_with_std_for_a_non_nan_second_operand() {
        let values = [
            f32::NEG_INFINITY,
            -3.5,
            -1.0e-40,
            -0.0,
            0.0,
            1.0e-40,
            2.0,
            f32::MAX,
            f32::INFINITY,
        ];
        for &b in &values {
            for a in values.iter().copied().chain([f32::NAN]) {
                assert_eq!(min_f32(a, b), a.min(b), "min({a}, {b})");
                assert_eq!(max_f32(a, b), a.max(b), "max({a}, {b})");
            }
        }
        assert_eq!(clamp_f32(7.0, 0.0, 1.0), 1.0);
        assert_eq!(clamp_f32(-7.0, 0.0, 1.0), 0.0);
        assert_eq!(clamp_f32(0.25, 0.0, 1.0), 0.25);
        assert_eq!(clamp_f32(f32::NAN, 0.0, 1.0), 0.0);
    }
}
