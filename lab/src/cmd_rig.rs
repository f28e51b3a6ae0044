//! `maglab rig`: the virtual test bench. Records a dataset (one `t_s,current_a,displacement_m`
//! CSV per experiment and the `dataset.json` a bench documents) from the bench plant
//! (`maglab-plant`: its own Preisach operator and integrator, the effects in physical forms, the
//! recording's nuisances): sine sweeps with DC bias, a quasi-static reversal (FORC) sweep for the
//! Preisach masses, and Van der Pol tracking runs. The effects and nuisances are printed and
//! optionally written to `--manifest FILE`, never into the dataset folder, so a diagnosis of the
//! folder cannot see them.

use anyhow::{anyhow, bail, Context, Result};
use clap::Args as ClapArgs;
use maglab_dataset::{CurrentBetweenSamples, StartState};
use maglab_plant::bench::{self, BenchSettings, Experiment};
use maglab_plant::{Effect, EFFECTS, PLANT_STARTS};
use std::path::PathBuf;

/// Arguments of `maglab rig`.
#[derive(Debug, ClapArgs)]
pub struct Args {
    /// Output dataset folder.
    #[arg(short = 'o', long, required_unless_present = "list_effects")]
    pub out: Option<PathBuf>,
    /// Nominal parameter file of the plant (default: `params/actuator.json` values).
    #[arg(long, value_name = "FILE")]
    pub params: Option<PathBuf>,
    /// An effect, `name` or `name:key=value,...` (repeatable). `--list-effects` shows the names,
    /// parameters, ranges and defaults.
    #[arg(long = "effect")]
    pub effects: Vec<String>,
    /// Print every effect's parameters with defaults and ranges and exit.
    #[arg(long)]
    pub list_effects: bool,
    /// Sine frequencies, Hz.
    #[arg(long, value_delimiter = ',', default_value = "20,50,100,200,300,400")]
    pub freq: Vec<f64>,
    /// Sine amplitudes, A (every frequency at every amplitude).
    #[arg(long, value_delimiter = ',', default_value = "0.15,0.3,0.45")]
    pub amplitude_a: Vec<f64>,
    /// DC bias, A.
    #[arg(long, default_value_t = 0.55)]
    pub bias_a: f64,
    /// Also record a quasi-static reversal (FORC) sweep from negative saturation (for `maglab
    /// identify`): a full-range triangle at this rate, Hz (0: none).
    #[arg(long, default_value_t = 0.0)]
    pub forc_hz: f64,
    /// Van der Pol tracking runs: frequency scales, Hz (none by default).
    #[arg(long, value_delimiter = ',')]
    pub vdp_hz: Vec<f64>,
    /// μ of the Van der Pol runs.
    #[arg(long, default_value_t = 2.0)]
    pub vdp_mu: f64,
    /// Duration of each sine and Van der Pol experiment, s.
    #[arg(long, default_value_t = 1.0)]
    pub duration_s: f64,
    /// How each experiment starts: switch-on-demagnetized, demagnetized, negative-saturation,
    /// positive-saturation, previous (no reset between experiments).
    #[arg(long, default_value = "demagnetized")]
    pub start: String,
    /// Do not document the start state in dataset.json (the diagnosis then estimates it).
    #[arg(long)]
    pub undocumented: bool,
    /// The rod's own Preisach measure instead of the parameter file's: `FAMILY:FACTOR[:C:S]`
    /// (gaussian, lognormal, bimodal, skewed; the plane FACTOR times wider than the coil reaches
    /// at the current limit; coercivity C ± S kA/m; `maglab_plant::rods`).
    #[arg(long, value_name = "FAMILY:FACTOR")]
    pub rod: Option<String>,
    /// Sampling rate, Hz.
    #[arg(long, default_value_t = 10_000.0)]
    pub rate_hz: f64,
    /// What the current source does between command samples: hold or linear.
    #[arg(long, default_value = "hold")]
    pub current_between_samples: String,
    /// The displacement is read this many samples after the current (|skew| < 1).
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pub skew_samples: f64,
    /// Sensor offset, m.
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pub offset_m: f64,
    /// Sensor noise (standard deviation), m.
    #[arg(long, default_value_t = 0.15e-6)]
    pub noise_m: f64,
    /// Displacement quantization step, m (0 = none).
    #[arg(long, default_value_t = 2e-9)]
    pub quantization_m: f64,
    /// Noise seed.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Also record the coil current (the amplifier's current monitor, on the displacement's
    /// trigger) with this white noise, A: the `coil_current_a` column.
    #[arg(long, value_name = "A")]
    pub coil_current_noise_a: Option<f64>,
    /// The coil current's quantization step, A (with `--coil-current-noise-a`; 0 = none).
    #[arg(long, default_value_t = 1e-3, value_name = "A")]
    pub coil_current_quantization_a: f64,
    /// Also write the effects and nuisances (the ground truth) to this JSON file (keep it
    /// outside the dataset).
    #[arg(long, value_name = "FILE")]
    pub manifest: Option<PathBuf>,
}

