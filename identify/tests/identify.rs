//! `identify` end to end on a synthetic dataset: FORC current from `excite`, displacement from
//! the relay reference through the static model (6) with LVDT noise, written in the measurement
//! format, read back, identified; the output is a valid parameter file whose provenance records
//! what was and was not identified.

use host_tests::reference::preisach::RelayPreisach;
use maglab_dataset::data::{load_dataset, write_measurement};
use maglab_dataset::excitation::{forc_excitation, ExciteOptions};
use maglab_dataset::StartState;
use maglab_identify::fit::{FitOptions, Unexcited};
use maglab_identify::magnetization::{Branch, StaticModel};
use maglab_identify::masses::{identify_masses, MassOptions};
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};

fn statics(p: &actuator_params::ActuatorParams) -> StaticModel {
    StaticModel {
        rod_length_m: p.actuator.rod_length_m,
        saturation_magnetostriction: p.actuator.saturation_magnetostriction,
        saturation_magnetization_a_per_m: p.actuator.saturation_magnetization_a_per_m,
    }
}

/// A temporary folder holding one measurement `run.csv` (removed when dropped).
fn dataset(current: &[f64], y: &[f64]) -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    let t: Vec<f64> = (0..current.len()).map(|k| k as f64 * 1e-3).collect();
    write_measurement(&dir.path().join("run.csv"), &t, current, y, None).unwrap();
    dir
}

/// The FORC excitation of `p`'s grid (1 Hz sweeps at 1 kHz) and the displacement `reference`
/// plus `extra_a_per_m(h)` (a reversible part, A/m) gives, with LVDT noise of 0.1 % of the stroke.
fn noisy_forc_record(
    p: &actuator_params::ActuatorParams,
    reference: &RelayPreisach,
    seed: u64,
    extra_a_per_m: impl Fn(f64) -> f64,
) -> (Vec<f64>, Vec<f64>) {
    let e = forc_excitation(&ExciteOptions {
        h_min_a_per_m: p.preisach.h_min_a_per_m,
        h_max_a_per_m: p.preisach.h_max_a_per_m,
        coil_factor_per_m: p.actuator.coil_factor_per_m,
        sweep_rate_hz: 1.0,
        sample_rate_hz: 1000.0,
        overdrive: 0.01,
    })
    .unwrap();
    let model = statics(p);
    let noise = Normal::new(0.0, 1e-3 * model.stroke_m()).unwrap();
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    let mut state = reference.negative_saturation();
    let y: Vec<f64> = e
        .current_a
        .iter()
        .map(|i| {
            let h = i * p.actuator.coil_factor_per_m;
            let m = reference.apply_a_per_m(&mut state, h) + extra_a_per_m(h);
            model.displacement_m(m) + noise.sample(&mut rng)
        })
        .collect();
    (e.current_a, y)
}

/// The paper's defaults and a noisy FORC record of their masses (the relay reference, 16 relays
/// per cell side), nothing beside the hysteresis.
fn paper_forc_record(seed: u64) -> (actuator_params::ActuatorParams, Vec<f64>, Vec<f64>) {
    let p = actuator_params::paper_defaults();
    let (h_min, h_max) = (p.preisach.h_min_a_per_m, p.preisach.h_max_a_per_m);
    let reference = RelayPreisach::new(&p.preisach.weights_a_per_m, h_min, h_max, 16).unwrap();
    let (current_a, y) = noisy_forc_record(&p, &reference, seed, |_| 0.0);
    (p, current_a, y)
}

/// The options for a sweep that starts at negative saturation and rises monotonically between
/// reversals (`noisy_forc_record`), its current read `shift` samples later; cells the sweep
/// never switches keep the prior masses.
fn forc_options(shift: f64) -> MassOptions {
    MassOptions {
        branch: Some(Branch::Monotone),
        initial: Some(StartState::NegativeSaturation),
        documented: None,
        lag_correction: None,
        current_shift_samples: shift,
        reach: None,
        zero_band_fraction: 0.01,
        fit: FitOptions {
            unexcited: Unexcited::KeepPrior,
            ..FitOptions::default()
        },
    }
}

