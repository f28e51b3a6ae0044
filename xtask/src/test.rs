//! `cargo xtask test`: every check the project promises, in order, failing fast.
//!
//! Runs `setup` first, then the [`steps`]; each step's command line is echoed, and the first
//! failure stops the run with the step's name and the failing command (`--keep-going` runs the
//! remaining steps anyway, to see every failure at once). The summary lists each
//! step with `ok` / `FAILED` / `skipped` and its duration, and ends with the line
//! `N passed, M failed` (plus `, K skipped` after a failure), which CI reads.
//!
//! One check runs beside the others: the diagnosis's blind suite is started by `test` (in the
//! idle scheduling class; confined to one core during the QEMU lock-step steps) and awaited by
//! the last step, `blind_suite` ([`test_workspace`]); a failure before then stops it.

use crate::qemu::firmware::firmware_cargo;
use crate::setup::{self, FIRMWARE_TARGET};
use crate::util::{display, run_checked, secs, Ctx};
use anyhow::{bail, Context, Result};
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::sync::Mutex;
use std::time::{Duration, Instant};

/// One check of the test command.
pub struct Step {
    /// Short name for the summary.
    pub name: &'static str,
    /// What the step proves, printed in its banner.
    pub purpose: &'static str,
    /// What it runs.
    pub action: Action,
}

/// What a step runs.
pub enum Action {
    /// `cargo <args>` in the repository root; a non-zero exit fails the step.
    Cargo(&'static [&'static str]),
    /// A function; an error fails the step.
    Func(fn(&Ctx) -> Result<()>),
}

impl Step {
    /// A step that runs `cargo <args>` in the repository root.
    pub fn cargo(name: &'static str, purpose: &'static str, args: &'static [&'static str]) -> Self {
        Step {
            name,
            purpose,
            action: Action::Cargo(args),
        }
    }

    fn run(&self, ctx: &Ctx) -> Result<()> {
        match &self.action {
            Action::Cargo(args) => run_checked(ctx.cargo(args)),
            Action::Func(f) => f(ctx),
        }
    }
}

/// The steps, in order.
pub fn steps() -> Vec<Step> {
    vec![
        Step::cargo(
            "fmt",
            "the code is rustfmt-formatted",
            &["fmt", "--all", "--", "--check"],
        ),
        Step::cargo(
            "clippy",
            "no clippy warnings in any crate or target",
            &[
                "clippy",
                "--workspace",
                "--all-targets",
                "--",
                "-D",
                "warnings",
            ],
        ),
        Step {
            name: "clippy_fw",
            purpose: "no clippy warnings in the firmware and board code (QEMU board, Cortex-M4F target, release as flashed)",
            action: Action::Func(|ctx| run_checked(firmware_cargo(ctx, &clippy_bins("board-mps2-an386")))),
        },
        Step {
            name: "clippy_nucleo",
            purpose: "no clippy warnings in the firmware and board code (NUCLEO-F446RE, release as flashed)",
            action: Action::Func(|ctx| run_checked(firmware_cargo(ctx, &clippy_bins("board-nucleo-f446re")))),
        },
        Step {
            name: "clippy_nucleo_measure",
            purpose: "no clippy warnings in the NUCLEO measurement image (measurement-mode, release as flashed)",
            action: Action::Func(|ctx| {
                run_checked(firmware_cargo(ctx, &clippy_bins("board-nucleo-f446re,measurement-mode")))
            }),
        },
        Step {
            name: "test",
            purpose: "unit, integration and property tests of every crate (the blind suite is started here, beside them and the steps after, and awaited by `blind_suite`)",
            action: Action::Func(test_workspace),
        },
        Step {
            name: "no_std",
            purpose: "the core type-checks for the Cortex-M4F target without std, with its default features (every firmware image below compiles it too)",
            action: Action::Func(|ctx| {
                run_checked(firmware_cargo(
                    ctx,
                    &["check", "-p", "magctl", "--lib", "--release", "--target", FIRMWARE_TARGET],
                ))
            }),
        },
        Step {
            name: "docs",
            purpose: "relative links and figures in the Markdown files exist",
            action: Action::Func(crate::doclinks::check),
        },
        Step {
            name: "qemu",
            purpose: "firmware under qemu-system-arm: host replay, tracking error vs the reference plant, instruction counts, no-panic proof",
            action: Action::Func(|ctx| crate::qemu::check(ctx).map(|_| ())),
        },
        Step {
            name: "hil",
            purpose: "virtual bench: firmware-hil under QEMU in lock-step with the default plant (1 s, tracking <= 1 %, <= 30 s wall) and a Python plant (also started late); conditioning vs random histories; measure (with the coil-current channel, through the firmware's record) -> identify -> diagnose (none) -> re-bake -> track on a plant with other parameters and a rod the coil cannot saturate (constants within 3 %, closed loop <= 1 %, feedforward >= 5x better than the defaults); the interrupt on rods the baked file does not describe (<= 1,500 instructions); NaN sample (feedback on: feedforward fallback; off: 0 A), silent link, corrupted frame (0 A) (exits 7/8)",
            action: Action::Func(|ctx| {
                with_background_confined(|| crate::hil::check(ctx).map(|_| ()))
            }),
        },
        Step {
            name: "robustness",
            purpose: "closed loop vs open loop on every robustness case (host) and three as firmware under QEMU: RMS <= 1 % of p-p in every row but backlash, >= 5x below the open loop in every rod-side row, the stroke-constant rows <= 1 % over the whole run and settled within 3 cycles",
            action: Action::Func(|ctx| {
                with_background_confined(|| crate::robustness::check(ctx).map(|_| ()))
            }),
        },
        Step {
            name: "nucleo",
            purpose: "NUCLEO-F446RE firmware builds; its no-panic proof holds",
            action: Action::Func(|ctx| crate::nucleo::check(ctx).map(|_| ())),
        },
        Step {
            name: "blind_suite",
            purpose: "the diagnosis's blind suite (diagnose/tests/blind_suite.rs, started by `test`): its confusion matrix and >= 85 % correct on seed 1",
            action: Action::Func(await_blind_suite),
        },
    ]
}

