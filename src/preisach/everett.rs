//! Coefficients of the Preisach operator: the cell masses and the per-pair sums from which the
//! Everett function `T(a, b) = μ{(β, α): b <= β <= α <= a}` is evaluated exactly in O(1).
//!
//! # The Everett function of a cell-uniform density
//!
//! Write `a = J + s` and `b = I + t` (normalized input, `J, I` grid intervals, `s, t ∈ [0, 1]`).
//! For `I < J` the triangle `{b <= β <= α <= a}` covers
//! * every cell with `I < i <= j < J` fully: the corner table `C[J][I+1]`;
//! * in α-row `J`, the squares `(i, J)`, `I < i < J`, over a fraction `s`, and the diagonal
//!   triangle `(J, J)` over `{J <= β <= α <= J+s}`: fraction `s²` of its half-square;
//! * in β-column `I`, the squares `(I, j)`, `I < j < J`, over a fraction `1 - t`, and the diagonal
//!   triangle `(I, I)` over a fraction `(1 - t)²`;
//! * the corner square `(I, J)` over a fraction `s (1 - t)`.
//!
//! so `T = C[J][I+1] + s R + s² w_JJ + (1-t) K + (1-t)² w_II + s (1-t) w_IJ` with the row sum
//! `R = Σ_{I<i<J} w_iJ` and column sum `K = Σ_{I<j<J} w_Ij`, stored with `C[J][I+1]`, `w_JJ`,
//! `w_II` and `w_IJ` side by side for each pair `I < J` (one address computation per piece). For `I == J`,
//! `T = w_II (s - t)²` when `s >= t`. `T` is quadratic in `s` for fixed `b` and in `1 - t` for
//! fixed `a`: that is what makes the inverse exact.
//!
//! Cost: one evaluation is about 12 flops and 6 adjacent table loads. Error: the tables are summed
//! in f64 and rounded once to f32, so each entry is within half an ulp of the exact sum; an evaluation
//! adds at most ~8 roundings of values bounded by `Σ w`, i.e. `|ΔT| <= 8 ε Σ w` with
//! `ε = 2⁻²⁴`.

use super::grid::{cell_index, CELL_COUNT, LEVELS};

/// The table entries of one pair of grid intervals `I < J` (see the module docs), stored side by
/// side so that one address computation serves every load of a piece of the inverse.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct StripSums {
    w_jj: f32,
    w_ij: f32,
    w_ii: f32,
    /// `R = Σ_{I<i<J} w_iJ`.
    row: f32,
    /// `K = Σ_{I<j<J} w_Ij`.
    column: f32,
    /// `C[J][I+1] = Σ_{I<i<=j<J} w_ij`, the cells covered fully.
    full: f32,
}

impl StripSums {
    const ZERO: StripSums = StripSums {
        w_jj: 0.0,
        w_ij: 0.0,
        w_ii: 0.0,
        row: 0.0,
        column: 0.0,
        full: 0.0,
    };
}

/// Coefficients of `T(J + s, ·)` or `T(·, I + 1 - v)` as a quadratic `q0 + q1 u + q2 u²`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Quadratic {
    pub q0: f32,
    pub q1: f32,
    pub q2: f32,
}

impl Quadratic {
    #[inline]
    pub fn at(&self, u: f32) -> f32 {
        self.q0 + u * (self.q1 + u * self.q2)
    }
    /// Derivative at `u`.
    #[inline]
    pub fn slope(&self, u: f32) -> f32 {
        self.q1 + 2.0 * u * self.q2
    }
}

