//! Every way of breaking the parameter file is rejected by `ActuatorParams::parse` with an error
//! that names the field (and the source), one test per case. `build_rejects_broken_files.rs`
//! checks the same cases through a real `cargo check` of the core.

mod common;

use actuator_params::ActuatorParams;
use common::{cases, valid_text};

fn check(name: &str) {
    let case = cases()
        .into_iter()
        .find(|c| c.name == name)
        .unwrap_or_else(|| panic!("no case {name}"));
    let err = ActuatorParams::parse(&case.text, "broken.json")
        .expect_err("a broken document must be rejected");
    assert_eq!(err.source_name, "broken.json");
    assert_eq!(err.field, case.field, "{name}: {err}");
    assert!(
        err.reason.contains(case.reason_contains),
        "{name}: reason {:?} lacks {:?}",
        err.reason,
        case.reason_contains
    );
    // The rendered message (what build.rs prints) names file and field.
    let shown = err.to_string();
    assert!(
        shown.starts_with(&format!("broken.json: field `{}`: ", case.field)),
        "{shown}"
    );
}

#[test]
fn the_valid_default_parses() {
    ActuatorParams::parse(&valid_text(), "default").expect("the default document is valid");
}

#[test]
fn every_case_is_tested_here() {
    let names: Vec<&str> = cases().iter().map(|c| c.name).collect();
    assert_eq!(
        names,
        [
            "missing_field",
            "wrong_type",
            "infinite_number",
            "nan_literal",
            "beyond_f32",
            "negative_weight",
            "negative_resistance",
            "slew_beyond_amplifier",
            "amplifier_cannot_hold_current_limit",
            "feedback_gain_out_of_range",
            "feedback_no_harmonics",
            "feedback_unknown_structure",
            "wrong_number_of_weights",
            "h_min_not_below_h_max",
            "levels_inconsistent_with_weights",
            "weights_for_another_level_count",
            "reversible_wrong_count",
            "reversible_negative",
            "grid_lines_wrong_count",
            "grid_lines_not_increasing",
            "grid_lines_wrong_ends",
        ]
    );
}

#[test]
fn slew_beyond_amplifier() {
    check("slew_beyond_amplifier");
}

#[test]
fn amplifier_cannot_hold_current_limit() {
    check("amplifier_cannot_hold_current_limit");
}

#[test]
fn feedback_gain_out_of_range() {
    check("feedback_gain_out_of_range");
}

#[test]
fn feedback_no_harmonics() {
    check("feedback_no_harmonics");
}

#[test]
fn feedback_unknown_structure() {
    check("feedback_unknown_structure");
}

#[test]
fn missing_field() {
    check("missing_field");
}

#[test]
fn wrong_type() {
    check("wrong_type");
}

#[test]
fn infinite_number() {
    check("infinite_number");
}

#[test]
fn nan_literal() {
    check("nan_literal");
}

#[test]
fn beyond_f32() {
    check("beyond_f32");
}

#[test]
fn negative_weight() {
    check("negative_weight");
}

#[test]
fn negative_resistance() {
    check("negative_resistance");
}

#[test]
fn wrong_number_of_weights() {
    check("wrong_number_of_weights");
}

#[test]
fn h_min_not_below_h_max() {
    check("h_min_not_below_h_max");
}

#[test]
fn levels_inconsistent_with_weights() {
    check("levels_inconsistent_with_weights");
}

#[test]
fn weights_for_another_level_count() {
    check("weights_for_another_level_count");
}

#[test]
fn reversible_wrong_count() {
    check("reversible_wrong_count");
}

#[test]
fn reversible_negative() {
    check("reversible_negative");
}

#[test]
fn grid_lines_wrong_count() {
    check("grid_lines_wrong_count");
}

#[test]
fn grid_lines_not_increasing() {
    check("grid_lines_not_increasing");
}

#[test]
fn grid_lines_wrong_ends() {
    check("grid_lines_wrong_ends");
}

