//! `maglab identify`: a dataset of quasi-static measurements → the full parameter file.
//!
//! Steps: read the dataset (`maglab_dataset::data`); `H = c0 I`; `M` from the displacement through the
//! static model (6) ([`crate::magnetization`], sign convention as chosen); fit the 325 masses on
//! the grid of the base file ([`crate::fit`]) with the base masses as prior; write the base file
//! with the masses replaced and a provenance that records the dataset, the date, the options, the
//! residuals and the unexcited cells.
//!
//! This stage identifies the Preisach masses only: `R_eddy`, `ξ` and `f0` are copied from the base
//! file and listed in the provenance's `not_identified`. `maglab identify` then runs the dynamic
//! stage ([`crate::dynamics::fit_eddy_and_damping`]: the phase-lag scheme of Section 4 and the
//! direct waveform fit) on the dataset's dynamic experiments and records its result with
//! [`crate::dynamics::record::record`], which replaces the three values and removes them from
//! `not_identified`. `M_s`, `λ_s`, `l_m`, `c0`, `N_m`, `A_m` are the manufacturer's constants in
//! the paper and are copied.
//!
//! The steps have their modules: [`lag`] (the record's timing and the first-order lags of a
//! finite-rate sweep), [`floor`] (the displacement's noise and offset, and which rows enter the
//! regression), [`start`] (each record's start state and sign convention), [`provenance`] (what
//! the parameter file records of the fit).

pub mod floor;
pub mod lag;
pub mod provenance;
pub mod start;

pub use floor::{
    displacement_noise_m, displacement_offset_m, fit_floor_m, FIT_FLOOR_MAX_FRACTION,
    SQRT_NOISE_BIAS_MAX,
};
pub use lag::{shifted, LagCorrection};
pub use start::{auto_branch, auto_initial, documented_initial, first_period_is_a_transient};

use crate::design::{Experiment, Grid};
use crate::fit::{fit, FitError, FitOptions, FitResult, Unexcited};
use crate::magnetization::{magnetization, Branch, StaticModel};
use crate::model::{nrmse, PreisachModel};
use crate::reach::{banded_grid, identification_grid, prefers_banded, IdentificationGrid, Reach};
use actuator_params::ActuatorParams;
use maglab_dataset::data::Dataset;
use maglab_dataset::StartState;
use provenance::identified_params;
use serde_json::{json, Value};

/// Options of `identify`.
#[derive(Debug, Clone, PartialEq)]
pub struct MassOptions {
    /// Sign convention for M (`None`: per file, [`auto_branch`]).
    pub branch: Option<Branch>,
    /// Initial memory of every file (`None`: per file, as `dataset.json` documents it, else
    /// [`auto_initial`]).
    pub initial: Option<StartState>,
    /// The dataset's `dataset.json`, when it has one.
    pub documented: Option<maglab_dataset::dataset_info::DatasetInfo>,
    /// Zero band of the monotone sign rule, as a fraction of the full stroke `l_m λ_s`.
    pub zero_band_fraction: f64,
    /// The fit.
    pub fit: FitOptions,
    /// `[R_eddy Ω, ξ, f0 Hz]` for the first-order lag corrections of a finite-rate record
    /// ([`LagCorrection`]); `None`: no correction (the static model (6) as it stands).
    pub lag_correction: Option<[f64; 3]>,
    /// Where the current is read for each displacement sample, in samples after the current's
    /// own sample time: the channel skew (the displacement read that much later), less half a
    /// sample when the current is held between samples (a held current is the linear one half
    /// a sample late). 0: both channels sampled at once, the current linear between samples.
    /// The dynamic fit estimates both nuisances on the sines (`maglab_diagnose::identification`);
    /// the sweep's masses must see the same timing as the model they go into, else the few
    /// tens of µs go into the loops' width, and the minor loops the sines run on come out wrong.
    pub current_shift_samples: f64,
    /// The field range of the whole dataset (quasi-static and dynamic records), which sets the
    /// grid ([`crate::reach`]); `None`: the range of the records given.
    pub reach: Option<Reach>,
}

