//! The analytic default Preisach measure shipped in `params/actuator.json`.
//!
//! The paper does not publish its identified weights, so the default file carries masses computed
//! from a documented analytic density instead. It is **not** a measurement of any actuator: replace
//! it with `maglab identify` output for a real rig.
//!
//! Density (the classic factorized form in coercive/interaction coordinates,
//! `h_c = (α - β) / 2 >= 0`, `h_i = (α + β) / 2`):
//!
//! `μ(β, α) ∝ exp(-(h_c - h_c0)² / (2 σ_c²)) · exp(-h_i² / (2 σ_i²))`
//!
//! with `h_c0` the typical coercive field, `σ_c` its spread and `σ_i` the interaction-field spread.
//! Each cell mass is the integral of the density over the cell (midpoint rule on a
//! `QUADRATURE_POINTS²` sub-grid, sub-squares cut by the diagonal counted half), and the masses
//! are scaled so that they sum to the saturation magnetization `M_s`: the operator's output then
//! saturates at exactly `±M_s`.

use crate::{cell_count, cell_index};

/// Sub-points per cell side used to integrate the density over a cell.
pub const QUADRATURE_POINTS: usize = 32;

/// Shape of the factorized Gaussian density, all in A/m.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GaussianDensity {
    /// Centre of the coercive-field distribution.
    pub coercive_center_a_per_m: f64,
    /// Spread of the coercive-field distribution.
    pub coercive_spread_a_per_m: f64,
    /// Spread of the interaction-field distribution.
    pub interaction_spread_a_per_m: f64,
}

/// The shape used for the shipped default: a soft, low-coercivity loop like a prestressed
/// Terfenol-D rod (coercive field ≈ 2.5 kA/m, close to saturation at ±30 kA/m).
pub const TERFENOL_LIKE: GaussianDensity = GaussianDensity {
    coercive_center_a_per_m: 2.5e3,
    coercive_spread_a_per_m: 2.0e3,
    interaction_spread_a_per_m: 7.0e3,
};

impl GaussianDensity {
    /// Unnormalized density at `(β, α)`, `α >= β`.
    pub fn density(&self, beta: f64, alpha: f64) -> f64 {
        let hc = 0.5 * (alpha - beta);
        let hi = 0.5 * (alpha + beta);
        let zc = (hc - self.coercive_center_a_per_m) / self.coercive_spread_a_per_m;
        let zi = hi / self.interaction_spread_a_per_m;
        (-0.5 * zc * zc).exp() * (-0.5 * zi * zi).exp()
    }

    /// Cell masses (alpha-major order, see [`crate::Preisach::weights_a_per_m`]) on a grid of
    /// `levels` intervals over `[h_min, h_max]`, scaled to sum to `total_a_per_m`.
    pub fn cell_masses(
        &self,
        levels: usize,
        h_min: f64,
        h_max: f64,
        total_a_per_m: f64,
    ) -> Vec<f64> {
        let step = (h_max - h_min) / levels as f64;
        let q = QUADRATURE_POINTS;
        let sub = step / q as f64;
        let mut masses = vec![0.0; cell_count(levels)];
        for j in 0..levels {
            for i in 0..=j {
                let mut sum = 0.0;
                for a in 0..q {
                    for b in 0..q {
                        // Sub-square (b along β, a along α); in a diagonal cell only α >= β counts.
                        let factor = match (i < j, a.cmp(&b)) {
                            (true, _) | (false, std::cmp::Ordering::Greater) => 1.0,
                            (false, std::cmp::Ordering::Equal) => 0.5,
                            (false, std::cmp::Ordering::Less) => 0.0,
                        };
                        if factor == 0.0 {
                            continue;
                        }
                        let beta = h_min + (i as f64) * step + (b as f64 + 0.5) * sub;
                        let alpha = h_min + (j as f64) * step + (a as f64 + 0.5) * sub;
                        sum += factor * self.density(beta, alpha);
                    }
                }
                masses[cell_index(i, j)] = sum;
            }
        }
        let total: f64 = masses.iter().sum();
        for m in &mut masses {
            *m *= total_a_per_m / total;
        }
        masses
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn masses_sum_to_total_and_are_symmetric() {
        let w = TERFENOL_LIKE.cell_masses(25, -3.0e4, 3.0e4, 7.87e5);
        let total: f64 = w.iter().sum();
        assert!((total - 7.87e5).abs() < 1e-6 * 7.87e5);
        // Symmetric range and density even in h_i: cell (i, j) mirrors to (L-1-j, L-1-i).
        for j in 0..25 {
            for i in 0..=j {
                let a = w[cell_index(i, j)];
                let b = w[cell_index(24 - j, 24 - i)];
                assert!((a - b).abs() <= 1e-9 * total, "cell ({i},{j})");
            }
        }
    }
}
