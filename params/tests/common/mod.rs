//! The broken parameter files the schema must reject, each with the field its error must name.
//!
//! Every case starts from the valid default document (`paper_defaults()`) and breaks exactly one
//! thing, so the error can only come from that change.
#![allow(dead_code)] // each test binary uses a different subset

use actuator_params::paper_defaults;
use serde_json::Value;

/// One broken document.
pub struct Case {
    /// Test-friendly name.
    pub name: &'static str,
    /// The dotted field path the error must name.
    pub field: &'static str,
    /// A phrase the reason must contain.
    pub reason_contains: &'static str,
    /// The broken JSON text.
    pub text: String,
}

/// The valid default document as text.
pub fn valid_text() -> String {
    paper_defaults().to_json_pretty()
}

fn edit(f: impl FnOnce(&mut Value)) -> String {
    let mut v: Value = serde_json::from_str(&valid_text()).expect("defaults serialize to JSON");
    f(&mut v);
    serde_json::to_string_pretty(&v).expect("a JSON value serializes")
}

/// Replaces the value of `"key": <number>` in the pretty-printed valid text with raw `literal`
/// (for values serde_json cannot hold: `1e999`, `NaN`).
fn raw_number(key: &str, literal: &str) -> String {
    let text = valid_text();
    let start = text
        .find(&format!("\"{key}\": "))
        .unwrap_or_else(|| panic!("key {key} in the default document"))
        + key.len()
        + 4;
    let end = start
        + text[start..]
            .find([',', '\n'])
            .expect("a value ends with a comma or a newline");
    format!("{}{}{}", &text[..start], literal, &text[end..])
}

