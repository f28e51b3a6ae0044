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

pub(super) fn plot(
    loaded: &LoadedParams,
    set: &LoopSet,
    out: &std::path::Path,
) -> Result<Vec<PathBuf>> {
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
