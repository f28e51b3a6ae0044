//! Semihosting calls used by the firmware under QEMU (both machines: `mps2-an386` and the
//! NUCLEO image's emulator build on `netduinoplus2`): open/write/close of host files (the capture
//! stream), the command line (fault injection), exit with a status code, and ([`logger`]) the
//! defmt global logger on the host's stdout.
//!
//! Under QEMU each call is a single `bkpt 0xAB` instruction: with `-icount` the guest's virtual
//! clock advances by one instruction per call however long the host takes, so streaming does not
//! disturb the control timing.

pub mod logger;

use cortex_m_semihosting::{nr, syscall};

/// A host file handle.
#[derive(Clone, Copy)]
pub struct HostFile(usize);

/// Opens `name` (NUL-terminated) on the host for binary writing (truncates).
pub fn create(name: &[u8]) -> Option<HostFile> {
    let len = name.len().checked_sub(1)?;
    if name.last() != Some(&0) {
        return None;
    }
    let fd = unsafe { syscall!(OPEN, name.as_ptr(), nr::open::W_TRUNC_BINARY, len) } as isize;
    if fd < 0 {
        None
    } else {
        Some(HostFile(fd as usize))
    }
}

/// The host's standard output.
pub fn stdout() -> Option<HostFile> {
    create(b":tt\0")
}

impl HostFile {
    /// Writes all of `bytes`; false if the host reported an error.
    pub fn write_all(&self, mut bytes: &[u8]) -> bool {
        while !bytes.is_empty() {
            let left = unsafe { syscall!(WRITE, self.0, bytes.as_ptr(), bytes.len()) };
            if left == 0 {
                return true;
            }
            if left > bytes.len() {
                return false;
            }
            let done = bytes.len() - left;
            if done == 0 {
                return false;
            }
            bytes = match bytes.get(done..) {
                Some(rest) => rest,
                None => return false,
            };
        }
        true
    }

    /// Closes the file.
    pub fn close(self) {
        unsafe { syscall!(CLOSE, self.0) };
    }
}

/// Reads the command line (`-semihosting-config arg=...`) into `buf`; returns its length.
pub fn command_line(buf: &mut [u8]) -> usize {
    // The parameter block {buffer, length}; the host writes the used length back into it.
    let mut block = [buf.as_mut_ptr() as usize, buf.len()];
    let r = unsafe { cortex_m_semihosting::syscall1(nr::GET_CMDLINE, block.as_mut_ptr() as usize) };
    if r == 0 {
        block[1].min(buf.len())
    } else {
        0
    }
}

/// `SYS_EXIT_EXTENDED`: ends the QEMU process with `code` as its exit status.
pub fn exit(code: u32) -> ! {
    // ADP_Stopped_ApplicationExit with a subcode: QEMU exits with the subcode.
    let block = [0x20026usize, code as usize];
    loop {
        unsafe { cortex_m_semihosting::syscall(0x20, &block) };
    }
}
