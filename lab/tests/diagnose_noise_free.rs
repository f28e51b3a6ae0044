//! A noise-free dataset from the bench plant without any effect, diagnosed with the plant's own
//! parameter file, through the `maglab` binary as a user runs it: the verdict must be `none`.
//!
//! With no noise the only gap left between the bench plant (its own Preisach evaluation, RK4 with
//! µs substeps) and the diagnosis's model (one substep per sample, Richardson-extrapolated) is
//! the model's own integration error, about 0.1 % of the motion here: above the noise-based
//! floors, and a lag candidate fits it (this dataset was named `amplifier_bandwidth`, 2.0x, before
//! the diagnosis measured that error). The diagnosis measures it (the refitted nominal model
//! against itself with twice the substeps) and reports it; a gap within 1.5 times it is `none`.
//! A bench with a nanometre sensor is in the same place.
use std::process::Command;

fn maglab(args: &[&str]) -> String {
    let out = Command::new(env!("CARGO_BIN_EXE_maglab"))
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

#[test]
fn a_noise_free_dataset_without_an_effect_is_none_within_the_models_integration_error() {
    let dir = tempfile::tempdir().expect("temp dir");
    let data = dir.path().join("data");
    let report = dir.path().join("report");
    let (data_s, report_s) = (data.to_str().unwrap(), report.to_str().unwrap());
    // Five frequencies through the rod's resonance region, two amplitudes (a CI budget; the
    // README's 8 x 2 dataset gives the same verdict).
    maglab(&[
        "rig",
        "-o",
        data_s,
        "--freq",
        "20,50,100,200,400",
        "--amplitude-a",
        "0.2,0.4",
        "--duration-s",
        "0.5",
        "--noise-m",
        "0",
        "--quantization-m",
        "0",
    ]);
    let params = format!("{}/../params/actuator.json", env!("CARGO_MANIFEST_DIR"));
    let out = maglab(&["diagnose", "--params", &params, data_s, "-o", report_s]);
    let d: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(report.join("diagnosis.json")).expect("diagnosis.json written"),
    )
    .expect("JSON");
    assert_eq!(d["verdict"], "none", "{out}");
    let model_error_m = d["model_error_m"].as_f64().expect("model_error_m");
    let gap_m = d["refitted_nominal"]["systematic_before_m"]
        .as_f64()
        .expect("the refitted nominal model's gap");
    let range_m = d["displacement_range_m"].as_f64().expect("range");
    // The error is measured, not zero, and small against the motion; the gap is within it.
    assert!(
        model_error_m > 1e-4 * range_m && model_error_m < 5e-3 * range_m,
        "model error {model_error_m:.3e} m of a {range_m:.3e} m range"
    );
    assert!(
        gap_m <= maglab_diagnose::diagnosis::MODEL_ERROR_FACTOR * model_error_m,
        "gap {gap_m:.3e} m, model error {model_error_m:.3e} m"
    );
    let text = std::fs::read_to_string(report.join("report.md")).expect("report.md");
    assert!(
        text.contains("the model's own integration error on the held-out experiments"),
        "{text}"
    );
}
