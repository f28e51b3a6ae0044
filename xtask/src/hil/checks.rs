//! The virtual bench's checks (the `hil` step of `cargo xtask test`).

use super::end_to_end::end_to_end;
use super::{firmware, maglab, run_once, HilRun, Inject};
use crate::util::Ctx;
use anyhow::{ensure, Context, Result};
use magctl::inverse::CommandFlags;
use std::fmt::Write as _;
use std::path::Path;

/// The runs `cargo xtask test` makes (step `hil`): the default plant for one second (exit 0,
/// tracking ≤ 1 % of the peak-to-peak on the true displacement, ≤ 30 s wall); the Python plant
/// `host-tests/hil/first_order_plant.py` speaking the protocol (exit 0), also started 5 s late;
/// conditioning vs random prior histories; measure → identify → re-bake → track
/// ([`end_to_end`], on a rod the coil cannot saturate); the interrupt's worst case on rods the
/// baked file does not describe (`super::matrix`, ≤ 1,500 instructions); a NaN sample (exit 7), a
/// silent link (exit 8) and a desynchronized frame (exit 8), each ending at 0 A; the NUCLEO image
/// under the STM32 emulator (`super::nucleo`).
pub fn check(ctx: &Ctx) -> Result<String> {
    let elf = firmware(ctx)?;
    let exe = maglab(ctx)?;
    let base = ctx.root.join("out").join("hil");
    let mut summary = default_plant(ctx, &elf, &exe, &base)?;
    summary.push_str(&python_plants(ctx, &elf, &base)?);
    summary.push_str(&conditioning(ctx, &elf, &exe, &base)?);
    summary.push_str(&end_to_end(ctx, &elf, &exe, &base.join("e2e"))?);
    let matrix = super::matrix::interrupt_matrix(ctx, &elf, &exe, &base.join("matrix"))?;
    print!("{matrix}");
    summary.push_str(&matrix);
    summary.push_str(&faults(ctx, &elf, &exe, &base)?);
    summary.push_str(&super::nucleo::check(ctx, &exe, &base.join("nucleo"))?);
    std::fs::write(base.join("summary.txt"), &summary)?;
    Ok(summary)
}

/// The default plant for one second: exit 0, more commands than ticks (the conditioning comes
/// first), ≤ 30 s of wall time, tracking ≤ 1 % of the peak-to-peak.
fn default_plant(ctx: &Ctx, elf: &Path, exe: &Path, base: &Path) -> Result<String> {
    let default = HilRun::new(base.join("default"));
    let r = run_once(ctx, elf, Some(exe), &default)?;
    let (rms, _, _) = r
        .tracking
        .context("no tracking error from the default plant")?;
    ensure!(
        r.commands > default.ticks as usize,
        "{} commands for {} tracking ticks and the conditioning",
        r.commands,
        default.ticks
    );
    ensure!(
        r.wall_s <= 30.0,
        "1 s of control took {:.1} s of wall time",
        r.wall_s
    );
    ensure!(
        rms <= 1.0,
        "tracking RMS {rms:.3} % > 1 % on the default plant"
    );
    Ok(r.summary)
}

/// The Python plant speaking the protocol (its tracking scored on the true displacement it
/// reports), and the same plant started 5 s late.
fn python_plants(ctx: &Ctx, elf: &Path, base: &Path) -> Result<String> {
    let mut py = HilRun::new(base.join("python"));
    py.plant_cmd =
        Some("python3 host-tests/hil/first_order_plant.py --params params/actuator.json".into());
    py.ticks = 2_000;
    let mut r = run_once(ctx, elf, None, &py)?;
    let mut summary = std::mem::take(&mut r.summary);
    // The Python plant writes its true displacement (docs/hil.md, "Scoring"): the tracking
    // figure is scored on it, and says so.
    ensure!(
        r.tracking.map(|t| t.2) == Some("true displacement, reported by the plant"),
        "the Python plant's tracking was scored on {:?}, not on its reported true displacement",
        r.tracking.map(|t| t.2)
    );
    ensure!(
        r.commands > py.ticks as usize,
        "{} commands for {} tracking ticks and the conditioning",
        r.commands,
        py.ticks
    );

    // A plant program that takes seconds to start (an interpreter, a simulation package) gets
    // the first frame's longer allowance.
    let mut slow = HilRun::new(base.join("python_slow_start"));
    slow.plant_cmd = Some(
        "sleep 5; python3 host-tests/hil/first_order_plant.py --params params/actuator.json".into(),
    );
    slow.ticks = 200;
    let r = run_once(ctx, elf, None, &slow)?;
    summary.push_str(&r.summary);
    Ok(summary)
}

