//! Each quasi-static record's start state and the sign convention of its magnetization.

use crate::design::Grid;
use crate::magnetization::Branch;
use maglab_dataset::StartState;

/// The sign convention a file needs: `monotone` when its current changes sign (bipolar data:
/// the magnetization changes sign too), else `positive` (DC-biased data from a state at zero).
pub fn auto_branch(current_a: &[f64]) -> Branch {
    let (lo, hi) = current_a
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
            (a.min(v), b.max(v))
        });
    if lo < 0.0 && hi > 0.0 {
        Branch::Monotone
    } else {
        Branch::Positive
    }
}

/// The initial memory of an undocumented file, from its field `h` and displacement `y` (white
/// noise `noise_m`): a record that starts beyond an end of the grid saturates the memory itself;
/// a closed record (first and last samples within 2 % of the field range, at least one
/// reversal) is a period of a periodic loop — unless it holds two periods and its first differs
/// from its second ([`first_period_is_a_transient`]): then it was switched on from a
/// demagnetized rod and its first period is the way onto the loop. Any other record starts from
/// a demagnetization at zero current.
pub fn auto_initial(h: &[f64], y: &[f64], noise_m: f64, grid: &Grid) -> StartState {
    let (Some(&first), Some(&last)) = (h.first(), h.last()) else {
        return StartState::Demagnetized;
    };
    if first <= grid.h_min {
        return StartState::NegativeSaturation;
    }
    if first >= grid.h_max {
        return StartState::PositiveSaturation;
    }
    let (lo, hi) = h
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
            (a.min(v), b.max(v))
        });
    let reversal = h.windows(3).any(|w| (w[1] - w[0]) * (w[2] - w[1]) < 0.0);
    let closed = reversal && (first - last).abs() <= 0.02 * (hi - lo);
    if closed && !first_period_is_a_transient(h, y, noise_m) {
        StartState::Periodic
    } else {
        StartState::Demagnetized
    }
}

/// Whether the displacement over the first period of the input differs from the second by more
/// than two noisy copies of one loop would: RMS difference above `max(3 √2 σ, 10⁻³ of the
/// displacement's range)` (the difference of two records with white noise σ has RMS `√2 σ`; the
/// floor covers noise-free records). The period ends where the input first returns to its first
/// value moving the way it started, after a reversal. `false` when the record holds less than
/// two periods (nothing to compare).
pub fn first_period_is_a_transient(h: &[f64], y: &[f64], noise_m: f64) -> bool {
    let n = h.len().min(y.len());
    let Some(&h0) = h.first() else {
        return false;
    };
    let Some(direction) = h
        .iter()
        .map(|&v| v - h0)
        .find(|d| *d != 0.0)
        .map(f64::signum)
    else {
        return false;
    };
    let mut reversed = false;
    let mut period = None;
    for t in 1..n {
        let step = h[t] - h[t - 1];
        if step * direction < 0.0 {
            reversed = true;
        }
        let crossed = (h[t - 1] - h0) * direction < 0.0 && (h[t] - h0) * direction >= 0.0;
        if reversed && crossed && step * direction > 0.0 {
            period = Some(t);
            break;
        }
    }
    let Some(p) = period.filter(|&p| 2 * p <= n) else {
        return false;
    };
    let (lo, hi) = y[..2 * p]
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
            (a.min(v), b.max(v))
        });
    let rms = (y[..p]
        .iter()
        .zip(&y[p..2 * p])
        .map(|(a, b)| (a - b) * (a - b))
        .sum::<f64>()
        / p as f64)
        .sqrt();
    rms > (3.0 * std::f64::consts::SQRT_2 * noise_m).max(1e-3 * (hi - lo))
}

/// The Preisach memory a documented bench start leaves (`switch-on-demagnetized` is
/// `demagnetized` for the memory); `previous` has none of its own: `None`, the file's start is
/// then estimated.
pub fn documented_initial(start: StartState) -> Option<StartState> {
    match start {
        StartState::SwitchOnDemagnetized => Some(StartState::Demagnetized),
        StartState::Previous => None,
        other => Some(other),
    }
}
