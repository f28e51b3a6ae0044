//! Frequency and phase of periodic signals: the excitation frequency of a measurement (the
//! identification's dataset convention), the fundamental phasors the phase-lag scheme of
//! Section 4 compares, and the spectra of the diagnosis.
//!
//! * [`dominant_tone`]: the largest peak of the Hann-windowed spectrum (`rustfft`) of the
//!   mean-removed signal, interpolated between bins (Gaussian/log-parabolic interpolation: exact
//!   for the Hann main lobe up to ~1 % of a bin), and the *tonal fraction*: the share of the AC
//!   power within ±[`TONE_HALF_WIDTH_BINS`] bins of the peak (the Hann main lobe is ±2 bins, so a
//!   pure sine puts > 99.9 % there; a reversal sequence spreads its power over many bins).
//! * [`refine_frequency`]: golden-section search of the frequency that minimizes the residual of
//!   the harmonic least squares below, within ±1 bin of the FFT estimate: sharper than the bin
//!   interpolation (the whole record's phase drift enters), so the analysis window holds whole
//!   periods.
//! * [`harmonic_fit`]: a lock-in amplifier generalized: least squares of
//!   `c + Σ_{k=1..K} (a_k cos kωt + b_k sin kωt)` over a window of whole periods (nalgebra SVD).
//!   Over whole periods the basis is orthogonal, so this equals the lock-in projection; fitting
//!   the DC level and the harmonics jointly also removes the leakage that a window a fraction of a
//!   sample off whole periods would let the large DC bias and the strong second harmonic of
//!   `y ∝ M²` put into the fundamental.
//! * [`amplitude_spectrum`], [`dominant_frequency_hz`]: the rectangular-window spectrum and its
//!   largest bin (log-parabolic interpolation) by which the diagnosis groups and splits its
//!   experiments; [`fourier_coefficient`] over [`whole_periods`] for its per-band breakdown.
//!
//! Phase convention: the fundamental is `A sin(ωt + φ)` with `t` the sample time; a lag is
//! `φ_input - φ_output`.

use nalgebra::{DMatrix, DVector};
use rustfft::num_complex::Complex;
use rustfft::FftPlanner;
use std::f64::consts::PI;

/// Half width (bins) of the band around the spectral peak that counts as "the tone".
pub const TONE_HALF_WIDTH_BINS: usize = 3;

/// The dominant tone of a signal.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tone {
    /// Frequency of the largest spectral peak, Hz (interpolated between bins).
    pub frequency_hz: f64,
    /// Share of the AC power (bins 1..N/2) within ±[`TONE_HALF_WIDTH_BINS`] of the peak.
    pub tonal_fraction: f64,
    /// Frequency resolution of the record, `1 / (N h)`, Hz.
    pub bin_hz: f64,
}

/// The dominant tone of `signal` sampled every `step_s`. `None` for fewer than 8 samples or a
/// constant signal.
pub fn dominant_tone(signal: &[f64], step_s: f64) -> Option<Tone> {
    let n = signal.len();
    if n < 8 {
        return None;
    }
    let mean = signal.iter().sum::<f64>() / n as f64;
    let mut buffer: Vec<Complex<f64>> = signal
        .iter()
        .enumerate()
        .map(|(k, &x)| {
            let w = 0.5 - 0.5 * (2.0 * PI * k as f64 / n as f64).cos();
            Complex::new((x - mean) * w, 0.0)
        })
        .collect();
    FftPlanner::new().plan_fft_forward(n).process(&mut buffer);
    let power: Vec<f64> = buffer[..=n / 2].iter().map(|c| c.norm_sqr()).collect();
    let total: f64 = power[1..].iter().sum();
    if total <= 0.0 || !total.is_finite() {
        return None;
    }
    let (peak, _) =
        power
            .iter()
            .enumerate()
            .skip(1)
            .fold((1, f64::NEG_INFINITY), |best, (k, &p)| {
                if p > best.1 {
                    (k, p)
                } else {
                    best
                }
            });
    let lo = peak.saturating_sub(TONE_HALF_WIDTH_BINS).max(1);
    let hi = (peak + TONE_HALF_WIDTH_BINS).min(power.len() - 1);
    let band: f64 = power[lo..=hi].iter().sum();
    // Log-parabolic interpolation of the magnitude (Hann main lobe ≈ Gaussian).
    let delta = if peak >= 1 && peak + 1 < power.len() && power[peak - 1] > 0.0 {
        let (a, b, c) = (
            power[peak - 1].sqrt().ln(),
            power[peak].sqrt().ln(),
            power[peak + 1].max(f64::MIN_POSITIVE).sqrt().ln(),
        );
        let d = a - 2.0 * b + c;
        if d < 0.0 {
            (0.5 * (a - c) / d).clamp(-0.5, 0.5)
        } else {
            0.0
        }
    } else {
        0.0
    };
    let bin_hz = 1.0 / (n as f64 * step_s);
    Some(Tone {
        frequency_hz: (peak as f64 + delta) * bin_hz,
        tonal_fraction: band / total,
        bin_hz,
    })
}

