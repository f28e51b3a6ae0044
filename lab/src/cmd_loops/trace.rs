//! The loops themselves: the initial curve, the major loop, the symmetric minor loops and the
//! biased loop, traced with the core's exact forward operator and inverse (`magctl::preisach`).

use crate::params_io::LoadedParams;
use anyhow::{anyhow, bail, Result};
use magctl::preisach::{PreisachMeasure, PreisachState, Saturation};

/// Permeability of vacuum μ0, H/m (for the loss `μ0 ∮ H dM`, J/m³).
const MU0_H_PER_M: f64 = 1.256_637_062_12e-6;

/// A closed loop traced as an ascending branch `h_lo → h_hi` and a descending one back.
#[derive(Debug, Clone)]
pub struct ClosedLoop {
    /// Legend / table name.
    pub name: String,
    /// Lower turning field, A/m.
    pub h_lo_a_per_m: f64,
    /// Upper turning field, A/m.
    pub h_hi_a_per_m: f64,
    /// `(H, M)` samples, A/m, rising.
    pub ascending: Vec<(f64, f64)>,
    /// `(H, M)` samples, A/m, falling.
    pub descending: Vec<(f64, f64)>,
    /// `|M(end of the descending branch) - M(start of the ascending branch)|`, A/m.
    pub closure_error_a_per_m: f64,
    /// Fields where `M = 0` on the ascending and descending branch (exact inverse), A/m; `None`
    /// when the branch does not cross zero.
    pub coercive_a_per_m: (Option<f64>, Option<f64>),
    /// `M` at the centre field on the ascending and descending branch, A/m; `None` when the
    /// centre lies outside the loop.
    pub remanence_a_per_m: (Option<f64>, Option<f64>),
    /// Hysteresis loss per cycle `μ0 ∮ H dM = μ0 ∫ (M↓ - M↑) dH` (trapezoid rule), J/m³.
    pub loss_j_per_m3: f64,
}

impl ClosedLoop {
    pub(super) fn m_range(&self) -> (f64, f64) {
        self.ascending
            .iter()
            .chain(&self.descending)
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
                (lo.min(p.1), hi.max(p.1))
            })
    }

    /// The closed polyline: ascending then descending.
    pub(super) fn polyline(&self) -> impl Iterator<Item = (f64, f64)> + '_ {
        self.ascending.iter().chain(&self.descending).copied()
    }
}

/// Everything `loops` traces.
#[derive(Debug, Clone)]
pub struct LoopSet {
    /// Centre of the field range (input of the demagnetized state), A/m.
    pub h_center_a_per_m: f64,
    /// Initial magnetization curve `(H, M)`, A/m.
    pub initial: Vec<(f64, f64)>,
    /// Major loop.
    pub major: ClosedLoop,
    /// Symmetric minor loops, in the order of the amplitudes given.
    pub symmetric: Vec<ClosedLoop>,
    /// The biased loop spanning the trajectory's displacement band.
    pub biased: ClosedLoop,
    /// Magnetization band `[M_lo, M_hi]` of the biased loop, A/m.
    pub biased_band_a_per_m: (f64, f64),
    /// Whether a band edge was beyond `±Σw` and clamped by the inverse.
    pub biased_clamped: bool,
}
/// Traces all loops. `amplitudes_a_per_m` must lie in `(0, half-range]`.
pub fn trace(
    loaded: &LoadedParams,
    measure: &PreisachMeasure,
    amplitudes_a_per_m: &[f64],
    points: usize,
) -> Result<LoopSet> {
    let grid = &loaded.params.preisach;
    let (h_min, h_max) = (f64::from(grid.h_min_a_per_m), f64::from(grid.h_max_a_per_m));
    let h_center = 0.5 * (h_min + h_max);
    let half_range = 0.5 * (h_max - h_min);
    for &a in amplitudes_a_per_m {
        if !a.is_finite() || a <= 0.0 || a > half_range * (1.0 + 1e-9) {
            bail!(
                "--amplitudes: {} kA/m is not in (0, {}] kA/m (half the field range [{}, {}] kA/m)",
                a / 1e3,
                half_range / 1e3,
                h_min / 1e3,
                h_max / 1e3
            );
        }
    }

    let demagnetized: PreisachState = measure.demagnetized();

    let mut state = demagnetized.clone();
    let initial = sweep(measure, &mut state, h_center, h_max, points)?;
    let major = closed_loop(
        measure,
        &mut state,
        "major loop".into(),
        (h_min, h_max),
        h_center,
        points,
    )?;

    let mut symmetric = Vec::new();
    for &a in amplitudes_a_per_m {
        let mut state = demagnetized.clone();
        symmetric.push(closed_loop(
            measure,
            &mut state,
            format!("minor ±{:.1} kA/m", a / 1e3),
            (h_center - a, h_center + a),
            h_center,
            points,
        )?);
    }

    // The static model (6): y = l_m λ_s M² / M_s²  =>  M = M_s √(y / (l_m λ_s)).
    let act = &loaded.params.actuator;
    let m_s = f64::from(act.saturation_magnetization_a_per_m);
    let stroke_m = f64::from(act.stroke_m());
    let traj = &loaded.params.trajectory;
    let m_for = |y_m: f32| m_s * (f64::from(y_m) / stroke_m).max(0.0).sqrt();
    let (m_lo, m_hi) = (
        m_for(traj.displacement_min_m),
        m_for(traj.displacement_max_m),
    );
    let mut state = demagnetized.clone();
    let up = measure
        .invert(&mut state, m_hi as f32)
        .map_err(|e| anyhow!("inverse to M = {m_hi} A/m failed: {e:?}"))?;
    let down = measure
        .invert(&mut state, m_lo as f32)
        .map_err(|e| anyhow!("inverse to M = {m_lo} A/m failed: {e:?}"))?;
    let biased_clamped = up.saturation != Saturation::None || down.saturation != Saturation::None;
    let biased = closed_loop(
        measure,
        &mut state,
        format!(
            "biased: y ∈ [{:.0}, {:.0}] µm",
            traj.displacement_min_m * 1e6,
            traj.displacement_max_m * 1e6
        ),
        (f64::from(down.h_a_per_m), f64::from(up.h_a_per_m)),
        h_center,
        points,
    )?;

    Ok(LoopSet {
        h_center_a_per_m: h_center,
        initial,
        major,
        symmetric,
        biased,
        biased_band_a_per_m: (m_lo, m_hi),
        biased_clamped,
    })
}

