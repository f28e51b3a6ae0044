//! `cargo xtask`: project automation in plain Rust (the cargo-xtask pattern; `.cargo/config.toml`
//! aliases `cargo xtask` to `cargo run --package xtask --`).
//!
//! Commands live one per module and are listed in [`COMMANDS`]:
//! * `setup` ([`setup`]): installs what is missing (the `thumbv7em-none-eabihf` target, rustfmt
//!   and clippy, `qemu-system-arm`);
//! * `test` ([`test`]): setup, then fmt, clippy, the workspace tests and the no_std build of the
//!   core, the Markdown link check ([`doclinks`]), with a summary whose last line is `N passed, M failed`;
//! * `demo` ([`demo`]): setup, then the host demo (`maglab loops`), the QEMU firmware run and the
//!   tracking figures (`maglab track`) into `out/`;
//! * `qemu` ([`qemu`]) and `nucleo` ([`nucleo`]): the firmware checks (also steps of `test`);
//! * `record` ([`record`]): the firmware's own measurement record → the dataset folder;
//! * `fuzz` ([`fuzz`]): the long cargo-fuzz runs (nightly); `test` replays their corpus.
//!
//! # Adding a command
//! 1. Write `src/<name>.rs` with `pub fn run(ctx: &Ctx, args: &[String]) -> anyhow::Result<()>`
//!    (use [`util::Ctx::cargo`] / [`util::run_checked`] to run processes in the repository root).
//! 2. Declare the module below (`mod <name>;`) and add a [`Command`] entry to [`COMMANDS`].
//! 3. To make `cargo xtask test` run it as a step, add a [`test::Step`] to `test::steps` (the
//!    marked hook there); to run it from `cargo xtask demo`, call it at the hook in `demo::run`.

mod demo;
mod doclinks;
mod frame_socket;
mod fuzz;
mod hil;
mod nucleo;
mod qemu;
mod record;
mod robustness;
mod setup;
mod test;
mod util;

use std::process::ExitCode;
use util::Ctx;

/// A subcommand: its name, a one-line description and its entry point (`args` are the words
/// after the command name).
pub struct Command {
    /// What the user types after `cargo xtask`.
    pub name: &'static str,
    /// One line for `cargo xtask help`.
    pub about: &'static str,
    /// Runs the command.
    pub run: fn(&Ctx, &[String]) -> anyhow::Result<()>,
}

/// Every subcommand, in the order `help` lists them.
const COMMANDS: &[Command] = &[
    Command {
        name: "setup",
        about: "install what is missing: thumbv7em-none-eabihf target, rustfmt, clippy, qemu-system-arm",
        run: setup::run,
    },
    Command {
        name: "test",
        about: "setup, then fmt, clippy -D warnings, workspace tests, no_std build, doc links, QEMU run, NUCLEO build [--keep-going]",
        run: test::run,
    },
    Command {
        name: "hil",
        about: "virtual bench: the firmware under QEMU in lock-step with a plant program over UART0 (docs/hil.md) [--plant-cmd CMD] [--effect E] [--ticks N] [--inject KIND@TICK] [--check]",
        run: hil::run,
    },
    Command {
        name: "robustness",
        about: "closed-loop robustness matrix: every case on the host, three as firmware under QEMU, open vs closed loop -> out/robustness/robustness.csv, table, plot [maglab robustness options: --gain-scale G, --static-inverse, --structure S ...]",
        run: robustness::run,
    },
    Command {
        name: "qemu",
        about: "build the mps2-an386 firmware, run it in QEMU, check commands, tracking, instruction counts, no-panic proof",
        run: qemu::run,
    },
    Command {
        name: "nucleo",
        about: "build the NUCLEO-F446RE firmware, report its sizes, prove it panic-free at link time",
        run: nucleo::run,
    },
    Command {
        name: "record",
        about: "the firmware's own measurement record (MEAS lines of its defmt log) -> dataset folder: -o DIR (--log FILE | -- probe-rs run --chip STM32F446RETx out/nucleo/firmware-nucleo-measure.elf)",
        run: record::run,
    },
    Command {
        name: "fuzz",
        about: "cargo-fuzz (nightly) on every fuzz target for 600 s each [--seconds N] [TARGET...]",
        run: fuzz::run,
    },
    Command {
        name: "demo",
        about: "setup, then `maglab loops` (out/loops.png, out/displacement.png), the QEMU run (out/qemu/) and Figures 7/8 (out/track/)",
        run: demo::run,
    },
];

fn usage() {
    eprintln!("usage: cargo xtask <command> [args]\n\ncommands:");
    for c in COMMANDS {
        eprintln!("  {:<8} {}", c.name, c.about);
    }
    eprintln!("  {:<8} show this list", "help");
}

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some(name) = args.first() else {
        usage();
        return ExitCode::from(2);
    };
    if matches!(name.as_str(), "help" | "-h" | "--help") {
        usage();
        return ExitCode::SUCCESS;
    }
    let Some(command) = COMMANDS.iter().find(|c| c.name == name) else {
        eprintln!("error: unknown xtask command `{name}`\n");
        usage();
        return ExitCode::from(2);
    };
    let ctx = match Ctx::new() {
        Ok(ctx) => ctx,
        Err(e) => {
            eprintln!("error: {e:#}");
            return ExitCode::FAILURE;
        }
    };
    match (command.run)(&ctx, &args[1..]) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("\nerror: cargo xtask {name}: {e:#}");
            ExitCode::FAILURE
        }
    }
}
