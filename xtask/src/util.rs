//! Shared helpers: the repository root, the cargo binary, and running processes with the command
//! line echoed and a clear error when they fail.

use anyhow::{bail, Context, Result};
use std::path::{Path, PathBuf};
use std::process::Command;

/// What every command needs: where the repository is and which cargo to call.
pub struct Ctx {
    /// The repository root (the workspace directory holding `Cargo.toml`).
    pub root: PathBuf,
    /// The cargo that runs this xtask (`$CARGO`), so child builds use the same toolchain.
    pub cargo: PathBuf,
}

impl Ctx {
    /// Locates the repository root from this crate's manifest directory.
    pub fn new() -> Result<Self> {
        let manifest = Path::new(env!("CARGO_MANIFEST_DIR"));
        let root = manifest
            .parent()
            .context("xtask/ has no parent directory")?
            .to_path_buf();
        if !root.join("Cargo.toml").is_file() {
            bail!(
                "no Cargo.toml in {} (expected the workspace root)",
                root.display()
            );
        }
        let cargo = std::env::var_os("CARGO")
            .map(PathBuf::from)
            .unwrap_or_else(|| PathBuf::from("cargo"));
        Ok(Ctx { root, cargo })
    }

    /// `cargo <args>` in the repository root.
    pub fn cargo(&self, args: &[&str]) -> Command {
        let mut cmd = Command::new(&self.cargo);
        cmd.args(args).current_dir(&self.root);
        cmd
    }

    /// `program <args>` in the repository root.
    pub fn command(&self, program: &str, args: &[&str]) -> Command {
        let mut cmd = Command::new(program);
        cmd.args(args).current_dir(&self.root);
        cmd
    }
}

/// The command line as a user would type it: the variables it sets in the environment
/// (`NAME=value`, so that a line copied from the log runs the same build, e.g. the firmware's
/// `CARGO_TARGET_DIR` and `DEFMT_LOG`), the program name without its directory, its arguments.
pub fn display(cmd: &Command) -> String {
    let program = Path::new(cmd.get_program())
        .file_name()
        .map(|p| p.to_string_lossy().into_owned())
        .unwrap_or_default();
    cmd.get_envs()
        .filter_map(|(name, value)| {
            value.map(|v| format!("{}={}", name.to_string_lossy(), v.to_string_lossy()))
        })
        .chain(std::iter::once(program))
        .chain(cmd.get_args().map(|a| a.to_string_lossy().into_owned()))
        .collect::<Vec<_>>()
        .join(" ")
}

/// Runs `cmd` with inherited stdio, echoing it first; fails with the command line and the exit
/// status when it does not succeed.
pub fn run_checked(mut cmd: Command) -> Result<()> {
    let line = display(&cmd);
    println!("$ {line}");
    let status = cmd
        .status()
        .with_context(|| format!("cannot start `{line}`"))?;
    if !status.success() {
        bail!("`{line}` failed ({status})");
    }
    Ok(())
}

/// Runs `cmd` quietly and returns its stdout, or `None` when it cannot start or fails.
pub fn output_of(mut cmd: Command) -> Option<String> {
    let out = cmd.output().ok()?;
    out.status
        .success()
        .then(|| String::from_utf8_lossy(&out.stdout).into_owned())
}

/// The first executable named `name` on `PATH`.
pub fn find_on_path(name: &str) -> Option<PathBuf> {
    use std::os::unix::fs::PermissionsExt;
    let path = std::env::var_os("PATH")?;
    std::env::split_paths(&path)
        .map(|dir| dir.join(name))
        .find(|p| {
            p.metadata()
                .map(|m| m.is_file() && m.permissions().mode() & 0o111 != 0)
                .unwrap_or(false)
        })
}

/// Seconds with one decimal, for summaries.
pub fn secs(d: std::time::Duration) -> String {
    format!("{:.1} s", d.as_secs_f64())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_displayed_command_sets_its_environment_first() {
        let mut cmd = Command::new("/usr/bin/cargo");
        cmd.args(["build", "--release"])
            .env("CARGO_TARGET_DIR", "target/firmware")
            .env_remove("RUSTFLAGS");
        assert_eq!(
            display(&cmd),
            "CARGO_TARGET_DIR=target/firmware cargo build --release"
        );
    }
}
