//! `maglab robustness`: the closed loop against plants the model does not describe — the
//! robustness matrix of the feedback (`magctl::inverse::feedback`).
//!
//! Every case runs the controller of the parameter file (`--params`, default the baked one) on the
//! host in lock-step with the bench plant (`maglab-plant`: its own f64 Preisach operator and RK4
//! integrator), twice: feedforward only (`control.feedback.structure = off`) and with the file's
//! feedback. Each tick the plant's sensor output at `t_k` (its own dynamics when a sensor effect is
//! on) plus white noise is quantized to an ADC count of the `sensor` section and handed to
//! `ControlLoop::tick_sensed`, exactly as the firmware's interrupt receives it; the command is
//! held over the period. The plant starts where the controller assumes (negative saturation
//! driven to the first field, the rod on the trajectory).
//!
//! The cases: the nominal plant; each library effect of the plant at a magnitude that leaves a
//! 5–30 % open-loop error; backlash; ±20 % on R_eddy, ξ, f0, λ_s, M_s; the Preisach masses scaled by
//! ±10 %; sensor noise at three levels (on the plant with R_eddy +20 %, so that there is an error
//! to correct). Errors are the plant's true displacement against `ȳ`, RMS and max over
//! `[--settle-s, --duration-s]` (the learning's first cycles excluded), in % of the trajectory's
//! peak-to-peak.
//!
//! Writes `<out>/robustness.csv` (`case,open_loop_rms_pct,closed_loop_rms_pct,
//! closed_loop_max_pct,current_rms_a`), `<out>/robustness.png/.svg`, and prints the table; and
//! the learning transient of every closed-loop run, `<out>/transient.csv`
//! (`case,whole_run_rms_pct,settled_rms_pct,settle_s,settle_cycles`: the RMS over the whole run,
//! the RMS over the scored window, and when the error last exceeded
//! [`closed_loop::SETTLED_PCT`] of the peak-to-peak — in seconds and in trajectory cycles; empty
//! when it never stays below).

mod cases;
mod closed_loop;
mod output;

use crate::params_io::{self, LoadedParams};
use anyhow::{bail, Context, Result};
use cases::{cases, Case, BASE_NOISE_M};
use clap::Args as ClapArgs;
use closed_loop::{run_case, RunStats, Transient};
use magctl::inverse::{ControlLoop, InverseKind};
use magctl::params::{ActuatorParameters, Feedback};
use output::{plot, read_csv, table, transient_table, write_csv, write_trace, write_transient_csv};
use std::path::{Path, PathBuf};

/// Arguments of `maglab robustness`.
#[derive(Debug, ClapArgs)]
pub struct Args {
    /// The controller's parameter file (default: the parameters baked into this build); the
    /// plants are this file with each case's change.
    #[arg(long, value_name = "FILE")]
    pub params: Option<PathBuf>,
    /// Control time of each run, s.
    #[arg(long, default_value_t = 1.0)]
    pub duration_s: f64,
    /// Errors are scored from this time on (the learning's first cycles excluded), s.
    #[arg(long, default_value_t = 0.5)]
    pub settle_s: f64,
    /// Run only the cases whose name contains one of these (comma separated).
    #[arg(long, value_delimiter = ',')]
    pub only: Vec<String>,
    /// Scale the feedback's gains (learning, K_p, K_i) by this factor (the stability check at
    /// 2×).
    #[arg(long, default_value_t = 1.0)]
    pub gain_scale: f64,
    /// Feedback structure instead of the file's: off, integral or repetitive.
    #[arg(long)]
    pub structure: Option<String>,
    /// K_p of the PI instead of the file's (before --gain-scale).
    #[arg(long)]
    pub proportional_gain: Option<f32>,
    /// K_i of the PI instead of the file's, 1/s (before --gain-scale).
    #[arg(long)]
    pub integral_gain_per_s: Option<f32>,
    /// Harmonics the learning corrects instead of the file's.
    #[arg(long)]
    pub learning_harmonics: Option<u32>,
    /// Use the static inverse (Figure 8) instead of the dynamic one.
    #[arg(long)]
    pub static_inverse: bool,
    /// Without the stroke-gain estimate (`magctl::inverse::StrokeGainLaw`): the learning alone.
    #[arg(long)]
    pub no_stroke_gain: bool,
    /// Output directory.
    #[arg(long, default_value = "out/robustness")]
    pub out: PathBuf,
    /// Seed of the sensor noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Only redraw the plot from this robustness.csv (e.g. with rows appended by `cargo xtask
    /// robustness`) into --out.
    #[arg(long, value_name = "CSV")]
    pub plot_only: Option<PathBuf>,
    /// Also write every case's per-tick traces (`<out>/traces/<case>.csv`: t_s, desired,
    /// open- and closed-loop displacement, closed-loop current and flags).
    #[arg(long)]
    pub traces: bool,
}

