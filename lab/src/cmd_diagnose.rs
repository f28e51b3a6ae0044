//! `maglab diagnose --params P.json DATASET_DIR -o REPORT_DIR`: where a dataset disagrees with the
//! nominal model, which unmodelled effect explains it, and how far the gap shrinks once it is
//! added (library: `maglab-diagnose::diagnosis`). Writes `diagnosis.json`, `report.md` and the
//! plots (`error_vs_frequency`, `loops_worst`, `ranking`, `residual_spectrum`, PNG + SVG).

use crate::plot_diagnose;
use anyhow::{anyhow, Context, Result};
use clap::Args as ClapArgs;
use indicatif::{ProgressBar, ProgressStyle};
use maglab_diagnose::diagnosis::{diagnose, DiagnoseOptions, Diagnosis, DiagnosisRun};
use std::fmt::Write as _;
use std::path::PathBuf;

/// Arguments of `maglab diagnose`.
#[derive(Debug, ClapArgs)]
pub struct Args {
    /// Dataset folder (`*.csv` files `t_s,current_a,displacement_m`).
    pub dataset: PathBuf,
    /// Nominal parameter file.
    #[arg(long, value_name = "FILE")]
    pub params: PathBuf,
    /// Report folder.
    #[arg(short = 'o', long)]
    pub out: PathBuf,
    /// Model substeps per sample (Richardson-extrapolated with twice as many).
    #[arg(long, default_value_t = 1)]
    pub substeps: usize,
}

/// Runs `maglab diagnose`.
pub fn run(args: &Args) -> Result<()> {
    let params =
        actuator_params::ActuatorParams::load(&args.params).context("invalid parameter file")?;
    let dataset = maglab_dataset::data::load_dataset(&args.dataset).map_err(|e| anyhow!("{e}"))?;
    for p in &dataset.ignored {
        println!("note: not a measurement file, not read: {}", p.display());
    }
    if args.substeps == 0 {
        return Err(anyhow!("--substeps must be at least 1"));
    }
    let documented = maglab_dataset::dataset_info::DatasetInfo::load(&args.dataset)
        .map_err(|e| anyhow!("{e}"))?;
    let options = DiagnoseOptions {
        substeps: args.substeps,
        ..DiagnoseOptions::default()
    };
    let started = std::time::Instant::now();
    let run = diagnose_with_progress(
        &params,
        &dataset.measurements,
        documented.as_ref(),
        &options,
    )?;
    let (json_path, md_path) = write_outputs(&run, args)?;
    print_summary(&run.diagnosis);
    println!(
        "wrote {} and {} ({:.1} s)",
        json_path.display(),
        md_path.display(),
        started.elapsed().as_secs_f64()
    );
    Ok(())
}

/// [`diagnose`] with a progress bar of model runs on the terminal.
fn diagnose_with_progress(
    params: &actuator_params::ActuatorParams,
    measurements: &[maglab_dataset::data::Measurement],
    documented: Option<&maglab_dataset::dataset_info::DatasetInfo>,
    options: &DiagnoseOptions,
) -> Result<DiagnosisRun> {
    // Work units: one per model evaluation (about 7 candidates × 150).
    let bar = ProgressBar::new(1000).with_style(
        ProgressStyle::with_template("diagnose {bar:40} {pos} model runs ({elapsed})")
            .map_err(|e| anyhow!("{e}"))?,
    );
    let run = diagnose(params, measurements, documented, options, &|n| {
        if bar.position() + n >= bar.length().unwrap_or(0) {
            bar.inc_length(200);
        }
        bar.inc(n)
    })
    .map_err(|e| anyhow!(e))?;
    bar.finish_and_clear();
    Ok(run)
}

/// Writes `diagnosis.json`, the plots and `report.md` into `args.out`; returns the paths of the
/// JSON and the report.
fn write_outputs(run: &DiagnosisRun, args: &Args) -> Result<(PathBuf, PathBuf)> {
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("cannot create {}", args.out.display()))?;
    let json = serde_json::to_string_pretty(&run.diagnosis)?;
    let json_path = args.out.join("diagnosis.json");
    std::fs::write(&json_path, json)
        .with_context(|| format!("cannot write {}", json_path.display()))?;
    let plots = plot_diagnose::write_all(run, &args.out)?;
    let md = report(run, args, &plots);
    let md_path = args.out.join("report.md");
    std::fs::write(&md_path, md).with_context(|| format!("cannot write {}", md_path.display()))?;
    Ok((json_path, md_path))
}

