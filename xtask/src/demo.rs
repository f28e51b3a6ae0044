//! `cargo xtask demo`: the project's main job, end to end on this machine.
//!
//! Runs `setup`, then `maglab loops` ([`maglab`]) with the baked parameters, which prints the
//! loop table and writes `out/loops.png|svg` and `out/displacement.png|svg`. Extra arguments are
//! passed to `maglab loops` (e.g. `cargo xtask demo --params my.json`). Then the QEMU firmware
//! run (`cargo xtask qemu`: `out/qemu/`) and the paper's Figures 7/8 from its captured current
//! commands (`maglab track --capture out/qemu/capture.csv`: `out/track/`). Both use the parameters
//! baked into the build (the firmware cannot read a file); `--params` only affects `maglab loops`.

use crate::setup;
use crate::util::{run_checked, Ctx};
use anyhow::{bail, Result};

/// Output directory of the demo, relative to the repository root.
pub const OUT_DIR: &str = "out";

/// `cargo xtask demo`'s options.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Another parameter file for `maglab loops` (the firmware and the tracking figures always
    /// use the parameters baked into the build).
    #[arg(long, value_name = "FILE")]
    params: Option<std::path::PathBuf>,
    /// Further options of `maglab loops` (`--amplitudes 20,12,6`, `--points N`).
    #[arg(
        trailing_var_arg = true,
        allow_hyphen_values = true,
        value_name = "LOOPS_OPTIONS"
    )]
    loops_options: Vec<String>,
}

/// Runs `cargo xtask demo`.
pub fn run(ctx: &Ctx, args: &Args) -> Result<()> {
    let mut loops_args: Vec<String> = args.loops_options.clone();
    if let Some(p) = &args.params {
        loops_args.extend(["--params".to_string(), p.display().to_string()]);
    }
    let args = &loops_args;
    if args.iter().any(|a| a == "--out" || a.starts_with("--out=")) {
        bail!("`demo` always writes into {OUT_DIR}/; run `maglab loops --out DIR` for another directory");
    }
    setup::ensure(ctx)?;

    println!("\n==> Preisach loops of the baked operator (maglab loops)");
    let exe = crate::hil::maglab(ctx)?;
    let mut cmd = maglab(ctx, &exe, &["loops", "--out", OUT_DIR]);
    cmd.args(args);
    run_checked(cmd)?;

    println!("\n==> The rate-dependent model at 1-400 Hz (maglab simulate)");
    run_checked(maglab(
        ctx,
        &exe,
        &[
            "simulate",
            "--freq",
            "1,50,100,200,400",
            "--out",
            "out/simulate",
        ],
    ))?;

    println!(
        "\n==> Firmware under QEMU: inverse control in the timer interrupt (cargo xtask qemu)"
    );
    crate::qemu::check(ctx)?;
    println!("\n==> Figures 7/8 from the QEMU run's current commands (maglab track --capture)");
    let cmd = maglab(
        ctx,
        &exe,
        &[
            "track",
            "--capture",
            "out/qemu/capture.csv",
            "--out",
            "out/track",
        ],
    );
    run_checked(cmd)?;

    let out = ctx.root.join(OUT_DIR);
    println!("\ndemo outputs:");
    for name in [
        "loops.png",
        "displacement.png",
        "simulate/loops.png",
        "simulate/traces.png",
        "qemu/capture.csv",
        "qemu/tracking.csv",
        "track/fig7_dynamic.png",
        "track/fig8_static.png",
    ] {
        let path = out.join(name);
        if !path.is_file() {
            bail!("{} was not written", path.display());
        }
        println!("  {}", path.display());
    }
    Ok(())
}

/// `maglab <args>` in the repository root, `exe` built as `cargo xtask hil` builds it
/// ([`crate::hil::maglab`]: as `cargo test --workspace` does, its computing crates optimized).
/// After `cargo xtask test` that build is there already; on a fresh clone the demo builds the
/// workspace's tests with it (about 2.5 min against 1.7 min for the tool alone), which
/// `cargo xtask test` then reuses. The demo's three commands take about 2 s.
fn maglab(ctx: &Ctx, exe: &std::path::Path, args: &[&str]) -> std::process::Command {
    let mut cmd = std::process::Command::new(exe);
    cmd.args(args).current_dir(&ctx.root);
    cmd
}
