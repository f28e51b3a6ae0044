//! The NUCLEO image's board code under QEMU's `netduinoplus2` (STM32F405): its emulator build
//! (`firmware-nucleo --features emulator-netduinoplus2`, docs/firmware.md) in lock-step with the
//! bench plant over USART2.

use super::checks::{check_fault_end, FAULT_TICK};
use super::{nucleo_emulator_firmware, run_once, Board, HilRun, Inject};
use crate::util::Ctx;
use anyhow::{ensure, Context, Result};
use std::path::Path;

/// The start-up halt's exit status when the clock flags are polled as on the chip (the PLL never
/// locks under the emulator; `docs/hil.md`).
const EXIT_CLOCKS: i32 = 9;

/// The runs: one second of tracking on the default plant (exit 0, ≤ 1 % RMS of the peak-to-peak
/// on the true displacement), a NaN sample (exit 7, the feedforward fallback flagged), a silent
/// link (exit 8, 0 A), and the start-up with the clock flags polled as on the chip, which the
/// emulator never sets (exit 9 before the first tick, in bounded time).
pub fn check(ctx: &Ctx, exe: &Path, base: &Path) -> Result<String> {
    let elf = nucleo_emulator_firmware(ctx)?;
    let mut summary = String::new();
    let mut run = HilRun::new(base.join("default"));
    run.board = Board::Nucleo;
    let r = run_once(ctx, &elf, Some(exe), &run)?;
    summary.push_str(&r.summary);
    let (rms, _, _) = r
        .tracking
        .context("no tracking error from the NUCLEO run")?;
    ensure!(
        r.commands > run.ticks as usize,
        "NUCLEO image: {} commands for {} tracking ticks and the conditioning",
        r.commands,
        run.ticks
    );
    ensure!(rms <= 1.0, "NUCLEO image: tracking RMS {rms:.3} % > 1 %");
    // Injected in tracking, after the start-up conditioning (1,055 ticks with the feedback on).
    for (name, inject, exit, zero) in [
        ("nan", Inject::Nan(FAULT_TICK), 7, false),
        ("silent", Inject::Silent(FAULT_TICK), 8, true),
    ] {
        let mut f = HilRun::new(base.join(format!("fault_{name}")));
        f.board = Board::Nucleo;
        f.ticks = 2_000;
        f.inject = Some(inject);
        f.expect_exit = exit;
        let r = run_once(ctx, &elf, Some(exe), &f)?;
        summary.push_str(&r.summary);
        ensure!(
            r.commands >= FAULT_TICK as usize,
            "NUCLEO {name}: the run ended after {} command frames, before the injected fault",
            r.commands
        );
        check_fault_end(&format!("NUCLEO {name}"), &f.out, zero)?;
    }
    let mut halt = HilRun::new(base.join("clocks_board"));
    halt.board = Board::Nucleo;
    halt.board_clock_flags = true;
    halt.expect_exit = EXIT_CLOCKS;
    let r = run_once(ctx, &elf, Some(exe), &halt)?;
    summary.push_str(&r.summary);
    ensure!(
        r.commands == 0,
        "NUCLEO start-up with the clock flags polled: {} commands, expected a halt before the first",
        r.commands
    );
    Ok(summary)
}
