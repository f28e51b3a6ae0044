//! `maglab rig`: the virtual test rig. Generates a dataset (one `t_s,current_a,displacement_m` CSV
//! per experiment) from the f64 reference plant with unmodelled effects switched on
//! (`--effect name:key=value,...`, repeatable; see `maglab-diagnose::effects` for the names and
//! parameters), plus sensor noise and quantization: sine sweeps with DC bias and Van der Pol
//! tracking runs. The effects are printed and optionally written to `--manifest FILE`, never into
//! the dataset folder, so a diagnosis of the folder cannot see them.

use anyhow::{anyhow, bail, Context, Result};
use clap::Args as ClapArgs;
use indicatif::{ProgressBar, ProgressStyle};
use maglab_diagnose::effects::{EffectName, RigEffect};
use maglab_diagnose::rig::{self, Excitation, RigOptions};
use std::path::PathBuf;

/// Arguments of `maglab rig`.
#[derive(Debug, ClapArgs)]
pub struct Args {
    /// Output dataset folder.
    #[arg(short = 'o', long)]
    pub out: PathBuf,
    /// Nominal parameter file of the plant (default: `params/actuator.json` values).
    #[arg(long, value_name = "FILE")]
    pub params: Option<PathBuf>,
    /// An effect, `name` or `name:key=value,...` (repeatable). Names: eddy_frequency_dependence,
    /// amplifier_bandwidth, sensor_dynamics, reversible_magnetization, thermal_drift,
    /// delta_e_effect, mechanical_load, backlash. `--list-effects` shows parameters and defaults.
    #[arg(long = "effect")]
    pub effects: Vec<String>,
    /// Print every effect's parameters with defaults and exit.
    #[arg(long)]
    pub list_effects: bool,
    /// Sine frequencies, Hz.
    #[arg(long, value_delimiter = ',', default_value = "20,50,100,200,300,400")]
    pub freq: Vec<f64>,
    /// Sine amplitudes, A (every frequency at every amplitude).
    #[arg(long, value_delimiter = ',', default_value = "0.2,0.4")]
    pub amplitude_a: Vec<f64>,
    /// DC bias, A.
    #[arg(long, default_value_t = 0.5)]
    pub bias_a: f64,
    /// Van der Pol tracking runs: frequency scales, Hz (none by default).
    #[arg(long, value_delimiter = ',')]
    pub vdp_hz: Vec<f64>,
    /// μ of the Van der Pol runs.
    #[arg(long, default_value_t = 2.0)]
    pub vdp_mu: f64,
    /// Duration of each experiment, s.
    #[arg(long, default_value_t = 1.0)]
    pub duration_s: f64,
    /// Sampling rate, Hz.
    #[arg(long, default_value_t = 10_000.0)]
    pub rate_hz: f64,
    /// Sensor noise (standard deviation), m.
    #[arg(long, default_value_t = 0.15e-6)]
    pub noise_m: f64,
    /// Displacement quantization step, m (0 = none).
    #[arg(long, default_value_t = 2e-9)]
    pub quantization_m: f64,
    /// Noise seed.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// RK4 substeps per sample of the reference plant.
    #[arg(long, default_value_t = 20)]
    pub substeps: usize,
    /// Preisach operator of the rig: 0 = the exact cell-uniform operator the parameter file
    /// defines (default); K > 0 = the independent relay field with K relays per cell side (its
    /// discretization error, ~1/K of a minor loop's swing, shows up as a DC-level gap).
    #[arg(long, default_value_t = 0)]
    pub relays: usize,
    /// Also write the effects (the ground truth) to this JSON file (keep it outside the dataset).
    #[arg(long, value_name = "FILE")]
    pub manifest: Option<PathBuf>,
}

/// Runs `maglab rig`.
pub fn run(args: &Args) -> Result<()> {
    if args.list_effects {
        for e in EffectName::ALL {
            println!("{}", e.name());
            for (k, v, what) in e.keys() {
                println!("    {k} = {v}  ({what})");
            }
        }
        return Ok(());
    }
    let params = match &args.params {
        Some(p) => actuator_params::ActuatorParams::load(p).context("invalid parameter file")?,
        None => actuator_params::paper_defaults(),
    };
    let effects = args
        .effects
        .iter()
        .map(|t| RigEffect::parse(t).map_err(|e| anyhow!("--effect {t}: {e}")))
        .collect::<Result<Vec<_>>>()?;
    for (name, list) in [("--freq", &args.freq), ("--amplitude-a", &args.amplitude_a)] {
        if let Some(v) = list.iter().find(|v| !(v.is_finite() && **v > 0.0)) {
            bail!("{name}: every value must be a positive number, got {v}");
        }
    }
    let mut excitations = rig::sine_sweep(&args.freq, &args.amplitude_a, args.bias_a);
    for &f in &args.vdp_hz {
        excitations.push(Excitation::VanDerPol {
            frequency_scale_hz: f,
            mu: args.vdp_mu,
        });
    }
    let options = RigOptions {
        rate_hz: args.rate_hz,
        duration_s: args.duration_s,
        substeps: args.substeps,
        relay_subdivision: args.relays,
        noise_m: args.noise_m,
        quantization_m: args.quantization_m,
        seed: args.seed,
    };
    let total = (excitations.len() as f64 * args.duration_s * args.rate_hz) as u64;
    let bar = ProgressBar::new(total).with_style(
        ProgressStyle::with_template("rig {bar:40} {pos}/{len} samples ({eta})")
            .map_err(|e| anyhow!("{e}"))?,
    );
    let experiments = rig::generate(&params, &effects, &excitations, &options, &|n| bar.inc(n))
        .map_err(|e| anyhow!(e))?;
    bar.finish_and_clear();
    let paths = rig::write_dataset(&args.out, &experiments).map_err(|e| anyhow!(e))?;
    println!(
        "wrote {} experiments to {} ({} s each at {} Hz)",
        paths.len(),
        args.out.display(),
        args.duration_s,
        args.rate_hz
    );
    let described: Vec<String> = effects.iter().map(|e| e.describe()).collect();
    println!(
        "effects: {}",
        if described.is_empty() {
            "none".to_string()
        } else {
            described.join("; ")
        }
    );
    if let Some(path) = &args.manifest {
        let manifest = serde_json::json!({
            "effects": effects.iter().map(|e| serde_json::json!({
                "name": e.name.name(),
                "parameters": e.values.iter().map(|(k, v)| (k.to_string(), *v)).collect::<std::collections::BTreeMap<_, _>>(),
            })).collect::<Vec<_>>(),
            "noise_m": args.noise_m,
            "quantization_m": args.quantization_m,
            "seed": args.seed,
        });
        std::fs::write(path, serde_json::to_string_pretty(&manifest)?)
            .with_context(|| format!("cannot write {}", path.display()))?;
        println!("wrote {}", path.display());
    }
    Ok(())
}
