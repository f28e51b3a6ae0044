//! `maglab preisach-fit` (module docs of [`super`]).

use super::{filter, loops_figure};
use crate::plot_preisach::WeightMap;
use anyhow::{anyhow, bail, Context, Result};
use clap::Parser;
use maglab_dataset::StartState;
use maglab_identify::columns::{read_columns, ColumnSpec, Table};
use maglab_identify::fit::{FitOptions, Reversible, Unexcited};
use maglab_identify::lines::LineChoice;
use maglab_identify::memory::PREISACH_STARTS;
use maglab_identify::model::PreisachModel;
use maglab_identify::table_fit::{fit_table, predict_table, DEFAULT_RANGE_MARGIN};
use std::path::PathBuf;

/// Arguments of `maglab preisach-fit`.
#[derive(Debug, Parser)]
pub struct FitArgs {
    /// CSV file with a header.
    file: PathBuf,
    /// Input column (e.g. h_a_per_m, voltage_v).
    #[arg(long)]
    input_col: String,
    /// Output column (e.g. b_t, displacement_um).
    #[arg(long)]
    output_col: String,
    /// Column whose runs of equal values are separate experiments (own initial state).
    #[arg(long)]
    group_col: Option<String>,
    /// Rows that enter the fit: COL=V1,V2,... or COL=LO..HI (LO inclusive, HI exclusive).
    /// Default: all rows.
    #[arg(long, value_name = "FILTER")]
    fit_rows: Option<String>,
    /// Input range of the grid, LO..HI (negative ends are fine: `--levels-range -1..166`).
    /// Default: the data's range plus --margin on each side.
    #[arg(long, value_name = "LO..HI", allow_hyphen_values = true)]
    levels_range: Option<String>,
    /// Margin added to the data range on each side, fraction of the range.
    #[arg(long, default_value_t = DEFAULT_RANGE_MARGIN)]
    margin: f64,
    /// Where the 24 interior grid lines go: equal-output (each interval carries the same share of
    /// the output change the fit rows show: narrow where the loops are steep), uniform, or auto
    /// (whichever predicts held-back fit rows better: alternate blocks of every experiment's fit
    /// rows fit and predict each other; the scores are printed).
    #[arg(long, default_value = "auto")]
    grid_lines: String,
    /// Initial memory of each experiment: auto, negative-saturation, positive-saturation,
    /// demagnetized-at-first-input (AC-demagnetized around the first input), demagnetized
    /// (around zero input), periodic (the experiment is one period of a periodic steady state).
    /// `auto`: each experiment on its own: periodic when it is a closed loop (its fit rows end
    /// where they started, in input and output, within 2 % of their ranges), else
    /// demagnetized-at-first-input; the choices are printed and `preisach-predict` judges
    /// every experiment the same way.
    #[arg(long, default_value = "auto")]
    initial: String,
    /// Smoothness weight λ_s (see maglab_identify::fit), or auto: chosen from 1e-7, 1e-6, 1e-5
    /// together with the grid lines by the same validation on held-back fit rows (printed).
    #[arg(long, default_value = "auto")]
    smoothness: String,
    /// Ridge weight λ_r toward zero.
    #[arg(long, default_value_t = 0.0)]
    ridge: f64,
    /// The reversible part fitted with the masses, each with an output offset: piecewise (a
    /// monotone piecewise-linear anhysteretic curve, a slope >= 0 per grid interval, flat beyond
    /// the grid; the default), linear (one slope, continued beyond the grid), none (no offset
    /// either).
    #[arg(long, default_value = "piecewise")]
    reversible: String,
    /// Same as the default: an offset and the reversible part (kept for old command lines).
    #[arg(long, conflicts_with = "no_affine")]
    affine: bool,
    /// Fit the Preisach masses alone: `--reversible none`.
    #[arg(long)]
    no_affine: bool,
    /// Unexcited cells: regularized (set by smoothness/ridge) or zero.
    #[arg(long, default_value = "regularized")]
    unexcited: String,
    /// Use every n-th fit row in the regression (the memory still sees every row).
    #[arg(long, default_value_t = 1)]
    row_stride: usize,
    /// Output model file.
    #[arg(short, long)]
    output: PathBuf,
    /// Directory for weights.png/.svg and fit-loops.png/.svg.
    #[arg(long, default_value = "out")]
    plot_dir: PathBuf,
}

