//! `cargo xtask`: project automation in plain Rust (the cargo-xtask pattern; `.cargo/config.toml`
//! aliases `cargo xtask` to `cargo run --package xtask --`).
//!
//! Commands live one per module and are listed in [`Task`]:
//! * `setup` ([`setup`]): installs what is missing (the `thumbv7em-none-eabihf` target, rustfmt
//!   and clippy, `qemu-system-arm`);
//! * `test` ([`test`](mod@test)): setup, then fmt, clippy, the workspace tests and the no_std build of the
//!   core, the Markdown link check ([`doclinks`]), with a summary whose last line is `N passed, M failed`;
//! * `demo` ([`demo`]): setup, then the host demo (`maglab loops`), the QEMU firmware run and the
//!   tracking figures (`maglab track`) into `out/`;
//! * `qemu` ([`qemu`]) and `nucleo` ([`nucleo`]): the firmware checks (also steps of `test`);
//! * `record` ([`record`]): the firmware's own measurement record → the dataset folder;
//! * `fuzz` ([`fuzz`]): the long cargo-fuzz runs (nightly); `test` replays their corpus.
//!
//! # Adding a command
//! 1. Write `src/<name>.rs` with its options as a `clap::Args` struct and `pub fn run(ctx: &Ctx,
//!    args: &Args) -> anyhow::Result<()>` (use [`util::Ctx::cargo`] / [`util::run_checked`] to
//!    run processes in the repository root).
//! 2. Declare the module below (`mod <name>;`) and add a variant to [`Task`] (its doc comment
//!    is the line `cargo xtask help` shows) and its arm in [`main`].
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

use clap::{Parser, Subcommand};
use std::process::ExitCode;
use util::Ctx;

/// Project automation: `cargo xtask <command> --help` lists a command's options.
#[derive(Debug, Parser)]
#[command(name = "cargo xtask", bin_name = "cargo xtask")]
struct Cli {
    #[command(subcommand)]
    task: Task,
}

/// Every command, in the order `cargo xtask help` lists them.
#[derive(Debug, Subcommand)]
enum Task {
    /// Install what is missing: thumbv7em-none-eabihf target, rustfmt, clippy, qemu-system-arm.
    Setup,
    /// Setup, then every check: fmt, clippy -D warnings (host and firmware), the workspace's
    /// tests, the no_std build, doc links, the QEMU run, the virtual bench, the robustness
    /// matrix, the NUCLEO build, the blind suite.
    Test(test::Args),
    /// The main job: the Preisach loops, the rate-dependent model, the firmware under QEMU and
    /// the paper's Figures 7/8, into out/.
    Demo(demo::Args),
    /// The virtual bench: the firmware under QEMU in lock-step with a plant program over UART0
    /// (docs/hil.md).
    Hil(hil::Args),
    /// The closed loop's robustness matrix: every case on the host, three as firmware under
    /// QEMU, open vs closed loop (out/robustness/).
    Robustness(robustness::Args),
    /// Build the mps2-an386 firmware, run it in QEMU, check its commands, tracking, instruction
    /// counts and the no-panic proof.
    Qemu,
    /// Build the NUCLEO-F446RE firmware, report its sizes, prove it panic-free at link time.
    Nucleo,
    /// The firmware's own measurement record (MEAS lines of its defmt log) → a dataset folder.
    Record(record::Args),
    /// cargo-fuzz (nightly) on the fuzz targets.
    Fuzz(fuzz::Args),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let ctx = match Ctx::new() {
        Ok(ctx) => ctx,
        Err(e) => {
            eprintln!("error: {e:#}");
            return ExitCode::FAILURE;
        }
    };
    let (name, result) = match &cli.task {
        Task::Setup => ("setup", setup::run(&ctx)),
        Task::Test(a) => ("test", test::run(&ctx, a)),
        Task::Demo(a) => ("demo", demo::run(&ctx, a)),
        Task::Hil(a) => ("hil", hil::run(&ctx, a)),
        Task::Robustness(a) => ("robustness", robustness::run(&ctx, a)),
        Task::Qemu => ("qemu", qemu::run(&ctx)),
        Task::Nucleo => ("nucleo", nucleo::run(&ctx)),
        Task::Record(a) => ("record", record::run(&ctx, a)),
        Task::Fuzz(a) => ("fuzz", fuzz::run(&ctx, a)),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("\nerror: cargo xtask {name}: {e:#}");
            ExitCode::FAILURE
        }
    }
}
