//! One lock-step run ([`run_once`]): the plant program and QEMU started, bridged until the
//! firmware exits, and what the link carried turned into `link.csv`, the measurement's dataset
//! folder and `summary.txt`.

use super::bridge::{self, Collected, LinkActivity};
use super::link_log::{self, tracking_error, write_link_csv, TickRow};
use super::measurement::{check_record_against_link, local_programme_ticks, write_dataset};
use super::{Board, HilResult, HilRun};
use crate::frame_socket::{FrameSocket, WAKE_BOUND};
use crate::qemu::firmware::decode_defmt;
use crate::qemu::instructions::stats;
use crate::qemu::machine::{netduino_command, qemu_command};
use crate::util::{display, Ctx};
use anyhow::{ensure, Context, Result};
use magctl::inverse::CommandFlags;
use magctl::link::COMMAND_FRAME_BYTES;
use std::fmt::Write as _;
use std::net::TcpListener;
use std::path::Path;
use std::process::{Command, Stdio};
use std::sync::atomic::Ordering;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// QEMU's wall-clock limit for one run, s.
const QEMU_TIMEOUT_S: &str = "300";

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
