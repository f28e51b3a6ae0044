//! Do the quasi-static records reverse where the dynamic ones do?
//!
//! The masses come from the quasi-static records alone; the dynamic fit then takes them as they
//! are. A minor loop between the currents `lo` and `hi` switches the cells of the triangle
//! `lo ≤ β ≤ α ≤ hi` (eq. (2): the relays whose thresholds the loop crosses), so its stroke is
//! the sum of those cells' masses, with the uniform density of each cell cut where the loop
//! reverses. A quasi-static record that reverses within one cell of `lo` and of `hi` crosses
//! the same cells and constrains that sum directly; a record that never reverses near `hi`
//! (a FORC sweep from one extreme reverses only at the other end) constrains it only through
//! differences of long branches, where a few cells near the diagonal weigh little in the fit.
//! Then the smallest dynamic loops are the worst-fitted ones at every frequency, and the
//! dynamic fit bends `R_eddy` and `ξ` to make up for what the masses miss (docs/model.md,
//! "Not on every design").
//!
//! The check: every dynamic record's loop (its current's extremes over the second half of the
//! record, past the start's transient) needs a quasi-static minimum within one grid cell of its
//! `lo` and a quasi-static maximum within one cell of its `hi`. The cell is the records' current
//! range over [`LEVELS`] (the grid's interval on the field the data reach). Reversals are the
//! current's turning points with a dead band of half a cell (smaller wiggles switch no whole
//! cell). An uncovered loop is warned about only when the identified model misses it by more
//! than the quasi-static records' own NRMSE limit: many rods' masses are smooth enough that
//! the long branches determine them.

use crate::LEVELS;

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

/// The dynamic loops (`(file, frequency_hz, current)`) that no quasi-static record reverses
/// within one grid cell of (module docs).
pub fn uncovered_loops(
    quasi_static: &[&[f64]],
    dynamic: &[(String, f64, &[f64])],
) -> Vec<UncoveredLoop> {
    let all = quasi_static
        .iter()
        .copied()
        .chain(dynamic.iter().map(|(_, _, c)| *c))
        .flat_map(|c| c.iter().copied());
    let (lo, hi) = all.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), i| {
        (lo.min(i), hi.max(i))
    });
    // No range (no samples, or NaN in them): nothing to cover.
    if hi.partial_cmp(&lo) != Some(std::cmp::Ordering::Greater) {
        return Vec::new();
    }
    let cell_a = (hi - lo) / LEVELS as f64;
    let (mut minima, mut maxima) = (Vec::new(), Vec::new());
    for c in quasi_static {
        let (mn, mx) = turning_points(c, 0.5 * cell_a);
        minima.extend(mn);
        maxima.extend(mx);
    }
    let near = |points: &[f64], i: f64| points.iter().any(|p| (p - i).abs() <= cell_a);
    dynamic
        .iter()
        .filter_map(|(file, frequency_hz, c)| {
            let steady = &c[c.len() / 2..];
            let lo_a = steady.iter().copied().fold(f64::INFINITY, f64::min);
            let hi_a = steady.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            // A loop within one cell switches no whole cell: nothing to cover.
            let covered = hi_a - lo_a <= cell_a || (near(&minima, lo_a) && near(&maxima, hi_a));
            (!covered).then(|| UncoveredLoop {
                file: file.clone(),
                lo_a,
                hi_a,
                frequency_hz: *frequency_hz,
                cell_a,
            })
        })
        .collect()
}

