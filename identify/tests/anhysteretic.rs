//! An almost anhysteretic material (the single-slope reversible part made the fit 12×
//! worse than a plain centre line there): B–H-like loops `y = tanh((u ∓ c) / a)` with a coercive
//! shift `c` of 1 % of the loop's field, three amplitudes, written as one CSV with a loop column;
//! fit two loops with `maglab preisach-fit`'s defaults, predict the third. The data are not made by
//! any Preisach model (a shifted tanh per branch, the branch switching at the turning points).
//! The prediction is compared with the true centre line `tanh(u / a)` (the best a
//! hysteresis-free model can do) and with the single-slope reversible part.

use maglab_dataset::StartState;
use maglab_identify::columns::{read_columns, ColumnSpec, RowFilter};
use maglab_identify::fit::{FitOptions, Reversible, Unexcited};
use maglab_identify::lines::LineChoice;
use maglab_identify::model::nrmse;
use maglab_identify::table_fit::{fit_table, predict_table, DEFAULT_RANGE_MARGIN};
use std::fmt::Write;

const SCALE: f64 = 30.0;
const SHIFT: f64 = 1.0;

fn branch(u: f64, rising: bool) -> f64 {
    let c = if rising { SHIFT } else { -SHIFT };
    ((u - c) / SCALE).tanh()
}

#[test]
fn an_almost_anhysteretic_loop_is_carried_by_the_reversible_part() {
    let mut csv = String::from("loop,h,b\n");
    let mut held_u = Vec::new();
    let mut held_y = Vec::new();
    for (n, amplitude) in [40.0, 100.0, 70.0].into_iter().enumerate() {
        // One period: from the top down to the bottom and back up.
        let samples = 400;
        for k in 0..samples {
            let phase = 2.0 * std::f64::consts::PI * k as f64 / samples as f64;
            let u = amplitude * phase.cos();
            let rising = phase > std::f64::consts::PI;
            let y = branch(u, rising);
            writeln!(csv, "{n},{u},{y}").unwrap();
            if n == 2 {
                held_u.push(u);
                held_y.push(y);
            }
        }
    }
    let folder = tempfile::tempdir().unwrap();
    let path = folder.path().join("loops.csv");
    std::fs::write(&path, csv).unwrap();
    let spec = ColumnSpec {
        input: "h".into(),
        output: "b".into(),
        group: Some("loop".into()),
        filter: RowFilter::parse("loop=0,1").unwrap(),
    };
    let table = read_columns(&path, &spec).unwrap();
    let held = ColumnSpec {
        filter: RowFilter::parse("loop=2").unwrap(),
        ..spec.clone()
    };
    let held_table = read_columns(&path, &held).unwrap();
    let score = |reversible: Reversible| {
        let options = FitOptions {
            smoothness: 1e-6,
            ridge: 0.0,
            reversible,
            unexcited: Unexcited::Regularized,
            row_stride: 1,
            total_mass_at_most: None,
            bands: Default::default(),
        };
        let (model, _) = fit_table(
            &table,
            &spec,
            None,
            DEFAULT_RANGE_MARGIN,
            (StartState::Periodic, false),
            LineChoice::Auto,
            true,
            &options,
        )
        .unwrap();
        predict_table(&model, &held_table).1.unwrap()
    };
    let piecewise = score(Reversible::Piecewise);
    let linear = score(Reversible::Linear);
    let centre: Vec<f64> = held_u.iter().map(|u| (u / SCALE).tanh()).collect();
    let centre_line = nrmse(&centre, &held_y, None).unwrap();
    println!(
        "held-out loop NRMSE: piecewise reversible part {:.3} %, single slope {:.3} %, true centre line {:.3} %",
        100.0 * piecewise,
        100.0 * linear,
        100.0 * centre_line
    );
    let _ = std::fs::remove_file(&path);
    assert!(
        piecewise <= centre_line,
        "{piecewise} vs centre line {centre_line}"
    );
    assert!(piecewise < linear, "{piecewise} vs single slope {linear}");
}
