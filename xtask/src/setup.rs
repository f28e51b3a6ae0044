//! `cargo xtask setup`: installs what the test and demo commands need, only where it is missing,
//! printing every install command before running it.
//!
//! * the `thumbv7em-none-eabihf` standard library (`rustup target add`), for the no_std build of
//!   the core and the firmware;
//! * the `rustfmt` and `clippy` components (`rustup component add`);
//! * `qemu-system-arm` (Debian/Ubuntu: `apt-get update && apt-get install -y qemu-system-arm`,
//!   through `sudo` when not root), for the firmware run under QEMU.

use crate::util::{find_on_path, output_of, run_checked, Ctx};
use anyhow::{bail, Result};
use std::path::Path;

/// The firmware target.
pub const FIRMWARE_TARGET: &str = "thumbv7em-none-eabihf";

/// Runs `cargo xtask setup`.
pub fn run(ctx: &Ctx) -> Result<()> {
    ensure(ctx)
}

/// Installs whatever is missing; prints one line per item either way.
pub fn ensure(ctx: &Ctx) -> Result<()> {
    println!("==> setup");
    ensure_target(ctx, FIRMWARE_TARGET)?;
    ensure_components(ctx, &["rustfmt", "clippy"])?;
    ensure_qemu(ctx)?;
    Ok(())
}

fn rustup_available() -> bool {
    find_on_path("rustup").is_some()
}

fn ensure_target(ctx: &Ctx, target: &str) -> Result<()> {
    if rustup_available() {
        let installed = output_of(ctx.command("rustup", &["target", "list", "--installed"]))
            .unwrap_or_default();
        if installed.lines().any(|l| l.trim() == target) {
            println!("    target {target}: installed");
            return Ok(());
        }
        println!("    target {target}: missing, installing");
        return run_checked(ctx.command("rustup", &["target", "add", target]));
    }
    // No rustup (e.g. a distribution toolchain): look for the target's standard library.
    let sysroot = output_of(ctx.command("rustc", &["--print", "sysroot"])).unwrap_or_default();
    let lib = Path::new(sysroot.trim())
        .join("lib")
        .join("rustlib")
        .join(target);
    if lib.is_dir() {
        println!("    target {target}: installed ({})", lib.display());
        Ok(())
    } else {
        bail!(
            "the Rust standard library for {target} is missing and rustup is not available: \
             install rustup (https://rustup.rs) or your distribution's rust-std package for {target}"
        )
    }
}

fn ensure_components(ctx: &Ctx, components: &[&str]) -> Result<()> {
    let probe = |c: &str| -> bool {
        let sub = if c == "rustfmt" { "fmt" } else { c };
        output_of(ctx.cargo(&[sub, "--version"])).is_some()
    };
    let missing: Vec<&str> = components.iter().copied().filter(|c| !probe(c)).collect();
    for c in components.iter().filter(|c| !missing.contains(c)) {
        println!("    component {c}: installed");
    }
    if missing.is_empty() {
        return Ok(());
    }
    if !rustup_available() {
        bail!("missing toolchain components {missing:?} and rustup is not available to add them");
    }
    println!("    components {missing:?}: missing, installing");
    let mut args = vec!["component", "add"];
    args.extend(&missing);
    run_checked(ctx.command("rustup", &args))
}

fn ensure_qemu(ctx: &Ctx) -> Result<()> {
    if let Some(path) = find_on_path("qemu-system-arm") {
        println!("    qemu-system-arm: installed ({})", path.display());
        return Ok(());
    }
    println!("    qemu-system-arm: missing, installing with apt-get");
    if find_on_path("apt-get").is_none() {
        bail!(
            "qemu-system-arm is not on PATH and apt-get is not available: install QEMU's ARM \
             system emulator with your package manager"
        );
    }
    let root = output_of(ctx.command("id", &["-u"])).is_some_and(|uid| uid.trim() == "0");
    let sudo = if root {
        None
    } else if find_on_path("sudo").is_some() {
        Some("sudo")
    } else {
        bail!("qemu-system-arm is missing; installing it needs root, and sudo is not available")
    };
    let apt = |apt_args: &[&str]| {
        let mut cmd = match sudo {
            Some(sudo) => {
                let mut args = vec!["apt-get"];
                args.extend(apt_args);
                ctx.command(sudo, &args)
            }
            None => ctx.command("apt-get", apt_args),
        };
        cmd.env("DEBIAN_FRONTEND", "noninteractive");
        run_checked(cmd)
    };
    apt(&["update"])?;
    apt(&[
        "install",
        "-y",
        "--no-install-recommends",
        "qemu-system-arm",
    ])?;
    match find_on_path("qemu-system-arm") {
        Some(path) => {
            println!("    qemu-system-arm: installed ({})", path.display());
            Ok(())
        }
        None => bail!("apt-get installed qemu-system-arm but it is still not on PATH"),
    }
}
