//! `maglab identify`: a dataset of quasi-static measurements → the full parameter file.
//!
//! Steps: read the dataset ([`crate::data`]); `H = c0 I`; `M` from the displacement through the
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

use crate::cell_of_index;
use crate::data::Dataset;
use crate::design::{Experiment, Grid};
use crate::fit::{fit, FitError, FitOptions, FitResult};
use crate::magnetization::{magnetization, Branch, StaticModel};
use crate::memory::InitialState;
use crate::model::{nrmse, PreisachModel, FORMAT};
use actuator_params::{ActuatorParams, Provenance};
use serde_json::{json, Map, Value};

/// Options of `identify`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IdentifyOptions {
    /// Sign convention for M.
    pub branch: Branch,
    /// Initial memory of every file.
    pub initial: InitialState,
    /// Zero band of the monotone sign rule, as a fraction of the full stroke `l_m λ_s`.
    pub zero_band_fraction: f64,
    /// The fit.
    pub fit: FitOptions,
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
}

/// The result of `identify`.
#[derive(Debug, Clone, PartialEq)]
pub struct Identification {
    /// The full parameter file (validated).
    pub params: ActuatorParams,
    /// The fit.
    pub fit: FitResult,
    /// Per-file diagnostics.
    pub files: Vec<FileReport>,
}

/// Identifies the Preisach masses from `dataset` on the grid of `base` (see the module docs).
pub fn identify(
    dataset: &Dataset,
    base: &ActuatorParams,
    base_name: &str,
    options: &IdentifyOptions,
) -> Result<Identification, FitError> {
    let a = &base.actuator;
    let model = StaticModel {
        rod_length_m: a.rod_length_m,
        saturation_magnetostriction: a.saturation_magnetostriction,
        saturation_magnetization_a_per_m: a.saturation_magnetization_a_per_m,
    };
    let grid = Grid {
        h_min: base.preisach.h_min_a_per_m,
        h_max: base.preisach.h_max_a_per_m,
    };
    let initial_sign: i8 = match options.initial {
        InitialState::NegativeSaturation => -1,
        InitialState::PositiveSaturation => 1,
        InitialState::Demagnetized | InitialState::Periodic => 0,
    };
    let zero_band_m = options.zero_band_fraction * model.stroke_m();
    let mut fields = Vec::new();
    let mut conversions = Vec::new();
    let mut labels = Vec::new();
    for m in &dataset.measurements {
        let h: Vec<f64> = m
            .current_a
            .iter()
            .map(|i| a.coil_factor_per_m * i)
            .collect();
        let conv = magnetization(
            &model,
            &m.displacement_m,
            &h,
            options.branch,
            initial_sign,
            zero_band_m,
        );
        labels.push(m.path.file_name().map_or_else(
            || m.path.display().to_string(),
            |n| n.to_string_lossy().into(),
        ));
        fields.push(h);
        conversions.push(conv);
    }
    let selected: Vec<Vec<bool>> = fields.iter().map(|h| vec![true; h.len()]).collect();
    let experiments: Vec<Experiment<'_>> = (0..fields.len())
        .map(|k| Experiment {
            label: &labels[k],
            input: &fields[k],
            output: &conversions[k].m_a_per_m,
            selected: &selected[k],
            initial: options.initial,
        })
        .collect();
    let result = fit(
        &grid,
        &experiments,
        Some(&base.preisach.weights_a_per_m),
        &options.fit,
    )?;

    let generic = PreisachModel {
        format: FORMAT.into(),
        input_column: "h_a_per_m".into(),
        output_column: "m_a_per_m".into(),
        levels: crate::LEVELS,
        h_min: grid.h_min,
        h_max: grid.h_max,
        weights: result.weights.clone(),
        offset: 0.0,
        slope: 0.0,
        initial_state: options.initial,
        provenance: Value::Null,
    };
    let mut files = Vec::new();
    for k in 0..fields.len() {
        let m_pred = generic.predict(&fields[k], options.initial);
        let y_pred: Vec<f64> = m_pred.iter().map(|&m| model.displacement_m(m)).collect();
        let meas = &dataset.measurements[k];
        files.push(FileReport {
            file: labels[k].clone(),
            samples: meas.len(),
            clipped_negative: conversions[k].clipped_negative,
            above_stroke: conversions[k].above_stroke,
            sign_changes: conversions[k].sign_changes,
            nrmse_magnetization: nrmse(&m_pred, &conversions[k].m_a_per_m, None),
            nrmse_displacement: nrmse(&y_pred, &meas.displacement_m, None),
            h_a_per_m: fields[k].clone(),
            m_measured_a_per_m: conversions[k].m_a_per_m.clone(),
            m_predicted_a_per_m: m_pred,
        });
    }

    let mut params = base.clone();
    params.preisach.weights_a_per_m = result.weights.clone();
    params.provenance = provenance(dataset, base, base_name, options, &result, &files);
    params
        .validate("identified parameters")
        .map_err(|e| FitError(format!("the identified parameters do not validate: {e}")))?;
    Ok(Identification {
        params,
        fit: result,
        files,
    })
}

