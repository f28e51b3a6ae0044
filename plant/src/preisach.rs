//! The plant's own Preisach operator, in f64, written independently of the core
//! (`magctl::preisach`, f32 Everett tables with a bounded staircase) and of the identification's
//! regressors (`maglab_identify::cells` computes them for the identification).
//!
//! **Measure.** The parameter file gives one mass per cell of a grid of `L` input intervals with
//! edges `x_0 < x_1 < … < x_L` (A/m), spread uniformly over the cell: the square
//! `[x_i, x_{i+1}] × [x_j, x_{j+1}]` for `i < j` (β in interval `i`, α in interval `j`), the half
//! square `β ≤ α` for `i = j`. The density of cell `(i, j)` is its mass over its area.
//!
//! **Everett function.** `E(α, β)` is the mass of the triangle `{β ≤ b ≤ a ≤ α}`. It is summed
//! row by row (`a` in interval `j`): the full off-diagonal cells of a row come from the row's
//! prefix sums of masses, the partly covered column `β` falls in and the diagonal half-square
//! are integrated exactly; `O(L)` per evaluation, exact up to f64 rounding.
//!
//! **Memory.** The staircase of dominant reversal points, unbounded (a `Vec`): `points[0]` is the
//! anchor at the bottom of the grid (a minimum), then maxima and minima alternate (maxima
//! decreasing, minima increasing), followed by the current input `h`. `μ(P₊)` is kept up to date
//! by Everett increments when the input moves (Mayergoyz): rising from `h` to `h'` above the last
//! minimum `m` adds `E(h', m) − E(h, m)`; falling below the last maximum `M` removes
//! `E(M, h') − E(M, h)`; a move past the previous reversal point is split there and the wiped-out
//! pair is dropped. Output `Γ = 2 μ(P₊) − Σ w`.
//!
//! **Branch slope.** The plant integrates the field in differential form (see
//! [`crate::actuator`]), which needs `dΓ/dH` on the branch the input is moving along:
//! rising from the last minimum `m`, `dΓ/dh = 2 ∫_m^h ρ(b, h) db` (a row integral); falling from
//! the last maximum `M`, `dΓ/dh = 2 ∫_h^M ρ(h, a) da` (a column integral). Both are exact line
//! integrals of the piecewise-constant density. [`PreisachMemory::slope_towards`] evaluates the
//! slope for a trial input on either side of the committed one (a reversal at the committed input
//! when the direction changes, and the wiping-out of reversal points the trial input passes),
//! without changing the memory.

use actuator_params::ActuatorParams;

/// The measure: grid edges and cell densities.
#[derive(Debug, Clone, PartialEq)]
pub struct PreisachGrid {
    /// Edges `x_0 … x_L`, A/m.
    edges: Vec<f64>,
    /// Masses `w[j][i]` (row `j` = α interval, column `i ≤ j` = β interval), A/m.
    mass: Vec<Vec<f64>>,
    /// `prefix[j][k] = Σ_{i < k} w[j][i]`.
    prefix: Vec<Vec<f64>>,
    /// Densities `ρ[j][i]` = mass / cell area (a half square on the diagonal), 1/(A/m): the
    /// divisions done once here, not per evaluation (the RK4 stages evaluate them ~10⁸ times
    /// per blind-suite case; the same quotients, so the same results to the bit).
    density: Vec<Vec<f64>>,
    /// Σ w, A/m.
    total: f64,
}

impl PreisachGrid {
    /// The grid of a parameter file: its grid lines, or `levels` equal intervals of
    /// `[h_min, h_max]`; masses in the schema's alpha-major order (`j (j + 1) / 2 + i`).
    pub fn from_params(params: &ActuatorParams) -> Result<Self, String> {
        let p = &params.preisach;
        let l = p.levels;
        let edges: Vec<f64> = match &p.grid_lines_a_per_m {
            Some(lines) => lines.clone(),
            None => (0..=l)
                .map(|k| {
                    p.h_min_a_per_m + (p.h_max_a_per_m - p.h_min_a_per_m) * k as f64 / l as f64
                })
                .collect(),
        };
        Self::new(edges, &p.weights_a_per_m)
    }