/// The Preisach measure on the fixed grid: the coefficients of the operator (`&self` everywhere;
/// the memory is the separate [`super::PreisachState`]).
///
/// Built once by [`PreisachMeasure::new`], a `const fn`: for the baked parameters the tables are
/// computed at compile time and live in flash (about 17.5 KiB: the masses, 2.5 KiB, and the
/// per-pair sums, 15 KiB).
#[derive(Debug, Clone, PartialEq)]
pub struct PreisachMeasure {
    pub(crate) h_min_a_per_m: f32,
    pub(crate) h_max_a_per_m: f32,
    /// Δ, the mean width of an input interval (the width of every interval when the grid is
    /// uniform), A/m.
    pub(crate) cell_width_a_per_m: f32,
    /// 1 / Δ.
    pub(crate) cells_per_a_per_m: f32,
    /// Whether the `LEVELS` intervals are equal (then `normalize`/`denormalize` are the affine maps
    /// through `h_min` and Δ, bit for bit those of a grid built without lines).
    pub(crate) uniform: bool,
    /// The `LEVELS + 1` grid lines, A/m (`lines[0] = h_min`, `lines[LEVELS] = h_max`).
    pub(crate) lines_a_per_m: [f32; LEVELS + 1],
    /// Width of each interval, A/m (all equal to Δ on a uniform grid).
    pub(crate) widths_a_per_m: [f32; LEVELS],
    /// 1 / width of each interval.
    pub(crate) inverse_widths_per_a_per_m: [f32; LEVELS],
    /// Σ w, the saturation output of the hysteretic part, A/m.
    pub(crate) total_a_per_m: f32,
    /// `Σ w − M_off`: the output is `M = 2 μ(P₊) − bias (+ R)`. Equal to `Σ w` without an
    /// offset (the same f32, so such a measure is bit for bit the one built without it).
    pub(crate) output_bias_a_per_m: f32,
    /// `M_off`, the magnetization of the part of the Preisach plane the coil never switches
    /// (see [`PreisachMeasure::with_offset`]), A/m.
    pub(crate) offset_a_per_m: f32,
    /// Largest mass per unit normalized area over all cells (triangles count double), A/m.
    pub(crate) max_density_a_per_m: f32,
    /// `w[j][i]` = mass of cell `(i, j)` for `i <= j`, 0 otherwise.
    pub(crate) w: [[f32; LEVELS]; LEVELS],
    /// `strips[J][I]`: the sums of the pair `I < J` (zero for `I >= J`), each summed in f64 and
    /// rounded once.
    pub(crate) strips: [[StripSums; LEVELS]; LEVELS],
    /// The reversible part `R` at the grid lines (normalized input `k`), A/m (all 0 without one).
    pub(crate) reversible_at_line_a_per_m: [f32; LEVELS + 1],
    /// `ρ_k = χ_k · width_k`, the change of `R` across interval `k` (its slope per unit of
    /// normalized input), A/m.
    pub(crate) reversible_rise_a_per_m: [f32; LEVELS],
    /// The susceptibilities `χ_k` the reversible part was built from (dimensionless).
    pub(crate) reversible_susceptibility: [f32; LEVELS],
    /// `Σ w + ½ Σ ρ`: the output at positive saturation (minus it at negative), A/m.
    pub(crate) saturation_a_per_m: f32,
    /// Whether any `χ_k` is nonzero (the solve's reversible terms are compiled out otherwise).
    pub(crate) has_reversible: bool,
}

impl PreisachMeasure {
    /// Builds the coefficients from the cell masses (alpha-major order, A/m) and the field range.
    ///
    /// The caller guarantees what `build.rs` / `actuator-params` validate: masses finite and
    /// `>= 0`, `h_min < h_max`, finite. (Violations give a meaningless but panic-free operator.)
    pub const fn new(
        weights_a_per_m: &[f32; CELL_COUNT],
        h_min_a_per_m: f32,
        h_max_a_per_m: f32,
    ) -> Self {
        Self::build(weights_a_per_m, h_min_a_per_m, h_max_a_per_m, None)
    }

    /// Builds the coefficients on a grid with the given lines (`LEVELS + 1` strictly increasing
    /// finite fields, A/m; the first and last are the range): the density is uniform in each
    /// cell *in the field*, so in the normalized input `x` (interval `k` mapped affinely onto
    /// `[k, k + 1]`) the cells are the unit cells of the uniform grid and every table, the
    /// forward update and the exact inverse stay as they are; only the maps between `h` and `x`
    /// become piecewise affine. Lines whose intervals all round to the same f32 width as Δ give exactly
    /// [`PreisachMeasure::new`].
    ///
    /// The caller guarantees what `actuator-params` validates (increasing, finite).
    pub const fn with_lines(
        weights_a_per_m: &[f32; CELL_COUNT],
        lines_a_per_m: &[f32; LEVELS + 1],
    ) -> Self {
        Self::build(
            weights_a_per_m,
            lines_a_per_m[0],
            lines_a_per_m[LEVELS],
            Some(lines_a_per_m),
        )
    }