/// One row of the matrix.
#[derive(Debug, Clone)]
pub struct Row {
    /// Case name.
    pub case: String,
    /// Feedforward only.
    pub open_loop: RunStats,
    /// With the feedback.
    pub closed_loop: RunStats,
    /// The closed loop's learning transient (`None` when read back from a CSV).
    pub transient: Option<Transient>,
}

/// The feedback settings of `params` with `structure` and the gains scaled by `gain_scale`.
pub fn feedback_settings(
    params: &ActuatorParameters,
    structure: Option<magctl::params::FeedbackStructure>,
    gain_scale: f32,
) -> Feedback {
    let mut f = params.control.feedback;
    if let Some(s) = structure {
        f.structure = s;
    }
    f.learning_gain *= gain_scale;
    f.proportional_gain *= gain_scale;
    f.integral_gain_per_s *= gain_scale;
    f
}

/// Parses a structure name.
pub fn parse_structure(text: &str) -> Result<magctl::params::FeedbackStructure> {
    Ok(match text {
        "off" => magctl::params::FeedbackStructure::Off,
        "integral" => magctl::params::FeedbackStructure::Integral,
        "repetitive" => magctl::params::FeedbackStructure::Repetitive,
        other => bail!("--structure `{other}`: expected off, integral or repetitive"),
    })
}

/// How every case of the matrix runs: the feedback it is compared with, the inverse, the
/// stroke-gain estimate on or off, the run's length and scored window, the noise seed.
struct Settings {
    feedback: Feedback,
    kind: InverseKind,
    stroke_gain: bool,
    duration_s: f64,
    settle_s: f64,
    seed: u64,
}

/// Runs the matrix (cases in parallel on all cores; rows in case order), every case's traces
/// into `traces` when given.
fn matrix(
    loaded: &LoadedParams,
    cases: &[Case],
    settings: &Settings,
    traces: Option<&Path>,
) -> Result<Vec<Row>> {
    let Settings {
        ref feedback,
        kind,
        stroke_gain,
        duration_s,
        settle_s,
        seed,
    } = *settings;
    use rayon::prelude::*;
    let p = &loaded.params;
    let measure = loaded.measure();
    ControlLoop::new(&measure, p)
        .map_err(|e| anyhow::anyhow!("{}: invalid control settings: {e:?}", loaded.origin))?;
    let rate = p.control.sample_rate_hz as f64;
    let ticks = (duration_s * rate).round() as usize;
    let from = (settle_s * rate).round() as usize;
    if from >= ticks {
        bail!("--settle-s {settle_s} must be below --duration-s {duration_s}");
    }
    cases
        .par_iter()
        .map(|case| {
            let mut params = *p;
            if let Some(d) = case.controller_sample_delay_s {
                params.sensor.sample_delay_s = d as f32;
            }
            let loop_for = |f: &Feedback| -> Result<ControlLoop<'_>> {
                let mut with = params;
                with.control.feedback = *f;
                let control = ControlLoop::new(&measure, &with).map_err(|e| {
                    anyhow::anyhow!("{}: invalid control settings: {e:?}", case.name)
                })?;
                Ok(if stroke_gain {
                    control
                } else {
                    control.without_stroke_gain()
                })
            };
            let mut off = *feedback;
            off.structure = magctl::params::FeedbackStructure::Off;
            let o = run_case(&params, &loop_for(&off)?, kind, case, ticks, seed)?;
            let c = run_case(&params, &loop_for(feedback)?, kind, case, ticks, seed)?;
            if let Some(dir) = traces {
                write_trace(dir, &case.name, rate, &o, &c)?;
            }
            let period_ticks = loop_for(feedback)?.trajectory().period_steps() as f64;
            Ok(Row {
                case: case.name.clone(),
                open_loop: o.stats(from),
                closed_loop: c.stats(from),
                transient: Some(c.transient(period_ticks, rate)),
            })
        })
        .collect()
}