    /// A grid from its edges (strictly increasing, `L + 1` of them) and `L (L + 1) / 2` masses
    /// (alpha-major, ≥ 0).
    pub fn new(edges: Vec<f64>, weights_alpha_major: &[f64]) -> Result<Self, String> {
        let l = edges.len().saturating_sub(1);
        if l == 0 {
            return Err("a Preisach grid needs at least two edges".into());
        }
        if let Some(k) = (1..edges.len())
            .find(|&k| edges[k].partial_cmp(&edges[k - 1]) != Some(std::cmp::Ordering::Greater))
        {
            return Err(format!(
                "grid edges must increase strictly: edge {k} = {} after {}",
                edges[k],
                edges[k - 1]
            ));
        }
        if weights_alpha_major.len() != l * (l + 1) / 2 {
            return Err(format!(
                "{} cell masses for {l} levels; expected {}",
                weights_alpha_major.len(),
                l * (l + 1) / 2
            ));
        }
        if let Some((k, w)) = weights_alpha_major
            .iter()
            .enumerate()
            .find(|(_, w)| !(w.is_finite() && **w >= 0.0))
        {
            return Err(format!("cell mass {k} = {w}: must be finite and >= 0"));
        }
        let mut mass = Vec::with_capacity(l);
        let mut prefix = Vec::with_capacity(l);
        for j in 0..l {
            let row: Vec<f64> = (0..=j)
                .map(|i| weights_alpha_major[j * (j + 1) / 2 + i])
                .collect();
            let mut acc = vec![0.0; j + 2];
            for i in 0..=j {
                acc[i + 1] = acc[i] + row[i];
            }
            mass.push(row);
            prefix.push(acc);
        }
        let total = weights_alpha_major.iter().sum();
        let width = |k: usize| edges[k + 1] - edges[k];
        let density = (0..l)
            .map(|j| {
                (0..=j)
                    .map(|i| {
                        let area = if i == j {
                            0.5 * width(i) * width(i)
                        } else {
                            width(i) * width(j)
                        };
                        mass[j][i] / area
                    })
                    .collect()
            })
            .collect();
        Ok(PreisachGrid {
            edges,
            mass,
            prefix,
            density,
            total,
        })
    }

    /// Number of input intervals `L`.
    pub fn levels(&self) -> usize {
        self.edges.len() - 1
    }

    /// Bottom of the grid, A/m.
    pub fn h_min(&self) -> f64 {
        self.edges[0]
    }

    /// Top of the grid, A/m.
    pub fn h_max(&self) -> f64 {
        self.edges[self.levels()]
    }

    /// Σ w: the output at positive saturation, A/m.
    pub fn total_mass(&self) -> f64 {
        self.total
    }

    /// Interval index of `x` (clamped to the grid): `x_k <= x < x_{k+1}`, the top edge in the
    /// last interval.
    fn interval(&self, x: f64) -> usize {
        let l = self.levels();
        match self.edges.partition_point(|&e| e <= x) {
            0 => 0,
            k if k > l => l - 1,
            k => k - 1,
        }
    }

    fn width(&self, k: usize) -> f64 {
        self.edges[k + 1] - self.edges[k]
    }

    /// Density of cell `(i, j)`, A/m per (A/m)².
    fn density(&self, i: usize, j: usize) -> f64 {
        self.density[j][i]
    }

    /// `E(α, β)`: the mass of `{β ≤ b ≤ a ≤ α}`, A/m (inputs clamped to the grid).
    pub fn everett(&self, alpha: f64, beta: f64) -> f64 {
        let (lo, hi) = (self.h_min(), self.h_max());
        let alpha = alpha.clamp(lo, hi);
        let beta = beta.clamp(lo, hi);
        if alpha <= beta {
            return 0.0;
        }
        let ib = self.interval(beta);
        let ja = self.interval(alpha);
        let mut sum = 0.0;
        for j in ib..=ja {
            let a_lo = self.edges[j].max(beta);
            let a_hi = self.edges[j + 1].min(alpha);
            if a_hi <= a_lo {
                continue;
            }
            let height = a_hi - a_lo;
            if j > ib {
                // Off-diagonal cells of row j: the partly covered column ib, then the full
                // columns ib+1 .. j-1 (their masses times the covered fraction of the row).
                let partial = self.density(ib, j) * (self.edges[ib + 1] - beta) * height;
                let full = (self.prefix[j][j] - self.prefix[j][ib + 1]) * height / self.width(j);
                sum += partial + full;
            }
            // Diagonal half-square (j, j): {max(x_j, β) ≤ b ≤ a ≤ a_hi}, a_lo = max(x_j, β).
            sum += self.density(j, j) * 0.5 * height * height;
        }
        sum
    }

