//! `cargo xtask qemu`: builds the mps2-an386 firmware, runs it under QEMU and checks it end to end.
//!
//! Steps (each prints what it does; any failure fails the command):
//! 1. **Build** `firmware-qemu` (release, `--features board-mps2-an386`, `DEFMT_LOG=info`) into
//!    `target/firmware/`.
//! 2. **Run** `timeout 600 qemu-system-arm -machine mps2-an386 -cpu cortex-m4 -nographic
//!    -semihosting-config enable=on,target=native -icount shift=10,sleep=off -kernel <elf>` in
//!    `out/qemu/`; exit status must be 0. The defmt log (semihosting stdout) is decoded with the
//!    ELF's defmt table and printed; the capture file `qemu_capture.bin` is parsed (record layout:
//!    `magctl::board::mps2_an386::capture`).
//! 3. **Instruction counts**: SysTick ticks / 25.6 per interrupt (the 25.6 is checked against the
//!    firmware's calibration record: 1024 extra `nop`s), min/median/max for the dynamic, static,
//!    merge-stress and naive phases, ratio naive/ours; the worst case of the dynamic and static
//!    phases must be <= 1,500 instructions, of the merge-stress phase <= 2,500 (the firmware itself fails the run when
//!    the merge phase merged nothing, or any DAC write timed out).
//! 4. **Same computation on the host**: the host runs `magctl::inverse::ControlLoop` with the same
//!    baked parameters; the captured currents and desired displacements must match bit for bit
//!    (IEEE f32 on both sides, no FMA contraction in Rust), proving the firmware computed the same
//!    trajectory and commands.
//! 5. **Tracking error**: the captured currents, each held over its period, drive the
//!    independent f64 reference plant (`host_tests::reference::dynamics`, relay-level Preisach
//!    operator; see [`tracking`]), and its displacement is compared with the captured Van der Pol
//!    trajectory: dynamic-inverse RMS error <= 1 % of the trajectory's peak-to-peak; the
//!    static/dynamic ratio is reported and must exceed [`MIN_STATIC_OVER_DYNAMIC`].
//! 6. **Sizes**: flash (`.vector_table + .text + .rodata + .data`) and static RAM
//!    (`.data + .bss + .uninit`) from the ELF's section headers.
//! 7. **Fault paths**: reruns QEMU with `arg=inject=panic` (exit 101), `arg=inject=hardfault`
//!    (exit 102) and `arg=inject=sensor-fault` (exit 7: an out-of-range sensor sample latched,
//!    the coil ramped to 0 A within the slew limit's time and held there, every command flagged).
//! 8. **No-panic proof**: builds the firmware with `--features panic-never` (must link: no panic
//!    path anywhere in the image, ISR included) and with `panic-never-canary` (a bounds check in
//!    the ISR; must fail to link naming `__firmware_contains_a_reachable_panic_path`).
//! 9. **Stack guard**: `firmware-hil` with `stack-overflow-canary` recurses until its stack
//!    reaches the MPU guard (`magctl::board::stack::guard`); the run must end with exit status
//!    104 (the guard's handler), not a hang, a HardFault or a lock-up.
//!
//! Writes `out/qemu/capture.csv` (columns documented in [`capture::CSV_HEADER`]), `out/qemu/tracking.csv`
//! ([`tracking::TRACKING_CSV_HEADER`]) and `out/qemu/summary.txt`.

/// Prints a line and appends it to the summary.
macro_rules! say {
    ($summary:expr, $($t:tt)*) => {{
        let line = format!($($t)*);
        println!("{line}");
        $summary.push_str(&line);
        $summary.push('\n');
    }};
}

mod capture;
pub mod firmware;
pub mod instructions;
pub mod machine;
mod tracking;

use crate::util::{display, Ctx};
use anyhow::{ensure, Context, Result};
use capture::Record;
use firmware::{build_bin, decode_defmt, elf_path, prove_panic_free, section_sizes};
use machine::qemu_command;
use std::path::{Path, PathBuf};
use std::process::Command;

/// Bound on one QEMU run of the benchmark image (it ends by itself in well under a minute).
const QEMU_TIMEOUT_S: &str = "600";

/// `firmware-qemu` built with `features` ([`build_bin`]).
fn build(ctx: &Ctx, features: &str) -> Command {
    build_bin(ctx, "firmware-qemu", features)
}

/// The benchmark image `elf` under QEMU in `out_dir` (where it writes its capture file), with
/// `extra_arg` (an `inject=` fault) passed on its semihosting command line.
fn qemu(elf: &Path, out_dir: &Path, extra_arg: Option<&str>) -> Command {
    let mut semi = String::from("enable=on,target=native,arg=firmware-qemu");
    if let Some(a) = extra_arg {
        semi.push_str(",arg=");
        semi.push_str(a);
    }
    let mut cmd = qemu_command(QEMU_TIMEOUT_S, "none", &semi, elf);
    cmd.current_dir(out_dir);
    cmd
}

/// Runs the whole check; returns the summary text.
pub fn check(ctx: &Ctx) -> Result<String> {
    let out_dir = ctx.root.join("out").join("qemu");
    std::fs::create_dir_all(&out_dir).with_context(|| format!("creating {}", out_dir.display()))?;
    let mut summary = String::new();
    let (elf_path, elf, firmware_lines, records) = run_benchmark(ctx, &out_dir, &mut summary)?;
    let (dynamic, stat) =
        instructions::check_instructions(&out_dir, &records, &firmware_lines, &mut summary)?;
    tracking::check_replay_and_tracking(&out_dir, &dynamic, &stat, &mut summary)?;
    let stack = stack_high_water_bytes(&firmware_lines)?;
    check_sizes_and_fatal_paths(&elf_path, &elf, stack, &out_dir, &mut summary)?;
    no_panic_proof(ctx, &out_dir, &mut summary)?;
    std::fs::write(out_dir.join("summary.txt"), &summary)?;
    Ok(summary)
}

