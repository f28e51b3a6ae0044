//! Whole frames from QEMU's UART socket, one wake-up per frame, with no read that can sleep
//! past the frame's arrival.
//!
//! QEMU's UART sends each byte the firmware writes as its own TCP segment. A bridge thread
//! blocked in `read` would wake once per byte (16 wake-ups per command frame, each a context
//! switch when the lock-step shares one core with QEMU and the plant). The socket's receive
//! low-water mark (`SO_RCVLOWAT`) makes the kernel wake the reader once the frame is there.
//!
//! But a *blocking* `read` under the mark has a hole (Linux, seen on 6.18): a reader woken
//! before the mark is reached (the kernel wakes sleepers for other reasons too) copies the bytes
//! already queued and sleeps again for the rest of its request, while the kernel wakes it only
//! when the bytes it has *not copied* reach the mark — which the rest of one frame never does.
//! In lock-step nothing more comes (the firmware waits for this frame's answer), so the read
//! sleeps until QEMU exits and the firmware sees a silent link. Found as a `hil` flake: the
//! bridge blocked in `read` with 11 bytes of a frame queued and unread. `python3` reproduces the
//! hole in a dozen lines: a `recv(16)` under a mark of 16 that was woken after 5 bytes stays
//! blocked with the other 11 queued.
//!
//! [`FrameSocket::read_frame`] therefore never sleeps inside `recv`: it waits in `poll` (which
//! copies nothing, so the mark is measured against every queued byte), copies what is there
//! without waiting (`MSG_DONTWAIT`), and, if that was part of a frame, lowers the mark to the
//! bytes still missing before it polls again. The `poll` is bounded ([`WAKE_BOUND`]): a frame
//! found queued without a wake-up is taken all the same and counted, so a missed wake-up
//! makes a frame late by at most the bound, never lost.

use anyhow::{bail, Context, Result};
use std::net::TcpStream;
use std::os::fd::AsRawFd;
use std::time::Duration;

/// How long [`FrameSocket::read_frame`] sleeps in `poll` before it looks at the socket's queue
/// itself.
pub const WAKE_BOUND: Duration = Duration::from_millis(100);

/// Reads fixed-size frames from a TCP socket (see the module docs).
pub struct FrameSocket {
    socket: TcpStream,
    /// The receive low-water mark the socket has now, bytes.
    mark: usize,
    /// Frames (or their rests) found queued after [`WAKE_BOUND`] without a wake-up.
    pub missed_wakes: usize,
    /// Frames that arrived in more than one copy (a wake-up before the whole frame was there).
    pub split_frames: usize,
}

impl FrameSocket {
    /// Takes `socket` (left blocking: a clone of it may write) for frames of `frame_bytes`.
    pub fn new(socket: TcpStream, frame_bytes: usize) -> Result<Self> {
        let mut s = FrameSocket {
            socket,
            mark: 0,
            missed_wakes: 0,
            split_frames: 0,
        };
        s.set_mark(frame_bytes)?;
        Ok(s)
    }

    /// Reads one whole frame into `buf`; `Ok(0)` at a clean end of stream (or a reset) before
    /// its first byte, an error for an end inside a frame.
    pub fn read_frame(&mut self, buf: &mut [u8]) -> Result<usize> {
        let mut got = 0;
        while got < buf.len() {
            let need = buf.len() - got;
            if self.mark != need {
                self.set_mark(need)?;
            }
            self.wait_readable(need)?;
            // SAFETY: `buf[got..]` is valid writable memory of the length passed; the
            // descriptor is owned by `self.socket` for the call's duration (recv(2)).
            let n = unsafe {
                libc::recv(
                    self.socket.as_raw_fd(),
                    buf[got..].as_mut_ptr().cast(),
                    need,
                    libc::MSG_DONTWAIT,
                )
            };
            if n < 0 {
                let e = std::io::Error::last_os_error();
                match e.kind() {
                    // Readable was reported for an end or an error the next call tells; or a
                    // spurious report: poll again.
                    std::io::ErrorKind::WouldBlock | std::io::ErrorKind::Interrupted => continue,
                    std::io::ErrorKind::ConnectionReset if got == 0 => return Ok(0),
                    _ => return Err(e).context("reading QEMU's UART socket"),
                }
            }
            if n == 0 {
                if got == 0 {
                    return Ok(0);
                }
                bail!(
                    "stream closed inside a frame ({got} of {} bytes)",
                    buf.len()
                );
            }
            if got == 0 && (n as usize) < need {
                self.split_frames += 1;
            }
            got += n as usize;
        }
        Ok(got)
    }

    /// Waits until the socket is readable under the mark (or ended or failed), or until `need`
    /// bytes are found queued after [`WAKE_BOUND`] without a wake-up.
    fn wait_readable(&mut self, need: usize) -> Result<()> {
        let bound_ms = libc::c_int::try_from(WAKE_BOUND.as_millis()).unwrap_or(libc::c_int::MAX);
        loop {
            let mut fd = libc::pollfd {
                fd: self.socket.as_raw_fd(),
                events: libc::POLLIN,
                revents: 0,
            };
            // SAFETY: one valid `pollfd` for a descriptor `self.socket` owns, count 1 (poll(2)).
            let rc = unsafe { libc::poll(&mut fd, 1, bound_ms) };
            if rc > 0 {
                return Ok(());
            }
            if rc < 0 {
                let e = std::io::Error::last_os_error();
                if e.kind() == std::io::ErrorKind::Interrupted {
                    continue;
                }
                return Err(e).context("poll on QEMU's UART socket");
            }
            if queued_bytes(&self.socket).is_some_and(|n| n >= need) {
                self.missed_wakes += 1;
                return Ok(());
            }
        }
    }

