//! Acceptance tests of the diagnosis on rig data (issue 6). The effect's identity is never passed
//! to `diagnose`: it sees the nominal parameter file and the measurement records only.
//!
//! Dataset: sines with 0.5 A bias at 20, 50, 100, 200, 300, 400 Hz × amplitudes 0.2 and 0.4 A,
//! 0.4 s each at 10 kHz (12 experiments; held out: 50 and 300 Hz). Sensor noise σ = 0.15 µm
//! (0.2 % of the 67 µm stroke) plus a 2 nm quantization step.
//!
//! Why the thresholds are what they are:
//! * "held-out error shrinks at least 3×" is the acceptance number. The floor the
//!   augmented model can reach is the noise (0.15 µm) plus the rig/model discretization
//!   difference: the rig evaluates the parameter file's Preisach measure exactly (the default
//!   of `RigOptions`), so what remains is time discretization (rig: RK4, 20 substeps; model:
//!   Richardson-extrapolated 2/4 substeps), measured ≤ 0.02 % of the motion (≤ 0.005 µm) without
//!   effects. Every effect is switched on at its default magnitude, which makes a nominal
//!   held-out gap of 0.6-3.7 µm (4-25 σ): "a visible gap", and ≥ 3× is reachable only if the
//!   right effect is identified with roughly the right parameters.
//! * Noise only: the diagnosis must answer `none` when the noise dominates the residual; the
//!   discretization floor (≤ 0.005 µm) is far below the σ = 0.15 µm of the sensor.

use actuator_params::ActuatorParams;
use maglab_diagnose::diagnosis::{diagnose, DiagnoseOptions, Diagnosis};
use maglab_diagnose::effects::{EffectName, RigEffect};
use maglab_diagnose::model::{simulate, Augmentation, Nominal};
use maglab_diagnose::rig::{self, RigOptions};
use maglab_identify::data::Measurement;

const FREQS_HZ: [f64; 6] = [20.0, 50.0, 100.0, 200.0, 300.0, 400.0];

/// Each test already uses every core (rayon: experiments of the rig, candidates and experiments
/// of the diagnosis). Two tests at once on the shared rayon pool interleave through work
/// stealing and finish later than one after the other (measured on 2 cores: 100 s against 49 s
/// for the file), so the tests of this file take turns.
static ONE_AT_A_TIME: std::sync::Mutex<()> = std::sync::Mutex::new(());

fn one_at_a_time() -> std::sync::MutexGuard<'static, ()> {
    // A failed (panicked) test poisons the lock; the next test can still run.
    ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner())
}

fn rig_options(noise_m: f64, seed: u64) -> RigOptions {
    RigOptions {
        duration_s: 0.4,
        noise_m,
        seed,
        ..RigOptions::default()
    }
}

fn dataset(
    params: &ActuatorParams,
    effects: &[RigEffect],
    freqs: &[f64],
    noise_m: f64,
    seed: u64,
) -> Vec<Measurement> {
    let excitations = rig::sine_sweep(freqs, &[0.2, 0.4], 0.5);
    rig::generate(
        params,
        effects,
        &excitations,
        &rig_options(noise_m, seed),
        &|_| {},
    )
    .expect("rig runs")
    .into_iter()
    .map(|e| Measurement {
        path: format!("{}.csv", e.name).into(),
        t_s: e.t_s,
        current_a: e.current_a,
        displacement_m: e.displacement_m,
        step_s: 1e-4,
    })
    .collect()
}

fn run(params: &ActuatorParams, data: &[Measurement]) -> Diagnosis {
    run_with(params, data, &DiagnoseOptions::default())
}

fn run_with(params: &ActuatorParams, data: &[Measurement], options: &DiagnoseOptions) -> Diagnosis {
    let started = std::time::Instant::now();
    let d = diagnose(params, data, options, &|_| {})
        .expect("diagnosis runs")
        .diagnosis;
    let evaluations: u64 = d.ranking.iter().map(|c| c.evaluations).sum();
    println!(
        "diagnosis took {:.1} s ({evaluations} candidate model evaluations)",
        started.elapsed().as_secs_f64()
    );
    println!("verdict {} ({})", d.verdict, d.verdict_reason);
    for c in &d.ranking {
        println!(
            "  {:26} held-out {:.3e} -> {:.3e} m ({:.2}x, {}/{}, significant {}) {:?}",
            c.effect,
            c.held_out_rms_before_m,
            c.held_out_rms_after_m,
            c.held_out_reduction,
            c.improved_experiments,
            c.held_out_experiments,
            c.significant,
            c.parameters
        );
    }
    for b in &d.where_.bands {
        println!(
            "  band {:6.1} Hz: rms {:.3e} sys {:.3e} rel {:.4} amp {:.4} phase {:.2} deg disagrees {}",
            b.frequency_hz, b.rms_m, b.systematic_m, b.relative_gap, b.amplitude_ratio,
            b.phase_error_deg, b.disagrees
        );
    }
    for s in &d.where_.summary {
        println!("  * {s}");
    }
    d
}

