//! The white-noise level of a residual: what a model cannot be asked to explain.

use rustfft::num_complex::Complex;
use rustfft::FftPlanner;
use std::f64::consts::PI;

/// Standard deviation of the white part of `residual`, m: the median periodogram level over
/// `[0.3, 0.5]·rate` (Hann window, normalized so white noise of variance σ² has mean level σ²)
/// divided by ln 2 (the median of the exponential distribution of a periodogram bin is ln 2 times
/// its mean). The median ignores the few bins harmonics of the excitation occupy; the band is
/// far above the actuator's mechanical bandwidth, where model errors have decayed.
pub fn white_noise_sigma(residual: &[f64]) -> f64 {
    let n = residual.len();
    if n < 64 {
        return 0.0;
    }
    let mean = residual.iter().sum::<f64>() / n as f64;
    let w: Vec<f64> = (0..n)
        .map(|k| 0.5 - 0.5 * (2.0 * PI * k as f64 / n as f64).cos())
        .collect();
    let w2: f64 = w.iter().map(|v| v * v).sum();
    let mut buf: Vec<Complex<f64>> = residual
        .iter()
        .zip(&w)
        .map(|(v, w)| Complex::new((v - mean) * w, 0.0))
        .collect();
    FftPlanner::new().plan_fft_forward(n).process(&mut buf);
    let lo = (0.3 * n as f64) as usize;
    let hi = n / 2;
    let mut levels: Vec<f64> = (lo..hi).map(|k| buf[k].norm_sqr() / w2).collect();
    if levels.is_empty() {
        return 0.0;
    }
    levels.sort_by(f64::total_cmp);
    (levels[levels.len() / 2] / std::f64::consts::LN_2).sqrt()
}
