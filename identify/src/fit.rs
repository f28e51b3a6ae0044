//! The cell masses by constrained, regularized least squares (paper Section 4, after its
//! reference \[5\]), solved as a convex QP with `clarabel`.
//!
//! Unknowns, in units of the output scale `s` (the output range of the fit rows, so that the
//! problem is well scaled whatever the units): the masses `w̃ = w / s` and, optionally, the affine
//! part `c̃₀ + c̃₁ (x / L - ½)`. The objective is
//!
//! `J = (1/n) ‖A z - b̃‖² + λ_s S(w̃) + λ_r R(w̃)`
//!
//! * data term: mean squared residual relative to the output range (`b̃ = y / s`);
//! * smoothness `S = (1/N_p) Σ_{neighbours a,b} ((ρ_a - ρ_b) / ρ_ref)²` over the cell densities
//!   `ρ_k = w̃_k / area_k` (area 1 for squares, ½ for the diagonal half-squares), `N_p` pairs of
//!   cells sharing an edge, `ρ_ref = 1 / L²` the mean density of a measure whose output range is
//!   the data's (`Σ w̃ = ½` over the triangle of area `L²/2`). `λ_s = 1e-4` thus weighs a density
//!   jump of 100 % between *every* pair of neighbours like a residual of 1 % RMS of the range.
//! * ridge `R = (1/K) Σ_k ((ρ_k - ρ_k^prior) / ρ_ref)²` toward a prior (the base weights when
//!   given, else zero).
//!
//! subject to `w̃ >= 0` (a Preisach measure is non-negative: Theorem 1's monotonicity and order
//! preservation rely on it) and to `w̃_k` fixed for the unexcited cells when [`Unexcited`] says so.

use crate::design::{Design, Experiment, Grid};
use crate::{cell_index, CELL_COUNT, LEVELS};
use clarabel::algebra::CscMatrix;
use clarabel::solver::{
    DefaultSettingsBuilder, DefaultSolver, IPSolver, NonnegativeConeT, SolverStatus,
    SupportedConeT, ZeroConeT,
};
use std::fmt;

/// What to do with cells the data did not excite (their regressor is constant).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Unexcited {
    /// Fix them at the prior (base) weights. Needs a prior.
    KeepPrior,
    /// Fix them at zero.
    Zero,
    /// Leave them to the regularization (needs `λ_s > 0` or `λ_r > 0`): smoothness extends the
    /// neighbouring excited densities into them, the ridge pulls them to the prior.
    Regularized,
}

impl Unexcited {
    /// CLI names.
    pub const NAMES: [(&'static str, Unexcited); 3] = [
        ("keep-prior", Unexcited::KeepPrior),
        ("zero", Unexcited::Zero),
        ("regularized", Unexcited::Regularized),
    ];

    /// Parses a CLI name.
    pub fn parse(text: &str) -> Result<Self, String> {
        Self::NAMES
            .iter()
            .find(|(n, _)| *n == text)
            .map(|(_, u)| *u)
            .ok_or_else(|| {
                format!(
                    "unknown treatment `{text}`; expected one of {}",
                    Self::NAMES.map(|(n, _)| n).join(", ")
                )
            })
    }

    /// The CLI name.
    pub fn name(self) -> &'static str {
        Self::NAMES
            .iter()
            .find(|(_, u)| *u == self)
            .map_or("?", |(n, _)| n)
    }
}