pub(super) fn apply(
    measure: &PreisachMeasure,
    state: &mut PreisachState,
    h_a_per_m: f64,
) -> Result<f64> {
    measure
        .apply(state, h_a_per_m as f32)
        .map(f64::from)
        .map_err(|e| anyhow!("input H = {h_a_per_m} A/m rejected: {e:?}"))
}

/// Moves the input linearly from `from` to `to` in `points` steps and records `(H, M)`.
fn sweep(
    measure: &PreisachMeasure,
    state: &mut PreisachState,
    from: f64,
    to: f64,
    points: usize,
) -> Result<Vec<(f64, f64)>> {
    (0..=points)
        .map(|k| {
            let h = from + (to - from) * k as f64 / points as f64;
            Ok((h, apply(measure, state, h)?))
        })
        .collect()
}

/// Drives the input to `hi`, then to `lo`, and records the cycle `lo → hi → lo`.
fn closed_loop(
    measure: &PreisachMeasure,
    state: &mut PreisachState,
    name: String,
    (lo, hi): (f64, f64),
    h_center: f64,
    points: usize,
) -> Result<ClosedLoop> {
    apply(measure, state, hi)?;
    apply(measure, state, lo)?;
    let at_lo = state.clone();
    let ascending = sweep(measure, state, lo, hi, points)?;
    let at_hi = state.clone();
    let descending = sweep(measure, state, hi, lo, points)?;

    let m_start = ascending[0].1;
    let m_top = ascending[ascending.len() - 1].1;
    let m_end = descending[descending.len() - 1].1;

    // Coercive field of a branch: the exact inverse Γ⁻¹(0) from the branch's start, when the
    // branch crosses zero (otherwise the inverse would leave the loop).
    let zero_crossing = |start: &PreisachState, m_from: f64, m_to: f64| -> Result<Option<f64>> {
        if m_from.min(m_to) <= 0.0 && 0.0 <= m_from.max(m_to) {
            let mut s = start.clone();
            let sol = measure
                .invert(&mut s, 0.0)
                .map_err(|e| anyhow!("inverse to M = 0 failed: {e:?}"))?;
            Ok(Some(f64::from(sol.h_a_per_m)))
        } else {
            Ok(None)
        }
    };
    let coercive = (
        zero_crossing(&at_lo, m_start, m_top)?,
        zero_crossing(&at_hi, m_top, m_end)?,
    );
    let remanence = if lo <= h_center && h_center <= hi {
        (
            Some(apply(measure, &mut at_lo.clone(), h_center)?),
            Some(apply(measure, &mut at_hi.clone(), h_center)?),
        )
    } else {
        (None, None)
    };

    // ∮ H dM = ∫ (M↓(H) - M↑(H)) dH over [lo, hi]; both branches share the H samples.
    let trapezoid = |branch: &[(f64, f64)]| -> f64 {
        branch
            .windows(2)
            .map(|w| 0.5 * (w[1].0 - w[0].0) * (w[0].1 + w[1].1))
            .sum()
    };
    let area = -trapezoid(&descending) - trapezoid(&ascending);

    Ok(ClosedLoop {
        name,
        h_lo_a_per_m: lo,
        h_hi_a_per_m: hi,
        closure_error_a_per_m: (m_end - m_start).abs(),
        coercive_a_per_m: coercive,
        remanence_a_per_m: remanence,
        loss_j_per_m3: MU0_H_PER_M * area,
        ascending,
        descending,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cmd_loops::DEFAULT_AMPLITUDE_FRACTIONS;
    use crate::params_io;

    /// Tolerance for comparing outputs that should agree exactly in exact arithmetic: the core
    /// evaluates `M = 2 μ(P₊) - Σw` from f32 prefix sums and per-vertex running sums, each a
    /// handful (≤ 8) of f32 roundings of quantities bounded by `Σw`; doubled and subtracted that
    /// is at most 16 units of `ε Σw` (ε = f32::EPSILON).
    fn tol(total: f64) -> f64 {
        16.0 * f64::from(f32::EPSILON) * total
    }

    fn baked() -> (LoadedParams, PreisachMeasure, f64) {
        let loaded = params_io::load(None).unwrap();
        let measure = loaded.measure();
        let total = f64::from(measure.saturation_a_per_m());
        (loaded, measure, total)
    }

    fn default_set() -> (LoopSet, f64) {
        let (loaded, measure, total) = baked();
        let half = 0.5
            * f64::from(
                loaded.params.preisach.h_max_a_per_m - loaded.params.preisach.h_min_a_per_m,
            );
        let amps: Vec<f64> = DEFAULT_AMPLITUDE_FRACTIONS
            .iter()
            .map(|f| f * half)
            .collect();
        (trace(&loaded, &measure, &amps, 200).unwrap(), total)
    }

    #[test]
    fn major_loop_saturates_at_the_total_mass_and_closes() {
        let (set, total) = default_set();
        let asc = &set.major.ascending;
        assert!(
            (asc[0].1 + total).abs() <= tol(total),
            "M(h_min) = {}",
            asc[0].1
        );
        assert!((asc[asc.len() - 1].1 - total).abs() <= tol(total));
        assert!(set.major.closure_error_a_per_m <= tol(total));
        // Descending branch above ascending (counter-clockwise loop): positive loss.
        assert!(set.major.loss_j_per_m3 > 0.0);
        let (hc_up, hc_down) = set.major.coercive_a_per_m;
        assert!(hc_up.unwrap() > 0.0 && hc_down.unwrap() < 0.0);
    }

    /// Order preservation / wiping-out: each symmetric minor loop traced from the demagnetized
    /// state lies between the branches of the major loop and of every larger minor loop, on
    /// samples at the same field.
    #[test]
    fn minor_loops_are_closed_and_nested() {
        let (set, total) = default_set();
        let mut loops: Vec<&ClosedLoop> = vec![&set.major];
        loops.extend(&set.symmetric);
        for l in &loops {
            assert!(l.closure_error_a_per_m <= tol(total), "{}", l.name);
        }
        // Compare at the inner loop's own sample fields against the outer loop's branches
        // evaluated exactly there (no interpolation error to allow for).
        let (_, measure, _) = baked();
        for w in loops.windows(2) {
            let (outer, inner) = (w[0], w[1]);
            let mut up = measure.demagnetized::<64>();
            measure.apply(&mut up, outer.h_hi_a_per_m as f32).unwrap();
            measure.apply(&mut up, outer.h_lo_a_per_m as f32).unwrap();
            let mut down = up.clone();
            measure.apply(&mut down, outer.h_hi_a_per_m as f32).unwrap();
            for &(h, m) in &inner.ascending {
                let m_outer = f64::from(measure.apply(&mut up.clone(), h as f32).unwrap());
                assert!(
                    m >= m_outer - tol(total),
                    "{} ↑ at {h}: {m} < {m_outer}",
                    inner.name
                );
            }
            for &(h, m) in &inner.descending {
                let m_outer = f64::from(measure.apply(&mut down.clone(), h as f32).unwrap());
                assert!(
                    m <= m_outer + tol(total),
                    "{} ↓ at {h}: {m} > {m_outer}",
                    inner.name
                );
            }
            assert!(inner.loss_j_per_m3 < outer.loss_j_per_m3);
        }
    }

    #[test]
    fn biased_loop_spans_the_trajectory_band() {
        let (set, total) = default_set();
        let (m_lo, m_hi) = set.biased.m_range();
        let (band_lo, band_hi) = set.biased_band_a_per_m;
        assert!(!set.biased_clamped);
        assert!((m_lo - band_lo).abs() <= tol(total), "{m_lo} vs {band_lo}");
        assert!((m_hi - band_hi).abs() <= tol(total), "{m_hi} vs {band_hi}");
        assert!(set.biased.closure_error_a_per_m <= tol(total));
        assert!(
            set.biased.h_lo_a_per_m > set.h_center_a_per_m,
            "biased loop sits at positive H"
        );
    }

    #[test]
    fn amplitude_outside_the_range_is_rejected() {
        let (loaded, measure, _) = baked();
        let err = trace(&loaded, &measure, &[1e9], 10).unwrap_err();
        assert!(err.to_string().contains("--amplitudes"), "{err}");
        assert!(trace(&loaded, &measure, &[-1.0], 10).is_err());
        assert!(trace(&loaded, &measure, &[f64::NAN], 10).is_err());
    }
}
