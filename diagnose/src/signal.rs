//! Signal measures used by the diagnosis: fundamental and harmonics of a record, amplitude
//! spectra (rustfft), the white-noise level of a residual, and the branch / reversal labels of each
//! sample.

use rustfft::num_complex::Complex;
use rustfft::FftPlanner;
use std::f64::consts::PI;

/// Dominant frequency of `x` (mean removed), Hz: the largest FFT bin above DC with parabolic
/// interpolation of the log-magnitude around it. `None` for a constant record.
pub fn dominant_frequency_hz(x: &[f64], rate_hz: f64) -> Option<f64> {
    let n = x.len();
    if n < 8 {
        return None;
    }
    let spectrum = amplitude_spectrum(x, rate_hz, false);
    let (k, &(_, peak)) = spectrum
        .iter()
        .enumerate()
        .skip(1)
        .max_by(|a, b| a.1 .1.total_cmp(&b.1 .1))?;
    if peak <= 0.0 {
        return None;
    }
    let df = rate_hz / n as f64;
    if k + 1 < spectrum.len() && k >= 2 {
        let (a, b, c) = (
            spectrum[k - 1].1.max(1e-300).ln(),
            peak.ln(),
            spectrum[k + 1].1.max(1e-300).ln(),
        );
        let denom = a - 2.0 * b + c;
        let shift = if denom.abs() > 0.0 {
            0.5 * (a - c) / denom
        } else {
            0.0
        };
        return Some((k as f64 + shift.clamp(-0.5, 0.5)) * df);
    }
    Some(k as f64 * df)
}

/// One-sided amplitude spectrum `(frequency Hz, amplitude)` of `x` with its mean removed, Hann
/// window when `window`, scaled so a sinusoid of amplitude `A` on a bin shows `A`.
pub fn amplitude_spectrum(x: &[f64], rate_hz: f64, window: bool) -> Vec<(f64, f64)> {
    let n = x.len();
    if n == 0 {
        return Vec::new();
    }
    let mean = x.iter().sum::<f64>() / n as f64;
    let w: Vec<f64> = (0..n)
        .map(|k| {
            if window {
                0.5 - 0.5 * (2.0 * PI * k as f64 / n as f64).cos()
            } else {
                1.0
            }
        })
        .collect();
    let wsum: f64 = w.iter().sum();
    let mut buf: Vec<Complex<f64>> = x
        .iter()
        .zip(&w)
        .map(|(v, w)| Complex::new((v - mean) * w, 0.0))
        .collect();
    FftPlanner::new().plan_fft_forward(n).process(&mut buf);
    (0..=n / 2)
        .map(|k| (k as f64 * rate_hz / n as f64, 2.0 * buf[k].norm() / wsum))
        .collect()
}

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

/// Fourier coefficient of `x` at `freq_hz` over the samples `range` (complex amplitude: a
/// sinusoid `A sin(ωt + φ)` gives `A e^{j(φ - π/2)}`).
pub fn fourier_coefficient(
    x: &[f64],
    range: std::ops::Range<usize>,
    freq_hz: f64,
    rate_hz: f64,
) -> Complex<f64> {
    let n = range.len().max(1) as f64;
    let mut acc = Complex::new(0.0, 0.0);
    for k in range {
        let ph = 2.0 * PI * freq_hz * k as f64 / rate_hz;
        acc += Complex::new(ph.cos(), -ph.sin()) * x[k];
    }
    acc * (2.0 / n)
}

/// The last whole number of periods of `freq_hz` in `start..n` (at least one period), so Fourier
/// coefficients are not smeared by a partial period.
pub fn whole_periods(start: usize, n: usize, freq_hz: f64, rate_hz: f64) -> std::ops::Range<usize> {
    let period = rate_hz / freq_hz;
    let available = (n - start) as f64;
    let periods = (available / period).floor();
    if periods < 1.0 {
        return start..n;
    }
    let len = (periods * period).round() as usize;
    (n - len.min(n - start))..n
}

/// Per-sample labels: ascending input (`true`) or descending, and near an input reversal (within
/// 15 % of the half-cycle on either side) or mid-branch.
#[derive(Debug, Clone, PartialEq)]
pub struct BranchLabels {
    /// The input is rising at this sample.
    pub ascending: Vec<bool>,
    /// The sample is within 15 % of the monotone segment's length of a reversal.
    pub near_reversal: Vec<bool>,
}

/// Labels of every sample of the input `x` (reversals found on a lightly smoothed copy, so
/// quantization steps of a measured current do not count as reversals).
pub fn branch_labels(x: &[f64]) -> BranchLabels {
    let n = x.len();
    let mut ascending = vec![true; n];
    let mut near = vec![false; n];
    if n < 3 {
        return BranchLabels {
            ascending,
            near_reversal: near,
        };
    }
    let range =
        x.iter().cloned().fold(f64::MIN, f64::max) - x.iter().cloned().fold(f64::MAX, f64::min);
    // Hysteresis threshold for a direction change: 2 % of the range.
    let threshold = 0.02 * range;
    let mut reversals = vec![0usize];
    let mut dir = 0i8;
    let mut extreme = x[0];
    let mut extreme_at = 0usize;
    for (k, &v) in x.iter().enumerate() {
        match dir {
            0 => {
                if v > x[0] + threshold {
                    dir = 1;
                    extreme = v;
                    extreme_at = k;
                } else if v < x[0] - threshold {
                    dir = -1;
                    extreme = v;
                    extreme_at = k;
                }
            }
            1 => {
                if v > extreme {
                    extreme = v;
                    extreme_at = k;
                } else if v < extreme - threshold {
                    reversals.push(extreme_at);
                    dir = -1;
                    extreme = v;
                    extreme_at = k;
                }
            }
            _ => {
                if v < extreme {
                    extreme = v;
                    extreme_at = k;
                } else if v > extreme + threshold {
                    reversals.push(extreme_at);
                    dir = 1;
                    extreme = v;
                    extreme_at = k;
                }
            }
        }
    }
    reversals.push(n - 1);
    for seg in reversals.windows(2) {
        let (a, b) = (seg[0], seg[1]);
        let rising = x[b] >= x[a];
        let len = (b - a).max(1) as f64;
        for k in a..=b.min(n - 1) {
            ascending[k] = rising;
            let d = (k - a).min(b - k) as f64;
            near[k] = d <= 0.15 * len;
        }
    }
    BranchLabels {
        ascending,
        near_reversal: near,
    }
}