/// Per-file diagnostics.
#[derive(Debug, Clone, PartialEq)]
pub struct FileReport {
    /// File name.
    pub file: String,
    /// Samples.
    pub samples: usize,
    /// Samples with negative displacement (clipped to M = 0).
    pub clipped_negative: usize,
    /// Samples above the full stroke.
    pub above_stroke: usize,
    /// Sign changes of M assigned by the monotone rule.
    pub sign_changes: usize,
    /// White-noise level of the displacement, m ([`displacement_noise_m`]).
    pub noise_m: f64,
    /// Rows whose `u` lies below this are left out of the regression, m ([`fit_floor_m`]).
    pub fit_floor_m: f64,
    /// Selected rows left out by that floor.
    pub rows_below_floor: usize,
    /// NRMSE of the predicted magnetization.
    pub nrmse_magnetization: Option<f64>,
    /// NRMSE of the predicted displacement (static model (6)).
    pub nrmse_displacement: Option<f64>,
    /// Field (A/m), measured-converted M and predicted M, for plots.
    pub h_a_per_m: Vec<f64>,
    /// M from the measured displacement, A/m.
    pub m_measured_a_per_m: Vec<f64>,
    /// M predicted by the identified model, A/m.
    pub m_predicted_a_per_m: Vec<f64>,
    /// Where the record's start state came from.
    pub start_from: StartFrom,
}

/// Where a quasi-static record's start state came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StartFrom {
    /// `--initial`.
    Given,
    /// `dataset.json`.
    Documented,
    /// Not documented: estimated ([`auto_initial`]).
    Estimated,
    /// Documented `previous`, which a quasi-static record is not continued from (the records
    /// before it, dynamic ones included, are not simulated here): estimated as [`Estimated`]
    /// is, and said so, since the estimate does not see the memory those records left.
    ///
    /// [`Estimated`]: StartFrom::Estimated
    EstimatedForPrevious,
}

impl StartFrom {
    /// The provenance's `initial_state_from`.
    pub fn name(self) -> &'static str {
        match self {
            StartFrom::Given => "given",
            StartFrom::Documented => "documented",
            StartFrom::Estimated => "estimated",
            StartFrom::EstimatedForPrevious => "estimated (documented previous)",
        }
    }
}

/// The result of `identify`.
#[derive(Debug, Clone, PartialEq)]
pub struct MassIdentification {
    /// The full parameter file (validated).
    pub params: ActuatorParams,
    /// The fit.
    pub fit: FitResult,
    /// Per-file diagnostics.
    pub files: Vec<FileReport>,
}

/// Identifies the Preisach masses from `dataset` on the grid of `base` (see the module docs).
pub fn identify_masses(
    dataset: &Dataset,
    base: &ActuatorParams,
    base_name: &str,
    options: &MassOptions,
) -> Result<MassIdentification, FitError> {
    let a = &base.actuator;
    let base_grid =
        Grid::of_params(&base.preisach).map_err(|e| FitError(format!("{base_name}: {e}")))?;
    let reach = options
        .reach
        .or_else(|| {
            Reach::of_currents(
                dataset.measurements.iter().map(|m| &m.current_a[..]),
                a.coil_factor_per_m,
            )
        })
        .ok_or_else(|| FitError(format!("{}: no finite current", dataset.dir.display())))?;
    let chosen = identification_grid(base_grid, reach);
    let on_base = identify_on_grid(dataset, base, base_name, options, chosen)?;
    if chosen.has_bands() {
        return Ok(on_base);
    }
    // The records cover the base grid: whether the coil saturates the rod there is for the data
    // to say. The banded grid is the larger model (its bands empty, it is the base grid's plane
    // on slightly coarser cells); it is kept when it explains the quasi-static rows better by
    // more than its extra parameters are worth (`prefers_banded`).
    let Some(banded) = banded_grid(base_grid, reach) else {
        return Ok(on_base);
    };
    let on_bands = identify_on_grid(dataset, base, base_name, options, banded)?;
    Ok(if prefers_banded(&on_base.fit, &on_bands.fit) {
        on_bands
    } else {
        on_base
    })
}

