//! The blind suite's runner, shared by the test and the example that prints a suite for any
//! seed: draw the cases on the bench plant (`maglab_plant::suite`), diagnose each through the
//! public API exactly as `maglab diagnose` does, and tabulate.
#![allow(dead_code)]

use maglab_dataset::data::Measurement;
use maglab_dataset::dataset_info::{DatasetInfo, FileInfo};
use maglab_diagnose::diagnosis::{diagnose, DiagnoseOptions, Diagnosis};
use maglab_plant::suite::{self, Case, Kind};

/// One diagnosed case.
pub struct Outcome {
    pub case: Case,
    pub named: Vec<String>,
    pub correct: bool,
    pub seconds: f64,
    pub diagnosis: Diagnosis,
}

/// Diagnoses one case.
pub fn run_case(params: &actuator_params::ActuatorParams, case: Case) -> Outcome {
    let recordings = case.record(params).expect("the plant runs");
    let rate = case.settings.rate_hz;
    let measurements: Vec<Measurement> = recordings
        .iter()
        .map(|r| Measurement {
            path: format!("case/{}.csv", r.name).into(),
            t_s: r.t_s.clone(),
            current_a: r.current_a.clone(),
            displacement_m: r.displacement_m.clone(),
            step_s: 1.0 / rate,
        })
        .collect();
    let documented = case.documented.then(|| {
        let mut info = DatasetInfo::default();
        for r in &recordings {
            info.files.insert(
                format!("{}.csv", r.name),
                FileInfo {
                    start_state: Some(r.start),
                    excitation: Some(r.description.clone()),
                },
            );
        }
        info
    });
    let started = std::time::Instant::now();
    let run = diagnose(
        params,
        &measurements,
        documented.as_ref(),
        &DiagnoseOptions::default(),
        &|_| {},
    )
    .expect("the diagnosis runs");
    let seconds = started.elapsed().as_secs_f64();
    let d = run.diagnosis;
    let mut named: Vec<String> = std::iter::once(d.verdict.clone())
        .chain(d.additional_effects.iter().cloned())
        .collect();
    named.sort();
    let expected: Vec<String> = case.kind.expected().iter().map(|s| s.to_string()).collect();
    Outcome {
        correct: named == expected,
        named,
        seconds,
        diagnosis: d,
        case,
    }
}

/// The experiment design from `BLIND_DESIGN` (`standard`, the default, or `varied`:
/// `maglab_plant::suite::Design`).
pub fn design_from_env() -> suite::Design {
    suite::Design::from_env("BLIND_DESIGN").unwrap_or_else(|e| panic!("{e}"))
}

/// The suite of `count` cases from `seed`, drawn and diagnosed on all cores (each case is
/// independent; the outcomes come back in case order), in the design of [`design_from_env`].
pub fn run_suite(seed: u64, count: usize, verbose: bool) -> Vec<Outcome> {
    let params = actuator_params::paper_defaults();
    let design = design_from_env();
    let kinds = suite::kinds(seed, count);
    let next = std::sync::atomic::AtomicUsize::new(0);
    let results = std::sync::Mutex::new(Vec::new());
    // `BLIND_THREADS` (default: the cores this process may use) cases at a time; `cargo xtask
    // test` sets it when it starts the suite confined to one core that it widens later.
    let threads = std::env::var("BLIND_THREADS").map_or_else(
        |_| std::thread::available_parallelism().map_or(1, |n| n.get()),
        |s| s.parse().expect("BLIND_THREADS: a whole number"),
    );
    std::thread::scope(|scope| {
        for _ in 0..threads {
            scope.spawn(|| loop {
                let i = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                let Some(kind) = kinds.get(i) else { break };
                let case = suite::draw_with(
                    &params,
                    seed.wrapping_mul(1000).wrapping_add(i as u64),
                    kind.clone(),
                    design,
                )
                .expect("the case is drawn");
                let o = run_case(&params, case);
                if verbose {
                    // The gap left by the best single candidate (also in units of the noise σ:
                    // the second stage's trigger) and by the best pair, % of the refitted
                    // nominal model's systematic gap (the margins of the verdict), and
                    // that gap against the model's own integration error (`none` within 1.5x).
                    let d = &o.diagnosis;
                    let gap0 = d.refitted_nominal.systematic_before_m.max(1e-300);
                    let single = d.ranking.first().map_or(f64::NAN, |c| c.systematic_after_m);
                    let pair = d.second_stage.first().map_or(f64::NAN, |c| c.systematic_after_m);
                    println!(
                        "{} {:2} {} -> {} ({:.1} s; gap {:.1}x the model's integration error at {} substep(s); best single leaves {:.0} % ({:.1} sigma), best pair {:.0} %){}",
                        if o.correct { "ok  " } else { "MISS" },
                        i,
                        o.case.describe(),
                        o.named.join("+"),
                        o.seconds,
                        gap0 / d.model_error_m.max(1e-300),
                        d.substeps,
                        100.0 * single / gap0,
                        single / d.noise_m.max(1e-300),
                        100.0 * pair / gap0,
                        if o.correct {
                            String::new()
                        } else {
                            format!("\n       {}", o.diagnosis.verdict_reason)
                        }
                    );
                }
                results.lock().expect("no thread panicked").push((i, o));
            });
        }
    });
    let mut results = results.into_inner().expect("no thread panicked");
    results.sort_by_key(|(i, _)| *i);
    results.into_iter().map(|(_, o)| o).collect()
}

/// The confusion matrix as Markdown: rows are what the case contains (pairs pooled), columns
/// what the diagnosis named.
pub fn confusion_matrix(outcomes: &[Outcome]) -> String {
    let row_of = |k: &Kind| match k {
        Kind::Single(e) => e.to_string(),
        Kind::Pair(..) => "pair of library effects".into(),
        Kind::OutOfLibrary(e) => format!("{e} (not in library)"),
        Kind::NoiseOnly => "noise only".into(),
    };
    let col_of = |o: &Outcome| match &o.case.kind {
        Kind::Pair(..) if o.correct => "both of the pair".to_string(),
        _ => o.named.join("+"),
    };
    let mut rows: Vec<String> = Vec::new();
    let mut cols: Vec<String> = Vec::new();
    for o in outcomes {
        let r = row_of(&o.case.kind);
        if !rows.contains(&r) {
            rows.push(r);
        }
        let c = col_of(o);
        if !cols.contains(&c) {
            cols.push(c);
        }
    }
    rows.sort();
    cols.sort();
    let mut s = format!(
        "| case \\ named | {} |\n|---|{}\n",
        cols.join(" | "),
        "---|".repeat(cols.len())
    );
    for r in &rows {
        let cells: Vec<String> = cols
            .iter()
            .map(|c| {
                let n = outcomes
                    .iter()
                    .filter(|o| &row_of(&o.case.kind) == r && &col_of(o) == c)
                    .count();
                if n == 0 {
                    String::new()
                } else {
                    n.to_string()
                }
            })
            .collect();
        s.push_str(&format!("| {r} | {} |\n", cells.join(" | ")));
    }
    let correct = outcomes.iter().filter(|o| o.correct).count();
    s.push_str(&format!(
        "\n{correct}/{} correct ({:.0} %)\n",
        outcomes.len(),
        100.0 * correct as f64 / outcomes.len().max(1) as f64
    ));
    s
}
