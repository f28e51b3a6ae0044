//! Which minor loops a file's Preisach masses were measured on.
//!
//! The masses come from quasi-static records alone. A minor loop between the currents `lo` and
//! `hi` switches the cells of the triangle `lo ≤ β ≤ α ≤ hi` (eq. (2): the relays whose
//! thresholds the loop crosses), so its stroke is the sum of those cells' masses, with the
//! uniform density of each cell cut where the loop reverses. A quasi-static record that
//! reverses within one cell of `lo` and of `hi` crosses the same cells and measures that sum
//! directly; a record that never reverses there (a FORC sweep reverses at its own points only)
//! constrains it only through differences of long branches, where a few cells near the
//! diagonal weigh little, and the masses there are what the fit's smoothness makes of them.
//!
//! [`MeasuredLoops`] holds the quasi-static reversals: `maglab identify` computes them from the
//! records its masses come from and writes them into the file's provenance
//! ([`MeasuredLoops::PROVENANCE_KEY`]); its own coverage check and `maglab diagnose` ask of
//! every dynamic record's loop whether they cover it ([`uncovered_loops`]). Reversals are the
//! current's turning points with a dead band of half a cell (smaller wiggles switch no whole
//! cell); a loop within one cell switches no whole cell and needs nothing.

use serde_json::{json, Value};

/// The levels of the grid the masses are identified on: the cell, in current, is the records'
/// current range over this many intervals (`maglab_identify::LEVELS`, the core's 25 levels).
pub const GRID_LEVELS: usize = magctl::preisach::LEVELS;

/// Reversals closer than this fraction of a cell are one in [`MeasuredLoops`] (they switch the
/// same cells to within a few % of one): the file keeps a few dozen numbers, not every period
/// of a slow sine.
const MERGE_FRACTION_OF_A_CELL: f64 = 0.05;

/// The quasi-static reversals the masses were measured at (module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct MeasuredLoops {
    /// Current minima of the quasi-static records, A, ascending.
    pub minima_a: Vec<f64>,
    /// Current maxima, A, ascending.
    pub maxima_a: Vec<f64>,
    /// The grid cell in current, A: a loop end within one cell of a reversal is covered.
    pub cell_a: f64,
}

impl MeasuredLoops {
    /// The key of the provenance entry `maglab identify` writes.
    pub const PROVENANCE_KEY: &'static str = "quasi_static_reversals";

    /// The reversals of `quasi_static` records (currents, A) on a grid of cell `cell_a`.
    pub fn of_records(quasi_static: &[&[f64]], cell_a: f64) -> Self {
        let (mut minima_a, mut maxima_a) = (Vec::new(), Vec::new());
        for c in quasi_static {
            let (mn, mx) = turning_points(c, 0.5 * cell_a);
            minima_a.extend(mn);
            maxima_a.extend(mx);
        }
        let merge = MERGE_FRACTION_OF_A_CELL * cell_a;
        MeasuredLoops {
            minima_a: merged(minima_a, merge),
            maxima_a: merged(maxima_a, merge),
            cell_a,
        }
    }

    /// Whether a quasi-static record reversed within one cell of both ends of the loop
    /// `[lo_a, hi_a]` (or the loop is within one cell: it switches no whole cell).
    pub fn covers(&self, lo_a: f64, hi_a: f64) -> bool {
        let near = |points: &[f64], i: f64| points.iter().any(|p| (p - i).abs() <= self.cell_a);
        hi_a - lo_a <= self.cell_a || (near(&self.minima_a, lo_a) && near(&self.maxima_a, hi_a))
    }

    /// The provenance entry.
    pub fn to_json(&self) -> Value {
        json!({
            "minima_a": self.minima_a,
            "maxima_a": self.maxima_a,
            "cell_a": self.cell_a,
            "why": "the current reversals of the quasi-static records the masses were fitted on: \
                    a dynamic loop is measured when a record reversed within one cell (cell_a) of \
                    both its ends (maglab_model::coverage)",
        })
    }

    /// The entry of a parameter file's provenance: `None` when it has none (masses not
    /// identified, or identified before the entry existed), an error naming the field when it
    /// is malformed.
    pub fn from_provenance(
        provenance: &actuator_params::Provenance,
    ) -> Option<Result<Self, String>> {
        let entry = provenance.details.get(Self::PROVENANCE_KEY)?;
        let field = |name: &str| format!("provenance.{}.{name}", Self::PROVENANCE_KEY);
        let list = |name: &str| -> Result<Vec<f64>, String> {
            entry
                .get(name)
                .and_then(Value::as_array)
                .ok_or_else(|| format!("{}: expected a list of currents, A", field(name)))?
                .iter()
                .map(|v| {
                    v.as_f64()
                        .filter(|x| x.is_finite())
                        .ok_or_else(|| format!("{}: `{v}` is not a finite current, A", field(name)))
                })
                .collect()
        };
        Some((|| {
            let cell_a = entry
                .get("cell_a")
                .and_then(Value::as_f64)
                .filter(|c| c.is_finite() && *c > 0.0)
                .ok_or_else(|| format!("{}: expected a positive current, A", field("cell_a")))?;
            Ok(MeasuredLoops {
                minima_a: list("minima_a")?,
                maxima_a: list("maxima_a")?,
                cell_a,
            })
        })())
    }
}

