//! Prints the blind suite for any seed: `cargo run --release -p maglab-diagnose --example
//! blind_suite -- SEED [COUNT]` (`BLIND_DESIGN=varied`: the varied experiment design,
//! `maglab_plant::suite::Design`; `BLIND_FORMS=tuning|held-out|all`: the effects' form set,
//! `maglab_plant::suite::Forms`).
#[path = "../tests/blind/mod.rs"]
mod blind;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let seed: u64 = args
        .first()
        .map_or(1, |s| s.parse().expect("SEED is a number"));
    let count: usize = args
        .get(1)
        .map_or(32, |s| s.parse().expect("COUNT is a number"));
    let started = std::time::Instant::now();
    let outcomes = blind::run_suite(seed, count, true);
    println!(
        "\nforms {}:\n{}\n{}",
        blind::forms_from_env().name(),
        blind::confusion_matrix(&outcomes),
        blind::summary(&outcomes)
    );
    println!(
        "suite seed {seed}: {} cases in {:.0} s",
        outcomes.len(),
        started.elapsed().as_secs_f64()
    );
}
