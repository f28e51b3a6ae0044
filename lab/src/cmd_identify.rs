//! `maglab identify`: a dataset folder → the full parameter JSON.
//!
//! The command parses its arguments into `maglab_identify::IdentifyOptions`, runs the
//! identification (`maglab_identify::identify`: masses, phase-lag scheme, waveform fit, the
//! alternation, the checks; docs/identification.md), prints what it found, writes the file and
//! the figures (`plot_identify`).

use crate::plot_identify;
use anyhow::{anyhow, Context, Result};
use clap::Parser;
use indicatif::{ProgressBar, ProgressStyle};
use maglab_dataset::{CurrentBetweenSamples, StartState};
use maglab_identify::dynamics::simulate::SimulationOptions;
use maglab_identify::dynamics::{
    DynamicFit, DynamicOptions, DYNAMIC_STARTS, F0_SCAN_RATIO, TERFENOL_RESISTIVITY_OHM_M,
};
use maglab_identify::experiments::ClassifyOptions;
use maglab_identify::fit::{FitOptions, Unexcited};
use maglab_identify::magnetization::Branch;
use maglab_identify::masses::MassOptions;
use maglab_identify::memory::PREISACH_STARTS;
use maglab_identify::pipeline::ReversiblePart;
use maglab_identify::{identify, Base, Identified, IdentifyOptions, RecordedDataset};
use std::path::PathBuf;

/// Arguments of `maglab identify`.
#[derive(Debug, Parser)]
pub struct Args {
    /// Dataset folder of measurement files (`t_s,current_a,displacement_m`): quasi-static and
    /// dynamic experiments, in `quasi-static/` and `dynamic/` sub-folders or classified by the
    /// spectrum of their current (docs/identification.md).
    dataset: PathBuf,
    /// Output parameter file.
    #[arg(short, long)]
    output: PathBuf,
    /// Base parameter file: grid, constants, R_eddy/ξ/f0, control and trajectory settings, and
    /// the prior masses. Default: the built-in paper defaults.
    #[arg(long)]
    params: Option<PathBuf>,
    /// Sign of M for every file: `positive` (DC-biased data, M >= 0) or `monotone` (bipolar
    /// data such as `maglab excite`; sign from input monotonicity). Default: per file, monotone
    /// when its current changes sign, else positive.
    #[arg(long)]
    branch: Option<String>,
    /// Initial memory of every quasi-static file: negative-saturation, positive-saturation,
    /// demagnetized-at-first-input (around the first current), demagnetized (around zero
    /// current), periodic. Default: per
    /// file, as dataset.json documents it, else estimated (a record starting beyond the grid
    /// saturates itself; a closed record is periodic; else demagnetized at zero current).
    #[arg(long)]
    initial: Option<String>,
    /// Zero band of the monotone sign rule, fraction of the full stroke l_m λ_s. Rows inside it
    /// are left out of the mass fit, and so are rows whose displacement lies below ≈ 11 times
    /// the record's own noise (after the lag correction) when that is higher: the square root
    /// M = M_s √(u/S) of a noisy u is biased low there (printed per record as the fit floor).
    #[arg(long, default_value_t = defaults().masses.zero_band_fraction)]
    zero_band: f64,
    /// Smoothness weight λ_s. Small by default: a Terfenol-like density is sharply peaked near
    /// the coercive field, and a stronger prior of smooth densities biases the central masses
    /// (measured on the bench plant: λ_s = 1e-6 put R_eddy 9 % off through them, 1e-8 under 1 %).
    #[arg(long, default_value_t = defaults().masses.fit.smoothness)]
    smoothness: f64,
    /// Ridge weight λ_r toward the base masses.
    #[arg(long, default_value_t = defaults().masses.fit.ridge)]
    ridge: f64,
    /// Unexcited cells: keep-prior (base masses), zero, regularized. On a grid around the
    /// reach of a rod the coil cannot saturate there are no base masses: keep-prior is
    /// regularized there (docs/model.md).
    #[arg(long, default_value_t = defaults().masses.fit.unexcited.name().to_string())]
    unexcited: String,
    /// Use every n-th sample in the regression (the memory still sees every sample).
    #[arg(long, default_value_t = defaults().masses.fit.row_stride)]
    row_stride: usize,
    /// The reversible magnetization: `none` (the paper's `M = Γ[H]`), `piecewise` (`M = Γ[H] +
    /// R(H)`, a monotone piecewise-linear anhysteretic part with a susceptibility per grid
    /// interval, fitted with the masses, which then sum to at most M_s, and written as
    /// `preisach.reversible_susceptibility`) or `auto`: `piecewise` only when the paper's masses
    /// sum past 1.02 x M_s (the sweep shows more magnetization than Γ gives) and the reversible
    /// part both meets every quasi-static record within the quality limit (2 % NRMSE) and
    /// predicts the lowest-frequency sines no worse; said in the output and in
    /// `provenance.reversible_part`. `maglab diagnose` names a kept part as an effect the
    /// paper's model lacks.
    #[arg(long, default_value_t = defaults().reversible.name().to_string())]
    reversible: String,
    /// Directory for the plots.
    #[arg(long, default_value = "out")]
    plot_dir: PathBuf,
    /// Lowest excitation frequency of a dynamic file (spectrum rule), Hz.
    #[arg(long, default_value_t = 10.0)]
    dynamic_min_hz: f64,
    /// Initial memory of every dynamic experiment for the phase-lag scheme (at rest under its
    /// first current): demagnetized, negative-saturation, positive-saturation. The final fit
    /// uses dataset.json's start states and estimates the others.
    #[arg(long, default_value = "demagnetized")]
    dynamic_start: String,
    /// The recorded current between samples for the phase-lag scheme: `linear` or `hold`. The
    /// final fit estimates it.
    #[arg(long, default_value = "linear")]
    current_between_samples: String,
    /// Longest model step of the phase-lag scheme's simulations, s.
    #[arg(long, default_value_t = 5e-6)]
    max_substep_s: f64,
    /// Electromagnetic substeps per sample of the final fit's model (Richardson-extrapolated
    /// with twice as many). Default: enough that one substep spans at most 1/200 of the period
    /// of the highest fitted frequency (4 for 200 Hz at 10 kHz): with fewer the model's own
    /// phase error bends R_eddy (−2.8 % with 1 substep on the bench plant).
    #[arg(long)]
    substeps: Option<std::num::NonZeroUsize>,
    /// f0 assumed by the phase-lag scheme, Hz (default: the base file's).
    #[arg(long)]
    resonance_hz: Option<f64>,
    /// Resistivity of the rod for the upper bound R̄ of R_eddy, Ω·m.
    #[arg(long, default_value_t = TERFENOL_RESISTIVITY_OHM_M)]
    resistivity_ohm_m: f64,
    /// Skip the final fit (write the phase-lag scheme's R_eddy, ξ and the base f0).
    #[arg(long)]
    no_waveform_fit: bool,
}

