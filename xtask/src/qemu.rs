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
//!    operator; see [`track`]), and its displacement is compared with the captured Van der Pol
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
//! Writes `out/qemu/capture.csv` (columns documented in [`CSV_HEADER`]), `out/qemu/tracking.csv`
//! ([`TRACKING_CSV_HEADER`]) and `out/qemu/summary.txt`.

use crate::util::{display, Ctx};
use anyhow::{bail, ensure, Context, Result};
use host_tests::reference::preisach::RelayPreisach;
use host_tests::tracking::{self, TrackingStats};
use magctl::board::capture_phase::CapturePhase;
use magctl::inverse::{ControlLoop, InverseKind, LoopState};
use magctl::params::{BAKED_MEASURE, BAKED_PARAMETERS};
use object::{Object, ObjectSection};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;

/// The firmware's target triple (one definition: `setup` installs it, every build here uses it).
pub use crate::setup::FIRMWARE_TARGET as TARGET;
const RECORD_BYTES: usize = 40;
/// SysTick ticks per instruction under `-icount shift=10` on the 25 MHz mps2: 1024 ns × 25 MHz.
const TICKS_PER_INSTRUCTION: f64 = 25.6;
/// The goal for the whole handler.
const MAX_INSTRUCTIONS: f64 = 1_500.0;
/// Budget of an interrupt that forces a staircase merge (the 64-point memory full: one O(N) scan
/// of the 62 candidate rectangles, a memmove, a running-sum update): ≤ 2,500 instructions,
/// ~3,300 cycles at 180 MHz with flash wait states, 18 % of the 18,000-cycle period at 10 kHz.
const MAX_MERGE_INSTRUCTIONS: f64 = 2_500.0;
const QEMU_TIMEOUT_S: &str = "600";
pub const PANIC_SYMBOL: &str = "__firmware_contains_a_reachable_panic_path";
/// "Clearly worse": the static inverse's RMS tracking error must exceed the dynamic one's by this
/// factor. The dynamic inverse must stay within 1 % of the peak-to-peak; the static inverse
/// ignores (4)-(5), whose phase lag at the trajectory's ≈ 94 Hz fundamental alone is
/// ≈ 2ξ f / f0 ≈ 0.37 rad, i.e. an RMS error of ≈ 13 % of the peak-to-peak — more than 10 times
/// the dynamic inverse's bound. 5 leaves room for a plant whose reference error eats into that.
const MIN_STATIC_OVER_DYNAMIC: f64 = 5.0;

/// Columns of `out/qemu/capture.csv`. `t_s` is the start of the period over which the current is
/// held (tick index / sample rate); the desired values are those at `t_s + h` (the end of the
/// period, what the inverse aims at). `instructions` = SysTick ticks / 25.6.
pub const CSV_HEADER: &str = "phase,index,t_s,current_a,y_desired_m,y_rate_m_per_s,y_accel_m_per_s2,h_a_per_m,m_a_per_m,flags,dac_code,instructions";

/// One parsed capture record.
#[derive(Debug, Clone, Copy)]
pub struct Record {
    phase: u8,
    flags: u8,
    index: u32,
    ticks: u32,
    current_a: f32,
    y_m: f32,
    y_rate: f32,
    y_accel: f32,
    h: f32,
    m: f32,
    dac_code: u16,
    overruns: u16,
}

fn parse_records(bytes: &[u8]) -> Result<Vec<Record>> {
    ensure!(
        bytes.len().is_multiple_of(RECORD_BYTES),
        "capture length {} is not a multiple of {RECORD_BYTES}",
        bytes.len()
    );
    Ok(bytes
        .chunks_exact(RECORD_BYTES)
        .map(|c| {
            let w =
                |i: usize| u32::from_le_bytes([c[4 * i], c[4 * i + 1], c[4 * i + 2], c[4 * i + 3]]);
            let f = |i: usize| f32::from_bits(w(i));
            Record {
                phase: (w(0) & 0xFF) as u8,
                flags: ((w(0) >> 8) & 0xFF) as u8,
                index: w(1),
                ticks: w(2),
                current_a: f(3),
                y_m: f(4),
                y_rate: f(5),
                y_accel: f(6),
                h: f(7),
                m: f(8),
                dac_code: (w(9) & 0xFFFF) as u16,
                overruns: (w(9) >> 16) as u16,
            }
        })
        .collect())
}

/// Where the firmware builds go.
pub fn firmware_dir(ctx: &Ctx) -> PathBuf {
    ctx.root.join("target").join("firmware")
}

