//! Measure (with the coil-current channel) → identify → diagnose → re-bake → track on a plant
//! whose parameters are not the baked ones: the bench workflow, end to end, under QEMU.

use super::measurement::identification_programme;
use super::{run_once, HilResult, HilRun};
use crate::qemu::firmware::build_bin;
use crate::util::{run_checked, Ctx};
use anyhow::{ensure, Context, Result};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::Arc;
use std::time::Instant;

/// Ticks of the streamed measurement compared with the compiled-in one in [`end_to_end`].
const STREAMED_CHECK_TICKS: u32 = 3_000;

/// The plant's rod: a factorized Gaussian Preisach measure on a plane 4× wider than the field
/// the coil reaches at its current limit (`maglab_plant::rods`), as a real Terfenol-D rod is.
const PLANT_ROD: &str = "gaussian:4";

/// The user's file before identification: the defaults with a trajectory band that rod can
/// follow (`host-tests/hil/wide_rod_base.json`). Baked as it is it is "the default file" of the
/// comparison; `maglab identify --params` starts from it.
const BASE_PARAMS: &str = "host-tests/hil/wide_rod_base.json";

/// The firmware image's features.
const FEATURES: &str = "board-mps2-an386,panic-never";

/// The identified constants' tolerance, relative to the plant's.
const CONSTANT_TOLERANCE: f64 = 0.03;

/// The plant's current monitor: white noise of its reading, A (a typical monitor through a
/// 12-bit ADC over ±2 A). The plant sends the coil current in every sample frame (link version
/// 2), the firmware records it, and the dataset has the `coil_current_a` column.
const MONITOR_NOISE_A: f64 = 1e-3;

/// Measure → identify → bake → track on a plant whose parameters are not the baked ones
/// (`host-tests/hil/other_actuator.json`: R_eddy +25 %, ξ −20 %, f0 +15 %) and whose rod the
/// coil cannot saturate ([`PLANT_ROD`]). Returns the summary lines; fails unless the identified
/// constants are within [`CONSTANT_TOLERANCE`], tracking with the identified parameters is ≤ 1 %
/// of the peak-to-peak in closed loop, and feedforward ≥ 5× better than with the defaults.
pub fn end_to_end(ctx: &Ctx, elf: &Path, exe: &Path, base: &Path) -> Result<String> {
    let plant = PathBuf::from("host-tests/hil/other_actuator.json");
    let data = base.join("data");
    let _ = std::fs::remove_dir_all(&data);
    let programme = Arc::new(identification_programme()?);
    let on_plant = |dir: &str| {
        let mut run = HilRun::new(base.join(dir));
        run.plant_params = Some(plant.clone());
        run.plant_rod = Some(PLANT_ROD.into());
        run
    };
    // The firmware plays its compiled-in programme and logs the record as the NUCLEO
    // measurement image does (defmt `MEAS` lines); `crate::record` writes the dataset from it.
    let mut m = on_plant("measure");
    m.plant_coil_current_noise_a = Some(MONITOR_NOISE_A);
    m.measure_local = Some(data.clone());
    let r = run_once(ctx, elf, Some(exe), &m)?;
    let mut s = r.summary.clone();
    let mut streamed = on_plant("measure_streamed");
    streamed.plant_coil_current_noise_a = Some(MONITOR_NOISE_A);
    streamed.measure = Some((programme.clone(), base.join("unused")));
    streamed.measure_ticks = Some(STREAMED_CHECK_TICKS);
    let r2 = run_once(ctx, elf, Some(exe), &streamed)?;
    writeln!(s, "{}", streamed_matches_compiled(&r, &r2)?)?;
    let identified = base.join("identified.json");
    let (json, identify_s) = identify(ctx, exe, &data, &identified, base)?;
    writeln!(s, "{}", coil_current_judged(&json)?)?;
    writeln!(
        s,
        "end to end on a {PLANT_ROD} rod: {} ticks measured ({} experiments), identify {identify_s:.0} s",
        programme.current_a.len(),
        programme.experiments.len()
    )?;
    let (table, worst_constant) = constants_table(ctx, &json, &plant)?;
    s.push_str(&table);
    writeln!(
        s,
        "{}",
        diagnose_measured(ctx, exe, &identified, &data, base)?
    )?;
    // Re-bake: the same firmware built with the base and with the identified file, each kept as
    // a copy; then the default build again, which the later runs use.
    let base_elf = bake(
        ctx,
        elf,
        &ctx.root.join(BASE_PARAMS),
        &base.join("firmware-hil-base"),
    )?;
    let identified_elf = bake(ctx, elf, &identified, &base.join("firmware-hil-identified"))?;
    run_checked(build_bin(ctx, "firmware-hil", FEATURES))?;
    let mut rms = [0.0f64; 2];
    for (k, (name, fw)) in [("default", &base_elf), ("identified", &identified_elf)]
        .into_iter()
        .enumerate()
    {
        // Feedforward only: this compares the models (the feedback would hide their error).
        let mut t = on_plant(&format!("track_{name}"));
        t.elf = Some(fw.clone());
        t.feedback = false;
        let (a, b) = tracking_error(ctx, elf, exe, &t)?;
        rms[k] = a;
        writeln!(
            s,
            "  tracking on that plant, feedforward, firmware baked with the {name} parameters: RMS {a:.3} %, max {b:.2} % of peak-to-peak"
        )?;
    }
    let mut t = on_plant("track_identified_feedback");
    t.elf = Some(identified_elf);
    let (closed_loop_rms, closed_loop_max) = tracking_error(ctx, elf, exe, &t)?;
    writeln!(
        s,
        "  the same with the parameter file's feedback on: RMS {closed_loop_rms:.3} %, max {closed_loop_max:.2} % of peak-to-peak (whole run, learning included)"
    )?;
    writeln!(
        s,
        "  default / identified (feedforward): {:.1}x",
        rms[0] / rms[1]
    )?;
    print!("{s}");
    ensure!(
        worst_constant <= CONSTANT_TOLERANCE,
        "an identified constant is {:.1} % off the plant's, above {:.0} %",
        100.0 * worst_constant,
        100.0 * CONSTANT_TOLERANCE
    );
    ensure!(
        closed_loop_rms <= 1.0,
        "identified parameters track at {closed_loop_rms:.3} % > 1 % in closed loop"
    );
    ensure!(
        rms[0] >= 5.0 * rms[1],
        "identified parameters only {:.1}x better than the defaults",
        rms[0] / rms[1]
    );
    Ok(s)
}

