//! The emulated boards: the `qemu-system-arm` command lines every QEMU run here starts from.

use std::path::Path;
use std::process::Command;

/// `timeout TIMEOUT qemu-system-arm` on mps2-an386 (Cortex-M4F) with semihosting (`semi`: the
/// `-semihosting-config` value), `-icount shift=10,sleep=off` (SysTick counts instructions), the
/// first UART on `serial` (a QEMU `-serial` value) and `elf` as the kernel.
pub fn qemu_command(timeout_s: &str, serial: &str, semi: &str, elf: &Path) -> Command {
    let mut cmd = Command::new("timeout");
    cmd.args([
        timeout_s,
        "qemu-system-arm",
        "-machine",
        "mps2-an386",
        "-cpu",
        "cortex-m4",
        "-nographic",
        "-monitor",
        "none",
        "-serial",
        serial,
        "-semihosting-config",
        semi,
        "-icount",
        "shift=10,sleep=off",
        "-kernel",
    ])
    .arg(elf);
    cmd
}

/// `timeout TIMEOUT qemu-system-arm` on `netduinoplus2` (STM32F405) for the NUCLEO image's
/// emulator build: USART1 unconnected, USART2 (the plant link) on `serial`, semihosting (`semi`),
/// `-icount shift=0,sleep=off` (1 ns of virtual time per instruction: the handler's work, about
/// a thousand instructions, fits the emulated TIM2's period, and an idle core skips to the next
/// timer event), `elf` as the kernel.
pub fn netduino_command(timeout_s: &str, serial: &str, semi: &str, elf: &Path) -> Command {
    let mut cmd = Command::new("timeout");
    cmd.args([
        timeout_s,
        "qemu-system-arm",
        "-machine",
        "netduinoplus2",
        "-nographic",
        "-monitor",
        "none",
        "-serial",
        "null",
        "-serial",
        serial,
        "-semihosting-config",
        semi,
        "-icount",
        "shift=0,sleep=off",
    ]);
    if std::env::var_os("DEBUG_GDB").is_some() {
        cmd.args(["-gdb", "tcp::3334"]);
    }
    cmd.arg("-kernel").arg(elf);
    cmd
}