/// The mass identification on one grid.
fn identify_on_grid(
    dataset: &Dataset,
    base: &ActuatorParams,
    base_name: &str,
    options: &MassOptions,
    mut chosen: IdentificationGrid,
) -> Result<MassIdentification, FitError> {
    let a = &base.actuator;
    let model = StaticModel {
        rod_length_m: a.rod_length_m,
        saturation_magnetostriction: a.saturation_magnetostriction,
        saturation_magnetization_a_per_m: a.saturation_magnetization_a_per_m,
    };
    let base_grid =
        Grid::of_params(&base.preisach).map_err(|e| FitError(format!("{base_name}: {e}")))?;
    // A documented `conditioned` start is the sweep the base file's firmware ran.
    let sweep = maglab_model::model::Nominal::from_params(base)
        .conditioning_sweep_a_per_m
        .map(|(lo, hi)| (f64::from(lo), f64::from(hi)));
    chosen.grid = chosen.grid.with_conditioning(sweep);
    let grid = chosen.grid;
    let zero_band_m = options.zero_band_fraction * model.stroke_m();
    let sensor_offset_m = displacement_offset_m(dataset, a.coil_factor_per_m, &base_grid);
    let records: Vec<Record> = dataset
        .measurements
        .iter()
        .map(|m| {
            let setting = RecordSetting {
                base,
                model: &model,
                grid: &grid,
                reach: chosen.reach,
                zero_band_m,
                sensor_offset_m: sensor_offset_m.unwrap_or(0.0),
                options,
            };
            setting.convert(m)
        })
        .collect();
    let (selected, rows_below_floor) = select_rows(&records, &model, zero_band_m);
    let experiments: Vec<Experiment<'_>> = records
        .iter()
        .zip(&selected)
        .map(|(r, selected)| Experiment {
            label: &r.label,
            input: &r.field,
            output: &r.conversion.m_a_per_m,
            selected,
            initial: r.initial,
            weights: None,
        })
        .collect();
    let fit_options = fit_options(&chosen, options, &model);
    let prior = (!chosen.has_bands()).then_some(&base.preisach.weights_a_per_m[..]);
    let result = fit(&grid, &experiments, prior, &fit_options)?;
    let files = file_reports(
        dataset,
        &records,
        &rows_below_floor,
        &grid,
        &result,
        &fit_options,
        &model,
    );
    let choices: Vec<Value> = records.iter().map(|r| r.choice.clone()).collect();
    let params = identified_params(
        (dataset, base, base_name),
        (&chosen, options, &fit_options),
        &result,
        &files,
        &choices,
        sensor_offset_m,
    )?;
    Ok(MassIdentification {
        params,
        fit: result,
        files,
    })
}

/// One quasi-static record made ready for the mass fit.
struct Record {
    /// File name.
    label: String,
    /// The field `H` (lag-corrected), A/m.
    field: Vec<f64>,
    /// `M` from the (lag-corrected, offset-free) displacement.
    conversion: crate::magnetization::Conversion,
    /// The start state the record is simulated from.
    initial: StartState,
    /// The displacement the masses are fitted to (lag-corrected), m.
    displacement_m: Vec<f64>,
    /// White-noise level of the displacement, m.
    noise_m: f64,
    /// Rows below this displacement are left out, m.
    floor_m: f64,
    /// How the start state and the sign convention were chosen, for the provenance.
    choice: Value,
    /// Where the start state came from.
    start_from: StartFrom,
}

/// What every record's conversion shares.
struct RecordSetting<'a> {
    base: &'a ActuatorParams,
    model: &'a StaticModel,
    grid: &'a Grid,
    /// The reach of a grid with bands: the lag-corrected field is kept inside it.
    reach: Option<Reach>,
    zero_band_m: f64,
    sensor_offset_m: f64,
    options: &'a MassOptions,
}

