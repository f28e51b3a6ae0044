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

use crate::frame_socket::{queued_bytes, unacknowledged_bytes, FrameSocket, WAKE_BOUND};
use crate::qemu::{build_bin, decode_defmt, firmware_dir, qemu_command, stats, TARGET};
use crate::util::{display, run_checked, Ctx};
use anyhow::{bail, ensure, Context, Result};
use magctl::inverse::CommandFlags;
use magctl::link::{
    CommandFrame, EndAck, ProgrammeFrame, Sample, SampleFrame, COMMAND_FRAME_BYTES, KIND_COMMAND,
    KIND_END, SAMPLE_FRAME_BYTES,
};
use magctl::params::BAKED_PARAMETERS;
use magctl::sensor::SensorScale;
use std::fmt::Write as _;
use std::io::{Read, Write};
use std::net::TcpListener;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// QEMU's wall-clock limit for one run, s.
const QEMU_TIMEOUT_S: &str = "300";
/// How long the bridge waits for QEMU to connect.
const CONNECT_TIMEOUT: Duration = Duration::from_secs(30);
/// Header of `link.csv`.
pub const LINK_CSV_HEADER: &str =
    "tick,sample_kind,sample_raw,sample_m,current_a,desired_m,flags,instructions";

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

/// One run's settings.
#[derive(Debug, Clone)]
pub struct HilRun {
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
}

