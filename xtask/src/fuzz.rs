//! `cargo xtask fuzz [--seconds N] [TARGET...]`: the long fuzz runs, one command.
//!
//! Runs each target of `maglab_fuzz_targets::TARGETS` (or those named) under libFuzzer with
//! cargo-fuzz for `N` seconds (default 600): `cargo +nightly fuzz run TARGET fuzz/corpus/TARGET
//! -- -max_total_time=N`, from `fuzz/` (its own workspace; cargo-fuzz and libFuzzer need a
//! nightly toolchain and `cargo install cargo-fuzz`). New interesting inputs are added to the
//! kept corpus `fuzz/corpus/TARGET/`; a crash leaves its input in `fuzz/artifacts/TARGET/` and
//! fails the command. The stable smoke of `cargo xtask test` replays the corpus
//! (`fuzz-targets/tests/corpus_smoke.rs`).

use crate::util::{display, run_checked, Ctx};
use anyhow::{Context, Result};
use std::process::Command;

/// The targets (the same list as `maglab_fuzz_targets::TARGETS`, which xtask does not link).
const TARGETS: [&str; 4] = [
    "params_validator",
    "measurement_csv",
    "preisach_fit_input",
    "core_numerics",
];

/// `cargo xtask fuzz`'s options.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Seconds per target.
    #[arg(long, default_value_t = 600)]
    seconds: u64,
    /// The targets to fuzz (default: all).
    #[arg(value_parser = TARGETS)]
    targets: Vec<String>,
}

/// Runs `cargo xtask fuzz`.
pub fn run(ctx: &Ctx, args: &Args) -> Result<()> {
    let seconds = args.seconds;
    let mut chosen: Vec<&str> = args.targets.iter().map(String::as_str).collect();
    if chosen.is_empty() {
        chosen = TARGETS.to_vec();
    }
    let fuzz_dir = ctx.root.join("fuzz");
    for target in chosen {
        let mut cmd = Command::new("cargo");
        cmd.current_dir(&fuzz_dir).args([
            "+nightly",
            "fuzz",
            "run",
            target,
            &format!("corpus/{target}"),
            "--",
            &format!("-max_total_time={seconds}"),
            "-print_final_stats=1",
        ]);
        println!("$ (cd fuzz && {})", display(&cmd));
        run_checked(cmd).with_context(|| {
            format!("fuzz target {target} failed (see fuzz/artifacts/{target}/)")
        })?;
    }
    Ok(())
}
