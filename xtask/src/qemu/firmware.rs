//! The firmware images: where they build and with which environment, what their ELF holds (the
//! defmt log table, section sizes) and a build's linker output (the no-panic proof reads it).

use crate::util::{display, Ctx};
use anyhow::{bail, ensure, Context, Result};
use object::{Object, ObjectSection};
use std::path::PathBuf;
use std::process::Command;

/// The firmware's target triple (one definition: `setup` installs it, every build here uses it).
pub use crate::setup::FIRMWARE_TARGET as TARGET;
/// The symbol a `panic-never` build leaves undefined when a panic path is reachable.
const PANIC_SYMBOL: &str = "__firmware_contains_a_reachable_panic_path";

/// Where the firmware builds go.
pub fn firmware_dir(ctx: &Ctx) -> PathBuf {
    ctx.root.join("target").join("firmware")
}

/// `cargo <args>` as every firmware build runs: in `target/firmware/` (its own directory, so
/// host builds never rebuild it) with `DEFMT_LOG=info`. The firmware lints and the `no_std`
/// check of `cargo xtask test` run through it too, so the host units they compile (build
/// scripts, syn, serde, defmt's and cortex-m-rt's macros) are the ones the image builds reuse;
/// a second copy of this environment that drifted would silently compile them twice.
pub fn firmware_cargo(ctx: &Ctx, args: &[&str]) -> Command {
    let mut cmd = ctx.cargo(args);
    cmd.env("CARGO_TARGET_DIR", firmware_dir(ctx))
        .env("DEFMT_LOG", "info");
    cmd
}

/// `cargo build --release` of firmware binary `bin` for the Cortex-M4F target with `features`
/// ([`firmware_cargo`]).
pub fn build_bin(ctx: &Ctx, bin: &str, features: &str) -> Command {
    firmware_cargo(
        ctx,
        &[
            "build",
            "-p",
            "magctl",
            "--release",
            "--target",
            TARGET,
            "--features",
            features,
            "--bin",
            bin,
        ],
    )
}

/// The ELF [`build_bin`] writes for firmware binary `bin`.
pub fn elf_path(ctx: &Ctx, bin: &str) -> PathBuf {
    firmware_dir(ctx).join(TARGET).join("release").join(bin)
}

/// The defmt frames of `stream` decoded with the table in `elf`, one line each.
pub fn decode_defmt(elf: &[u8], stream: &[u8]) -> Result<Vec<String>> {
    let table = defmt_decoder::Table::parse(elf)?.context("the firmware ELF has no defmt table")?;
    let mut decoder = table.new_stream_decoder();
    decoder.received(stream);
    let mut lines = Vec::new();
    loop {
        match decoder.decode() {
            Ok(frame) => lines.push(frame.display(false).to_string()),
            Err(defmt_decoder::DecodeError::UnexpectedEof) => break,
            Err(defmt_decoder::DecodeError::Malformed) => bail!("malformed defmt frame in the log"),
        }
    }
    Ok(lines)
}

/// (flash, static RAM) in bytes from the ELF's section headers (module docs, step 6).
pub fn section_sizes(elf: &[u8]) -> Result<(u64, u64)> {
    let file = object::File::parse(elf)?;
    let size = |name: &str| file.section_by_name(name).map(|s| s.size()).unwrap_or(0);
    let flash = size(".vector_table") + size(".text") + size(".rodata") + size(".data");
    let ram = size(".data") + size(".bss") + size(".uninit");
    Ok((flash, ram))
}

/// Runs a command, returning (success, stderr).
fn run_capture(mut cmd: Command) -> Result<(bool, String)> {
    let out = cmd
        .output()
        .with_context(|| format!("running {}", display(&cmd)))?;
    Ok((
        out.status.success(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    ))
}

/// The no-panic proof of firmware binary `bin` built with `features`: with `panic-never` the
/// image must link (no panic path anywhere in it); with `canary` (where the canary feature puts
/// a bounds check, e.g. "the ISR") the `panic-never-canary` build must fail to link naming
/// [`PANIC_SYMBOL`], so that the proof is seen to catch a panic there.
pub fn prove_panic_free(ctx: &Ctx, bin: &str, features: &str, canary: Option<&str>) -> Result<()> {
    let cmd = build_bin(ctx, bin, &format!("{features},panic-never"));
    println!("$ {}", display(&cmd));
    let (linked, stderr) = run_capture(cmd)?;
    if !linked {
        bail!(
            "no-panic proof FAILED for {bin} ({features}): the image still contains a reachable \
             panic path:\n{}",
            stderr
                .lines()
                .filter(|l| l.contains("undefined symbol")
                    || l.contains(">>> referenced")
                    || l.starts_with("error"))
                .collect::<Vec<_>>()
                .join("\n")
        );
    }
    let Some(place) = canary else {
        return Ok(());
    };
    let cmd = build_bin(ctx, bin, &format!("{features},panic-never-canary"));
    println!("$ {}", display(&cmd));
    let (linked, stderr) = run_capture(cmd)?;
    ensure!(
        !linked && stderr.contains(PANIC_SYMBOL),
        "the {bin} canary build (a panic in {place}) linked: the no-panic proof would not catch a \
         panic"
    );
    Ok(())
}
