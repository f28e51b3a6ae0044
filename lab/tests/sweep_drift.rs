//! `maglab identify`'s drift check (`maglab_model::drift`) on the reversal sweeps of the bench
//! plant (`maglab-plant`: its own Preisach evaluation, integrator and effect forms, none shared
//! with the check): a sweep whose returns to the same extreme read differently is warned about
//! when something time-dependent or friction moves the rod, and only then — not for hysteresis,
//! a reversible part, backlash or a sensor nonlinearity, which are rate-independent. Magnitudes
//! as the blind suite draws them (`maglab_plant::suite`); the 64 sweeps of its seeds 1 and 4 are
//! in the module docs of `drift`.

use maglab_model::drift::drift_warning;
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

/// The firmware's identification programme (`magctl::programme`) played tick by tick on the
/// bench plant with a lumped thermal drift: the peak coil temperature rise of the plant's own
/// thermal model, the spread of the FORC sweep's returns to its largest current and the drift
/// warning. `budget`: the file's `coil_thermal` section.
fn programme_on_heating_plant(
    budget: Option<actuator_params::CoilThermal>,
) -> (f64, f64, Option<String>, usize) {
    use magctl::inverse::OutputLimiter;
    use magctl::params::ActuatorParameters;
    use magctl::programme::IdentificationProgramme;
    let mut file = actuator_params::paper_defaults();
    file.coil_thermal = budget;
    let p = ActuatorParameters::from_file(&file, "defaults").expect("core parameters");
    let measure = p.preisach.measure();
    let limiter = OutputLimiter::new(&p.control).expect("limiter");
    let programme =
        IdentificationProgramme::for_parameters(&limiter, &p, &measure).expect("programme");
    // The plant's coil: 5.8 K/A² at the file's hot resistance (1 K/W on 5.8 Ω, copper at
    // +0.39 %/K from a cold 5.67 K/A²), τ 2 s; the rod behind it at 4 s.
    let thermal = "thermal_drift:coil_rise_k_per_a2=5.67,coil_time_constant_s=2,\
                   rod_time_constant_s=4,magnetostriction_loss_per_k=0.003,expansion_m_per_k=2e-8";
    let effects = [Effect::parse(thermal).expect("effect")];
    let rate_hz = p.control.sample_rate_hz as f64;
    let mut plant = Plant::new(&file, &effects, rate_hz).expect("plant");
    plant
        .start(maglab_dataset::StartState::SwitchOnDemagnetized, 0.0)
        .expect("start");
    let mut state = programme.start(0.0);
    let (mut peak_k, mut ticks) = (0.0f64, 0usize);
    let (mut t_s, mut current_a, mut y_m) = (Vec::new(), Vec::new(), Vec::new());
    while let Some(tick) = programme.step(&mut state) {
        let applied_a = limiter
            .limit_a()
            .min(tick.current_a.max(-limiter.limit_a())) as f64;
        plant.advance(applied_a, applied_a);
        peak_k = peak_k.max(plant.coil_temperature_rise_k());
        ticks += 1;
        if let (0, Some(k)) = (tick.experiment, tick.sample) {
            t_s.push(k as f64 / rate_hz);
            current_a.push(applied_a);
            y_m.push(plant.displacement_m());
        }
    }
    let [top, _] = maglab_model::drift::extreme_visits(&t_s, &current_a, &y_m);
    let range_m = y_m.iter().cloned().fold(f64::NEG_INFINITY, f64::max)
        - y_m.iter().cloned().fold(f64::INFINITY, f64::min);
    let warning = drift_warning("00_forc.csv", &t_s, &current_a, &y_m);
    (peak_k, top.spread_m() / range_m, warning, ticks)
}

/// Issue: "a sweep that does not cook the coil". Without a budget the programme heats the plant's
/// coil past 7 K and the FORC sweep's returns to its top drift apart (warned); with a 6 K budget
/// the plant's coil, whose thermal model is not the firmware's estimate (copper resistance rising
/// with temperature, its own integrator), stays at or below 6 K, and the sweep drifts less.
#[test]
fn a_coil_heat_budget_bounds_the_plants_coil_rise_and_the_sweeps_drift() {
    let budget = actuator_params::CoilThermal {
        thermal_resistance_k_per_w: 1.0,
        time_constant_s: 2.0,
        max_rise_k: 6.0,
    };
    let (without, with) = std::thread::scope(|s| {
        let a = s.spawn(|| programme_on_heating_plant(None));
        let b = s.spawn(move || programme_on_heating_plant(Some(budget)));
        (a.join().expect("no panic"), b.join().expect("no panic"))
    });
    for (name, (peak_k, spread, warning, ticks)) in [("without", &without), ("with", &with)] {
        println!(
            "{name} a 6 K budget: {ticks} ticks, plant coil peak rise {peak_k:.2} K, spread at the \
             sweep's top {:.2} % of its range, warning {warning:?}",
            spread * 100.0
        );
    }
    assert!(
        without.0 > 7.0,
        "the programme heats the coil: {}",
        without.0
    );
    assert!(with.0 <= 6.0, "the budget holds on the plant: {}", with.0);
    assert!(
        without.2.is_some(),
        "drift without the budget is warned about"
    );
    assert!(with.1 < without.1, "less drift with the budget");
}