/// Runs `maglab rig`: the experiments on the bench plant, written as a dataset folder.
pub fn run(args: &Args) -> Result<()> {
    if args.list_effects {
        print_effects();
        return Ok(());
    }
    let params = match &args.params {
        Some(p) => actuator_params::ActuatorParams::load(p).context("invalid parameter file")?,
        None => actuator_params::paper_defaults(),
    };
    let effects = args
        .effects
        .iter()
        .map(|t| Effect::parse(t).map_err(|e| anyhow!("--effect {t}: {e}")))
        .collect::<Result<Vec<_>>>()?;
    for (name, list) in [("--freq", &args.freq), ("--amplitude-a", &args.amplitude_a)] {
        if let Some(v) = list.iter().find(|v| !(v.is_finite() && **v > 0.0)) {
            bail!("{name}: every value must be a positive number, got {v}");
        }
    }
    let start =
        StartState::parse_among(&args.start, &PLANT_STARTS).map_err(|e| anyhow!("--start: {e}"))?;
    let settings = bench_settings(args)?;
    let experiments = experiments(args, &params, start)?;
    let out = args
        .out
        .as_deref()
        .ok_or_else(|| anyhow!("--out is required (the dataset folder)"))?;
    let started = std::time::Instant::now();
    let recordings = match &args.rod {
        Some(text) => {
            let rod = maglab_plant::Rod::parse(text).map_err(|e| anyhow!("--rod: {e}"))?;
            let plant = maglab_plant::Plant::with_rod(&params, &rod, &effects, settings.rate_hz)
                .map_err(|e| anyhow!(e))?;
            bench::record_all_on(plant, &experiments, &settings)
        }
        None => bench::record_all(&params, &effects, &experiments, &settings),
    }
    .map_err(|e| anyhow!(e))?;
    let paths = bench::write_dataset(out, &recordings).map_err(|e| anyhow!(e))?;
    if args.undocumented {
        std::fs::remove_file(out.join(maglab_dataset::dataset_info::FILE_NAME)).ok();
    }
    println!(
        "wrote {} experiments to {} ({:.1} s of plant time at {} Hz in {:.1} s){}",
        paths.len(),
        out.display(),
        recordings.iter().map(|r| r.t_s.len()).sum::<usize>() as f64 / args.rate_hz,
        args.rate_hz,
        started.elapsed().as_secs_f64(),
        if args.undocumented {
            "; start states not documented"
        } else {
            ""
        }
    );
    drop(recordings);
    let described: Vec<String> = effects.iter().map(|e| e.to_string()).collect();
    println!(
        "effects: {}",
        if described.is_empty() {
            "none".to_string()
        } else {
            described.join("; ")
        }
    );
    if let Some(path) = &args.manifest {
        std::fs::write(
            path,
            serde_json::to_string_pretty(&manifest(args, &effects))?,
        )
        .with_context(|| format!("cannot write {}", path.display()))?;
        println!("wrote {}", path.display());
    }
    Ok(())
}

/// `--list-effects`: every effect with its keys, their defaults and ranges, and its forms.
fn print_effects() {
    for spec in EFFECTS {
        println!(
            "{}{}",
            spec.name,
            if spec.in_library {
                ""
            } else {
                "  (not in the diagnosis library)"
            }
        );
        for (k, v, lo, hi, what) in spec.keys {
            println!("    {k} = {v}  in [{lo}, {hi}]  ({what})");
        }
        for (i, (form, equation)) in spec.forms.iter().enumerate() {
            println!("    form={i}: {form}: {equation}");
        }
    }
}