    const fn build(
        weights_a_per_m: &[f32; CELL_COUNT],
        h_min_a_per_m: f32,
        h_max_a_per_m: f32,
        lines: Option<&[f32; LEVELS + 1]>,
    ) -> Self {
        let mut w64 = [[0.0f64; LEVELS]; LEVELS];
        let mut w = [[0.0f32; LEVELS]; LEVELS];
        let mut total = 0.0f64;
        let mut max_density = 0.0f64;
        let mut j = 0;
        while j < LEVELS {
            let mut i = 0;
            while i <= j {
                let m = weights_a_per_m[cell_index(i, j)] as f64;
                w64[j][i] = m;
                w[j][i] = m as f32;
                total += m;
                let density = if i == j { 2.0 * m } else { m };
                if density > max_density {
                    max_density = density;
                }
                i += 1;
            }
            j += 1;
        }
        // corner[J][I] = Σ_{I <= i <= j < J} w_ij, by rows: corner[J][I] = corner[J-1][I] + Σ_{I<=i<=J-1} w[J-1][i].
        let mut corner64 = [[0.0f64; LEVELS + 1]; LEVELS + 1];
        let mut big_j = 1;
        while big_j <= LEVELS {
            let mut big_i = 0;
            while big_i <= big_j {
                let mut row = 0.0f64;
                let mut i = big_i;
                while i < big_j {
                    row += w64[big_j - 1][i];
                    i += 1;
                }
                let above = if big_i < big_j {
                    corner64[big_j - 1][big_i]
                } else {
                    0.0
                };
                corner64[big_j][big_i] = above + row;
                big_i += 1;
            }
            big_j += 1;
        }
        let mut strips = [[StripSums::ZERO; LEVELS]; LEVELS];
        let mut big_j = 1;
        while big_j < LEVELS {
            let mut big_i = 0;
            while big_i < big_j {
                let mut row = 0.0f64;
                let mut column = 0.0f64;
                let mut k = big_i + 1;
                while k < big_j {
                    row += w64[big_j][k];
                    column += w64[k][big_i];
                    k += 1;
                }
                strips[big_j][big_i] = StripSums {
                    w_jj: w[big_j][big_j],
                    w_ij: w[big_j][big_i],
                    w_ii: w[big_i][big_i],
                    row: row as f32,
                    column: column as f32,
                    full: corner64[big_j][big_i + 1] as f32,
                };
                big_i += 1;
            }
            big_j += 1;
        }
        let width = (h_max_a_per_m as f64 - h_min_a_per_m as f64) / LEVELS as f64;
        // The lines: given, or equally spaced (each interval then has width Δ exactly as f32,
        // so `a · width[k]` equals `a · Δ` bit for bit).
        let mut lines_a_per_m = [0.0f32; LEVELS + 1];
        let mut widths_a_per_m = [width as f32; LEVELS];
        let mut inverse_widths_per_a_per_m = [(1.0 / width) as f32; LEVELS];
        let mut uniform = true;
        let mut k = 0;
        while k <= LEVELS {
            lines_a_per_m[k] = match lines {
                Some(given) => given[k],
                None => (h_min_a_per_m as f64 + k as f64 * width) as f32,
            };
            k += 1;
        }
        lines_a_per_m[0] = h_min_a_per_m;
        lines_a_per_m[LEVELS] = h_max_a_per_m;
        if let Some(given) = lines {
            let mut k = 0;
            while k < LEVELS {
                let w = given[k + 1] as f64 - given[k] as f64;
                if (w as f32).to_bits() != (width as f32).to_bits() {
                    uniform = false;
                }
                widths_a_per_m[k] = w as f32;
                inverse_widths_per_a_per_m[k] = (1.0 / w) as f32;
                k += 1;
            }
            if uniform {
                widths_a_per_m = [width as f32; LEVELS];
                inverse_widths_per_a_per_m = [(1.0 / width) as f32; LEVELS];
            }
        }
        PreisachMeasure {
            h_min_a_per_m,
            h_max_a_per_m,
            cell_width_a_per_m: width as f32,
            cells_per_a_per_m: (1.0 / width) as f32,
            uniform,
            lines_a_per_m,
            widths_a_per_m,
            inverse_widths_per_a_per_m,
            total_a_per_m: total as f32,
            output_bias_a_per_m: total as f32,
            offset_a_per_m: 0.0,
            max_density_a_per_m: max_density as f32,
            w,
            strips,
            reversible_at_line_a_per_m: [0.0; LEVELS + 1],
            reversible_rise_a_per_m: [0.0; LEVELS],
            reversible_susceptibility: [0.0; LEVELS],
            saturation_a_per_m: total as f32,
            has_reversible: false,
        }
    }

