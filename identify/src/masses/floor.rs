//! The displacement's noise and sensor offset, and the floor below which a row leaves the
//! regression (the square root of (6) turns noise near `M = 0` into a bias).

use crate::design::Grid;
use maglab_dataset::data::Dataset;

/// The white-noise level of a record's displacement, m: from its second differences
/// `y[k+1] − 2 y[k] + y[k−1]`, whose noise is `√6 σ` and whose signal is nil on a slow record but
/// at its reversals — hence the median absolute deviation (`σ = 1.4826 · MAD / √6`), which the
/// few reversal samples do not move. 0 for fewer than 3 samples.
pub fn displacement_noise_m(y: &[f64]) -> f64 {
    let mut d2: Vec<f64> = y
        .windows(3)
        .map(|w| (w[2] - 2.0 * w[1] + w[0]).abs())
        .collect();
    if d2.is_empty() {
        return 0.0;
    }
    let mid = d2.len() / 2;
    let (_, median, _) = d2.select_nth_unstable_by(mid, f64::total_cmp);
    1.4826 * *median / 6f64.sqrt()
}

/// Largest relative bias of `|M| = M_s √(u / (l_m λ_s))` that a fitted row may carry from the
/// noise of `u`. The square root is concave, so noise of RMS `σ_u` biases it low by
/// `σ_u² / (8 u²)` of itself (second order): near `M = 0`, on the steep branch around the coercive
/// field, that is percents, the masses there come out low and R_eddy, ξ, f0 bend to make up for
/// it (measured on `maglab rig` folders: R_eddy +8.2 % at σ = 0.5 µm with the fixed zero band,
/// +2.5 % with this bound, +1.4 % without noise).
pub const SQRT_NOISE_BIAS_MAX: f64 = 0.001;

/// The fit floor never passes this fraction of the stroke `l_m λ_s` (`|M| = 0.32 M_s`): a record
/// so noisy, or sampled so coarsely that its own curvature reads as noise, keeps its rows above.
pub const FIT_FLOOR_MAX_FRACTION: f64 = 0.1;

/// The smallest `u` (m) whose row enters the regression: the zero band (`zero_band_m`: below it
/// the sign of `M` is uncertain) or, when the noise is larger, where the square root's noise bias
/// reaches [`SQRT_NOISE_BIAS_MAX`]: `u = σ_u / √(8 · SQRT_NOISE_BIAS_MAX)` ≈ 11 σ_u, that never
/// above [`FIT_FLOOR_MAX_FRACTION`] of the stroke `stroke_m`.
pub fn fit_floor_m(zero_band_m: f64, noise_u_m: f64, stroke_m: f64) -> f64 {
    let noise_floor_m = noise_u_m / (8.0 * SQRT_NOISE_BIAS_MAX).sqrt();
    zero_band_m.max(noise_floor_m.min(FIT_FLOOR_MAX_FRACTION * stroke_m))
}

/// The sensor offset, m: in a bipolar quasi-static record the magnetization crosses zero, where
/// `y = l_m λ_s M²/M_s²` vanishes, so the floor of the measured displacement is the offset. The
/// floor is the minimum of a moving average over `max(5, n/2000)` samples (the noise averaged
/// down); the median over the bipolar records (`None` when there is none). Records whose field
/// never leaves the grid's middle (|H| below a tenth of the range) are not bipolar enough.
pub fn displacement_offset_m(dataset: &Dataset, c0: f64, grid: &Grid) -> Option<f64> {
    let span = grid.h_max - grid.h_min;
    let mut floors: Vec<f64> = dataset
        .measurements
        .iter()
        .filter(|m| {
            let (lo, hi) = m
                .current_a
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &i| {
                    (a.min(c0 * i), b.max(c0 * i))
                });
            lo < -0.1 * span && hi > 0.1 * span
        })
        .filter_map(|m| {
            let y = &m.displacement_m;
            let w = (y.len() / 2000).max(5);
            if y.len() < w {
                return None;
            }
            let mut sum: f64 = y[..w].iter().sum();
            let mut floor = sum / w as f64;
            for k in w..y.len() {
                sum += y[k] - y[k - w];
                floor = floor.min(sum / w as f64);
            }
            Some(floor)
        })
        .collect();
    if floors.is_empty() {
        return None;
    }
    floors.sort_by(f64::total_cmp);
    Some(floors[floors.len() / 2])
}