fn build(ctx: &Ctx, features: &str) -> Command {
    build_bin(ctx, "firmware-qemu", features)
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

/// `timeout TIMEOUT qemu-system-arm` on mps2-an386 (Cortex-M4F) with semihosting (`semi`: the
/// `-semihosting-config` value), `-icount shift=10,sleep=off` (SysTick counts instructions), the
/// first UART on `serial` (a QEMU `-serial` value) and `elf` as the kernel.
pub fn qemu_command(timeout_s: &str, serial: &str, semi: &str, elf: &Path) -> Command {
    let mut cmd = Command::new("timeout");
    cmd.args([
        timeout_s,
        "qemu-system-arm",
        "-machine",
        "mps2-an386",
        "-cpu",
        "cortex-m4",
        "-nographic",
        "-monitor",
        "none",
        "-serial",
        serial,
        "-semihosting-config",
        semi,
        "-icount",
        "shift=10,sleep=off",
        "-kernel",
    ])
    .arg(elf);
    cmd
}

/// `timeout TIMEOUT qemu-system-arm` on `netduinoplus2` (STM32F405) for the NUCLEO image's
/// emulator build: USART1 unconnected, USART2 (the plant link) on `serial`, semihosting (`semi`),
/// `-icount shift=0,sleep=off` (1 ns of virtual time per instruction: the handler's work, about
/// a thousand instructions, fits the emulated TIM2's period, and an idle core skips to the next
/// timer event), `elf` as the kernel.
pub fn netduino_command(timeout_s: &str, serial: &str, semi: &str, elf: &Path) -> Command {
    let mut cmd = Command::new("timeout");
    cmd.args([
        timeout_s,
        "qemu-system-arm",
        "-machine",
        "netduinoplus2",
        "-nographic",
        "-monitor",
        "none",
        "-serial",
        "null",
        "-serial",
        serial,
        "-semihosting-config",
        semi,
        "-icount",
        "shift=0,sleep=off",
    ]);
    if std::env::var_os("DEBUG_GDB").is_some() {
        cmd.args(["-gdb", "tcp::3334"]);
    }
    cmd.arg("-kernel").arg(elf);
    cmd
}

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

/// (min, median, max) of a list.
pub fn stats(mut v: Vec<f64>) -> (f64, f64, f64) {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    let median = if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    };
    (v[0], median, v[n - 1])
}

/// (flash, static RAM) in bytes from the ELF's section headers (module docs, step 6).
pub fn section_sizes(elf: &[u8]) -> Result<(u64, u64)> {
    let file = object::File::parse(elf)?;
    let size = |name: &str| file.section_by_name(name).map(|s| s.size()).unwrap_or(0);
    let flash = size(".vector_table") + size(".text") + size(".rodata") + size(".data");
    let ram = size(".data") + size(".bss") + size(".uninit");
    Ok((flash, ram))
}

/// Feeds the captured currents of one phase (each held over its control period) to the
/// independent f64 reference plant (`host_tests::reference::dynamics`: RK4 on the integral form
/// (8), [`tracking::SUBSTEPS`] substeps per period, relay-level Preisach operator with
/// `field.subdivision()` relays per cell side), started in the state the controller assumes
/// (`host_tests::tracking::start_plant`), and compares its displacement with the captured Van der
/// Pol trajectory. Returns the statistics and the plant's displacement.
fn track(
    records: &[Record],
    kind: InverseKind,
    field: &RelayPreisach,
) -> Result<(TrackingStats, Vec<f64>)> {
    let p = &BAKED_PARAMETERS;
    let control = ControlLoop::new(&BAKED_MEASURE, p).map_err(|e| anyhow::anyhow!("{e:?}"))?;
    let currents: Vec<f32> = records.iter().map(|r| r.current_a).collect();
    let actual = tracking::plant_response(
        &control,
        kind,
        tracking::plant_constants(&p.actuator),
        field,
        1.0 / p.control.sample_rate_hz as f64,
        &currents,
    );
    let desired: Vec<f64> = records.iter().map(|r| r.y_m as f64).collect();
    Ok((TrackingStats::of(&desired, &actual), actual))
}