impl RecordSetting<'_> {
    /// The record `m` with its current read at the fit's timing, the sensor offset removed,
    /// the lags corrected, its start state and sign convention chosen, converted to `M`.
    fn convert(&self, m: &maglab_dataset::data::Measurement) -> Record {
        let (a, options) = (&self.base.actuator, self.options);
        let correction = options
            .lag_correction
            .map(|c| LagCorrection::new(self.base, c));
        let current_a = shifted(&m.current_a, options.current_shift_samples);
        let h_static: Vec<f64> = current_a.iter().map(|i| a.coil_factor_per_m * i).collect();
        let y: Vec<f64> = m
            .displacement_m
            .iter()
            .map(|y| y - self.sensor_offset_m)
            .collect();
        let noise_m = displacement_noise_m(&y);
        let gain = correction.map_or(1.0, |c| c.noise_gain(m.step_s));
        let displacement = match &correction {
            Some(c) => c.displacement(&y, m.step_s),
            None => y,
        };
        let name = m.path.file_name().map_or_else(
            || m.path.display().to_string(),
            |n| n.to_string_lossy().into(),
        );
        let documented = options.documented.as_ref().and_then(|d| d.start_of(&name));
        let (initial, start_from) = match options.initial {
            Some(i) => (i, StartFrom::Given),
            None => match documented.and_then(documented_initial) {
                Some(i) => (i, StartFrom::Documented),
                None => (
                    auto_initial(&h_static, &displacement, noise_m, self.grid),
                    if documented == Some(StartState::Previous) {
                        StartFrom::EstimatedForPrevious
                    } else {
                        StartFrom::Estimated
                    },
                ),
            },
        };
        let branch = options.branch.unwrap_or_else(|| auto_branch(&current_a));
        // The zero band guards the sign of M; with `positive` there is no sign to guess, only
        // the square root's noise bias sets the floor (on a rod the coil cannot saturate the
        // whole motion may lie within a few zero bands of rest).
        let band_m = match branch {
            Branch::Positive => 0.0,
            Branch::Monotone => self.zero_band_m,
        };
        let floor_m = fit_floor_m(band_m, gain * noise_m, self.model.stroke_m());
        let initial_sign: i8 = match initial {
            StartState::NegativeSaturation | StartState::Conditioned => -1,
            StartState::PositiveSaturation => 1,
            _ => 0,
        };
        let conversion = magnetization(
            self.model,
            &displacement,
            &h_static,
            branch,
            initial_sign,
            self.zero_band_m,
        );
        let mut field = match &correction {
            Some(c) => c.field(&current_a, &conversion.m_a_per_m, m.step_s),
            None => h_static,
        };
        // Eq. (4) moves H toward c0 I at every instant (H' = c1 (I − H/c0) / (1 + dM/dH) with
        // dM/dH >= 0), so H never leaves the range of c0 I. The first-order correction can
        // overshoot it by its noise; inside a band that would fake an excitation of cells the
        // coil never switches, which only the offset could balance.
        if let Some(r) = self.reach {
            for h in &mut field {
                *h = h.clamp(r.lo_a_per_m, r.hi_a_per_m);
            }
        }
        Record {
            choice: json!({"file": name, "initial_state": initial.name(), "initial_state_from": start_from.name(), "branch": branch.name()}),
            label: name,
            start_from,
            field,
            conversion,
            initial,
            displacement_m: displacement,
            noise_m,
            floor_m,
        }
    }
}