/// Runs `preisach-fit`.
pub fn run_fit(args: &FitArgs) -> Result<()> {
    let spec = ColumnSpec {
        input: args.input_col.clone(),
        output: args.output_col.clone(),
        group: args.group_col.clone(),
        filter: filter(args.fit_rows.as_deref())?,
    };
    let table = read_columns(&args.file, &spec)?;
    let range = levels_range(args)?;
    let (options, auto_smoothness) = fit_options(args)?;
    let initial = initial_state(args, &table)?;
    let lines = LineChoice::parse(&args.grid_lines).map_err(|e| anyhow!("--grid-lines: {e}"))?;
    let (model, result) = fit_table(
        &table,
        &spec,
        range,
        args.margin,
        initial,
        lines,
        auto_smoothness,
        &options,
    )?;
    print_validation(&model);
    let json = model.to_json_pretty();
    if let Some(dir) = args.output.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir)?;
    }
    std::fs::write(&args.output, json)
        .with_context(|| format!("cannot write {}", args.output.display()))?;
    let (predictions, score) = predict_table(&model, &table);
    print_fit(&table, &spec, &model, &result, score, &options, initial.0);
    println!("wrote {}", args.output.display());
    let map = WeightMap {
        title: format!("Preisach masses, {}", args.file.display()),
        axis_label: args.input_col.clone(),
        axis_scale: 1.0,
        h_min: model.h_min,
        h_max: model.h_max,
        weights: &model.weights,
        outlined: &result.unexcited,
    };
    for p in map.write(&args.plot_dir.join("weights"))? {
        println!("wrote {}", p.display());
    }
    for p in loops_figure(&table, &predictions, &spec, "fitted")?
        .write(&args.plot_dir.join("fit-loops"))?
    {
        println!("wrote {}", p.display());
    }
    Ok(())
}

/// `--levels-range LO..HI`, if given.
fn levels_range(args: &FitArgs) -> Result<Option<(f64, f64)>> {
    Ok(match &args.levels_range {
        None => None,
        Some(text) => {
            let (lo, hi) = text
                .split_once("..")
                .ok_or_else(|| anyhow!("--levels-range `{text}`: expected LO..HI"))?;
            let lo: f64 = lo
                .trim()
                .parse()
                .with_context(|| format!("--levels-range `{text}`"))?;
            let hi: f64 = hi
                .trim()
                .parse()
                .with_context(|| format!("--levels-range `{text}`"))?;
            if !(lo.is_finite() && hi.is_finite() && lo < hi) {
                bail!("--levels-range `{text}`: need finite LO < HI");
            }
            Some((lo, hi))
        }
    })
}

/// The fit's settings, and whether the smoothness is chosen by validation (`auto`).
fn fit_options(args: &FitArgs) -> Result<(FitOptions, bool)> {
    let (smoothness, auto_smoothness) = match args.smoothness.as_str() {
        "auto" => (maglab_identify::table_fit::SMOOTHNESS_CANDIDATES[1], true),
        text => (
            text.parse::<f64>()
                .map_err(|_| anyhow!("--smoothness `{text}`: expected a number >= 0 or auto"))?,
            false,
        ),
    };
    let reversible = if args.no_affine {
        Reversible::None
    } else {
        match Reversible::parse(&args.reversible).map_err(|e| anyhow!("--reversible: {e}"))? {
            Reversible::PiecewiseNoOffset => {
                bail!("--reversible: piecewise-no-offset is for maglab identify; use piecewise")
            }
            Reversible::Offset => {
                bail!("--reversible: offset is for maglab identify; use linear (an offset and a slope) or none")
            }
            r => r,
        }
    };
    let options = FitOptions {
        smoothness,
        ridge: args.ridge,
        reversible,
        unexcited: Unexcited::parse(&args.unexcited).map_err(|e| anyhow!(e))?,
        row_stride: args.row_stride,
        total_mass_at_most: None,
        bands: Default::default(),
    };
    Ok((options, auto_smoothness))
}

/// `--initial`: given, or `auto` (each experiment judged on its own, printed): the state and
/// whether closed loops start periodic.
fn initial_state(args: &FitArgs, table: &Table) -> Result<(StartState, bool)> {
    Ok(if args.initial == "auto" {
        println!("initial state auto: {}", auto_initial(table));
        (StartState::DemagnetizedAtFirstInput, true)
    } else {
        let state = StartState::parse_among(&args.initial, &PREISACH_STARTS).map_err(|e| {
            anyhow!(
                "--initial: {e}, or auto (each experiment on its own: periodic for a closed \
                 loop, else demagnetized-at-first-input)"
            )
        })?;
        (state, false)
    })
}