/// The host recomputation must reproduce the firmware's stream bit for bit.
fn replay_on_host(records: &[Record], kind: InverseKind) -> Result<()> {
    let control = ControlLoop::new(&BAKED_MEASURE, &BAKED_PARAMETERS)
        .map_err(|e| anyhow::anyhow!("{e:?}"))?;
    let mut state: LoopState<64> = control.init(kind);
    for r in records {
        let out = control.tick(kind, &mut state);
        ensure!(
            out.current_a.to_bits() == r.current_a.to_bits()
                && out.desired.displacement_m.to_bits() == r.y_m.to_bits(),
            "{kind:?} tick {}: firmware current {} A / ȳ {} m, host {} A / {} m",
            r.index,
            r.current_a,
            r.y_m,
            out.current_a,
            out.desired.displacement_m
        );
    }
    Ok(())
}

/// Columns of `out/qemu/tracking.csv`: one row per control period of the dynamic and static
/// phases; `t_s` is the end of the period (the time of `y_desired_m` and of the plant's `y_plant_m`).
pub const TRACKING_CSV_HEADER: &str = "phase,index,t_s,current_a,y_desired_m,y_plant_m,error_m";

fn write_tracking_csv(
    out_dir: &Path,
    dynamic: &[Record],
    dyn_y: &[f64],
    stat: &[Record],
    stat_y: &[f64],
    rate: f64,
) -> Result<()> {
    let mut csv = String::from(TRACKING_CSV_HEADER);
    csv.push('\n');
    for (name, records, ys) in [("dynamic", dynamic, dyn_y), ("static", stat, stat_y)] {
        for (r, &y) in records.iter().zip(ys) {
            let _ = writeln!(
                csv,
                "{name},{},{:.6},{:e},{:e},{:e},{:e}",
                r.index,
                (r.index as f64 + 1.0) / rate,
                r.current_a,
                r.y_m,
                y,
                y - r.y_m as f64
            );
        }
    }
    let path = out_dir.join("tracking.csv");
    std::fs::write(&path, csv).with_context(|| format!("writing {}", path.display()))
}

/// Prints a line and appends it to the summary.
macro_rules! say {
    ($summary:expr, $($t:tt)*) => {{
        let line = format!($($t)*);
        println!("{line}");
        $summary.push_str(&line);
        $summary.push('\n');
    }};
}

/// Runs the whole check; returns the summary text.
pub fn check(ctx: &Ctx) -> Result<String> {
    let out_dir = ctx.root.join("out").join("qemu");
    std::fs::create_dir_all(&out_dir).with_context(|| format!("creating {}", out_dir.display()))?;
    let mut summary = String::new();
    let (elf_path, elf, firmware_lines, records) = run_benchmark(ctx, &out_dir, &mut summary)?;
    let (dynamic, stat) = check_instructions(&out_dir, &records, &firmware_lines, &mut summary)?;
    check_replay_and_tracking(&out_dir, &dynamic, &stat, &mut summary)?;
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
    let elf_path = firmware_dir(ctx)
        .join(TARGET)
        .join("release")
        .join("firmware-qemu");
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
        parse_records(&std::fs::read(&capture_path).context("reading the capture file")?)?;

    Ok((elf_path, elf, firmware_lines, records))
}

