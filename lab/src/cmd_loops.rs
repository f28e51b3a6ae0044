//! `maglab loops`: the hysteresis loops of the Preisach operator `M = Γ[H]` (paper Section 2)
//! for one parameter set, traced with the no_std core exactly as the firmware evaluates it.
//!
//! Starting from the demagnetized state (the staircase along `α = -β`) it traces
//! * the initial magnetization curve, from the centre of the field range up to `h_max`;
//! * the major loop between `h_min` and `h_max` (saturating at `±Σw`, `= ±M_s` for the default
//!   measure);
//! * symmetric minor loops `±A` around the centre, each from a fresh demagnetized state (first
//!   `+A`, then `-A`, then the recorded cycle `-A → +A → -A`); by the wiping-out property the
//!   recorded cycle closes exactly and each lies inside the loops of larger amplitude;
//! * a biased minor loop like the controller drives: the magnetization band that the static model
//!   (6), `y = l_m λ_s M² / M_s²`, maps onto the trajectory's displacement band
//!   `[displacement_min_m, displacement_max_m]`, reached from the demagnetized state with the
//!   core's exact inverse (up to `M_hi`, down to `M_lo`) and then cycled.
//!
//! It prints `M` on the branches at a few fields, and per loop the coercive fields (exact inverse
//! `Γ⁻¹(0)` on each branch), the remanences (`M` at the centre field), the hysteresis loss
//! `μ0 ∮ H dM` and the closure error; it plots `M` against `H` (`loops.png/.svg`) and the static
//! model's displacement `y` against the current `I = H / c0` (`displacement.png/.svg`, the
//! butterfly curve).

use crate::params_io::{self, LoadedParams};
use crate::plot::{Figure, Panel, Series, PALETTE};
use anyhow::{anyhow, bail, Context, Result};
use clap::Parser;
use magctl::preisach::{PreisachMeasure, PreisachState, Saturation};
use plotters::prelude::SeriesLabelPosition;
use std::path::PathBuf;

/// Arguments of `maglab loops`.
#[derive(Debug, Parser)]
pub struct Args {
    /// Parameter file (JSON, see docs/params.md); default: the parameters baked into this build.
    #[arg(long, value_name = "FILE")]
    params: Option<PathBuf>,
    /// Directory for loops.png/.svg and displacement.png/.svg.
    #[arg(long, value_name = "DIR", default_value = "out")]
    out: PathBuf,
    /// Amplitudes of the symmetric minor loops around the centre of the field range, kA/m,
    /// comma-separated. Default: 2/3, 2/5 and 1/5 of the half-range.
    #[arg(long, value_name = "KA_PER_M", value_delimiter = ',', num_args = 1..)]
    amplitudes: Vec<f64>,
    /// Samples per monotone branch.
    #[arg(long, default_value_t = 400, value_parser = clap::value_parser!(u32).range(10..=100_000))]
    points: u32,
}

/// Default minor-loop amplitudes as fractions of the half-range `(h_max - h_min) / 2`.
const DEFAULT_AMPLITUDE_FRACTIONS: [f64; 3] = [2.0 / 3.0, 2.0 / 5.0, 1.0 / 5.0];

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
    fn m_range(&self) -> (f64, f64) {
        self.ascending
            .iter()
            .chain(&self.descending)
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
                (lo.min(p.1), hi.max(p.1))
            })
    }

    /// The closed polyline: ascending then descending.
    fn polyline(&self) -> impl Iterator<Item = (f64, f64)> + '_ {
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

