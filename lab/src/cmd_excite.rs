//! `maglab excite`: writes the current to apply for a recording.
//!
//! * `--design forc` (default): the quasi-static identification current (first-order reversal
//!   curves with a reversal on every grid line, `maglab_dataset::excitation`), checked on the
//!   design matrix to reach every cell, optionally with the displacement the static model (6) of
//!   the parameter file predicts (a dry-run dataset for `maglab identify`, labelled as such);
//! * `--design sines` / `soak`: the records `maglab diagnose` advises when it cannot separate
//!   candidates (`maglab_dataset::records`), one file per record in the output folder.

use anyhow::{anyhow, bail, Context, Result};
use clap::Parser;
use maglab_dataset::excitation::{forc_excitation, Excitation, ExciteOptions};
use maglab_dataset::records::{check_sine, sine_file_name, sine_record, soak_record, Sine};
use maglab_dataset::StartState;
use maglab_identify::design::{Design, Experiment, Grid};
use maglab_identify::magnetization::StaticModel;
use maglab_identify::model::PreisachModel;
use std::path::PathBuf;

/// Arguments of `maglab excite`.
#[derive(Debug, Parser)]
pub struct Args {
    /// forc: output CSV `t_s,current_a` (the current to apply), or the full measurement format
    /// `t_s,current_a,displacement_m` with --predict-displacement. sines, soak: output folder,
    /// one `t_s,current_a` file per record.
    #[arg(short, long)]
    output: PathBuf,
    /// What to write: forc (the reversal sweep for the masses), sines (one record per
    /// frequency, amplitude and bias), soak (a sine, a hold at --soak-current-a, the same sine).
    #[arg(long, default_value = "forc")]
    design: String,
    /// sines, soak: frequencies, Hz (comma separated).
    #[arg(long, value_delimiter = ',')]
    freq_hz: Vec<f64>,
    /// sines, soak: amplitudes (half the peak-to-peak), A (comma separated).
    #[arg(long, value_delimiter = ',')]
    amplitude_a: Vec<f64>,
    /// sines, soak: bias currents, A (comma separated).
    #[arg(long, value_delimiter = ',')]
    bias_a: Vec<f64>,
    /// sines, soak: duration of each sine, s (whole periods, rounded up).
    #[arg(long, default_value_t = 1.0)]
    duration_s: f64,
    /// soak: the current held between the two sines, A.
    #[arg(long)]
    soak_current_a: Option<f64>,
    /// soak: how long it is held, s.
    #[arg(long, default_value_t = 120.0)]
    soak_s: f64,
    /// Parameter file giving the grid range and c0. Default: the built-in paper defaults.
    #[arg(long)]
    params: Option<PathBuf>,
    /// Sweep speed: that of a full-range triangle wave at this frequency, Hz. Keep it far below
    /// the eddy-current corner and the resonance so that the static model (6) holds.
    #[arg(long, default_value_t = 1.0)]
    rate_hz: f64,
    /// Sampling rate of the file, Hz [default: 1000 for forc, 10000 for sines and soak].
    #[arg(long)]
    sample_rate_hz: Option<f64>,
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
    match args.design.as_str() {
        "forc" => forc(args, &params, &origin),
        "sines" | "soak" => records(args, &params),
        other => bail!("--design `{other}`: expected forc, sines or soak"),
    }
}

/// The settings of every sine record `--freq-hz × --amplitude-a × --bias-a`, checked.
fn sines(args: &Args, params: &actuator_params::ActuatorParams) -> Result<Vec<Sine>> {
    for (name, list) in [
        ("--freq-hz", &args.freq_hz),
        ("--amplitude-a", &args.amplitude_a),
        ("--bias-a", &args.bias_a),
    ] {
        if list.is_empty() {
            bail!("--design {} needs {name}", args.design);
        }
    }
    let rate = args.sample_rate_hz.unwrap_or(10_000.0);
    let mut out = Vec::new();
    for &bias_a in &args.bias_a {
        for &amplitude_a in &args.amplitude_a {
            for &frequency_hz in &args.freq_hz {
                let sine = Sine {
                    frequency_hz,
                    amplitude_a,
                    bias_a,
                    duration_s: args.duration_s,
                };
                check_sine(&sine, rate, params.control.current_limit_a).map_err(|e| anyhow!(e))?;
                out.push(sine);
            }
        }
    }
    Ok(out)
}