#[derive(Debug, Clone, Copy, Default)]
struct TickRow {
    sample: Option<Sample>,
    command: Option<CommandFrame>,
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

/// Builds the HIL firmware and returns its ELF.
pub fn firmware(ctx: &Ctx) -> Result<PathBuf> {
    run_checked(build_bin(
        ctx,
        "firmware-hil",
        "board-mps2-an386,panic-never",
    ))?;
    Ok(firmware_dir(ctx)
        .join(TARGET)
        .join("release")
        .join("firmware-hil"))
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
    let mut plant = match &run.plant_cmd {
        Some(cmd) => {
            let mut c = Command::new("sh");
            c.args(["-c", cmd]).current_dir(&ctx.root);
            c
        }
        None => {
            let exe = maglab_exe.context("the default plant needs maglab")?;
            let mut c = Command::new(exe);
            c.arg("hil-plant").arg("--log").arg(&plant_log);
            if let Some(p) = &run.plant_params {
                c.arg("--params").arg(ctx.root.join(p));
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
            c.current_dir(&ctx.root);
            c
        }
    };
    println!("$ {}", display(&plant));
    let listener = TcpListener::bind("127.0.0.1:0").context("cannot open a local TCP port")?;
    let port = listener.local_addr()?.port();
    let elf = run.elf.as_deref().unwrap_or(elf);
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
    let mut qemu = qemu_command(
        QEMU_TIMEOUT_S,
        &format!("tcp:127.0.0.1:{port},nodelay=on"),
        &semi,
        elf,
    );
    qemu.current_dir(&out_abs)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    println!("$ {}", display(&qemu));
    let started = Instant::now();
    let mut qemu_child = qemu.spawn().context("cannot start qemu-system-arm")?;
    listener.set_nonblocking(true)?;
    let socket = loop {
        match listener.accept() {
            Ok((s, _)) => break s,
            Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {
                if started.elapsed() > CONNECT_TIMEOUT {
                    let _ = qemu_child.kill();
                    bail!("QEMU did not connect its UART within {CONNECT_TIMEOUT:?}");
                }
                if let Some(status) = qemu_child.try_wait()? {
                    bail!("QEMU ended ({status}) before connecting its UART");
                }
                std::thread::sleep(Duration::from_millis(5));
            }
            Err(e) => return Err(e).context("accepting QEMU's connection"),
        }
    };
    socket.set_nonblocking(false)?;
    socket.set_nodelay(true)?;
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
    let commands: Arc<Mutex<Vec<CommandFrame>>> = Arc::new(Mutex::new(Vec::new()));
    let samples: Arc<Mutex<Vec<Sample>>> = Arc::new(Mutex::new(Vec::new()));
    let activity = Arc::new(LinkActivity::default());
    let stalls = watch_stalls(activity.clone(), socket.try_clone()?, started);

    // Firmware → plant: copy, decode the command frames (the k-th `C` frame is tick k's).
    let fw_to_plant = {
        let mut from = FrameSocket::new(socket, COMMAND_FRAME_BYTES)?;
        let commands = commands.clone();
        let to_firmware = to_firmware.clone();
        let mut to = plant_in;
        let activity = activity.clone();
        // Ends with the reader, whose counts the run reports.
        std::thread::spawn(move || -> Result<FrameSocket> {
            let mut buf = [0u8; COMMAND_FRAME_BYTES];
            loop {
                activity.reading_firmware.store(true, Ordering::Release);
                let n = from.read_frame(&mut buf)?;
                activity.reading_firmware.store(false, Ordering::Release);
                if n == 0 {
                    return Ok(from);
                }
                activity.firmware_frames.fetch_add(1, Ordering::AcqRel);
                let frame = CommandFrame::decode(&buf)
                    .map_err(|e| anyhow::anyhow!("firmware sent a bad frame: {e:?}"))?;
                if frame.kind == KIND_COMMAND {
                    commands
                        .lock()
                        .map_err(|_| anyhow::anyhow!("poisoned"))?
                        .push(frame);
                }
                // The plant may already be gone after a fault: ignore write errors.
                let _ = to.write_all(&buf).and_then(|_| to.flush());
                if frame.kind == KIND_END {
                    // Everything the firmware sent has been read: it may exit (its `end`).
                    let ack = EndAck {
                        seq: frame.seq,
                        status: frame.aux,
                    };
                    let _ = to_firmware
                        .lock()
                        .map_err(|_| anyhow::anyhow!("poisoned"))?
                        .write_all(&ack.encode());
                    return Ok(from);
                }
            }
        })
    };
    // Plant → firmware: copy, decode the sample frames, inject faults.
    let plant_to_fw = {
        let to = to_firmware;
        let samples = samples.clone();
        let mut from = plant_out;
        let inject = run.inject;
        let programme = run.measure.as_ref().map(|(p, _)| p.clone());
        let activity = activity.clone();
        std::thread::spawn(move || -> Result<()> {
            let mut buf = [0u8; SAMPLE_FRAME_BYTES];
            let mut tick: u32 = 0;
            loop {
                activity.reading_plant.store(true, Ordering::Release);
                let n = read_full(&mut from, &mut buf)?;
                activity.reading_plant.store(false, Ordering::Release);
                if n == 0 {
                    return Ok(());
                }
                activity.plant_frames.fetch_add(1, Ordering::AcqRel);
                let mut frame = SampleFrame::decode(&buf, tick as u16)
                    .map_err(|e| anyhow::anyhow!("plant sent a bad frame at tick {tick}: {e:?}"))?;
                let mut bytes = buf;
                match inject {
                    Some(Inject::Silent(at)) if tick >= at => {
                        // Keep reading so the plant is not blocked, forward nothing.
                        tick += 1;
                        continue;
                    }
                    Some(Inject::Nan(at)) if tick == at => {
                        frame.sample = Sample::Metres(f32::NAN);
                        bytes = frame.encode();
                    }
                    Some(Inject::Range(at)) if tick == at => {
                        frame.sample = Sample::Count(u32::MAX);
                        bytes = frame.encode();
                    }
                    Some(Inject::Garbage(at)) if tick == at => bytes[0] = 0x00,
                    _ => {}
                }
                samples
                    .lock()
                    .map_err(|_| anyhow::anyhow!("poisoned"))?
                    .push(frame.sample);
                let mut w = to.lock().map_err(|_| anyhow::anyhow!("poisoned"))?;
                if let Some(p) = &programme {
                    // Measurement mode: the programme's current of this tick goes first.
                    let current_a = p.current_a.get(tick as usize).copied().unwrap_or(0.0);
                    let r = ProgrammeFrame {
                        seq: tick as u16,
                        current_a,
                    };
                    if w.write_all(&r.encode()).is_err() {
                        return Ok(());
                    }
                }
                if w.write_all(&bytes).is_err() {
                    return Ok(());
                }
                tick += 1;
            }
        })
    };

    let output = qemu_child.wait_with_output().context("waiting for QEMU")?;
    let wall_s = started.elapsed().as_secs_f64();
    let exit = output.status.code().unwrap_or(-1);
    activity.done.store(true, Ordering::Release);
    let stall_lines = stalls
        .join()
        .map_err(|_| anyhow::anyhow!("stall watch thread panicked"))?;
    // QEMU is gone: its socket end is closed, the bridge threads see EOF.
    let fw_result = fw_to_plant
        .join()
        .map_err(|_| anyhow::anyhow!("bridge thread panicked"))?;
    let plant_status = wait_with_timeout(&mut plant_child, Duration::from_secs(20))?;
    let _ = plant_to_fw.join();
    let frames = fw_result?;

    let log_lines = decode_defmt(&std::fs::read(elf)?, &output.stdout).unwrap_or_default();
    let mut batches = 0usize;
    for l in &log_lines {
        if l.contains("MEAS ") {
            batches += 1;
        } else {
            println!("  firmware: {l}");
        }
    }
    if batches > 0 {
        println!("  firmware: … {batches} `MEAS` record lines (not shown)");
    }
    // The link's report, printed here (a run that fails below still shows it) and kept in
    // `summary.txt`.
    let mut link_report = String::new();
    if frames.split_frames > 0 {
        writeln!(
            link_report,
            "  link: {} command frame(s) read in parts (a wake-up before the whole frame was there)",
            frames.split_frames
        )?;
    }
    if frames.missed_wakes > 0 {
        writeln!(
            link_report,
            "  link: {} command frame(s) found queued without a wake-up, taken after the bridge's {} ms bound",
            frames.missed_wakes,
            WAKE_BOUND.as_millis()
        )?;
    }
    for l in &stall_lines {
        writeln!(link_report, "{l}")?;
    }
    print!("{link_report}");
    let stderr = String::from_utf8_lossy(&output.stderr);
    if !stderr.trim().is_empty() {
        println!("  qemu stderr: {}", stderr.trim());
    }
    let rows: Vec<TickRow> = {
        let c = commands.lock().map_err(|_| anyhow::anyhow!("poisoned"))?;
        let sm = samples.lock().map_err(|_| anyhow::anyhow!("poisoned"))?;
        (0..c.len().max(sm.len()))
            .map(|k| TickRow {
                sample: sm.get(k).copied(),
                command: c.get(k).copied(),
            })
            .collect()
    };
    write_link_csv(&out_abs.join("link.csv"), &rows)?;
    if let Some((programme, dir)) = &run.measure {
        if exit == 0 && run.measure_ticks.is_none() {
            write_dataset(programme, &rows, dir)?;
            println!("  wrote the dataset folder {}", dir.display());
        }
    }
    let mut record_line = String::new();
    if let Some(dir) = &run.measure_local {
        ensure!(exit == 0, "local measurement: firmware exit {exit}");
        let record = crate::record::parse(&log_lines).context("the firmware's record")?;
        let checked = check_record_against_link(&record, &rows)?;
        crate::record::write_dataset(&record, dir)?;
        record_line = format!(
            "  record (defmt MEAS lines, as the NUCLEO streams over RTT): {} experiments, {checked} ticks, each identical to its command frame; dataset folder {}\n",
            record.experiments.len(),
            dir.display()
        );
    }

    let commands = rows.iter().filter(|r| r.command.is_some()).count();
    // Tracking interrupts only (the conditioning ticks skip the inverse).
    let instructions: Vec<f64> = rows
        .iter()
        .filter_map(|r| r.command)
        .filter(|c| c.flags & CommandFlags::CONDITIONING == 0)
        .map(|c| c.aux as f64)
        .collect();
    let conditioning_ticks = commands - instructions.len();
    ensure!(
        !instructions.is_empty(),
        "no tracking command came back from the firmware (exit {exit})"
    );
    let instr = stats(instructions);
    let tracking = tracking_error(&plant_log, &rows)?;

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
        "  firmware exit {exit} (expected {}), {commands} command frames ({conditioning_ticks} start-up conditioning), plant exit {plant_status}",
        run.expect_exit
    )?;
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
    if let Some((rms, max, on)) = tracking {
        writeln!(
            s,
            "  tracking error ({on}): RMS {rms:.3} % of peak-to-peak, max {max:.3} %"
        )?;
    }
    s.push_str(&record_line);
    writeln!(s, "  wall time {wall_s:.1} s")?;
    print!("{s}");
    s.push_str(&link_report);
    std::fs::write(out_abs.join("summary.txt"), &s)?;
    ensure!(
        exit == run.expect_exit,
        "firmware exit status {exit}, expected {}",
        run.expect_exit
    );
    Ok(HilResult {
        commands,
        tracking,
        wall_s,
        summary: s,
        frames: rows.iter().filter_map(|r| r.command).collect(),
    })
}

/// What the bridge threads are doing, for the stall report ([`watch_stalls`]).
#[derive(Default)]
struct LinkActivity {
    /// Command frames (any kind) read from QEMU's socket.
    firmware_frames: AtomicUsize,
    /// Sample frames read from the plant program.
    plant_frames: AtomicUsize,
    /// The firmware → plant thread is waiting to read QEMU's socket.
    reading_firmware: AtomicBool,
    /// The plant → firmware thread is waiting to read the plant's stdout.
    reading_plant: AtomicBool,
    /// The run is over (QEMU has exited).
    done: AtomicBool,
}

/// How long the link may carry no frame in either direction before the bridge reports where
/// the bytes are (the firmware's own bound, `MAX_LINK_POLLS`, is about 3 s of host time).
const STALL_REPORT: Duration = Duration::from_millis(500);

/// Watches the bridge while QEMU runs; when no frame has moved for [`STALL_REPORT`], records
/// one line per stall (and how long it lasted): the frame counts, which bridge thread waits to
/// read, and the bytes queued in QEMU's socket both ways (received and not read by the bridge;
/// written by the bridge and not acknowledged by QEMU's end). A stall with a frame's bytes
/// unread in the socket is the host's, not QEMU's (how the flake `frame_socket` fixes was
/// found). A stall where the run means one (a plant that takes seconds to start, an injected
/// silent link) is reported the same way.
fn watch_stalls(
    activity: Arc<LinkActivity>,
    socket: std::net::TcpStream,
    started: Instant,
) -> std::thread::JoinHandle<Vec<String>> {
    std::thread::spawn(move || {
        let mut reports = Vec::new();
        let mut last = (usize::MAX, usize::MAX);
        let mut since = Instant::now();
        let mut reported = false;
        while !activity.done.load(Ordering::Acquire) {
            std::thread::sleep(Duration::from_millis(50));
            let now = (
                activity.firmware_frames.load(Ordering::Acquire),
                activity.plant_frames.load(Ordering::Acquire),
            );
            if now != last {
                if reported {
                    reports.push(format!(
                        "    resumed after {:.2} s",
                        since.elapsed().as_secs_f64()
                    ));
                }
                last = now;
                since = Instant::now();
                reported = false;
                continue;
            }
            if reported || since.elapsed() < STALL_REPORT {
                continue;
            }
            reported = true;
            let (unread, unsent) = (queued_bytes(&socket), unacknowledged_bytes(&socket));
            reports.push(format!(
                "  link stall at {:.2} s: no frame for {:.1} s after {} frames from the firmware and {} from the plant; bridge waiting to read: firmware {}, plant {}; QEMU's socket: {} bytes received and unread, {} bytes sent and unacknowledged",
                started.elapsed().as_secs_f64(),
                since.elapsed().as_secs_f64(),
                now.0,
                now.1,
                activity.reading_firmware.load(Ordering::Acquire),
                activity.reading_plant.load(Ordering::Acquire),
                unread.map_or("?".into(), |n| n.to_string()),
                unsent.map_or("?".into(), |n| n.to_string()),
            ));
        }
        reports
    })
}

/// Reads exactly `buf.len()` bytes; 0 at a clean end of stream.
fn read_full(from: &mut impl Read, buf: &mut [u8]) -> Result<usize> {
    let mut got = 0;
    while got < buf.len() {
        match from.read(&mut buf[got..]) {
            Ok(0) if got == 0 => return Ok(0),
            Ok(0) => bail!(
                "stream closed inside a frame ({got} of {} bytes)",
                buf.len()
            ),
            Ok(n) => got += n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) if e.kind() == std::io::ErrorKind::ConnectionReset => return Ok(0),
            Err(e) => return Err(e.into()),
        }
    }
    Ok(got)
}