    /// Adds the reversible (anhysteretic) part `R(h) = Σ_k χ_k (clamp(h, l_k, l_{k+1}) − m_k)`
    /// (`l_k` the grid lines, `m_k` the middle of interval `k`, `χ_k >= 0` the susceptibility
    /// `dR/dh` on interval `k`): monotone, piecewise linear with kinks at the grid lines, odd
    /// about the middle of the range when the `χ_k` are symmetric, flat beyond the grid. The
    /// output becomes `M = Γ[h] + R(h)` — the paper's `M = Γ[H]` generalized, a constant
    /// `χ_r` giving the familiar `Γ[H] + χ_r H` on a symmetric grid.
    ///
    /// Why the kinks sit on the grid lines: in the normalized input `R` is then affine on each
    /// interval, `R(k + s) = R_k + ρ_k s`, so along a monotone path the output stays piecewise
    /// quadratic with the same pieces as `Γ` alone — forward, exact inverse and the solve keep
    /// their closed forms (the piece's linear coefficient gains `ρ_k`).
    ///
    /// The caller guarantees what `actuator-params` validates: every `χ_k` finite and `>= 0`.
    /// All zero gives exactly the measure without a reversible part.
    pub const fn with_reversible(mut self, susceptibility: &[f32; LEVELS]) -> Self {
        let mut rise = [0.0f64; LEVELS];
        let mut total_rise = 0.0f64;
        let mut k = 0;
        while k < LEVELS {
            let width = self.lines_a_per_m[k + 1] as f64 - self.lines_a_per_m[k] as f64;
            rise[k] = susceptibility[k] as f64 * width;
            total_rise += rise[k];
            self.reversible_rise_a_per_m[k] = rise[k] as f32;
            self.reversible_susceptibility[k] = susceptibility[k];
            if susceptibility[k] != 0.0 {
                self.has_reversible = true;
            }
            k += 1;
        }
        // R at line k: the rises below it minus half of all of them (each summed in f64 and
        // rounded once).
        let mut below = 0.0f64;
        let mut k = 0;
        while k <= LEVELS {
            self.reversible_at_line_a_per_m[k] = (below - 0.5 * total_rise) as f32;
            if k < LEVELS {
                below += rise[k];
            }
            k += 1;
        }
        self.saturation_a_per_m = (self.total_a_per_m as f64 + 0.5 * total_rise) as f32;
        self
    }

    /// Adds a constant magnetization `M_off` to the output: `M = Γ[h] + M_off`.
    ///
    /// On a rod the coil cannot saturate, the field stays in the reach `[H_lo, H_hi]`. The
    /// hysterons with `α > H_hi` and `β < H_lo` never switch, those with both thresholds beyond
    /// one end switch once at the first input and then stay; the grid's outermost intervals hold
    /// the one-way bands (`β < H_lo`: can only switch up; `α > H_hi`: only down), and what is
    /// left is a constant, `M_off` (docs/model.md, "Rods the coil cannot saturate"). Only the
    /// output moves: the forward update, the exact inverse and the solve see `2 μ(P₊) − (Σ w −
    /// M_off)` and stay exact. `M_off = 0` gives the measure without an offset, bit for bit.
    ///
    /// The caller guarantees what `actuator-params` validates: `M_off` finite.
    pub const fn with_offset(mut self, offset_a_per_m: f32) -> Self {
        self.offset_a_per_m = offset_a_per_m;
        self.output_bias_a_per_m = (self.total_a_per_m as f64 - offset_a_per_m as f64) as f32;
        self
    }