/// Runs `maglab robustness`.
pub fn run(args: &Args) -> Result<()> {
    if let Some(csv) = &args.plot_only {
        let rows = read_csv(csv)?;
        crate::plot::register_font()?;
        for p in plot(&args.out.join("robustness"), &rows)? {
            println!("wrote {}", p.display());
        }
        return Ok(());
    }
    let loaded = params_io::load(args.params.as_deref())?;
    let settings = settings(args, &loaded.params)?;
    let all = selected_cases(&loaded.file, &args.only)?;
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("cannot create {}", args.out.display()))?;
    let trace_dir = args.out.join("traces");
    if args.traces {
        std::fs::create_dir_all(&trace_dir)
            .with_context(|| format!("cannot create {}", trace_dir.display()))?;
    }
    let started = std::time::Instant::now();
    let rows = matrix(
        &loaded,
        &all,
        &settings,
        args.traces.then_some(trace_dir.as_path()),
    )?;
    let csv = args.out.join("robustness.csv");
    write_csv(&csv, &rows)?;
    let transient_csv = args.out.join("transient.csv");
    write_transient_csv(&transient_csv, &rows)?;
    crate::plot::register_font()?;
    let pictures = plot(&args.out.join("robustness"), &rows)?;
    println!(
        "robustness matrix: {:?} inverse, feedback {:?} (gains x{}), errors over [{}, {}] s, {:.1} s",
        settings.kind,
        settings.feedback.structure,
        args.gain_scale,
        args.settle_s,
        args.duration_s,
        started.elapsed().as_secs_f64()
    );
    print!("{}", table(&rows));
    print!("{}", transient_table(&rows, args.settle_s));
    print!(
        "{}",
        table(&reference_row(&loaded, &settings)?)
            .lines()
            .nth(1)
            .unwrap_or_default()
    );
    println!();
    println!("wrote {}", csv.display());
    println!("wrote {}", transient_csv.display());
    for p in pictures {
        println!("wrote {}", p.display());
    }
    Ok(())
}

/// The controller and the run from the options: the file's feedback with the options' gains
/// and structure (an error when it is off: nothing to compare), the inverse, the times, the seed.
fn settings(args: &Args, file: &ActuatorParameters) -> Result<Settings> {
    if !(args.gain_scale.is_finite() && args.gain_scale >= 0.0) {
        bail!("--gain-scale must be >= 0, got {}", args.gain_scale);
    }
    let structure = args.structure.as_deref().map(parse_structure).transpose()?;
    let mut params = *file;
    if let Some(k) = args.proportional_gain {
        params.control.feedback.proportional_gain = k;
    }
    if let Some(k) = args.integral_gain_per_s {
        params.control.feedback.integral_gain_per_s = k;
    }
    if let Some(n) = args.learning_harmonics {
        params.control.feedback.learning_harmonics = n;
    }
    let feedback = feedback_settings(&params, structure, args.gain_scale as f32);
    if feedback.structure == magctl::params::FeedbackStructure::Off {
        bail!(
            "the feedback is off (control.feedback.structure or --structure): nothing to compare"
        );
    }
    Ok(Settings {
        feedback,
        kind: if args.static_inverse {
            InverseKind::Static
        } else {
            InverseKind::Dynamic
        },
        stroke_gain: !args.no_stroke_gain,
        duration_s: args.duration_s,
        settle_s: args.settle_s,
        seed: args.seed,
    })
}

/// The matrix's cases on the `nominal` file, those whose name contains one of `only` when it is
/// given (an error when none does).
fn selected_cases(nominal: &actuator_params::ActuatorParams, only: &[String]) -> Result<Vec<Case>> {
    let mut all = cases(nominal)?;
    if !only.is_empty() {
        all.retain(|c| only.iter().any(|o| c.name.contains(o.as_str())));
        if all.is_empty() {
            bail!("--only {only:?} matches no case");
        }
    }
    Ok(all)
}

/// The nominal plant under the same controller: what the loop does without model error (a
/// reference printed under the table, not a row).
fn reference_row(loaded: &LoadedParams, settings: &Settings) -> Result<Vec<Row>> {
    matrix(
        loaded,
        &[Case {
            name: "nominal plant (no model error; reference, not a row)".into(),
            plant: loaded.file.clone(),
            effects: Vec::new(),
            noise_m: BASE_NOISE_M,
            controller_sample_delay_s: None,
        }],
        settings,
        None,
    )
}