/// `cargo clippy` of the firmware binaries with `features` (`--release`: the lints see the
/// configuration that is flashed), run with [`firmware_cargo`] (the firmware builds'
/// environment: the host units the lints compile are the ones the image builds reuse).
fn clippy_bins(features: &str) -> Vec<&str> {
    vec![
        "clippy",
        "-p",
        "magctl",
        "--release",
        "--target",
        FIRMWARE_TARGET,
        "--features",
        features,
        "--bins",
        "--",
        "-D",
        "warnings",
    ]
}

/// The blind suite's test (`diagnose/tests/blind_suite.rs`): the one test `test` leaves out of
/// `cargo test --workspace` to run it in the background.
const BLIND_SUITE_TEST: &str = "blind_suite_names_the_right_effect";

/// The blind suite running in the background: its process, when it started, its log.
struct Background {
    child: Child,
    started: Instant,
    log: PathBuf,
}

/// The background blind suite between `test` (which starts it) and `blind_suite` (which waits
/// for it); `run` kills it when a step fails before then.
static BLIND_SUITE: Mutex<Option<Background>> = Mutex::new(None);

/// The `test` step. The blind suite (~500 s of two cores) would otherwise run alone while the
/// rest of the run, single-threaded for the most part (the other tests, QEMU, the lock-step
/// bench), waits for it: its test binary is built with the others, started directly (not
/// through cargo, which would hold the build directory's lock for the later steps' builds) with
/// its output in `out/blind_suite.log` and in the idle scheduling class, and `cargo test
/// --workspace` then runs every other test.
fn test_workspace(ctx: &Ctx) -> Result<()> {
    // Build every test binary once; the JSON on stdout names the blind suite's executable
    // (the compiler's messages go to stderr as usual).
    let mut build = ctx.cargo(&[
        "test",
        "--workspace",
        "--no-run",
        "--message-format=json-render-diagnostics",
    ]);
    println!("$ {}", display(&build));
    let built = build
        .stderr(Stdio::inherit())
        .output()
        .context("cannot start cargo")?;
    if !built.status.success() {
        bail!("building the tests failed ({})", built.status);
    }
    let exe = String::from_utf8_lossy(&built.stdout)
        .lines()
        .filter_map(|l| serde_json::from_str::<serde_json::Value>(l).ok())
        .find(|v| {
            // The integration test, not the example of the same name.
            v["reason"] == "compiler-artifact"
                && v["target"]["name"] == "blind_suite"
                && v["target"]["kind"] == serde_json::json!(["test"])
        })
        .and_then(|v| v["executable"].as_str().map(PathBuf::from))
        .context("cargo named no test executable `blind_suite`")?;
    let log = ctx.root.join("out").join("blind_suite.log");
    std::fs::create_dir_all(log.parent().expect("out/"))?;
    let file =
        std::fs::File::create(&log).with_context(|| format!("cannot create {}", log.display()))?;
    // In the idle scheduling class (`chrt --idle 0`, util-linux): the other steps take the cores
    // first and the suite the cycles they leave. The lock-step steps confine it to one core
    // besides ([`with_background_confined`]).
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let spawn = |launcher: &[&str]| -> Result<(Child, String)> {
        let mut cmd = Command::new(launcher[0]);
        cmd.args(&launcher[1..])
            .arg(&exe)
            .args(["--exact", BLIND_SUITE_TEST, "--nocapture"])
            .env("BLIND_THREADS", cores.to_string())
            .env("RAYON_NUM_THREADS", cores.to_string())
            .current_dir(ctx.root.join("diagnose"))
            .stdout(file.try_clone()?)
            .stderr(file.try_clone()?);
        let line = display(&cmd);
        Ok((cmd.spawn()?, line))
    };
    let (child, line) = spawn(&["chrt", "--idle", "0"])
        .or_else(|_| spawn(&["nice", "-n19"]))
        .with_context(|| format!("cannot start {}", exe.display()))?;
    println!("$ {line} > {} (in the background)", log.display());
    *BLIND_SUITE.lock().unwrap_or_else(|p| p.into_inner()) = Some(Background {
        child,
        started: Instant::now(),
        log,
    });
    run_checked(ctx.cargo(&["test", "--workspace", "--", "--skip", BLIND_SUITE_TEST]))
}