/// The verdict and what a user acts on, on the terminal: the other candidates as good, the
/// parameter file's warnings, the datasheet priors used, the advice, the nuisances and where
/// the model disagrees.
fn print_summary(d: &Diagnosis) {
    let named: Vec<&str> = std::iter::once(d.verdict.as_str())
        .chain(d.additional_effects.iter().map(|s| s.as_str()))
        .collect();
    println!(
        "verdict: {} (grade {}) — {}",
        named.join(" + "),
        d.grade.name(),
        d.verdict_reason
    );
    if !d.equal_on_training.is_empty() {
        println!(
            "  as good on the training experiments (only the held-out extrapolation ranks them): {}",
            d.equal_on_training.join(", ")
        );
    }
    if let Some(note) = also_significant_note(d) {
        println!("  {}", note.replace("**", ""));
    }
    for w in &d.parameter_file_warnings {
        println!("WARNING (from the parameter file's identification): {w}");
    }
    for prior in &d.datasheet_priors {
        println!("datasheet prior used: {prior}");
    }
    if let Some(w) = &d.unmeasured_loops_warning {
        println!("WARNING: {w}");
    }
    for a in &d.advice {
        println!(
            "{}, record {}{}: {}",
            a.purpose(),
            a.what,
            if a.in_dataset {
                " (more of it: the dataset has such records)"
            } else {
                ""
            },
            a.how
        );
    }
    println!("estimated (nuisances, not effects):");
    for e in &d.nuisance.estimated {
        println!("  {e}");
    }
    println!("  constants' refit range: {}", d.constants_range.reason);
    for s in &d.where_.summary {
        println!("  {s}");
    }
}

/// The sentence on the other candidates that meet the naming criterion alone
/// (`Diagnosis::also_significant`), or `None` when there are none. When R_eddy, ξ, f0 were
/// identified from the same data and a lag is among the effects, it says that those constants
/// absorb part of a lag.
fn also_significant_note(d: &maglab_diagnose::diagnosis::Diagnosis) -> Option<String> {
    if d.also_significant.is_empty() {
        return None;
    }
    let list: Vec<String> = d
        .also_significant
        .iter()
        .map(|a| format!("{} ({:.1}x)", a.effect, a.held_out_reduction))
        .collect();
    let lags = maglab_diagnose::diagnosis::LAG_EFFECTS.map(|e| e.name());
    let lag_involved = std::iter::once(&d.verdict)
        .chain(d.also_significant.iter().map(|a| &a.effect))
        .any(|e| lags.contains(&e.as_str()));
    let absorbed = if lag_involved && !d.constants_range.identified_from_data.is_empty() {
        format!(
            " R_eddy, xi, f0 were identified from these data ({}), and below about twice the \
             rod's resonance a lag of the amplifier, the sensor or a load, or eddy currents that \
             vary with frequency, shift the response as lower R_eddy, xi, f0 do: the identified \
             constants absorb part of any of them, and these are the effects that identify -> \
             diagnose takes for one another.",
            d.constants_range.identified_from_data.join(", ")
        )
    } else {
        String::new()
    };
    Some(format!(
        "**Also consistent with the data:** {} meet{} the naming criterion alone (held-out \
         reduction); the verdict goes to the lowest held-out error.{absorbed}",
        list.join(", "),
        if list.len() == 1 { "s" } else { "" }
    ))
}

fn um(v: f64) -> String {
    format!("{:.3}", v * 1e6)
}

/// `report.md`: every section in order.
fn report(run: &DiagnosisRun, args: &Args, plots: &[&str]) -> String {
    let mut s = String::new();
    verdict_section(&mut s, run, args);
    advice_section(&mut s, &run.diagnosis);
    estimated_section(&mut s, &run.diagnosis);
    where_section(&mut s, &run.diagnosis);
    candidates_section(&mut s, &run.diagnosis);
    plots_section(&mut s, plots);
    s
}

/// The report's section: what to record next to separate the verdict from the candidates
/// beside it (`maglab_diagnose::diagnosis::advice`).
fn advice_section(s: &mut String, d: &maglab_diagnose::diagnosis::Diagnosis) {
    if d.advice.is_empty() {
        return;
    }
    let _ = writeln!(
        s,
        "## What to record next
"
    );
    for a in &d.advice {
        let held = if a.in_dataset {
            " This dataset already has such records: longer or repeated ones lower the noise on \
             the difference."
        } else {
            ""
        };
        let _ = writeln!(
            s,
            "- {}: {}. Why: {}.{held}\n  `{}`",
            a.purpose(),
            a.what,
            a.why,
            a.how
        );
    }
    let _ = writeln!(s);
}