    /// Sets the socket's receive low-water mark to `bytes`.
    fn set_mark(&mut self, bytes: usize) -> Result<()> {
        let mark = libc::c_int::try_from(bytes).context("frame size")?;
        // SAFETY: the descriptor is owned by `self.socket` for the call's duration; the value
        // is a `c_int` passed by pointer with its exact size (setsockopt(2)).
        let rc = unsafe {
            libc::setsockopt(
                self.socket.as_raw_fd(),
                libc::SOL_SOCKET,
                libc::SO_RCVLOWAT,
                (&mark as *const libc::c_int).cast(),
                std::mem::size_of::<libc::c_int>() as libc::socklen_t,
            )
        };
        if rc != 0 {
            return Err(std::io::Error::last_os_error())
                .context("setsockopt(SO_RCVLOWAT) on QEMU's UART socket");
        }
        self.mark = bytes;
        Ok(())
    }
}

/// Bytes received and not yet read (`FIONREAD`); `None` where the query fails.
pub fn queued_bytes(socket: &TcpStream) -> Option<usize> {
    ioctl_count(socket, libc::FIONREAD)
}

/// Bytes written and not yet acknowledged by the peer (`TIOCOUTQ`, tcp(7)); `None` where the
/// query fails.
pub fn unacknowledged_bytes(socket: &TcpStream) -> Option<usize> {
    ioctl_count(socket, libc::TIOCOUTQ)
}

fn ioctl_count(socket: &TcpStream, request: libc::Ioctl) -> Option<usize> {
    let mut n: libc::c_int = 0;
    // SAFETY: the descriptor is owned by `socket` for the call's duration; both requests write
    // one `c_int` through the pointer (ioctl(2), tcp(7)).
    let rc = unsafe { libc::ioctl(socket.as_raw_fd(), request, &mut n as *mut libc::c_int) };
    (rc == 0).then(|| usize::try_from(n).ok()).flatten()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Write;
    use std::net::TcpListener;
    use std::time::Instant;

    fn pair() -> (TcpStream, TcpStream) {
        let listener = TcpListener::bind("127.0.0.1:0").unwrap();
        let writer = TcpStream::connect(listener.local_addr().unwrap()).unwrap();
        writer.set_nodelay(true).unwrap();
        let (reader, _) = listener.accept().unwrap();
        (writer, reader)
    }

    /// Frames written a byte at a time (each its own segment, as QEMU's UART sends them), with
    /// pauses inside a frame, arrive whole and in order, none late by the bound.
    #[test]
    fn trickled_frames_arrive_whole_and_in_order() {
        let (mut writer, reader) = pair();
        let mut frames = FrameSocket::new(reader, 16).unwrap();
        let sender = std::thread::spawn(move || {
            for k in 0..20u8 {
                for b in 0..16u8 {
                    writer
                        .write_all(&[k.wrapping_mul(16).wrapping_add(b)])
                        .unwrap();
                    if b == 4 || b == 11 {
                        std::thread::sleep(Duration::from_millis(3));
                    }
                }
            }
        });
        let t0 = Instant::now();
        for k in 0..20u8 {
            let mut buf = [0u8; 16];
            assert_eq!(frames.read_frame(&mut buf).unwrap(), 16);
            let want: Vec<u8> = (0..16u8)
                .map(|b| k.wrapping_mul(16).wrapping_add(b))
                .collect();
            assert_eq!(buf.to_vec(), want, "frame {k}");
        }
        sender.join().unwrap();
        // 40 pauses of 3 ms; a missed wake-up would add the 100 ms bound.
        assert_eq!(frames.missed_wakes, 0);
        assert!(t0.elapsed() < Duration::from_secs(2), "{:?}", t0.elapsed());
        let mut buf = [0u8; 16];
        assert_eq!(frames.read_frame(&mut buf).unwrap(), 0, "end of stream");
    }

    /// The hole of a blocking read (module docs): a reader woken after part of a frame. Here the
    /// wake-up is forced by a mark of 1 while 5 bytes are queued; the reader copies them, lowers
    /// the mark to the 11 still missing and returns the whole frame once they arrive.
    #[test]
    fn a_frame_copied_in_part_is_completed_when_its_rest_arrives() {
        let (mut writer, reader) = pair();
        let mut frames = FrameSocket::new(reader, 16).unwrap();
        frames.set_mark(1).unwrap();
        frames.mark = 16; // the reader believes the mark is the frame's: a wake-up comes early
        writer.write_all(&[1, 2, 3, 4, 5]).unwrap();
        let sender = std::thread::spawn(move || {
            std::thread::sleep(Duration::from_millis(50));
            for b in 6..=16u8 {
                writer.write_all(&[b]).unwrap();
            }
            writer
        });
        let mut buf = [0u8; 16];
        assert_eq!(frames.read_frame(&mut buf).unwrap(), 16);
        assert_eq!(buf.to_vec(), (1..=16u8).collect::<Vec<_>>());
        assert_eq!(frames.split_frames, 1);
        assert_eq!(frames.mark, 11);
        drop(sender.join().unwrap());
        // The next frame's read sets the mark back to a whole frame.
        assert_eq!(frames.read_frame(&mut buf).unwrap(), 0);
        assert_eq!(frames.mark, 16);
    }

    /// A stream that ends inside a frame is an error naming how much of it came.
    #[test]
    fn an_end_inside_a_frame_is_an_error() {
        let (mut writer, reader) = pair();
        let mut frames = FrameSocket::new(reader, 16).unwrap();
        writer.write_all(&[0xA5, 0x43, 0, 0]).unwrap();
        drop(writer);
        let mut buf = [0u8; 16];
        let e = frames.read_frame(&mut buf).unwrap_err().to_string();
        assert!(e.contains("4 of 16 bytes"), "{e}");
    }
}
