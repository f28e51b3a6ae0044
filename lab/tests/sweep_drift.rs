//! `maglab identify`'s drift check (`maglab_identify::drift`) on the reversal sweeps of the bench
//! plant (`maglab-plant`: its own Preisach evaluation, integrator and effect forms, none shared
//! with the check): a sweep whose returns to the same extreme read differently is warned about
//! when something time-dependent or friction moves the rod, and only then — not for hysteresis,
//! a reversible part, backlash or a sensor nonlinearity, which are rate-independent. Magnitudes
//! as the blind suite draws them (`maglab_plant::suite`); the 64 sweeps of its seeds 1 and 4 are
//! in the module docs of `drift`.

use maglab_identify::drift::drift_warning;
use maglab_plant::bench::{forc_experiment, record};
use maglab_plant::{BenchSettings, Effect, Plant};

/// The warning for the plant's 1 Hz reversal sweep with `effects`, and its text.
fn sweep_warning(effects: &[&str]) -> Option<String> {
    let params = actuator_params::paper_defaults();
    let effects: Vec<Effect> = effects
        .iter()
        .map(|e| Effect::parse(e).expect("effect"))
        .collect();
    let settings = BenchSettings::default();
    let mut plant = Plant::new(&params, &effects, settings.rate_hz).expect("plant");
    let forc = forc_experiment(&params, 1.0, settings.rate_hz).expect("sweep");
    let r = record(&mut plant, &forc, &settings, 7).expect("recorded");
    drift_warning("00_forc.csv", &r.t_s, &r.current_a, &r.displacement_m)
}

#[test]
fn time_dependent_effects_and_friction_are_warned_about_rate_independent_ones_are_not() {
    let cases: [(&[&str], bool); 8] = [
        (&[], false),
        (&["reversible_magnetization:susceptibility=6"], false),
        (&["backlash:width_m=1e-5"], false),
        (
            &["sensor_nonlinearity:gain_change=-0.5,null_m=2e-5,range_m=1.65e-5"],
            false,
        ),
        (&["eddy_frequency_dependence", "amplifier_bandwidth"], false),
        (
            &["thermal_drift:coil_rise_k_per_a2=45,coil_time_constant_s=0.3,rod_time_constant_s=0.27,magnetostriction_loss_per_k=0.0175,expansion_m_per_k=1.1e-7"],
            true,
        ),
        (&["creep:ratio=0.55,time_constant_s=0.008"], true),
        (&["stick_slip:breakaway_m=4.6e-6,kinetic_ratio=0.55"], true),
    ];
    let results: Vec<Option<String>> = std::thread::scope(|s| {
        let handles: Vec<_> = cases
            .iter()
            .map(|(effects, _)| s.spawn(move || sweep_warning(effects)))
            .collect();
        handles
            .into_iter()
            .map(|h| h.join().expect("no panic"))
            .collect()
    });
    for ((effects, expected), warning) in cases.iter().zip(&results) {
        println!("{effects:?}: {warning:?}");
        assert_eq!(
            warning.is_some(),
            *expected,
            "{effects:?}: expected a warning: {expected}, got {warning:?}"
        );
    }
}