#[test]
fn forc_dataset_identifies_to_a_valid_parameter_file() {
    let (p, current_a, y) = paper_forc_record(5);
    let dir = dataset(&current_a, &y);
    let ds = load_dataset(dir.path()).unwrap();
    let id = identify_masses(&ds, &p, "paper defaults", &forc_options(0.0)).unwrap();
    // Noise reaches below zero near M = 0: clipped and counted, not hidden.
    assert!(id.files[0].clipped_negative > 0);
    assert!(id.fit.unexcited.is_empty());
    // Displacement prediction on the training run: within the noise plus 1 % of the stroke.
    let nrmse_y = id.files[0].nrmse_displacement.unwrap();
    println!(
        "identify on FORC data: NRMSE y {:.3} %, M {:.3} %",
        100.0 * nrmse_y,
        100.0 * id.files[0].nrmse_magnetization.unwrap()
    );
    assert!(nrmse_y <= 0.01, "{nrmse_y}");
    // The file round-trips through the schema the firmware build reads.
    let text = id.params.to_json_pretty();
    let back = actuator_params::ActuatorParams::parse(&text, "identified").unwrap();
    assert_eq!(back.preisach.weights_a_per_m, id.fit.weights);
    assert_eq!(
        back.actuator.eddy_resistance_ohm,
        p.actuator.eddy_resistance_ohm
    );
    let prov = &back.provenance.details;
    assert!(prov["not_identified"]["fields"].as_array().unwrap().len() == 3);
    assert_eq!(prov["dataset"], dir.path().display().to_string());
    assert!(prov.contains_key("date") && prov.contains_key("fit"));
}

#[test]
fn biased_data_are_identified_on_the_reach_with_a_band_below_it() {
    // DC-biased quasi-static current I >= 0 from the demagnetized state: M >= 0 (order
    // preservation), the positive branch is exact, but the hysterons with β below H = 0 never
    // switch down. The grid becomes the reach [0, h_max] with a band below it (the hysterons
    // with β < 0, which can only switch up), the rest an offset: the model predicts the data.
    let p = actuator_params::paper_defaults();
    let (h_min, h_max) = (p.preisach.h_min_a_per_m, p.preisach.h_max_a_per_m);
    let reference = RelayPreisach::new(&p.preisach.weights_a_per_m, h_min, h_max, 8).unwrap();
    let i_max = h_max / p.actuator.coil_factor_per_m;
    let mut current = Vec::new();
    for amp in [1.0, 0.8, 0.6, 0.4, 0.2] {
        for k in 0..=400 {
            let s = k as f64 / 400.0;
            current.push(i_max * amp * 0.5 * (1.0 - (2.0 * std::f64::consts::PI * s).cos()));
        }
    }
    let model = statics(&p);
    // The reference's demagnetized state is centred at H = 0 = the first current.
    let mut state = reference.demagnetized();
    let y: Vec<f64> = current
        .iter()
        .map(|i| {
            model.displacement_m(
                reference.apply_a_per_m(&mut state, i * p.actuator.coil_factor_per_m),
            )
        })
        .collect();
    let dir = dataset(&current, &y);
    let ds = load_dataset(dir.path()).unwrap();
    let id = identify_masses(
        &ds,
        &p,
        "paper defaults",
        &MassOptions {
            branch: Some(Branch::Positive),
            initial: Some(StartState::Demagnetized),
            documented: None,
            lag_correction: None,
            current_shift_samples: 0.0,
            reach: None,
            zero_band_fraction: 0.01,
            fit: FitOptions {
                unexcited: Unexcited::KeepPrior,
                ..FitOptions::default()
            },
        },
    )
    .unwrap();
    let pre = &id.params.preisach;
    let reach = pre.reach_a_per_m.as_deref().expect("a reach");
    assert!(
        reach[0].abs() < 1e-6 && (reach[1] - h_max).abs() < 1e-6 * h_max,
        "{reach:?}"
    );
    // Low band only: the data reach the grid's top.
    assert!(pre.h_min_a_per_m < 0.0 && (pre.h_max_a_per_m - h_max).abs() < 1e-6 * h_max);
    // Unexcited cells: band cells (fixed at 0) or regularized, never the base grid's prior.
    println!(
        "biased data: {} unexcited cells, offset {:.0} A/m",
        id.fit.unexcited.len(),
        pre.offset_a_per_m
    );
    for &k in &id.fit.unexcited {
        let (i, _) = maglab_identify::cell_of_index(k);
        if i == 0 {
            assert_eq!(id.fit.weights[k], 0.0);
        }
    }
    assert!(id.files[0].nrmse_magnetization.unwrap() <= 0.01);
}

