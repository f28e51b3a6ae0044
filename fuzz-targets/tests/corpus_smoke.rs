//! The fuzz smoke of `cargo xtask test`: every file of the kept corpus (`fuzz/corpus/<target>/`)
//! and 2,000 seeded random inputs per target (fresh bytes and mutations of corpus files) through
//! each target on stable. The long runs are `cargo xtask fuzz` (cargo-fuzz, nightly).

use maglab_fuzz_targets::{run, TARGETS};
use rand::rngs::Xoshiro256PlusPlus;
use rand::{RngExt, SeedableRng};
use std::path::Path;

fn corpus(target: &str) -> Vec<Vec<u8>> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .join("fuzz")
        .join("corpus")
        .join(target);
    let mut files: Vec<_> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .filter_map(|e| e.ok().map(|e| e.path()))
        .collect();
    files.sort();
    files.iter().filter_map(|p| std::fs::read(p).ok()).collect()
}

#[test]
fn every_target_survives_its_corpus_and_random_inputs() {
    for target in TARGETS {
        let kept = corpus(target);
        assert!(!kept.is_empty(), "{target}: empty corpus");
        for input in &kept {
            assert!(run(target, input));
        }
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(0xf022);
        for k in 0..2_000 {
            let mut input = if k % 2 == 0 || kept.is_empty() {
                (0..rng.random_range(0..400))
                    .map(|_| rng.random())
                    .collect()
            } else {
                kept[rng.random_range(0..kept.len())].clone()
            };
            for _ in 0..rng.random_range(0..8) {
                if input.is_empty() {
                    break;
                }
                let at = rng.random_range(0..input.len());
                match rng.random_range(0..3) {
                    0 => input[at] = rng.random(),
                    1 => {
                        input.remove(at);
                    }
                    _ => input.insert(at, rng.random()),
                }
            }
            run(target, &input);
        }
        println!("{target}: {} corpus files + 2000 random inputs", kept.len());
    }
}