/// The library's defaults, which the options' defaults show.
fn defaults() -> IdentifyOptions {
    IdentifyOptions::default()
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
    let options = options(args)?;
    let dataset = RecordedDataset::load(
        &args.dataset,
        &ClassifyOptions {
            dynamic_min_hz: args.dynamic_min_hz,
            ..ClassifyOptions::default()
        },
    )?;
    print_dataset(args, &dataset);
    let bar = ProgressBar::new(0).with_style(
        ProgressStyle::with_template("{msg:28} [{bar:40}] {pos}/{len} ({elapsed})")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    let stage = std::sync::Mutex::new(String::new());
    let progress = |name: &str, done: usize, total: usize| {
        if let Ok(mut current) = stage.lock() {
            if *current != name {
                *current = name.to_string();
                bar.set_message(name.to_string());
                bar.set_position(0);
            }
            bar.set_length(if total == 0 {
                done as u64
            } else {
                total as u64
            });
            bar.set_position(done as u64);
        }
    };
    let base_ref = Base {
        params: &base,
        name: &base_name,
    };
    let id = identify(&dataset, base_ref, &options, &progress)?;
    bar.finish_and_clear();
    print_result(args, &id, &base, &base_name);
    if let Some(dir) = args.output.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir)?;
    }
    std::fs::write(&args.output, id.params.to_json_pretty())
        .with_context(|| format!("cannot write {}", args.output.display()))?;
    println!("wrote {}", args.output.display());
    for p in plot_identify::write_all(&id, &dataset.split, &base, &args.plot_dir)? {
        println!("wrote {}", p.display());
    }
    Ok(())
}

