//! A PI current loop around the coil (the bench plant's `amplifier_bandwidth` form 2, a tuning
//! form: `v = K_p (i_cmd − i) + z`, `K_p = ω_c τ_L`, against the coil's `v = i + (τ_L/c0) w'`)
//! on a noise-free dataset, diagnosed with the plant's own file through the `maglab` binary:
//! the library's amplifier is that loop (`maglab_model::model::CurrentLoop`), so it is named and
//! its fit gives back the loop the plant ran — the coil's `τ_L` and the crossover
//! `K = ωn/(2ζ)` (the candidate's PI gain; its filter pole goes to high frequency) — while the
//! eddy candidate, which has the loop's EMF term but not its command response, is not named.

mod common;
use common::{json, maglab, SHORT_SINES_ARGS};

const CROSSOVER_HZ: f64 = 300.0;
const COIL_TIME_CONSTANT_S: f64 = 5e-4;

#[test]
fn a_pi_current_loop_is_named_the_amplifier_with_the_plants_coil_and_crossover() {
    let dir = tempfile::tempdir().expect("temp dir");
    let data = dir.path().join("data");
    let report = dir.path().join("report");
    let (data_s, report_s) = (data.to_str().unwrap(), report.to_str().unwrap());
    let effect = format!(
        "amplifier_bandwidth:form=2,natural_hz={CROSSOVER_HZ},\
         coil_time_constant_s={COIL_TIME_CONSTANT_S},voltage_limit_a=100"
    );
    let noise_free = ["--noise-m", "0", "--quantization-m", "0"];
    let rig: Vec<&str> = ["rig", "-o", data_s, "--effect", &effect]
        .into_iter()
        .chain(noise_free)
        .chain(SHORT_SINES_ARGS)
        .collect();
    maglab(&rig);
    let params = format!("{}/../params/actuator.json", env!("CARGO_MANIFEST_DIR"));
    let out = maglab(&["diagnose", "--params", &params, data_s, "-o", report_s]);
    let d = json(&report.join("diagnosis.json"));
    assert_eq!(d["verdict"], "amplifier_bandwidth", "{out}");
    let winner = &d["ranking"][0];
    assert_eq!(winner["effect"], "amplifier_bandwidth", "{}", d["ranking"]);
    let p = &winner["parameters"];
    let value = |name: &str| p[name].as_f64().unwrap_or_else(|| panic!("{name} in {p}"));
    let tau_l = value("coil_time_constant_s");
    let crossover_hz = value("natural_hz") / (2.0 * value("amplifier_bandwidth.damping_ratio"));
    // Within 10 %: the refit's constants and the channel skew share the lag with the loop.
    assert!(
        (tau_l / COIL_TIME_CONSTANT_S - 1.0).abs() < 0.1,
        "tau_L {tau_l:.3e} s, the plant's {COIL_TIME_CONSTANT_S:.1e} s"
    );
    assert!(
        (crossover_hz / CROSSOVER_HZ - 1.0).abs() < 0.1,
        "crossover {crossover_hz:.1} Hz, the plant's {CROSSOVER_HZ} Hz"
    );
}
