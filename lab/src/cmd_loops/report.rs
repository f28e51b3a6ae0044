//! The printed report: `M` on the branches at a few fields, and per loop the coercive fields,
//! remanences, hysteresis loss and closure error.

use super::trace::apply;
use super::LoopSet;
use crate::params_io::LoadedParams;
use anyhow::Result;
use magctl::preisach::{PreisachMeasure, PreisachState};

fn opt_ka(v: Option<f64>) -> String {
    v.map_or("—".to_string(), |v| format!("{:+.2}", v / 1e3))
}

/// Prints the report of `set`, the loops of the Preisach measure `measure` of `loaded`.
pub(super) fn print_report(
    loaded: &LoadedParams,
    measure: &PreisachMeasure,
    set: &LoopSet,
) -> Result<()> {
    print_header(loaded, measure);
    print_branches(loaded, measure, set)?;
    print_loops(loaded, set);
    Ok(())
}

/// The grid, where the parameters come from, and the rod's saturation and stroke.
fn print_header(loaded: &LoadedParams, measure: &PreisachMeasure) {
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
}

/// `M` on the initial and major branches at nine fields across the grid, each evaluated exactly
/// from its branch's start state, and the saturation the major loop reaches.
fn print_branches(loaded: &LoadedParams, measure: &PreisachMeasure, set: &LoopSet) -> Result<()> {
    let grid = &loaded.params.preisach;
    let m_s = f64::from(loaded.params.actuator.saturation_magnetization_a_per_m);
    let total = f64::from(measure.saturation_a_per_m());
    let c0 = f64::from(loaded.params.actuator.coil_factor_per_m);
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
    Ok(())
}

/// Per loop: its field and magnetization ranges, coercive fields, remanences, stroke range,
/// hysteresis loss and closure error; then the biased loop's band.
fn print_loops(loaded: &LoadedParams, set: &LoopSet) {
    let m_s = f64::from(loaded.params.actuator.saturation_magnetization_a_per_m);
    let stroke_um = f64::from(loaded.params.actuator.stroke_m()) * 1e6;
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
}