fn wait_with_timeout(child: &mut std::process::Child, limit: Duration) -> Result<String> {
    let t0 = Instant::now();
    loop {
        if let Some(status) = child.try_wait()? {
            return Ok(status.code().map_or("signal".into(), |c| c.to_string()));
        }
        if t0.elapsed() > limit {
            let _ = child.kill();
            let _ = child.wait();
            return Ok("killed (did not end)".into());
        }
        std::thread::sleep(Duration::from_millis(10));
    }
}

fn sample_m(scale: &SensorScale, s: Sample) -> f64 {
    match s {
        Sample::Count(c) => scale.displacement_m(c).map_or(f64::NAN, |m| m as f64),
        Sample::Metres(m) => m as f64,
    }
}

fn write_link_csv(path: &Path, rows: &[TickRow]) -> Result<()> {
    let scale = SensorScale::new(&BAKED_PARAMETERS.sensor);
    let mut f = std::io::BufWriter::new(
        std::fs::File::create(path).with_context(|| format!("cannot write {}", path.display()))?,
    );
    writeln!(f, "{LINK_CSV_HEADER}")?;
    for (k, r) in rows.iter().enumerate() {
        let (kind, raw, m) = match r.sample {
            Some(s @ Sample::Count(c)) => ("S", c.to_string(), sample_m(&scale, s)),
            Some(s @ Sample::Metres(v)) => ("M", format!("{v:e}"), sample_m(&scale, s)),
            None => ("", String::new(), f64::NAN),
        };
        let (i, d, fl, ins) = match r.command {
            Some(c) => (
                format!("{:e}", c.value),
                format!("{:e}", c.desired_m),
                c.flags.to_string(),
                c.aux.to_string(),
            ),
            None => Default::default(),
        };
        writeln!(f, "{k},{kind},{raw},{m:e},{i},{d},{fl},{ins}")?;
    }
    f.flush()?;
    Ok(())
}