    /// `M_off`, the constant magnetization of the part of the plane the coil never switches, A/m
    /// (0 without one).
    pub fn offset_a_per_m(&self) -> f32 {
        self.offset_a_per_m
    }

    /// The output at negative and at positive saturation of the grid, A/m:
    /// `M_off ∓ (Σ w + ½ Σ ρ)`.
    pub fn output_range_a_per_m(&self) -> (f32, f32) {
        (
            self.offset_a_per_m - self.saturation_a_per_m,
            self.offset_a_per_m + self.saturation_a_per_m,
        )
    }

    /// Lower end of the field range, A/m.
    pub fn h_min_a_per_m(&self) -> f32 {
        self.h_min_a_per_m
    }
    /// Upper end of the field range, A/m.
    pub fn h_max_a_per_m(&self) -> f32 {
        self.h_max_a_per_m
    }
    /// Mean width Δ = (h_max − h_min) / 25 of a grid interval (the width of every interval on a
    /// uniform grid), A/m.
    pub fn cell_width_a_per_m(&self) -> f32 {
        self.cell_width_a_per_m
    }
    /// Width of interval `k` (clamped into the grid), A/m.
    pub fn interval_width_a_per_m(&self, k: usize) -> f32 {
        self.widths_a_per_m[k.min(LEVELS - 1)]
    }
    /// The smallest interval width, A/m (Δ on a uniform grid).
    pub fn narrowest_interval_a_per_m(&self) -> f32 {
        let mut narrowest = self.widths_a_per_m[0];
        for &w in self.widths_a_per_m.iter() {
            narrowest = crate::select::min_f32(narrowest, w);
        }
        narrowest
    }
    /// The largest interval width, A/m (Δ on a uniform grid).
    pub fn widest_interval_a_per_m(&self) -> f32 {
        let mut widest = self.widths_a_per_m[0];
        for &w in self.widths_a_per_m.iter() {
            widest = crate::select::max_f32(widest, w);
        }
        widest
    }
    /// The `LEVELS + 1` grid lines, A/m.
    pub fn grid_lines_a_per_m(&self) -> &[f32; LEVELS + 1] {
        &self.lines_a_per_m
    }
    /// Whether the intervals are equal.
    pub fn is_uniform(&self) -> bool {
        self.uniform
    }
    /// Saturation output: `Σ w` plus the reversible part at the top of the grid, A/m (the output
    /// at negative saturation is minus it; with an offset both move by `M_off`, see
    /// [`PreisachMeasure::output_range_a_per_m`]).
    pub fn saturation_a_per_m(&self) -> f32 {
        self.saturation_a_per_m
    }
    /// `Σ w`, the hysteretic part's saturation output, A/m.
    pub fn hysteretic_saturation_a_per_m(&self) -> f32 {
        self.total_a_per_m
    }
    /// The reversible part's susceptibility on each grid interval (all 0 without one).
    pub fn reversible_susceptibility(&self) -> &[f32; LEVELS] {
        &self.reversible_susceptibility
    }
    /// The reversible part `R(h)`, A/m (the field clamped to the grid: flat beyond it).
    pub fn reversible_a_per_m(&self, h_a_per_m: f32) -> f32 {
        self.reversible_at(self.normalize(h_a_per_m))
    }
    /// `R` at normalized input `x ∈ [0, LEVELS]`.
    #[inline(always)]
    pub(crate) fn reversible_at(&self, x: f32) -> f32 {
        self.reversible_in(x, split(x).0)
    }
    /// `R` at normalized input `x` known to lie in interval `k` (`k <= x <= k + 1`):
    /// `R_k + ρ_k (x − k)`.
    #[inline(always)]
    pub(crate) fn reversible_in(&self, x: f32, k: usize) -> f32 {
        let k = k.min(LEVELS - 1);
        self.reversible_at_line_a_per_m[k] + self.reversible_rise_a_per_m[k] * (x - k as f32)
    }
    /// `ρ_k`, the change of `R` across interval `k`, A/m (its slope in normalized input).
    #[inline(always)]
    pub(crate) fn reversible_rise(&self, k: usize) -> f32 {
        self.reversible_rise_a_per_m[k.min(LEVELS - 1)]
    }
    /// Largest mass per unit of normalized cell area (diagonal triangles count their mass twice,
    /// since their area is 1/2), A/m.
    pub fn max_density_a_per_m(&self) -> f32 {
        self.max_density_a_per_m
    }
    /// Mass of cell `(i, j)`, A/m (0 outside the grid or below the diagonal).
    pub fn cell_mass_a_per_m(&self, i: usize, j: usize) -> f32 {
        if i <= j && j < LEVELS {
            self.w[j][i]
        } else {
            0.0
        }
    }