/// The streamed programme (R frames, the protocol's measurement mode) drives the same firmware
/// as the compiled-in one (`compiled`): its first [`STREAMED_CHECK_TICKS`] command frames,
/// bit for bit. Returns the summary line.
fn streamed_matches_compiled(compiled: &HilResult, streamed: &HilResult) -> Result<String> {
    let n = STREAMED_CHECK_TICKS as usize;
    ensure!(
        streamed.frames.len() >= n && compiled.frames.len() >= n,
        "streamed check: {} / {} frames",
        streamed.frames.len(),
        compiled.frames.len()
    );
    for (k, (a, b)) in compiled
        .frames
        .iter()
        .zip(&streamed.frames)
        .take(n)
        .enumerate()
    {
        ensure!(
            a.value.to_bits() == b.value.to_bits()
                && a.desired_m.to_bits() == b.desired_m.to_bits()
                && a.flags == b.flags,
            "tick {k}: the compiled-in programme commands {} A (reading {} m), the streamed one {} A ({} m)",
            a.value,
            a.desired_m,
            b.value,
            b.desired_m
        );
    }
    Ok(format!(
        "  streamed programme (R frames): its first {n} ticks command the same currents and read the same samples, bit for bit"
    ))
}

/// `maglab identify` on the measured folder `data` from [`BASE_PARAMS`] into `identified`:
/// the file as JSON and how long it took, s.
fn identify(
    ctx: &Ctx,
    exe: &Path,
    data: &Path,
    identified: &Path,
    base: &Path,
) -> Result<(serde_json::Value, f64)> {
    let started = Instant::now();
    let mut id = Command::new(exe);
    id.arg("identify")
        .arg(data)
        .arg("-o")
        .arg(identified)
        .arg("--params")
        .arg(ctx.root.join(BASE_PARAMS))
        .arg("--plot-dir")
        .arg(base.join("plots"))
        .current_dir(&ctx.root);
    run_checked(id)?;
    let identify_s = started.elapsed().as_secs_f64();
    let json = serde_json::from_str(&std::fs::read_to_string(identified)?)?;
    Ok((json, identify_s))
}