/// The report's section: the verdict, why, and the parameter file's warnings.
fn verdict_section(s: &mut String, run: &DiagnosisRun, args: &Args) {
    let d = &run.diagnosis;
    let _ = writeln!(s, "# Sim-to-real gap diagnosis\n");
    let _ = writeln!(
        s,
        "Dataset `{}` ({} experiments), nominal parameters `{}`.\n",
        args.dataset.display(),
        d.experiments.len(),
        args.params.display()
    );
    let named: Vec<&str> = std::iter::once(d.verdict.as_str())
        .chain(d.additional_effects.iter().map(|s| s.as_str()))
        .collect();
    let _ = writeln!(
        s,
        "## Verdict: `{}` (grade `{}`)\n\n{}.\n",
        named.join(" + "),
        d.grade.name(),
        d.verdict_reason
    );
    if let Some(note) = also_significant_note(d) {
        let _ = writeln!(s, "{note}\n");
    }
    if !d.parameter_file_warnings.is_empty() {
        let _ = writeln!(
            s,
            "**The parameter file's identification warned** (`provenance.warnings`): its model \
             did not describe the data it was identified from.\n"
        );
        for w in &d.parameter_file_warnings {
            let _ = writeln!(s, "- {w}");
        }
        let _ = writeln!(s);
    }
    if let Some(w) = &d.unmeasured_loops_warning {
        let _ = writeln!(
            s,
            "**Loops the parameter file's masses were not measured on** (`unmeasured_loops`): \
             {w}.\n"
        );
    }
}

/// The report's section: what was estimated (not effects), the refit and the criterion.
fn estimated_section(s: &mut String, d: &Diagnosis) {
    let _ = writeln!(s, "## Estimated, not effects\n");
    for e in &d.nuisance.estimated {
        let _ = writeln!(s, "- {e}");
    }
    let r = &d.refitted_nominal;
    let _ = writeln!(
        s,
        "- the nominal constants refitted on the training experiments: {} (held-out RMS {} µm)",
        r.parameters
            .iter()
            .map(|(k, v)| format!("{k} = {v:.4}"))
            .collect::<Vec<_>>()
            .join(", "),
        um(r.held_out_rms_after_m)
    );
    let _ = writeln!(
        s,
        "- how far the refit could move them: {}\n",
        d.constants_range.reason
    );
    if !d.ambiguous_with.is_empty() {
        let _ = writeln!(
            s,
            "Nearly as good (within 10 % of the winner's held-out error): {}.\n",
            d.ambiguous_with.join(", ")
        );
    }
    if !d.equal_on_training.is_empty() {
        let _ = writeln!(
            s,
            "Fit the training experiments as well (training RMS within {:.0} % of the winner's) \
             and also explain the held-out gap: {}. The training data cannot tell them from the \
             verdict; only the extrapolation to the held-out experiments ranks them. A measurement \
             that separates them decides (the coil's current for an amplifier, the sensor's step \
             response for a sensor, the rod's resonance without the load for a load).\n",
            100.0 * (maglab_diagnose::diagnosis::rules::EQUAL_ON_TRAINING - 1.0),
            d.equal_on_training.join(", ")
        );
    }
    // A tie on the held-out experiments, broken by the constants at an end of their band (the
    // library records it: Diagnosis::held_out_tie).
    if let Some(tie) = &d.held_out_tie {
        let fit = |f: &maglab_diagnose::diagnosis::TiedFit| {
            format!(
                "{} ({} µm; at a band end: [{}])",
                f.effect,
                um(f.held_out_rms_after_m),
                f.constants_at_range_end.join(", ")
            )
        };
        let others: Vec<String> = tie.tied[1..].iter().map(fit).collect();
        let _ = writeln!(
            s,
            "Tied on the held-out experiments (within {:.0} %): {} against {}. The data do not \
             rank them; the verdict goes to the fit that needs fewer of R_eddy, xi, f0 and the \
             channel skew at an end of their band.\n",
            100.0 * (maglab_diagnose::diagnosis::rules::EQUAL_HELD_OUT - 1.0),
            fit(&tie.tied[0]),
            others.join(", "),
        );
    }
    let _ = writeln!(s, "Criterion: {}.\n", d.criterion);
    let _ = writeln!(
        s,
        "Noise level (white residual above 0.3 f_s): {} µm; displacement range {} µm; nominal RMS \
         residual {} µm (systematic {} µm); the model's own integration error on the held-out \
         experiments {} µm at {} substep(s) per sample (against itself with twice the substeps; \
         `--substeps` lowers it){}.\n",
        um(d.noise_m),
        um(d.displacement_range_m),
        um(d.nominal_rms_m),
        um(d.nominal_systematic_m),
        um(d.model_error_m),
        d.substeps,
        d.substeps_raised
            .as_ref()
            .map_or(String::new(), |r| format!("; {r}"))
            + &if d.none_by_model_error {
                format!(
                    "; the verdict is `none` only because of that error (a candidate explained \
                     the gap): `--substeps {}` gives a finer model",
                    2 * d.substeps
                )
            } else {
                String::new()
            }
    );
}