/// The identification's settings from the command line.
fn options(args: &Args) -> Result<IdentifyOptions> {
    let reversible =
        ReversiblePart::parse(&args.reversible).map_err(|e| anyhow!("--reversible {e}"))?;
    Ok(IdentifyOptions {
        masses: MassOptions {
            branch: args
                .branch
                .as_deref()
                .map(Branch::parse)
                .transpose()
                .map_err(|e| anyhow!(e))?,
            initial: args
                .initial
                .as_deref()
                .map(|s| StartState::parse_among(s, &PREISACH_STARTS))
                .transpose()
                .map_err(|e| anyhow!("--initial: {e}"))?,
            documented: None,
            zero_band_fraction: args.zero_band,
            fit: FitOptions {
                smoothness: args.smoothness,
                ridge: args.ridge,
                reversible: reversible.first_fit(),
                unexcited: Unexcited::parse(&args.unexcited).map_err(|e| anyhow!(e))?,
                row_stride: args.row_stride,
                total_mass_at_most: None,
                bands: Default::default(),
            },
            lag_correction: None,
            current_shift_samples: 0.0,
            reach: None,
        },
        reversible,
        dynamics: DynamicOptions {
            simulation: SimulationOptions {
                start: StartState::parse_among(&args.dynamic_start, &DYNAMIC_STARTS)
                    .map_err(|e| anyhow!("--dynamic-start: {e}"))?,
                current: CurrentBetweenSamples::parse(&args.current_between_samples)
                    .map_err(|e| anyhow!("--current-between-samples: {e}"))?,
                max_substep_s: args.max_substep_s,
            },
            resistivity_ohm_m: args.resistivity_ohm_m,
            phase_lag_resonance_hz: args.resonance_hz,
            ..DynamicOptions::default()
        },
        waveform_fit: !args.no_waveform_fit,
        substeps: args.substeps.map(|n| n.get()),
    })
}

/// How the dataset was read: documented starts, files not read, each file's class.
fn print_dataset(args: &Args, dataset: &RecordedDataset) {
    if dataset.documented.is_some() {
        println!(
            "{}: start states as documented there",
            args.dataset
                .join(maglab_dataset::dataset_info::FILE_NAME)
                .display()
        );
    }
    for p in &dataset.split.ignored {
        println!("not read (not a *.csv file): {}", p.display());
    }
    for c in &dataset.split.classification {
        println!("{}: {} ({})", c.path.display(), c.kind.name(), c.reason);
    }
    if let Some(a) = &dataset.amplifier {
        println!(
            "coil current recorded: the rod is identified from the measured current; the \
             amplifier: {}",
            a.reason
        );
    }
}

/// Everything the identification found, in the order it was found.
fn print_result(
    args: &Args,
    id: &Identified,
    base: &actuator_params::ActuatorParams,
    base_name: &str,
) {
    for prior in maglab_model::priors::uses_of(base) {
        println!("datasheet prior: {}", prior.describe());
    }
    if let Some(choice) = &id.reversible {
        println!("reversible part (--reversible auto): {}", choice.reason);
    }
    if let Some(fit) = &id.dynamic {
        print_dynamic_fit(fit, args.resistivity_ohm_m);
        if let Some(instruments) = fit
            .refined
            .as_ref()
            .and_then(|r| r.details.get("instruments_fitted_with_the_rod"))
            .and_then(|v| v.as_object())
            .filter(|m| !m.is_empty())
        {
            let list: Vec<String> = instruments
                .iter()
                .map(|(name, v)| format!("{name} = {v}"))
                .collect();
            println!(
                "instruments fitted with the rod (their datasheet bandwidth given): {}",
                list.join(", ")
            );
        }
    }
    if let Some(kept) = &id.passes {
        print_passes(kept);
    }
    print_masses(id, base);
    if id.dynamic.is_none() {
        println!(
            "NOT identified: R_eddy = {} Ω, ξ = {}, f0 = {} Hz are copied from {base_name}: the \
             dataset has no dynamic files (sinusoidal currents >= {} Hz); see \
             provenance.not_identified",
            base.actuator.eddy_resistance_ohm,
            base.actuator.damping_ratio,
            base.actuator.resonance_hz,
            args.dynamic_min_hz
        );
    }
    for w in &id.warnings {
        println!("WARNING: {w}");
    }
}

