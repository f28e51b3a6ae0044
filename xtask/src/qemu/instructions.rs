//! Step 3: instructions per interrupt, counted by SysTick under `-icount shift=10`, against the
//! handler's budgets and against the peers' inverses run in the same image.

use super::capture::{self, Record};
use anyhow::{ensure, Context, Result};
use magctl::board::capture_phase::CapturePhase;
use magctl::inverse::CommandFlags;
use magctl::params::BAKED_PARAMETERS;
use std::path::Path;

/// SysTick ticks per instruction under `-icount shift=10` on the 25 MHz mps2: 1024 ns × 25 MHz.
pub(super) const TICKS_PER_INSTRUCTION: f64 = 25.6;
/// The goal for the whole handler.
pub(super) const MAX_INSTRUCTIONS: f64 = 1_500.0;
/// Budget of an interrupt that forces a staircase merge (the 64-point memory full: one O(N) scan
/// of the 62 candidate rectangles, a memmove, a running-sum update): ≤ 2,500 instructions,
/// ~3,300 cycles at 180 MHz with flash wait states, 18 % of the 18,000-cycle period at 10 kHz.
pub(super) const MAX_MERGE_INSTRUCTIONS: f64 = 2_500.0;

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

/// The rows of the instructions table: phase and label, in the summary's order (ours, then the
/// peers').
const TABLE: [(CapturePhase, &str); 6] = [
    (
        CapturePhase::Dynamic,
        "dynamic inverse, exact Preisach inverse:",
    ),
    (
        CapturePhase::Static,
        "static inverse,  exact Preisach inverse:",
    ),
    (
        CapturePhase::Merge,
        "merge stress (dynamic inverse, staircase full, no trajectory step):",
    ),
    (
        CapturePhase::Naive,
        "dynamic inverse, naive (bisection):     ",
    ),
    (
        CapturePhase::EverettBisection,
        "dynamic inverse, Everett + bisection (openCFS-style):",
    ),
    (
        CapturePhase::RelayGrid,
        "dynamic inverse, relay grid + bisection (5,050 relays):",
    ),
];

/// The calibration record (`CapturePhase::Calibration`): two timed blocks that differ by exactly `index` nops take
/// `index` × [`TICKS_PER_INSTRUCTION`] SysTick ticks more. The surrounding reads may differ by
/// one instruction depending on code generation, and SysTick rounds to whole ticks: ±(1
/// instruction + 1 tick) is accepted.
fn check_calibration(records: &[Record], summary: &mut String) -> Result<()> {
    let cal = records
        .first()
        .filter(|r| r.phase == CapturePhase::Calibration.code())
        .context("no calibration record")?;
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
    Ok(())
}

/// (min, median, max) instructions per interrupt of `records`.
fn instructions(records: &[Record]) -> (f64, f64, f64) {
    stats(
        records
            .iter()
            .map(|r| r.ticks as f64 / TICKS_PER_INSTRUCTION)
            .collect(),
    )
}

/// Step 3: the instruction counter's calibration, each phase's instructions per interrupt
/// against the goals, the capture CSV; returns the dynamic and static phases' records.
pub(super) fn check_instructions(
    out_dir: &Path,
    records: &[Record],
    firmware_lines: &[String],
    summary: &mut String,
) -> Result<(Vec<Record>, Vec<Record>)> {
    check_calibration(records, summary)?;
    let rate = BAKED_PARAMETERS.control.sample_rate_hz as f64;
    let of_phase = |phase: CapturePhase| {
        records
            .iter()
            .filter(|r| r.phase == phase.code())
            .copied()
            .collect::<Vec<_>>()
    };
    let (dynamic, stat) = (
        of_phase(CapturePhase::Dynamic),
        of_phase(CapturePhase::Static),
    );
    ensure!(
        dynamic.len() as f64 >= rate && stat.len() as f64 >= rate,
        "less than 1 s of control time captured"
    );
    say!(summary, "instructions per interrupt (min / median / max):");
    let mut counted = std::collections::BTreeMap::new();
    for (phase, label) in TABLE {
        let rs = of_phase(phase);
        ensure!(
            !rs.is_empty(),
            "no records of phase {} ({label})",
            phase.name()
        );
        let (lo, median, hi) = instructions(&rs);
        say!(
            summary,
            "  {label} {lo:.0} / {median:.0} / {hi:.0}  ({} interrupts)",
            rs.len()
        );
        counted.insert(phase.code(), (lo, median, hi));
    }
    let ours = counted[&CapturePhase::Dynamic.code()];
    for (phase, name, digits) in [
        (CapturePhase::EverettBisection, "Everett bisection", 1),
        (CapturePhase::RelayGrid, "relay grid", 0),
        (CapturePhase::Naive, "naive (strawman)", 0),
    ] {
        let peer = counted[&phase.code()];
        say!(
            summary,
            "  {name} / ours: median {:.digits$}x, worst case {:.digits$}x",
            peer.1 / ours.1,
            peer.2 / ours.2
        );
    }
    say!(summary, "dynamic-inverse interrupt by stage (2,000 steps in thread mode, instructions min / mean / max):");
    for line in firmware_lines
        .iter()
        .filter_map(|l| l.split("stage ").nth(1))
    {
        say!(summary, "  {line}");
    }
    let overruns = records.iter().map(|r| r.overruns).max().unwrap_or(0);
    let faults = records
        .iter()
        .filter(|r| r.flags & CommandFlags::FAULT != 0)
        .count();
    say!(summary, "overruns {overruns}, fault flags {faults}");
    ensure!(
        overruns == 0 && faults == 0,
        "overruns or faults in the QEMU run"
    );
    capture::write_csv(out_dir, records, rate)?;
    say!(
        summary,
        "wrote out/qemu/capture.csv ({} rows)",
        records.len() - 1
    );
    let stat_worst = counted[&CapturePhase::Static.code()].2;
    ensure!(
        ours.2 <= MAX_INSTRUCTIONS && stat_worst <= MAX_INSTRUCTIONS,
        "worst case above {MAX_INSTRUCTIONS} instructions"
    );
    let merge_worst = counted[&CapturePhase::Merge.code()].2;
    ensure!(
        merge_worst <= MAX_MERGE_INSTRUCTIONS,
        "merge-stress worst case {merge_worst:.0} above {MAX_MERGE_INSTRUCTIONS} instructions"
    );
    Ok((dynamic, stat))
}