/// The warning for the dynamic loops no quasi-static record covers that the identified model
/// also misses by more than `limit` (NRMSE with the noise taken out, `nrmse_of` a file's) at
/// the lowest frequency the
/// data drive that loop at, or `None`. There the loop is closest to quasi-static, so `limit` is
/// the quasi-static records' own; at higher frequencies the misfit is the dynamics' as well. An
/// uncovered loop the model fits is no concern: the rod's masses are smooth enough there.
pub fn coverage_warning(
    uncovered: &[UncoveredLoop],
    nrmse_of: impl Fn(&str) -> Option<f64>,
    limit: f64,
    dynamic_count: usize,
) -> Option<String> {
    let same_loop = |a: &UncoveredLoop, b: &UncoveredLoop| {
        (a.lo_a - b.lo_a).abs() <= a.cell_a && (a.hi_a - b.hi_a).abs() <= a.cell_a
    };
    let slowest = |u: &UncoveredLoop| {
        !uncovered
            .iter()
            .any(|v| same_loop(u, v) && v.frequency_hz < u.frequency_hz)
    };
    let missed: Vec<(&UncoveredLoop, f64)> = uncovered
        .iter()
        .filter(|u| slowest(u))
        .filter_map(|u| nrmse_of(&u.file).filter(|e| *e > limit).map(|e| (u, e)))
        .collect();
    let (worst, nrmse) = missed.iter().max_by(|a, b| a.1.total_cmp(&b.1))?;
    Some(format!(
        "{} of {dynamic_count} dynamic records make loops that no quasi-static record reverses at \
         (within one grid cell) and the model misses by more than the quasi-static limit of \
         {:.0} % at the slowest frequency they are driven at, the worst {} between {:.3} and \
         {:.3} A at {:.1} %: the masses of the cells \
         such loops switch are fitted only through long reversal branches, and R_eddy, xi, f0 \
         absorb what they miss (docs/model.md); record slow loops (<= 1 Hz) between the same \
         currents and identify again",
        missed.len(),
        100.0 * limit,
        worst.file,
        worst.lo_a,
        worst.hi_a,
        100.0 * nrmse
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sine(bias: f64, amp: f64, cycles: f64, n: usize) -> Vec<f64> {
        (0..n)
            .map(|k| bias + amp * (2.0 * std::f64::consts::PI * cycles * k as f64 / n as f64).sin())
            .collect()
    }

    #[test]
    fn turning_points_of_a_sine_and_a_ramp() {
        let (mn, mx) = turning_points(&sine(0.5, 0.2, 2.0, 2000), 0.01);
        assert_eq!((mn.len(), mx.len()), (2, 2), "{mn:?} {mx:?}");
        assert!(mx.iter().all(|m| (m - 0.7).abs() < 1e-6));
        assert!(mn.iter().all(|m| (m - 0.3).abs() < 1e-6), "{mn:?}");
        // Wiggles inside the dead band are no reversal.
        let ramp: Vec<f64> = (0..100)
            .map(|k| k as f64 * 0.01 + 0.001 * (k % 2) as f64)
            .collect();
        let (mn, mx) = turning_points(&ramp, 0.01);
        assert_eq!((mn.len(), mx.len()), (0, 0), "{mn:?} {mx:?}");
    }

    #[test]
    fn a_forc_sweep_covers_only_loops_up_to_its_top() {
        // Reversal sweep: from 0 A up to the top, down to 1.4 − 0.14 k, back up, ...
        let mut forc: Vec<f64> = (0..=140).map(|s| s as f64 * 0.01).collect();
        for k in 1..=10 {
            let steps = (14 * k) as usize;
            forc.extend((1..=steps).map(|s| 1.4 - s as f64 * 0.01));
            forc.extend((1..=steps).rev().map(|s| 1.4 - (s - 1) as f64 * 0.01));
        }
        let small = sine(0.55, 0.15, 20.0, 10_000);
        let top = sine(1.1, 0.3, 20.0, 10_000);
        let dynamic = vec![
            ("small".to_string(), 20.0, &small[..]),
            ("top".to_string(), 20.0, &top[..]),
        ];
        let u = uncovered_loops(&[&forc], &dynamic);
        assert_eq!(u.len(), 1, "{u:?}");
        assert_eq!(u[0].file, "small");
        // Warned about only when the model misses the loop.
        let w = coverage_warning(&u, |_| Some(0.07), 0.02, 2).unwrap();
        assert!(w.contains("between 0.400 and 0.700 A at 7.0 %"), "{w}");
        assert!(coverage_warning(&u, |_| Some(0.005), 0.02, 2).is_none());
        // Only the slowest record of a loop counts: the same loop at 400 Hz missed by the
        // dynamics is no sign of the masses when its 20 Hz record fits.
        let mut both = u.clone();
        both.push(UncoveredLoop {
            file: "small-400".into(),
            frequency_hz: 400.0,
            ..u[0].clone()
        });
        let nrmse = |f: &str| Some(if f == "small-400" { 0.05 } else { 0.005 });
        assert!(coverage_warning(&both, nrmse, 0.02, 3).is_none());
        // A slow sine between the same currents covers it.
        let slow = sine(0.55, 0.15, 1.0, 10_000);
        assert!(uncovered_loops(&[&forc, &slow], &dynamic).is_empty());
    }
}
