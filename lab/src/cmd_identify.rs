//! `maglab identify`: a dataset folder of quasi-static measurements → the full parameter JSON
//! (`maglab_identify::actuator`), with the Preisach masses identified and R_eddy, ξ, f0 copied
//! from the base file (they need the dynamic model; the output and the provenance say so).
//! Plots: the identified masses on the Preisach plane and measured vs predicted loops.

use crate::plot::{Figure, Panel, Series, PALETTE};
use crate::plot_preisach::WeightMap;
use anyhow::{anyhow, Context, Result};
use clap::Parser;
use maglab_identify::actuator::{identify, IdentifyOptions};
use maglab_identify::data::load_dataset;
use maglab_identify::fit::{FitOptions, Unexcited};
use maglab_identify::magnetization::Branch;
use maglab_identify::memory::InitialState;
use std::path::PathBuf;

/// Arguments of `maglab identify`.
#[derive(Debug, Parser)]
pub struct Args {
    /// Folder of measurement files (`t_s,current_a,displacement_m`, quasi-static).
    dataset: PathBuf,
    /// Output parameter file.
    #[arg(short, long)]
    output: PathBuf,
    /// Base parameter file: grid, constants, R_eddy/ξ/f0, control and trajectory settings, and
    /// the prior masses. Default: the built-in paper defaults.
    #[arg(long)]
    params: Option<PathBuf>,
    /// Sign of M: `positive` (DC-biased data, M >= 0) or `monotone` (bipolar data such as
    /// `maglab excite`; sign from input monotonicity). No default: the choice depends on how
    /// the data were taken.
    #[arg(long)]
    branch: String,
    /// Initial memory of every file: negative-saturation (data from `maglab excite`),
    /// positive-saturation, demagnetized (around the first current), periodic.
    #[arg(long)]
    initial: String,
    /// Zero band of the monotone sign rule, fraction of the full stroke l_m λ_s.
    #[arg(long, default_value_t = 0.01)]
    zero_band: f64,
    /// Smoothness weight λ_s.
    #[arg(long, default_value_t = 1e-6)]
    smoothness: f64,
    /// Ridge weight λ_r toward the base masses.
    #[arg(long, default_value_t = 0.0)]
    ridge: f64,
    /// Unexcited cells: keep-prior (base masses), zero, regularized.
    #[arg(long, default_value = "keep-prior")]
    unexcited: String,
    /// Use every n-th sample in the regression (the memory still sees every sample).
    #[arg(long, default_value_t = 1)]
    row_stride: usize,
    /// Directory for the plots.
    #[arg(long, default_value = "out")]
    plot_dir: PathBuf,
}

/// Runs `maglab identify`.
pub fn run(args: &Args) -> Result<()> {
    let (base, base_name) = match &args.params {
        Some(p) => (
            actuator_params::ActuatorParams::load(p).context("invalid base parameter file")?,
            p.display().to_string(),
        ),
        None => (
            actuator_params::paper_defaults(),
            "built-in paper defaults (params/actuator.json content)".to_string(),
        ),
    };
    let options = IdentifyOptions {
        branch: Branch::parse(&args.branch).map_err(|e| anyhow!(e))?,
        initial: InitialState::parse(&args.initial).map_err(|e| anyhow!(e))?,
        zero_band_fraction: args.zero_band,
        fit: FitOptions {
            smoothness: args.smoothness,
            ridge: args.ridge,
            affine: false,
            unexcited: Unexcited::parse(&args.unexcited).map_err(|e| anyhow!(e))?,
            row_stride: args.row_stride,
        },
    };
    let dataset = load_dataset(&args.dataset)?;
    for p in &dataset.ignored {
        println!("not read (not a *.csv file): {}", p.display());
    }
    let id = identify(&dataset, &base, &base_name, &options)?;
    for f in &id.files {
        println!(
            "{}: {} samples, negative displacement clipped {}, above stroke {}, sign changes {}, \
             NRMSE M {}, NRMSE y {}",
            f.file,
            f.samples,
            f.clipped_negative,
            f.above_stroke,
            f.sign_changes,
            pct(f.nrmse_magnetization),
            pct(f.nrmse_displacement)
        );
    }
    println!(
        "fit: {} rows (left out by stride {}), RMS residual {:.4e} A/m, {}",
        id.fit.rows, id.fit.strided_out, id.fit.rms_residual, id.fit.solver
    );
    println!(
        "sum of masses {:.6e} A/m (M_s = {:.6e} A/m)",
        id.fit.weights.iter().sum::<f64>(),
        base.actuator.saturation_magnetization_a_per_m
    );
    println!(
        "unexcited cells: {} (treatment: {})",
        id.fit.unexcited.len(),
        options.fit.unexcited.name()
    );
    for (label, n) in &id.fit.outside {
        if *n > 0 {
            println!("{label}: {n} samples outside the grid (memory saturated there)");
        }
    }
    println!(
        "NOT identified: R_eddy = {} Ω, ξ = {}, f0 = {} Hz are copied from {base_name} \
         (identification of these needs the dynamic model; see provenance.not_identified)",
        base.actuator.eddy_resistance_ohm, base.actuator.damping_ratio, base.actuator.resonance_hz
    );
    if let Some(dir) = args.output.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir)?;
    }
    std::fs::write(&args.output, id.params.to_json_pretty())
        .with_context(|| format!("cannot write {}", args.output.display()))?;
    println!("wrote {}", args.output.display());

    let map = WeightMap {
        title: "identified masses".into(),
        axis_label: "kA/m".into(),
        axis_scale: 1e-3,
        h_min: base.preisach.h_min_a_per_m,
        h_max: base.preisach.h_max_a_per_m,
        weights: &id.fit.weights,
        outlined: &id.fit.unexcited,
    };
    for p in map.write(&args.plot_dir.join("identified-weights"))? {
        println!("wrote {}", p.display());
    }
    let mut panel = Panel::new(
        "measured (thin) vs predicted (thick) M-H loops",
        "H, kA/m",
        "M, kA/m",
    );
    for (k, f) in id.files.iter().enumerate() {
        let colour = PALETTE[k % PALETTE.len()];
        let pts = |m: &[f64]| -> Vec<(f64, f64)> {
            f.h_a_per_m
                .iter()
                .zip(m)
                .map(|(h, m)| (h * 1e-3, m * 1e-3))
                .collect()
        };
        panel.series.push(Series {
            label: Some(format!("{} measured", f.file)),
            points: pts(&f.m_measured_a_per_m),
            color: colour,
            width: 1,
        });
        panel.series.push(Series {
            label: Some(format!("{} predicted", f.file)),
            points: pts(&f.m_predicted_a_per_m),
            color: colour,
            width: 3,
        });
    }
    let figure = Figure {
        panels: vec![panel],
        rows: 1,
        cols: 1,
        size_px: (1000, 800),
    };
    for p in figure.write(&args.plot_dir.join("identified-loops"))? {
        println!("wrote {}", p.display());
    }
    Ok(())
}

fn pct(v: Option<f64>) -> String {
    v.map_or("n/a".into(), |v| format!("{:.3} %", 100.0 * v))
}