/// RMS and max |y − ȳ| in % of ȳ's peak-to-peak over the tracking ticks (conditioning excluded): the plant's true
/// displacement from its log when present, the next tick's sensor reading otherwise.
fn tracking_error(plant_log: &Path, rows: &[TickRow]) -> Result<Option<(f64, f64, &'static str)>> {
    let mut pairs: Vec<(f64, f64)> = Vec::new();
    let on;
    if plant_log.exists() {
        on = "true displacement, plant log";
        let text = std::fs::read_to_string(plant_log)?;
        for (n, line) in text.lines().enumerate().skip(1) {
            let cols: Vec<&str> = line.split(',').collect();
            ensure!(
                cols.len() == 9,
                "{}: line {}: expected 9 columns",
                plant_log.display(),
                n + 1
            );
            let desired: f64 = cols[3].parse().with_context(|| format!("line {}", n + 1))?;
            let y: f64 = cols[4].parse().with_context(|| format!("line {}", n + 1))?;
            let flags: u8 = cols[7].parse().with_context(|| format!("line {}", n + 1))?;
            if flags & (CommandFlags::CONDITIONING | CommandFlags::MEASURE) == 0 {
                pairs.push((desired, y));
            }
        }
    } else {
        on = "sensor reading at the period's end";
        let scale = SensorScale::new(&BAKED_PARAMETERS.sensor);
        for w in rows.windows(2) {
            if let (Some(c), Some(s)) = (w[0].command, w[1].sample) {
                if c.flags & (CommandFlags::CONDITIONING | CommandFlags::MEASURE) != 0 {
                    continue;
                }
                let y = sample_m(&scale, s);
                if y.is_finite() {
                    pairs.push((c.desired_m as f64, y));
                }
            }
        }
    }
    if pairs.len() < 2 {
        return Ok(None);
    }
    let (lo, hi) = pairs
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), p| {
            (l.min(p.0), h.max(p.0))
        });
    let p2p = hi - lo;
    let n = pairs.len() as f64;
    let rms = (pairs.iter().map(|(d, y)| (y - d).powi(2)).sum::<f64>() / n).sqrt();
    let max = pairs.iter().map(|(d, y)| (y - d).abs()).fold(0.0, f64::max);
    Ok(Some((100.0 * rms / p2p, 100.0 * max / p2p, on)))
}

/// An identification programme: every tick's current and the experiments it records.
#[derive(Debug, Clone, PartialEq)]
pub struct Programme {
    /// Current of every tick, A (conditioning included).
    pub current_a: Vec<f32>,
    /// Recorded experiments: file stem, description, first tick, ticks.
    pub experiments: Vec<(String, String, usize, usize)>,
}