/// What the benchmark run left: the ELF's path and bytes, the decoded log, the capture records.
type Benchmark = (PathBuf, Vec<u8>, Vec<String>, Vec<Record>);

/// Steps 1-2: builds the benchmark image and runs it under QEMU; returns the ELF's path and
/// bytes, the decoded log and the capture records.
fn run_benchmark(ctx: &Ctx, out_dir: &Path, summary: &mut String) -> Result<Benchmark> {
    // 1. build
    let cmd = build(ctx, "board-mps2-an386");
    println!("$ {}", display(&cmd));
    crate::util::run_checked(cmd)?;
    let elf_path = elf_path(ctx, "firmware-qemu");
    let elf =
        std::fs::read(&elf_path).with_context(|| format!("reading {}", elf_path.display()))?;

    // 2. run
    let capture_path = out_dir.join("qemu_capture.bin");
    let _ = std::fs::remove_file(&capture_path);
    let mut cmd = qemu(&elf_path, out_dir, None);
    println!("$ (cd out/qemu && {})", display(&cmd));
    let started = std::time::Instant::now();
    let output = cmd
        .output()
        .context("running timeout/qemu-system-arm (is QEMU installed? `cargo xtask setup`)")?;
    let code = output.status.code();
    let firmware_lines = decode_defmt(&elf, &output.stdout)?;
    for line in &firmware_lines {
        println!("  [firmware] {line}");
    }
    if !output.stderr.is_empty() {
        eprintln!("{}", String::from_utf8_lossy(&output.stderr));
    }
    ensure!(
        code == Some(0),
        "QEMU run exited with {code:?} (0 expected; 124 = timeout)"
    );
    say!(
        summary,
        "qemu: exit status 0 after {:.1} s host time",
        started.elapsed().as_secs_f64()
    );
    let records =
        capture::parse_records(&std::fs::read(&capture_path).context("reading the capture file")?)?;

    Ok((elf_path, elf, firmware_lines, records))
}

/// The stack high-water mark the firmware logs at the end of its run (`stack: high-water N B`).
fn stack_high_water_bytes(firmware_lines: &[String]) -> Result<u64> {
    firmware_lines
        .iter()
        .find_map(|l| {
            let rest = l.split("stack: high-water ").nth(1)?;
            rest.split(' ').next()?.parse().ok()
        })
        .context("the firmware logged no `stack: high-water N B` line")
}

/// Steps 6-7: the image's sizes and its fatal paths (before the proof builds, which replace
/// the binary).
fn check_sizes_and_fatal_paths(
    elf_path: &Path,
    elf: &[u8],
    stack_bytes: u64,
    out_dir: &Path,
    summary: &mut String,
) -> Result<()> {
    // 6. sizes: static RAM from the image, the stack measured (`magctl::board::stack`)
    let (flash, ram) = section_sizes(elf)?;
    say!(
        summary,
        "firmware-qemu sizes: flash {flash} B, RAM {} B = static {ram} B + stack high-water {stack_bytes} B (painted stack read back after the run)",
        ram + stack_bytes
    );

    // 7. fatal paths (before the proof builds, which replace the binary)
    for (arg, want) in [
        ("inject=panic", 101),
        ("inject=hardfault", 102),
        ("inject=sensor-fault", 7),
    ] {
        let got = qemu(elf_path, out_dir, Some(arg)).output()?.status.code();
        ensure!(
            got == Some(want),
            "{arg}: QEMU exit status {got:?}, expected {want}"
        );
        say!(summary, "fatal path {arg}: QEMU exited with {want}");
    }
    Ok(())
}

/// Step 8: the no-panic proof (last: it replaces the binary; the summary is written first).
fn no_panic_proof(ctx: &Ctx, out_dir: &Path, summary: &mut String) -> Result<()> {
    std::fs::write(out_dir.join("summary.txt"), &*summary)?;
    prove_panic_free(ctx, "firmware-qemu", "board-mps2-an386", Some("the ISR"))?;
    say!(summary, "no-panic proof: panic-never build links; the canary (bounds check in the ISR) fails to link as it must");
    stack_guard(ctx, summary)
}

/// Exit status of the stack guard's handler on `mps2-an386`.
const EXIT_STACK_OVERFLOW: i32 = 104;

/// Step 9: a stack overflow ends in the guard's handler.
fn stack_guard(ctx: &Ctx, summary: &mut String) -> Result<()> {
    let cmd = build_bin(
        ctx,
        "firmware-hil",
        "board-mps2-an386,stack-overflow-canary",
    );
    println!("$ {}", display(&cmd));
    crate::util::run_checked(cmd)?;
    let elf = elf_path(ctx, "firmware-hil");
    let mut qemu = qemu_command(
        "60",
        "null",
        "enable=on,target=native,arg=firmware-hil",
        &elf,
    );
    println!("$ {}", display(&qemu));
    let status = qemu.output().context("cannot run qemu-system-arm")?.status;
    ensure!(
        status.code() == Some(EXIT_STACK_OVERFLOW),
        "the stack-overflow canary ended with {status}, not the guard's exit status {EXIT_STACK_OVERFLOW}"
    );
    say!(
        summary,
        "stack guard: the overflow canary ends in the guard's handler (exit {EXIT_STACK_OVERFLOW})"
    );
    Ok(())
}

/// `cargo xtask qemu`.
pub fn run(ctx: &Ctx) -> Result<()> {
    check(ctx).map(|_| ())
}