/// `maglab identify --reversible piecewise` on data whose magnetization has a reversible part:
/// the relay reference with 80 % of the paper's masses plus a bell-shaped anhysteretic
/// `R(H)` carrying the other 20 % of the saturation, evaluated from its definition in f64
/// (`host_tests::reference::preisach::reversible_a_per_m`). The identified `R` follows the true one, the
/// saturation output `Σ w + ½ Σ χ Δ` is `M_s`, and the fit is better than the paper's `M = Γ[H]`
/// alone on the same data.
#[test]
fn a_reversible_part_is_identified_with_the_masses() {
    use host_tests::reference::preisach::reversible_a_per_m;
    use maglab_identify::fit::Reversible;
    let p = actuator_params::paper_defaults();
    let (h_min, h_max) = (p.preisach.h_min_a_per_m, p.preisach.h_max_a_per_m);
    let total: f64 = p.preisach.weights_a_per_m.iter().sum();
    let masses: Vec<f64> = p.preisach.weights_a_per_m.iter().map(|w| 0.8 * w).collect();
    let reference = RelayPreisach::new(&masses, h_min, h_max, 16).unwrap();
    let levels = p.preisach.levels;
    let lines: Vec<f64> = (0..=levels)
        .map(|k| h_min + (h_max - h_min) * k as f64 / levels as f64)
        .collect();
    let shape: Vec<f64> = (0..levels)
        .map(|k| {
            let mid = 0.5 * (lines[k] + lines[k + 1]);
            1.0 / (4.0 * mid / (h_max - h_min)).cosh().powi(2)
        })
        .collect();
    let rise: f64 = (0..levels)
        .map(|k| shape[k] * (lines[k + 1] - lines[k]))
        .sum();
    let chi: Vec<f64> = shape.iter().map(|s| s * 2.0 * 0.2 * total / rise).collect();
    let (current_a, y) =
        noisy_forc_record(&p, &reference, 7, |h| reversible_a_per_m(&lines, &chi, h));
    let dir = dataset(&current_a, &y);
    let ds = load_dataset(dir.path()).unwrap();
    let run = |reversible: Reversible| {
        let base = forc_options(0.0);
        let options = MassOptions {
            fit: FitOptions {
                reversible,
                ..base.fit
            },
            ..base
        };
        identify_masses(&ds, &p, "paper defaults", &options).unwrap()
    };
    let with = run(Reversible::PiecewiseNoOffset);
    let without = run(Reversible::None);
    let fitted = with
        .params
        .preisach
        .reversible_susceptibility
        .clone()
        .expect("the parameter file carries the reversible part");
    assert!(without.params.preisach.reversible_susceptibility.is_none());
    // R identified vs true, over the grid, relative to M_s.
    let ms = p.actuator.saturation_magnetization_a_per_m;
    let worst_r = (0..=200)
        .map(|n| h_min + (h_max - h_min) * n as f64 / 200.0)
        .map(|h| {
            (reversible_a_per_m(&lines, &fitted, h) - reversible_a_per_m(&lines, &chi, h)).abs()
        })
        .fold(0.0, f64::max);
    let half_span: f64 = 0.5
        * (0..levels)
            .map(|k| fitted[k] * (lines[k + 1] - lines[k]))
            .sum::<f64>();
    let saturation = with.fit.weights.iter().sum::<f64>() + half_span;
    let (nrmse_with, nrmse_without) = (
        with.files[0].nrmse_displacement.unwrap(),
        without.files[0].nrmse_displacement.unwrap(),
    );
    println!(
        "reversible part: worst |R_fit - R_true| {:.2} % of M_s (R spans {:.0} % of M_s), \
         saturation {:.4} M_s; NRMSE y with R {:.3} %, without {:.3} %",
        100.0 * worst_r / ms,
        100.0 * 0.4 * total / ms,
        saturation / ms,
        100.0 * nrmse_with,
        100.0 * nrmse_without
    );
    assert!(worst_r <= 0.05 * ms, "R off by {worst_r} A/m");
    assert!(
        (saturation / ms - 1.0).abs() <= 0.02,
        "saturation {saturation} vs M_s {ms}"
    );
    assert!(nrmse_with <= 0.01, "{nrmse_with}");
    assert!(
        nrmse_with < nrmse_without,
        "{nrmse_with} vs {nrmse_without}"
    );
    // The file round-trips through the schema the firmware build reads.
    let back = actuator_params::ActuatorParams::parse(&with.params.to_json_pretty(), "identified")
        .unwrap();
    assert_eq!(back.preisach.reversible_susceptibility, Some(fitted));
}

