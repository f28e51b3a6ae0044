//! The recording's nuisances, estimated with a given model before anything is fitted: the start
//! state of undocumented experiments (one plan for the dataset), what the current does between
//! samples, the channel skew; and the memory a quasi-static lead-in record leaves.

use crate::experiments::experiment_data;
use crate::fit::{ExperimentData, ModelSetup};
use crate::model::{run_mech, Electro, Mech, Memory, ModelStart};
use crate::residual::{offset_of, pooled_rms};
use maglab_dataset::data::Measurement;
use maglab_dataset::{CurrentBetweenSamples, StartState};
use rayon::prelude::*;
use std::sync::Arc;

/// Start choices tried when none is documented.
pub const START_CHOICES: [StartState; 5] = [
    StartState::Demagnetized,
    StartState::SwitchOnDemagnetized,
    StartState::NegativeSaturation,
    StartState::PositiveSaturation,
    StartState::Previous,
];

/// The start plans (step 2): documented starts are fixed; the others follow one dataset-wide
/// plan (a bench starts its experiments one way), each plan a start per experiment and whether
/// it continues the previous experiment (its coil temperature carries over too). An experiment
/// that continues a lead-in record (`lead_ins[k]`: the memory the quasi-static record before it
/// left, simulated once, see [`lead_in_memory`]) starts from that memory instead of simulating
/// the record in every fit; the first experiment of a chain without one starts demagnetized.
pub fn start_sets(
    documented: &[Option<StartState>],
    lead_ins: &[Option<Arc<Memory>>],
) -> Vec<(StartState, Vec<(ModelStart, bool)>)> {
    let plans: Vec<StartState> = if documented.iter().all(|s| s.is_some()) {
        vec![StartState::Demagnetized]
    } else {
        START_CHOICES.to_vec()
    };
    plans
        .iter()
        .map(|&plan| {
            let starts = (0..documented.len())
                .map(|k| {
                    let choice = documented[k].unwrap_or(plan);
                    let chained = choice == StartState::Previous && k > 0;
                    let lead_in = lead_ins.get(k).and_then(Option::as_ref);
                    let start = match (choice, lead_in) {
                        (StartState::Previous, Some(m)) => ModelStart::After(m.clone()),
                        (StartState::Previous, None) if k == 0 => {
                            ModelStart::State(StartState::Demagnetized)
                        }
                        _ => ModelStart::State(choice),
                    };
                    (start, chained)
                })
                .collect();
            (plan, starts)
        })
        .collect()
}

/// The memory the quasi-static record `record` leaves, simulated once with the constants of
/// `electro` from its documented start (`demagnetized` when it has none or continues another: a
/// reversal sweep saturates the rod and wipes out its start). An experiment recorded right after
/// it without a reset starts from this memory, [`ModelStart::After`]: the memory of a slow
/// record hardly depends on `R_eddy`, `ξ`, `f0` or on any effect of the library (none of them
/// changes the field history at its frequency), so it is not re-simulated in every fit.
pub fn lead_in_memory(
    setup: &ModelSetup<'_>,
    electro: &Electro,
    record: &Measurement,
    documented: Option<StartState>,
) -> Arc<Memory> {
    let start = documented.filter(|s| *s != StartState::Previous).map_or(
        ModelStart::State(StartState::Demagnetized),
        ModelStart::State,
    );
    let data = ExperimentData {
        current_a: &record.current_a,
        measured_m: &record.displacement_m,
        settle: 0,
        start,
        heat_history: Vec::new(),
    };
    Arc::new(*setup.electro(electro, &data, record.len(), None).end_memory)
}

/// What step 2 estimates.
pub struct NuisanceEstimate {
    /// Every start plan.
    pub start_sets: Vec<(StartState, Vec<(ModelStart, bool)>)>,
    /// The plan chosen.
    pub plan: usize,
    /// The current between samples.
    pub interpolation: CurrentBetweenSamples,
    /// The channel skew, samples.
    pub skew: f64,
    /// RMS residual with a held current, m.
    pub rms_hold: f64,
    /// RMS residual with a linear current, m.
    pub rms_linear: f64,
}

/// Step 2 with the model `electro`, `mech`: the start plan, then the current between samples
/// (among `interpolations`: linear is always tried; hold when listed, and kept when it fits
/// better; `rms_hold` is infinite when it is not tried), the skew by golden section on the mechanical stage (one electromagnetic run per plan and
/// interpolation), over the first `probe_lens` samples of the `dynamic` experiments.
#[allow(clippy::too_many_arguments)]
pub fn estimate_nuisances(
    linear_setup: &ModelSetup<'_>,
    interpolations: &[CurrentBetweenSamples],
    measurements: &[Measurement],
    settles: &[usize],
    dynamic: &[usize],
    probe_lens: &[usize],
    documented: &[Option<StartState>],
    lead_ins: &[Option<Arc<Memory>>],
    electro: &Electro,
    mech: &Mech,
) -> NuisanceEstimate {
    let start_sets = start_sets(documented, lead_ins);
    let estimate = |interp: CurrentBetweenSamples, starts: &[(ModelStart, bool)]| -> (f64, f64) {
        let setup = ModelSetup {
            interpolation: interp,
            ..*linear_setup
        };
        let data = experiment_data(measurements, settles, starts);
        let lens: Vec<usize> = dynamic.iter().map(|&k| probe_lens[k]).collect();
        let runs = setup.electro_runs(electro, &data, dynamic, &lens);
        let rms_at = |skew: f64| -> f64 {
            let m = Mech {
                skew_samples: skew,
                ..*mech
            };
            let preds: Vec<Vec<f64>> = dynamic
                .par_iter()
                .zip(&runs)
                .map(|(&k, run)| {
                    run_mech(
                        setup.nominal,
                        &m,
                        run,
                        probe_lens[k],
                        setup.step_s,
                        (0.0, 0.0),
                    )
                })
                .collect();
            let items: Vec<(&[f64], &[f64], usize)> = dynamic
                .iter()
                .zip(&preds)
                .map(|(&k, p)| (p.as_slice(), data[k].measured_m, data[k].settle))
                .collect();
            pooled_rms(&items, offset_of(&items))
        };
        let skew = maglab_signal::golden::golden_section_min(-1.0, 1.0, 24, rms_at);
        (rms_at(skew), skew)
    };
    let plan_fits: Vec<(f64, f64)> = start_sets
        .par_iter()
        .map(|(_, starts)| estimate(CurrentBetweenSamples::Linear, starts))
        .collect();
    let plan = (0..start_sets.len())
        .min_by(|&a, &b| plan_fits[a].0.total_cmp(&plan_fits[b].0))
        .unwrap_or(0);
    let (rms_linear, skew_linear) = plan_fits[plan];
    let (rms_hold, skew_hold) = if interpolations.contains(&CurrentBetweenSamples::Hold) {
        estimate(CurrentBetweenSamples::Hold, &start_sets[plan].1)
    } else {
        (f64::INFINITY, 0.0)
    };
    let (interpolation, skew) = if rms_hold < rms_linear {
        (CurrentBetweenSamples::Hold, skew_hold)
    } else {
        (CurrentBetweenSamples::Linear, skew_linear)
    };
    NuisanceEstimate {
        start_sets,
        plan,
        interpolation,
        skew,
        rms_hold,
        rms_linear,
    }
}