/// The identification programme `maglab identify` needs, built from the *nominal* (baked)
/// parameters — all a bench user knows before identifying — by the core's generator
/// (`magctl::programme`, the one the firmware plays itself in `mode=measure-local` and on the
/// NUCLEO measurement image): the FORC sweep (reversals on every grid line, 5 % beyond the grid,
/// clipped to the current limit by the firmware's limiter) and biased sines, each experiment
/// preceded by the start-up conditioning sequence (negative saturation, then slowly to its first
/// current — the start state `negative-saturation` of `dataset.json`).
pub fn identification_programme() -> Result<Programme> {
    let programme = core_programme()?;
    let mut prog = Programme {
        current_a: Vec::new(),
        experiments: Vec::new(),
    };
    let mut state = programme.start(0.0);
    while let Some(t) = programme.step(&mut state) {
        if t.sample == Some(0) {
            let e = programme
                .experiment(t.experiment)
                .context("the programme's experiment table")?;
            let (kind, a, b, c) = e.kind.fields();
            let described = crate::record::RecordedExperiment {
                kind: kind.to_string(),
                values: [a as f64, b as f64, c as f64],
                ticks: e.ticks as usize,
                samples: Vec::new(),
            };
            prog.experiments.push((
                described.name(t.experiment),
                described.description(),
                prog.current_a.len(),
                e.ticks as usize,
            ));
        }
        prog.current_a.push(t.current_a);
    }
    Ok(prog)
}

/// The core's identification programme for the baked parameters.
fn core_programme() -> Result<magctl::programme::IdentificationProgramme> {
    let p = &BAKED_PARAMETERS;
    let measure = &magctl::params::BAKED_MEASURE;
    let limiter = magctl::inverse::OutputLimiter::new(&p.control)
        .map_err(|e| anyhow::anyhow!("control settings: {e:?}"))?;
    magctl::programme::IdentificationProgramme::new(
        &limiter,
        p.actuator.coil_factor_per_m,
        measure.h_min_a_per_m(),
        measure.h_max_a_per_m(),
        p.control.sample_rate_hz,
    )
    .map_err(|e| anyhow::anyhow!("identification programme: {e:?}"))
}

/// Ticks of a local measurement run: the programme, then the ramp to 0 A (as firmware-hil
/// counts them).
fn local_programme_ticks() -> Result<u32> {
    let limiter = magctl::inverse::OutputLimiter::new(&BAKED_PARAMETERS.control)
        .map_err(|e| anyhow::anyhow!("control settings: {e:?}"))?;
    let ramp = (limiter.limit_a() / limiter.max_step_a()).ceil() as u32 + 2;
    Ok(core_programme()?.total_ticks(0.0) + ramp)
}

/// Checks every tick of the firmware's record against the command frame of the same tick
/// (bit for bit: the current applied, the reading, the flags); returns the ticks checked.
fn check_record_against_link(record: &crate::record::Record, rows: &[TickRow]) -> Result<usize> {
    let programme = core_programme()?;
    let mut state = programme.start(0.0);
    let mut tick = 0usize;
    let mut checked = 0usize;
    while let Some(t) = programme.step(&mut state) {
        if let Some(k) = t.sample {
            let s = record
                .experiments
                .get(t.experiment)
                .and_then(|e| e.samples.get(k as usize))
                .copied()
                .flatten()
                .with_context(|| format!("record: experiment {} tick {k} missing", t.experiment))?;
            let c = rows
                .get(tick)
                .and_then(|r| r.command)
                .with_context(|| format!("no command frame for tick {tick}"))?;
            ensure!(
                s.current_a.to_bits() == c.value.to_bits()
                    && s.reading_m.to_bits() == c.desired_m.to_bits()
                    && s.flags == c.flags,
                "tick {tick} (experiment {} tick {k}): record ({} A, {} m, flags {}) differs from the link ({} A, {} m, flags {})",
                t.experiment,
                s.current_a,
                s.reading_m,
                s.flags,
                c.value,
                c.desired_m,
                c.flags
            );
            checked += 1;
        }
        tick += 1;
    }
    Ok(checked)
}

/// Writes the dataset folder of a measurement run: one `t_s,current_a,displacement_m` file per
/// experiment (the current the firmware applied and its reading of the tick's sample) and
/// `dataset.json` (start state `negative-saturation`, the excitation of each file).
fn write_dataset(programme: &Programme, rows: &[TickRow], dir: &Path) -> Result<()> {
    use maglab_dataset::dataset_info::{DatasetInfo, FileInfo, StartState};
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let rate_hz = BAKED_PARAMETERS.control.sample_rate_hz as f64;
    let mut info = DatasetInfo {
        start_state: Some(StartState::NegativeSaturation),
        files: Default::default(),
    };
    for (name, description, start, len) in &programme.experiments {
        let mut t = Vec::with_capacity(*len);
        let mut i = Vec::with_capacity(*len);
        let mut y = Vec::with_capacity(*len);
        for k in 0..*len {
            let c = rows
                .get(start + k)
                .and_then(|r| r.command)
                .with_context(|| format!("{name}: no command frame for tick {}", start + k))?;
            ensure!(
                c.flags & CommandFlags::MEASURE != 0 && c.desired_m.is_finite(),
                "{name}: tick {} has no valid reading (flags {})",
                start + k,
                c.flags
            );
            t.push(k as f64 / rate_hz);
            i.push(c.value as f64);
            y.push(c.desired_m as f64);
        }
        let file = format!("{name}.csv");
        maglab_dataset::data::write_measurement(&dir.join(&file), &t, &i, &y)
            .map_err(|e| anyhow::anyhow!("{e}"))?;
        info.files.insert(
            file,
            FileInfo {
                start_state: None,
                excitation: Some(description.clone()),
            },
        );
    }
    info.write(dir).map_err(|e| anyhow::anyhow!("{e}"))?;
    Ok(())
}