/// A file with grid lines parses and keeps them through the writer (the core's side:
/// `lab/src/params_io.rs`'s tests).
#[test]
fn grid_lines_are_accepted_and_reach_the_core() {
    let mut v: serde_json::Value = serde_json::from_str(&valid_text()).unwrap();
    v["preisach"]["grid_lines_a_per_m"] = serde_json::Value::from(common::lines(26));
    let text = serde_json::to_string(&v).unwrap();
    let params = ActuatorParams::parse(&text, "lines.json").expect("valid grid lines");
    let parsed = params
        .preisach
        .grid_lines_a_per_m
        .clone()
        .expect("lines kept");
    assert_eq!(parsed.len(), 26);
    for (a, b) in parsed.iter().zip(common::lines(26)) {
        // (serde_json's default float parser may differ in the last bit)
        assert!((a - b).abs() <= 1e-12 * b.abs().max(1.0), "{a} vs {b}");
    }
    // Round trip through the writer keeps them; a file without them writes none.
    let again = ActuatorParams::parse(&params.to_json_pretty(), "again.json").unwrap();
    let kept = again
        .preisach
        .grid_lines_a_per_m
        .expect("the writer keeps the lines");
    for (a, b) in kept.iter().zip(&parsed) {
        assert!((a - b).abs() <= 1e-12 * b.abs().max(1.0), "{a} vs {b}");
    }
    assert!(!valid_text().contains("grid_lines_a_per_m"));
}

#[test]
fn a_valid_range_above_the_rest_position_is_refused_for_a_firmware_image_only() {
    // The older default (valid from 0.5 µm): the rod at rest (0 m) would read as a sensor fault.
    let mut doc: serde_json::Value = serde_json::from_str(&valid_text()).expect("json");
    doc["sensor"]["valid_min_m"] = serde_json::json!(0.5e-6);
    doc["trajectory"]["displacement_min_m"] = serde_json::json!(1e-5);
    let params = ActuatorParams::parse(&doc.to_string(), "older.json")
        .expect("the host tools accept it: they never judge a reading against the range");
    let err = params
        .validate_for_firmware("older.json")
        .expect_err("a firmware image must not fault at rest");
    assert_eq!(err.field, "sensor.valid_min_m", "{err}");
    assert!(err.reason.contains("rest position"), "{err}");
    ActuatorParams::parse(&valid_text(), "default")
        .and_then(|p| p.validate_for_firmware("default"))
        .expect("the default file is fit for a firmware image");
}

/// The valid document with `section` set to `entry`.
fn with_section(section: &str, entry: &serde_json::Value) -> String {
    let mut v: serde_json::Value = serde_json::from_str(&valid_text()).expect("JSON");
    v[section] = entry.clone();
    serde_json::to_string_pretty(&v).expect("JSON")
}

/// Each `(entry, field, reason)` set as `section` is rejected naming `field` with `reason`.
fn assert_rejected(section: &str, rejected: &[(serde_json::Value, &str, &str)]) {
    for (entry, field, reason) in rejected {
        let err = ActuatorParams::parse(&with_section(section, entry), "section.json")
            .expect_err("a bad section value must be rejected");
        assert_eq!(err.field, *field, "{entry}: {err}");
        assert!(err.reason.contains(reason), "{entry}: {err}");
    }
}

/// The optional `datasheet` section (host tools' priors, not in the cases above: the firmware
/// bakes none of it): each bad value is rejected naming its field; a valid one reads back.
#[test]
fn datasheet_values_are_checked_and_read_back() {
    assert_rejected(
        "datasheet",
        &[
            (
                serde_json::json!({"sensor_bandwidth_hz": {"value": 100.0, "plus_minus": 150.0}}),
                "datasheet.sensor_bandwidth_hz",
                "must lie above 0",
            ),
            (
                serde_json::json!({"sensor_delay_s": {"value": -1e-5, "plus_minus": 1e-6}}),
                "datasheet.sensor_delay_s",
                "must be >= 0",
            ),
            (
                serde_json::json!({"load_mass_kg": {"value": 0.01, "plus_minus": -0.001}}),
                "datasheet.load_mass_kg.plus_minus",
                "must be >= 0",
            ),
            (
                serde_json::json!({"sensor_bandwidth": {"value": 1.0, "plus_minus": 0.1}}),
                "datasheet.sensor_bandwidth",
                "unknown field `sensor_bandwidth`",
            ),
            (
                serde_json::json!({"coil_inductance_h": {"value": 0.008}}),
                "datasheet.coil_inductance_h.plus_minus",
                "missing field",
            ),
        ],
    );
    let good = with_section(
        "datasheet",
        &serde_json::json!({
        "sensor_delay_s": {"value": 5e-5, "plus_minus": 8e-5},
        "amplifier_bandwidth_hz": {"value": 2000.0, "plus_minus": 200.0}
        }),
    );
    let p = ActuatorParams::parse(&good, "sheet.json").expect("valid");
    let d = p.datasheet.expect("read");
    let (lo, hi) = d.sensor_delay_s.expect("read").band_from_zero();
    assert!(lo == 0.0 && (hi - 1.3e-4).abs() < 1e-15, "{lo} {hi}");
    assert_eq!(d.sensor_bandwidth_hz, None);
    let again = ActuatorParams::parse(&p.to_json_pretty(), "again").expect("round trip");
    assert_eq!(again.datasheet, p.datasheet);
    // Without the section nothing is written: a file without priors reads as before.
    assert!(!actuator_params::paper_defaults()
        .to_json_pretty()
        .contains("datasheet"));
}