fn check_single(effect: EffectName) {
    let _turn = one_at_a_time();
    let params = actuator_params::paper_defaults();
    let data = dataset(
        &params,
        &[RigEffect::default_for(effect)],
        &FREQS_HZ,
        0.15e-6,
        11,
    );
    let d = run(&params, &data);
    assert_eq!(d.verdict, effect.name(), "verdict for {effect}");
    let best = &d.ranking[0];
    assert!(
        best.held_out_reduction >= 3.0,
        "{effect}: held-out reduction {:.2}",
        best.held_out_reduction
    );
}

#[test]
fn names_eddy_frequency_dependence() {
    check_single(EffectName::EddyFrequencyDependence);
}

#[test]
fn names_amplifier_bandwidth() {
    check_single(EffectName::AmplifierBandwidth);
}

#[test]
fn names_sensor_dynamics() {
    check_single(EffectName::SensorDynamics);
}

#[test]
fn names_reversible_magnetization() {
    check_single(EffectName::ReversibleMagnetization);
}

#[test]
fn names_thermal_drift() {
    check_single(EffectName::ThermalDrift);
}

#[test]
fn names_delta_e_effect() {
    check_single(EffectName::DeltaEEffect);
}

#[test]
fn names_mechanical_load() {
    check_single(EffectName::MechanicalLoad);
}

#[test]
fn two_effects_are_the_top_two() {
    let _turn = one_at_a_time();
    let params = actuator_params::paper_defaults();
    let effects = [
        RigEffect::default_for(EffectName::AmplifierBandwidth),
        RigEffect::default_for(EffectName::ThermalDrift),
    ];
    let data = dataset(&params, &effects, &FREQS_HZ, 0.15e-6, 12);
    let d = run(&params, &data);
    let top: Vec<&str> = d.ranking[..2].iter().map(|c| c.effect.as_str()).collect();
    assert!(
        top.contains(&"amplifier_bandwidth") && top.contains(&"thermal_drift"),
        "top two: {top:?}"
    );
}

#[test]
fn backlash_is_unexplained() {
    let _turn = one_at_a_time();
    let params = actuator_params::paper_defaults();
    let data = dataset(
        &params,
        &[RigEffect::default_for(EffectName::Backlash)],
        &FREQS_HZ,
        0.15e-6,
        13,
    );
    let d = run(&params, &data);
    assert_eq!(d.verdict, "unexplained");
}

#[test]
fn noise_only_is_none() {
    let _turn = one_at_a_time();
    let params = actuator_params::paper_defaults();
    let data = dataset(&params, &[], &FREQS_HZ, 0.15e-6, 14);
    let d = run(&params, &data);
    assert_eq!(d.verdict, "none");
    // The noise estimate recovers the rig's σ: ~700 periodogram bins above 0.3 f_s per
    // experiment (3600 scored samples), so each experiment's σ is within ~2 % (1/√(2·700) of σ²
    // halved), and the median of 12 is tighter; allow 10 % for quantization (2 nm, negligible)
    // and residual model error leaking into the band.
    assert!(
        (d.noise_m - 0.15e-6).abs() < 0.015e-6,
        "noise estimate {:.3e}",
        d.noise_m
    );
}

