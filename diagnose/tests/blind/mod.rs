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
    /// Right under the graded scoring ([`graded_right`]).
    pub graded_correct: bool,
    pub seconds: f64,
    pub diagnosis: Diagnosis,
}

/// Diagnoses one case recorded on a plant of `plant_params` (and the case's rod, if any) against
/// the `nominal` file.
pub fn run_case(
    plant_params: &actuator_params::ActuatorParams,
    nominal: &actuator_params::ActuatorParams,
    case: Case,
) -> Outcome {
    let params = nominal;
    let recordings = case.record(plant_params).expect("the plant runs");
    let rate = case.settings.rate_hz;
    let measurements: Vec<Measurement> = recordings
        .iter()
        .map(|r| Measurement {
            path: format!("case/{}.csv", r.name).into(),
            t_s: r.t_s.clone(),
            current_a: r.current_a.clone(),
            displacement_m: r.displacement_m.clone(),
            coil_current_a: r.coil_current_a.clone(),
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
    Outcome {
        correct: case.kind.strictly_right(&named),
        graded_correct: graded_right(&case.kind, &named, &d),
        named,
        seconds,
        diagnosis: d,
        case,
    }
}

/// What diagnosis `d`, whose named set is `named`, said, as the suite's scorings read it.
fn said<'a>(named: &'a [String], d: &'a Diagnosis) -> suite::Said<'a> {
    suite::Said {
        verdict: &d.verdict,
        named,
        grade: d.grade.name(),
        partly_explained: d.partly_explained.as_ref().map(|p| p.effect.as_str()),
        either: &d.either,
    }
}

/// The graded scoring ([`Kind::graded_right`]) of diagnosis `d`, whose named set is `named`.
pub fn graded_right(kind: &Kind, named: &[String], d: &Diagnosis) -> bool {
    kind.graded_right(&said(named, d))
}

/// What the verdict said, graded: `X`, `X+Y`, `partly X`, `X or Y`, `unexplained`, `none`.
pub fn graded_label(o: &Outcome) -> String {
    said(&o.named, &o.diagnosis).label()
}

/// Right per kind of case, strict and graded, and how often each grade was given, as Markdown.
pub fn summary(outcomes: &[Outcome]) -> String {
    let class = |k: &Kind| match k {
        Kind::Single(_) => "single library effect",
        Kind::Pair(..) => "pair",
        Kind::OutOfLibrary(_) => "outside the library",
        Kind::NoiseOnly => "noise only",
    };
    let mut s =
        String::from("| kind | cases | right (strict) | right (graded) |\n|---|---|---|---|\n");
    for c in [
        "single library effect",
        "pair",
        "outside the library",
        "noise only",
    ] {
        let of: Vec<&Outcome> = outcomes
            .iter()
            .filter(|o| class(&o.case.kind) == c)
            .collect();
        s.push_str(&format!(
            "| {c} | {} | {} | {} |\n",
            of.len(),
            of.iter().filter(|o| o.correct).count(),
            of.iter().filter(|o| o.graded_correct).count()
        ));
    }
    let mut grades: std::collections::BTreeMap<&str, usize> = Default::default();
    for o in outcomes {
        *grades.entry(o.diagnosis.grade.name()).or_default() += 1;
    }
    s.push_str(&format!(
        "\ngrades given: {}\n",
        grades
            .iter()
            .map(|(g, n)| format!("{g} {n}"))
            .collect::<Vec<_>>()
            .join(", ")
    ));
    let graded = outcomes.iter().filter(|o| o.graded_correct).count();
    s.push_str(&format!(
        "{graded}/{} right graded ({:.0} %)\n",
        outcomes.len(),
        100.0 * graded as f64 / outcomes.len().max(1) as f64
    ));
    s
}

/// What the misses' reports advise recording (`Diagnosis::advice`): the misses (graded scoring),
/// those whose report names no recording, and, of the misses with library effects, those whose
/// advice has every true effect among its candidates.
pub struct AdviceOnMisses {
    pub misses: usize,
    pub without_advice: Vec<u64>,
    pub library_misses: usize,
    pub truth_among_candidates: usize,
}

/// Tabulates [`AdviceOnMisses`].
pub fn advice_on_misses(outcomes: &[Outcome]) -> AdviceOnMisses {
    let mut a = AdviceOnMisses {
        misses: 0,
        without_advice: Vec::new(),
        library_misses: 0,
        truth_among_candidates: 0,
    };
    for o in outcomes.iter().filter(|o| !o.graded_correct) {
        a.misses += 1;
        let advice = &o.diagnosis.advice;
        if advice.is_empty() {
            a.without_advice.push(o.case.seed);
        }
        let truth: Vec<&str> = match o.case.kind {
            Kind::Single(e) => vec![e],
            Kind::Pair(x, y) => vec![x, y],
            _ => continue,
        };
        a.library_misses += 1;
        let advised = |e: &str| advice.iter().any(|x| x.candidates.iter().any(|c| c == e));
        if truth.iter().all(|e| advised(e)) {
            a.truth_among_candidates += 1;
        }
    }
    a
}

/// The experiment design from `BLIND_DESIGN` (`standard`, the default, or `varied`:
/// `maglab_plant::suite::Design`).
pub fn design_from_env() -> suite::Design {
    suite::Design::from_env("BLIND_DESIGN").unwrap_or_else(|e| panic!("{e}"))
}

/// The effects' form set from `BLIND_FORMS` (`original`, the default, `tuning`, `held-out` or
/// `all`: `maglab_plant::suite::Forms`).
pub fn forms_from_env() -> suite::Forms {
    suite::Forms::from_env("BLIND_FORMS").unwrap_or_else(|e| panic!("{e}"))
}

/// `case` with the coil-current channel recorded when `BLIND_COIL_CURRENT=measured` asks for
/// it (`maglab_plant::CurrentMonitor::TYPICAL`: 1 mA of noise in 1 mA steps; `off`, the
/// default: the commanded current only). The draws are the same either way: the channel's
/// noise has a stream of its own.
pub fn with_coil_current_from_env(mut case: Case) -> Case {
    match std::env::var("BLIND_COIL_CURRENT").as_deref() {
        Err(_) | Ok("") | Ok("off") => {}
        Ok("measured") => case.settings.coil_current = Some(maglab_plant::CurrentMonitor::TYPICAL),
        Ok(other) => panic!("BLIND_COIL_CURRENT `{other}`: expected `measured` or `off`"),
    }
    case
}

/// The rod of case `i` in the rod mode (`BLIND_RODS=families`): the four families in turn, their
/// planes 1× to 5× the coil's reach (`maglab_plant::rods`), default coercivity and spread.
pub fn rod_of_case(i: usize) -> maglab_plant::Rod {
    let (_, family) = maglab_plant::Family::NAMES[i % 4];
    maglab_plant::Rod::new(family, (1 + (i / 4) % 5) as f64)
}

/// Whether `BLIND_RODS=families` asks for the rod mode: each case on a rod of its own
/// ([`rod_of_case`]), diagnosed against the file `maglab identify` makes from that rod's
/// effect-free standard dataset with quasi-static loops on the case's own loops
/// (`maglab_plant::bench::identification_design_covering`, 20 nm of noise): the nominal file a
/// bench could have, since no file of the model's form describes such a rod exactly. The masses
/// are measured where the case's experiments run, as `maglab identify` asks of a dataset
/// (`maglab_identify::coverage`): a file whose masses were never measured on a loop predicts it
/// by the smoothness of its fit alone, which is no effect of the library.
pub fn rods_from_env() -> bool {
    match std::env::var("BLIND_RODS").as_deref() {
        Err(_) | Ok("") | Ok("off") => false,
        Ok("families") => true,
        Ok(other) => panic!("BLIND_RODS `{other}`: expected `families` or `off`"),
    }
}

/// Loops of a case within this of each other's bias and amplitude are one (the sweep's
/// frequencies jitter, its amplitudes do not).
pub const LOOP_TOLERANCE_A: f64 = 0.01;

/// Numbers the rod datasets' folders of this process (cases identify in parallel).
static NEXT_DIR: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);

/// The nominal file of `rod`: identified from its effect-free standard dataset with a
/// quasi-static sine on each of `loops` (`(bias, amplitude)`, A) as well.
pub fn identified_nominal(
    params: &actuator_params::ActuatorParams,
    rod: &maglab_plant::Rod,
    loops: &[(f64, f64)],
) -> actuator_params::ActuatorParams {
    use maglab_identify::experiments::ClassifyOptions;
    use maglab_identify::pipeline::{identify, Base, IdentifyOptions, RecordedDataset};
    use maglab_plant::bench::{self, BenchSettings};
    let settings = BenchSettings {
        noise_m: 20e-9,
        ..BenchSettings::default()
    };
    let plant = maglab_plant::Plant::with_rod(params, rod, &[], settings.rate_hz).expect("plant");
    let recordings = bench::record_all_on(
        plant,
        &bench::identification_design_covering(settings.rate_hz, loops),
        &settings,
    )
    .expect("the rod's standard dataset");
    let dir = std::env::temp_dir().join(format!(
        "maglab-blind-rod-{}-{}-{}",
        rod.label().replace(':', "-"),
        std::process::id(),
        NEXT_DIR.fetch_add(1, std::sync::atomic::Ordering::Relaxed)
    ));
    let _ = std::fs::remove_dir_all(&dir);
    bench::write_dataset(&dir, &recordings).expect("write");
    let dataset = RecordedDataset::load(&dir, &ClassifyOptions::default()).expect("load");
    let identified = identify(
        &dataset,
        Base {
            params,
            name: "default parameters",
        },
        &IdentifyOptions::default(),
        &|_, _, _| {},
    )
    .expect("the rod is identified");
    let _ = std::fs::remove_dir_all(&dir);
    identified.params
}

/// The suite of `count` cases from `seed`, drawn and diagnosed on all cores (each case is
/// independent; the outcomes come back in case order), in the design of [`design_from_env`].
pub fn run_suite(seed: u64, count: usize, verbose: bool) -> Vec<Outcome> {
    let params = actuator_params::paper_defaults();
    let design = design_from_env();
    let forms = forms_from_env();
    let rods = rods_from_env();
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
                let rod = rods.then(|| rod_of_case(i));
                let case = suite::draw_on(
                    &params,
                    rod.as_ref(),
                    seed.wrapping_mul(1000).wrapping_add(i as u64),
                    kind.clone(),
                    design,
                    forms,
                )
                .expect("the case is drawn");
                let case = with_coil_current_from_env(case);
                // Each case's rod is identified on the loops the case runs (one file per case).
                let nominal = match &rod {
                    None => params.clone(),
                    Some(r) => identified_nominal(
                        &params,
                        r,
                        &maglab_plant::bench::operating_loops(&case.experiments, LOOP_TOLERANCE_A),
                    ),
                };
                let o = run_case(&params, &nominal, case);
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
        _ => graded_label(o),
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

/// One-sided upper bound at confidence `1 − alpha` on a rate of which `k` of `n` trials were
/// seen (Clopper–Pearson: the `p` at which `P(X ≤ k; n, p) = alpha`), by bisection.
pub fn upper_bound(k: usize, n: usize, alpha: f64) -> f64 {
    let cdf = |p: f64| {
        // P(X ≤ k) for X ~ Binomial(n, p), summed term by term.
        let mut term = (1.0 - p).powi(n as i32);
        let mut sum = term;
        for i in 0..k {
            term *= (n - i) as f64 / (i + 1) as f64 * p / (1.0 - p);
            sum += term;
        }
        sum
    };
    if k >= n {
        return 1.0;
    }
    let (mut lo, mut hi) = (0.0_f64, 1.0_f64);
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if cdf(mid) > alpha {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    hi
}

#[cfg(test)]
mod upper_bound_tests {
    #[test]
    fn the_bound_for_no_alarms_is_the_rule_of_three() {
        // k = 0: 1 − 0.05^(1/n) ≈ 3/n.
        let b = super::upper_bound(0, 100, 0.05);
        assert!((b - (1.0 - 0.05_f64.powf(0.01))).abs() < 1e-9, "{b}");
        // k = n/2 of a large n sits just above one half.
        let b = super::upper_bound(500, 1000, 0.05);
        assert!(b > 0.5 && b < 0.53, "{b}");
    }
}
