//! The figures of `maglab diagnose`: the residual by frequency band, the loops and the residual
//! spectrum at the worst experiment, the held-out ranking of the candidates.

use crate::plot::{Figure, Panel, Series, PALETTE};
use anyhow::Result;
use maglab_diagnose::diagnosis::{CandidateResult, Diagnosis, DiagnosisRun};
use maglab_signal::spectrum;
use std::path::Path;

/// Writes every figure of `run` into `out`; returns their names (stems).
pub fn write_all(run: &DiagnosisRun, out: &Path) -> Result<Vec<&'static str>> {
    let d = &run.diagnosis;
    let label = if d.verdict == "none" || d.verdict == "unexplained" {
        format!(
            "best candidate ({})",
            d.ranking.first().map(|c| c.effect.as_str()).unwrap_or("-")
        )
    } else {
        format!("with {}", d.verdict)
    };
    let mut names = Vec::new();
    if let Some(best) = d.ranking.first() {
        error_vs_frequency(d, best, &label).write(&out.join("error_vs_frequency"))?;
        names.push("error_vs_frequency");
    }
    let worst = d
        .where_
        .experiments
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.relative_rms.total_cmp(&b.1.relative_rms))
        .map(|(k, _)| k)
        .unwrap_or(0);
    loops_at(run, worst, &label).write(&out.join("loops_worst"))?;
    names.push("loops_worst");
    ranking(d).write(&out.join("ranking"))?;
    names.push("ranking");
    residual_spectrum(run, worst, &label).write(&out.join("residual_spectrum"))?;
    names.push("residual_spectrum");
    Ok(names)
}

/// The RMS residual by frequency band: the refitted nominal model, the verdict's (or best)
/// candidate `best`, the noise level, the held-out bands marked.
fn error_vs_frequency(d: &Diagnosis, best: &CandidateResult, label: &str) -> Figure {
    let mut panel = Panel::new(
        "RMS residual by frequency band",
        "frequency (Hz)",
        "RMS residual (µm)",
    );
    panel.series.push(Series {
        label: Some("nominal, refitted".into()),
        points: best
            .per_band
            .iter()
            .map(|b| (b.frequency_hz, b.before_m * 1e6))
            .collect(),
        color: PALETTE[0],
        width: 2,
    });
    panel.series.push(Series {
        label: Some(label.to_string()),
        points: best
            .per_band
            .iter()
            .map(|b| (b.frequency_hz, b.after_m * 1e6))
            .collect(),
        color: PALETTE[2],
        width: 2,
    });
    panel.series.push(Series {
        label: Some("noise level".into()),
        points: best
            .per_band
            .iter()
            .map(|b| (b.frequency_hz, d.noise_m * 1e6))
            .collect(),
        color: PALETTE[7],
        width: 1,
    });
    for b in best.per_band.iter().filter(|b| b.held_out) {
        panel.series.push(Series {
            label: None,
            points: vec![(b.frequency_hz, 0.0), (b.frequency_hz, b.before_m * 1e6)],
            color: PALETTE[6],
            width: 1,
        });
    }
    panel.y_range = Some((
        0.0,
        best.per_band
            .iter()
            .map(|b| b.before_m.max(b.after_m))
            .fold(d.noise_m, f64::max)
            * 1.15e6,
    ));
    Figure {
        panels: vec![panel],
        rows: 1,
        cols: 1,
        size_px: (900, 520),
    }
}

