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

pub use checks::check;
pub use end_to_end::end_to_end;
pub use matrix::interrupt_matrix;
pub use measurement::{identification_programme, Programme};

use crate::frame_socket::{FrameSocket, WAKE_BOUND};
use crate::qemu::firmware::{build_bin, decode_defmt, elf_path};
use crate::qemu::instructions::stats;
use crate::qemu::machine::{netduino_command, qemu_command};
use crate::util::{display, run_checked, Ctx};
use anyhow::{bail, ensure, Context, Result};
use bridge::{Collected, LinkActivity};
use link_log::{tracking_error, write_link_csv, TickRow};
use magctl::inverse::CommandFlags;
use magctl::link::{CommandFrame, COMMAND_FRAME_BYTES};
use measurement::{check_record_against_link, local_programme_ticks, write_dataset};
use std::fmt::Write as _;
use std::net::TcpListener;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::atomic::Ordering;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// QEMU's wall-clock limit for one run, s.
const QEMU_TIMEOUT_S: &str = "300";

/// A fault the bridge injects into the plant → firmware stream.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Inject {
    /// The sample of this tick becomes NaN metres.
    Nan(u32),
    /// The sample of this tick becomes an ADC count beyond the converter's range.
    Range(u32),
    /// No sample is forwarded from this tick on.
    Silent(u32),
    /// This tick's frame gets a wrong sync byte.
    Garbage(u32),
}

impl Inject {
    fn parse(text: &str) -> Result<Self> {
        let (kind, at) = text
            .split_once('@')
            .with_context(|| format!("--inject `{text}`: expected KIND@TICK"))?;
        let at: u32 = at
            .parse()
            .with_context(|| format!("--inject `{text}`: tick `{at}` is not a number"))?;
        Ok(match kind {
            "nan" => Inject::Nan(at),
            "range" => Inject::Range(at),
            "silent" => Inject::Silent(at),
            "garbage" => Inject::Garbage(at),
            k => bail!("--inject `{text}`: unknown kind `{k}` (nan, range, silent, garbage)"),
        })
    }
}

/// Which firmware image and QEMU machine run the bench.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Board {
    /// `firmware-hil` on `mps2-an386` (the plant link on UART0; instruction counts exact).
    Mps2,
    /// The NUCLEO image (`firmware-nucleo`, its emulator build) on `netduinoplus2`: the board's
    /// TIM2, SPI1, watchdog and start-up code, the plant link on USART2 (docs/firmware.md).
    Nucleo,
}

/// One run's settings.
#[derive(Debug, Clone)]
pub struct HilRun {
    /// The image and machine.
    pub board: Board,
    /// NUCLEO image only: poll the clock flags after the HSE's as on the chip (`clocks=board`;
    /// the emulator never sets them: the start-up halts at 0 A, exit 9).
    pub board_clock_flags: bool,
    /// External plant command (`sh -c`), or the default plant.
    pub plant_cmd: Option<String>,
    /// Effects of the default plant.
    pub effects: Vec<String>,
    /// Sensor noise of the default plant, m.
    pub noise_m: Option<f64>,
    /// Random prior history levels of the default plant.
    pub prior_history: usize,
    /// Seed of the default plant (noise, prior history).
    pub seed: u64,
    /// Control ticks.
    pub ticks: u32,
    /// `static` or `dynamic`.
    pub inverse: String,
    /// Injected fault.
    pub inject: Option<Inject>,
    /// Expected firmware exit status.
    pub expect_exit: i32,
    /// Run the firmware's start-up conditioning (default).
    pub conditioning: bool,
    /// Run the parameter file's displacement feedback (default); `false` passes `feedback=off`.
    pub feedback: bool,
    /// Parameter file of the default plant (default: the baked parameters).
    pub plant_params: Option<PathBuf>,
    /// The default plant's own rod (`maglab hil-plant --rod FAMILY:FACTOR`): a Preisach measure
    /// on the plant's grid instead of the file's.
    pub plant_rod: Option<String>,
    /// The default plant's current monitor (`maglab hil-plant --coil-current-noise-a`): every
    /// sample frame carries the coil current (link version 2), and a measurement's dataset has
    /// the `coil_current_a` column.
    pub plant_coil_current_noise_a: Option<f64>,
    /// Measurement mode: the programme to stream and where to write the dataset folder.
    pub measure: Option<(Arc<Programme>, PathBuf)>,
    /// Streamed measurement of only the programme's first ticks (no dataset written).
    pub measure_ticks: Option<u32>,
    /// Local measurement (`mode=measure-local`): the firmware plays its compiled-in programme
    /// and logs the record (`MEAS` lines), which is checked against the link and written here.
    pub measure_local: Option<PathBuf>,
    /// Firmware ELF to run instead of the default build (e.g. one baked with identified
    /// parameters).
    pub elf: Option<PathBuf>,
    /// Output directory.
    pub out: PathBuf,
}

