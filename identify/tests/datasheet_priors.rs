//! Identification with datasheet priors (`datasheet` in the base file, `maglab_model::priors`):
//! a sensor whose bandwidth and delay the datasheet gives is fitted with the rod, so that its
//! lag is not absorbed into `R_eddy`, `ξ`, `f0`.
//!
//! On the bench plant (`maglab-plant`) with a sensor of each form of its library (an LVDT's
//! second-order demodulator, a capacitive probe's first-order filter, a laser's moving average;
//! 1.5 kHz at −3 dB, 50 µs conversion delay), the standard identification dataset
//! (`maglab_plant::bench::identification_design`) and 20 nm of noise, a base file whose
//! datasheet gives the sensor's −3 dB bandwidth ±10 % and its delay ±10 µs: `R_eddy`, `ξ`, `f0`
//! within 3 % of the plant's, the priors recorded in the identified file's provenance. The same
//! folder identified without the datasheet is printed beside it (`PRIORS_COMPARE=1`; it doubles
//! the test's time). `PRIORS_FORMS=0,1,2` runs those sensor forms (default: 1); `PRIORS_KEEP=1`
//! keeps the folders (printed).

mod common;

use actuator_params::{ActuatorParams, Datasheet, Toleranced};
use common::{constant_errors, pct, BenchFolder};
use maglab_identify::pipeline::PRIORS_KEY;
use maglab_plant::bench::{self, BenchSettings};
use maglab_plant::Effect;

/// The sensor's −3 dB bandwidth (every form's `natural_hz` is its −3 dB frequency but the
/// LVDT's, whose damping ratio 0.7 puts it 0.75 % higher: inside the datasheet's ±10 %), Hz.
const SENSOR_BANDWIDTH_HZ: f64 = 1500.0;
/// The sensor's conversion delay, s.
const SENSOR_DELAY_S: f64 = 5e-5;

/// A datasheet with the sensor's bandwidth ±10 % and its delay ±10 µs.
fn sensor_datasheet() -> Datasheet {
    Datasheet {
        sensor_bandwidth_hz: Some(Toleranced {
            value: SENSOR_BANDWIDTH_HZ,
            plus_minus: 0.1 * SENSOR_BANDWIDTH_HZ,
        }),
        sensor_delay_s: Some(Toleranced {
            value: SENSOR_DELAY_S,
            plus_minus: 1e-5,
        }),
        ..Datasheet::default()
    }
}

/// The identified file and its constants' errors (R_eddy, ξ, f0) against the plant's.
fn identified(form: usize, datasheet: Option<Datasheet>) -> (ActuatorParams, [f64; 3]) {
    let truth = actuator_params::paper_defaults();
    let effects = [Effect::parse(&format!(
        "sensor_dynamics:form={form},natural_hz={SENSOR_BANDWIDTH_HZ},delay_s={SENSOR_DELAY_S}"
    ))
    .expect("the sensor")];
    let settings = BenchSettings {
        noise_m: 20e-9,
        seed: 5,
        ..BenchSettings::default()
    };
    let recordings = bench::record_all(
        &truth,
        &effects,
        &bench::identification_design(settings.rate_hz),
        &settings,
    )
    .expect("rig");
    let folder = BenchFolder::write(
        &format!("datasheet-priors-{form}-{}", datasheet.is_some()),
        &recordings,
        true,
        "PRIORS_KEEP",
    );
    // A datasheet's constants, not the plant's: R_eddy, ξ, f0 off by ×1.4, ×0.75, ×1.2 (as
    // `lab/tests/common`'s base file), so that the fit does not start at its answer.
    let mut base = ActuatorParams {
        datasheet,
        ..truth.clone()
    };
    base.actuator.eddy_resistance_ohm *= 1.4;
    base.actuator.damping_ratio *= 0.75;
    base.actuator.resonance_hz *= 1.2;
    base.validate("base").expect("a valid base file");
    let id = folder.identify(&base, "base with a datasheet");
    let errors = constant_errors(&id.params, &truth);
    (id.params, errors)
}

#[test]
fn a_sensor_the_datasheet_gives_is_fitted_with_the_rod_and_not_absorbed_into_its_constants() {
    // By default the capacitive probe (a first-order filter: not the library's form; the laser
    // is `lab/tests/datasheet_priors.rs`'s), a CI budget; docs/identification.md's table is all
    // three.
    let forms: Vec<usize> = std::env::var("PRIORS_FORMS").map_or(vec![1], |v| {
        v.split(',')
            .map(|f| f.parse().expect("PRIORS_FORMS"))
            .collect()
    });
    for form in forms {
        let (file, with) = identified(form, Some(sensor_datasheet()));
        let recorded = file
            .provenance
            .details
            .get(PRIORS_KEY)
            .and_then(|v| v.as_array())
            .expect("the priors in the provenance");
        let bounds: Vec<&str> = recorded
            .iter()
            .filter_map(|u| u["bounds"].as_str())
            .collect();
        assert_eq!(
            bounds,
            ["sensor_dynamics.natural_hz", "sensor_dynamics.delay_s"]
        );
        assert_eq!(file.datasheet, Some(sensor_datasheet()), "kept in the file");
        let instruments = &file.provenance.details["dynamics"];
        println!("sensor form {form}: with the datasheet {}", pct(with));
        if std::env::var("PRIORS_COMPARE").is_ok() {
            let (_, without) = identified(form, None);
            println!("sensor form {form}: without it {}", pct(without));
        }
        assert!(
            with.iter().all(|e| e.abs() <= 0.03),
            "form {form}: {} ({instruments})",
            pct(with)
        );
    }
}