    /// Normalized input of field `h` (A/m), clamped to `[0, LEVELS]`. NaN maps to 0; callers
    /// reject non-finite inputs before.
    #[inline]
    pub(crate) fn normalize(&self, h_a_per_m: f32) -> f32 {
        if self.uniform {
            let x = (h_a_per_m - self.h_min_a_per_m) * self.cells_per_a_per_m;
            return x.clamp(0.0, LEVELS as f32);
        }
        // Below the range, and NaN (callers reject non-finite inputs before): the bottom.
        if h_a_per_m <= self.h_min_a_per_m || h_a_per_m.is_nan() {
            return 0.0;
        }
        if h_a_per_m >= self.h_max_a_per_m {
            return LEVELS as f32;
        }
        // The interval holding h: lines[k] <= h < lines[k + 1], by bisection (5 halvings).
        let (mut lo, mut hi) = (0usize, LEVELS);
        while hi - lo > 1 {
            let mid = (lo + hi) / 2;
            if h_a_per_m >= self.lines_a_per_m[mid.min(LEVELS)] {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        let k = lo.min(LEVELS - 1);
        let s = (h_a_per_m - self.lines_a_per_m[k]) * self.inverse_widths_per_a_per_m[k];
        (k as f32 + crate::select::clamp_f32(s, 0.0, 1.0)).clamp(0.0, LEVELS as f32)
    }

    /// Field (A/m) at normalized input `x`.
    #[inline]
    pub(crate) fn denormalize(&self, x: f32) -> f32 {
        if self.uniform {
            return self.h_min_a_per_m + x * self.cell_width_a_per_m;
        }
        let (k, s) = split(x);
        self.lines_a_per_m[k.min(LEVELS - 1)] + s * self.widths_a_per_m[k.min(LEVELS - 1)]
    }

    /// Field (A/m) at normalized input `x` known to lie in interval `k` (`k <= x <= k + 1`):
    /// [`PreisachMeasure::denormalize`] without the split (the inverse knows the piece's
    /// interval).
    #[inline(always)]
    pub(crate) fn denormalize_in(&self, x: f32, k: usize) -> f32 {
        if self.uniform {
            return self.h_min_a_per_m + x * self.cell_width_a_per_m;
        }
        let k = k.min(LEVELS - 1);
        self.lines_a_per_m[k] + (x - k as f32) * self.widths_a_per_m[k]
    }

    /// Everett function `T(a, b) = μ{b <= β <= α <= a}` for normalized `a, b ∈ [0, LEVELS]`
    /// (0 when `a <= b`).
    #[inline]
    pub(crate) fn everett(&self, a: f32, b: f32) -> f32 {
        if a <= b {
            return 0.0;
        }
        let (big_j, s) = split(a);
        let (big_i, t) = split(b);
        self.quadratic_in_alpha(big_j, big_i, t).at(s)
    }

    /// The table entries of the pair `I < J` shared by both quadratic forms (see the module
    /// docs). The indices are clamped into the table, so the optimizer can drop all bounds checks
    /// (the firmware's link-time no-panic proof relies on it).
    #[inline(always)]
    fn strip_sums(&self, big_j: usize, big_i: usize) -> StripSums {
        self.strips[big_j.min(LEVELS - 1)][big_i.min(LEVELS - 1)]
    }

    /// `T(J + s, I + t)` as a quadratic in `s` (fixed `b = I + t`), valid for `J + s >= I + t`.
    #[inline]
    pub(crate) fn quadratic_in_alpha(&self, big_j: usize, big_i: usize, t: f32) -> Quadratic {
        let big_j = big_j.min(LEVELS - 1);
        let big_i = big_i.min(LEVELS - 1);
        if big_i > big_j {
            return Quadratic {
                q0: 0.0,
                q1: 0.0,
                q2: 0.0,
            };
        }
        let w_ii = self.w[big_i][big_i];
        if big_i == big_j {
            // T = w (s - t)² = w t² - 2 w t s + w s².
            return Quadratic {
                q0: w_ii * t * t,
                q1: -2.0 * w_ii * t,
                q2: w_ii,
            };
        }
        let one_minus_t = 1.0 - t;
        let p = self.strip_sums(big_j, big_i);
        Quadratic {
            q0: p.full + one_minus_t * (p.column + one_minus_t * p.w_ii),
            q1: p.row + one_minus_t * p.w_ij,
            q2: p.w_jj,
        }
    }

    /// `T(J + s, I + 1 - v)` as a quadratic in `v` (fixed `a = J + s`), valid for
    /// `I + 1 - v <= J + s`.
    #[inline]
    pub(crate) fn quadratic_in_beta(&self, big_j: usize, s: f32, big_i: usize) -> Quadratic {
        let big_j = big_j.min(LEVELS - 1);
        let big_i = big_i.min(LEVELS - 1);
        if big_i > big_j {
            return Quadratic {
                q0: 0.0,
                q1: 0.0,
                q2: 0.0,
            };
        }
        let w_ii = self.w[big_i][big_i];
        if big_i == big_j {
            // T = w (s - t)², t = 1 - v: w (v - (1 - s))².
            let c = 1.0 - s;
            return Quadratic {
                q0: w_ii * c * c,
                q1: -2.0 * w_ii * c,
                q2: w_ii,
            };
        }
        let p = self.strip_sums(big_j, big_i);
        Quadratic {
            q0: p.full + s * (p.row + s * p.w_jj),
            q1: p.column + s * p.w_ij,
            q2: p.w_ii,
        }
    }
}

/// Splits a normalized input into its grid interval and the offset inside it:
/// `x = J + s`, `J ∈ [0, LEVELS - 1]`, `s ∈ [0, 1]` (`x = LEVELS` gives `J = LEVELS - 1, s = 1`).
#[inline]
pub(crate) fn split(x: f32) -> (usize, f32) {
    // `as` saturates: negative and NaN give 0, never a panic.
    let j = (x as usize).min(LEVELS - 1);
    (j, x - j as f32)
}

/// Splits for a path going down: `x = I + t` with `t ∈ (0, 1]` where possible, so that the interval
/// below an integer `x` is the one entered next.
#[inline]
pub(crate) fn split_down(x: f32) -> (usize, f32) {
    // ⌈x⌉ - 1 from the truncation (`as` saturates: negative and NaN give 0), capped before the
    // `+ 1` so that it cannot overflow; `libm::ceilf` is a software routine on the M4F.
    let floor = (x as usize).min(LEVELS);
    let ceil = if (floor as f32) < x { floor + 1 } else { floor };
    let i = ceil.saturating_sub(1).min(LEVELS - 1);
    (i, x - i as f32)
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::{split_down, LEVELS};
    use std::vec;

    /// `split_down` equals its definition through `ceil` (`I = ⌈x⌉ - 1` clamped to the grid) on
    /// a sweep of the range with every grid line and its f32 neighbours, and beyond the range.
    #[test]
    fn split_down_is_ceil_minus_one() {
        let by_ceil = |x: f32| -> usize {
            let c = libm::ceilf(x);
            if c >= 1.0 {
                (c as usize - 1).min(LEVELS - 1)
            } else {
                0
            }
        };
        let mut inputs = vec![-1.0f32, -0.0, 0.0, 1.0e-30, 26.0, 1.0e30, f32::NAN];
        for k in 0..=LEVELS {
            let x = k as f32;
            inputs.extend([x, f32::from_bits(x.to_bits() + 1), x - x * f32::EPSILON]);
        }
        inputs.extend((0..2500).map(|k| k as f32 * 0.0101));
        for x in inputs {
            let (i, t) = split_down(x);
            assert_eq!(i, by_ceil(x), "x = {x}");
            if (0.0..=LEVELS as f32).contains(&x) {
                assert_eq!(t, x - i as f32);
            }
        }
    }
}