impl HilRun {
    /// Default settings writing into `out`.
    pub fn new(out: PathBuf) -> Self {
        HilRun {
            board: Board::Mps2,
            board_clock_flags: false,
            plant_cmd: None,
            effects: Vec::new(),
            noise_m: None,
            prior_history: 0,
            seed: 1,
            ticks: 10_000,
            inverse: "dynamic".into(),
            inject: None,
            expect_exit: 0,
            conditioning: true,
            feedback: true,
            plant_params: None,
            plant_rod: None,
            plant_coil_current_noise_a: None,
            measure: None,
            measure_ticks: None,
            measure_local: None,
            elf: None,
            out,
        }
    }
}

/// What a run produced.
#[derive(Debug, Clone)]
pub struct HilResult {
    /// Command frames received.
    pub commands: usize,
    /// Tracking RMS and max error, % of the desired peak-to-peak, and what it was measured on.
    pub tracking: Option<(f64, f64, &'static str)>,
    /// Wall time of the QEMU run, s.
    pub wall_s: f64,
    /// The summary text.
    pub summary: String,
    /// The command frames, in tick order.
    pub frames: Vec<CommandFrame>,
    /// The tracking interrupts' instructions: min, median, max.
    pub instructions: (f64, f64, f64),
}

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

/// The plant program's command line: `--plant-cmd` through `sh -c`, or `maglab hil-plant`
/// with the run's effects, noise, prior history and seed, logging its true displacement to
/// `plant_log`.
fn plant_command(
    ctx: &Ctx,
    maglab_exe: Option<&Path>,
    run: &HilRun,
    plant_log: &Path,
) -> Result<Command> {
    let mut c = match &run.plant_cmd {
        Some(cmd) => {
            let mut c = Command::new("sh");
            c.args(["-c", cmd]);
            c
        }
        None => {
            let exe = maglab_exe.context("the default plant needs maglab")?;
            let mut c = Command::new(exe);
            c.arg("hil-plant").arg("--log").arg(plant_log);
            if let Some(p) = &run.plant_params {
                c.arg("--params").arg(ctx.root.join(p));
            }
            if let Some(rod) = &run.plant_rod {
                c.args(["--rod", rod]);
            }
            if let Some(n) = run.plant_coil_current_noise_a {
                c.args(["--coil-current-noise-a", &n.to_string()]);
            }
            for e in &run.effects {
                c.args(["--effect", e]);
            }
            if let Some(n) = run.noise_m {
                c.args(["--noise-m", &n.to_string()]);
            }
            if run.prior_history > 0 {
                c.args(["--prior-history", &run.prior_history.to_string()]);
            }
            c.args(["--seed", &run.seed.to_string()]);
            c
        }
    };
    c.current_dir(&ctx.root);
    Ok(c)
}

/// The firmware's ticks and its semihosting command line (`docs/hil.md`).
fn firmware_arguments(run: &HilRun) -> Result<(u32, String)> {
    if run.board == Board::Nucleo {
        ensure!(
            run.measure.is_none()
                && run.measure_local.is_none()
                && run.inverse == "dynamic"
                && run.conditioning
                && run.feedback,
            "the NUCLEO image tracks with its baked settings: no measurement mode, --inverse, \
             --no-conditioning or --feedback-off on --board nucleo"
        );
        let mut semi = format!(
            "enable=on,target=native,arg=firmware-nucleo,arg=ticks={}",
            run.ticks
        );
        if run.board_clock_flags {
            semi.push_str(",arg=clocks=board");
        }
        return Ok((run.ticks, semi));
    }
    let ticks = match (&run.measure, &run.measure_local) {
        (Some((p, _)), _) => run.measure_ticks.unwrap_or(p.current_a.len() as u32),
        (None, Some(_)) => local_programme_ticks()?,
        (None, None) => run.ticks,
    };
    let mut semi = format!("enable=on,target=native,arg=firmware-hil,arg=ticks={ticks}");
    if run.measure_local.is_some() {
        semi.push_str(",arg=mode=measure-local");
    } else if run.measure.is_some() {
        semi.push_str(",arg=mode=measure");
    }
    if run.inverse == "static" {
        semi.push_str(",arg=inverse=static");
    }
    if !run.conditioning {
        semi.push_str(",arg=condition=off");
    }
    if !run.feedback {
        semi.push_str(",arg=feedback=off");
    }
    Ok((ticks, semi))
}

/// What the bridged run left: QEMU's output, the link's frames and counts.
struct Bridged {
    exit: i32,
    wall_s: f64,
    qemu_stdout: Vec<u8>,
    qemu_stderr: String,
    plant_status: String,
    rows: Vec<TickRow>,
    link_report: String,
}

/// Starts QEMU and the plant, bridges them until QEMU exits, and collects the link.
fn bridge_run(
    qemu: &mut Command,
    plant: &mut Command,
    listener: TcpListener,
    run: &HilRun,
) -> Result<Bridged> {
    println!("$ {}", display(qemu));
    let started = Instant::now();
    let mut qemu_child = qemu.spawn().context("cannot start qemu-system-arm")?;
    let socket = bridge::accept_qemu(&listener, &mut qemu_child, started)?;
    let mut plant_child = plant
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .context("cannot start the plant program")?;
    let plant_in = plant_child.stdin.take().context("plant stdin")?;
    let plant_out = plant_child.stdout.take().context("plant stdout")?;
    // Both bridge threads write to the firmware (samples; the acknowledgement of `E`), a whole
    // frame at a time.
    let to_firmware = Arc::new(Mutex::new(socket.try_clone()?));
    let collected = Arc::new(Collected::default());
    let activity = Arc::new(LinkActivity::default());
    let stalls = bridge::watch_stalls(activity.clone(), socket.try_clone()?, started);
    let fw_to_plant = bridge::firmware_to_plant(
        FrameSocket::new(socket, COMMAND_FRAME_BYTES)?,
        plant_in,
        to_firmware.clone(),
        collected.clone(),
        activity.clone(),
    );
    let plant_to_fw = bridge::plant_to_firmware(
        plant_out,
        to_firmware,
        run.inject,
        run.measure.as_ref().map(|(p, _)| p.clone()),
        collected.clone(),
        activity.clone(),
    );
    let output = qemu_child.wait_with_output().context("waiting for QEMU")?;
    let wall_s = started.elapsed().as_secs_f64();
    activity.done.store(true, Ordering::Release);
    let stall_lines = stalls
        .join()
        .map_err(|_| anyhow::anyhow!("stall watch thread panicked"))?;
    // QEMU is gone: its socket end is closed, the bridge threads see EOF.
    let fw_result = fw_to_plant
        .join()
        .map_err(|_| anyhow::anyhow!("bridge thread panicked"))?;
    let plant_status = bridge::wait_with_timeout(&mut plant_child, Duration::from_secs(20))?;
    let _ = plant_to_fw.join();
    let frames = fw_result?;
    let link_report = link_report(&frames, &stall_lines)?;
    let rows: Vec<TickRow> = {
        let c = collected
            .commands
            .lock()
            .map_err(|_| anyhow::anyhow!("poisoned"))?;
        let sm = collected
            .samples
            .lock()
            .map_err(|_| anyhow::anyhow!("poisoned"))?;
        (0..c.len().max(sm.len()))
            .map(|k| TickRow {
                sample: sm.get(k).map(|f| f.sample),
                coil_current_a: sm.get(k).and_then(|f| f.coil_current_a),
                command: c.get(k).copied(),
            })
            .collect()
    };
    Ok(Bridged {
        exit: output.status.code().unwrap_or(-1),
        wall_s,
        qemu_stdout: output.stdout,
        qemu_stderr: String::from_utf8_lossy(&output.stderr).trim().to_string(),
        plant_status,
        rows,
        link_report,
    })
}

/// The link's report: frames read in parts or found without a wake-up, and every stall.
fn link_report(frames: &FrameSocket, stall_lines: &[String]) -> Result<String> {
    let mut report = String::new();
    if frames.split_frames > 0 {
        writeln!(
            report,
            "  link: {} command frame(s) read in parts (a wake-up before the whole frame was there)",
            frames.split_frames
        )?;
    }
    if frames.missed_wakes > 0 {
        writeln!(
            report,
            "  link: {} command frame(s) found queued without a wake-up, taken after the bridge's {} ms bound",
            frames.missed_wakes,
            WAKE_BOUND.as_millis()
        )?;
    }
    for l in stall_lines {
        writeln!(report, "{l}")?;
    }
    Ok(report)
}

/// Runs one lock-step co-simulation.
pub fn run_once(
    ctx: &Ctx,
    elf: &Path,
    maglab_exe: Option<&Path>,
    run: &HilRun,
) -> Result<HilResult> {
    std::fs::create_dir_all(&run.out)
        .with_context(|| format!("cannot create {}", run.out.display()))?;
    let out_abs = run.out.canonicalize()?;
    let plant_log = out_abs.join("plant_log.csv");
    let _ = std::fs::remove_file(&plant_log);
    let true_displacement = out_abs.join("true_displacement.csv");
    let _ = std::fs::remove_file(&true_displacement);
    let mut plant = plant_command(ctx, maglab_exe, run, &plant_log)?;
    plant.env(link_log::TRUE_DISPLACEMENT_ENV, &true_displacement);
    println!("$ {}", display(&plant));
    let listener = TcpListener::bind("127.0.0.1:0").context("cannot open a local TCP port")?;
    let port = listener.local_addr()?.port();
    let elf = run.elf.as_deref().unwrap_or(elf);
    let (ticks, semi) = firmware_arguments(run)?;
    let serial = format!("tcp:127.0.0.1:{port},nodelay=on");
    let mut qemu = match run.board {
        Board::Mps2 => qemu_command(QEMU_TIMEOUT_S, &serial, &semi, elf),
        Board::Nucleo => netduino_command(QEMU_TIMEOUT_S, &serial, &semi, elf),
    };
    qemu.current_dir(&out_abs)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    let b = bridge_run(&mut qemu, &mut plant, listener, run)?;
    let log_lines = decode_defmt(&std::fs::read(elf)?, &b.qemu_stdout).unwrap_or_default();
    print_firmware_log(&log_lines);
    // The link's report, printed here (a run that fails below still shows it) and kept in
    // `summary.txt`.
    print!("{}", b.link_report);
    if !b.qemu_stderr.is_empty() {
        println!("  qemu stderr: {}", b.qemu_stderr);
    }
    write_link_csv(&out_abs.join("link.csv"), &b.rows)?;
    if b.rows.iter().all(|r| r.command.is_none()) && run.expect_exit != 0 {
        return halted_before_first_tick(run, &b, &out_abs);
    }
    let record_line = write_measurement(run, &b, &log_lines)?;
    let (commands, conditioning_ticks, instr) = interrupt_costs(&b)?;
    let tracking = tracking_error(&plant_log, &true_displacement, &b.rows)?;
    let mut s = summary(
        run,
        ticks,
        &b,
        commands,
        conditioning_ticks,
        instr,
        tracking,
    )?;
    s.push_str(&record_line);
    writeln!(s, "  wall time {:.1} s", b.wall_s)?;
    print!("{s}");
    s.push_str(&b.link_report);
    std::fs::write(out_abs.join("summary.txt"), &s)?;
    expect_exit(run, &b)?;
    Ok(HilResult {
        commands,
        tracking,
        wall_s: b.wall_s,
        summary: s,
        frames: b.rows.iter().filter_map(|r| r.command).collect(),
        instructions: instr,
    })
}

/// The run ended with the exit status it expects.
fn expect_exit(run: &HilRun, b: &Bridged) -> Result<()> {
    ensure!(
        b.exit == run.expect_exit,
        "firmware exit status {}, expected {}",
        b.exit,
        run.expect_exit
    );
    Ok(())
}

/// A run that ended before its first tick (a start-up halt the run expects): its exit status is
/// the result.
fn halted_before_first_tick(run: &HilRun, b: &Bridged, out: &Path) -> Result<HilResult> {
    let s = format!(
        "hil: start-up only\n  firmware exit {} (expected {}) before its first tick, plant {}\n  wall time {:.1} s\n",
        b.exit, run.expect_exit, b.plant_status, b.wall_s
    );
    print!("{s}");
    std::fs::write(out.join("summary.txt"), &s)?;
    expect_exit(run, b)?;
    Ok(HilResult {
        commands: 0,
        tracking: None,
        wall_s: b.wall_s,
        summary: s,
        frames: Vec::new(),
        instructions: (f64::NAN, f64::NAN, f64::NAN),
    })
}

/// The firmware's log, its `MEAS` record lines counted instead of shown.
fn print_firmware_log(log_lines: &[String]) {
    let mut batches = 0usize;
    for l in log_lines {
        if l.contains("MEAS ") {
            batches += 1;
        } else {
            println!("  firmware: {l}");
        }
    }
    if batches > 0 {
        println!("  firmware: … {batches} `MEAS` record lines (not shown)");
    }
}

/// Measurement mode: the dataset folder from the link (streamed programme) or from the
/// firmware's own record, checked against the link (local); returns the summary's line.
fn write_measurement(run: &HilRun, b: &Bridged, log_lines: &[String]) -> Result<String> {
    if let Some((programme, dir)) = &run.measure {
        if b.exit == 0 && run.measure_ticks.is_none() {
            write_dataset(programme, &b.rows, dir)?;
            println!("  wrote the dataset folder {}", dir.display());
        }
    }
    let Some(dir) = &run.measure_local else {
        return Ok(String::new());
    };
    ensure!(b.exit == 0, "local measurement: firmware exit {}", b.exit);
    let record = crate::record::parse(log_lines).context("the firmware's record")?;
    let checked = check_record_against_link(&record, &b.rows)?;
    crate::record::write_dataset(&record, dir)?;
    Ok(format!(
        "  record (defmt MEAS lines, as the NUCLEO streams over RTT): {} experiments, {checked} ticks, each identical to its command frame; dataset folder {}\n",
        record.experiments.len(),
        dir.display()
    ))
}

/// Command frames, conditioning ticks and the tracking interrupts' instructions (min, median,
/// max; the conditioning ticks skip the inverse).
fn interrupt_costs(b: &Bridged) -> Result<(usize, usize, (f64, f64, f64))> {
    let commands = b.rows.iter().filter(|r| r.command.is_some()).count();
    let instructions: Vec<f64> = b
        .rows
        .iter()
        .filter_map(|r| r.command)
        .filter(|c| c.flags & CommandFlags::CONDITIONING == 0)
        .map(|c| c.aux as f64)
        .collect();
    let conditioning_ticks = commands - instructions.len();
    ensure!(
        !instructions.is_empty(),
        "no tracking command came back from the firmware (exit {})",
        b.exit
    );
    Ok((commands, conditioning_ticks, stats(instructions)))
}

/// The run's summary lines (`summary.txt`).
fn summary(
    run: &HilRun,
    ticks: u32,
    b: &Bridged,
    commands: usize,
    conditioning_ticks: usize,
    instr: (f64, f64, f64),
    tracking: Option<(f64, f64, &'static str)>,
) -> Result<String> {
    let mut s = String::new();
    writeln!(
        s,
        "hil: plant {}, {}{}",
        run.plant_cmd.clone().unwrap_or_else(|| format!(
            "maglab hil-plant ({}effects: {})",
            run.plant_params
                .as_ref()
                .map(|p| format!("{}, ", p.display()))
                .unwrap_or_default(),
            if run.effects.is_empty() {
                "none".into()
            } else {
                run.effects.join("; ")
            }
        )),
        if run.measure_local.is_some() {
            format!("compiled-in measurement programme of {ticks} ticks")
        } else if run.measure.is_some() {
            format!("measurement programme of {ticks} ticks")
        } else {
            format!("{} tracking ticks, {} inverse", run.ticks, run.inverse)
        },
        run.inject
            .map(|i| format!(", injected {i:?}"))
            .unwrap_or_default()
    )?;
    writeln!(
        s,
        "  firmware exit {} (expected {}), {commands} command frames ({conditioning_ticks} start-up conditioning), plant exit {}",
        b.exit, run.expect_exit, b.plant_status
    )?;
    if run.board == Board::Nucleo {
        writeln!(
            s,
            "  control interrupt (TIM2 update, plant sample over USART2, conditioning or tracking, SPI1 DAC frame): \
             instructions not counted on netduinoplus2 (the mps2-an386 bench counts them)"
        )?;
    } else {
        writeln!(
            s,
            "  control interrupt {} instructions min {:.0} median {:.0} max {:.0}",
            if run.measure.is_some() || run.measure_local.is_some() {
                "(sample read, programme current through the limiter, DAC frame):"
            } else {
                "while tracking (sensor read, trajectory, inverse, limiter, DAC frame):"
            },
            instr.0,
            instr.1,
            instr.2
        )?;
    }
    if let Some((rms, max, on)) = tracking {
        writeln!(
            s,
            "  tracking error ({on}): RMS {rms:.3} % of peak-to-peak, max {max:.3} %"
        )?;
    }
    Ok(s)
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
