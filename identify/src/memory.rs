//! An f64 Preisach memory: the staircase of dominant reversal points, written for identification
//! independently of the no_std core (`magctl::preisach`), so that the regressors are computed in
//! f64 and the core can be checked against them.
//!
//! Inputs are normalized, `x = (u - h_min) / Δ ∈ [0, L]` (clamped: an input beyond the grid
//! saturates the memory). The memory is the alternating list `p_0 = 0 < ...` of reversal points —
//! `p_0` the anchor (a minimum at the bottom of the range), odd entries maxima (decreasing), even
//! entries minima (increasing) — plus the current input `x`. A hysteron `(β, α)` is in `P₊` iff
//! `α <= φ(β)` with the staircase
//!
//! `φ(β) = p_{2k+1}` for `β ∈ [p_{2k}, p_{2k+2})`,
//!
//! where the list is closed by the current input: rising (last stored point a minimum), `φ = x`
//! from the last minimum to the top of the range; falling (last stored point a maximum), `φ` is
//! the last maximum up to `x` and nothing is on for `β > x`. Each rise switches on `α <= x` for
//! `β` above the last minimum, each fall switches off `β >= x`; the wiping-out property pops the
//! pairs the input passes (paper Section 2; Mayergoyz). There is no capacity limit here.

use maglab_dataset::StartState;

/// The start states a normalized Preisach memory reproduces on its own (no mechanics, no
/// previous experiment): saturated, AC-demagnetized at zero input or around the first input,
/// or one period of a periodic steady state.
pub const PREISACH_STARTS: [StartState; 5] = [
    StartState::NegativeSaturation,
    StartState::PositiveSaturation,
    StartState::DemagnetizedAtFirstInput,
    StartState::Demagnetized,
    StartState::Periodic,
];

/// Step of the staircase that approximates the demagnetized line `α + β = 2c`, in cells.
///
/// Every step is a horizontal and a vertical segment of length δ whose midpoints lie on the line,
/// so it deviates from the line by two triangles of area δ²/8 with opposite signs. Inside one
/// cell (uniform density) they cancel; only steps cut by a grid line (at most 2L of them) leave an
/// error, so `|ΔM| <= 2 · 2L · δ²/8 · ρ_max = L δ² ρ_max / 2 ≈ 0.012 ρ_max` for δ = 1/32 (ρ_max:
/// largest cell mass per unit cell area).
pub const DEMAG_STEP: f64 = 1.0 / 32.0;

/// The memory: reversal points and the current input, normalized.
#[derive(Debug, Clone, PartialEq)]
pub struct Memory {
    levels: f64,
    points: Vec<f64>,
    x: f64,
}

/// One piece of the staircase: `P₊ ∋ (β, α)` for `β ∈ [beta_lo, beta_hi)` and `α <= phi`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Piece {
    /// Lower end of the β interval.
    pub beta_lo: f64,
    /// Upper end of the β interval.
    pub beta_hi: f64,
    /// Height of the staircase on it.
    pub phi: f64,
}

impl Memory {
    /// Negative saturation on a grid of `levels` intervals.
    pub fn negative_saturation(levels: usize) -> Self {
        Memory {
            levels: levels as f64,
            points: vec![0.0],
            x: 0.0,
        }
    }

    /// Positive saturation: risen from the anchor to the top.
    pub fn positive_saturation(levels: usize) -> Self {
        Memory {
            levels: levels as f64,
            points: vec![0.0],
            x: levels as f64,
        }
    }

    /// AC-demagnetized around `center` (normalized): from negative saturation, reversals with
    /// maxima `2c - (k + ½) δ` and minima `(k + 1) δ` (δ = [`DEMAG_STEP`]) until they meet, then
    /// the input moves to `c`. Maxima above the range clamp to the top (and are wiped out by the
    /// next, equal maximum), so the staircase follows the line where it lies inside the range.
    pub fn demagnetized(levels: usize, center: f64) -> Self {
        let mut memory = Self::negative_saturation(levels);
        let c = center.clamp(0.0, levels as f64);
        let mut k = 0.0;
        loop {
            let max = 2.0 * c - (k + 0.5) * DEMAG_STEP;
            let min = (k + 1.0) * DEMAG_STEP;
            if max <= c || min >= c {
                break;
            }
            memory.move_to(max);
            memory.move_to(min);
            k += 1.0;
        }
        memory.move_to(c);
        memory
    }

    /// The memory a start state leaves; `centre_x` (normalized) is the demagnetization centre
    /// (the first input for `demagnetized-at-first-input`, the zero input for `demagnetized`, the
    /// middle of the excursion for `periodic`, which then also needs the caller to run the
    /// preconditioning period). Every state but the saturations is a demagnetization there.
    pub fn initial(levels: usize, state: StartState, centre_x: f64) -> Self {
        match state {
            // `conditioned` starts from negative saturation; the caller then applies the sweep
            // (`crate::design::Grid::conditioning`).
            StartState::NegativeSaturation | StartState::Conditioned => {
                Self::negative_saturation(levels)
            }
            StartState::PositiveSaturation => Self::positive_saturation(levels),
            _ => Self::demagnetized(levels, centre_x),
        }
    }

    /// Current normalized input.
    pub fn input(&self) -> f64 {
        self.x
    }

    /// Stored reversal points (anchor first).
    pub fn reversal_points(&self) -> &[f64] {
        &self.points
    }

    fn rising(&self) -> bool {
        // Indices 0, 2, 4... are minima: an odd count means the last stored point is a minimum.
        self.points.len() % 2 == 1
    }

    /// Moves the input to `x` (normalized; clamped to `[0, L]`, non-finite inputs are the
    /// caller's to reject).
    pub fn move_to(&mut self, x: f64) {
        let x = x.clamp(0.0, self.levels);
        if x == self.x {
            return;
        }
        if (x > self.x) != self.rising() {
            // The input reverses at the current point.
            if self.points.len() >= 2 && self.points.last() == Some(&self.x) {
                // Straight back over the last reversal point: that reversal never happened.
                self.points.pop();
            } else {
                self.points.push(self.x);
            }
        }
        loop {
            let n = self.points.len();
            if n % 2 == 1 {
                // Rising from the minimum p[n-1]; p[n-2] is the maximum that dominates it.
                if n >= 3 && x >= self.points[n - 2] {
                    self.points.truncate(n - 2);
                    continue;
                }
            } else if n >= 4 && x <= self.points[n - 2] {
                // Falling from the maximum p[n-1] past the minimum p[n-2] before it.
                self.points.truncate(n - 2);
                continue;
            } else if n == 2 && x <= 0.0 {
                self.points.truncate(1);
                continue;
            }
            break;
        }
        self.x = x;
    }

    /// The staircase `φ` as pieces (see the module docs), in increasing β.
    pub fn pieces(&self, out: &mut Vec<Piece>) {
        out.clear();
        let n = self.points.len();
        let at = |k: usize| if k < n { self.points[k] } else { self.x };
        let total = n + 1; // points followed by the current input
        let mut k = 1;
        while k < total {
            let beta_lo = at(k - 1);
            let phi = at(k);
            let beta_hi = if k + 1 < total {
                at(k + 1)
            } else {
                self.levels
            };
            if beta_hi > beta_lo && phi > beta_lo {
                out.push(Piece {
                    beta_lo,
                    beta_hi,
                    phi,
                });
            }
            k += 2;
        }
    }
}
