//! `cargo xtask hil`: the virtual bench — the firmware under QEMU in lock-step with a plant
//! program (protocol: `docs/hil.md`, frames: `magctl::link`).
//!
//! ```text
//! firmware-hil (QEMU, UART0) ──TCP──► xtask bridge ──stdin──► plant program
//!                            ◄──TCP── (log, faults) ◄─stdout──
//! ```
//!
//! QEMU's UART0 connects to a TCP port this command listens on (`-serial tcp:127.0.0.1:PORT`);
//! the bridge copies the byte streams between it and the plant program's stdin/stdout, decodes
//! every frame into `out/hil/link.csv`, and can inject link faults. The plant is `maglab
//! hil-plant` (the bench plant with `--effect`, sensor noise, ADC quantization) unless
//! `--plant-cmd "PROGRAM ARGS"` names another program (run through `sh -c`).
//!
//! Options: `--plant-cmd CMD`, `--effect E` (repeatable, default plant only), `--noise-m X`,
//! `--prior-history N`, `--ticks N` tracking ticks (default 10,000: one second at 10 kHz; the
//! firmware's start-up conditioning adds its own), `--no-conditioning`, `--inverse static`,
//! `--inject KIND@TICK` with KIND `nan` (the sample becomes a NaN in metres), `range` (an ADC count
//! beyond the converter's range), `silent` (the bridge stops forwarding samples), `garbage` (a
//! frame with a wrong sync byte), `--expect-exit N` (default 0), `--out DIR` (default `out/hil`).
//! `--check` runs the set `cargo xtask test` runs (see [`check`]).
//!
//! Prints and writes to `summary.txt`: the firmware's exit status, ticks, the control
//! interrupt's instructions (min / median / max, from the command frames), the tracking error
//! (the plant's true displacement from its log when it writes one — `maglab hil-plant --log` —,
//! and the sensor's reading otherwise), and the wall time.

mod bridge;
mod checks;
mod end_to_end;
mod link_log;
mod matrix;
mod measurement;
mod nucleo;
mod session;
mod settings;

pub use checks::check;
pub use end_to_end::end_to_end;
pub use matrix::interrupt_matrix;
pub use measurement::{identification_programme, Programme};
pub use session::run_once;
pub use settings::{Board, HilResult, HilRun, Inject};

use crate::qemu::firmware::{build_bin, elf_path};
use crate::util::{run_checked, Ctx};
use anyhow::{bail, ensure, Result};
use std::path::PathBuf;
use std::sync::Arc;

