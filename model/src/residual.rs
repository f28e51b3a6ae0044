//! Residual statistics every fit and score of a recorded dataset uses: the pooled RMS over the
//! scored samples, the least-squares sensor offset, and the systematic part of an RMS error once
//! the white noise is removed.

/// Noise-corrected systematic part of an RMS error.
pub fn systematic(rms: f64, noise: f64) -> f64 {
    (rms * rms - noise * noise).max(0.0).sqrt()
}

/// Pooled RMS of `pred + offset − measured` over the scored samples `settle..len`.
pub fn pooled_rms(items: &[(&[f64], &[f64], usize)], offset: f64) -> f64 {
    let mut sum = 0.0;
    let mut n = 0usize;
    for (pred, meas, settle) in items {
        for k in *settle..pred.len().min(meas.len()) {
            let r = pred[k] + offset - meas[k];
            sum += r * r;
            n += 1;
        }
    }
    if n == 0 {
        0.0
    } else {
        (sum / n as f64).sqrt()
    }
}

/// Least-squares offset `mean(measured − pred)` over the scored samples.
pub fn offset_of(items: &[(&[f64], &[f64], usize)]) -> f64 {
    let mut sum = 0.0;
    let mut n = 0usize;
    for (pred, meas, settle) in items {
        for k in *settle..pred.len().min(meas.len()) {
            sum += meas[k] - pred[k];
            n += 1;
        }
    }
    if n == 0 {
        0.0
    } else {
        sum / n as f64
    }
}