/// A displacement channel read later than the current (a channel skew) shifts every branch of
/// the sweep along the field: the loops look wider than the material's. Reading the current at
/// the displacement's time (`current_shift_samples`) takes that width back out of the masses.
#[test]
fn a_channel_skew_is_taken_out_of_the_masses_by_the_current_shift() {
    let (p, current_a, y) = paper_forc_record(11);
    // The displacement of sample k is the rod's at sample k + 3: read 3 ms after the current.
    let skew = 3;
    let n = current_a.len();
    let dir = dataset(&current_a[..n - skew], &y[skew..]);
    let ds = load_dataset(dir.path()).unwrap();
    let run =
        |shift: f64| identify_masses(&ds, &p, "paper defaults", &forc_options(shift)).unwrap();
    let ms = p.actuator.saturation_magnetization_a_per_m;
    let l1 = |w: &[f64]| {
        w.iter()
            .zip(&p.preisach.weights_a_per_m)
            .map(|(a, b)| (a - b).abs())
            .sum::<f64>()
            / ms
    };
    let (plain, aligned, half) = (run(0.0), run(skew as f64), run(skew as f64 - 0.5));
    println!(
        "skew 3 samples: RMS residual {:.0} A/m unshifted, {:.0} A/m shifted by 3, {:.0} A/m by 2.5; \
         masses off in L1 by {:.2} %, {:.2} %, {:.2} % of M_s",
        plain.fit.rms_residual,
        aligned.fit.rms_residual,
        half.fit.rms_residual,
        100.0 * l1(&plain.fit.weights),
        100.0 * l1(&aligned.fit.weights),
        100.0 * l1(&half.fit.weights)
    );
    assert!(aligned.fit.rms_residual < 0.6 * plain.fit.rms_residual);
    assert!(l1(&aligned.fit.weights) < 0.5 * l1(&plain.fit.weights));
    // Half a sample off lies between (the current is linear between samples): the residual is
    // at the noise's level either way, the masses are best at the true skew.
    assert!(half.fit.rms_residual < 0.6 * plain.fit.rms_residual);
    assert!(l1(&aligned.fit.weights) < l1(&half.fit.weights));
    assert!(l1(&half.fit.weights) < 0.5 * l1(&plain.fit.weights));
}
