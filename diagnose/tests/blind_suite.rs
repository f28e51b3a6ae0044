//! The blind suite: datasets from the bench plant (`maglab-plant`, whose equations the
//! diagnosis does not share) with single library effects, pairs, out-of-library effects and
//! noise only, drawn at random from fixed seeds and calibrated to 5–30 % gaps. The goal is the
//! right set named in ≥ 90 % of the cases; CI asserts a regression floor of 85 % on seed 1 and
//! prints the matrix (`BLIND_MIN_PERCENT=90` asserts the goal). docs/diagnosis.md has the
//! figures on other seeds.
//!
//! Why a floor below the measured count: a rounding-level change of the model (the same
//! integrator evaluated as a matrix instead of a loop) flips 2–3 of 32 verdicts in either
//! direction — cases whose margins lie within the fits' flat directions — so an exact count
//! would fail on unrelated changes.
//!
//! `BLIND_SEED` (default 1) and `BLIND_CASES` (default 32) choose another suite,
//! `BLIND_DESIGN=varied` another experiment design per case (`maglab_plant::suite::Design`:
//! frequencies, amplitudes, bias, rate and duration drawn too), `BLIND_RODS=families` every case
//! on a rod of its own (`maglab_plant::rods`: the four families, planes 1× to 5× the coil's
//! reach), diagnosed against the file `maglab identify` makes from that rod's effect-free
//! standard dataset (no file of the model's form describes such a rod exactly); the example
//! `cargo run --release -p maglab-diagnose --example blind_suite -- SEED COUNT` prints one
//! without asserting.
mod blind;

use std::io::Write;

#[test]
fn blind_suite_names_the_right_effect() {
    let seed: u64 = std::env::var("BLIND_SEED").map_or(1, |s| s.parse().expect("BLIND_SEED"));
    let count: usize = std::env::var("BLIND_CASES").map_or(32, |s| s.parse().expect("BLIND_CASES"));
    let started = std::time::Instant::now();
    let outcomes = blind::run_suite(seed, count, true);
    let matrix = blind::confusion_matrix(&outcomes);
    // Written to the process's stderr, past libtest's capture (which takes only the print
    // macros), so that `cargo xtask test`'s log shows the matrix on a pass too.
    let _ = writeln!(
        std::io::stderr(),
        "\nblind suite, seed {seed}, forms {}:\n{matrix}\n{}",
        blind::forms_from_env().name(),
        blind::summary(&outcomes)
    );
    let mut seconds: Vec<f64> = outcomes.iter().map(|o| o.seconds).collect();
    seconds.sort_by(f64::total_cmp);
    let _ = writeln!(
        std::io::stderr(),
        "diagnosis time per case: median {:.1} s, max {:.1} s; suite {:.0} s",
        seconds[seconds.len() / 2],
        seconds[seconds.len() - 1],
        started.elapsed().as_secs_f64()
    );
    // Every case's gaps lie in the drawn 5–30 % band (or the case is noise only), or fall short
    // of their target where none of the effect's drawn shapes reaches it
    // (`maglab_plant::suite::REACHED_SHARE`; counted below, never silently).
    // In the varied design an effect's plausible range may not reach 5 % at the frequencies a
    // case was drawn with (a 200 Hz sensor lag seen up to 270 Hz): such cases stay in, weaker.
    // So may an effect on a rod the coil cannot saturate (rod mode: its loops strain the rod less).
    // So may another physical form of an effect than the plant's first (`BLIND_FORMS`).
    let lowest = match (
        blind::design_from_env(),
        blind::rods_from_env(),
        blind::forms_from_env(),
    ) {
        (maglab_plant::suite::Design::Standard, false, maglab_plant::suite::Forms::Original) => {
            0.04
        }
        _ => 0.0,
    };
    let mut short = Vec::new();
    for o in &outcomes {
        for (i, (g, e)) in o.case.gaps.iter().zip(&o.case.effects).enumerate() {
            if *g < lowest && !o.case.reached(i) {
                short.push(format!(
                    "case {} {}: {:.1} % for {:.1} %",
                    o.case.seed,
                    e.spec.name,
                    100.0 * g,
                    100.0 * o.case.target_gaps[i]
                ));
                continue;
            }
            assert!(
                (lowest..=0.32).contains(g),
                "case {} ({}): gap {:.1} % of {} outside 5–30 %",
                o.case.seed,
                o.case.kind.label(),
                100.0 * g,
                e.spec.name
            );
        }
    }
    if !short.is_empty() {
        let _ = writeln!(
            std::io::stderr(),
            "effects below the band, short of their target gap in every drawn shape: {}",
            short.join("; ")
        );
    }
    // Every miss's report names a recording that would separate its candidates.
    let advice = blind::advice_on_misses(&outcomes);
    let _ = writeln!(
        std::io::stderr(),
        "advice on the {} misses: {} without a recording; {} of {} library misses advise on \
         every true effect",
        advice.misses,
        advice.without_advice.len(),
        advice.truth_among_candidates,
        advice.library_misses
    );
    assert!(
        advice.without_advice.is_empty(),
        "misses whose report names no recording to separate the candidates: cases {:?}",
        advice.without_advice
    );
    let correct = outcomes.iter().filter(|o| o.correct).count();
    let min_percent: usize = std::env::var("BLIND_MIN_PERCENT").map_or(85, |s| {
        s.parse().expect("BLIND_MIN_PERCENT: a whole percentage")
    });
    let _ = writeln!(
        std::io::stderr(),
        "{correct}/{} correct; asserted >= {min_percent} % (the goal is 90 %)",
        outcomes.len()
    );
    assert!(
        100 * correct >= min_percent * outcomes.len(),
        "{correct}/{} correct, below {min_percent} %",
        outcomes.len()
    );
}