/// The rows each record's regression keeps, and how many between the zero band and the fit
/// floor it leaves out. Rows whose |M| lies below the fit floor are left out: inside the zero
/// band the sign of M is uncertain, and near zero M = M_s √(u/S) turns the sensor noise into
/// tens of kA/m (dM/du grows as 1/√u) with a bias (`fit_floor_m`). The memory still sees them.
fn select_rows(
    records: &[Record],
    model: &StaticModel,
    zero_band_m: f64,
) -> (Vec<Vec<bool>>, Vec<usize>) {
    // |M| at u (static model (6)).
    let m_at = |u_m: f64| model.saturation_magnetization_a_per_m * (u_m / model.stroke_m()).sqrt();
    let m_zero_band = m_at(zero_band_m);
    records
        .iter()
        .map(|r| {
            let m_floor = m_at(r.floor_m);
            let kept: Vec<bool> = r
                .conversion
                .m_a_per_m
                .iter()
                .map(|m| m.abs() >= m_floor)
                .collect();
            let below = r
                .conversion
                .m_a_per_m
                .iter()
                .filter(|m| (m_zero_band..m_floor).contains(&m.abs()))
                .count();
            (kept, below)
        })
        .unzip()
}

/// The fit's options on the chosen grid. With a reversible part the masses saturate at M_s
/// (Σ masses <= M_s) and the part carries the magnetization beyond it (the paper's model alone
/// keeps its masses free: what they absorb past M_s is what `--reversible auto` looks at). On a
/// grid with one-way bands ([`crate::reach`]) the output gets its offset `M_off`, the masses have
/// no prior (the base grid's cells are not these) and sum to at most M_s (they are parts of the
/// rod's plane), and unexcited cells the base would have kept are left to the regularization
/// (band cells: fixed at 0, [`crate::fit::Bands`]).
fn fit_options(
    chosen: &IdentificationGrid,
    options: &MassOptions,
    model: &StaticModel,
) -> FitOptions {
    let ms = model.saturation_magnetization_a_per_m;
    let mut fit_options = FitOptions {
        total_mass_at_most: if options.fit.reversible.is_piecewise() {
            Some(options.fit.total_mass_at_most.map_or(ms, |cap| cap.min(ms)))
        } else {
            options.fit.total_mass_at_most
        },
        ..options.fit
    };
    if chosen.has_bands() {
        fit_options.reversible = fit_options.reversible.with_offset();
        fit_options.bands = chosen.bands;
        // The cells are parts of the rod's plane, whose whole mass is at most M_s (|M| <= M_s).
        fit_options.total_mass_at_most =
            Some(fit_options.total_mass_at_most.map_or(ms, |cap| cap.min(ms)));
        if fit_options.unexcited == Unexcited::KeepPrior {
            fit_options.unexcited = Unexcited::Regularized;
        }
    }
    fit_options
}

/// Each record's report: its conversion and how the identified model predicts it.
fn file_reports(
    dataset: &Dataset,
    records: &[Record],
    rows_below_floor: &[usize],
    grid: &Grid,
    result: &FitResult,
    fit_options: &FitOptions,
    model: &StaticModel,
) -> Vec<FileReport> {
    let initial_state = records
        .first()
        .map(|r| r.initial)
        .unwrap_or(StartState::NegativeSaturation);
    let generic = PreisachModel {
        offset: result.offset,
        reversible_slopes: fit_options
            .reversible
            .is_piecewise()
            .then(|| result.reversible_slopes.clone()),
        ..PreisachModel::from_weights(*grid, &result.weights, initial_state)
    };
    records
        .iter()
        .enumerate()
        .map(|(k, r)| {
            let m_pred = generic.predict(&r.field, r.initial);
            let y_pred: Vec<f64> = m_pred.iter().map(|&m| model.displacement_m(m)).collect();
            FileReport {
                file: r.label.clone(),
                samples: dataset.measurements[k].len(),
                clipped_negative: r.conversion.clipped_negative,
                above_stroke: r.conversion.above_stroke,
                sign_changes: r.conversion.sign_changes,
                noise_m: r.noise_m,
                fit_floor_m: r.floor_m,
                rows_below_floor: rows_below_floor[k],
                nrmse_magnetization: nrmse(&m_pred, &r.conversion.m_a_per_m, None),
                nrmse_displacement: nrmse(&y_pred, &r.displacement_m, None),
                h_a_per_m: r.field.clone(),
                m_measured_a_per_m: r.conversion.m_a_per_m.clone(),
                m_predicted_a_per_m: m_pred,
                start_from: r.start_from,
            }
        })
        .collect()
}