/// Step 3: the instruction counter's calibration, each phase's instructions per interrupt
/// against the goals, the capture CSV; returns the dynamic and static phases' records.
fn check_instructions(
    out_dir: &Path,
    records: &[Record],
    firmware_lines: &[String],
    summary: &mut String,
) -> Result<(Vec<Record>, Vec<Record>)> {
    // 3. instruction counts
    let cal = records
        .first()
        .filter(|r| r.phase == 0)
        .context("no calibration record")?;
    // The two timed blocks differ by exactly `index` nops; the surrounding reads may differ by one
    // instruction depending on code generation, and SysTick rounds to whole ticks: accept
    // ±(1 instruction + 1 tick) around index × 25.6.
    let ticks_per_instruction = cal.ticks as f64 / cal.index as f64;
    let expected_ticks = cal.index as f64 * TICKS_PER_INSTRUCTION;
    say!(
        summary,
        "calibration: {} extra nops = {} SysTick ticks -> {:.4} ticks/instruction (expected {TICKS_PER_INSTRUCTION})",
        cal.index, cal.ticks, ticks_per_instruction
    );
    ensure!(
        (cal.ticks as f64 - expected_ticks).abs() <= TICKS_PER_INSTRUCTION + 1.0,
        "SysTick does not count 25.6 ticks per instruction: {ticks_per_instruction}"
    );
    let rate = BAKED_PARAMETERS.control.sample_rate_hz as f64;
    let phase = |k: u8| {
        records
            .iter()
            .filter(|r| r.phase == k)
            .copied()
            .collect::<Vec<_>>()
    };
    let (dynamic, stat, naive, merge) = (phase(1), phase(2), phase(3), phase(4));
    let (everett, relay) = (phase(5), phase(6));
    ensure!(
        dynamic.len() as f64 >= rate && stat.len() as f64 >= rate,
        "less than 1 s of control time captured"
    );
    ensure!(!naive.is_empty(), "no naive-phase records");
    ensure!(!merge.is_empty(), "no merge-stress records");
    ensure!(
        !everett.is_empty() && !relay.is_empty(),
        "no records of the peer baselines"
    );
    let instr = |rs: &[Record]| {
        stats(
            rs.iter()
                .map(|r| r.ticks as f64 / TICKS_PER_INSTRUCTION)
                .collect(),
        )
    };
    let (d, s, n, m) = (instr(&dynamic), instr(&stat), instr(&naive), instr(&merge));
    let (e, r) = (instr(&everett), instr(&relay));
    say!(summary, "instructions per interrupt (min / median / max):");
    say!(
        summary,
        "  dynamic inverse, exact Preisach inverse: {:.0} / {:.0} / {:.0}  ({} interrupts)",
        d.0,
        d.1,
        d.2,
        dynamic.len()
    );
    say!(
        summary,
        "  static inverse,  exact Preisach inverse: {:.0} / {:.0} / {:.0}  ({} interrupts)",
        s.0,
        s.1,
        s.2,
        stat.len()
    );
    say!(
        summary,
        "  merge stress (dynamic inverse, staircase full, no trajectory step): {:.0} / {:.0} / {:.0}  ({} interrupts)",
        m.0,
        m.1,
        m.2,
        merge.len()
    );
    say!(
        summary,
        "  dynamic inverse, naive (bisection):      {:.0} / {:.0} / {:.0}  ({} interrupts)",
        n.0,
        n.1,
        n.2,
        naive.len()
    );
    say!(
        summary,
        "  dynamic inverse, Everett + bisection (openCFS-style): {:.0} / {:.0} / {:.0}  ({} interrupts)",
        e.0,
        e.1,
        e.2,
        everett.len()
    );
    say!(
        summary,
        "  dynamic inverse, relay grid + bisection (5,050 relays): {:.0} / {:.0} / {:.0}  ({} interrupts)",
        r.0,
        r.1,
        r.2,
        relay.len()
    );
    say!(
        summary,
        "  Everett bisection / ours: median {:.1}x, worst case {:.1}x",
        e.1 / d.1,
        e.2 / d.2
    );
    say!(
        summary,
        "  relay grid / ours: median {:.0}x, worst case {:.0}x",
        r.1 / d.1,
        r.2 / d.2
    );
    say!(
        summary,
        "  naive (strawman) / ours: median {:.0}x, worst case {:.0}x",
        n.1 / d.1,
        n.2 / d.2
    );
    say!(summary, "dynamic-inverse interrupt by stage (2,000 steps in thread mode, instructions min / mean / max):");
    for line in firmware_lines
        .iter()
        .filter_map(|l| l.split("stage ").nth(1))
    {
        say!(summary, "  {line}");
    }
    let overruns = records.iter().map(|r| r.overruns).max().unwrap_or(0);
    let faults = records.iter().filter(|r| r.flags & 8 != 0).count();
    say!(summary, "overruns {overruns}, fault flags {faults}");
    ensure!(
        overruns == 0 && faults == 0,
        "overruns or faults in the QEMU run"
    );

    // CSV
    let mut csv = String::from(CSV_HEADER);
    csv.push('\n');
    for r in records.iter().filter(|r| r.phase != 0) {
        let _ = writeln!(
            csv,
            "{},{},{:.6},{:e},{:e},{:e},{:e},{:e},{:e},{},{},{:.1}",
            CapturePhase::from_code(r.phase).map_or("unknown", CapturePhase::name),
            r.index,
            r.index as f64 / rate,
            r.current_a,
            r.y_m,
            r.y_rate,
            r.y_accel,
            r.h,
            r.m,
            r.flags,
            r.dac_code,
            r.ticks as f64 / TICKS_PER_INSTRUCTION
        );
    }
    std::fs::write(out_dir.join("capture.csv"), csv)?;
    say!(
        summary,
        "wrote out/qemu/capture.csv ({} rows)",
        records.len() - 1
    );
    ensure!(
        d.2 <= MAX_INSTRUCTIONS && s.2 <= MAX_INSTRUCTIONS,
        "worst case above {MAX_INSTRUCTIONS} instructions"
    );
    ensure!(
        m.2 <= MAX_MERGE_INSTRUCTIONS,
        "merge-stress worst case {:.0} above {MAX_MERGE_INSTRUCTIONS} instructions",
        m.2
    );

    Ok((dynamic, stat))
}

