//! Step 3: instructions per interrupt, counted by SysTick under `-icount shift=10`, against the
//! handler's budgets and against the peers' inverses run in the same image.

use super::capture::{self, Record};
use anyhow::{ensure, Context, Result};
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

/// Step 3: the instruction counter's calibration, each phase's instructions per interrupt
/// against the goals, the capture CSV; returns the dynamic and static phases' records.
pub(super) fn check_instructions(
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

    capture::write_csv(out_dir, records, rate)?;
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
