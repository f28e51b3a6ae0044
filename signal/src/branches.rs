//! Branch and reversal labels of each sample of an input: where a residual lies on the loop.

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