/// Ticks of the streamed measurement compared with the compiled-in one in [`end_to_end`].
const STREAMED_CHECK_TICKS: u32 = 3_000;

/// Measure → identify → bake → track on a plant whose parameters are not the baked ones
/// (`host-tests/hil/other_actuator.json`: R_eddy +25 %, ξ −20 %, f0 +15 %, another Preisach
/// measure). Returns the summary lines; fails unless tracking with the identified parameters is
/// ≤ 1 % of the peak-to-peak and ≥ 5× better than with the defaults.
pub fn end_to_end(ctx: &Ctx, elf: &Path, exe: &Path, base: &Path) -> Result<String> {
    let plant = PathBuf::from("host-tests/hil/other_actuator.json");
    let data = base.join("data");
    let _ = std::fs::remove_dir_all(&data);
    let programme = Arc::new(identification_programme()?);
    // The firmware plays its compiled-in programme and logs the record as the NUCLEO
    // measurement image does (defmt `MEAS` lines); `crate::record` writes the dataset from it.
    let mut m = HilRun::new(base.join("measure"));
    m.plant_params = Some(plant.clone());
    m.measure_local = Some(data.clone());
    let r = run_once(ctx, elf, Some(exe), &m)?;
    let mut s = r.summary.clone();
    // The streamed programme (R frames, the protocol's measurement mode) drives the same
    // firmware identically: its first ticks, frame for frame.
    let mut streamed = HilRun::new(base.join("measure_streamed"));
    streamed.plant_params = Some(plant.clone());
    streamed.measure = Some((programme.clone(), base.join("unused")));
    streamed.measure_ticks = Some(STREAMED_CHECK_TICKS);
    let r2 = run_once(ctx, elf, Some(exe), &streamed)?;
    let n = STREAMED_CHECK_TICKS as usize;
    ensure!(
        r2.frames.len() >= n && r.frames.len() >= n,
        "streamed check: {} / {} frames",
        r2.frames.len(),
        r.frames.len()
    );
    for (k, (a, b)) in r.frames.iter().zip(&r2.frames).take(n).enumerate() {
        ensure!(
            a.value.to_bits() == b.value.to_bits()
                && a.desired_m.to_bits() == b.desired_m.to_bits()
                && a.flags == b.flags,
            "tick {k}: the compiled-in programme commands {} A (reading {} m), the streamed one {} A ({} m)",
            a.value,
            a.desired_m,
            b.value,
            b.desired_m
        );
    }
    writeln!(
        s,
        "  streamed programme (R frames): its first {n} ticks command the same currents and read the same samples, bit for bit"
    )?;
    let identified = base.join("identified.json");
    let started = Instant::now();
    let mut id = Command::new(exe);
    id.arg("identify")
        .arg(&data)
        .arg("-o")
        .arg(&identified)
        .arg("--params")
        .arg(ctx.root.join("params/actuator.json"))
        .arg("--plot-dir")
        .arg(base.join("plots"))
        .current_dir(&ctx.root);
    run_checked(id)?;
    let identify_s = started.elapsed().as_secs_f64();
    let json: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&identified)?)?;
    let truth: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(ctx.root.join(&plant))?)?;
    let nominal: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(
        ctx.root.join("params/actuator.json"),
    )?)?;
    writeln!(
        s,
        "end to end: {} ticks measured ({} experiments), identify {identify_s:.0} s",
        programme.current_a.len(),
        programme.experiments.len()
    )?;
    writeln!(
        s,
        "  constant             nominal (baked)   plant   identified"
    )?;
    for key in ["eddy_resistance_ohm", "damping_ratio", "resonance_hz"] {
        let v = |j: &serde_json::Value| j["actuator"][key].as_f64().unwrap_or(f64::NAN);
        writeln!(
            s,
            "  {key:<20} {:>15.4} {:>7.4} {:>12.4} ({:+.1} %)",
            v(&nominal),
            v(&truth),
            v(&json),
            100.0 * (v(&json) / v(&truth) - 1.0)
        )?;
    }
    // Re-bake: the same firmware built with the identified file, in the firmware's own target
    // directory (only `magctl` recompiles: `build.rs` declares `rerun-if-env-changed`; a
    // directory of its own rebuilt every dependency, 71 s in CI), kept as a copy; then the
    // default build again, which the later runs use.
    let features = "board-mps2-an386,panic-never";
    let mut build = build_bin(ctx, "firmware-hil", features);
    build.env("ACTUATOR_PARAMS", identified.canonicalize()?);
    run_checked(build)?;
    let identified_elf = base.join("firmware-hil-identified");
    std::fs::copy(elf, &identified_elf).with_context(|| {
        format!(
            "cannot copy {} to {}",
            elf.display(),
            identified_elf.display()
        )
    })?;
    run_checked(build_bin(ctx, "firmware-hil", features))?;
    let mut rms = [0.0f64; 2];
    for (k, (name, fw)) in [("default", None), ("identified", Some(identified_elf))]
        .into_iter()
        .enumerate()
    {
        // Feedforward only: this compares the models (the feedback would hide their error).
        let mut t = HilRun::new(base.join(format!("track_{name}")));
        t.plant_params = Some(plant.clone());
        t.elf = fw.clone();
        t.feedback = false;
        let r = run_once(ctx, elf, Some(exe), &t)?;
        let (a, b, _) = r.tracking.context("no tracking error")?;
        rms[k] = a;
        writeln!(
            s,
            "  tracking on that plant, feedforward, firmware baked with the {name} parameters: RMS {a:.3} %, max {b:.2} % of peak-to-peak"
        )?;
        if let Some(fw) = fw {
            let mut t = HilRun::new(base.join("track_identified_feedback"));
            t.plant_params = Some(plant.clone());
            t.elf = Some(fw);
            let r = run_once(ctx, elf, Some(exe), &t)?;
            let (a, b, _) = r.tracking.context("no tracking error")?;
            writeln!(
                s,
                "  the same with the parameter file's feedback on: RMS {a:.3} %, max {b:.2} % of peak-to-peak (whole run, learning included)"
            )?;
        }
    }
    writeln!(
        s,
        "  default / identified (feedforward): {:.1}x",
        rms[0] / rms[1]
    )?;
    print!("{s}");
    ensure!(
        rms[1] <= 1.0,
        "identified parameters track at {:.3} % > 1 %",
        rms[1]
    );
    ensure!(
        rms[0] >= 5.0 * rms[1],
        "identified parameters only {:.1}x better than the defaults",
        rms[0] / rms[1]
    );
    Ok(s)
}

