//! `cargo xtask demo`: the project's main job, end to end on this machine.
//!
//! Runs `setup`, then `maglab loops` (release build) with the baked parameters, which prints the
//! loop table and writes `out/loops.png|svg` and `out/displacement.png|svg`. Extra arguments are
//! passed to `maglab loops` (e.g. `cargo xtask demo --params my.json`).

use crate::setup;
use crate::util::{run_checked, Ctx};
use anyhow::{bail, Result};

/// Output directory of the demo, relative to the repository root.
pub const OUT_DIR: &str = "out";

/// Runs `cargo xtask demo`.
pub fn run(ctx: &Ctx, args: &[String]) -> Result<()> {
    if args.iter().any(|a| a == "--out" || a.starts_with("--out=")) {
        bail!("`demo` always writes into {OUT_DIR}/; run `maglab loops --out DIR` for another directory");
    }
    setup::ensure(ctx)?;

    println!("\n==> Preisach loops of the baked operator (maglab loops)");
    let mut cmd = ctx.cargo(&[
        "run",
        "--release",
        "--quiet",
        "-p",
        "maglab",
        "--",
        "loops",
        "--out",
        OUT_DIR,
    ]);
    cmd.args(args);
    run_checked(cmd)?;

    // HOOK (issue 5): the QEMU firmware run and its tracking plots go here, e.g.
    //     crate::qemu::demo(ctx)?;

    let out = ctx.root.join(OUT_DIR);
    println!("\ndemo outputs:");
    for name in ["loops.png", "displacement.png"] {
        let path = out.join(name);
        if !path.is_file() {
            bail!("{} was not written", path.display());
        }
        println!("  {}", path.display());
    }
    Ok(())
}
