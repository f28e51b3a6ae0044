//! The grid the masses are identified on, from the field the data reach.
//!
//! A coil drives the rod through `[H_lo, H_hi] = c0 · [min I, max I]` of the records (the eddy
//! lag keeps the field inside, eq. (4)). Where the base file's grid extends beyond that reach,
//! the data cannot say how the plane's mass is spread there: the hysterons with `α > H_hi` can
//! only switch down, those with `β < H_lo` only up, those with both never (docs/model.md, "Rods
//! the coil cannot saturate"). Such a side gets a band: one grid interval beyond the reach that
//! collapses the whole one-way region on that side into one row (or column) of cells, and the
//! other `L − 1` or `L − 2` intervals divide the reach equally. What no reachable field changes
//! is the constant `M_off`, fitted with the masses.
//!
//! A side the data reach — the grid's end lies inside the reach — keeps the base grid's end.
//! When both do, the data decide whether the coil saturated the rod there: the masses are fitted
//! on the base grid and on the banded one ([`banded_grid`]) and the banded fit is kept when the
//! Bayesian information criterion prefers it (`prefers_banded`).

use crate::design::Grid;
use crate::fit::{Bands, FitResult};
use crate::LEVELS;

/// A grid end counts as reached when the data come within this fraction of one of the base
/// grid's intervals of it: the FORC sweep's overdrive, clipped by the current limit, ends
/// exactly at `c0 · I_max`, which may fall a rounding short of a grid end at the same field.
const REACHED_TOLERANCE_OF_A_CELL: f64 = 1e-3;

/// The field range the records reach, A/m.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Reach {
    /// `H_lo = c0 · min I`.
    pub lo_a_per_m: f64,
    /// `H_hi = c0 · max I`.
    pub hi_a_per_m: f64,
}

impl Reach {
    /// The reach of records with these currents (A) through a coil of factor `c0` (1/m);
    /// `None` without a finite current.
    pub fn of_currents<'a>(
        currents_a: impl IntoIterator<Item = &'a [f64]>,
        coil_factor_per_m: f64,
    ) -> Option<Self> {
        let (lo, hi) = currents_a
            .into_iter()
            .flatten()
            .filter(|i| i.is_finite())
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &i| {
                (a.min(i), b.max(i))
            });
        (lo <= hi).then_some(Reach {
            lo_a_per_m: coil_factor_per_m * lo,
            hi_a_per_m: coil_factor_per_m * hi,
        })
    }
}

/// The grid the masses go on.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IdentificationGrid {
    /// The grid.
    pub grid: Grid,
    /// Its one-way bands (none: the coil saturates the rod on the base grid).
    pub bands: Bands,
    /// The reach the file records (`preisach.reach_a_per_m`), `None` without bands.
    pub reach: Option<Reach>,
}

impl IdentificationGrid {
    /// Whether the grid has a band (the rod's plane is wider than the reach).
    pub fn has_bands(&self) -> bool {
        self.bands.low || self.bands.high
    }
}

/// The grid for data reaching `reach` on a rod whose base grid is `base` (module docs).
pub fn identification_grid(base: Grid, reach: Reach) -> IdentificationGrid {
    let tolerance = REACHED_TOLERANCE_OF_A_CELL * base.cell_width();
    let bands = Bands {
        low: reach.lo_a_per_m > base.h_min + tolerance,
        high: reach.hi_a_per_m < base.h_max - tolerance,
    };
    if !(bands.low || bands.high) || reach.hi_a_per_m <= reach.lo_a_per_m {
        return IdentificationGrid {
            grid: base,
            bands: Bands::default(),
            reach: None,
        };
    }
    with_bands(base, reach, bands)
}

/// The grid with a band on both sides of `reach`, for data that cover the base grid: whether
/// the coil saturates the rod there is then a question for the data (`crate::masses` fits both
/// and keeps this one when the base grid's residual says the rod was not saturated). `None`
/// for an empty reach.
pub fn banded_grid(base: Grid, reach: Reach) -> Option<IdentificationGrid> {
    (reach.hi_a_per_m > reach.lo_a_per_m).then(|| {
        with_bands(
            base,
            reach,
            Bands {
                low: true,
                high: true,
            },
        )
    })
}

/// The reach on grid lines, a band one interval wide beyond each banded side, the base grid's
/// end on the others.
fn with_bands(base: Grid, reach: Reach, bands: Bands) -> IdentificationGrid {
    let lo = if bands.low {
        reach.lo_a_per_m
    } else {
        base.h_min
    };
    let hi = if bands.high {
        reach.hi_a_per_m
    } else {
        base.h_max
    };
    let inside = LEVELS - usize::from(bands.low) - usize::from(bands.high);
    let width = (hi - lo) / inside as f64;
    let h_min = if bands.low { lo - width } else { lo };
    let h_max = if bands.high { hi + width } else { hi };
    IdentificationGrid {
        grid: Grid::uniform(h_min, h_max),
        bands,
        reach: Some(Reach {
            lo_a_per_m: lo,
            hi_a_per_m: hi,
        }),
    }
}

/// Bayesian information criterion between the base grid's fit and the banded grid's on the same
/// rows: `n ln(SSE_base / SSE_banded) > k ln n`, with `k` the banded fit's extra free parameters
/// (its band cells and the offset). Derived, not tuned: the BIC's penalty is what a Gaussian
/// residual's likelihood gives for `k` parameters that explain nothing.
pub(crate) fn prefers_banded(base: &FitResult, banded: &FitResult) -> bool {
    let n = base.rows.min(banded.rows) as f64;
    let extra = (band_cells() + 1) as f64;
    let (sse_base, sse_banded) = (
        base.rms_residual.powi(2).max(f64::MIN_POSITIVE),
        banded.rms_residual.powi(2).max(f64::MIN_POSITIVE),
    );
    n > extra && n * (sse_base / sse_banded).ln() > extra * n.ln()
}

/// Cells in the two one-way bands of a banded grid: a row and a column of `LEVELS` cells each,
/// sharing one.
fn band_cells() -> usize {
    2 * crate::LEVELS - 1
}