/// A fitted periodic signal: DC level and harmonics `k = 1..=K`.
#[derive(Debug, Clone, PartialEq)]
pub struct HarmonicFit {
    /// Fundamental frequency used, Hz.
    pub frequency_hz: f64,
    /// DC level.
    pub mean: f64,
    /// `(a_k, b_k)`: coefficients of `cos kωt` and `sin kωt`, `k = 1..=K`.
    pub harmonics: Vec<(f64, f64)>,
    /// RMS residual of the fit.
    pub rms_residual: f64,
}

impl HarmonicFit {
    /// Amplitude `A` of the fundamental `A sin(ωt + φ)`.
    pub fn amplitude(&self) -> f64 {
        let (a, b) = self.harmonics[0];
        a.hypot(b)
    }

    /// Phase `φ` (rad) of the fundamental `A sin(ωt + φ)` (`t` = sample time).
    pub fn phase_rad(&self) -> f64 {
        let (a, b) = self.harmonics[0];
        a.atan2(b)
    }
}

/// Least squares of `c + Σ_{k=1..harmonics} (a_k cos kωt + b_k sin kωt)` to `signal[window]`
/// with `t = index · step_s`. `None` if the window is shorter than the number of unknowns.
pub fn harmonic_fit(
    signal: &[f64],
    step_s: f64,
    frequency_hz: f64,
    window: std::ops::Range<usize>,
    harmonics: usize,
) -> Option<HarmonicFit> {
    let rows = window.len();
    let cols = 1 + 2 * harmonics;
    if rows < cols || window.end > signal.len() || harmonics == 0 {
        return None;
    }
    let omega = 2.0 * PI * frequency_hz;
    let a = DMatrix::from_fn(rows, cols, |r, c| {
        let t = (window.start + r) as f64 * step_s;
        if c == 0 {
            1.0
        } else {
            let k = c.div_ceil(2) as f64;
            if c % 2 == 1 {
                (k * omega * t).cos()
            } else {
                (k * omega * t).sin()
            }
        }
    });
    let b = DVector::from_iterator(rows, signal[window.clone()].iter().copied());
    let svd = a.clone().svd(true, true);
    let x = svd.solve(&b, 1e-12).ok()?;
    let residual = &a * &x - &b;
    Some(HarmonicFit {
        frequency_hz,
        mean: x[0],
        harmonics: (0..harmonics)
            .map(|k| (x[1 + 2 * k], x[2 + 2 * k]))
            .collect(),
        rms_residual: (residual.norm_squared() / rows as f64).sqrt(),
    })
}

/// The frequency within `[f - bin, f + bin]` (`bin` = [`Tone::bin_hz`]) that minimizes the RMS
/// residual of [`harmonic_fit`] over the whole record (golden section, 40 iterations: the
/// bracket shrinks to 10⁻⁸ of a bin).
pub fn refine_frequency(signal: &[f64], step_s: f64, tone: &Tone, harmonics: usize) -> f64 {
    let cost = |f: f64| {
        harmonic_fit(signal, step_s, f, 0..signal.len(), harmonics)
            .map_or(f64::INFINITY, |h| h.rms_residual)
    };
    crate::golden::golden_section_min(
        (tone.frequency_hz - tone.bin_hz).max(0.5 * tone.bin_hz),
        tone.frequency_hz + tone.bin_hz,
        40,
        cost,
    )
}

/// `θ` wrapped into `(-π/2, 3π/2]`: phase lags of causal, at most second-order-plus-delay
/// systems are in `(0, π)` plus small delays; this keeps them continuous through `π/2`.
pub fn wrap_lag_rad(theta: f64) -> f64 {
    let mut t = theta.rem_euclid(2.0 * PI);
    if t > 1.5 * PI {
        t -= 2.0 * PI;
    }
    t
}

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