/// Builds `maglab` and returns its path: as `cargo test --workspace` builds it (the `test`
/// profile, whose simulating crates are optimized as in `dev`, and the workspace's features), so
/// that within `cargo xtask test`, whose `test` step has built exactly that, this only checks it
/// is current. (A `dev` build, or `cargo build --profile test -p maglab`, resolves other
/// features and compiled `magctl`, `maglab-identify`, `maglab-diagnose` and `maglab` again: on a
/// clean clone after the `test` step, about 110 s on the one core `hil` keeps.) Alone, the first
/// `cargo xtask hil` therefore builds every test of the workspace once.
pub fn maglab(ctx: &Ctx) -> Result<PathBuf> {
    run_checked(ctx.cargo(&["test", "--workspace", "--no-run", "--quiet"]))?;
    let target = std::env::var_os("CARGO_TARGET_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| ctx.root.join("target"));
    let exe = target.join("debug").join("maglab");
    ensure!(exe.exists(), "{} was not built", exe.display());
    Ok(exe)
}

/// Features of the NUCLEO image's emulator build.
const NUCLEO_EMULATOR_FEATURES: &str = "emulator-netduinoplus2,panic-never";

/// Builds the NUCLEO image's emulator build and returns its ELF.
pub fn nucleo_emulator_firmware(ctx: &Ctx) -> Result<PathBuf> {
    run_checked(build_bin(ctx, "firmware-nucleo", NUCLEO_EMULATOR_FEATURES))?;
    Ok(elf_path(ctx, "firmware-nucleo"))
}

/// Builds the HIL firmware and returns its ELF.
pub fn firmware(ctx: &Ctx) -> Result<PathBuf> {
    run_checked(build_bin(
        ctx,
        "firmware-hil",
        "board-mps2-an386,panic-never",
    ))?;
    Ok(elf_path(ctx, "firmware-hil"))
}

/// `cargo xtask hil`'s options (module docs).
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Run the checks `cargo xtask test` runs (every run below) and nothing else.
    #[arg(long)]
    check: bool,
    /// Measure with the firmware, identify, re-bake and track on another plant, and nothing else.
    #[arg(long)]
    end_to_end: bool,
    /// The plant program (run through `sh -c`; protocol in docs/hil.md). Default: `maglab
    /// hil-plant`.
    #[arg(long, value_name = "CMD")]
    plant_cmd: Option<String>,
    /// An unmodelled effect of the default plant (`NAME` or `NAME:k=v,...`; repeatable).
    #[arg(long = "effect", value_name = "E")]
    effects: Vec<String>,
    /// Sensor noise of the default plant, m.
    #[arg(long)]
    noise_m: Option<f64>,
    /// Random current levels the default plant saw before power-up.
    #[arg(long, default_value_t = 0)]
    prior_history: usize,
    /// The default plant's parameter file (default: the baked parameters).
    #[arg(long, value_name = "FILE")]
    plant_params: Option<PathBuf>,
    /// The default plant's own rod, `FAMILY:FACTOR[:C:S]` (`maglab hil-plant --rod`).
    #[arg(long, value_name = "FAMILY:FACTOR")]
    plant_rod: Option<String>,
    /// The default plant's current monitor, with this noise, A (`maglab hil-plant
    /// --coil-current-noise-a`): the sample frames carry the coil current (docs/hil.md, link
    /// version 2) and `--measure` writes it into the dataset.
    #[arg(long, value_name = "A")]
    plant_coil_current_noise_a: Option<f64>,
    /// Measure the whole control interrupt on a matrix of rods the baked model does not
    /// describe (docs/firmware.md), and nothing else.
    #[arg(long)]
    interrupt_matrix: bool,
    /// Tracking ticks (the start-up conditioning adds its own).
    #[arg(long, default_value_t = 10_000, value_parser = clap::value_parser!(u32).range(1..))]
    ticks: u32,
    /// The inverse: dynamic or static.
    #[arg(long, default_value = "dynamic", value_parser = ["dynamic", "static"])]
    inverse: String,
    /// Skip the firmware's start-up conditioning.
    #[arg(long)]
    no_conditioning: bool,
    /// Run without the displacement feedback (`feedback=off`).
    #[arg(long)]
    feedback_off: bool,
    /// A link fault: `KIND@TICK`, KIND one of nan, range, silent, garbage.
    #[arg(long, value_name = "KIND@TICK", value_parser = Inject::parse)]
    inject: Option<Inject>,
    /// The firmware exit status the run must end with.
    #[arg(long, default_value_t = 0)]
    expect_exit: i32,
    /// Measurement mode: stream the identification programme and write the dataset folder DIR.
    #[arg(long, value_name = "DIR", conflicts_with = "measure_local")]
    measure: Option<PathBuf>,
    /// Local measurement: the firmware plays its compiled-in programme and logs the record,
    /// written to the dataset folder DIR.
    #[arg(long, value_name = "DIR")]
    measure_local: Option<PathBuf>,
    /// The image and QEMU machine: mps2 (`firmware-hil` on mps2-an386) or nucleo (the NUCLEO
    /// image's emulator build on netduinoplus2).
    #[arg(long, value_enum, default_value_t = Board::Mps2)]
    board: Board,
    /// With --board nucleo: poll the clock flags the emulator never sets, as on the chip (the
    /// start-up must halt at 0 A: exit 9).
    #[arg(long, requires = "board")]
    board_clock_flags: bool,
    /// Output directory.
    #[arg(long, default_value = "out/hil")]
    out: PathBuf,
}

/// Runs `cargo xtask hil` (module docs).
pub fn run(ctx: &Ctx, args: &Args) -> Result<()> {
    if args.check {
        return check(ctx).map(|_| ());
    }
    if args.end_to_end {
        let elf = firmware(ctx)?;
        let exe = maglab(ctx)?;
        return end_to_end(ctx, &elf, &exe, &ctx.root.join("out/hil/e2e")).map(|_| ());
    }
    if args.interrupt_matrix {
        let elf = firmware(ctx)?;
        let exe = maglab(ctx)?;
        let table = interrupt_matrix(ctx, &elf, &exe, &ctx.root.join("out/hil/matrix"))?;
        print!("{table}");
        return Ok(());
    }
    if args.plant_cmd.is_some() && (!args.effects.is_empty() || args.noise_m.is_some()) {
        bail!("--effect and --noise-m configure the default plant; pass them to --plant-cmd's program instead");
    }
    let mut run = HilRun::new(ctx.root.join(&args.out));
    run.plant_cmd = args.plant_cmd.clone();
    run.effects = args.effects.clone();
    run.noise_m = args.noise_m;
    run.prior_history = args.prior_history;
    run.plant_params = args.plant_params.clone();
    run.plant_rod = args.plant_rod.clone();
    run.plant_coil_current_noise_a = args.plant_coil_current_noise_a;
    run.ticks = args.ticks;
    run.inverse = args.inverse.clone();
    run.conditioning = !args.no_conditioning;
    run.feedback = !args.feedback_off;
    run.inject = args.inject;
    run.expect_exit = args.expect_exit;
    run.measure_local = args.measure_local.clone();
    run.board = args.board;
    run.board_clock_flags = args.board_clock_flags;
    if let Some(dir) = &args.measure {
        run.measure = Some((Arc::new(identification_programme()?), dir.clone()));
    }
    let elf = match run.board {
        Board::Mps2 => firmware(ctx)?,
        Board::Nucleo => nucleo_emulator_firmware(ctx)?,
    };
    let exe = if run.plant_cmd.is_none() {
        Some(maglab(ctx)?)
    } else {
        None
    };
    run_once(ctx, &elf, exe.as_deref(), &run).map(|_| ())
}