/// The masses: each quasi-static record's fit, the sum, the reversible part, unexcited cells.
fn print_masses(id: &Identified, base: &actuator_params::ActuatorParams) {
    let m = &id.masses;
    for f in &m.files {
        println!(
            "{}: {} samples, negative displacement clipped {}, above stroke {}, sign changes {}, \
             noise {:.3} µm (fit floor u >= {:.2} µm: {} rows outside the zero band left out), \
             NRMSE M {}, NRMSE y {}",
            f.file,
            f.samples,
            f.clipped_negative,
            f.above_stroke,
            f.sign_changes,
            f.noise_m * 1e6,
            f.fit_floor_m * 1e6,
            f.rows_below_floor,
            pct(f.nrmse_magnetization),
            pct(f.nrmse_displacement)
        );
    }
    println!(
        "fit: {} rows (left out by stride {}), RMS residual {:.4e} A/m, {}",
        m.fit.rows, m.fit.strided_out, m.fit.rms_residual, m.fit.solver
    );
    println!(
        "sum of masses {:.6e} A/m (M_s = {:.6e} A/m)",
        m.fit.weights.iter().sum::<f64>(),
        base.actuator.saturation_magnetization_a_per_m
    );
    if let Some(chi) = &m.params.preisach.reversible_susceptibility {
        if let Ok(grid) = maglab_identify::design::Grid::of_params(&m.params.preisach) {
            // R at the top of the grid: ½ Σ χ_k Δ_k.
            let half_span: f64 = 0.5
                * maglab_identify::model::reversible_rises(&grid, chi)
                    .iter()
                    .sum::<f64>();
            println!(
                "reversible part: susceptibility {:.3e} to {:.3e}, R at the top of the grid \
                 {:.6e} A/m (saturation output = sum of masses + that)",
                chi.iter().cloned().fold(f64::INFINITY, f64::min),
                chi.iter().cloned().fold(0.0, f64::max),
                half_span
            );
        }
    }
    println!(
        "unexcited cells: {} (treatment: {}; cells of the one-way bands: 0, the offset carries them)",
        m.fit.unexcited.len(),
        m.fit.unexcited_treatment.name()
    );
    for (label, n) in &m.fit.outside {
        if *n > 0 {
            println!("{label}: {n} samples outside the grid (memory saturated there)");
        }
    }
}

/// Every pass of the alternation and the one kept.
fn print_passes(kept: &maglab_identify::pipeline::ChosenPass) {
    for p in &kept.passes {
        let kept_for = if p.base_value_kept_for.is_empty() {
            String::new()
        } else {
            format!(
                " ({} the base file's: the sines' value lies at an end of its search)",
                p.base_value_kept_for.join(", ")
            )
        };
        println!(
            "pass {}: masses with the lags of R_eddy = {:.2} Ω, ξ = {:.4}, f0 = {:.1} Hz{kept_for}, \
             the current read {:+.3} samples after its own sample time -> R_eddy {:.2} Ω, ξ {:.4}, \
             f0 {:.1} Hz, RMS NRMSE {:.3} %{}",
            p.pass,
            p.lags[0],
            p.lags[1],
            p.lags[2],
            p.current_shift_samples,
            p.fitted[0],
            p.fitted[1],
            p.fitted[2],
            100.0 * p.rms_nrmse,
            p.moved_from_pass_before
                .map_or(String::new(), |m| format!(" (moved {:.2} % from the pass before)", 100.0 * m))
        );
    }
    let c = kept.passes[kept.pass - 1].fitted;
    println!(
        "R_eddy, ξ, f0: {:.2} Ω, {:.4}, {:.1} Hz from pass {} of {} ({})",
        c[0],
        c[1],
        c[2],
        kept.pass,
        kept.passes.len(),
        if kept.settled {
            "the alternation settled there"
        } else {
            "the lowest RMS NRMSE"
        }
    );
}