/// The `blind_suite` step: waits for the suite `test` started and shows its log.
fn await_blind_suite(_ctx: &Ctx) -> Result<()> {
    let Some(mut bg) = BLIND_SUITE.lock().unwrap_or_else(|p| p.into_inner()).take() else {
        bail!("the blind suite was not started (the `test` step starts it)");
    };
    let status = bg.child.wait().context("cannot wait for the blind suite")?;
    let log = std::fs::read_to_string(&bg.log)
        .with_context(|| format!("cannot read {}", bg.log.display()))?;
    print!("{log}");
    println!(
        "blind suite: {} in the background since the `test` step ({status})",
        secs(bg.started.elapsed())
    );
    if !status.success() {
        bail!(
            "the blind suite failed ({status}); its log: {}",
            bg.log.display()
        );
    }
    Ok(())
}

/// Runs `step` (a step with QEMU in lock-step with a plant over TCP: 121 723 round trips in
/// `hil`'s measurement) with the background blind suite confined to the last core and this
/// process (so the step's QEMU, plant program and the bridge threads between them) to the
/// others (`taskset`, util-linux); every core again for both after it. The lock-step is
/// latency-bound: its three parties on one core hand each frame over without waking another
/// core. Measured alone, `cargo xtask hil --check`: 147 s wall, 105 s user + 67 s system on both
/// cores; 176 s wall, 164 s user + 10 s system under `taskset -c 0` (the 121 723-tick measurement
/// 76.7 s -> 63.2 s; what it loses is `maglab identify`'s second thread and the builds). Beside
/// the suite in CI, with only the suite confined, `hil` took 238 s on a clean clone.
/// Measured beside the suite on both cores: `hil`'s default run 12.5 s under `nice -n19`, 7.5 s
/// in the idle class (5 s alone). (Once, in the idle class, the link lost the firmware's last two
/// frames of the `garbage` fault run: QEMU's socket was reset on exit with bytes unread; the
/// firmware now exits only after the bridge acknowledges its `E` frame,
/// `magctl::link::EndAck`.) The suite's threads were counted from every core (`BLIND_THREADS`,
/// `RAYON_NUM_THREADS`).
fn with_background_confined(step: impl FnOnce() -> Result<()>) -> Result<()> {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let all = format!("0-{}", cores.saturating_sub(1));
    let set_cores = |pid: u32, list: &str, what: &str| {
        let mut taskset = Command::new("taskset");
        taskset
            .args(["-a", "-p", "-c", list, &pid.to_string()])
            .stdout(Stdio::null());
        if let Err(e) = run_checked(taskset) {
            println!("({what}'s cores unchanged: {e:#})");
        }
    };
    // The suite's process, while it runs (it may end between the check and the call; it then
    // needs no cores).
    let suite = || {
        let mut guard = BLIND_SUITE.lock().unwrap_or_else(|p| p.into_inner());
        let bg = guard.as_mut()?;
        matches!(bg.child.try_wait(), Ok(None)).then(|| bg.child.id())
    };
    let confined = match suite() {
        Some(pid) if cores >= 2 => {
            set_cores(pid, &(cores - 1).to_string(), "the blind suite");
            set_cores(std::process::id(), &format!("0-{}", cores - 2), "this step");
            true
        }
        _ => false,
    };
    let result = step();
    if confined {
        set_cores(std::process::id(), &all, "this step");
        if let Some(pid) = suite() {
            set_cores(pid, &all, "the blind suite");
        }
    }
    result
}