/// The coil current went through the firmware's record into the dataset, and the
/// identification judged the amplifier on it (the plant's follows the command: ruled out).
/// Returns the summary line.
fn coil_current_judged(identified: &serde_json::Value) -> Result<String> {
    let judgement = &identified["provenance"]["coil_current"]["judgement"];
    ensure!(
        judgement["amplifier_named"] == serde_json::Value::Bool(false),
        "the identification did not judge the amplifier on the recorded coil current \
         (provenance.coil_current: {judgement})"
    );
    Ok(format!(
        "  coil current recorded (plant's monitor, {MONITOR_NOISE_A} A noise, through the firmware's record): {}",
        judgement["reason"].as_str().unwrap_or("?")
    ))
}

/// R_eddy, ξ, f0 of the base file, the plant (`plant`, relative to the repository) and the
/// `identified` file, as table lines, and the largest relative error of the identified ones
/// (infinite when one is missing).
fn constants_table(
    ctx: &Ctx,
    identified: &serde_json::Value,
    plant: &Path,
) -> Result<(String, f64)> {
    let truth: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(ctx.root.join(plant))?)?;
    let nominal: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(ctx.root.join(BASE_PARAMS))?)?;
    let mut s = String::new();
    writeln!(
        s,
        "  constant             nominal (baked)   plant   identified"
    )?;
    let mut worst_constant = 0.0f64;
    for key in ["eddy_resistance_ohm", "damping_ratio", "resonance_hz"] {
        let v = |j: &serde_json::Value| j["actuator"][key].as_f64().unwrap_or(f64::NAN);
        let error = v(identified) / v(&truth) - 1.0;
        // NaN (a missing field) fails the tolerance check.
        worst_constant = worst_constant.max(if error.is_nan() {
            f64::INFINITY
        } else {
            error.abs()
        });
        writeln!(
            s,
            "  {key:<20} {:>15.4} {:>7.4} {:>12.4} ({:+.1} %)",
            v(&nominal),
            v(&truth),
            v(identified),
            100.0 * error
        )?;
    }
    Ok((s, worst_constant))
}

/// Diagnoses the measured folder `data` with the `identified` file: split at the coil (the
/// amplifier on the recorded current, the rest of the library on it against the
/// displacement), a plant without effects must come out `none`. Returns the summary line.
fn diagnose_measured(
    ctx: &Ctx,
    exe: &Path,
    identified: &Path,
    data: &Path,
    base: &Path,
) -> Result<String> {
    let report = base.join("diagnosis");
    let mut diagnose = Command::new(exe);
    diagnose
        .arg("diagnose")
        .arg("--params")
        .arg(identified)
        .arg("-o")
        .arg(&report)
        .arg(data)
        .current_dir(&ctx.root);
    let started = Instant::now();
    run_checked(diagnose)?;
    let d: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(report.join("diagnosis.json"))?)?;
    let line = format!(
        "  maglab diagnose --params identified.json on the measured folder: {} (grade {}; amplifier named on the coil current: {}), {:.0} s",
        d["verdict"].as_str().unwrap_or("?"),
        d["grade"].as_str().unwrap_or("?"),
        d["coil_current"]["amplifier_named"],
        started.elapsed().as_secs_f64()
    );
    ensure!(
        d["verdict"] == "none" && d["coil_current"]["amplifier_named"] == false,
        "the measured folder of a plant without effects diagnosed as `{}`: {}",
        d["verdict"].as_str().unwrap_or("?"),
        d["verdict_reason"].as_str().unwrap_or("?")
    );
    Ok(line)
}

/// Runs `run` and returns its tracking error: RMS and largest, % of the peak-to-peak.
fn tracking_error(ctx: &Ctx, elf: &Path, exe: &Path, run: &HilRun) -> Result<(f64, f64)> {
    let r = run_once(ctx, elf, Some(exe), run)?;
    let (rms, max, _) = r.tracking.context("no tracking error")?;
    Ok((rms, max))
}

/// Builds the firmware with `params` baked in, in the firmware's own target directory (only
/// `magctl` recompiles: `build.rs` declares `rerun-if-env-changed`), and keeps a copy at `to`.
fn bake(ctx: &Ctx, elf: &Path, params: &Path, to: &Path) -> Result<PathBuf> {
    let mut build = build_bin(ctx, "firmware-hil", FEATURES);
    build.env("ACTUATOR_PARAMS", params.canonicalize()?);
    run_checked(build)?;
    std::fs::copy(elf, to)
        .with_context(|| format!("cannot copy {} to {}", elf.display(), to.display()))?;
    Ok(to.to_path_buf())
}
