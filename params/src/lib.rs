//! The actuator parameter file: one JSON document that carries everything the firmware bakes in at
//! build time and every host tool reads or writes.
//!
//! This crate owns the schema ([`ActuatorParams`]), its validation (every error names the field
//! and the reason), the analytic default Preisach measure ([`default_measure`]) and the Rust
//! source that `build.rs` writes into `OUT_DIR` ([`codegen`]), and the list of the fields the
//! core carries that every mapping to the core's types derives from ([`core_fields`](mod@core_fields)). It is `std` only: the no_std core
//! never parses JSON; it sees typed constants.
//!
//! The schema is documented field by field in `docs/params.md`.

pub mod codegen;
pub mod core_fields;
mod datasheet;
pub mod default_measure;
mod schema;

pub use datasheet::{Datasheet, Toleranced};
pub use schema::*;

/// The paper's identified constants (Tan & Baras, Section 4) with the analytic default measure
/// ([`default_measure::TERFENOL_LIKE`]) and this project's default control settings. This is what
/// `params/actuator.json` holds; `maglab params default` writes it.
pub fn paper_defaults() -> ActuatorParams {
    let levels = PREISACH_LEVELS;
    let (h_min, h_max) = (-3.0e4, 3.0e4);
    let m_s = 7.87e5;
    let weights = default_measure::TERFENOL_LIKE.cell_masses(levels, h_min, h_max, m_s);
    let mut details = serde_json::Map::new();
    details.insert(
        "note".into(),
        serde_json::Value::String(
            "Actuator constants, R_eddy and damping are the paper's identified values (Tan & Baras, \
             Section 4). The Preisach weights are NOT identified from any actuator: the paper does \
             not publish its weights, so these are cell integrals of an analytic factorized Gaussian \
             density (coercive centre 2.5 kA/m, spread 2.0 kA/m; interaction spread 7.0 kA/m), \
             scaled to sum to M_s so the loop saturates at +/-M_s. Replace them with `maglab \
             identify` output for a real rig. See docs/params.md."
                .into(),
        ),
    );
    ActuatorParams {
        schema_version: SCHEMA_VERSION,
        actuator: Actuator {
            coil_turns: 1300.0,
            rod_area_m2: 2.83e-5,
            rod_length_m: 5.13e-2,
            coil_factor_per_m: 1.54e4,
            saturation_magnetization_a_per_m: m_s,
            saturation_magnetostriction: 0.001313,
            resonance_hz: 392.0,
            eddy_resistance_ohm: 70.0,
            damping_ratio: 0.7783,
        },
        preisach: Preisach {
            levels,
            h_min_a_per_m: h_min,
            h_max_a_per_m: h_max,
            grid_lines_a_per_m: None,
            reversible_susceptibility: None,
            reach_a_per_m: None,
            offset_a_per_m: 0.0,
            weights_a_per_m: weights,
        },
        control: Control {
            sample_rate_hz: 10_000.0,
            current_limit_a: 2.0,
            // The amplifier's guaranteed slew at 2 A, (48 - 5.8 x 2) / 8e-3 = 4550 A/s, rounded
            // down (see `amplifier`).
            current_slew_limit_a_per_s: 4.5e3,
            feedback: Feedback::default(),
        },
        // An example coil and amplifier (the paper does not publish them): 1300 turns of
        // 0.5 mm copper on an 84 mm bobbin around the 6 mm rod (~69 m of wire, 5.8 ohm hot), about
        // 8 mH with the rod inside, and a 48 V linear transconductance amplifier. Measure your own.
        amplifier: Amplifier {
            compliance_voltage_v: 48.0,
            coil_resistance_ohm: 5.8,
            coil_inductance_h: 8.0e-3,
        },
        // An example sensor (measure your own): an 80 µm displacement sensor on a 12-bit ADC
        // (19.5 nm per count) reading −2 … 78 µm, covering the rod at rest (0 m, unmagnetized at
        // 0 A, with its noise) and its full stroke λ_s·L = 67.4 µm; its two rails (0 and 4095
        // counts, a saturated or disconnected sensor) lie outside the valid range; 20 µs of
        // conversion and filter delay.
        sensor: Sensor {
            adc_bits: 12,
            gain_m_per_count: 80.0e-6 / 4095.0,
            offset_m: -2.0e-6,
            valid_min_m: -1.5e-6,
            valid_max_m: 77.5e-6,
            sample_delay_s: 20.0e-6,
        },
        trajectory: Trajectory {
            van_der_pol_mu: 1.0,
            frequency_scale_hz: 100.0,
            displacement_min_m: 10.0e-6,
            displacement_max_m: 40.0e-6,
        },
        provenance: Provenance {
            source: "analytic default (paper constants, synthetic Preisach measure)".into(),
            details,
        },
        datasheet: None,
        coil_thermal: None,
        current_monitor: None,
    }
}
