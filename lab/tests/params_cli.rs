//! `maglab params check` as a user runs it on a file with the optional sections: each one's
//! summary line, with what it derives (the coil's steady rise, the monitor's range over the ADC,
//! the datasheet values given).
mod common;
use common::maglab;

#[test]
fn check_summarizes_the_optional_sections() {
    let dir = std::env::temp_dir().join(format!("maglab-params-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let path = dir.join("bench.json");
    let mut file = actuator_params::paper_defaults();
    file.coil_thermal = Some(actuator_params::CoilThermal {
        thermal_resistance_k_per_w: 4.0,
        time_constant_s: 300.0,
        max_rise_k: 20.0,
    });
    file.current_monitor = Some(actuator_params::CurrentMonitorScale {
        gain_a_per_count: 10.0 / 4095.0,
        offset_a: -5.0,
    });
    file.datasheet = Some(actuator_params::Datasheet {
        sensor_delay_s: Some(actuator_params::Toleranced {
            value: 5e-5,
            plus_minus: 1e-5,
        }),
        ..Default::default()
    });
    std::fs::write(&path, file.to_json_pretty()).expect("written");
    let out = maglab(&["params", "check", path.to_str().expect("UTF-8 path")]);
    let _ = std::fs::remove_dir_all(&dir);
    println!("{out}");
    // 4 K/W on the 5.8 Ω coil: 23.2 K/A², 92.8 K steady at 2 A.
    assert!(
        out.contains("coil heat    4 K/W, τ 300 s: 23.2 K/A², 92.8 K steady"),
        "{out}"
    );
    assert!(out.contains("keeps the rise <= 20 K"), "{out}");
    assert!(out.contains("[-5.000, 5.000] A over the ADC"), "{out}");
    assert!(out.contains("datasheet    sensor_delay_s"), "{out}");
}
