//! The f64 memory and cell fractions of the identify crate against the no_std core: for the
//! default (paper) masses, `Σ w (2 f - 1)` must equal `measure.apply`, and the staircases must
//! hold the same reversal points.

use magctl::preisach::{PreisachMeasure, PreisachState, CELL_COUNT as CORE_CELLS};
use maglab_identify::cells::{fractions, output};
use maglab_identify::memory::{Memory, Piece};
use maglab_identify::{CELL_COUNT, LEVELS};
use rand::{RngExt, SeedableRng};

fn inputs(seed: u64, n: usize) -> Vec<f64> {
    // A random walk with random reversals and occasional jumps, in normalized units [-1, 26]
    // (beyond the grid at both ends: saturation).
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    let mut x: f64 = 12.5;
    (0..n)
        .map(|_| {
            if rng.random_bool(0.1) {
                x = rng.random_range(-1.0..26.0);
            } else {
                x = (x + rng.random_range(-3.0..3.0)).clamp(-1.0, 26.0);
            }
            x
        })
        .collect()
}

#[test]
fn fractions_reproduce_the_core_output() {
    let params = actuator_params::paper_defaults();
    let w64 = &params.preisach.weights_a_per_m;
    let (h_min, h_max) = (params.preisach.h_min_a_per_m, params.preisach.h_max_a_per_m);
    let mut w32 = [0f32; CORE_CELLS];
    for (a, b) in w32.iter_mut().zip(w64) {
        *a = *b as f32;
    }
    let measure = PreisachMeasure::new(&w32, h_min as f32, h_max as f32);
    let total: f64 = w64.iter().sum();
    let width = (h_max - h_min) / LEVELS as f64;
    // Tolerance: the core is f32. Its Everett values are within 8 ε Σw (ε = 2⁻²⁴, see
    // src/preisach/everett.rs), the running sums add one such term per staircase vertex (at most
    // 64), and the f32 input carries a rounding of ε |h| that moves M by at most
    // 2 ρ_max · ε |h|/Δ · L (a full α- or β-row of cells): with ρ_max <= Σw, bounded by
    // (8·65 + 2·2·L) ε Σw ≈ 620 ε Σw. The f64 side is exact to ~1e-13 Σw.
    let eps = f32::EPSILON as f64 / 2.0;
    let tol = (8.0 * 65.0 + 4.0 * LEVELS as f64) * eps * total;
    let mut worst = 0.0f64;
    for seed in 0..4 {
        let mut state: PreisachState = measure.negative_saturation();
        let mut memory = Memory::negative_saturation(LEVELS);
        let mut pieces: Vec<Piece> = Vec::new();
        let mut f = [0.0; CELL_COUNT];
        for x in inputs(seed, 2000) {
            let h = h_min + x * width;
            let m_core = measure.apply(&mut state, h as f32).unwrap() as f64;
            // Feed the f64 side the same (f32-rounded) input the core saw.
            memory.move_to(((h as f32) as f64 - h_min) / width);
            fractions(&memory, &mut pieces, &mut f);
            let m = output(&f, w64);
            worst = worst.max((m - m_core).abs());
            assert!(
                (m - m_core).abs() <= tol,
                "seed {seed}: f64 fractions give {m}, core {m_core}, tolerance {tol}"
            );
            assert_eq!(
                state.merges(),
                0,
                "the test sequence must not overflow the core"
            );
        }
    }
    println!("worst |Σw(2f-1) - core| = {worst:.3e} A/m (tolerance {tol:.3e}, Σw = {total:.4e})");
}

#[test]
fn staircases_match_the_core() {
    let params = actuator_params::paper_defaults();
    let mut w32 = [0f32; CORE_CELLS];
    for (a, b) in w32.iter_mut().zip(&params.preisach.weights_a_per_m) {
        *a = *b as f32;
    }
    let measure = PreisachMeasure::new(&w32, 0.0, LEVELS as f32);
    let mut state: PreisachState = measure.negative_saturation();
    let mut memory = Memory::negative_saturation(LEVELS);
    for x in inputs(7, 3000) {
        // Inputs exactly representable in f32 (multiples of 1/64): both sides see the same number.
        let x = (x * 64.0).round() / 64.0;
        measure.apply(&mut state, x as f32).unwrap();
        memory.move_to(x);
        let core: Vec<f64> = state
            .reversal_points_normalized()
            .map(|v| v as f64)
            .collect();
        assert_eq!(core, memory.reversal_points(), "after input {x}");
    }
}

#[test]
fn fractions_are_areas_in_unit_range_and_saturate() {
    let mut pieces = Vec::new();
    let mut f = [0.0; CELL_COUNT];
    fractions(&Memory::negative_saturation(LEVELS), &mut pieces, &mut f);
    assert!(f.iter().all(|&v| v == 0.0));
    fractions(&Memory::positive_saturation(LEVELS), &mut pieces, &mut f);
    assert!(f.iter().all(|&v| (v - 1.0).abs() < 1e-12), "{f:?}");
    // Demagnetized about the centre: P₊ = {α + β < L}, half of every cell the line cuts through
    // its centre, so Σ (2f - 1) area_k = 0 (zero output for any symmetric uniform measure).
    let demag = Memory::demagnetized(LEVELS, LEVELS as f64 / 2.0);
    fractions(&demag, &mut pieces, &mut f);
    let uniform: Vec<f64> = (0..CELL_COUNT)
        .map(|k| {
            if maglab_identify::cell_of_index(k).0 == maglab_identify::cell_of_index(k).1 {
                0.5
            } else {
                1.0
            }
        })
        .collect();
    let m = output(&f, &uniform);
    // Bound of memory::DEMAG_STEP for ρ_max = 1: L δ² / 2.
    let bound = LEVELS as f64 * maglab_identify::memory::DEMAG_STEP.powi(2) / 2.0;
    assert!(m.abs() <= bound, "demagnetized output {m}, bound {bound}");
}