/// The reversible (anhysteretic) part of the output, fitted in the same least squares as the
/// masses, each with an output offset.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Reversible {
    /// The masses alone (no offset, no reversible part).
    None,
    /// `offset + slope · ĥ(input)`, one slope of either sign, continued beyond the grid (`ĥ`:
    /// [`crate::design::Grid::equivalent_input`]; the input itself on equal intervals).
    Linear,
    /// `offset + Σ_k χ_k (clamp(input, line_k, line_{k+1}) - mid_k)`: a monotone piecewise-linear
    /// anhysteretic curve with a free slope `χ_k >= 0` on each grid interval (kinks at the grid
    /// lines, flat beyond the grid), smoothed like the densities (see the module docs). The
    /// actuator model's reversible magnetization (`preisach.reversible_susceptibility`).
    Piecewise,
    /// [`Reversible::Piecewise`] without the offset: the actuator's `M = Γ[H] + R(H)`, whose
    /// parameter file has no output offset (`maglab identify` on a rod the coil saturates).
    PiecewiseNoOffset,
    /// The masses and an output offset, no reversible part: the actuator's
    /// `M = Γ[H] + M_off` on a rod the coil cannot saturate (`preisach.offset_a_per_m`).
    Offset,
}

impl Reversible {
    /// CLI names.
    pub const NAMES: [(&'static str, Reversible); 5] = [
        ("none", Reversible::None),
        ("linear", Reversible::Linear),
        ("piecewise", Reversible::Piecewise),
        ("piecewise-no-offset", Reversible::PiecewiseNoOffset),
        ("offset", Reversible::Offset),
    ];

    /// Parses a CLI name.
    pub fn parse(text: &str) -> Result<Self, String> {
        Self::NAMES
            .iter()
            .find(|(n, _)| *n == text)
            .map(|(_, r)| *r)
            .ok_or_else(|| {
                format!(
                    "unknown reversible part `{text}`; expected one of {}",
                    Self::NAMES.map(|(n, _)| n).join(", ")
                )
            })
    }

    /// The CLI name.
    pub fn name(self) -> &'static str {
        Self::NAMES
            .iter()
            .find(|(_, r)| *r == self)
            .map_or("?", |(n, _)| n)
    }

    /// Unknowns after the masses: offset and slope(s).
    pub fn unknowns(self) -> usize {
        match self {
            Reversible::None => 0,
            Reversible::Linear => 2,
            Reversible::Piecewise => 1 + LEVELS,
            Reversible::PiecewiseNoOffset => LEVELS,
            Reversible::Offset => 1,
        }
    }

    /// The same part with an output offset (`none` → `offset`, `piecewise-no-offset` →
    /// `piecewise`; the others have one).
    pub fn with_offset(self) -> Self {
        match self {
            Reversible::None => Reversible::Offset,
            Reversible::PiecewiseNoOffset => Reversible::Piecewise,
            other => other,
        }
    }

    /// Whether the part has an output offset (the unknown right after the masses).
    pub fn has_offset(self) -> bool {
        matches!(
            self,
            Reversible::Linear | Reversible::Piecewise | Reversible::Offset
        )
    }

    /// Whether the part has a slope per grid interval.
    pub fn is_piecewise(self) -> bool {
        matches!(self, Reversible::Piecewise | Reversible::PiecewiseNoOffset)
    }

    /// Index of the first piecewise slope among the unknowns.
    pub fn first_slope(self) -> usize {
        match self {
            Reversible::PiecewiseNoOffset => CELL_COUNT,
            _ => CELL_COUNT + 1,
        }
    }
}

/// Options of the fit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FitOptions {
    /// λ_s, smoothness weight (dimensionless, see the module docs).
    pub smoothness: f64,
    /// λ_r, ridge weight toward the prior.
    pub ridge: f64,
    /// The reversible part fitted jointly with the masses (with an output offset), see
    /// [`Reversible`].
    pub reversible: Reversible,
    /// Treatment of unexcited cells.
    pub unexcited: Unexcited,
    /// Keep every n-th selected row in the regression (1 = all).
    pub row_stride: usize,
    /// An upper bound on the sum of the masses (output units): the Preisach operator's output
    /// at saturation. An actuator's masses sum to at most its saturation magnetization `M_s`
    /// (the paper's `M = Γ[H]`, `|M| <= M_s`); without the bound, output beyond it (a reversible
    /// part, a sensor reading high) is absorbed into masses summing past `M_s` instead of being
    /// left in the residual for the diagnosis. `None`: no bound.
    pub total_mass_at_most: Option<f64>,
    /// Which outer intervals of the grid are one-way bands (a grid around the reach of a coil
    /// that cannot saturate the rod, [`crate::reach`]).
    pub bands: Bands,
}

