//! `√x` for f32: the FPU's `VSQRT.F32` on the Cortex-M4F, `libm::sqrtf` elsewhere.
//!
//! `libm::sqrtf` is a software square root on `thumbv7em-none-eabihf` (a loop of integer code);
//! the M4F's FPU has `VSQRT.F32` (one instruction, 14 cycles; 5 with the register moves here). Both are correctly
//! rounded (IEEE 754 requires it of `squareRoot`; ARM's VSQRT implements it, and libm's `sqrtf`
//! computes the exact rounded root), so the results are **bit-identical** for every input,
//! NaN payloads aside: a negative or NaN input gives a NaN on both (the callers never pass one:
//! their arguments are clamped to ≥ 0 first). `cargo xtask qemu` checks the firmware's commands
//! against the host's `libm` ones bit for bit, and `tests::agrees_with_libm` below checks the
//! host path.

/// Correctly rounded square root.
#[inline(always)]
pub fn sqrt_f32(x: f32) -> f32 {
    #[cfg(all(target_arch = "arm", target_abi = "eabihf"))]
    {
        let root_bits: u32;
        // The FP register classes need rustc's `vfp2` feature, which also means double
        // precision (the M4F has none), so the operand travels in core registers and s0 is
        // saved around the instruction: 5 instructions, still far below the software root.
        // SAFETY: s0 is restored; the stack holds 4 bytes for 2 instructions.
        unsafe {
            core::arch::asm!(
                "vpush {{s0}}",
                "vmov s0, {x}",
                "vsqrt.f32 s0, s0",
                "vmov {root}, s0",
                "vpop {{s0}}",
                x = in(reg) x.to_bits(),
                root = lateout(reg) root_bits,
                options(preserves_flags)
            );
        }
        f32::from_bits(root_bits)
    }
    #[cfg(not(all(target_arch = "arm", target_abi = "eabihf")))]
    {
        libm::sqrtf(x)
    }
}

#[cfg(test)]
mod tests {
    use super::sqrt_f32;

    /// Correct rounding: the result r satisfies (r − ½ulp)² ≤ x ≤ (r + ½ulp)², checked in f64
    /// (exact for these products) over a sweep of magnitudes and on the exact squares.
    #[test]
    fn agrees_with_libm_and_is_correctly_rounded() {
        let mut x = 1.0e-30f32;
        while x < 1.0e30 {
            for y in [x, f32::from_bits(x.to_bits() + 1), x * 1.37] {
                let r = sqrt_f32(y);
                assert_eq!(r.to_bits(), libm::sqrtf(y).to_bits(), "{y}");
                let below = f32::from_bits(r.to_bits() - 1) as f64;
                let above = f32::from_bits(r.to_bits() + 1) as f64;
                let (lo, hi) = ((below + r as f64) / 2.0, (above + r as f64) / 2.0);
                assert!(lo * lo <= y as f64 && y as f64 <= hi * hi, "{y} -> {r}");
            }
            x *= 1.9;
        }
        assert_eq!(sqrt_f32(0.0), 0.0);
        assert_eq!(sqrt_f32(4.0), 2.0);
        assert!(sqrt_f32(-1.0).is_nan());
    }
}
