//! `maglab params`: write the default parameter file, or check one.
//!
//! `params default [-o FILE]` writes `actuator_params::paper_defaults()` (the paper's constants
//! with the analytic default Preisach measure, see `docs/params.md`) as pretty JSON, to stdout
//! without `-o`. `params check FILE` validates a file exactly as `build.rs` would and prints a
//! summary; an invalid file is reported with its field and reason and exits with code 2.

use crate::params_io;
use actuator_params::{ActuatorParams, PREISACH_LEVELS};
use anyhow::{Context, Result};
use clap::{Parser, Subcommand};
use std::path::{Path, PathBuf};

/// Arguments of `maglab params`.
#[derive(Debug, Parser)]
pub struct Args {
    #[command(subcommand)]
    action: Action,
}

#[derive(Debug, Subcommand)]
enum Action {
    /// Write the default parameter file (paper constants, analytic Preisach measure).
    Default {
        /// Output file; stdout when omitted.
        #[arg(short, long, value_name = "FILE")]
        output: Option<PathBuf>,
    },
    /// Validate a parameter file and print a summary (exit code 2 when invalid).
    Check {
        /// The parameter file to check.
        #[arg(value_name = "FILE")]
        file: PathBuf,
    },
}

/// Runs `maglab params`.
pub fn run(args: &Args) -> Result<()> {
    match &args.action {
        Action::Default { output } => write_default(output.as_ref()),
        Action::Check { file } => check(file),
    }
}

fn write_default(output: Option<&PathBuf>) -> Result<()> {
    let params = actuator_params::paper_defaults();
    let text = params.to_json_pretty();
    // What we write must read back as a valid file: the same check `build.rs` applies.
    ActuatorParams::parse(&text, "paper_defaults()")
        .context("the built-in defaults do not validate")?;
    match output {
        None => print!("{text}"),
        Some(path) => {
            if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
                std::fs::create_dir_all(dir)
                    .with_context(|| format!("cannot create directory {}", dir.display()))?;
            }
            std::fs::write(path, &text)
                .with_context(|| format!("cannot write {}", path.display()))?;
            eprintln!("wrote {}", path.display());
        }
    }
    Ok(())
}

/// Validates `path` as `build.rs` would (the file, then what a firmware image needs) and prints
/// its summary.
fn check(path: &Path) -> Result<()> {
    let file = ActuatorParams::load(path).context("invalid parameter file")?;
    file.validate_for_firmware(&path.display().to_string())
        .context("invalid parameter file for a firmware image")?;
    let core = params_io::to_core(&file)?;
    let measure = core.preisach.measure();
    println!(
        "{}: valid (schema version {})",
        path.display(),
        file.schema_version
    );
    println!("  provenance   {}", file.provenance.source);
    print_actuator(&file);
    print_preisach(&file, measure.max_density_a_per_m());
    print_drive_and_sensor(&file);
    print_optional_sections(&file);
    Ok(())
}

/// The rod's constants and what follows from them (stroke, c1 of eq. (4)).
fn print_actuator(file: &ActuatorParams) {
    let a = &file.actuator;
    let stroke_m = a.rod_length_m * a.saturation_magnetostriction;
    let mu0 = f64::from(magctl::params::VACUUM_PERMEABILITY_H_PER_M);
    let c1 = a.eddy_resistance_ohm / (mu0 * a.coil_turns * a.rod_area_m2);
    println!(
        "  actuator     N_m = {}, A_m = {:.3e} m², l_m = {:.3e} m, c0 = {:.3e} 1/m",
        a.coil_turns, a.rod_area_m2, a.rod_length_m, a.coil_factor_per_m
    );
    println!(
        "               M_s = {:.4e} A/m, λ_s = {}, f0 = {} Hz, R_eddy = {} Ω, ξ = {}",
        a.saturation_magnetization_a_per_m,
        a.saturation_magnetostriction,
        a.resonance_hz,
        a.eddy_resistance_ohm,
        a.damping_ratio
    );
    println!(
        "               stroke l_m λ_s = {:.2} µm, c1 = R_eddy/(μ0 N_m A_m) = {c1:.4e} 1/(m·s)",
        stroke_m * 1e6
    );
}

