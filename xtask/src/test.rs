//! `cargo xtask test`: every check the project promises, in order, failing fast.
//!
//! Runs `setup` first, then the [`steps`]; each step's command line is echoed, and the first
//! failure stops the run with the step's name and the failing command (`--keep-going` runs the
//! remaining steps anyway, to see every failure at once). The summary lists each
//! step with `ok` / `FAILED` / `skipped` and its duration, and ends with the line
//! `N passed, M failed` (plus `, K skipped` after a failure), which CI reads.

use crate::setup::{self, FIRMWARE_TARGET};
use crate::util::{run_checked, secs, Ctx};
use anyhow::{bail, Result};
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
        Step::cargo(
            "clippy_fw",
            "no clippy warnings in the firmware and board code (QEMU board, Cortex-M4F target)",
            &[
                "clippy",
                "-p",
                "magctl",
                "--target",
                FIRMWARE_TARGET,
                "--features",
                "board-mps2-an386",
                "--bins",
                "--",
                "-D",
                "warnings",
            ],
        ),
        Step::cargo(
            "clippy_nucleo",
            "no clippy warnings in the firmware and board code (NUCLEO-F446RE)",
            &[
                "clippy",
                "-p",
                "magctl",
                "--target",
                FIRMWARE_TARGET,
                "--features",
                "board-nucleo-f446re",
                "--bins",
                "--",
                "-D",
                "warnings",
            ],
        ),
        Step::cargo(
            "clippy_nucleo_measure",
            "no clippy warnings in the NUCLEO measurement image (measurement-mode)",
            &[
                "clippy",
                "-p",
                "magctl",
                "--target",
                FIRMWARE_TARGET,
                "--features",
                "board-nucleo-f446re,measurement-mode",
                "--bins",
                "--",
                "-D",
                "warnings",
            ],
        ),
        Step::cargo(
            "test",
            "unit, integration and property tests of every crate",
            &["test", "--workspace"],
        ),
        Step::cargo(
            "no_std",
            "the core builds for the Cortex-M4F target without std",
            &[
                "build",
                "-p",
                "magctl",
                "--lib",
                "--target",
                FIRMWARE_TARGET,
            ],
        ),
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
            purpose: "virtual bench: firmware-hil under QEMU in lock-step with the default plant (1 s, tracking <= 1 %, <= 30 s wall) and a Python plant (also started late); conditioning vs random histories; measure -> identify -> re-bake -> track on a plant with other parameters (<= 1 %, >= 5x better than the defaults); NaN sample (feedback on: feedforward fallback; off: 0 A), silent link, corrupted frame (0 A) (exits 7/8)",
            action: Action::Func(|ctx| crate::hil::check(ctx).map(|_| ())),
        },
        Step {
            name: "robustness",
            purpose: "closed loop vs open loop on every robustness case (host) and three as firmware under QEMU: RMS <= 1 % of p-p in every row but backlash, >= 5x below the open loop in every rod-side row",
            action: Action::Func(|ctx| crate::robustness::check(ctx).map(|_| ())),
        },
        Step {
            name: "nucleo",
            purpose: "NUCLEO-F446RE firmware builds; its no-panic proof holds",
            action: Action::Func(|ctx| crate::nucleo::check(ctx).map(|_| ())),
        },
    ]
}

/// Runs `cargo xtask test`.
pub fn run(ctx: &Ctx, args: &[String]) -> Result<()> {
    let mut keep_going = false;
    for arg in args {
        match arg.as_str() {
            "--keep-going" => keep_going = true,
            other => bail!("`test` takes only --keep-going, got `{other}`"),
        }
    }
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
        let t = Instant::now();
        match step.run(ctx) {
            Ok(()) => results.push((step.name, Outcome::Passed(t.elapsed()))),
            Err(e) => {
                eprintln!("\nstep `{}` FAILED: {e:#}", step.name);
                results.push((step.name, Outcome::Failed(t.elapsed())));
                failure.get_or_insert((step.name, e));
            }
        }
    }

    println!("\nsummary (setup {}):", secs(setup_time));
    for (name, outcome) in &results {
        match outcome {
            Outcome::Passed(d) => println!("  ok       {name:<10} {:>9}", secs(*d)),
            Outcome::Failed(d) => println!("  FAILED   {name:<10} {:>9}", secs(*d)),
            Outcome::Skipped => println!("  skipped  {name}"),
        }
    }
    println!("  total               {:>9}", secs(started.elapsed()));
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

enum Outcome {
    Passed(Duration),
    Failed(Duration),
    Skipped,
}