/// Steps 4-5: the host replays the captured commands bit for bit, and the reference plant
/// tracks them.
fn check_replay_and_tracking(
    out_dir: &Path,
    dynamic: &[Record],
    stat: &[Record],
    summary: &mut String,
) -> Result<()> {
    let rate = BAKED_PARAMETERS.control.sample_rate_hz as f64;
    // 4. host replay
    replay_on_host(dynamic, InverseKind::Dynamic)?;
    replay_on_host(stat, InverseKind::Static)?;
    say!(summary, "host replay: firmware currents and trajectory identical bit for bit (dynamic and static phases)");

    // 5. tracking
    let field = tracking::relay_field(&BAKED_PARAMETERS, tracking::RELAY_SUBDIVISION)
        .map_err(|e| anyhow::anyhow!("reference relay field: {}", e.0))?;
    let (dyn_stats, dyn_y) = track(dynamic, InverseKind::Dynamic, &field)?;
    let (stat_stats, stat_y) = track(stat, InverseKind::Static, &field)?;
    let ratio = stat_stats.rms_error_m / dyn_stats.rms_error_m;
    say!(
        summary,
        "tracking (reference plant: f64 RK4, {} substeps/period, {} relays per cell side), trajectory p2p {:.3e} m:",
        tracking::SUBSTEPS,
        field.subdivision(),
        dyn_stats.peak_to_peak_m
    );
    say!(
        summary,
        "  dynamic inverse: RMS {:.3e} m = {:.3} % of p2p, max {:.3e} m = {:.3} %",
        dyn_stats.rms_error_m,
        dyn_stats.rms_percent(),
        dyn_stats.max_error_m,
        dyn_stats.max_percent()
    );
    say!(
        summary,
        "  static inverse:  RMS {:.3e} m = {:.3} % of p2p, max {:.3e} m = {:.3} %",
        stat_stats.rms_error_m,
        stat_stats.rms_percent(),
        stat_stats.max_error_m,
        stat_stats.max_percent()
    );
    say!(summary, "  static / dynamic RMS error: {ratio:.1}x");
    ensure!(
        dyn_stats.rms_error_m <= 0.01 * dyn_stats.peak_to_peak_m,
        "dynamic-inverse RMS error {:.3} % is above 1 % of the peak-to-peak",
        dyn_stats.rms_percent()
    );
    ensure!(
        ratio > MIN_STATIC_OVER_DYNAMIC,
        "static inverse not clearly worse than the dynamic one (ratio {ratio:.2}, need > {MIN_STATIC_OVER_DYNAMIC})"
    );
    write_tracking_csv(out_dir, dynamic, &dyn_y, stat, &stat_y, rate)?;
    say!(summary, "wrote out/qemu/tracking.csv");

    Ok(())
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
    // 8. no-panic proof (last: it replaces the binary; the summary is written first)
    let cmd = build(ctx, "board-mps2-an386,panic-never");
    println!("$ {}", display(&cmd));
    std::fs::write(out_dir.join("summary.txt"), &*summary)?;
    let proof = run_capture(cmd)?;
    if !proof.0 {
        bail!(
            "no-panic proof FAILED: the firmware image still contains a reachable panic path:\n{}",
            proof
                .1
                .lines()
                .filter(|l| l.contains("undefined symbol") || l.contains(">>> referenced"))
                .collect::<Vec<_>>()
                .join("\n")
        );
    }
    let cmd = build(ctx, "board-mps2-an386,panic-never-canary");
    println!("$ {}", display(&cmd));
    let canary = run_capture(cmd)?;
    ensure!(
        !canary.0 && canary.1.contains(PANIC_SYMBOL),
        "the canary build (a panic in the ISR) linked: the no-panic proof would not catch a panic"
    );
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
    let elf = firmware_dir(ctx)
        .join(TARGET)
        .join("release")
        .join("firmware-hil");
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

/// Runs a command, returning (success, stderr).
pub fn run_capture(mut cmd: Command) -> Result<(bool, String)> {
    let out = cmd
        .output()
        .with_context(|| format!("running {}", display(&cmd)))?;
    Ok((
        out.status.success(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    ))
}

/// `cargo xtask qemu`.
pub fn run(ctx: &Ctx) -> Result<()> {
    check(ctx).map(|_| ())
}