    /// `2 ∫_m^h ρ(b, h) db`: slope of a rising branch from the minimum `m` at input `h`.
    pub fn rising_slope(&self, m: f64, h: f64) -> f64 {
        let (lo, hi) = (self.h_min(), self.h_max());
        if h <= m || h < lo || h > hi {
            return 0.0;
        }
        let m = m.max(lo);
        let j = self.interval(h);
        let im = self.interval(m);
        let mut s = 0.0;
        if im < j {
            s += self.density(im, j) * (self.edges[im + 1] - m);
            s += (self.prefix[j][j] - self.prefix[j][im + 1]) / self.width(j);
            s += self.density(j, j) * (h - self.edges[j]);
        } else {
            s += self.density(j, j) * (h - m);
        }
        2.0 * s
    }

    /// `2 ∫_h^M ρ(h, a) da`: slope of a falling branch from the maximum `M` at input `h`.
    pub fn falling_slope(&self, big_m: f64, h: f64) -> f64 {
        let (lo, hi) = (self.h_min(), self.h_max());
        if h >= big_m || h < lo || h > hi {
            return 0.0;
        }
        let big_m = big_m.min(hi);
        let i = self.interval(h);
        let jm = self.interval(big_m);
        let mut s = 0.0;
        // Diagonal cell (i, i): a from h to min(x_{i+1}, M).
        s += self.density(i, i) * (self.edges[i + 1].min(big_m) - h).max(0.0);
        for j in (i + 1)..=jm {
            let top = self.edges[j + 1].min(big_m);
            s += self.density(i, j) * (top - self.edges[j]).max(0.0);
        }
        2.0 * s
    }
}

/// The Preisach memory (see the module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct PreisachMemory {
    /// Reversal points, A/m: anchor (bottom, a minimum), then maxima and minima alternating.
    points: Vec<f64>,
    /// Current input, A/m (inside the grid).
    h: f64,
    /// μ(P₊), A/m.
    plus: f64,
}

impl PreisachMemory {
    /// Every hysteron at −1 (input at the bottom of the grid).
    pub fn negative_saturation(grid: &PreisachGrid) -> Self {
        PreisachMemory {
            points: vec![grid.h_min()],
            h: grid.h_min(),
            plus: 0.0,
        }
    }

    /// Every hysteron at +1 (input at the top of the grid).
    pub fn positive_saturation(grid: &PreisachGrid) -> Self {
        let mut m = Self::negative_saturation(grid);
        m.move_to(grid, grid.h_max());
        m
    }

    /// The state an AC demagnetization leaves: from positive saturation, a field alternating about
    /// `centre_a_per_m` whose amplitude shrinks by `ratio` every half cycle (a decaying AC field,
    /// applied quasi-statically) until it is below `floor_a_per_m`, then the input at the centre.
    /// With `ratio` near 1 the staircase hugs the line `α + β = 2 · centre`.
    pub fn ac_demagnetized(
        grid: &PreisachGrid,
        centre_a_per_m: f64,
        ratio: f64,
        floor_a_per_m: f64,
    ) -> Self {
        let mut m = Self::positive_saturation(grid);
        let mut amplitude = (grid.h_max() - grid.h_min()).max(1.0);
        let mut sign = -1.0;
        let ratio = ratio.clamp(0.5, 0.9999);
        while amplitude > floor_a_per_m.max(1e-9) {
            m.move_to(grid, centre_a_per_m + sign * amplitude);
            amplitude *= ratio;
            sign = -sign;
        }
        m.move_to(grid, centre_a_per_m);
        m
    }

    /// Current input, A/m.
    pub fn input_a_per_m(&self) -> f64 {
        self.h
    }

    /// Output `Γ = 2 μ(P₊) − Σ w`, A/m.
    pub fn output_a_per_m(&self, grid: &PreisachGrid) -> f64 {
        2.0 * self.plus - grid.total_mass()
    }

