//! Shared by the `maglab` binary's tests: running it, the base file a user starts `maglab
//! identify` from and that command's arguments, the bench folder the identify tests record, and
//! reading the JSON files it writes.

use std::path::Path;

/// `maglab rig`'s arguments (after `-o DIR`) for the bench folders the identify tests record: a
/// 1 Hz reversal sweep in front of 0.5 s sines, the current linear between samples, a 0.4-sample
/// channel skew, a 1 µm sensor offset, seed 11 (the rig's default noise).
#[allow(dead_code)] // used by record_bench_folder only
const BENCH_FOLDER_ARGS: [&str; 12] = [
    "--forc-hz",
    "1",
    "--duration-s",
    "0.5",
    "--current-between-samples",
    "linear",
    "--skew-samples",
    "0.4",
    "--offset-m",
    "1e-6",
    "--seed",
    "11",
];

/// `maglab rig`'s arguments for a short sine set: five frequencies through the rod's resonance
/// region, two amplitudes, 0.5 s each (a CI budget).
#[allow(dead_code)] // not every test crate that includes this module records one
pub const SHORT_SINES_ARGS: [&str; 6] = [
    "--freq",
    "20,50,100,200,400",
    "--amplitude-a",
    "0.2,0.4",
    "--duration-s",
    "0.5",
];

/// Records the bench folder ([`BENCH_FOLDER_ARGS`]) into `data` with `maglab rig`, `extra`
/// arguments added (an effect, another start).
#[allow(dead_code)] // not every test crate that includes this module records one
pub fn record_bench_folder(data: &Path, extra: &[&str]) {
    let data = data.to_str().expect("UTF-8 path");
    let args: Vec<&str> = ["rig", "-o", data]
        .into_iter()
        .chain(BENCH_FOLDER_ARGS)
        .chain(extra.iter().copied())
        .collect();
    maglab(&args);
}

/// The arguments of `maglab identify` on the folder `data` from a datasheet's base file
/// ([`write_datasheet`], written to `dir/datasheet.json`), writing `identified` and its plots
/// under `dir/plots` (not into the working directory).
#[allow(dead_code)] // not every test crate that includes this module identifies
pub fn identify_args(dir: &Path, data: &Path, identified: &Path) -> Vec<String> {
    let datasheet = dir.join("datasheet.json");
    write_datasheet(&datasheet);
    let s = |p: &Path| p.to_str().expect("UTF-8 path").to_string();
    vec![
        "identify".into(),
        "--params".into(),
        s(&datasheet),
        s(data),
        "-o".into(),
        s(identified),
        "--plot-dir".into(),
        s(&dir.join("plots")),
    ]
}

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

/// The JSON file `maglab` wrote at `path` (an identified parameter file, `diagnosis.json`).
#[allow(dead_code)] // not every test crate that includes this module reads one
pub fn json(path: &Path) -> serde_json::Value {
    let text = std::fs::read_to_string(path)
        .unwrap_or_else(|e| panic!("{} not written: {e}", path.display()));
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("{}: not JSON: {e}", path.display()))
}
