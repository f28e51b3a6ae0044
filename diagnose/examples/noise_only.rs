//! The diagnosis's false-alarm rate on noise-only data: `cargo run --release -p
//! maglab-diagnose --example noise_only -- [COUNT] [FIRST_SEED]` draws COUNT noise-only
//! datasets on the bench plant (noise level, current interpolation, channel skew, offset and
//! start states drawn as in the blind suite; `BLIND_DESIGN=varied` for the varied experiment
//! design), diagnoses each against the true nominal file, and prints how often the verdict is
//! not `none`, with its one-sided 95 % upper confidence bound (Clopper–Pearson), and the
//! distribution of the statistic that decides `none`: the refitted nominal model's held-out
//! systematic gap in units of the noise, against the resolution floor
//! (`rules::resolution_floor`, 0.35 σ) and the none threshold (`rules::none_threshold`, 1 σ).
//!
//! The seeds start at 9,000,000 by default, a stream the blind suite's cases (seed × 1000 +
//! index for seeds below 9000) never reach.
#[path = "../tests/blind/mod.rs"]
mod blind;

use maglab_plant::suite::{self, Kind};

fn quantile(sorted: &[f64], q: f64) -> f64 {
    let i = ((sorted.len() - 1) as f64 * q).round() as usize;
    sorted[i]
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let count: usize = args
        .first()
        .map_or(40, |s| s.parse().expect("COUNT is a number"));
    let first_seed: u64 = args
        .get(1)
        .map_or(9_000_000, |s| s.parse().expect("FIRST_SEED is a number"));
    let params = actuator_params::paper_defaults();
    let design = blind::design_from_env();
    let mut alarms = Vec::new();
    let mut gap_sigma = Vec::new();
    for i in 0..count as u64 {
        let seed = first_seed + i;
        let case = suite::draw_on(
            &params,
            None,
            seed,
            Kind::NoiseOnly,
            design,
            suite::Forms::Original,
        )
        .expect("the case is drawn");
        let described = case.describe();
        let o = blind::run_case(&params, &params, case);
        let d = &o.diagnosis;
        let g = d.refitted_nominal.systematic_before_m / d.noise_m;
        gap_sigma.push(g);
        if d.verdict != "none" {
            alarms.push(seed);
        }
        println!(
            "{seed}: {} (grade {}), held-out gap {g:.3} sigma, model error {:.3} sigma, {:.1} s; {described}",
            d.verdict,
            d.grade.name(),
            d.model_error_m / d.noise_m,
            o.seconds
        );
    }
    gap_sigma.sort_by(f64::total_cmp);
    println!(
        "\nnoise only, design {}: {} of {count} not `none` (seeds {alarms:?}); false-alarm rate \
         <= {:.1} % (one-sided 95 %)",
        if design == suite::Design::Standard {
            "standard"
        } else {
            "varied"
        },
        alarms.len(),
        100.0 * blind::upper_bound(alarms.len(), count, 0.05)
    );
    println!(
        "held-out systematic gap of the refitted nominal model, sigma: median {:.3}, 90 % {:.3}, \
         max {:.3} (floor 0.35 sigma: `none` outright below it)",
        quantile(&gap_sigma, 0.5),
        quantile(&gap_sigma, 0.9),
        gap_sigma[gap_sigma.len() - 1]
    );
}
