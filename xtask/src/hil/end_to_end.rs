//! Measure → identify → re-bake → track on a plant whose parameters are not the baked ones:
//! the bench workflow, end to end, under QEMU.

use super::measurement::identification_programme;
use super::{run_once, HilRun};
use crate::qemu::build_bin;
use crate::util::{run_checked, Ctx};
use anyhow::{ensure, Context, Result};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::Arc;
use std::time::Instant;

/// Ticks of the streamed measurement compared with the compiled-in one in [`end_to_end`].
const STREAMED_CHECK_TICKS: u32 = 3_000;

/// Measure → identify → bake → track on a plant whose parameters are not the baked ones
/// (`host-tests/hil/other_actuator.json`: R_eddy +25 %, ξ −20 %, f0 +15 %, another Preisach
/// measure). Returns the summary lines; fails unless tracking with the identified parameters is
/// ≤ 1 % of the peak-to-peak and ≥ 5× better than with the defaults.
pub fn end_to_end(ctx: &Ctx, elf: &Path, exe: &Path, base: &Path) -> Result<String> {
    let plant = PathBuf::from("host-tests/hil/other_actuator.json");
    let data = base.join("data");
    let _ = std::fs::remove_dir_all(&data);
    let programme = Arc::new(identification_programme()?);
    // The firmware plays its compiled-in programme and logs the record as the NUCLEO
    // measurement image does (defmt `MEAS` lines); `crate::record` writes the dataset from it.
    let mut m = HilRun::new(base.join("measure"));
    m.plant_params = Some(plant.clone());
    m.measure_local = Some(data.clone());
    let r = run_once(ctx, elf, Some(exe), &m)?;
    let mut s = r.summary.clone();
    // The streamed programme (R frames, the protocol's measurement mode) drives the same
    // firmware identically: its first ticks, frame for frame.
    let mut streamed = HilRun::new(base.join("measure_streamed"));
    streamed.plant_params = Some(plant.clone());
    streamed.measure = Some((programme.clone(), base.join("unused")));
    streamed.measure_ticks = Some(STREAMED_CHECK_TICKS);
    let r2 = run_once(ctx, elf, Some(exe), &streamed)?;
    let n = STREAMED_CHECK_TICKS as usize;
    ensure!(
        r2.frames.len() >= n && r.frames.len() >= n,
        "streamed check: {} / {} frames",
        r2.frames.len(),
        r.frames.len()
    );
    for (k, (a, b)) in r.frames.iter().zip(&r2.frames).take(n).enumerate() {
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
    writeln!(
        s,
        "  streamed programme (R frames): its first {n} ticks command the same currents and read the same samples, bit for bit"
    )?;
    let identified = base.join("identified.json");
    let started = Instant::now();
    let mut id = Command::new(exe);
    id.arg("identify")
        .arg(&data)
        .arg("-o")
        .arg(&identified)
        .arg("--params")
        .arg(ctx.root.join("params/actuator.json"))
        .arg("--plot-dir")
        .arg(base.join("plots"))
        .current_dir(&ctx.root);
    run_checked(id)?;
    let identify_s = started.elapsed().as_secs_f64();
    let json: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&identified)?)?;
    let truth: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(ctx.root.join(&plant))?)?;
    let nominal: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(
        ctx.root.join("params/actuator.json"),
    )?)?;
    writeln!(
        s,
        "end to end: {} ticks measured ({} experiments), identify {identify_s:.0} s",
        programme.current_a.len(),
        programme.experiments.len()
    )?;
    writeln!(
        s,
        "  constant             nominal (baked)   plant   identified"
    )?;
    for key in ["eddy_resistance_ohm", "damping_ratio", "resonance_hz"] {
        let v = |j: &serde_json::Value| j["actuator"][key].as_f64().unwrap_or(f64::NAN);
        writeln!(
            s,
            "  {key:<20} {:>15.4} {:>7.4} {:>12.4} ({:+.1} %)",
            v(&nominal),
            v(&truth),
            v(&json),
            100.0 * (v(&json) / v(&truth) - 1.0)
        )?;
    }
    // Re-bake: the same firmware built with the identified file, in the firmware's own target
    // directory (only `magctl` recompiles: `build.rs` declares `rerun-if-env-changed`; a
    // directory of its own rebuilt every dependency, 71 s in CI), kept as a copy; then the
    // default build again, which the later runs use.
    let features = "board-mps2-an386,panic-never";
    let mut build = build_bin(ctx, "firmware-hil", features);
    build.env("ACTUATOR_PARAMS", identified.canonicalize()?);
    run_checked(build)?;
    let identified_elf = base.join("firmware-hil-identified");
    std::fs::copy(elf, &identified_elf).with_context(|| {
        format!(
            "cannot copy {} to {}",
            elf.display(),
            identified_elf.display()
        )
    })?;
    run_checked(build_bin(ctx, "firmware-hil", features))?;
    let mut rms = [0.0f64; 2];
    for (k, (name, fw)) in [("default", None), ("identified", Some(identified_elf))]
        .into_iter()
        .enumerate()
    {
        // Feedforward only: this compares the models (the feedback would hide their error).
        let mut t = HilRun::new(base.join(format!("track_{name}")));
        t.plant_params = Some(plant.clone());
        t.elf = fw.clone();
        t.feedback = false;
        let r = run_once(ctx, elf, Some(exe), &t)?;
        let (a, b, _) = r.tracking.context("no tracking error")?;
        rms[k] = a;
        writeln!(
            s,
            "  tracking on that plant, feedforward, firmware baked with the {name} parameters: RMS {a:.3} %, max {b:.2} % of peak-to-peak"
        )?;
        if let Some(fw) = fw {
            let mut t = HilRun::new(base.join("track_identified_feedback"));
            t.plant_params = Some(plant.clone());
            t.elf = Some(fw);
            let r = run_once(ctx, elf, Some(exe), &t)?;
            let (a, b, _) = r.tracking.context("no tracking error")?;
            writeln!(
                s,
                "  the same with the parameter file's feedback on: RMS {a:.3} %, max {b:.2} % of peak-to-peak (whole run, learning included)"
            )?;
        }
    }
    writeln!(
        s,
        "  default / identified (feedforward): {:.1}x",
        rms[0] / rms[1]
    )?;
    print!("{s}");
    ensure!(
        rms[1] <= 1.0,
        "identified parameters track at {:.3} % > 1 %",
        rms[1]
    );
    ensure!(
        rms[0] >= 5.0 * rms[1],
        "identified parameters only {:.1}x better than the defaults",
        rms[0] / rms[1]
    );
    Ok(s)
}