/// On rods the coil cannot saturate (`BLIND_RODS=families` runs the whole suite there), the
/// noise-only cases of seed 1 are `none` against the file identified from each rod's standard
/// dataset with quasi-static loops on the case's own loops (`blind::identified_nominal`): the
/// reachable plane and its offset describe the rod, no false alarm. And the file identified
/// without those loops says so: the case's loops are reported as not measured, with the
/// recording that measures them first in the advice (`maglab_diagnose::diagnosis::coverage`).
#[test]
fn on_rods_noise_only_is_none_and_loops_the_masses_lack_are_reported() {
    use maglab_diagnose::diagnosis::advice::Recording;
    use maglab_plant::bench::operating_loops;
    let params = actuator_params::paper_defaults();
    let kinds = maglab_plant::suite::kinds(1, 32);
    let noise_only: Vec<usize> = (0..kinds.len())
        .filter(|&i| kinds[i] == maglab_plant::suite::Kind::NoiseOnly)
        .collect();
    assert!(!noise_only.is_empty());
    let draw = |i: usize| {
        maglab_plant::suite::draw_on(
            &params,
            Some(&blind::rod_of_case(i)),
            1000 + i as u64,
            kinds[i].clone(),
            maglab_plant::suite::Design::Standard,
            maglab_plant::suite::Forms::Original,
        )
        .expect("the case is drawn")
    };
    for &i in &noise_only {
        let rod = blind::rod_of_case(i);
        let case = draw(i);
        let loops = operating_loops(&case.experiments, blind::LOOP_TOLERANCE_A);
        let nominal = blind::identified_nominal(&params, &rod, &loops);
        let o = blind::run_case(&params, &nominal, case);
        let d = &o.diagnosis;
        let _ = writeln!(
            std::io::stderr(),
            "rod {}: noise only -> {} (held-out systematic gap {:.3} sigma)",
            rod.label(),
            o.named.join("+"),
            d.refitted_nominal.systematic_before_m / d.noise_m
        );
        assert!(
            o.graded_correct,
            "rod {}: {}",
            rod.label(),
            d.verdict_reason
        );
        assert!(d.unmeasured_loops.is_empty(), "{:?}", d.unmeasured_loops);
    }
    // The first of them against the file of the standard dataset alone (its sines run at
    // another bias): the case's loops were not measured.
    let i = noise_only[0];
    let rod = blind::rod_of_case(i);
    let nominal = blind::identified_nominal(&params, &rod, &[]);
    let o = blind::run_case(&params, &nominal, draw(i));
    let d = &o.diagnosis;
    let _ = writeln!(
        std::io::stderr(),
        "rod {}, file without the case's loops: {} -> {}; {:?}",
        rod.label(),
        o.named.join("+"),
        d.advice.first().map(|a| a.purpose()).unwrap_or_default(),
        d.unmeasured_loops_warning
    );
    assert!(!d.unmeasured_loops.is_empty());
    assert!(d.unmeasured_loops_warning.is_some());
    assert_eq!(
        d.advice.first().map(|a| a.recording),
        Some(Recording::MeasuredLoops)
    );
}
