//! What the parameter file records of the mass fit: the fields identified, the grid chosen, each
//! record's conversion and start, the fit's figures.

use super::floor::{FIT_FLOOR_MAX_FRACTION, SQRT_NOISE_BIAS_MAX};
use super::{FileReport, MassOptions};
use crate::cell_of_index;
use crate::fit::{FitError, FitOptions, FitResult};
use crate::reach::IdentificationGrid;
use actuator_params::{ActuatorParams, Provenance};
use maglab_dataset::data::Dataset;
use serde_json::{json, Map, Value};

/// The base file with the identified masses (and reversible part; on a grid with bands the grid,
/// the reach and the offset) and the provenance, validated.
pub(super) fn identified_params(
    (dataset, base, base_name): (&Dataset, &ActuatorParams, &str),
    (chosen, options, fit_options): (&IdentificationGrid, &MassOptions, &FitOptions),
    result: &FitResult,
    files: &[FileReport],
    choices: &[Value],
    sensor_offset_m: Option<f64>,
) -> Result<ActuatorParams, FitError> {
    let mut params = base.clone();
    let p = &mut params.preisach;
    p.weights_a_per_m = result.weights.clone();
    p.reversible_susceptibility = fit_options
        .reversible
        .is_piecewise()
        .then(|| result.reversible_slopes.clone());
    if let Some(reach) = chosen.reach {
        p.h_min_a_per_m = chosen.grid.h_min;
        p.h_max_a_per_m = chosen.grid.h_max;
        p.grid_lines_a_per_m = chosen.grid.lines.map(|l| l.to_vec());
        p.reach_a_per_m = Some(vec![reach.lo_a_per_m, reach.hi_a_per_m]);
        p.offset_a_per_m = result.offset;
    }
    let mut prov = provenance(
        (dataset, base, base_name),
        (options, fit_options),
        result,
        files,
        choices,
    );
    prov.details.insert(
        "sensor_offset_m".into(),
        json!({
            "value": sensor_offset_m.unwrap_or(0.0),
            "how": if sensor_offset_m.is_some() {
                "estimated: the floor of the displacement where M crosses zero in the bipolar \
                 quasi-static records (median over them), subtracted before M = +/- M_s sqrt(y / (l_m lambda_s))"
            } else {
                "assumed 0: no bipolar quasi-static record (M never crosses zero) to estimate it from"
            },
        }),
    );
    prov.details
        .insert("grid".into(), grid_provenance(chosen, base));
    params.provenance = prov;
    params
        .validate("identified parameters")
        .map_err(|e| FitError(format!("the identified parameters do not validate: {e}")))?;
    Ok(params)
}

/// The file's fields the mass fit identified.
fn identified_fields(fit_options: &FitOptions) -> Vec<&'static str> {
    let mut fields = vec!["preisach.weights_a_per_m"];
    if fit_options.reversible.is_piecewise() {
        fields.push("preisach.reversible_susceptibility");
    }
    if fit_options.bands != Default::default() {
        fields.extend([
            "preisach.h_min_a_per_m",
            "preisach.h_max_a_per_m",
            "preisach.reach_a_per_m",
            "preisach.offset_a_per_m",
        ]);
    }
    fields
}

/// How the grid was chosen, for the provenance.
fn grid_provenance(chosen: &IdentificationGrid, base: &ActuatorParams) -> Value {
    match chosen.reach {
        None => json!({
            "choice": "base",
            "why": "the records reach both ends of the base file's grid: the coil saturates the rod there",
        }),
        Some(reach)
            if reach.lo_a_per_m <= base.preisach.h_min_a_per_m
                && reach.hi_a_per_m >= base.preisach.h_max_a_per_m =>
        {
            json!({
                "choice": "reach",
                "reach_a_per_m": [reach.lo_a_per_m, reach.hi_a_per_m],
                "base_range_a_per_m": [base.preisach.h_min_a_per_m, base.preisach.h_max_a_per_m],
                "bands": {"low": true, "high": true},
                "why": "the records cover the base file's grid but the rod was not saturated there: \
                        the fit with a one-way band beyond each end of the reach and the offset \
                        preisach.offset_a_per_m explains the quasi-static rows better than the base \
                        grid by more than the Bayesian information criterion charges for the band \
                        cells (docs/model.md)",
            })
        }
        Some(reach) => json!({
            "choice": "reach",
            "reach_a_per_m": [reach.lo_a_per_m, reach.hi_a_per_m],
            "base_range_a_per_m": [base.preisach.h_min_a_per_m, base.preisach.h_max_a_per_m],
            "bands": {"low": chosen.bands.low, "high": chosen.bands.high},
            "why": "the base file's grid extends beyond the field the records reach (c0 times their \
                    current extremes): the grid divides the reach, a band interval beyond each \
                    unreached end holds the one-way hysterons there, and the output offset \
                    preisach.offset_a_per_m the part no reachable field switches (docs/model.md)",
        }),
    }
}

