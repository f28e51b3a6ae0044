//! Whether a quasi-static record reads the same state the same way each time it returns to it.
//!
//! Preisach's wiping-out property: once the input has reached its largest value and then its
//! smallest (or the reverse), the memory holds only those two reversal points, so every later
//! visit to either extreme finds the rod in the same state. Anything rate-independent keeps that:
//! the reversible part, a static sensor nonlinearity, a backlash past its first take-up. A
//! displacement that differs between such visits therefore means something that depends on time
//! or on more of the history: the coil heating the rod (thermal drift), creep with long time
//! constants, a drifting sensor, friction that sticks at different places.
//!
//! Measured on the bench plant's 1 Hz FORC sweeps of the blind suite (seeds 1 and 4, 64 folders
//! of `lab/tests/identified_suite.rs`; the spread over the 25 counted visits to the largest
//! current, as a fraction of the record's displacement range): without an effect and with every
//! library effect but thermal drift at most 0.17 %, backlash 0.04–0.19 %, a sensor nonlinearity
//! 0.03–0.36 %; stick-slip 2.0–3.7 %, creep (three time constants up to 0.8 s) 5.7–9.9 %, thermal
//! drift 6.6–73 % (a sweep that heats the coil up to the plant's 200 K limit, where the rod's
//! magnetostriction is gone). [`DRIFT_LIMIT`] between them warns about all 17 of the last three
//! and none of the other 47 (`identify/examples/drift_scan.rs`); on seeds 2 and 3, scanned after the limit
//! was set, all 12 of them (the smallest 1.31 %, a thermal drift) and none of the other 52 (the
//! largest 0.22 %). `lab/tests/sweep_drift.rs` checks both sides on fresh sweeps.

/// A spread of the displacement at one extreme, over its visits, above this fraction of the
/// record's displacement range is reported (module docs).
pub const DRIFT_LIMIT: f64 = 0.01;

/// A sample belongs to a visit of an extreme when its current lies within this fraction of the
/// record's current span from the extreme.
const VISIT_BAND: f64 = 0.01;

/// The visits of a record to one extreme of its current, after the other extreme was reached.
#[derive(Debug, Clone, PartialEq)]
pub struct ExtremeVisits {
    /// The extreme's current, A.
    pub current_a: f64,
    /// Per visit: its mid time, s, and the median displacement over it, m.
    pub visits: Vec<(f64, f64)>,
}

impl ExtremeVisits {
    /// Largest minus smallest displacement over the visits, m (0 with fewer than two).
    pub fn spread_m(&self) -> f64 {
        let lo = self
            .visits
            .iter()
            .map(|v| v.1)
            .fold(f64::INFINITY, f64::min);
        let hi = self
            .visits
            .iter()
            .map(|v| v.1)
            .fold(f64::NEG_INFINITY, f64::max);
        if self.visits.len() < 2 {
            0.0
        } else {
            hi - lo
        }
    }

    /// The visits at the smallest and the largest displacement, `((t_s, y_m), (t_s, y_m))`.
    pub fn lowest_and_highest(&self) -> Option<((f64, f64), (f64, f64))> {
        let lo = self.visits.iter().min_by(|a, b| a.1.total_cmp(&b.1))?;
        let hi = self.visits.iter().max_by(|a, b| a.1.total_cmp(&b.1))?;
        Some((*lo, *hi))
    }
}

/// The visits to the record's largest and smallest current that count (each after the other
/// extreme has been reached once, and not cut by the record's start or end; module docs). `t_s`, `current_a` and `displacement_m` are the
/// record's columns (equal lengths; the shortest is used).
pub fn extreme_visits(
    t_s: &[f64],
    current_a: &[f64],
    displacement_m: &[f64],
) -> [ExtremeVisits; 2] {
    let n = t_s.len().min(current_a.len()).min(displacement_m.len());
    let (lo, hi) = current_a[..n]
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &i| {
            (lo.min(i), hi.max(i))
        });
    let band = VISIT_BAND * (hi - lo);
    // Which extreme each sample is at: +1 the largest current, -1 the smallest, 0 neither.
    let at = |k: usize| -> i8 {
        let i = current_a[k];
        if !band.is_finite() || band <= 0.0 {
            0
        } else if i >= hi - band {
            1
        } else if i <= lo + band {
            -1
        } else {
            0
        }
    };
    let mut out = [
        ExtremeVisits {
            current_a: hi,
            visits: Vec::new(),
        },
        ExtremeVisits {
            current_a: lo,
            visits: Vec::new(),
        },
    ];
    let mut reached = [false, false];
    let mut k = 0;
    while k < n {
        let side = at(k);
        if side == 0 {
            k += 1;
            continue;
        }
        let start = k;
        while k < n && at(k) == side {
            k += 1;
        }
        let (me, other) = if side > 0 { (0, 1) } else { (1, 0) };
        // A visit cut by the record's start or end may miss its turning point: not compared.
        let whole = start > 0 && k < n;
        if reached[other] && whole {
            let mut y: Vec<f64> = displacement_m[start..k].to_vec();
            y.sort_by(f64::total_cmp);
            let median = y[y.len() / 2];
            out[me]
                .visits
                .push((0.5 * (t_s[start] + t_s[k - 1]), median));
        }
        reached[me] = true;
    }
    out
}

/// The warning for a record whose visits to one extreme disagree by more than [`DRIFT_LIMIT`]
/// of its displacement range, or `None`.
pub fn drift_warning(
    file: &str,
    t_s: &[f64],
    current_a: &[f64],
    displacement_m: &[f64],
) -> Option<String> {
    let n = t_s.len().min(current_a.len()).min(displacement_m.len());
    let (lo, hi) = displacement_m[..n]
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &y| {
            (lo.min(y), hi.max(y))
        });
    let range = hi - lo;
    if !range.is_finite() || range <= 0.0 {
        return None;
    }
    let visits = extreme_visits(t_s, current_a, displacement_m);
    let worst = visits
        .iter()
        .max_by(|a, b| a.spread_m().total_cmp(&b.spread_m()))?;
    let spread = worst.spread_m();
    if spread <= DRIFT_LIMIT * range {
        return None;
    }
    let (lowest, highest) = worst.lowest_and_highest()?;
    // Earlier first.
    let ((t_a, y_a), (t_b, y_b)) = if lowest.0 <= highest.0 {
        (lowest, highest)
    } else {
        (highest, lowest)
    };
    Some(format!(
        "{file}: at {:.3} A the displacement reads {:.2} um at t = {:.2} s and {:.2} um at t = \
         {:.2} s ({} visits; {:.1} % of the record's range, limit {:.0} %), though hysteresis \
         alone returns to the same state there each time: something that depends on time moved \
         the rod or its reading during the sweep (the coil heating the rod, creep, a drifting \
         sensor) or friction held it; masses fitted to this record absorb it (let the rod cool, \
         lower the sweep's duty or shorten it, and record again)",
        worst.current_a,
        1e6 * y_a,
        t_a,
        1e6 * y_b,
        t_b,
        worst.visits.len(),
        100.0 * spread / range,
        100.0 * DRIFT_LIMIT
    ))
}