    /// Stored reversal points (anchor first), A/m.
    pub fn reversal_points(&self) -> &[f64] {
        &self.points
    }

    /// The last stored point is a minimum: the input rose (or is about to rise) from it.
    fn rising(&self) -> bool {
        self.points.len() % 2 == 1
    }

    /// Moves the input monotonically to `h` (clamped to the grid), updating `μ(P₊)`.
    pub fn move_to(&mut self, grid: &PreisachGrid, h: f64) {
        let h = h.clamp(grid.h_min(), grid.h_max());
        if h == self.h {
            return;
        }
        let up = h > self.h;
        if up != self.rising() {
            // Reversal at the current input (unless the input goes straight back over the last
            // reversal point, which then never happened).
            if self.points.len() >= 2 && self.points.last() == Some(&self.h) {
                self.points.pop();
            } else {
                self.points.push(self.h);
            }
        }
        if up {
            loop {
                let n = self.points.len();
                let m = self.points[n - 1];
                // The maximum that dominates this rise (none: up to the top).
                let cap = if n >= 3 {
                    self.points[n - 2]
                } else {
                    f64::INFINITY
                };
                let to = h.min(cap);
                self.plus += grid.everett(to, m) - grid.everett(self.h, m);
                self.h = to;
                if h >= cap {
                    // Wipe out the pair (max at n-2, min at n-1): the rise continues from the
                    // older minimum at n-3.
                    self.points.truncate(n - 2);
                    if self.h == h {
                        break;
                    }
                } else {
                    break;
                }
            }
        } else {
            loop {
                let n = self.points.len();
                let big_m = self.points[n - 1];
                // The minimum that bounds this fall (the anchor: down to the bottom).
                let floor = if n >= 4 {
                    self.points[n - 2]
                } else {
                    f64::NEG_INFINITY
                };
                let to = h.max(floor);
                self.plus -= grid.everett(big_m, to) - grid.everett(big_m, self.h);
                self.h = to;
                if h <= floor {
                    self.points.truncate(n - 2);
                    if self.h == h {
                        break;
                    }
                } else {
                    break;
                }
            }
            if self.points.len() == 2 && self.h <= grid.h_min() {
                // Back at the bottom: negative saturation, only the anchor remains.
                self.points.truncate(1);
            }
        }
        // Keep μ(P₊) inside its range against accumulated rounding.
        self.plus = self.plus.clamp(0.0, grid.total_mass());
    }

