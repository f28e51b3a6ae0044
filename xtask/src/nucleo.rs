//! `cargo xtask nucleo`: builds the NUCLEO-F446RE firmware and proves it panic-free at link time.
//!
//! Steps (no board or probe needed; flashing is `probe-rs run --chip STM32F446RETx <elf>`, see
//! docs/firmware.md):
//! 1. **Build** `firmware-nucleo` (release, `--features board-nucleo-f446re`) into
//!    `target/firmware/`, and report its flash and static RAM from the ELF's section headers.
//! 2. **No-panic proof**: the same with `panic-never` must link (no panic path anywhere in the
//!    image, the TIM2 control interrupt included), and with `panic-never-canary` (a bounds check
//!    in the interrupt) must fail to link naming the undefined panic symbol.
//! 3. **Measurement image** (`measurement-mode`: the compiled-in identification programme,
//!    recorded over RTT for `cargo xtask record`): built, sized, copied to
//!    `out/nucleo/firmware-nucleo-measure.elf`, and proven panic-free the same way.
//!
//! Writes `out/nucleo/summary.txt`.

use crate::qemu::firmware::{build_bin, elf_path, prove_panic_free, section_sizes};
use crate::util::{run_checked, Ctx};
use anyhow::{Context, Result};

const BIN: &str = "firmware-nucleo";
const BOARD: &str = "board-nucleo-f446re";

/// Runs the build and the proof; returns the summary text.
pub fn check(ctx: &Ctx) -> Result<String> {
    let out_dir = ctx.root.join("out").join("nucleo");
    std::fs::create_dir_all(&out_dir).with_context(|| format!("creating {}", out_dir.display()))?;
    let mut summary = String::new();
    macro_rules! say {
        ($($t:tt)*) => {{ let line = format!($($t)*); println!("{line}"); summary.push_str(&line); summary.push('\n'); }};
    }

    run_checked(build_bin(ctx, BIN, BOARD))?;
    let elf_path = elf_path(ctx, BIN);
    let elf =
        std::fs::read(&elf_path).with_context(|| format!("reading {}", elf_path.display()))?;
    let (flash, ram) = section_sizes(&elf)?;
    say!("firmware-nucleo sizes: flash {flash} B, static RAM {ram} B (stack not included)");
    // The ELF is overwritten by the proof builds below; keep a copy to flash.
    let keep = out_dir.join("firmware-nucleo.elf");
    std::fs::write(&keep, &elf).with_context(|| format!("writing {}", keep.display()))?;
    say!("firmware ELF copied to out/nucleo/firmware-nucleo.elf (probe-rs run --chip STM32F446RETx out/nucleo/firmware-nucleo.elf)");

    prove_panic_free(ctx, BIN, BOARD, Some("the TIM2 interrupt"))?;
    say!("no-panic proof (firmware-nucleo): panic-never build links; the canary (bounds check in the TIM2 interrupt) fails to link as it must");

    // The measurement image.
    let measure_features = format!("{BOARD},measurement-mode");
    run_checked(build_bin(ctx, BIN, &measure_features))?;
    let elf =
        std::fs::read(&elf_path).with_context(|| format!("reading {}", elf_path.display()))?;
    let (flash, ram) = section_sizes(&elf)?;
    let keep = out_dir.join("firmware-nucleo-measure.elf");
    std::fs::write(&keep, &elf).with_context(|| format!("writing {}", keep.display()))?;
    say!("firmware-nucleo measurement image sizes: flash {flash} B, static RAM {ram} B (16 KiB RTT ring, 512-tick record queue); out/nucleo/firmware-nucleo-measure.elf (cargo xtask record -o DIR -- probe-rs run --chip STM32F446RETx out/nucleo/firmware-nucleo-measure.elf)");
    prove_panic_free(ctx, BIN, &measure_features, None)?;
    say!("no-panic proof (firmware-nucleo measurement image): panic-never build links");
    std::fs::write(out_dir.join("summary.txt"), &summary)?;
    Ok(summary)
}

/// `cargo xtask nucleo`.
pub fn run(ctx: &Ctx) -> Result<()> {
    check(ctx).map(|_| ())
}