/// The paper's situation: R_eddy identified from data up to 100 Hz (1-D golden-section search of
/// the nominal model's RMS error), the rig's R_eddy depends on frequency, data up to 400 Hz. The
/// rig's extra eddy path (50 Ω, corner 400 Hz, beside the nominal 70 Ω) makes the effective
/// resistance rise from 29.2 Ω at DC to 30.2 Ω at 100 Hz, 33 Ω at 200 Hz and 41 Ω at 400 Hz; its
/// inductance also gives the eddy admittance a reactive part no single resistor has, so even the
/// identified model leaves an error that grows steadily with frequency inside the identification
/// band. The diagnosis is told that band (`identified_up_to_hz = 100`), and the gap onset is where
/// the error exceeds twice the agreement reached there (`maglab_diagnose::breakdown`).
#[test]
fn paper_situation_eddy_identified_below_100_hz() {
    let _turn = one_at_a_time();
    let truth = actuator_params::paper_defaults();
    let eddy = RigEffect::parse("eddy_frequency_dependence:path_ohm=50,corner_hz=400").unwrap();
    let data = dataset(&truth, std::slice::from_ref(&eddy), &FREQS_HZ, 0.15e-6, 15);
    // Identify R_eddy on the experiments at or below 100 Hz.
    let low: Vec<&Measurement> = data
        .iter()
        .filter(|m| {
            let name = m.path.to_string_lossy().into_owned();
            ["00020.0hz", "00050.0hz", "00100.0hz"]
                .iter()
                .any(|f| name.contains(f))
        })
        .collect();
    assert_eq!(low.len(), 6);
    let core = rig::to_core(&truth).unwrap();
    let measure = magctl::preisach::PreisachMeasure::new(
        &core.preisach.weights_a_per_m,
        core.preisach.h_min_a_per_m,
        core.preisach.h_max_a_per_m,
    );
    let cost = |r_ohm: f64| -> f64 {
        let mut p = truth.clone();
        p.actuator.eddy_resistance_ohm = r_ohm;
        let nominal = Nominal::from_params(&p);
        low.iter()
            .map(|m| {
                let y = simulate(
                    &nominal,
                    &measure,
                    &Augmentation::default(),
                    &m.current_a,
                    1e-4,
                    DiagnoseOptions::default().substeps,
                );
                m.displacement_m
                    .iter()
                    .zip(&y)
                    .skip(400)
                    .map(|(a, b)| (a - b) * (a - b))
                    .sum::<f64>()
            })
            .sum()
    };
    // Golden section on log R over [5, 500] Ω.
    let (mut a, mut b) = (5f64.ln(), 500f64.ln());
    let g = 0.5 * (5f64.sqrt() - 1.0);
    let (mut c, mut d) = (b - g * (b - a), a + g * (b - a));
    let (mut fc, mut fd) = (cost(c.exp()), cost(d.exp()));
    for _ in 0..30 {
        if fc < fd {
            b = d;
            d = c;
            fd = fc;
            c = b - g * (b - a);
            fc = cost(c.exp());
        } else {
            a = c;
            c = d;
            fc = fd;
            d = a + g * (b - a);
            fd = cost(d.exp());
        }
    }
    let r_id = (0.5 * (a + b)).exp();
    let r_eff = |f_hz: f64| {
        host_tests::reference::rig::effective_eddy_resistance_ohm(
            truth.actuator.eddy_resistance_ohm,
            &[host_tests::reference::rig::EddyPath {
                resistance_ohm: eddy.get("path_ohm"),
                corner_hz: eddy.get("corner_hz"),
            }],
            f_hz,
        )
    };
    println!(
        "R_eddy identified <= 100 Hz: {r_id:.2} ohm (rig's effective R: {:.2} ohm at 20 Hz, \
         {:.2} ohm at 100 Hz, {:.2} ohm at 400 Hz)",
        r_eff(20.0),
        r_eff(100.0),
        r_eff(400.0)
    );
    let mut identified = truth.clone();
    identified.actuator.eddy_resistance_ohm = r_id;
    let options = DiagnoseOptions {
        identified_up_to_hz: Some(100.0),
        ..DiagnoseOptions::default()
    };
    let d = run_with(&identified, &data, &options);
    assert_eq!(d.verdict, "eddy_frequency_dependence");
    // The "shrinks at least 3x" on the held-out RMS (noise included, so the bound is
    // the noise floor σ: reachable because the nominal held-out error is ≈ 4 σ).
    assert!(
        d.ranking[0].held_out_reduction >= 3.0,
        "reduction {:.2}",
        d.ranking[0].held_out_reduction
    );
    // The model was identified up to 100 Hz, so the gap must start above that band: the next
    // band, 200 Hz, where the effective R has risen 13 % over its low-frequency value, and every
    // band above must disagree too (the rule's "from which every higher band disagrees").
    let start = d.where_.gap_start_hz.expect("a gap onset");
    println!("gap starts at {start:.0} Hz");
    assert!((start - 200.0).abs() < 10.0, "gap start {start} Hz");
}
