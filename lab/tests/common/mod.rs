//! Shared by the `maglab` binary's tests: running it, and the base file a user starts `maglab
//! identify` from.

use std::path::Path;

/// Writes a datasheet's base file to `path`: the paper defaults with R_eddy, ξ, f0 off by ×1.4,
/// ×0.75, ×1.2 (a datasheet's values, not this rod's), so that the identification does not start
/// at the bench plant's own constants. Its masses, the fit's prior, are the plant's.
#[allow(dead_code)] // not every test crate that includes this module writes one
pub fn write_datasheet(path: &Path) {
    let mut base = actuator_params::paper_defaults();
    base.actuator.eddy_resistance_ohm *= 1.4;
    base.actuator.damping_ratio *= 0.75;
    base.actuator.resonance_hz *= 1.2;
    std::fs::write(path, serde_json::to_string_pretty(&base).expect("JSON"))
        .expect("datasheet written");
}

/// Runs the `maglab` binary with `args`; panics with its output unless it succeeds. Returns
/// stdout and stderr together.
#[allow(dead_code)] // not every test crate that includes this module runs the binary
pub fn maglab(args: &[&str]) -> String {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_maglab"))
        .args(args)
        .output()
        .expect("maglab runs");
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(out.status.success(), "maglab {args:?} failed:\n{text}");
    text
}
