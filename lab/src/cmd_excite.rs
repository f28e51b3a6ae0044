//! `maglab excite`: writes the quasi-static identification current (first-order reversal curves
//! with a reversal on every grid line, `maglab_identify::excite`), checks on the design matrix
//! that it reaches every cell, and optionally adds the displacement the static model (6) of the
//! parameter file predicts (a dry-run dataset for `maglab identify`, labelled as such).

use anyhow::{anyhow, Context, Result};
use clap::Parser;
use maglab_dataset::excitation::{forc_excitation, ExciteOptions};
use maglab_dataset::StartState;
use maglab_identify::design::{Design, Experiment, Grid};
use maglab_identify::magnetization::StaticModel;
use maglab_identify::model::PreisachModel;
use std::path::PathBuf;

/// Arguments of `maglab excite`.
#[derive(Debug, Parser)]
pub struct Args {
    /// Output CSV: `t_s,current_a` (the current to apply), or the full measurement format
    /// `t_s,current_a,displacement_m` with --predict-displacement.
    #[arg(short, long)]
    output: PathBuf,
    /// Parameter file giving the grid range and c0. Default: the built-in paper defaults.
    #[arg(long)]
    params: Option<PathBuf>,
    /// Sweep speed: that of a full-range triangle wave at this frequency, Hz. Keep it far below
    /// the eddy-current corner and the resonance so that the static model (6) holds.
    #[arg(long, default_value_t = 1.0)]
    rate_hz: f64,
    /// Sampling rate of the file, Hz.
    #[arg(long, default_value_t = 1000.0)]
    sample_rate_hz: f64,
    /// Overshoot beyond the grid at both ends, fraction of the range (1 % keeps the default
    /// parameters' current inside control.current_limit_a).
    #[arg(long, default_value_t = 0.01)]
    overdrive: f64,
    /// Add the displacement predicted by the static model (6) of the parameter file (for dry
    /// runs and tests; NOT a measurement).
    #[arg(long)]
    predict_displacement: bool,
}

/// Runs `maglab excite`.
pub fn run(args: &Args) -> Result<()> {
    let (params, origin) = match &args.params {
        Some(p) => (
            actuator_params::ActuatorParams::load(p).context("invalid parameter file")?,
            p.display().to_string(),
        ),
        None => (
            actuator_params::paper_defaults(),
            "built-in paper defaults".to_string(),
        ),
    };
    let options = ExciteOptions {
        h_min_a_per_m: params.preisach.h_min_a_per_m,
        h_max_a_per_m: params.preisach.h_max_a_per_m,
        coil_factor_per_m: params.actuator.coil_factor_per_m,
        sweep_rate_hz: args.rate_hz,
        sample_rate_hz: args.sample_rate_hz,
        overdrive: args.overdrive,
    };
    let excitation = forc_excitation(&options).map_err(|e| anyhow!(e))?;
    let c0 = params.actuator.coil_factor_per_m;
    let h: Vec<f64> = excitation.current_a.iter().map(|i| c0 * i).collect();
    let grid = Grid::uniform(options.h_min_a_per_m, options.h_max_a_per_m);
    let zeros = vec![0.0; h.len()];
    let all = vec![true; h.len()];
    let design = Design::build(
        &grid,
        &[Experiment {
            label: "excitation",
            input: &h,
            output: &zeros,
            selected: &all,
            initial: StartState::NegativeSaturation,
            weights: None,
        }],
        maglab_identify::fit::Reversible::None,
        1.0,
        1,
    );
    let unexcited = design.unexcited();
    let (i_min, i_max) = excitation
        .current_a
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &i| {
            (a.min(i), b.max(i))
        });
    println!(
        "parameters: {origin}; grid [{:.4e}, {:.4e}] A/m, c0 = {c0:.4e} 1/m",
        grid.h_min, grid.h_max
    );
    println!(
        "{} first-order reversal curves, {} samples at {} Hz ({:.2} s), current [{i_min:.4}, {i_max:.4}] A",
        excitation.reversals,
        excitation.t_s.len(),
        args.sample_rate_hz,
        excitation.t_s.last().copied().unwrap_or(0.0)
    );
    println!(
        "cells excited: {} of {} (unexcited: {:?})",
        maglab_identify::CELL_COUNT - unexcited.len(),
        maglab_identify::CELL_COUNT,
        unexcited
            .iter()
            .map(|&k| maglab_identify::cell_of_index(k))
            .collect::<Vec<_>>()
    );
    if params.control.current_limit_a < i_max.max(-i_min) {
        println!(
            "WARNING: the current exceeds control.current_limit_a = {} A",
            params.control.current_limit_a
        );
    }
    if let Some(dir) = args.output.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir)?;
    }
    if args.predict_displacement {
        let model = PreisachModel::from_weights(
            grid,
            &params.preisach.weights_a_per_m,
            StartState::NegativeSaturation,
        );
        let statics = StaticModel {
            rod_length_m: params.actuator.rod_length_m,
            saturation_magnetostriction: params.actuator.saturation_magnetostriction,
            saturation_magnetization_a_per_m: params.actuator.saturation_magnetization_a_per_m,
        };
        let y: Vec<f64> = model
            .predict(&h, StartState::NegativeSaturation)
            .iter()
            .map(|&m| statics.displacement_m(m))
            .collect();
        maglab_dataset::data::write_measurement(
            &args.output,
            &excitation.t_s,
            &excitation.current_a,
            &y,
        )?;
        println!(
            "wrote {} with the displacement PREDICTED by the static model (6) of {origin} \
             (dry run, not a measurement)",
            args.output.display()
        );
    } else {
        let mut text = String::from("t_s,current_a\n");
        for (t, i) in excitation.t_s.iter().zip(&excitation.current_a) {
            text.push_str(&format!("{t:e},{i:e}\n"));
        }
        std::fs::write(&args.output, text)
            .with_context(|| format!("cannot write {}", args.output.display()))?;
        println!(
            "wrote {} (start from any state: the first sample saturates the memory negatively; \
             identify the recorded file with --initial negative-saturation --branch monotone)",
            args.output.display()
        );
    }
    Ok(())
}