fn provenance(
    dataset: &Dataset,
    base: &ActuatorParams,
    base_name: &str,
    options: &IdentifyOptions,
    result: &FitResult,
    files: &[FileReport],
) -> Provenance {
    let mut d = Map::new();
    d.insert("dataset".into(), json!(dataset.dir.display().to_string()));
    d.insert(
        "dataset_files".into(),
        json!(files
            .iter()
            .map(|f| json!({
                "file": f.file,
                "samples": f.samples,
                "negative_displacement_clipped_to_zero": f.clipped_negative,
                "above_full_stroke": f.above_stroke,
                "sign_changes_of_m": f.sign_changes,
                "nrmse_magnetization": f.nrmse_magnetization,
                "nrmse_displacement": f.nrmse_displacement,
            }))
            .collect::<Vec<_>>()),
    );
    d.insert(
        "dataset_entries_not_read".into(),
        json!(dataset
            .ignored
            .iter()
            .map(|p| p.display().to_string())
            .collect::<Vec<_>>()),
    );
    d.insert(
        "date".into(),
        json!(humantime::format_rfc3339_seconds(std::time::SystemTime::now()).to_string()),
    );
    d.insert("base_parameters".into(), json!(base_name));
    d.insert("identified".into(), json!(["preisach.weights_a_per_m"]));
    d.insert(
        "not_identified".into(),
        json!({
            "fields": ["actuator.eddy_resistance_ohm", "actuator.damping_ratio", "actuator.resonance_hz"],
            "values": {
                "eddy_resistance_ohm": base.actuator.eddy_resistance_ohm,
                "damping_ratio": base.actuator.damping_ratio,
                "resonance_hz": base.actuator.resonance_hz,
            },
            "reason": "copied from the base parameter file: identifying R_eddy, xi and f0 needs the \
                       dynamic model (4)-(5) (phase-lag scheme or direct waveform fit), not implemented \
                       in `maglab identify` yet. The other actuator constants are manufacturer data \
                       (paper Section 4) and are copied as well.",
        }),
    );
    d.insert(
        "method".into(),
        json!({
            "input": "H = c0 * current_a (static limit of (4))",
            "output": "M = +/- M_s sqrt(y / (l_m lambda_s)) (static model (6))",
            "branch": options.branch.name(),
            "zero_band_fraction_of_stroke": options.zero_band_fraction,
            "initial_state": options.initial.name(),
            "regression": "M = sum_k w_k (2 f_k - 1), f_k = exact fraction of cell k in P+, \
                           w >= 0, clarabel QP",
            "smoothness": options.fit.smoothness,
            "ridge_toward_base": options.fit.ridge,
            "row_stride": options.fit.row_stride,
        }),
    );
    d.insert(
        "fit".into(),
        json!({
            "rows": result.rows,
            "selected_rows_left_out_by_stride": result.strided_out,
            "rms_residual_a_per_m": result.rms_residual,
            "output_range_a_per_m": result.output_scale,
            "solver": result.solver,
            "samples_outside_grid": result.outside.iter().map(|(l, n)| json!({"file": l, "samples": n})).collect::<Vec<_>>(),
            "sum_of_weights_a_per_m": result.weights.iter().sum::<f64>(),
            "saturation_magnetization_a_per_m": base.actuator.saturation_magnetization_a_per_m,
        }),
    );
    d.insert(
        "unexcited_cells".into(),
        json!({
            "count": result.unexcited.len(),
            "treatment": options.fit.unexcited.name(),
            "meaning": "cells whose P+ fraction never changed over the data: the data do not \
                        determine their masses; `keep-prior` = base file's mass kept, `zero` = set \
                        to 0, `regularized` = set by the smoothness/ridge terms only",
            "cells_i_j": result.unexcited.iter().map(|&k| { let (i, j) = cell_of_index(k); json!([i, j]) }).collect::<Vec<_>>(),
        }),
    );
    Provenance {
        source: "maglab identify (Preisach masses identified; R_eddy, xi, f0 copied from base)"
            .into(),
        details: d,
    }
}