    /// `dΓ/dH` on the branch a move from the committed input towards `h` follows, at `h`,
    /// without changing the memory (see the module docs). At `h` equal to the committed input
    /// the branch the memory is on continues.
    pub fn slope_towards(&self, grid: &PreisachGrid, h: f64) -> f64 {
        let n = self.points.len();
        let up = h > self.h || (h == self.h && self.rising());
        if up {
            // The minimum the rise starts from: the committed input itself if the memory is
            // falling (a new reversal), else the last stored minimum; maxima below h are wiped.
            let (mut min, mut k) = if self.rising() {
                (self.points[n - 1], n - 1)
            } else {
                (self.h, n)
            };
            // points[k] is `min` (or the virtual reversal at k = n); the max before it is k-1.
            while k >= 2 && h >= self.points[k - 1] {
                min = self.points[k - 2];
                k -= 2;
            }
            grid.rising_slope(min, h)
        } else {
            let (mut max, mut k) = if self.rising() {
                (self.h, n)
            } else {
                (self.points[n - 1], n - 1)
            };
            // The min before points[k] is k-1; it bounds the fall unless it is the anchor.
            while k >= 3 && h <= self.points[k - 1] {
                max = self.points[k - 2];
                k -= 2;
            }
            grid.falling_slope(max, h)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid() -> PreisachGrid {
        PreisachGrid::from_params(&actuator_params::paper_defaults()).unwrap()
    }

    /// Everett by brute-force midpoint integration of the density on a fine lattice.
    fn everett_brute(g: &PreisachGrid, alpha: f64, beta: f64, n: usize) -> f64 {
        let (lo, hi) = (g.h_min(), g.h_max());
        let d = (hi - lo) / n as f64;
        let mut s = 0.0;
        for jb in 0..n {
            let b = lo + (jb as f64 + 0.5) * d;
            if b < beta {
                continue;
            }
            for ja in jb..n {
                let a = lo + (ja as f64 + 0.5) * d;
                if a > alpha {
                    break;
                }
                let weight = if ja == jb { 0.5 } else { 1.0 };
                s += weight * g.density(g.interval(b), g.interval(a)) * d * d;
            }
        }
        s
    }

    #[test]
    fn everett_matches_brute_force_and_total() {
        let g = grid();
        assert!((g.everett(g.h_max(), g.h_min()) - g.total_mass()).abs() < 1e-6 * g.total_mass());
        for (a, b) in [
            (12_345.0, -7_777.0),
            (2_000.0, 1_000.0),
            (29_000.0, 28_500.0),
        ] {
            let exact = g.everett(a, b);
            // Lattice of 2400 points: the midpoint rule on piecewise-constant densities errs only
            // where lattice squares straddle a cell edge or the limits: O(1/n) relative.
            let brute = everett_brute(&g, a, b, 2400);
            assert!(
                (exact - brute).abs() <= 2e-3 * g.total_mass().max(exact),
                "E({a}, {b}) = {exact} vs {brute}"
            );
        }
    }

    #[test]
    fn slopes_are_derivatives_of_the_everett_function() {
        let g = grid();
        let (m, h, dh) = (-3_210.0, 9_876.0, 1e-2);
        let num = 2.0 * (g.everett(h + dh, m) - g.everett(h - dh, m)) / (2.0 * dh);
        assert!((g.rising_slope(m, h) - num).abs() < 1e-6 * num.abs().max(1.0));
        let big_m = 17_000.0;
        let num = 2.0 * (g.everett(big_m, h - dh) - g.everett(big_m, h + dh)) / (2.0 * dh);
        assert!((g.falling_slope(big_m, h) - num).abs() < 1e-6 * num.abs().max(1.0));
    }

    #[test]
    fn major_loop_saturates_and_wipes_out() {
        let g = grid();
        let mut m = PreisachMemory::negative_saturation(&g);
        assert!((m.output_a_per_m(&g) + g.total_mass()).abs() < 1e-9);
        m.move_to(&g, 5_000.0);
        m.move_to(&g, -2_000.0);
        let inner = m.output_a_per_m(&g);
        m.move_to(&g, 3_000.0);
        m.move_to(&g, -2_000.0);
        // Returning to a reversal point closes the minor loop (wiping-out).
        assert!((m.output_a_per_m(&g) - inner).abs() < 1e-6);
        m.move_to(&g, g.h_max() + 10.0);
        assert!((m.output_a_per_m(&g) - g.total_mass()).abs() < 1e-6);
        assert_eq!(m.reversal_points().len(), 1);
    }

    #[test]
    fn slope_preview_integrates_to_the_committed_change() {
        // Integrating slope_towards along a path that crosses a reversal point gives the change
        // move_to commits (the preview follows wiping-out correctly).
        let g = grid();
        let mut m = PreisachMemory::negative_saturation(&g);
        for h in [20_000.0, -5_000.0, 8_000.0, 1_000.0] {
            m.move_to(&g, h);
        }
        for target in [12_000.0, -9_000.0, 4_000.0] {
            let start = m.output_a_per_m(&g);
            let h0 = m.input_a_per_m();
            let n = 20_000;
            let mut integral = 0.0;
            for k in 0..n {
                let h = h0 + (target - h0) * (k as f64 + 0.5) / n as f64;
                integral += m.slope_towards(&g, h) * (target - h0) / n as f64;
            }
            let mut moved = m.clone();
            moved.move_to(&g, target);
            let change = moved.output_a_per_m(&g) - start;
            assert!(
                (integral - change).abs() < 1e-3 * change.abs().max(100.0),
                "to {target}: integral {integral} vs {change}"
            );
        }
    }

    #[test]
    fn ac_demagnetized_is_near_zero_for_a_symmetric_measure_and_hugs_the_line() {
        let g = grid();
        let m = PreisachMemory::ac_demagnetized(&g, 0.0, 0.98, 1.0);
        // The default measure is symmetric about 0: the ideal demagnetized output is 0.
        assert!(
            m.output_a_per_m(&g).abs() < 2e-3 * g.total_mass(),
            "{}",
            m.output_a_per_m(&g)
        );
    }
}