/// The phase-lag scheme and the final fit of the kept pass, side by side.
fn print_dynamic_fit(fit: &DynamicFit, resistivity_ohm_m: f64) {
    let pl = &fit.phase_lag;
    if let Some(file_hz) = pl.scanned_from_hz {
        println!(
            "phase-lag scheme: no R_eddy gives a positive damping ratio at the file's f0 = {file_hz} \
             Hz; f0 scanned from {:.1} to {:.1} Hz, least phase misfit at {:.1} Hz (the rig's \
             resonance differs from the file's, or the chain has a lag (4)-(5) do not model: \
             `maglab diagnose` tells which)",
            file_hz / F0_SCAN_RATIO,
            file_hz * F0_SCAN_RATIO,
            pl.resonance_hz
        );
    }
    println!(
        "R̄ = 8πρN²/l_m = {:.1} Ω (ρ = {:e} Ω·m); grid: {} geometric points from {:.3} Ω, then {} \
         points in [{:.2}, {:.2}] Ω",
        pl.r_bar_ohm,
        resistivity_ohm_m,
        pl.coarse.len(),
        pl.coarse[0].eddy_resistance_ohm,
        pl.fine.len(),
        pl.fine.first().map_or(f64::NAN, |c| c.eddy_resistance_ohm),
        pl.fine.last().map_or(f64::NAN, |c| c.eddy_resistance_ohm)
    );
    println!(
        "{:>10} {:>10} {:>12} {:>12} {:>14}",
        "f (Hz)", "lag (°)", "ξ_k (PL)", "NRMSE PL", "NRMSE final"
    );
    for (k, e) in fit.experiments.iter().enumerate() {
        println!(
            "{:>10.3} {:>10.3} {:>12.4} {:>11.3} % {:>13}",
            e.frequency_hz,
            e.measured_lag_deg,
            pl.chosen.damping_ratios[k],
            100.0 * e.nrmse_phase_lag,
            e.nrmse_refined
                .map_or("—".into(), |v| format!("{:.3} %", 100.0 * v))
        );
    }
    println!(
        "{:<34} {:>12} {:>10} {:>10} {:>12}",
        "method", "R_eddy (Ω)", "ξ", "f0 (Hz)", "RMS NRMSE"
    );
    let rms = |v: &mut dyn Iterator<Item = f64>| {
        let (s, n) = v.fold((0.0, 0usize), |(s, n), x| (s + x * x, n + 1));
        (s / n.max(1) as f64).sqrt()
    };
    println!(
        "{:<34} {:>12.2} {:>10.4} {:>10.1} {:>10.3} %",
        if pl.scanned_from_hz.is_some() {
            "phase-lag scheme (f0 scanned)"
        } else {
            "phase-lag scheme (f0 assumed)"
        },
        fit.phase_lag_params.eddy_resistance_ohm,
        fit.phase_lag_params.damping_ratio,
        fit.phase_lag_params.resonance_hz,
        100.0 * rms(&mut fit.experiments.iter().map(|e| e.nrmse_phase_lag))
    );
    if let Some(w) = &fit.refined {
        println!(
            "{:<34} {:>12.2} {:>10.4} {:>10.1} {:>10.3} %",
            "waveform fit with nuisances (LM)",
            w.params.eddy_resistance_ohm,
            w.params.damping_ratio,
            w.params.resonance_hz,
            100.0 * w.rms_nrmse,
        );
        if let Some(e) = w.details.get("estimated") {
            println!("estimated with it: {e}");
        }
        if let (Some(top), Some(substeps)) = (
            w.details.get("fitted_up_to_hz").and_then(|v| v.as_f64()),
            w.details.get("substeps").and_then(|v| v.as_u64()),
        ) {
            println!("fitted up to {top:.1} Hz, {substeps} substep(s) per sample");
        }
    }
    println!(
        "(paper's literal criterion, least variance of ξ_k: R_eddy = {:.2} Ω; least std/mean: {:.2} Ω; \
         phase misfit of the chosen candidate {:.3}°)",
        pl.least_variance_ohm,
        pl.least_cv_ohm,
        pl.chosen.phase_misfit_rad.to_degrees()
    );
}

fn pct(v: Option<f64>) -> String {
    v.map_or("n/a".into(), |v| format!("{:.3} %", 100.0 * v))
}