/// The runs `cargo xtask test` makes (step `hil`): the default plant for one second (exit 0,
/// tracking ≤ 1 % of the peak-to-peak on the true displacement, ≤ 30 s wall); the Python plant
/// `host-tests/hil/first_order_plant.py` speaking the protocol (exit 0), also started 5 s late;
/// conditioning vs random prior histories; measure → identify → re-bake → track
/// ([`end_to_end`]); a NaN sample (exit 7), a
/// silent link (exit 8) and a desynchronized frame (exit 8), each ending at 0 A.
pub fn check(ctx: &Ctx) -> Result<String> {
    let elf = firmware(ctx)?;
    let exe = maglab(ctx)?;
    let base = ctx.root.join("out").join("hil");
    let mut summary = String::new();

    let default = HilRun::new(base.join("default"));
    let r = run_once(ctx, &elf, Some(&exe), &default)?;
    summary.push_str(&r.summary);
    let (rms, _, _) = r
        .tracking
        .context("no tracking error from the default plant")?;
    ensure!(
        r.commands > default.ticks as usize,
        "{} commands for {} tracking ticks and the conditioning",
        r.commands,
        default.ticks
    );
    ensure!(
        r.wall_s <= 30.0,
        "1 s of control took {:.1} s of wall time",
        r.wall_s
    );
    ensure!(
        rms <= 1.0,
        "tracking RMS {rms:.3} % > 1 % on the default plant"
    );

    let mut py = HilRun::new(base.join("python"));
    py.plant_cmd =
        Some("python3 host-tests/hil/first_order_plant.py --params params/actuator.json".into());
    py.ticks = 2_000;
    let r = run_once(ctx, &elf, None, &py)?;
    summary.push_str(&r.summary);
    ensure!(
        r.commands > py.ticks as usize,
        "{} commands for {} tracking ticks and the conditioning",
        r.commands,
        py.ticks
    );

    // A plant program that takes seconds to start (an interpreter, a simulation package) gets
    // the first frame's longer allowance.
    let mut slow = HilRun::new(base.join("python_slow_start"));
    slow.plant_cmd = Some(
        "sleep 5; python3 host-tests/hil/first_order_plant.py --params params/actuator.json".into(),
    );
    slow.ticks = 200;
    let r = run_once(ctx, &elf, None, &slow)?;
    summary.push_str(&r.summary);

    // Start-up conditioning against unknown prior histories (20 random current levels within
    // ±I_max before power-up), with and without it.
    let mut table = String::from(
        "start-up conditioning vs a random prior history (20 levels), 0.3 s of feedforward tracking:\n  seed  with: RMS %  max %   without: RMS %  max %\n",
    );
    for seed in 1..=3u64 {
        let mut rms = [0.0f64; 2];
        let mut max = [0.0f64; 2];
        for (k, conditioning) in [true, false].into_iter().enumerate() {
            let mut c = HilRun::new(base.join(format!(
                "prior_{seed}_{}",
                if conditioning {
                    "conditioned"
                } else {
                    "unconditioned"
                }
            )));
            c.ticks = 3_000;
            c.prior_history = 20;
            c.seed = seed;
            c.conditioning = conditioning;
            // Feedforward only: what conditioning is for is the memory the inverse assumes.
            c.feedback = false;
            let r = run_once(ctx, &elf, Some(&exe), &c)?;
            let (a, b, _) = r.tracking.context("no tracking error")?;
            rms[k] = a;
            max[k] = b;
        }
        writeln!(
            table,
            "  {seed:>4}  {:>10.3} {:>6.2}   {:>13.3} {:>6.2}",
            rms[0], max[0], rms[1], max[1]
        )?;
        ensure!(
            rms[0] <= 1.0,
            "seed {seed}: tracking RMS {:.3} % > 1 % after conditioning",
            rms[0]
        );
    }
    print!("{table}");
    summary.push_str(&table);

    summary.push_str(&end_to_end(ctx, &elf, &exe, &base.join("e2e"))?);

    // (name, fault, exit status, feedback on, the run must end at 0 A)
    for (name, inject, exit, feedback, zero) in [
        ("nan", Inject::Nan(1_000), 7, true, false),
        ("nan_feedback_off", Inject::Nan(1_000), 7, false, true),
        ("silent", Inject::Silent(1_000), 8, true, true),
        ("garbage", Inject::Garbage(1_000), 8, true, true),
    ] {
        let mut f = HilRun::new(base.join(format!("fault_{name}")));
        f.ticks = 2_000;
        f.inject = Some(inject);
        f.expect_exit = exit;
        f.feedback = feedback;
        let r = run_once(ctx, &elf, Some(&exe), &f)?;
        summary.push_str(&r.summary);
        // The expected exit status alone would also pass a fault of the run's own before the
        // injected one (a frame lost at tick 0 once ended the silent run with exit 8 too).
        let at = match inject {
            Inject::Nan(t) | Inject::Range(t) | Inject::Silent(t) | Inject::Garbage(t) => t,
        };
        ensure!(
            r.commands >= at as usize,
            "{name}: the run ended after {} command frames, before the fault injected at tick \
             {at}: a fault of its own (a lost or late frame)",
            r.commands
        );
        let rows = std::fs::read_to_string(f.out.join("link.csv"))?;
        // The last tick the firmware commanded (a row may hold only a plant sample).
        let last = rows
            .lines()
            .rev()
            .find(|l| l.split(',').nth(4).is_some_and(|c| !c.is_empty()))
            .unwrap_or_default()
            .to_string();
        let current: f64 = last
            .split(',')
            .nth(4)
            .and_then(|c| c.parse().ok())
            .with_context(|| format!("{name}: no current in the last link row `{last}`"))?;
        if zero {
            ensure!(
                current == 0.0,
                "{name}: the last command is {current} A, not 0 A"
            );
        } else {
            // Feedback on: the loop fell back to the feedforward, which keeps driving the coil;
            // every command from the fault on carries SENSOR_FAULT | FEEDFORWARD (the firmware
            // checks that itself, exit 3 otherwise).
            let flags: u8 = last
                .split(',')
                .nth(6)
                .and_then(|c| c.parse().ok())
                .unwrap_or(0);
            ensure!(
                current != 0.0
                    && flags & (CommandFlags::SENSOR_FAULT | CommandFlags::FEEDFORWARD)
                        == CommandFlags::SENSOR_FAULT | CommandFlags::FEEDFORWARD,
                "{name}: the feedforward fallback should keep tracking, flagged: got {current} A, flags {flags}"
            );
        }
    }
    std::fs::write(base.join("summary.txt"), &summary)?;
    Ok(summary)
}

