//! The firmware's capture file (`qemu_capture.bin`, record layout
//! `magctl::board::mps2_an386::capture`) and its CSV form, `out/qemu/capture.csv`.

use super::instructions::TICKS_PER_INSTRUCTION;
use anyhow::{ensure, Context, Result};
use magctl::board::capture_phase::CapturePhase;
use std::fmt::Write as _;
use std::path::Path;

/// Bytes per capture record.
const RECORD_BYTES: usize = 40;

/// Columns of `out/qemu/capture.csv`. `t_s` is the start of the period over which the current is
/// held (tick index / sample rate); the desired values are those at `t_s + h` (the end of the
/// period, what the inverse aims at). `instructions` = SysTick ticks / 25.6.
pub const CSV_HEADER: &str = "phase,index,t_s,current_a,y_desired_m,y_rate_m_per_s,y_accel_m_per_s2,h_a_per_m,m_a_per_m,flags,dac_code,instructions";

/// One parsed capture record.
#[derive(Debug, Clone, Copy)]
pub struct Record {
    pub(super) phase: u8,
    pub(super) flags: u8,
    pub(super) index: u32,
    pub(super) ticks: u32,
    pub(super) current_a: f32,
    pub(super) y_m: f32,
    pub(super) y_rate: f32,
    pub(super) y_accel: f32,
    pub(super) h: f32,
    pub(super) m: f32,
    pub(super) dac_code: u16,
    pub(super) overruns: u16,
}

/// The records of a capture file, in the order the firmware wrote them.
pub(super) fn parse_records(bytes: &[u8]) -> Result<Vec<Record>> {
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

/// Writes `out_dir/capture.csv` ([`CSV_HEADER`]): every record but the calibration, its time the
/// tick index over the control rate `rate_hz`.
pub fn write_csv(out_dir: &Path, records: &[Record], rate_hz: f64) -> Result<()> {
    let mut csv = String::from(CSV_HEADER);
    csv.push('\n');
    for r in records.iter().filter(|r| r.phase != 0) {
        let _ = writeln!(
            csv,
            "{},{},{:.6},{:e},{:e},{:e},{:e},{:e},{:e},{},{},{:.1}",
            CapturePhase::from_code(r.phase).map_or("unknown", CapturePhase::name),
            r.index,
            r.index as f64 / rate_hz,
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
    let path = out_dir.join("capture.csv");
    std::fs::write(&path, csv).with_context(|| format!("writing {}", path.display()))
}
