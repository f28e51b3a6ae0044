//! The bridge of the virtual bench: QEMU's UART (a TCP socket) on one side, the plant program's
//! stdin/stdout on the other, a thread each way copying whole frames, decoding them and
//! injecting link faults, and a watch that reports stalls.

use super::measurement::Programme;
use super::Inject;
use crate::frame_socket::{queued_bytes, unacknowledged_bytes, FrameSocket};
use anyhow::{bail, ensure, Context, Result};
use magctl::link::{
    received_frame_bytes, CommandFrame, EndAck, ProgrammeFrame, Sample, SampleFrame,
    COMMAND_FRAME_BYTES, KIND_COMMAND, KIND_END, MAX_RECEIVED_FRAME_BYTES,
};
use std::io::{Read, Write};
use std::net::{TcpListener, TcpStream};
use std::process::{Child, ChildStdin, ChildStdout};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// How long QEMU may take to connect its UART.
const CONNECT_TIMEOUT: Duration = Duration::from_secs(30);

/// Waits for QEMU (`qemu`, started at `started`) to connect its UART to `listener`.
pub(super) fn accept_qemu(
    listener: &TcpListener,
    qemu: &mut Child,
    started: Instant,
) -> Result<TcpStream> {
    listener.set_nonblocking(true)?;
    let socket = loop {
        match listener.accept() {
            Ok((s, _)) => break s,
            Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {
                if started.elapsed() > CONNECT_TIMEOUT {
                    let _ = qemu.kill();
                    bail!("QEMU did not connect its UART within {CONNECT_TIMEOUT:?}");
                }
                if let Some(status) = qemu.try_wait()? {
                    bail!("QEMU ended ({status}) before connecting its UART");
                }
                std::thread::sleep(Duration::from_millis(5));
            }
            Err(e) => return Err(e).context("accepting QEMU's connection"),
        }
    };
    socket.set_nonblocking(false)?;
    socket.set_nodelay(true)?;
    Ok(socket)
}

/// What the bridge threads collect.
#[derive(Default)]
pub(super) struct Collected {
    /// The firmware's command frames, in tick order (the k-th `C` frame is tick k's).
    pub commands: Mutex<Vec<CommandFrame>>,
    /// The plant's sample frames as forwarded (faults injected), in tick order.
    pub samples: Mutex<Vec<SampleFrame>>,
}

/// Firmware → plant: copies every frame, decodes the command frames and acknowledges `E`.
/// Ends with the reader, whose counts the run reports.
pub(super) fn firmware_to_plant(
    mut from: FrameSocket,
    mut to: ChildStdin,
    to_firmware: Arc<Mutex<TcpStream>>,
    collected: Arc<Collected>,
    activity: Arc<LinkActivity>,
) -> std::thread::JoinHandle<Result<FrameSocket>> {
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
                collected
                    .commands
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
}

/// Plant → firmware: copies every sample frame (8 bytes, or 12 with the coil current: the kind
/// byte says which), injects `inject`, and in measurement mode sends the programme's current of
/// each tick first.
pub(super) fn plant_to_firmware(
    mut from: ChildStdout,
    to: Arc<Mutex<TcpStream>>,
    inject: Option<Inject>,
    programme: Option<Arc<Programme>>,
    collected: Arc<Collected>,
    activity: Arc<LinkActivity>,
) -> std::thread::JoinHandle<Result<()>> {
    std::thread::spawn(move || -> Result<()> {
        let mut buf = [0u8; MAX_RECEIVED_FRAME_BYTES];
        let mut tick: u32 = 0;
        loop {
            activity.reading_plant.store(true, Ordering::Release);
            let n = read_full(&mut from, &mut buf[..2])?;
            let len = received_frame_bytes(buf[1]);
            let rest = if n == 2 && len > 2 {
                read_full(&mut from, &mut buf[2..len])?
            } else {
                0
            };
            activity.reading_plant.store(false, Ordering::Release);
            if n == 0 {
                return Ok(());
            }
            ensure!(
                rest + 2 == len,
                "plant sent a bad frame at tick {tick}: kind byte {:#04x} ({} bytes read)",
                buf[1],
                n + rest
            );
            activity.plant_frames.fetch_add(1, Ordering::AcqRel);
            let mut frame = SampleFrame::decode(&buf[..len], tick as u16)
                .map_err(|e| anyhow::anyhow!("plant sent a bad frame at tick {tick}: {e:?}"))?;
            let mut bytes = buf[..len].to_vec();
            match inject {
                Some(Inject::Silent(at)) if tick >= at => {
                    // Keep reading so the plant is not blocked, forward nothing.
                    tick += 1;
                    continue;
                }
                Some(Inject::Nan(at)) if tick == at => {
                    frame.sample = Sample::Metres(f32::NAN);
                    bytes = frame.encode().as_slice().to_vec();
                }
                Some(Inject::Range(at)) if tick == at => {
                    frame.sample = Sample::Count(u32::MAX);
                    bytes = frame.encode().as_slice().to_vec();
                }
                Some(Inject::Garbage(at)) if tick == at => bytes[0] = 0x00,
                _ => {}
            }
            collected
                .samples
                .lock()
                .map_err(|_| anyhow::anyhow!("poisoned"))?
                .push(frame);
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
}

/// What the bridge threads are doing, for the stall report ([`watch_stalls`]).
#[derive(Default)]
pub(super) struct LinkActivity {
    /// Command frames (any kind) read from QEMU's socket.
    firmware_frames: AtomicUsize,
    /// Sample frames read from the plant program.
    plant_frames: AtomicUsize,
    /// The firmware → plant thread is waiting to read QEMU's socket.
    reading_firmware: AtomicBool,
    /// The plant → firmware thread is waiting to read the plant's stdout.
    reading_plant: AtomicBool,
    /// The run is over (QEMU has exited).
    pub done: AtomicBool,
}

/// How long the link may carry no frame in either direction before the bridge reports where
/// the bytes are (the firmware's own bound, `MAX_LINK_POLLS`, is about 3 s of host time).
const STALL_REPORT: Duration = Duration::from_millis(500);

/// Watches the bridge while QEMU runs; when no frame has moved for [`STALL_REPORT`], records
/// one line per stall (and how long it lasted): the frame counts, which bridge thread waits to
/// read, and the bytes queued in QEMU's socket both ways (received and not read by the bridge;
/// written by the bridge and not acknowledged by QEMU's end). A stall with a frame's bytes
/// unread in the socket is the host's, not QEMU's. A stall where the run means one (a plant that takes seconds to start, an injected
/// silent link) is reported the same way.
pub(super) fn watch_stalls(
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
pub(super) fn read_full(from: &mut impl Read, buf: &mut [u8]) -> Result<usize> {
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

pub(super) fn wait_with_timeout(
    child: &mut std::process::Child,
    limit: Duration,
) -> Result<String> {
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
