//! The cases of a blind-suite seed as drawn and calibrated, without a diagnosis:
//! `cargo run --release -p maglab-plant --example draw_suite -- SEED [COUNT]` prints each case
//! (its effects, target and reached gaps) and the time its draw took, one thread, so the cost of
//! the plant's calibration can be read apart from the diagnoses'.
use maglab_plant::suite;
use std::time::Instant;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let seed: u64 = match args.first().map(|s| s.parse()) {
        Some(Ok(s)) => s,
        _ => {
            eprintln!("usage: draw_suite SEED [COUNT]  (SEED: a whole number)");
            std::process::exit(2);
        }
    };
    let count: usize = match args.get(1).map(|s| s.parse()) {
        None => 32,
        Some(Ok(c)) => c,
        Some(Err(_)) => {
            eprintln!("draw_suite: COUNT {:?} is not a whole number", args[1]);
            std::process::exit(2);
        }
    };
    let params = actuator_params::paper_defaults();
    let all = Instant::now();
    for (i, kind) in suite::kinds(seed, count).into_iter().enumerate() {
        let started = Instant::now();
        let case = suite::draw(
            &params,
            seed.wrapping_mul(1000).wrapping_add(i as u64),
            kind,
        )
        .unwrap_or_else(|e| {
            eprintln!("draw_suite: case {i} of seed {seed}: {e}");
            std::process::exit(1);
        });
        let targets: Vec<String> = case
            .target_gaps
            .iter()
            .map(|g| format!("{:.1} %", 100.0 * g))
            .collect();
        println!(
            "{i:2} {} (targets {}) [{:.1} s]",
            case.describe(),
            targets.join(", "),
            started.elapsed().as_secs_f64()
        );
    }
    println!(
        "seed {seed}: {count} cases drawn in {:.1} s",
        all.elapsed().as_secs_f64()
    );
}
