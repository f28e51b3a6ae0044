//! The FORC excitation reaches every cell, and determines every mass: every column of the design
//! matrix varies and the normal matrix `AᵀA` is positive definite.

use maglab_dataset::excitation::{forc_excitation, ExciteOptions};
use maglab_dataset::StartState;
use maglab_identify::design::{Design, Experiment, Grid};
use maglab_identify::CELL_COUNT;
use nalgebra::{Cholesky, DMatrix};

#[test]
fn forc_excitation_excites_and_determines_every_cell() {
    let p = actuator_params::paper_defaults();
    let options = ExciteOptions {
        h_min_a_per_m: p.preisach.h_min_a_per_m,
        h_max_a_per_m: p.preisach.h_max_a_per_m,
        coil_factor_per_m: p.actuator.coil_factor_per_m,
        sweep_rate_hz: 1.0,
        sample_rate_hz: 1000.0,
        overdrive: 0.01,
    };
    let e = forc_excitation(&options).unwrap();
    // Uniform sampling, as the measurement format requires.
    let dt = 1.0 / options.sample_rate_hz;
    assert!(e
        .t_s
        .windows(2)
        .all(|w| ((w[1] - w[0]) - dt).abs() < 1e-9 * dt + 1e-12));
    // Within the controller's current limit.
    assert!(e
        .current_a
        .iter()
        .all(|i| i.abs() <= p.control.current_limit_a));
    let h: Vec<f64> = e
        .current_a
        .iter()
        .map(|i| i * p.actuator.coil_factor_per_m)
        .collect();
    let zeros = vec![0.0; h.len()];
    let all = vec![true; h.len()];
    let grid = Grid::uniform(p.preisach.h_min_a_per_m, p.preisach.h_max_a_per_m);
    let design = Design::build(
        &grid,
        &[Experiment {
            label: "forc",
            input: &h,
            output: &zeros,
            selected: &all,
            initial: StartState::NegativeSaturation,
            weights: None,
        }],
        maglab_identify::fit::Reversible::None,
        1.0,
        1,
    );
    assert_eq!(design.unexcited(), Vec::<usize>::new());
    // Positive definite with a margin far above rounding: Cholesky of AᵀA/n - δ·I succeeds with
    // δ = 1e-9 · (largest diagonal entry), i.e. the smallest eigenvalue exceeds δ. A singular
    // direction would sit at ~1e-16 of the diagonal (f64 rounding of sums of O(1) terms).
    let gram = DMatrix::from_row_slice(CELL_COUNT, CELL_COUNT, &design.ata) / design.rows as f64;
    let shift = 1e-9 * gram.diagonal().max();
    let shifted = &gram - DMatrix::identity(CELL_COUNT, CELL_COUNT) * shift;
    assert!(Cholesky::new(shifted).is_some(), "AᵀA is (nearly) singular");

    // A single major loop, by contrast, varies every column but does not determine the masses:
    // the same check fails.
    let width = (grid.h_max - grid.h_min) / maglab_identify::LEVELS as f64;
    let n = 2000;
    let loop_h: Vec<f64> = (0..=2 * n)
        .map(|k| {
            let s = if k <= n {
                k as f64 / n as f64
            } else {
                2.0 - k as f64 / n as f64
            };
            grid.h_min - 0.01 * width + s * (grid.h_max - grid.h_min + 0.02 * width)
        })
        .collect();
    let zeros = vec![0.0; loop_h.len()];
    let all = vec![true; loop_h.len()];
    let d2 = Design::build(
        &grid,
        &[Experiment {
            label: "major loop",
            input: &loop_h,
            output: &zeros,
            selected: &all,
            initial: StartState::NegativeSaturation,
            weights: None,
        }],
        maglab_identify::fit::Reversible::None,
        1.0,
        1,
    );
    assert!(d2.unexcited().is_empty());
    let g2 = DMatrix::from_row_slice(CELL_COUNT, CELL_COUNT, &d2.ata) / d2.rows as f64;
    let shift2 = 1e-9 * g2.diagonal().max();
    assert!(Cholesky::new(&g2 - DMatrix::identity(CELL_COUNT, CELL_COUNT) * shift2).is_none());
}
