//! The figures: `M` against `H` (`loops.png/.svg`) and the static model's displacement against
//! the coil current (`displacement.png/.svg`, the butterfly curve).

use super::LoopSet;
use crate::params_io::LoadedParams;
use crate::plot::{Figure, Panel, Series, PALETTE};
use anyhow::{Context, Result};
use plotters::prelude::SeriesLabelPosition;
use std::path::PathBuf;

/// One traced curve in `(H, M)`, A/m, with its legend name and style.
struct Curve {
    name: String,
    color: plotters::style::RGBColor,
    width: u32,
    points: Vec<(f64, f64)>,
}

/// Writes both figures into `out`; returns the files written.
pub(super) fn plot(
    loaded: &LoadedParams,
    set: &LoopSet,
    out: &std::path::Path,
) -> Result<Vec<PathBuf>> {
    let act = &loaded.params.actuator;
    let scales = Scales {
        saturation_a_per_m: f64::from(act.saturation_magnetization_a_per_m),
        coil_factor_per_m: f64::from(act.coil_factor_per_m),
        stroke_um: f64::from(act.stroke_m()) * 1e6,
    };
    let source = loaded
        .origin
        .rsplit('/')
        .next()
        .unwrap_or(&loaded.origin)
        .to_string();
    let curves = curves(set);
    let h_range_a_per_m = (set.major.h_lo_a_per_m, set.major.h_hi_a_per_m);
    let mut files = one_panel(
        magnetization_panel(&curves, &scales, h_range_a_per_m, &source),
        &out.join("loops"),
    )
    .context("writing the M-H plot")?;
    files.extend(
        one_panel(
            displacement_panel(&curves, &scales, h_range_a_per_m, &source),
            &out.join("displacement"),
        )
        .context("writing the displacement plot")?,
    );
    Ok(files)
}

/// The rod's constants the figures scale by.
struct Scales {
    saturation_a_per_m: f64,
    coil_factor_per_m: f64,
    stroke_um: f64,
}

/// The loops to draw, in drawing order: the symmetric minor loops, the initial curve, the major
/// loop on top of them and the biased loop, so the major loop lies over the minor ones and the
/// initial curve shows where they coincide.
fn curves(set: &LoopSet) -> Vec<Curve> {
    let curve = |name: &str, color: usize, width: u32, points: Vec<(f64, f64)>| Curve {
        name: name.to_string(),
        color: PALETTE[color],
        width,
        points,
    };
    let mut curves: Vec<Curve> = set
        .symmetric
        .iter()
        .enumerate()
        .map(|(k, l)| curve(&l.name, [1, 2, 3, 4, 6][k % 5], 2, l.polyline().collect()))
        .collect();
    curves.push(curve("initial curve", 7, 3, set.initial.clone()));
    curves.push(curve(&set.major.name, 0, 2, set.major.polyline().collect()));
    curves.push(curve(
        &set.biased.name,
        5,
        3,
        set.biased.polyline().collect(),
    ));
    curves
}

/// `M` against `H`, kA/m, with `±M_s` over the major loop's field range `(lo, hi)`, A/m.
fn magnetization_panel(
    curves: &[Curve],
    scales: &Scales,
    (h_lo_a_per_m, h_hi_a_per_m): (f64, f64),
    source: &str,
) -> Panel {
    let mut mh = Panel::new(
        &format!("Preisach loops M = Γ[H] ({source})"),
        "H (kA/m)",
        "M (kA/m)",
    );
    let (h_lo, h_hi) = (h_lo_a_per_m / 1e3, h_hi_a_per_m / 1e3);
    for (sign, label) in [(1.0, Some("±M_s".to_string())), (-1.0, None)] {
        mh.series.push(Series {
            label,
            points: vec![
                (h_lo, sign * scales.saturation_a_per_m / 1e3),
                (h_hi, sign * scales.saturation_a_per_m / 1e3),
            ],
            color: PALETTE[7],
            width: 1,
        });
    }
    for c in curves {
        mh.series.push(Series {
            label: Some(c.name.clone()),
            points: c.points.iter().map(|&(h, m)| (h / 1e3, m / 1e3)).collect(),
            color: c.color,
            width: c.width,
        });
    }
    mh
}

/// The static model's displacement (6), µm, against the coil current `H/c0`, with the stroke
/// over the major loop's field range `(lo, hi)`, A/m.
fn displacement_panel(
    curves: &[Curve],
    scales: &Scales,
    (h_lo_a_per_m, h_hi_a_per_m): (f64, f64),
    source: &str,
) -> Panel {
    let mut yi = Panel::new(
        &format!("Static model (6): y = l_m λ_s M²/M_s² ({source})"),
        "I = H/c0 (A)",
        "y (µm)",
    );
    yi.legend = SeriesLabelPosition::UpperMiddle;
    yi.series.push(Series {
        label: Some("stroke l_m λ_s".into()),
        points: vec![
            (h_lo_a_per_m / scales.coil_factor_per_m, scales.stroke_um),
            (h_hi_a_per_m / scales.coil_factor_per_m, scales.stroke_um),
        ],
        color: PALETTE[7],
        width: 1,
    });
    for c in curves {
        yi.series.push(Series {
            label: Some(c.name.clone()),
            points: c
                .points
                .iter()
                .map(|&(h, m)| {
                    (
                        h / scales.coil_factor_per_m,
                        scales.stroke_um * (m / scales.saturation_a_per_m).powi(2),
                    )
                })
                .collect(),
            color: c.color,
            width: c.width,
        });
    }
    yi
}

/// A figure of one panel, 1000 × 750 px, as PNG and SVG at `stem`.
fn one_panel(panel: Panel, stem: &std::path::Path) -> Result<Vec<PathBuf>> {
    Figure {
        panels: vec![panel],
        rows: 1,
        cols: 1,
        size_px: (1000, 750),
    }
    .write(stem)
}