/// The validation's scores (grid lines and smoothness chosen on held-back fit rows), if it ran.
fn print_validation(model: &PreisachModel) {
    if let Some(scores) = model.provenance["validation"].as_array() {
        let text: Vec<String> = scores
            .iter()
            .map(|s| {
                format!(
                    "{} {:e} {:.4e}",
                    s["lines"].as_str().unwrap_or("?"),
                    s["smoothness"].as_f64().unwrap_or(f64::NAN),
                    s["held_back_rms"].as_f64().unwrap_or(f64::NAN)
                )
            })
            .collect();
        println!(
            "validated: grid lines {}, smoothness {:e} (RMS on held-back fit rows: {})",
            model.provenance["grid_lines"].as_str().unwrap_or("?"),
            model.provenance["options"]["smoothness"]
                .as_f64()
                .unwrap_or(f64::NAN),
            text.join("; ")
        );
    }
}

/// What the fit found: the table, the grid, the residual, the affine or reversible part, the
/// unexcited cells, the samples outside the grid.
fn print_fit(
    table: &Table,
    spec: &ColumnSpec,
    model: &PreisachModel,
    result: &maglab_identify::fit::FitResult,
    score: Option<f64>,
    options: &FitOptions,
    initial: StartState,
) {
    println!(
        "file {}: {} experiments, {} rows, fit rows ({}): {}",
        table.path.display(),
        table.series.len(),
        table.rows(),
        spec.filter.describe(),
        table.selected_rows()
    );
    println!(
        "grid [{:.6e}, {:.6e}] ({} levels, lines {}), initial state {}",
        model.h_min,
        model.h_max,
        maglab_identify::LEVELS,
        match &model.grid_lines {
            Some(l) => {
                let widths: Vec<f64> = l.windows(2).map(|w| w[1] - w[0]).collect();
                let (lo, hi) = widths
                    .iter()
                    .fold((f64::INFINITY, 0.0f64), |(a, b), &w| (a.min(w), b.max(w)));
                format!(
                    "{}: intervals {lo:.4e} to {hi:.4e}",
                    model.provenance["grid_lines"].as_str().unwrap_or("?")
                )
            }
            None => "uniform".into(),
        },
        initial.name()
    );
    println!(
        "regression rows {} (left out by --row-stride: {}), {}",
        result.rows, result.strided_out, result.solver
    );
    println!(
        "RMS residual {:.6e}, output range {:.6e}; NRMSE on the fit rows {}",
        result.rms_residual,
        result.output_scale,
        score.map_or("n/a".into(), |s| format!("{:.4} %", 100.0 * s))
    );
    match options.reversible {
        Reversible::None => {}
        Reversible::Linear => println!(
            "affine part: offset {:.6e}, slope {:.6e} per input unit",
            model.offset, model.slope
        ),
        _ => {
            let slopes = model.reversible_slopes.as_deref().unwrap_or(&[]);
            println!(
                "reversible part (piecewise): offset {:.6e}, slopes {:.4e} to {:.4e} per input unit",
                model.offset,
                slopes.iter().cloned().fold(f64::INFINITY, f64::min),
                slopes.iter().cloned().fold(0.0, f64::max)
            );
        }
    }
    println!(
        "unexcited cells: {} (treatment: {}){}",
        result.unexcited.len(),
        options.unexcited.name(),
        if result.unexcited.is_empty() {
            String::new()
        } else {
            format!(
                ": {}",
                result
                    .unexcited
                    .iter()
                    .map(|&k| format!("{:?}", maglab_identify::cell_of_index(k)))
                    .collect::<Vec<_>>()
                    .join(" ")
            )
        }
    );
    for (label, n) in &result.outside {
        if *n > 0 {
            println!("{label}: {n} samples outside the grid (memory saturated there)");
        }
    }
}

/// `--initial auto`: each experiment judged on its own ([`maglab_identify::model::is_closed_loop`]
/// on its fit rows): a closed loop starts `periodic`, the others demagnetized about their first
/// input. Returns the description printed.
fn auto_initial(table: &Table) -> String {
    let n = table.series.len();
    let closed: Vec<&str> = table
        .series
        .iter()
        .filter(|s| maglab_identify::model::is_closed_loop(s))
        .map(|s| s.label.as_str())
        .collect();
    format!(
        "periodic for the {} of {n} experiments that are closed loops{}, demagnetized about the first input for the others",
        closed.len(),
        if closed.is_empty() || closed.len() > 8 {
            String::new()
        } else {
            format!(" ({})", closed.join(", "))
        }
    )
}