/// All the ways the issue lists, plus an f32 overflow.
pub fn cases() -> Vec<Case> {
    vec![
        Case {
            name: "missing_field",
            field: "actuator.coil_turns",
            reason_contains: "missing field",
            text: edit(|v| {
                v["actuator"]
                    .as_object_mut()
                    .expect("object")
                    .remove("coil_turns");
            }),
        },
        Case {
            name: "wrong_type",
            field: "actuator.coil_turns",
            reason_contains: "invalid type",
            text: edit(|v| v["actuator"]["coil_turns"] = Value::from("1300")),
        },
        Case {
            name: "infinite_number",
            field: "actuator.eddy_resistance_ohm",
            reason_contains: "finite",
            text: raw_number("eddy_resistance_ohm", "1e999"),
        },
        Case {
            name: "nan_literal",
            field: "preisach.h_max_a_per_m",
            reason_contains: "NaN",
            text: raw_number("h_max_a_per_m", "NaN"),
        },
        Case {
            name: "beyond_f32",
            field: "preisach.h_max_a_per_m",
            reason_contains: "f32",
            text: edit(|v| v["preisach"]["h_max_a_per_m"] = Value::from(1.0e39)),
        },
        Case {
            name: "negative_weight",
            field: "preisach.weights_a_per_m[17]",
            reason_contains: ">= 0",
            text: edit(|v| v["preisach"]["weights_a_per_m"][17] = Value::from(-1.0)),
        },
        Case {
            name: "negative_resistance",
            field: "actuator.eddy_resistance_ohm",
            reason_contains: ">= 0",
            text: edit(|v| v["actuator"]["eddy_resistance_ohm"] = Value::from(-70.0)),
        },
        Case {
            name: "slew_beyond_amplifier",
            field: "control.current_slew_limit_a_per_s",
            reason_contains: "faster than the amplifier can drive the coil",
            text: edit(|v| v["control"]["current_slew_limit_a_per_s"] = Value::from(2.0e4)),
        },
        Case {
            name: "amplifier_cannot_hold_current_limit",
            field: "amplifier.compliance_voltage_v",
            reason_contains: "cannot drive control.current_limit_a",
            text: edit(|v| v["amplifier"]["compliance_voltage_v"] = Value::from(10.0)),
        },
        Case {
            name: "feedback_gain_out_of_range",
            field: "control.feedback.learning_gain",
            reason_contains: "must be in [0, 2]",
            text: edit(|v| {
                v["control"]["feedback"] = serde_json::json!({
                    "structure": "repetitive", "learning_gain": 3.0, "learning_harmonics": 6,
                    "learning_leak_per_cycle": 0.002, "proportional_gain": 0.0,
                    "integral_gain_per_s": 0.0, "correction_limit_m": 2.5e-5,
                    "stuck_sensor_ticks": 200
                })
            }),
        },
        Case {
            name: "feedback_no_harmonics",
            field: "control.feedback.learning_harmonics",
            reason_contains: "must be in 1..=16",
            text: edit(|v| {
                v["control"]["feedback"] = serde_json::json!({
                    "structure": "repetitive", "learning_gain": 0.3, "learning_harmonics": 0,
                    "learning_leak_per_cycle": 0.002, "proportional_gain": 0.0,
                    "integral_gain_per_s": 0.0, "correction_limit_m": 2.5e-5,
                    "stuck_sensor_ticks": 200
                })
            }),
        },
        Case {
            name: "feedback_unknown_structure",
            field: "control.feedback.structure",
            reason_contains: "unknown variant",
            text: edit(|v| v["control"]["feedback"]["structure"] = Value::from("pid")),
        },
        Case {
            name: "wrong_number_of_weights",
            field: "preisach.weights_a_per_m",
            reason_contains: "need 325 weights, the file has 324",
            text: edit(|v| {
                v["preisach"]["weights_a_per_m"]
                    .as_array_mut()
                    .expect("array")
                    .pop();
            }),
        },
        Case {
            name: "h_min_not_below_h_max",
            field: "preisach.h_min_a_per_m",
            reason_contains: "must be < preisach.h_max_a_per_m",
            text: edit(|v| v["preisach"]["h_min_a_per_m"] = Value::from(3.0e4)),
        },
        Case {
            name: "levels_inconsistent_with_weights",
            field: "preisach.levels",
            reason_contains: "its 325 weights imply 25",
            text: edit(|v| v["preisach"]["levels"] = Value::from(24)),
        },
        Case {
            name: "weights_for_another_level_count",
            field: "preisach.weights_a_per_m",
            reason_contains: "that is the count for 24 levels",
            text: edit(|v| {
                v["preisach"]["weights_a_per_m"]
                    .as_array_mut()
                    .expect("array")
                    .truncate(300);
            }),
        },
        Case {
            name: "reversible_wrong_count",
            field: "preisach.reversible_susceptibility",
            reason_contains:
                "25 levels need 25 susceptibilities (one per interval), the file has 24",
            text: edit(|v| v["preisach"]["reversible_susceptibility"] = Value::from(vec![0.5; 24])),
        },
        Case {
            name: "reversible_negative",
            field: "preisach.reversible_susceptibility[3]",
            reason_contains: "must be >= 0",
            text: edit(|v| {
                let mut chi = vec![0.5; 25];
                chi[3] = -0.1;
                v["preisach"]["reversible_susceptibility"] = Value::from(chi);
            }),
        },
        Case {
            name: "grid_lines_wrong_count",
            field: "preisach.grid_lines_a_per_m",
            reason_contains: "25 levels need 26 grid lines, the file has 25",
            text: edit(|v| v["preisach"]["grid_lines_a_per_m"] = Value::from(lines(25))),
        },
        Case {
            name: "grid_lines_not_increasing",
            field: "preisach.grid_lines_a_per_m[7]",
            reason_contains: "grid lines must increase strictly",
            text: edit(|v| {
                let mut l = lines(26);
                l[7] = l[6];
                v["preisach"]["grid_lines_a_per_m"] = Value::from(l);
            }),
        },
        Case {
            name: "grid_lines_wrong_ends",
            field: "preisach.grid_lines_a_per_m",
            reason_contains: "the first and last lines must be preisach.h_min_a_per_m",
            text: edit(|v| {
                let mut l = lines(26);
                l[25] = 2.9e4;
                v["preisach"]["grid_lines_a_per_m"] = Value::from(l);
            }),
        },
    ]
}

/// `n` grid lines over the default range [-3e4, 3e4], denser in the middle.
pub fn lines(n: usize) -> Vec<f64> {
    (0..n)
        .map(|k| {
            let s = 2.0 * k as f64 / (n - 1) as f64 - 1.0;
            3.0e4 * s.signum() * s.abs().powf(1.5)
        })
        .collect()
}