/// The optional `coil_thermal` section (baked: the measurement programme's heat budget): a bad
/// or missing member is rejected naming it; a valid one reads back and bakes.
#[test]
fn coil_thermal_values_are_checked_read_back_and_baked() {
    assert_rejected(
        "coil_thermal",
        &[
            (
                serde_json::json!({"thermal_resistance_k_per_w": 4.0, "time_constant_s": 0.0, "max_rise_k": 20.0}),
                "coil_thermal.time_constant_s",
                "must be finite and > 0",
            ),
            (
                serde_json::json!({"thermal_resistance_k_per_w": -4.0, "time_constant_s": 300.0, "max_rise_k": 20.0}),
                "coil_thermal.thermal_resistance_k_per_w",
                "must be finite and > 0",
            ),
            (
                serde_json::json!({"thermal_resistance_k_per_w": 4.0, "time_constant_s": 300.0}),
                "coil_thermal.max_rise_k",
                "missing field",
            ),
        ],
    );
    let good = with_section(
        "coil_thermal",
        &serde_json::json!({
            "thermal_resistance_k_per_w": 4.0, "time_constant_s": 300.0, "max_rise_k": 20.0
        }),
    );
    let p = ActuatorParams::parse(&good, "coil.json").expect("valid");
    assert_eq!(
        p.coil_thermal.map(|t| t.max_rise_k),
        Some(20.0),
        "read back"
    );
    let again = ActuatorParams::parse(&p.to_json_pretty(), "again").expect("round trip");
    assert_eq!(again.coil_thermal, p.coil_thermal);
    let source = actuator_params::codegen::rust_constants(&p, "coil.json");
    assert!(
        source.contains("p.coil_thermal = Some(CoilThermal { thermal_resistance_k_per_w: 4.0f32"),
        "{source}"
    );
    assert!(!actuator_params::paper_defaults()
        .to_json_pretty()
        .contains("coil_thermal"));
}

/// The optional `current_monitor` section (baked: the measurement image's second ADC channel).
#[test]
fn current_monitor_values_are_checked_read_back_and_baked() {
    assert_rejected(
        "current_monitor",
        &[
            (
                serde_json::json!({"gain_a_per_count": 0.0, "offset_a": -5.0}),
                "current_monitor.gain_a_per_count",
                "must be finite and non-zero",
            ),
            (
                serde_json::json!({"gain_a_per_count": 0.002}),
                "current_monitor.offset_a",
                "missing field",
            ),
            (
                serde_json::json!({"gain_a_per_count": 0.002, "offset_a": -5.0, "bits": 12}),
                "current_monitor.bits",
                "unknown field",
            ),
        ],
    );
    let good = with_section(
        "current_monitor",
        &serde_json::json!({"gain_a_per_count": 0.002442, "offset_a": -5.0}),
    );
    let p = ActuatorParams::parse(&good, "monitor.json").expect("valid");
    let again = ActuatorParams::parse(&p.to_json_pretty(), "again").expect("round trip");
    assert_eq!(again.current_monitor, p.current_monitor);
    let source = actuator_params::codegen::rust_constants(&p, "monitor.json");
    assert!(
        source.contains("p.current_monitor = Some(CurrentMonitorScale { gain_a_per_count: 0.002442f32, offset_a: -5.0f32 })"),
        "{source}"
    );
}
