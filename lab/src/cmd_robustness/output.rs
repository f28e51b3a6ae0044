//! What the matrix writes: `robustness.csv` (read back by `--plot-only`), `transient.csv`, the
//! per-tick traces, the printed tables and the bar chart.

use super::closed_loop::{RunStats, Trace, SETTLED_PCT};
use super::Row;
use crate::plot::PALETTE;
use crate::plot_bars::{BarChart, BarSeries};
use anyhow::{bail, Context, Result};
use std::io::Write;
use std::path::{Path, PathBuf};

/// One case's traces as CSV.
pub fn write_trace(
    dir: &Path,
    name: &str,
    rate_hz: f64,
    open: &Trace,
    closed: &Trace,
) -> Result<()> {
    let file: String = name
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                c
            } else {
                '_'
            }
        })
        .collect();
    let path = dir.join(format!("{file}.csv"));
    let mut f = std::io::BufWriter::new(
        std::fs::File::create(&path).with_context(|| format!("cannot write {}", path.display()))?,
    );
    writeln!(
        f,
        "t_s,desired_m,open_loop_m,closed_loop_m,closed_loop_current_a,closed_loop_flags"
    )?;
    for k in 0..closed.desired_m.len() {
        writeln!(
            f,
            "{:.6},{:e},{:e},{:e},{:e},{}",
            (k + 1) as f64 / rate_hz,
            closed.desired_m[k],
            open.actual_m[k],
            closed.actual_m[k],
            closed.current_a[k],
            closed.flags[k]
        )?;
    }
    f.flush()
        .with_context(|| format!("cannot write {}", path.display()))
}

/// The CSV of the matrix.
pub fn write_csv(path: &Path, rows: &[Row]) -> Result<()> {
    let mut f = std::io::BufWriter::new(
        std::fs::File::create(path).with_context(|| format!("cannot write {}", path.display()))?,
    );
    writeln!(
        f,
        "case,open_loop_rms_pct,closed_loop_rms_pct,closed_loop_max_pct,current_rms_a"
    )?;
    for r in rows {
        writeln!(
            f,
            "{},{:.4},{:.4},{:.4},{:.4}",
            r.case,
            r.open_loop.rms_pct,
            r.closed_loop.rms_pct,
            r.closed_loop.max_pct,
            r.closed_loop.current_rms_a
        )?;
    }
    f.flush()
        .with_context(|| format!("cannot write {}", path.display()))
}

/// Reads a robustness.csv back (for `--plot-only`).
pub fn read_csv(path: &Path) -> Result<Vec<Row>> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    let mut rows = Vec::new();
    for (n, line) in text.lines().enumerate().skip(1) {
        let c: Vec<&str> = line.split(',').collect();
        if c.len() != 5 {
            bail!(
                "{}: line {}: expected 5 columns, got {}",
                path.display(),
                n + 1,
                c.len()
            );
        }
        let f = |i: usize| -> Result<f64> {
            c[i].parse().map_err(|_| {
                anyhow::anyhow!(
                    "{}: line {}: `{}` is not a number",
                    path.display(),
                    n + 1,
                    c[i]
                )
            })
        };
        let stats = |rms: f64, max: f64, current: f64| RunStats {
            rms_pct: rms,
            max_pct: max,
            current_rms_a: current,
            sensor_fault_ticks: 0,
        };
        rows.push(Row {
            case: c[0].to_string(),
            open_loop: stats(f(1)?, f64::NAN, f64::NAN),
            closed_loop: stats(f(2)?, f(3)?, f(4)?),
            transient: None,
        });
    }
    Ok(rows)
}

/// The learning transient as CSV (module docs).
pub fn write_transient_csv(path: &Path, rows: &[Row]) -> Result<()> {
    let mut text = String::from("case,whole_run_rms_pct,settled_rms_pct,settle_s,settle_cycles\n");
    let opt = |v: Option<f64>| v.map_or(String::new(), |v| format!("{v:.4}"));
    for r in rows {
        if let Some(t) = r.transient {
            text += &format!(
                "{},{:.4},{:.4},{},{}\n",
                r.case,
                t.whole_run_rms_pct,
                r.closed_loop.rms_pct,
                opt(t.settle_s),
                opt(t.settle_cycles)
            );
        }
    }
    std::fs::write(path, text).with_context(|| format!("cannot write {}", path.display()))
}

/// The learning transient as text: whole run, settled window, time to settle below
/// [`SETTLED_PCT`].
pub fn transient_table(rows: &[Row], settle_window_s: f64) -> String {
    let mut s = format!(
        "learning transient (closed loop): {:<25} {:>13} {:>17} {:>22}\n",
        "case",
        "whole run RMS %",
        format!("from {settle_window_s} s RMS %"),
        format!("below {SETTLED_PCT} % from (s / cycles)")
    );
    for r in rows {
        let Some(t) = r.transient else { continue };
        let settle = match (t.settle_s, t.settle_cycles) {
            (Some(s), Some(c)) => format!("{s:.3} s / {c:.1}"),
            _ => "never".to_string(),
        };
        s += &format!(
            "  {:<56} {:>13.3} {:>17.3} {:>22}\n",
            r.case, t.whole_run_rms_pct, r.closed_loop.rms_pct, settle
        );
    }
    s
}

/// The table as text.
pub fn table(rows: &[Row]) -> String {
    let mut s = format!(
        "{:<48} {:>12} {:>12} {:>11} {:>9} {:>10}\n",
        "case", "open RMS %", "closed RMS %", "closed max %", "ratio", "I rms (A)"
    );
    for r in rows {
        s += &format!(
            "{:<48} {:>12.3} {:>12.3} {:>11.3} {:>8.1}x {:>10.3}\n",
            r.case,
            r.open_loop.rms_pct,
            r.closed_loop.rms_pct,
            r.closed_loop.max_pct,
            r.open_loop.rms_pct / r.closed_loop.rms_pct.max(1e-12),
            r.closed_loop.current_rms_a
        );
    }
    s
}

/// The plot: open- vs closed-loop RMS per case, named bars on a log axis in % of the
/// peak-to-peak, with the 1 % goal.
pub fn plot(stem: &Path, rows: &[Row]) -> Result<Vec<PathBuf>> {
    let values = |f: &dyn Fn(&Row) -> f64| rows.iter().map(f).collect::<Vec<f64>>();
    BarChart {
        title: "Robustness matrix: tracking RMS error per case".into(),
        value_label: "RMS tracking error, % of the trajectory's peak-to-peak (log scale)".into(),
        unit: "%".into(),
        cases: rows.iter().map(|r| r.case.clone()).collect(),
        series: vec![
            BarSeries {
                label: "feedforward (open loop)".into(),
                color: PALETTE[5],
                values: values(&|r| r.open_loop.rms_pct),
            },
            BarSeries {
                label: "with feedback (closed loop)".into(),
                color: PALETTE[1],
                values: values(&|r| r.closed_loop.rms_pct),
            },
        ],
        reference: Some(("1 % goal".into(), 1.0)),
    }
    .write(stem)
}