/// What the bench adds to the plant's motion (`--rate-hz`, the nuisances, the noise, the
/// current monitor), checked.
fn bench_settings(args: &Args) -> Result<BenchSettings> {
    let current_between_samples = CurrentBetweenSamples::parse(&args.current_between_samples)
        .map_err(|e| anyhow!("--current-between-samples: {e}"))?;
    let settings = BenchSettings {
        rate_hz: args.rate_hz,
        current_between_samples,
        channel_skew_samples: args.skew_samples,
        sensor_offset_m: args.offset_m,
        noise_m: args.noise_m,
        quantization_m: args.quantization_m,
        seed: args.seed,
        coil_current: args
            .coil_current_noise_a
            .map(|noise_a| maglab_plant::CurrentMonitor {
                noise_a,
                quantization_a: args.coil_current_quantization_a,
            }),
    };
    settings.check().map_err(|e| anyhow!(e))?;
    Ok(settings)
}

/// The experiments in recording order: the reversal sweep (`--forc-hz`), every sine of
/// `--freq` × `--amplitude-a`, the Van der Pol trajectories (`--vdp-hz`).
fn experiments(
    args: &Args,
    params: &actuator_params::ActuatorParams,
    start: StartState,
) -> Result<Vec<Experiment>> {
    let mut experiments = Vec::new();
    if args.forc_hz > 0.0 {
        experiments.push(
            bench::forc_experiment(params, args.forc_hz, args.rate_hz)
                .map_err(|e| anyhow!("--forc-hz: {e}"))?,
        );
    }
    for &f in &args.freq {
        for &a in &args.amplitude_a {
            experiments.push(bench::sine_experiment(
                experiments.len(),
                start,
                args.bias_a,
                a,
                f,
                args.duration_s,
                args.rate_hz,
            ));
        }
    }
    for &f in &args.vdp_hz {
        let n = experiments.len();
        experiments.push(van_der_pol(
            params,
            n,
            start,
            f,
            args.vdp_mu,
            args.duration_s,
            args.rate_hz,
        )?);
    }
    Ok(experiments)
}

/// `--manifest`: what the dataset holds (the effects with their parameters, the nuisances, the
/// noise, the seed), for scoring a diagnosis against it.
fn manifest(args: &Args, effects: &[Effect]) -> serde_json::Value {
    serde_json::json!({
        "effects": effects.iter().map(|e| serde_json::json!({
            "name": e.name(),
            "parameters": e.spec.keys.iter().zip(&e.values).map(|(k, v)| (k.0.to_string(), *v)).collect::<std::collections::BTreeMap<_, _>>(),
        })).collect::<Vec<_>>(),
        "nuisances": {
            "current_between_samples": args.current_between_samples,
            "channel_skew_samples": args.skew_samples,
            "sensor_offset_m": args.offset_m,
            "start_state": args.start,
            "documented": !args.undocumented,
        },
        "noise_m": args.noise_m,
        "quantization_m": args.quantization_m,
        "seed": args.seed,
    })
}

/// The current the dynamic-inverse tracking loop (`magctl::inverse::ControlLoop`) commands for a
/// Van der Pol trajectory, open loop.
#[allow(clippy::too_many_arguments)]
fn van_der_pol(
    params: &actuator_params::ActuatorParams,
    index: usize,
    start: StartState,
    frequency_scale_hz: f64,
    mu: f64,
    duration_s: f64,
    rate_hz: f64,
) -> Result<Experiment> {
    let mut core = magctl::params::ActuatorParameters::from_file(params, "parameter file")?;
    core.control.sample_rate_hz = rate_hz as f32;
    core.trajectory.frequency_scale_hz = frequency_scale_hz as f32;
    core.trajectory.van_der_pol_mu = mu as f32;
    let measure = core.preisach.measure();
    let control = magctl::inverse::ControlLoop::new(&measure, &core)
        .map_err(|e| anyhow!("Van der Pol tracking loop: {e:?}"))?;
    let kind = magctl::inverse::InverseKind::Dynamic;
    let mut state = control.init::<64>(kind);
    let n = (duration_s * rate_hz).round() as usize;
    Ok(Experiment {
        name: format!("{index:02}_vdp_{frequency_scale_hz:07.1}hz_mu{mu:.2}"),
        start,
        current_a: (0..n)
            .map(|_| control.tick(kind, &mut state).current_a as f64)
            .collect(),
        description: format!(
            "Van der Pol tracking command, {frequency_scale_hz} Hz scale, mu {mu}"
        ),
    })
}