/// `cargo xtask hil [options]` (module docs).
pub fn run(ctx: &Ctx, args: &[String]) -> Result<()> {
    let mut run = HilRun::new(ctx.root.join("out").join("hil"));
    let mut it = args.iter();
    while let Some(a) = it.next() {
        let mut value = |name: &str| -> Result<String> {
            it.next()
                .cloned()
                .with_context(|| format!("{name} needs a value"))
        };
        match a.as_str() {
            "--check" => return check(ctx).map(|_| ()),
            "--plant-cmd" => run.plant_cmd = Some(value(a)?),
            "--feedback-off" => run.feedback = false,
            "--effect" => run.effects.push(value(a)?),
            "--noise-m" => {
                let v = value(a)?;
                run.noise_m = Some(v.parse().with_context(|| format!("--noise-m `{v}`"))?)
            }
            "--prior-history" => {
                let v = value(a)?;
                run.prior_history = v
                    .parse()
                    .with_context(|| format!("--prior-history `{v}`"))?
            }
            "--ticks" => {
                let v = value(a)?;
                run.ticks = v.parse().with_context(|| format!("--ticks `{v}`"))?;
                ensure!(run.ticks > 0, "--ticks must be > 0");
            }
            "--inverse" => {
                let v = value(a)?;
                ensure!(
                    v == "static" || v == "dynamic",
                    "--inverse `{v}`: static or dynamic"
                );
                run.inverse = v;
            }
            "--inject" => run.inject = Some(Inject::parse(&value(a)?)?),
            "--expect-exit" => {
                let v = value(a)?;
                run.expect_exit = v.parse().with_context(|| format!("--expect-exit `{v}`"))?
            }
            "--out" => run.out = PathBuf::from(value(a)?),
            "--no-conditioning" => run.conditioning = false,
            "--plant-params" => run.plant_params = Some(PathBuf::from(value(a)?)),
            "--measure" => {
                run.measure = Some((
                    Arc::new(identification_programme()?),
                    PathBuf::from(value(a)?),
                ))
            }
            "--measure-local" => run.measure_local = Some(PathBuf::from(value(a)?)),
            "--end-to-end" => {
                let elf = firmware(ctx)?;
                let exe = maglab(ctx)?;
                return end_to_end(ctx, &elf, &exe, &ctx.root.join("out/hil/e2e")).map(|_| ());
            }
            other => bail!("unknown option `{other}` (see `cargo xtask help`)"),
        }
    }
    if run.plant_cmd.is_some() && (!run.effects.is_empty() || run.noise_m.is_some()) {
        bail!("--effect and --noise-m configure the default plant; pass them to --plant-cmd's program instead");
    }
    let elf = firmware(ctx)?;
    let exe = if run.plant_cmd.is_none() {
        Some(maglab(ctx)?)
    } else {
        None
    };
    run_once(ctx, &elf, exe.as_deref(), &run).map(|_| ())
}
