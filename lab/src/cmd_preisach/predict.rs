//! `maglab preisach-predict` (module docs of [`super`]).

use super::{filter, loops_figure};
use anyhow::{anyhow, bail, Context, Result};
use clap::Parser;
use maglab_identify::columns::{read_columns, ColumnSpec, Table};
use maglab_identify::model::PreisachModel;
use maglab_identify::table_fit::predict_table;
use std::path::{Path, PathBuf};

/// Arguments of `maglab preisach-predict`.
#[derive(Debug, Parser)]
pub struct PredictArgs {
    /// Model file written by `maglab preisach-fit`.
    model: PathBuf,
    /// CSV file with a header.
    file: PathBuf,
    /// Input column (default: the model's).
    #[arg(long)]
    input_col: Option<String>,
    /// Output column (default: the model's).
    #[arg(long)]
    output_col: Option<String>,
    /// Group column (runs of equal values are separate experiments). Default: the model's
    /// (the group column it was fitted with), so that each experiment starts from the model's
    /// initial state.
    #[arg(long, conflicts_with = "no_group")]
    group_col: Option<String>,
    /// Score the whole file as one experiment even if the model was fitted with groups.
    #[arg(long)]
    no_group: bool,
    /// Rows that are scored: COL=V1,V2,... or COL=LO..HI. Default: all rows.
    #[arg(long, value_name = "FILTER")]
    score_rows: Option<String>,
    /// Predicted CSV (group, line, input, measured, predicted, scored).
    #[arg(short, long, default_value = "out/predicted.csv")]
    output: PathBuf,
    /// Path stem of the loop plot.
    #[arg(long, default_value = "out/predicted-loops")]
    plot: PathBuf,
}

/// The group column a model was fitted with (recorded in its provenance), if any.
fn model_group_column(model: &PreisachModel) -> Option<String> {
    model
        .provenance
        .get("group_column")
        .and_then(|g| g.as_str())
        .map(str::to_string)
}

/// Runs `preisach-predict`.
pub fn run_predict(args: &PredictArgs) -> Result<()> {
    let model = PreisachModel::load(&args.model).map_err(|e| anyhow!(e))?;
    let group = if args.no_group {
        None
    } else {
        args.group_col
            .clone()
            .or_else(|| model_group_column(&model))
    };
    let spec = ColumnSpec {
        input: args
            .input_col
            .clone()
            .unwrap_or_else(|| model.input_column.clone()),
        output: args
            .output_col
            .clone()
            .unwrap_or_else(|| model.output_column.clone()),
        group,
        filter: filter(args.score_rows.as_deref())?,
    };
    let table = read_columns(&args.file, &spec)?;
    let (predictions, score) = predict_table(&model, &table);
    println!(
        "experiments: {} (initial state {})",
        match (&spec.group, args.group_col.is_some(), args.no_group) {
            (Some(g), true, _) => format!("runs of equal `{g}` (--group-col)"),
            (Some(g), false, _) => format!("runs of equal `{g}` (the model's group column)"),
            (None, _, true) => "the whole file (--no-group)".to_string(),
            (None, _, false) => "the whole file (the model was fitted without groups)".to_string(),
        },
        if model.closed_loops_periodic {
            format!(
                "periodic for a closed loop, else {}, each judged on its own",
                model.initial_state.name()
            )
        } else {
            format!("{} each", model.initial_state.name())
        }
    );
    let outside: usize = table
        .series
        .iter()
        .flat_map(|s| s.input.iter())
        .filter(|&&u| u < model.h_min || u > model.h_max)
        .count();
    println!(
        "model {} on {}: {} experiments, {} rows, scored rows ({}): {}",
        args.model.display(),
        table.path.display(),
        table.series.len(),
        table.rows(),
        spec.filter.describe(),
        table.selected_rows()
    );
    if outside > 0 {
        println!(
            "{outside} samples lie outside the model's input range [{:.6e}, {:.6e}] (memory saturated there)",
            model.h_min, model.h_max
        );
    }
    let groups = group_scores(&table, &predictions);
    if groups.len() > 1 {
        println!(
            "per experiment (scored rows): rows, RMS error in `{}` units, NRMSE of its own range",
            spec.output
        );
        for g in &groups {
            println!(
                "  {:>12}: {:>6} rows, RMS {:.4e}, NRMSE {}",
                g.label,
                g.rows,
                g.rms,
                g.nrmse.map_or("n/a (no output range)".into(), |s| format!(
                    "{:.4} %",
                    100.0 * s
                ))
            );
        }
    }
    let (rows, sq) = groups.iter().fold((0usize, 0.0f64), |(n, s), g| {
        (n + g.rows, s + g.rms * g.rms * g.rows as f64)
    });
    match score {
        Some(s) => println!(
            "NRMSE {:.4} % of the measured range; RMS {:.4e} `{}` over {rows} scored rows",
            100.0 * s,
            (sq / rows.max(1) as f64).sqrt(),
            spec.output
        ),
        None => bail!("no scored rows with an output range: nothing to compare"),
    }
    write_predicted(&args.output, &table, &predictions, &spec)?;
    println!("wrote {}", args.output.display());
    for p in loops_figure(&table, &predictions, &spec, "predicted")?.write(&args.plot)? {
        println!("wrote {}", p.display());
    }
    Ok(())
}

/// The score of one experiment.
struct GroupScore {
    label: String,
    rows: usize,
    /// RMS error over its scored rows, output units.
    rms: f64,
    /// RMS error / measured range of its scored rows.
    nrmse: Option<f64>,
}

fn group_scores(table: &Table, predictions: &[Vec<f64>]) -> Vec<GroupScore> {
    table
        .series
        .iter()
        .zip(predictions)
        .filter_map(|(s, p)| {
            let pairs: Vec<(f64, f64)> = s
                .selected
                .iter()
                .zip(p.iter().zip(&s.output))
                .filter(|(&sel, _)| sel)
                .map(|(_, (&pt, &mt))| (pt, mt))
                .collect();
            if pairs.is_empty() {
                return None;
            }
            let rms = (pairs.iter().map(|(p, m)| (p - m) * (p - m)).sum::<f64>()
                / pairs.len() as f64)
                .sqrt();
            let (lo, hi) = pairs
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &(_, m)| {
                    (a.min(m), b.max(m))
                });
            Some(GroupScore {
                label: s.label.clone(),
                rows: pairs.len(),
                rms,
                nrmse: (hi > lo).then(|| rms / (hi - lo)),
            })
        })
        .collect()
}

fn write_predicted(
    path: &Path,
    table: &Table,
    predictions: &[Vec<f64>],
    spec: &ColumnSpec,
) -> Result<()> {
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir)?;
    }
    let mut text = format!(
        "experiment,line,{},{},predicted,scored\n",
        spec.input, spec.output
    );
    for (s, p) in table.series.iter().zip(predictions) {
        for (t, pt) in p.iter().enumerate() {
            text.push_str(&format!(
                "\"{}\",{},{:e},{:e},{:e},{}\n",
                s.label.replace('"', "'"),
                s.lines[t],
                s.input[t],
                s.output[t],
                pt,
                u8::from(s.selected[t])
            ));
        }
    }
    std::fs::write(path, text).with_context(|| format!("cannot write {}", path.display()))
}