/// Runs `maglab loops`.
pub fn run(args: &Args) -> Result<()> {
    let loaded = params_io::load(args.params.as_deref())?;
    let measure = loaded.measure();
    let grid = &loaded.params.preisach;
    let half_range = 0.5 * f64::from(grid.h_max_a_per_m - grid.h_min_a_per_m);
    let amplitudes_a_per_m: Vec<f64> = if args.amplitudes.is_empty() {
        DEFAULT_AMPLITUDE_FRACTIONS
            .iter()
            .map(|f| f * half_range)
            .collect()
    } else {
        args.amplitudes.iter().map(|a| a * 1e3).collect()
    };
    let set = trace(&loaded, &measure, &amplitudes_a_per_m, args.points as usize)?;
    print_report(&loaded, &measure, &set)?;
    let files = plot(&loaded, &set, &args.out)?;
    println!();
    for f in files {
        println!("wrote {}", f.display());
    }
    Ok(())
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

fn apply(measure: &PreisachMeasure, state: &mut PreisachState, h_a_per_m: f64) -> Result<f64> {
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

fn opt_ka(v: Option<f64>) -> String {
    v.map_or("—".to_string(), |v| format!("{:+.2}", v / 1e3))
}

fn print_report(loaded: &LoadedParams, measure: &PreisachMeasure, set: &LoopSet) -> Result<()> {
    let act = &loaded.params.actuator;
    let grid = &loaded.params.preisach;
    let m_s = f64::from(act.saturation_magnetization_a_per_m);
    let total = f64::from(measure.saturation_a_per_m());
    let c0 = f64::from(act.coil_factor_per_m);
    let stroke_um = f64::from(act.stroke_m()) * 1e6;
    println!(
        "Preisach operator Γ: 25 levels over [{:.1}, {:.1}] kA/m (cell width {:.2} kA/m)",
        grid.h_min_a_per_m / 1e3,
        grid.h_max_a_per_m / 1e3,
        measure.cell_width_a_per_m() / 1e3
    );
    println!("parameters: {} ({})", loaded.origin, loaded.provenance);
    println!(
        "M_s = {:.1} kA/m, Σw = {:.1} kA/m, stroke l_m λ_s = {:.2} µm, c0 = {:.4e} 1/m (I = H/c0)",
        m_s / 1e3,
        total / 1e3,
        stroke_um,
        c0
    );

    // M on the branches at nine fields, evaluated exactly from each branch's start state.
    let h_min = f64::from(grid.h_min_a_per_m);
    let h_max = f64::from(grid.h_max_a_per_m);
    println!();
    println!("M (kA/m) on the branches; I = H/c0");
    println!(
        "{:>10} {:>8} {:>10} {:>10} {:>10}",
        "H (kA/m)", "I (A)", "initial", "major ↓", "major ↑"
    );
    let demag: PreisachState = measure.demagnetized();
    let pos: PreisachState = measure.positive_saturation();
    let neg: PreisachState = measure.negative_saturation();
    for k in 0..=8 {
        let h = h_min + (h_max - h_min) * k as f64 / 8.0;
        let initial = if h >= set.h_center_a_per_m {
            format!("{:.1}", apply(measure, &mut demag.clone(), h)? / 1e3)
        } else {
            "—".into()
        };
        println!(
            "{:>10.2} {:>8.3} {:>10} {:>10.1} {:>10.1}",
            h / 1e3,
            h / c0,
            initial,
            apply(measure, &mut pos.clone(), h)? / 1e3,
            apply(measure, &mut neg.clone(), h)? / 1e3
        );
    }
    println!(
        "saturation: M(h_max) = {:.2} kA/m, M(h_min) = {:.2} kA/m (Σw = {:.2} kA/m, {:.2} % of M_s)",
        set.major.ascending[set.major.ascending.len() - 1].1 / 1e3,
        set.major.ascending[0].1 / 1e3,
        total / 1e3,
        100.0 * total / m_s
    );

    println!();
    println!(
        "{:<24} {:>17} {:>17} {:>15} {:>15} {:>13} {:>14} {:>9}",
        "loop",
        "H range (kA/m)",
        "M range (kA/m)",
        "H_c ↑/↓ (kA/m)",
        "M_r ↑/↓ (kA/m)",
        "y range (µm)",
        "μ0∮H dM (J/m³)",
        "closure"
    );
    let loops = std::iter::once(&set.major)
        .chain(&set.symmetric)
        .chain(std::iter::once(&set.biased));
    for l in loops {
        let (m_lo, m_hi) = l.m_range();
        let y = |m: f64| stroke_um * (m / m_s).powi(2);
        // y = l_m λ_s M²/M_s² is smallest where M is closest to zero.
        let y_min = if m_lo <= 0.0 && m_hi >= 0.0 {
            0.0
        } else {
            y(m_lo).min(y(m_hi))
        };
        let y_max = y(m_lo).max(y(m_hi));
        println!(
            "{:<24} {:>17} {:>17} {:>15} {:>15} {:>13} {:>14.1} {:>7.1e} A/m",
            l.name,
            format!("[{:.2}, {:.2}]", l.h_lo_a_per_m / 1e3, l.h_hi_a_per_m / 1e3),
            format!("[{:.1}, {:.1}]", m_lo / 1e3, m_hi / 1e3),
            format!(
                "{}/{}",
                opt_ka(l.coercive_a_per_m.0),
                opt_ka(l.coercive_a_per_m.1)
            ),
            format!(
                "{}/{}",
                opt_ka(l.remanence_a_per_m.0),
                opt_ka(l.remanence_a_per_m.1)
            ),
            format!("[{:.1}, {:.1}]", y_min, y_max),
            l.loss_j_per_m3,
            l.closure_error_a_per_m
        );
    }
    let (band_lo, band_hi) = set.biased_band_a_per_m;
    println!(
        "biased loop: M band [{:.1}, {:.1}] kA/m from the trajectory band via (6){}",
        band_lo / 1e3,
        band_hi / 1e3,
        if set.biased_clamped {
            " — CLAMPED: the band needs more than ±Σw"
        } else {
            ""
        }
    );
    Ok(())
}

/// One traced curve in `(H, M)`, A/m, with its legend name and style.
struct Curve {
    name: String,
    color: plotters::style::RGBColor,
    width: u32,
    points: Vec<(f64, f64)>,
}

fn plot(loaded: &LoadedParams, set: &LoopSet, out: &std::path::Path) -> Result<Vec<PathBuf>> {
    let act = &loaded.params.actuator;
    let m_s = f64::from(act.saturation_magnetization_a_per_m);
    let c0 = f64::from(act.coil_factor_per_m);
    let stroke_um = f64::from(act.stroke_m()) * 1e6;
    let source = loaded
        .origin
        .rsplit('/')
        .next()
        .unwrap_or(&loaded.origin)
        .to_string();

    // Drawn in this order, so the major loop lies on top of the minor loops and the initial
    // curve where they coincide.
    let curve = |name: &str, color: usize, width: u32, points: Vec<(f64, f64)>| Curve {
        name: name.to_string(),
        color: PALETTE[color],
        width,
        points,
    };
    let mut curves = Vec::new();
    for (k, l) in set.symmetric.iter().enumerate() {
        curves.push(curve(
            &l.name,
            [1, 2, 3, 4, 6][k % 5],
            2,
            l.polyline().collect(),
        ));
    }
    curves.push(curve("initial curve", 7, 3, set.initial.clone()));
    curves.push(curve(&set.major.name, 0, 2, set.major.polyline().collect()));
    curves.push(curve(
        &set.biased.name,
        5,
        3,
        set.biased.polyline().collect(),
    ));

    let mut mh = Panel::new(
        &format!("Preisach loops M = Γ[H] ({source})"),
        "H (kA/m)",
        "M (kA/m)",
    );
    let mut yi = Panel::new(
        &format!("Static model (6): y = l_m λ_s M²/M_s² ({source})"),
        "I = H/c0 (A)",
        "y (µm)",
    );
    yi.legend = SeriesLabelPosition::UpperMiddle;
    let (h_lo, h_hi) = (set.major.h_lo_a_per_m / 1e3, set.major.h_hi_a_per_m / 1e3);
    for (sign, label) in [(1.0, Some("±M_s".to_string())), (-1.0, None)] {
        mh.series.push(Series {
            label,
            points: vec![(h_lo, sign * m_s / 1e3), (h_hi, sign * m_s / 1e3)],
            color: PALETTE[7],
            width: 1,
        });
    }
    yi.series.push(Series {
        label: Some("stroke l_m λ_s".into()),
        points: vec![(h_lo * 1e3 / c0, stroke_um), (h_hi * 1e3 / c0, stroke_um)],
        color: PALETTE[7],
        width: 1,
    });
    for c in &curves {
        mh.series.push(Series {
            label: Some(c.name.clone()),
            points: c.points.iter().map(|&(h, m)| (h / 1e3, m / 1e3)).collect(),
            color: c.color,
            width: c.width,
        });
        yi.series.push(Series {
            label: Some(c.name.clone()),
            points: c
                .points
                .iter()
                .map(|&(h, m)| (h / c0, stroke_um * (m / m_s).powi(2)))
                .collect(),
            color: c.color,
            width: c.width,
        });
    }
    let mut files = Figure {
        panels: vec![mh],
        rows: 1,
        cols: 1,
        size_px: (1000, 750),
    }
    .write(&out.join("loops"))
    .context("writing the M-H plot")?;
    files.extend(
        Figure {
            panels: vec![yi],
            rows: 1,
            cols: 1,
            size_px: (1000, 750),
        }
        .write(&out.join("displacement"))
        .context("writing the displacement plot")?,
    );
    Ok(files)
}

#[cfg(test)]
mod tests {
    use super::*;

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