/// Start-up conditioning against unknown prior histories (20 random current levels within
/// ±I_max before power-up), with and without it: tracking ≤ 1 % with it on every seed.
fn conditioning(ctx: &Ctx, elf: &Path, exe: &Path, base: &Path) -> Result<String> {
    let mut table = String::from(
        "start-up conditioning vs a random prior history (20 levels), 0.3 s of feedforward tracking:\n  seed  with: RMS %  max %   without: RMS %  max %\n",
    );
    for seed in 1..=3u64 {
        let mut rms = [0.0f64; 2];
        let mut max = [0.0f64; 2];
        for (k, conditioning) in [true, false].into_iter().enumerate() {
            let mut c = HilRun::new(base.join(format!(
                "prior_{seed}_{}",
                if conditioning {
                    "conditioned"
                } else {
                    "unconditioned"
                }
            )));
            c.ticks = 3_000;
            c.prior_history = 20;
            c.seed = seed;
            c.conditioning = conditioning;
            // Feedforward only: what conditioning is for is the memory the inverse assumes.
            c.feedback = false;
            let r = run_once(ctx, elf, Some(exe), &c)?;
            let (a, b, _) = r.tracking.context("no tracking error")?;
            rms[k] = a;
            max[k] = b;
        }
        writeln!(
            table,
            "  {seed:>4}  {:>10.3} {:>6.2}   {:>13.3} {:>6.2}",
            rms[0], max[0], rms[1], max[1]
        )?;
        ensure!(
            rms[0] <= 1.0,
            "seed {seed}: tracking RMS {:.3} % > 1 % after conditioning",
            rms[0]
        );
    }
    print!("{table}");
    Ok(table)
}

/// A NaN sample (exit 7), a silent link and a desynchronized frame (exit 8), injected in
/// tracking: each must be the run's first fault and end as [`check_fault_end`] asks.
fn faults(ctx: &Ctx, elf: &Path, exe: &Path, base: &Path) -> Result<String> {
    let mut summary = String::new();
    // (name, fault, exit status, feedback on, the run must end at 0 A); injected in tracking,
    // after the start-up conditioning (1,055 ticks with the feedback on, 552 without).
    for (name, inject, exit, feedback, zero) in [
        ("nan", Inject::Nan(FAULT_TICK), 7, true, false),
        ("nan_feedback_off", Inject::Nan(FAULT_TICK), 7, false, true),
        ("silent", Inject::Silent(FAULT_TICK), 8, true, true),
        ("garbage", Inject::Garbage(FAULT_TICK), 8, true, true),
    ] {
        let mut f = HilRun::new(base.join(format!("fault_{name}")));
        f.ticks = 2_000;
        f.inject = Some(inject);
        f.expect_exit = exit;
        f.feedback = feedback;
        let r = run_once(ctx, elf, Some(exe), &f)?;
        summary.push_str(&r.summary);
        // The expected exit status alone would also pass a fault of the run's own before the
        // injected one (a frame lost at tick 0 once ended the silent run with exit 8 too).
        let at = match inject {
            Inject::Nan(t) | Inject::Range(t) | Inject::Silent(t) | Inject::Garbage(t) => t,
        };
        ensure!(
            r.commands >= at as usize,
            "{name}: the run ended after {} command frames, before the fault injected at tick \
             {at}: a fault of its own (a lost or late frame)",
            r.commands
        );
        check_fault_end(name, &f.out, zero)?;
    }
    Ok(summary)
}

/// The tick the fault runs inject at: in tracking, after the start-up conditioning.
pub(super) const FAULT_TICK: u32 = 1_500;

/// The last command of a fault run (`link.csv` in `out`): 0 A when `zero`, else the feedforward
/// fallback, still driving the coil and flagged `SENSOR_FAULT | FEEDFORWARD`.
pub(super) fn check_fault_end(name: &str, out: &std::path::Path, zero: bool) -> Result<()> {
    let rows = std::fs::read_to_string(out.join("link.csv"))?;
    // The last tick the firmware commanded (a row may hold only a plant sample).
    let last = rows
        .lines()
        .rev()
        .find(|l| l.split(',').nth(4).is_some_and(|c| !c.is_empty()))
        .unwrap_or_default()
        .to_string();
    let current: f64 = last
        .split(',')
        .nth(4)
        .and_then(|c| c.parse().ok())
        .with_context(|| format!("{name}: no current in the last link row `{last}`"))?;
    if zero {
        ensure!(
            current == 0.0,
            "{name}: the last command is {current} A, not 0 A"
        );
    } else {
        // Feedback on: the loop fell back to the feedforward, which keeps driving the coil;
        // every command from the fault on carries SENSOR_FAULT | FEEDFORWARD (the firmware
        // checks that itself, exit 3 otherwise).
        let flags: u8 = last
            .split(',')
            .nth(6)
            .and_then(|c| c.parse().ok())
            .unwrap_or(0);
        ensure!(
            current != 0.0
                && flags & (CommandFlags::SENSOR_FAULT | CommandFlags::FEEDFORWARD)
                    == CommandFlags::SENSOR_FAULT | CommandFlags::FEEDFORWARD,
            "{name}: the feedforward fallback should keep tracking, flagged: got {current} A, flags {flags}"
        );
    }
    Ok(())
}
