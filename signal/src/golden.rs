//! Golden-section search for the minimum of a unimodal function on an interval: the one
//! one-dimensional minimizer of the workspace (the frequency refinement of [`crate::spectrum`], the channel-skew
//! estimate of the diagnosis, the nuisance shift of the blind suite's gap).
//!
//! Each iteration shrinks the bracket by the golden ratio φ⁻¹ ≈ 0.618 with one new evaluation,
//! so `n` iterations leave a bracket of `0.618ⁿ` of the start (40: ≈ 4·10⁻⁹) and cost `n + 2`
//! evaluations. On a function that is not unimodal it returns a local minimum.

/// The midpoint of the final bracket after `iterations` golden-section steps minimizing `f` on
/// `[lo, hi]`.
pub fn golden_section_min(
    mut lo: f64,
    mut hi: f64,
    iterations: usize,
    f: impl Fn(f64) -> f64,
) -> f64 {
    let ratio = 0.5 * (5f64.sqrt() - 1.0);
    let mut x1 = hi - ratio * (hi - lo);
    let mut x2 = lo + ratio * (hi - lo);
    let (mut c1, mut c2) = (f(x1), f(x2));
    for _ in 0..iterations {
        if c1 <= c2 {
            hi = x2;
            x2 = x1;
            c2 = c1;
            x1 = hi - ratio * (hi - lo);
            c1 = f(x1);
        } else {
            lo = x1;
            x1 = x2;
            c1 = c2;
            x2 = lo + ratio * (hi - lo);
            c2 = f(x2);
        }
    }
    0.5 * (lo + hi)
}