/// The provenance of the mass fit: the dataset and its files, what was identified and what
/// copied, the method, the fit's figures and the cells the data left undetermined.
fn provenance(
    (dataset, base, base_name): (&Dataset, &ActuatorParams, &str),
    (options, fit_options): (&MassOptions, &FitOptions),
    result: &FitResult,
    files: &[FileReport],
    choices: &[Value],
) -> Provenance {
    let mut d = Map::new();
    d.insert("dataset".into(), json!(dataset.dir.display().to_string()));
    d.insert("dataset_files".into(), dataset_files(files));
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
    d.insert(
        actuator_params::Provenance::IDENTIFIED.into(),
        json!(identified_fields(fit_options)),
    );
    d.insert("not_identified".into(), not_identified(base));
    d.insert("method".into(), method(options, fit_options, choices));
    d.insert("fit".into(), fit_figures(result, base));
    d.insert(
        "unexcited_cells".into(),
        unexcited_cells(result, fit_options),
    );
    Provenance {
        source: "maglab identify (Preisach masses identified; R_eddy, xi, f0 copied from base)"
            .into(),
        details: d,
    }
}

/// Per record: its samples, what was clipped or left out, its noise and fit errors.
fn dataset_files(files: &[FileReport]) -> Value {
    json!(files
        .iter()
        .map(|f| json!({
            "file": f.file,
            "samples": f.samples,
            "negative_displacement_clipped_to_zero": f.clipped_negative,
            "above_full_stroke": f.above_stroke,
            "sign_changes_of_m": f.sign_changes,
            "displacement_noise_m": f.noise_m,
            "fit_floor_m": f.fit_floor_m,
            "rows_below_fit_floor_outside_zero_band": f.rows_below_floor,
            "nrmse_magnetization": f.nrmse_magnetization,
            "nrmse_displacement": f.nrmse_displacement,
        }))
        .collect::<Vec<_>>())
}

/// The dynamic constants the mass fit copies from the base file, and why.
fn not_identified(base: &ActuatorParams) -> Value {
    json!({
        "fields": actuator_params::Provenance::DYNAMIC_FIELDS,
        "values": {
            "eddy_resistance_ohm": base.actuator.eddy_resistance_ohm,
            "damping_ratio": base.actuator.damping_ratio,
            "resonance_hz": base.actuator.resonance_hz,
        },
        "reason": "copied from the base parameter file: R_eddy, xi and f0 are fitted with the \
                   dynamic model (4)-(5) on the dataset's dynamic records (phase-lag scheme and \
                   direct waveform fit), and this dataset has none. The other actuator constants \
                   are manufacturer data (paper Section 4) and are copied as well.",
    })
}

/// The static inversion (H from the current, M from the displacement), the rows left out and
/// the regression with its regularization.
fn method(options: &MassOptions, fit_options: &FitOptions, choices: &[Value]) -> Value {
    json!({
        "input": "H = c0 * current_a (static limit of (4))",
        "output": "M = +/- M_s sqrt(y / (l_m lambda_s)) (static model (6))",
        "branch_and_initial_state_per_file": choices,
        "zero_band_fraction_of_stroke": options.zero_band_fraction,
        "fit_floor": format!(
            "rows with u below max(zero band, min(sigma_u / sqrt(8 * {SQRT_NOISE_BIAS_MAX}), \
             {FIT_FLOOR_MAX_FRACTION} * l_m lambda_s)) are left out: sigma_u (the noise of u after the lag correction) biases \
             M = M_s sqrt(u/S) low by sigma_u^2 / (8 u^2) of itself"
        ),
        "regression": "M = sum_k w_k (2 f_k - 1), f_k = exact fraction of cell k in P+, \
                       w >= 0, clarabel QP",
        "smoothness": fit_options.smoothness,
        "ridge_toward_base": fit_options.ridge,
        "row_stride": fit_options.row_stride,
    })
}

/// The regression's rows, residual, solver and the sum of the masses beside `M_s`.
fn fit_figures(result: &FitResult, base: &ActuatorParams) -> Value {
    json!({
        "rows": result.rows,
        "selected_rows_left_out_by_stride": result.strided_out,
        "rms_residual_a_per_m": result.rms_residual,
        "output_range_a_per_m": result.output_scale,
        "solver": result.solver,
        "samples_outside_grid": result.outside.iter().map(|(l, n)| json!({"file": l, "samples": n})).collect::<Vec<_>>(),
        "sum_of_weights_a_per_m": result.weights.iter().sum::<f64>(),
        "saturation_magnetization_a_per_m": base.actuator.saturation_magnetization_a_per_m,
    })
}

/// The cells whose `P+` fraction never changed over the data, and how their masses were set.
fn unexcited_cells(result: &FitResult, fit_options: &FitOptions) -> Value {
    json!({
        "count": result.unexcited.len(),
        "treatment": fit_options.unexcited.name(),
        "meaning": "cells whose P+ fraction never changed over the data: the data do not \
                    determine their masses; `keep-prior` = base file's mass kept, `zero` = set \
                    to 0, `regularized` = set by the smoothness/ridge terms only",
        "cells_i_j": result.unexcited.iter().map(|&k| { let (i, j) = cell_of_index(k); json!([i, j]) }).collect::<Vec<_>>(),
    })
}
