//! A record with a known white noise taken out: its cosine-transform coefficients kept where
//! they stand above the noise, dropped where they do not (hard thresholding at the universal
//! threshold of Donoho & Johnstone, "Ideal spatial adaptation by wavelet shrinkage", 1994).
//!
//! The cosine transform (DCT-II, from the FFT of the record followed by its mirror image) is
//! orthogonal, so white noise of standard deviation `σ` stays white with the same `σ` in every
//! coefficient, and it treats the record as continued by its mirror image: no jump at the ends
//! spreads the record's level or slope over every coefficient, as a plain DFT's periodic
//! continuation would. Of `n` coefficients of pure noise, the largest stays below
//! `λ = σ √(2 ln n)` with a probability that tends to one (about 1 − 1/√(π ln n)); a coefficient
//! above `λ` is kept exactly (hard thresholding: a kept component is not shrunk, so the
//! record's content is not biased), one below is set to zero. What is dropped of the signal is,
//! per coefficient, below the noise that stood on it.

use rustfft::num_complex::Complex;
use rustfft::FftPlanner;
use std::f64::consts::PI;

/// `x` with white noise of standard deviation `sigma` taken out (module docs). Records shorter
/// than 4 samples, and a `sigma` that is not finite and positive, come back as they are.
pub fn without_white_noise(x: &[f64], sigma: f64) -> Vec<f64> {
    let n = x.len();
    if n < 4 || !(sigma.is_finite() && sigma > 0.0) {
        return x.to_vec();
    }
    let mut coefficients = cosine_transform(x);
    let threshold = sigma * (2.0 * (n as f64).ln()).sqrt();
    for c in coefficients.iter_mut() {
        if c.abs() <= threshold {
            *c = 0.0;
        }
    }
    inverse_cosine_transform(&coefficients)
}

/// The orthonormal DCT-II of `x`: `X_k = s_k Σ_j x_j cos(π k (j + ½) / n)`, `s_0 = √(1/n)`,
/// `s_k = √(2/n)`; through the FFT of `[x, reversed x]` (length `2n`), whose bin `k` is
/// `2 e^{iπk/2n} Σ_j x_j cos(π k (j + ½) / n)`.
fn cosine_transform(x: &[f64]) -> Vec<f64> {
    let n = x.len();
    let mut buf: Vec<Complex<f64>> = x
        .iter()
        .chain(x.iter().rev())
        .map(|&v| Complex::new(v, 0.0))
        .collect();
    FftPlanner::new().plan_fft_forward(2 * n).process(&mut buf);
    (0..n)
        .map(|k| {
            let turn = Complex::from_polar(1.0, -PI * k as f64 / (2 * n) as f64);
            let sum = 0.5 * (buf[k] * turn).re;
            sum * scale(k, n)
        })
        .collect()
}

/// The inverse of [`cosine_transform`] (its transpose: the DCT-III with the same scales),
/// through the inverse FFT of the `2n` bins of the mirrored record.
fn inverse_cosine_transform(coefficients: &[f64]) -> Vec<f64> {
    let n = coefficients.len();
    // Bin k of the mirrored record: 2 e^{iπk/2n} C_k (C_k = X_k / s_k), bin 2n − k its
    // conjugate, bin n zero.
    let mut buf = vec![Complex::new(0.0, 0.0); 2 * n];
    for (k, &c) in coefficients.iter().enumerate() {
        let bin = Complex::from_polar(2.0 * c / scale(k, n), PI * k as f64 / (2 * n) as f64);
        buf[k] = bin;
        if k > 0 {
            buf[2 * n - k] = bin.conj();
        }
    }
    FftPlanner::new().plan_fft_inverse(2 * n).process(&mut buf);
    buf[..n].iter().map(|v| v.re / (2 * n) as f64).collect()
}

/// The orthonormal DCT-II's scale of coefficient `k` of `n`.
fn scale(k: usize, n: usize) -> f64 {
    if k == 0 {
        (1.0 / n as f64).sqrt()
    } else {
        (2.0 / n as f64).sqrt()
    }
}
