//! The fields of the parameter file that the core (`magctl::params::ActuatorParameters`) carries,
//! listed once: each line is the field's path in the file, then its path in the core's types.
//!
//! [`core_fields!`](macro@crate::core_fields) hands the list to a macro of the caller's, which derives
//! one mapping from it. There are three: the Rust source `build.rs` bakes ([`crate::codegen`]),
//! the run-time narrowing of a file to the core's f32 types
//! (`magctl::params::ActuatorParameters::from_file`) and its widening back to a file
//! (`ActuatorParameters::to_file`). A field added to the core is added here once, and all three
//! follow. The conversion of each field follows from its two types (`f64` ↔ `f32`, counts as
//! they are, the feedback structure by variant, the Preisach vectors ↔ fixed arrays).

/// Calls `$callback!` with every core field as `file.path => core.path;` (module docs).
#[macro_export]
macro_rules! core_fields {
    ($callback:ident) => {
        $callback! {
            actuator.coil_turns => actuator.coil_turns;
            actuator.rod_area_m2 => actuator.rod_area_m2;
            actuator.rod_length_m => actuator.rod_length_m;
            actuator.coil_factor_per_m => actuator.coil_factor_per_m;
            actuator.saturation_magnetization_a_per_m => actuator.saturation_magnetization_a_per_m;
            actuator.saturation_magnetostriction => actuator.saturation_magnetostriction;
            actuator.resonance_hz => actuator.resonance_hz;
            actuator.eddy_resistance_ohm => actuator.eddy_resistance_ohm;
            actuator.damping_ratio => actuator.damping_ratio;
            preisach.h_min_a_per_m => preisach.h_min_a_per_m;
            preisach.h_max_a_per_m => preisach.h_max_a_per_m;
            preisach.grid_lines_a_per_m => preisach.lines_a_per_m;
            preisach.reversible_susceptibility => preisach.reversible_susceptibility;
            preisach.reach_a_per_m => preisach.reach_a_per_m;
            preisach.offset_a_per_m => preisach.offset_a_per_m;
            preisach.weights_a_per_m => preisach.weights_a_per_m;
            control.sample_rate_hz => control.sample_rate_hz;
            control.current_limit_a => control.current_limit_a;
            control.current_slew_limit_a_per_s => control.current_slew_limit_a_per_s;
            control.feedback.structure => control.feedback.structure;
            control.feedback.learning_gain => control.feedback.learning_gain;
            control.feedback.learning_harmonics => control.feedback.learning_harmonics;
            control.feedback.learning_leak_per_cycle => control.feedback.learning_leak_per_cycle;
            control.feedback.proportional_gain => control.feedback.proportional_gain;
            control.feedback.integral_gain_per_s => control.feedback.integral_gain_per_s;
            control.feedback.correction_limit_m => control.feedback.correction_limit_m;
            control.feedback.stuck_sensor_ticks => control.feedback.stuck_sensor_ticks;
            amplifier.compliance_voltage_v => amplifier.compliance_voltage_v;
            amplifier.coil_resistance_ohm => amplifier.coil_resistance_ohm;
            amplifier.coil_inductance_h => amplifier.coil_inductance_h;
            coil_thermal => coil_thermal;
            current_monitor => current_monitor;
            sensor.adc_bits => sensor.adc_bits;
            sensor.gain_m_per_count => sensor.gain_m_per_count;
            sensor.offset_m => sensor.offset_m;
            sensor.valid_min_m => sensor.valid_min_m;
            sensor.valid_max_m => sensor.valid_max_m;
            sensor.sample_delay_s => sensor.sample_delay_s;
            trajectory.van_der_pol_mu => trajectory.van_der_pol_mu;
            trajectory.frequency_scale_hz => trajectory.frequency_scale_hz;
            trajectory.displacement_min_m => trajectory.displacement_min_m;
            trajectory.displacement_max_m => trajectory.displacement_max_m;
        }
    };
}

/// `a.b.c` of a path's identifiers (for the generated source and error messages).
#[macro_export]
macro_rules! field_path {
    ($($part:ident).+) => {
        [$(stringify!($part)),+].join(".")
    };
}