/// `--design sines` / `soak`: one file per record in the output folder.
fn records(args: &Args, params: &actuator_params::ActuatorParams) -> Result<()> {
    if args.predict_displacement {
        bail!("--predict-displacement is for --design forc only");
    }
    let rate = args.sample_rate_hz.unwrap_or(10_000.0);
    let sines = sines(args, params)?;
    std::fs::create_dir_all(&args.output)
        .with_context(|| format!("cannot create {}", args.output.display()))?;
    let limit = params.control.current_limit_a;
    for (k, sine) in sines.iter().enumerate() {
        let (record, name) = if args.design == "soak" {
            let Some(soak_a) = args.soak_current_a else {
                bail!("--design soak needs --soak-current-a");
            };
            let record =
                soak_record(sine, soak_a, args.soak_s, rate, limit).map_err(|e| anyhow!(e))?;
            let name = sine_file_name(k, sine).replace("_sine_", "_soak_");
            (record, name)
        } else {
            (sine_record(sine, rate), sine_file_name(k, sine))
        };
        let path = args.output.join(&name);
        write_current(&path, &record.t_s, &record.current_a)?;
        println!(
            "wrote {} ({} samples at {rate} Hz, {:.2} s)",
            path.display(),
            record.t_s.len(),
            record.t_s.len() as f64 / rate
        );
    }
    println!(
        "each record switches the current on at t = 0: record it from a demagnetized rod (or say \
         its start in dataset.json) and add the measured files to the dataset's folder"
    );
    Ok(())
}

/// Writes `t_s,current_a`.
fn write_current(path: &std::path::Path, t_s: &[f64], current_a: &[f64]) -> Result<()> {
    let mut text = String::from("t_s,current_a\n");
    for (t, i) in t_s.iter().zip(current_a) {
        text.push_str(&format!("{t:e},{i:e}\n"));
    }
    std::fs::write(path, text).with_context(|| format!("cannot write {}", path.display()))
}

/// `--design forc`.
fn forc(args: &Args, params: &actuator_params::ActuatorParams, origin: &str) -> Result<()> {
    let sample_rate_hz = args.sample_rate_hz.unwrap_or(1000.0);
    let options = ExciteOptions {
        h_min_a_per_m: params.preisach.h_min_a_per_m,
        h_max_a_per_m: params.preisach.h_max_a_per_m,
        coil_factor_per_m: params.actuator.coil_factor_per_m,
        sweep_rate_hz: args.rate_hz,
        sample_rate_hz,
        overdrive: args.overdrive,
    };
    let excitation = forc_excitation(&options).map_err(|e| anyhow!(e))?;
    let c0 = params.actuator.coil_factor_per_m;
    let h: Vec<f64> = excitation.current_a.iter().map(|i| c0 * i).collect();
    let grid = Grid::uniform(options.h_min_a_per_m, options.h_max_a_per_m);
    let unexcited = unexcited_cells(&grid, &h);
    print_forc_summary(
        params,
        origin,
        &grid,
        (&excitation, sample_rate_hz),
        &unexcited,
    );
    write_forc(args, params, origin, grid, &h, &excitation)
}

/// The grid cells the reversal sweep `h` (A/m), started from negative saturation, never switches.
fn unexcited_cells(grid: &Grid, h: &[f64]) -> Vec<usize> {
    let zeros = vec![0.0; h.len()];
    let all = vec![true; h.len()];
    let design = Design::build(
        grid,
        &[Experiment {
            label: "excitation",
            input: h,
            output: &zeros,
            selected: &all,
            initial: StartState::NegativeSaturation,
            weights: None,
        }],
        maglab_identify::fit::Reversible::None,
        1.0,
        1,
    );
    design.unexcited()
}

/// The sweep's size, current range and cells on the terminal, with a warning when its current
/// exceeds the file's limit.
fn print_forc_summary(
    params: &actuator_params::ActuatorParams,
    origin: &str,
    grid: &Grid,
    (excitation, sample_rate_hz): (&Excitation, f64),
    unexcited: &[usize],
) {
    let c0 = params.actuator.coil_factor_per_m;
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
        sample_rate_hz,
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
}

/// Writes the sweep's current to `args.output`, or with `--predict-displacement` a dry-run
/// record with the displacement the static model (6) predicts.
fn write_forc(
    args: &Args,
    params: &actuator_params::ActuatorParams,
    origin: &str,
    grid: Grid,
    h: &[f64],
    excitation: &Excitation,
) -> Result<()> {
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
            .predict(h, StartState::NegativeSaturation)
            .iter()
            .map(|&m| statics.displacement_m(m))
            .collect();
        maglab_dataset::data::write_measurement(
            &args.output,
            &excitation.t_s,
            &excitation.current_a,
            &y,
            None,
        )?;
        println!(
            "wrote {} with the displacement PREDICTED by the static model (6) of {origin} \
             (dry run, not a measurement)",
            args.output.display()
        );
    } else {
        write_current(&args.output, &excitation.t_s, &excitation.current_a)?;
        println!(
            "wrote {} (start from any state: the first sample saturates the memory negatively; \
             identify the recorded file with --initial negative-saturation --branch monotone)",
            args.output.display()
        );
    }
    Ok(())
}