/// Measured, nominal and the verdict's displacement against current over the last period of
/// experiment `worst`.
fn loops_at(run: &DiagnosisRun, worst: usize, label: &str) -> Figure {
    let d = &run.diagnosis;
    let t = &run.traces[worst];
    let info = &d.experiments[worst];
    let period = (t.rate_hz / info.fundamental_hz).round() as usize;
    let n = t.current_a.len();
    // The last full period plus its closing sample, so the loop is drawn closed.
    let start = n.saturating_sub((period + 1).clamp(2, n));
    let mut panel = Panel::new(
        &format!("Loops at {:.0} Hz ({})", info.fundamental_hz, t.name),
        "current (A)",
        "displacement (µm)",
    );
    for (name, ys, color) in [
        ("measured", &t.measured_m, PALETTE[0]),
        ("nominal", &t.nominal_m, PALETTE[1]),
        (label, &t.augmented_m, PALETTE[2]),
    ] {
        panel.series.push(Series {
            label: Some(name.to_string()),
            points: (start..n).map(|k| (t.current_a[k], ys[k] * 1e6)).collect(),
            color,
            width: 2,
        });
    }
    Figure {
        panels: vec![panel],
        rows: 1,
        cols: 1,
        size_px: (900, 620),
    }
}

/// The held-out RMS residual of every candidate against the refitted nominal model's.
fn ranking(d: &Diagnosis) -> Figure {
    let mut panel = Panel::new(
        "Held-out RMS residual per candidate (nominal: black line)",
        "candidate rank",
        "held-out RMS (µm)",
    );
    if let Some(first) = d.ranking.first() {
        let nominal = first.held_out_rms_before_m * 1e6;
        panel.series.push(Series {
            label: Some("nominal".into()),
            points: vec![(0.4, nominal), (d.ranking.len() as f64 + 0.6, nominal)],
            color: PALETTE[0],
            width: 2,
        });
        for (k, c) in d.ranking.iter().enumerate() {
            panel.series.push(Series {
                label: Some(format!("{}. {}", k + 1, c.effect)),
                points: vec![
                    (k as f64 + 1.0, 0.0),
                    (k as f64 + 1.0, c.held_out_rms_after_m * 1e6),
                ],
                color: PALETTE[1 + k % 7],
                width: 18,
            });
        }
        panel.x_range = Some((0.4, d.ranking.len() as f64 + 0.6));
        panel.y_range = Some((
            0.0,
            nominal.max(
                d.ranking
                    .iter()
                    .map(|c| c.held_out_rms_after_m * 1e6)
                    .fold(0.0, f64::max),
            ) * 1.5,
        ));
        panel.legend = plotters::prelude::SeriesLabelPosition::UpperRight;
    }
    Figure {
        panels: vec![panel],
        rows: 1,
        cols: 1,
        size_px: (900, 560),
    }
}

/// The residual spectrum of experiment `worst`, nominal and with the verdict's model.
fn residual_spectrum(run: &DiagnosisRun, worst: usize, label: &str) -> Figure {
    let d = &run.diagnosis;
    let t = &run.traces[worst];
    let info = &d.experiments[worst];
    let s0 = info.settle_samples;
    let resid = |ys: &[f64]| -> Vec<f64> {
        t.measured_m[s0..]
            .iter()
            .zip(&ys[s0..])
            .map(|(a, b)| a - b)
            .collect()
    };
    let mut panel = Panel::new(
        &format!(
            "Residual spectrum at {:.0} Hz ({})",
            info.fundamental_hz, t.name
        ),
        "frequency (Hz)",
        "log10 amplitude (m)",
    );
    for (name, ys, color) in [
        ("nominal", &t.nominal_m, PALETTE[1]),
        (label, &t.augmented_m, PALETTE[2]),
    ] {
        let spec = spectrum::amplitude_spectrum(&resid(ys), t.rate_hz, true);
        panel.series.push(Series {
            label: Some(name.to_string()),
            points: spec
                .iter()
                .skip(1)
                .map(|&(f, a)| (f, a.max(1e-14).log10()))
                .collect(),
            color,
            width: 1,
        });
    }
    panel.legend = plotters::prelude::SeriesLabelPosition::UpperRight;
    Figure {
        panels: vec![panel],
        rows: 1,
        cols: 1,
        size_px: (900, 520),
    }
}