/// The grid's outer intervals that collapse the Preisach plane beyond the coil's reach: the
/// bottom interval holds every hysteron with `β < H_lo` (row `i = 0`: it can only switch up),
/// the top one every hysteron with `α > H_hi` (column `j = L − 1`: only down).
///
/// A band cell's mass is the mass of a whole region of the plane, not a density that varies
/// smoothly from its neighbours': band cells stay out of the smoothness term. A band cell the
/// data never switch (the corner `(0, L − 1)` always: no reachable field switches it) cannot be
/// told from the output offset, which carries it: such cells are fixed at 0. A band cell counts
/// as excited only when the fit rows switch at least [`BAND_EXCITATION`] of it: its mass is seen
/// only through that part, `δw ≈ σ / (2 Δf)` for a residual σ, so with the fit's residual of
/// about 1 % of the output range a smaller `Δf` would let the mass take any value up to `M_s`,
/// balanced by the offset.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Bands {
    /// Row 0 is the band `β < H_lo`.
    pub low: bool,
    /// Column `L − 1` is the band `α > H_hi`.
    pub high: bool,
}

/// The regressor range (`2 Δf`, `Δf` the switched fraction) below which a band cell is taken as
/// unexcited: `Δf` = 1 % of the cell ([`Bands`]).
pub const BAND_EXCITATION: f64 = 0.02;

impl Bands {
    /// Whether cell `k` (alpha-major) lies in a band.
    pub fn contains(self, k: usize) -> bool {
        let (i, j) = crate::cell_of_index(k);
        (self.low && i == 0) || (self.high && j == LEVELS - 1)
    }
}

impl Default for FitOptions {
    fn default() -> Self {
        FitOptions {
            smoothness: 1e-6,
            ridge: 0.0,
            reversible: Reversible::None,
            unexcited: Unexcited::Regularized,
            row_stride: 1,
            total_mass_at_most: None,
            bands: Bands::default(),
        }
    }
}

/// The fitted masses and affine part, with diagnostics.
#[derive(Debug, Clone, PartialEq)]
pub struct FitResult {
    /// Cell masses (output units), alpha-major.
    pub weights: Vec<f64>,
    /// Affine offset (output units); 0 without the affine part.
    pub offset: f64,
    /// Affine slope (output units per input unit); 0 unless [`Reversible::Linear`].
    pub slope: f64,
    /// The slope `χ_k` on each grid interval (output units per input unit) of
    /// [`Reversible::Piecewise`]; empty otherwise.
    pub reversible_slopes: Vec<f64>,
    /// Cells the fit rows did not excite (alpha-major indices).
    pub unexcited: Vec<usize>,
    /// What was done with them.
    pub unexcited_treatment: Unexcited,
    /// Rows in the regression.
    pub rows: usize,
    /// Selected rows left out by the row stride.
    pub strided_out: usize,
    /// RMS residual over the regression rows (output units).
    pub rms_residual: f64,
    /// The output scale `s` (range of the fit outputs).
    pub output_scale: f64,
    /// Samples outside the grid (clamped = saturated memory), per experiment.
    pub outside: Vec<(String, usize)>,
    /// Solver status and iteration count.
    pub solver: String,
}

/// A fit that cannot be done.
#[derive(Debug, Clone, PartialEq)]
pub struct FitError(pub String);

impl fmt::Display for FitError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for FitError {}

/// Smallest smoothness weight of the piecewise reversible part's slopes: an interval the data
/// never cross leaves its ramp constant, and the smoothing then carries its neighbours' slope in.
pub const REVERSIBLE_SMOOTHNESS_MIN: f64 = 1e-6;

/// Area of cell `k` in normalized units.
fn cell_area(k: usize) -> f64 {
    let (i, j) = crate::cell_of_index(k);
    if i == j {
        0.5
    } else {
        1.0
    }
}