/// Stops a background blind suite that no step will wait for (a step before `blind_suite`
/// failed).
fn stop_background() {
    if let Some(mut bg) = BLIND_SUITE.lock().unwrap_or_else(|p| p.into_inner()).take() {
        let _ = bg.child.kill();
        let _ = bg.child.wait();
        println!(
            "blind suite stopped (not awaited); its log so far: {}",
            bg.log.display()
        );
    }
}

/// CPU time (user + system) of the waited-for child processes of this process so far
/// (`getrusage(RUSAGE_CHILDREN)`): a step's difference is the CPU its commands used. The
/// background blind suite is counted only when it is reaped, by `blind_suite`.
fn children_cpu() -> Duration {
    // SAFETY: `getrusage` writes one `rusage` through the pointer, which points at a zeroed
    // value of that type owned by this frame.
    let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
    if unsafe { libc::getrusage(libc::RUSAGE_CHILDREN, &mut usage) } != 0 {
        return Duration::ZERO;
    }
    let tv = |t: libc::timeval| Duration::new(t.tv_sec as u64, 1000 * t.tv_usec as u32);
    tv(usage.ru_utime) + tv(usage.ru_stime)
}

/// `cargo xtask test`'s options.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Run the remaining steps after a failure (to see every failure at once).
    #[arg(long)]
    keep_going: bool,
}

/// Runs `cargo xtask test`.
pub fn run(ctx: &Ctx, args: &Args) -> Result<()> {
    let keep_going = args.keep_going;
    let started = Instant::now();
    setup::ensure(ctx)?;
    let setup_time = started.elapsed();

    let steps = steps();
    let mut results: Vec<(&str, Outcome)> = Vec::new();
    let mut failure = None;
    for (k, step) in steps.iter().enumerate() {
        if failure.is_some() && !keep_going {
            results.push((step.name, Outcome::Skipped));
            continue;
        }
        println!(
            "\n==> [{}/{}] {}: {}",
            k + 1,
            steps.len(),
            step.name,
            step.purpose
        );
        let (t, cpu) = (Instant::now(), children_cpu());
        let result = step.run(ctx);
        let timing = (t.elapsed(), children_cpu().saturating_sub(cpu));
        match result {
            Ok(()) => results.push((step.name, Outcome::Passed(timing))),
            Err(e) => {
                eprintln!("\nstep `{}` FAILED: {e:#}", step.name);
                results.push((step.name, Outcome::Failed(timing)));
                failure.get_or_insert((step.name, e));
            }
        }
    }

    stop_background();
    // Wall time, and the CPU time (user + system, all cores) of the step's commands: the run is
    // CPU-bound on two cores, so the CPU column is what a step costs the whole run.
    println!(
        "\nsummary (setup {}; wall time, CPU time of the step's commands):",
        secs(setup_time)
    );
    for (name, outcome) in &results {
        match outcome {
            Outcome::Passed((d, c)) => {
                println!("  ok       {name:<10} {:>9} {:>9} cpu", secs(*d), secs(*c))
            }
            Outcome::Failed((d, c)) => {
                println!("  FAILED   {name:<10} {:>9} {:>9} cpu", secs(*d), secs(*c))
            }
            Outcome::Skipped => println!("  skipped  {name}"),
        }
    }
    println!(
        "  total               {:>9} {:>9} cpu",
        secs(started.elapsed()),
        secs(children_cpu())
    );
    let passed = results
        .iter()
        .filter(|r| matches!(r.1, Outcome::Passed(_)))
        .count();
    let failed = results
        .iter()
        .filter(|r| matches!(r.1, Outcome::Failed(_)))
        .count();
    let skipped = results.len() - passed - failed;
    if skipped > 0 {
        println!("{passed} passed, {failed} failed, {skipped} skipped");
    } else {
        println!("{passed} passed, {failed} failed");
    }
    match failure {
        None => Ok(()),
        Some((name, e)) => Err(e.context(format!("step `{name}` failed"))),
    }
}

/// A step's outcome with its wall time and its commands' CPU time.
enum Outcome {
    Passed((Duration, Duration)),
    Failed((Duration, Duration)),
    Skipped,
}