/// The Preisach grid and its masses; `max_density_a_per_m` the largest cell's.
fn print_preisach(file: &ActuatorParams, max_density_a_per_m: f32) {
    let a = &file.actuator;
    let p = &file.preisach;
    let total = file.preisach_total_a_per_m();
    println!(
        "  preisach     {} levels ({} cells) over [{:.2}, {:.2}] kA/m, cell width {:.3} kA/m",
        p.levels,
        p.weights_a_per_m.len(),
        p.h_min_a_per_m / 1e3,
        p.h_max_a_per_m / 1e3,
        (p.h_max_a_per_m - p.h_min_a_per_m) / PREISACH_LEVELS as f64 / 1e3
    );
    println!(
        "               Σw = {:.4e} A/m ({:.2} % of M_s), largest cell density {:.4e} A/m per cell",
        total,
        100.0 * total / a.saturation_magnetization_a_per_m,
        max_density_a_per_m
    );
}

/// The control loop's limits, the amplifier, the sensor and the trajectory.
fn print_drive_and_sensor(file: &ActuatorParams) {
    let c = &file.control;
    let t = &file.trajectory;
    println!(
        "  control      {} Hz, |I| <= {} A, |dI/dt| <= {} A/s",
        c.sample_rate_hz, c.current_limit_a, c.current_slew_limit_a_per_s
    );
    let amp = &file.amplifier;
    println!(
        "  amplifier    {} V compliance, coil {} Ω, {} mH: slew at the limit <= {:.0} A/s",
        amp.compliance_voltage_v,
        amp.coil_resistance_ohm,
        amp.coil_inductance_h * 1e3,
        amp.max_slew_a_per_s(c.current_limit_a)
    );
    let sn = &file.sensor;
    println!(
        "  sensor       {}-bit ADC, {:.4} nm/count from {:.3} µm, valid [{:.2}, {:.2}] µm, delay {:.1} µs",
        sn.adc_bits,
        sn.gain_m_per_count * 1e9,
        sn.offset_m * 1e6,
        sn.valid_min_m * 1e6,
        sn.valid_max_m * 1e6,
        sn.sample_delay_s * 1e6
    );
    println!(
        "  trajectory   Van der Pol μ = {}, scale {} Hz, band [{:.2}, {:.2}] µm",
        t.van_der_pol_mu,
        t.frequency_scale_hz,
        t.displacement_min_m * 1e6,
        t.displacement_max_m * 1e6
    );
}

/// The sections a file may leave out: the coil's heating, the current monitor, the datasheet.
fn print_optional_sections(file: &ActuatorParams) {
    let c = &file.control;
    let amp = &file.amplifier;
    let sn = &file.sensor;
    if let Some(h) = &file.coil_thermal {
        let rise_k_per_a2 = h.thermal_resistance_k_per_w * amp.coil_resistance_ohm;
        println!(
            "  coil heat    {} K/W, τ {} s: {:.1} K/A², {:.1} K steady at the limit; the measurement \
             programme keeps the rise <= {} K",
            h.thermal_resistance_k_per_w,
            h.time_constant_s,
            rise_k_per_a2,
            rise_k_per_a2 * c.current_limit_a * c.current_limit_a,
            h.max_rise_k
        );
    }
    if let Some(m) = &file.current_monitor {
        let full_scale = ((1u64 << sn.adc_bits.min(63)) - 1) as f64;
        println!(
            "  monitor      coil current {:.4} mA/count from {} A: [{:.3}, {:.3}] A over the ADC",
            m.gain_a_per_count * 1e3,
            m.offset_a,
            m.offset_a.min(m.offset_a + m.gain_a_per_count * full_scale),
            m.offset_a.max(m.offset_a + m.gain_a_per_count * full_scale)
        );
    }
    if let Some(d) = &file.datasheet {
        let given: Vec<&str> = d
            .fields()
            .iter()
            .filter(|(_, v)| v.is_some())
            .map(|(name, _)| *name)
            .collect();
        println!("  datasheet    {}", given.join(", "));
    }
}