/// Pairs of cells sharing an edge.
pub fn neighbour_pairs() -> Vec<(usize, usize)> {
    let mut pairs = Vec::new();
    for j in 0..LEVELS {
        for i in 0..=j {
            if i < j {
                pairs.push((cell_index(i, j), cell_index(i + 1, j)));
            }
            if j + 1 < LEVELS {
                pairs.push((cell_index(i, j), cell_index(i, j + 1)));
            }
        }
    }
    pairs
}

/// Fits the masses on `grid` to `experiments`. `prior` (output units, 325 masses) is the ridge
/// target and the value of unexcited cells under [`Unexcited::KeepPrior`].
pub fn fit(
    grid: &Grid,
    experiments: &[Experiment<'_>],
    prior: Option<&[f64]>,
    options: &FitOptions,
) -> Result<FitResult, FitError> {
    check_inputs(grid, prior, options)?;
    let scale = output_scale(experiments)?;
    let design = Design::build(
        grid,
        experiments,
        options.reversible,
        scale,
        options.row_stride,
    );
    let unexcited = design.unexcited_with_bands(options.bands);
    let n = design.unknowns;
    let (h, g) = quadratic_form(grid, &design, prior, options, scale);
    let (p, q) = objective(&h, &g, n);
    let fixed = fixed_cells(&unexcited, prior, options, scale);
    let (a, b, cones) = constraints(&fixed, options, scale, n);
    let (z, status, iterations) = solve_qp(&p, &q, &a, &b, &cones)?;
    let rms_residual = residual_rms(&design, &z, scale);
    let (weights, offset, slope, reversible_slopes) =
        in_output_units(grid, &z, &fixed, prior, options, scale);
    Ok(FitResult {
        weights,
        offset,
        slope,
        reversible_slopes,
        unexcited,
        unexcited_treatment: options.unexcited,
        rows: design.rows,
        strided_out: design.strided_out,
        rms_residual,
        output_scale: scale,
        outside: design.outside,
        solver: format!("clarabel {status:?} in {iterations} iterations"),
    })
}

/// The fit's inputs make sense: a finite range, a prior of every cell, non-negative weights,
/// and an unexcited-cell treatment that determines them.
fn check_inputs(grid: &Grid, prior: Option<&[f64]>, options: &FitOptions) -> Result<(), FitError> {
    if !(grid.h_min.is_finite() && grid.h_max.is_finite() && grid.h_min < grid.h_max) {
        return Err(FitError(format!(
            "invalid input range [{}, {}]",
            grid.h_min, grid.h_max
        )));
    }
    if let Some(p) = prior {
        if p.len() != CELL_COUNT {
            return Err(FitError(format!(
                "the prior has {} weights, {CELL_COUNT} are needed",
                p.len()
            )));
        }
    }
    for (name, v) in [("smoothness", options.smoothness), ("ridge", options.ridge)] {
        if !(v.is_finite() && v >= 0.0) {
            return Err(FitError(format!(
                "{name} must be a finite number >= 0, got {v}"
            )));
        }
    }
    if let Some(cap) = options.total_mass_at_most {
        if !(cap.is_finite() && cap > 0.0) {
            return Err(FitError(format!(
                "total_mass_at_most must be a finite number > 0, got {cap}"
            )));
        }
    }
    match options.unexcited {
        Unexcited::KeepPrior if prior.is_none() => {
            return Err(FitError(
                "unexcited cells `keep-prior` needs prior (base) weights".into(),
            ))
        }
        Unexcited::Regularized if options.smoothness == 0.0 && options.ridge == 0.0 => {
            return Err(FitError(
                "unexcited cells `regularized` needs smoothness > 0 or ridge > 0 (otherwise their \
                 masses are not determined)"
                    .into(),
            ))
        }
        _ => {}
    }
    Ok(())
}

/// The output scale the unknowns are normalized by: the range of the selected outputs.
fn output_scale(experiments: &[Experiment<'_>]) -> Result<f64, FitError> {
    let mut lo = f64::INFINITY;
    let mut hi = f64::NEG_INFINITY;
    for e in experiments {
        for (t, &y) in e.output.iter().enumerate() {
            if e.selected.get(t).copied().unwrap_or(false) {
                lo = lo.min(y);
                hi = hi.max(y);
            }
        }
    }
    if hi.partial_cmp(&lo) != Some(std::cmp::Ordering::Greater) {
        return Err(FitError(
            "the selected rows have no output variation (or there are none): nothing to fit".into(),
        ));
    }
    Ok(hi - lo)
}

/// The quadratic form `H` (row-major, n × n) and the linear term `g` of the cost
/// `J = zᵀ H z − 2 gᵀ z + const`: the normal equations, the smoothness and ridge priors, and the
/// reversible part's smoothing.
fn quadratic_form(
    grid: &Grid,
    design: &Design,
    prior: Option<&[f64]>,
    options: &FitOptions,
    scale: f64,
) -> (Vec<f64>, Vec<f64>) {
    let n = design.unknowns;
    let rows = design.rows as f64;
    let mut h: Vec<f64> = design.ata.iter().map(|v| v / rows).collect();
    let mut g: Vec<f64> = design.atb.iter().map(|v| v / rows).collect();
    let rho_ref = 1.0 / (LEVELS * LEVELS) as f64;
    let pairs = neighbour_pairs();
    if options.smoothness > 0.0 {
        let c = options.smoothness / (pairs.len() as f64 * rho_ref * rho_ref);
        for &(a, b) in &pairs {
            if options.bands.contains(a) || options.bands.contains(b) {
                continue;
            }
            let (ia, ib) = (1.0 / cell_area(a), 1.0 / cell_area(b));
            h[a * n + a] += c * ia * ia;
            h[b * n + b] += c * ib * ib;
            h[a * n + b] -= c * ia * ib;
            h[b * n + a] -= c * ia * ib;
        }
    }
    if options.ridge > 0.0 {
        let c = options.ridge / (CELL_COUNT as f64 * rho_ref * rho_ref);
        for k in 0..CELL_COUNT {
            let ia = 1.0 / cell_area(k);
            h[k * n + k] += c * ia * ia;
            if let Some(p) = prior {
                g[k] += c * ia * ia * p[k] / scale;
            }
        }
    }

    // The piecewise reversible part: its slopes per unit field, `c_k / ŵ_k` (`c_k` the
    // coefficient of interval k's ramp in normalized input, `ŵ_k` its width in units of Δ), are
    // smoothed between neighbouring intervals like the densities, relative to `1 / L` (the slope
    // of a straight line through the output range).
    let slope0 = options.reversible.first_slope();
    if options.reversible.is_piecewise() {
        let lines = grid.lines();
        let widths: Vec<f64> = (0..LEVELS)
            .map(|k| (lines[k + 1] - lines[k]) / grid.cell_width())
            .collect();
        let c_ref = 1.0 / LEVELS as f64;
        let c = options.smoothness.max(REVERSIBLE_SMOOTHNESS_MIN)
            / ((LEVELS - 1) as f64 * c_ref * c_ref);
        for k in 0..LEVELS - 1 {
            let (a, b) = (slope0 + k, slope0 + k + 1);
            let (ia, ib) = (1.0 / widths[k], 1.0 / widths[k + 1]);
            h[a * n + a] += c * ia * ia;
            h[b * n + b] += c * ib * ib;
            h[a * n + b] -= c * ia * ib;
            h[b * n + a] -= c * ia * ib;
        }
    }

    (h, g)
}

/// clarabel's objective: minimize ½ zᵀ P z + qᵀ z with P = 2H (upper triangle, CSC), q = −2g.
fn objective(h: &[f64], g: &[f64], n: usize) -> (CscMatrix<f64>, Vec<f64>) {
    let mut colptr = Vec::with_capacity(n + 1);
    let mut rowval = Vec::new();
    let mut nzval = Vec::new();
    colptr.push(0);
    for c in 0..n {
        for r in 0..=c {
            let v = 2.0 * h[r * n + c];
            if v != 0.0 {
                rowval.push(r);
                nzval.push(v);
            }
        }
        colptr.push(rowval.len());
    }
    let p = CscMatrix::new(n, n, colptr, rowval, nzval);
    let q: Vec<f64> = g.iter().map(|v| -2.0 * v).collect();

    (p, q)
}

/// The cells whose mass is fixed (unexcited ones kept at the prior or at zero; unexcited band
/// cells at zero whatever the treatment, see [`Bands`]), normalized.
fn fixed_cells(
    unexcited: &[usize],
    prior: Option<&[f64]>,
    options: &FitOptions,
    scale: f64,
) -> Vec<(usize, f64)> {
    unexcited
        .iter()
        .filter_map(|&k| match options.unexcited {
            _ if options.bands.contains(k) => Some((k, 0.0)),
            Unexcited::KeepPrior => Some((k, prior.map_or(0.0, |p| p[k]) / scale)),
            Unexcited::Zero => Some((k, 0.0)),
            Unexcited::Regularized => None,
        })
        .collect()
}

/// The constraints `A z + s = b`, `s` in the cones: the fixed cells (equalities, zero cone)
/// first, then `w ≥ 0` for the free cells (and monotone reversible slopes), then the cap on the
/// total mass.
fn constraints(
    fixed: &[(usize, f64)],
    options: &FitOptions,
    scale: f64,
    n: usize,
) -> (CscMatrix<f64>, Vec<f64>, Vec<SupportedConeT<f64>>) {
    let slope0 = options.reversible.first_slope();
    let is_fixed = {
        let mut v = vec![false; CELL_COUNT];
        for &(k, _) in fixed {
            v[k] = true;
        }
        v
    };
    let mut free: Vec<usize> = (0..CELL_COUNT).filter(|&k| !is_fixed[k]).collect();
    if options.reversible.is_piecewise() {
        // Monotone: every slope >= 0.
        free.extend(slope0..slope0 + LEVELS);
    }
    let capped = usize::from(options.total_mass_at_most.is_some());
    let m = fixed.len() + free.len() + capped;
    // One nonzero per constraint row but the cap's (one per mass); build column-wise.
    let mut entries: Vec<(usize, usize, f64)> = Vec::with_capacity(m + CELL_COUNT); // (col, row, val)
    let mut b = vec![0.0; m];
    for (r, &(k, v)) in fixed.iter().enumerate() {
        entries.push((k, r, 1.0));
        b[r] = v;
    }
    for (r, &k) in free.iter().enumerate() {
        entries.push((k, fixed.len() + r, -1.0));
    }
    if let Some(cap) = options.total_mass_at_most {
        // cap - Σ_k w_k >= 0 (the last row of the nonnegative cone).
        let r = m - 1;
        for k in 0..CELL_COUNT {
            entries.push((k, r, 1.0));
        }
        b[r] = cap / scale;
    }
    entries.sort_by_key(|e| (e.0, e.1));
    let mut a_colptr = vec![0usize; n + 1];
    for e in &entries {
        a_colptr[e.0 + 1] += 1;
    }
    for c in 0..n {
        a_colptr[c + 1] += a_colptr[c];
    }
    let a = CscMatrix::new(
        m,
        n,
        a_colptr,
        entries.iter().map(|e| e.1).collect(),
        entries.iter().map(|e| e.2).collect(),
    );
    let mut cones: Vec<SupportedConeT<f64>> = Vec::new();
    if !fixed.is_empty() {
        cones.push(ZeroConeT(fixed.len()));
    }
    if free.len() + capped > 0 {
        cones.push(NonnegativeConeT(free.len() + capped));
    }
    (a, b, cones)
}

/// Solves the QP; returns the solution, the solver's status and its iterations.
fn solve_qp(
    p: &CscMatrix<f64>,
    q: &[f64],
    a: &CscMatrix<f64>,
    b: &[f64],
    cones: &[SupportedConeT<f64>],
) -> Result<(Vec<f64>, SolverStatus, u32), FitError> {
    let settings = DefaultSettingsBuilder::default()
        .verbose(false)
        .max_iter(500)
        .build()
        .map_err(|e| FitError(format!("solver settings: {e:?}")))?;
    let mut solver = DefaultSolver::new(p, q, a, b, cones, settings)
        .map_err(|e| FitError(format!("solver setup failed: {e:?}")))?;
    solver.solve();
    let status = solver.solution.status;
    if !matches!(status, SolverStatus::Solved | SolverStatus::AlmostSolved) {
        return Err(FitError(format!(
            "the QP solver did not converge: {status:?} after {} iterations",
            solver.solution.iterations
        )));
    }
    let z = solver.solution.x.clone();
    Ok((z, status, solver.solution.iterations))
}

/// The RMS residual of `z`, output units, from the normal equations:
/// `‖Az − b‖² = zᵀAᵀAz − 2 zᵀAᵀb + bᵀb`.
fn residual_rms(design: &Design, z: &[f64], scale: f64) -> f64 {
    let n = design.unknowns;
    let rows = design.rows as f64;
    let mut quad = 0.0;
    for r in 0..n {
        let s: f64 = design.ata[r * n..(r + 1) * n]
            .iter()
            .zip(z)
            .map(|(a, b)| a * b)
            .sum();
        quad += z[r] * s;
    }
    let cross: f64 = (0..n).map(|r| z[r] * design.atb[r]).sum();
    let sse = (quad - 2.0 * cross + design.btb).max(0.0);
    (sse / rows).sqrt() * scale
}

/// The masses (output units, the solver's slack below zero clipped, fixed cells exact) and the
/// affine or reversible part of the solution `z`.
#[allow(clippy::type_complexity)]
fn in_output_units(
    grid: &Grid,
    z: &[f64],
    fixed: &[(usize, f64)],
    prior: Option<&[f64]>,
    options: &FitOptions,
    scale: f64,
) -> (Vec<f64>, f64, f64, Vec<f64>) {
    let slope0 = options.reversible.first_slope();
    // Back to output units; clip the solver's interior-point slack (|w̃| ~ 1e-10) at zero.
    let mut weights: Vec<f64> = z[..CELL_COUNT]
        .iter()
        .map(|w| (w * scale).max(0.0))
        .collect();
    // Fixed cells get their exact value (not the solver's rescaled copy of it).
    for &(k, _) in fixed {
        weights[k] = match options.unexcited {
            Unexcited::KeepPrior if !options.bands.contains(k) => prior.map_or(0.0, |p| p[k]),
            _ => 0.0,
        };
    }
    let (offset, slope, reversible_slopes) = match options.reversible {
        Reversible::None => (0.0, 0.0, Vec::new()),
        Reversible::Offset => (z[CELL_COUNT] * scale, 0.0, Vec::new()),
        Reversible::Linear => {
            let (c0, c1) = (z[CELL_COUNT] * scale, z[CELL_COUNT + 1] * scale);
            let span = grid.h_max - grid.h_min;
            // c0 + c1 ((u - h_min)/span - ½) = offset + slope u.
            (c0 - c1 * (grid.h_min / span + 0.5), c1 / span, Vec::new())
        }
        Reversible::Piecewise | Reversible::PiecewiseNoOffset => {
            // c_k (clamp(x - k, 0, 1) - ½) = χ_k (clamp(u, line_k, line_k+1) - mid_k) with
            // χ_k = c_k / width_k (field units); slack below zero clipped.
            let lines = grid.lines();
            let slopes = (0..LEVELS)
                .map(|k| (z[slope0 + k] * scale).max(0.0) / (lines[k + 1] - lines[k]))
                .collect();
            let offset = if options.reversible == Reversible::Piecewise {
                z[CELL_COUNT] * scale
            } else {
                0.0
            };
            (offset, 0.0, slopes)
        }
    };
    (weights, offset, slope, reversible_slopes)
}
