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
//!   difference (measured 0.2-0.4 % of the motion, ≈ 0.1 µm: relay field with 64 relays per cell
//!   side vs the exact cell-uniform operator, and the model's Richardson-extrapolated steps), so
//!   every effect is switched on at its default magnitude, which makes a nominal gap of 1.5-4 µm
//!   (4-10 % of the motion): "a visible gap", and ≥ 3× is reachable only if the right effect
//!   is identified with roughly the right parameters.
//! * Noise only: the diagnosis must answer `none` when the noise dominates the residual; with the
//!   rig's discretization floor ≈ 0.1 µm, a noise σ of 0.25 µm keeps the systematic part (the
//!   floor) below σ, which is what `none` means.

use actuator_params::ActuatorParams;
use maglab_diagnose::diagnosis::{diagnose, DiagnoseOptions, Diagnosis};
use maglab_diagnose::effects::{EffectName, RigEffect};
use maglab_diagnose::model::{simulate, Augmentation, Nominal};
use maglab_diagnose::rig::{self, RigOptions};
use maglab_identify::data::Measurement;

const FREQS_HZ: [f64; 6] = [20.0, 50.0, 100.0, 200.0, 300.0, 400.0];

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
    let d = diagnose(params, data, &DiagnoseOptions::default(), &|_| {})
        .expect("diagnosis runs")
        .diagnosis;
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
    for s in &d.where_.summary {
        println!("  * {s}");
    }
    d
}

fn check_single(effect: EffectName) {
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
    let params = actuator_params::paper_defaults();
    let data = dataset(&params, &[], &FREQS_HZ, 0.25e-6, 14);
    let d = run(&params, &data);
    assert_eq!(d.verdict, "none");
    // The noise estimate recovers the rig's σ: ~1.5·10⁴ bins per experiment in the median band,
    // statistical error < 2 %; allow 10 % for quantization (2 nm, negligible) and residual model
    // error leaking into the band.
    assert!(
        (d.noise_m - 0.25e-6).abs() < 0.025e-6,
        "noise estimate {:.3e}",
        d.noise_m
    );
}

/// The paper's situation: R_eddy identified from data up to 100 Hz (1-D golden-section search of
/// the nominal model's RMS error), the rig's R_eddy depends on frequency, data up to 400 Hz. As in
/// the paper (agreement up to ~200 Hz), the rig's extra eddy path has its corner at 400 Hz, so
/// the effective R_eddy is nearly constant below 100 Hz (within 6 %) and rises above.
#[test]
fn paper_situation_eddy_identified_below_100_hz() {
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
                    4,
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
    let r_low = host_tests::reference::rig::effective_eddy_resistance_ohm(
        70.0,
        &[host_tests::reference::rig::EddyPath {
            resistance_ohm: 50.0,
            corner_hz: 150.0,
        }],
        50.0,
    );
    println!("R_eddy identified <= 100 Hz: {r_id:.2} ohm (ladder's effective R at 50 Hz: {r_low:.2} ohm)");
    let mut identified = truth.clone();
    identified.actuator.eddy_resistance_ohm = r_id;
    let d = run(&identified, &data);
    assert_eq!(d.verdict, "eddy_frequency_dependence");
    assert!(
        d.ranking[0].held_out_reduction >= 3.0,
        "reduction {:.2}",
        d.ranking[0].held_out_reduction
    );
    // The model was fitted up to 100 Hz, so it must agree there and the gap must start above:
    // at 200, 300 or 400 Hz (where exactly it crosses the onset rule depends on the noise).
    let start = d.where_.gap_start_hz.expect("a gap onset");
    println!("gap starts at {start:.0} Hz");
    assert!(start > 110.0 && start <= 410.0, "gap start {start}");
}