/// Sorted, with points closer than `within` to the last kept one dropped.
fn merged(mut points: Vec<f64>, within: f64) -> Vec<f64> {
    points.sort_by(f64::total_cmp);
    let mut out: Vec<f64> = Vec::with_capacity(points.len());
    for p in points {
        if out.last().is_none_or(|l| p - l > within) {
            out.push(p);
        }
    }
    out
}

/// The grid cell in current for records spanning these currents: their range over
/// [`GRID_LEVELS`] (the grid's interval on the field the data reach); `None` without a range.
pub fn cell_of_currents<'a>(currents_a: impl IntoIterator<Item = &'a [f64]>) -> Option<f64> {
    let (lo, hi) = currents_a
        .into_iter()
        .flatten()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &i| {
            (lo.min(i), hi.max(i))
        });
    // No range (no samples, or NaN in them): no cell.
    (hi.partial_cmp(&lo) == Some(std::cmp::Ordering::Greater))
        .then(|| (hi - lo) / GRID_LEVELS as f64)
}

/// The turning points of `current_a` (minima, maxima), A, ignoring reversals smaller than
/// `dead_band_a`.
pub fn turning_points(current_a: &[f64], dead_band_a: f64) -> (Vec<f64>, Vec<f64>) {
    let (mut minima, mut maxima) = (Vec::new(), Vec::new());
    let Some(&first) = current_a.first() else {
        return (minima, maxima);
    };
    // Until the first move beyond the dead band the direction is unknown (`0`): the running
    // extremes are within the dead band of the start, which is no reversal. After it, `high`
    // (rising) or `low` (falling) is the running extreme since the last reversal.
    let (mut direction, mut low, mut high) = (0i8, first, first);
    for &i in &current_a[1..] {
        match direction {
            0 if i - low > dead_band_a => (direction, high) = (1, i),
            0 if high - i > dead_band_a => (direction, low) = (-1, i),
            0 => (low, high) = (low.min(i), high.max(i)),
            1 if i > high => high = i,
            1 if high - i > dead_band_a => {
                maxima.push(high);
                (direction, low) = (-1, i);
            }
            -1 if i < low => low = i,
            -1 if i - low > dead_band_a => {
                minima.push(low);
                (direction, high) = (1, i);
            }
            _ => {}
        }
    }
    // The record's last extreme is no reversal: the record ends there.
    (minima, maxima)
}

/// The loop a periodic record runs: its current's extremes over the second half (past the
/// start's transient), A; `None` for an empty record.
pub fn steady_loop(current_a: &[f64]) -> Option<(f64, f64)> {
    let steady = &current_a[current_a.len() / 2..];
    let (lo, hi) = steady
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &i| {
            (a.min(i), b.max(i))
        });
    (lo <= hi).then_some((lo, hi))
}

/// A dynamic loop no quasi-static record reverses at.
#[derive(Debug, Clone, PartialEq)]
pub struct UncoveredLoop {
    /// The dynamic record.
    pub file: String,
    /// Its lower and upper reversal current, A.
    pub lo_a: f64,
    /// See [`UncoveredLoop::lo_a`].
    pub hi_a: f64,
    /// The record's frequency, Hz.
    pub frequency_hz: f64,
    /// The grid cell the check used, A.
    pub cell_a: f64,
}

/// The dynamic loops (`(file, frequency_hz, current)`) that `measured` does not cover.
pub fn uncovered_loops(
    measured: &MeasuredLoops,
    dynamic: &[(String, f64, &[f64])],
) -> Vec<UncoveredLoop> {
    dynamic
        .iter()
        .filter_map(|(file, frequency_hz, c)| {
            let (lo_a, hi_a) = steady_loop(c)?;
            (!measured.covers(lo_a, hi_a)).then(|| UncoveredLoop {
                file: file.clone(),
                lo_a,
                hi_a,
                frequency_hz: *frequency_hz,
                cell_a: measured.cell_a,
            })
        })
        .collect()
}

/// The same loop, within one cell at both ends.
pub fn same_loop(a: &UncoveredLoop, b: &UncoveredLoop) -> bool {
    (a.lo_a - b.lo_a).abs() <= a.cell_a && (a.hi_a - b.hi_a).abs() <= a.cell_a
}