/// The report's section: where the parameter file's model disagrees.
fn where_section(s: &mut String, d: &Diagnosis) {
    let _ = writeln!(s, "## Where\n");
    for line in &d.where_.summary {
        let _ = writeln!(s, "- {line}");
    }
    let _ = writeln!(
        s,
        "\n| band (Hz) | RMS (µm) | systematic (µm) | gap / motion | harmonic | amplitude ratio | phase error (deg) | disagrees |\n|---|---|---|---|---|---|---|---|"
    );
    for b in &d.where_.bands {
        let _ = writeln!(
            s,
            "| {:.1} | {} | {} | {:.2} % | {} | {:.3} | {:+.2} | {} |",
            b.frequency_hz,
            um(b.rms_m),
            um(b.systematic_m),
            100.0 * b.relative_gap,
            b.displacement_order,
            b.amplitude_ratio,
            b.phase_error_deg,
            if b.disagrees { "yes" } else { "no" }
        );
    }
    let w = &d.where_;
    let _ = writeln!(
        s,
        "\nBranches (RMS, µm): ascending {}, descending {}; near reversal {}, mid-branch {}; early {}, late {}.\n",
        um(w.parts.ascending_rms_m),
        um(w.parts.descending_rms_m),
        um(w.parts.near_reversal_rms_m),
        um(w.parts.mid_branch_rms_m),
        um(w.parts.early_rms_m),
        um(w.parts.late_rms_m)
    );
}

/// The report's section: every candidate's held-out scores and the second stage.
fn candidates_section(s: &mut String, d: &Diagnosis) {
    let _ = writeln!(s, "## Candidates (held-out experiments)\n");
    let _ = writeln!(
        s,
        "| rank | effect | held-out RMS, refitted nominal (µm) | with the effect (µm) | effect switched off (µm) | reduction | worse | pinned | at a band end | significant | fitted parameters |\n|---|---|---|---|---|---|---|---|---|---|---|"
    );
    for (k, c) in d.ranking.iter().enumerate() {
        let params: Vec<String> = c
            .parameters
            .iter()
            .map(|(k, v)| format!("{k} = {v:.4}"))
            .collect();
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} | {:.2}x | {}/{} | {} | {} | {} | {} |",
            k + 1,
            c.effect,
            um(c.held_out_rms_before_m),
            um(c.held_out_rms_after_m),
            um(c.knocked_out_rms_m),
            c.held_out_reduction,
            c.worse_experiments,
            c.held_out_experiments,
            c.pinned.join(", "),
            c.constants_at_range_end.join(", "),
            if c.significant { "yes" } else { "no" },
            params.join(", ")
        );
    }
    let _ = writeln!(s, "\nSecond stage: {}.", d.second_stage_reason);
    if !d.second_stage.is_empty() {
        let _ = writeln!(
            s,
            "\nPairs (second stage), against the best single candidate:\n"
        );
        for c in &d.second_stage {
            let _ = writeln!(
                s,
                "- {}: held-out RMS {} µm (systematic {} µm), pinned [{}], at a band end [{}]",
                c.effect,
                um(c.held_out_rms_after_m),
                um(c.systematic_after_m),
                c.pinned.join(", "),
                c.constants_at_range_end.join(", ")
            );
        }
    }
    let held: Vec<&str> = d
        .experiments
        .iter()
        .filter(|e| e.held_out)
        .map(|e| e.name.as_str())
        .collect();
    let _ = writeln!(s, "\nHeld-out experiments: {}.\n", held.join(", "));
}

/// The report's section: the plots.
fn plots_section(s: &mut String, plots: &[&str]) {
    let _ = writeln!(s, "## Plots\n");
    for p in plots {
        let _ = writeln!(s, "![{p}]({p}.png)\n");
    }
}
