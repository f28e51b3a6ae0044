//! The blind suite through identify → diagnose: each case of the diagnosis's blind suite
//! (`maglab_plant::suite`, the same draws as `diagnose/tests/blind_suite.rs`) recorded with a
//! quasi-static reversal sweep in front of its sines, written as a dataset folder, identified
//! with `maglab identify` (the effect is in the data the masses and R_eddy, ξ, f0 come from),
//! then diagnosed with `maglab diagnose --params identified.json`. The cases whose start states
//! the suite leaves undocumented document only the sweep's.
//!
//! `maglab identify` starts from a datasheet's base file (`--params`): the paper defaults with
//! R_eddy, ξ, f0 off by ×1.4, ×0.75, ×1.2, as in `identify_then_diagnose`, so that no
//! identification starts at the plant's own constants. The masses, the fit's prior, are the
//! plant's.
//!
//! `IDENTIFIED_DIR` keeps the outputs. `IDENTIFIED_SEED` (default 1) and `IDENTIFIED_CASES` (the
//! first N cases, 32 the whole suite, a list such as `3,11,14`, or `noise`: the suite's noise-only
//! cases) choose the run; without `IDENTIFIED_CASES`, four cases of the seed chosen for what they
//! exercise. It scores each case as the diagnosis suite does, strict and graded
//! (`suite::Kind::graded_right`: the truth in the verdict, at most two effects named — "X or
//! Y", "partly X", X beside an `unexplained` rest), asserts that every report short of the
//! truth names a recording that would separate its candidates (`advice`, printed beside it),
//! then ≥ 90 % right graded. For the noise-only cases it also prints the identified R_eddy, ξ,
//! f0 against the plant's and how many have all three within 3 % (not asserted).
//! `IDENTIFIED_DESIGN=varied` records the sines in a design drawn per case (frequencies,
//! amplitudes, bias, rate, duration: `maglab_plant::suite::Design`);
//! `IDENTIFIED_COIL_CURRENT=measured` records the coil current as well (`coil_current_a`).
//! `IDENTIFIED_FROM=separate` identifies from a separate identification folder recorded on the
//! same bench instead of the case's own folder (`write_case`).
//! `IDENTIFIED_FOLLOW_ADVICE=on` does what a user does with a report that advises recordings:
//! records each with the command the report gives, on the same bench, adds them to the folder,
//! identifies again with the loops advised for the masses and diagnoses the whole folder
//! ([`follow_advice`]); the second pass is the one scored, the first pass's grade printed
//! beside it.
//!
//! **Ignored in `cargo test`: it does not reach 90 %.** The identification absorbs part of a lag
//! (an amplifier's, a sensor's, a load's) into R_eddy, ξ, f0 identified from the same sines, and
//! a thermal sweep that heats the coil spoils the masses (the file says so:
//! `provenance.warnings`). Noise-only and out-of-library cases come out right; docs/diagnosis.md
//! has the figures. Run it with
//! `IDENTIFIED_CASES=32 cargo test --release -p maglab --test identified_suite -- --ignored --nocapture`.
mod common;
use maglab_plant::bench::{
    forc_experiment, identification_design_covering, operating_loops, record_all, write_dataset,
};
use maglab_plant::suite;
use std::path::Path;
use std::process::Command;

fn maglab(args: &[&str]) -> Result<String, String> {
    let out = Command::new(env!("CARGO_BIN_EXE_maglab"))
        .args(args)
        .output()
        .map_err(|e| e.to_string())?;
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    if out.status.success() {
        Ok(text)
    } else {
        Err(format!("maglab {args:?} failed:\n{text}"))
    }
}

struct Outcome {
    label: String,
    expected: Vec<String>,
    /// The scored pass: the first, or with `IDENTIFIED_FOLLOW_ADVICE=on` the one after the
    /// advice was followed.
    pass: Pass,
    /// With the advice followed, the first pass's graded verdict.
    first_label: Option<String>,
    seconds: f64,
}

/// Draws case `index` of the suite `seed`, records it behind a quasi-static reversal sweep and
/// writes the dataset folder under `root`: `(case, case folder, data folder, the folder to
/// identify from)` — the data folder itself, or with `IDENTIFIED_FROM=separate` a separate
/// identification folder recorded on the same bench (the case's plant, effects and recording
/// settings): the standard identification dataset (reversal sweep, 1 Hz loops, sines 20–400 Hz;
/// `maglab_plant::bench::identification_design`) with 1 Hz loops on the case's own loops as
/// docs/identification.md "What to record" asks, every start documented — a bench's
/// measurement programme, identified once, then the case's experiments diagnosed.
fn write_case(
    seed: u64,
    index: usize,
    kind: suite::Kind,
    root: &Path,
) -> (
    suite::Case,
    std::path::PathBuf,
    std::path::PathBuf,
    std::path::PathBuf,
) {
    let params = actuator_params::paper_defaults();
    // `IDENTIFIED_DESIGN=varied`: the sines in a design drawn per case (`suite::Design`).
    let design = suite::Design::from_env("IDENTIFIED_DESIGN").unwrap_or_else(|e| panic!("{e}"));
    let mut case = suite::draw_with(
        &params,
        seed.wrapping_mul(1000).wrapping_add(index as u64),
        kind,
        design,
    )
    .expect("the case is drawn");
    // `IDENTIFIED_COIL_CURRENT=measured`: the bench records the coil current too (a typical
    // current monitor, `maglab_plant::CurrentMonitor::TYPICAL`); the draws are the same.
    match std::env::var("IDENTIFIED_COIL_CURRENT").as_deref() {
        Err(_) | Ok("") | Ok("off") => {}
        Ok("measured") => case.settings.coil_current = Some(maglab_plant::CurrentMonitor::TYPICAL),
        Ok(other) => panic!("IDENTIFIED_COIL_CURRENT `{other}`: expected `measured` or `off`"),
    }
    let rate = case.settings.rate_hz;
    let mut experiments = vec![forc_experiment(&params, 1.0, rate).expect("FORC sweep")];
    experiments.extend(case.experiments.iter().cloned());
    let recordings =
        record_all(&params, &case.effects, &experiments, &case.settings).expect("plant runs");
    let dir = root.join(format!("case{index:02}"));
    let data = dir.join("data");
    write_dataset(&data, &recordings).expect("dataset written");
    if !case.documented {
        // Only the identification sweep's start is documented.
        let mut info = maglab_dataset::dataset_info::DatasetInfo::load(&data)
            .expect("dataset.json")
            .expect("written");
        info.files.retain(|name, _| name.starts_with("00_forc"));
        info.write(&data).expect("dataset.json written");
    }
    let identify_from = match std::env::var("IDENTIFIED_FROM").as_deref() {
        Err(_) | Ok("") | Ok("case") => data.clone(),
        Ok("separate") => {
            let design =
                identification_design_covering(rate, &operating_loops(&case.experiments, 0.01));
            let recordings =
                record_all(&params, &case.effects, &design, &case.settings).expect("plant runs");
            let folder = dir.join("identification");
            write_dataset(&folder, &recordings).expect("dataset written");
            folder
        }
        Ok(other) => panic!("IDENTIFIED_FROM `{other}`: expected `case` or `separate`"),
    };
    (case, dir, data, identify_from)
}

/// What one identify → diagnose pass over a folder gave.
struct Pass {
    /// Right under the strict scoring (the named set is the truth).
    strict: bool,
    /// Right under the diagnosis suite's graded scoring (`suite::Kind::graded_right`): what
    /// the goal counts.
    graded: bool,
    /// The verdict as graded: `X`, `X+Y`, `partly X`, `X or Y`, `unexplained`, `none`.
    graded_label: String,
    identified: String,
    /// R_eddy, ξ, f0 as identified.
    constants: [f64; 3],
    /// The report's advice (`diagnosis.json` `advice`): `recording (candidate vs candidate)`.
    advice: Vec<String>,
    /// `diagnosis.json` `advice` as written (followed by [`follow_advice`]).
    advice_json: serde_json::Value,
}

/// `maglab identify` on `identify_from` (from a datasheet's base file, not the plant's own
/// constants: module docs) into `dir/identified.json`, then `maglab diagnose` on `data` with
/// it into `dir/report`, scored against `case`.
fn identify_and_diagnose(
    case: &suite::Case,
    dir: &Path,
    identify_from: &Path,
    data: &Path,
) -> Pass {
    let s = |p: &Path| p.to_str().expect("UTF-8 path").to_string();
    let identified = dir.join("identified.json");
    let identify = common::identify_args(dir, identify_from, &identified);
    let log =
        maglab(&identify.iter().map(String::as_str).collect::<Vec<_>>()).expect("identify runs");
    std::fs::write(dir.join("identify.log"), log).expect("log written");
    let id = common::json(&identified);
    let a = &id["actuator"];
    let constants = [
        a["eddy_resistance_ohm"].as_f64().unwrap_or(f64::NAN),
        a["damping_ratio"].as_f64().unwrap_or(f64::NAN),
        a["resonance_hz"].as_f64().unwrap_or(f64::NAN),
    ];
    let identified_text = format!(
        "R {:.1} ohm, xi {:.3}, f0 {:.0} Hz, {} quality warnings",
        constants[0],
        constants[1],
        constants[2],
        id["provenance"]["warnings"].as_array().map_or(0, Vec::len)
    );
    let report = dir.join("report");
    maglab(&[
        "diagnose",
        "--params",
        &s(&identified),
        "-o",
        &s(&report),
        &s(data),
    ])
    .expect("diagnose runs");
    let d = common::json(&report.join("diagnosis.json"));
    let mut named: Vec<String> = std::iter::once(d["verdict"].as_str().unwrap_or("?").to_string())
        .chain(
            d["additional_effects"]
                .as_array()
                .into_iter()
                .flatten()
                .filter_map(|v| v.as_str().map(String::from)),
        )
        .collect();
    named.sort();
    let strs = |v: &serde_json::Value| -> Vec<String> {
        v.as_array()
            .into_iter()
            .flatten()
            .filter_map(|x| x.as_str().map(String::from))
            .collect()
    };
    let either = strs(&d["either"]);
    let partly = d["partly_explained"]["effect"].as_str();
    let said = suite::Said {
        verdict: d["verdict"].as_str().unwrap_or("?"),
        named: &named,
        grade: d["grade"].as_str().unwrap_or("?"),
        partly_explained: partly,
        either: &either,
    };
    let advice = d["advice"]
        .as_array()
        .into_iter()
        .flatten()
        .map(|a| {
            let c = |k: usize| a["candidates"][k].as_str().unwrap_or("?").to_string();
            format!(
                "{} ({} vs {})",
                a["recording"].as_str().unwrap_or("?"),
                c(0),
                c(1)
            )
        })
        .collect();
    Pass {
        strict: case.kind.strictly_right(&named),
        graded: case.kind.graded_right(&said),
        graded_label: said.label(),
        identified: identified_text,
        constants,
        advice,
        advice_json: d["advice"].clone(),
    }
}

/// Follows a report's advice on the bench the case was recorded on: every advised recording is
/// written by the command the report gives (`how`, a `maglab excite` line, at the bench's
/// sampling rate), played on the case's plant from a demagnetized rod (what `maglab excite`
/// asks), its start documented. Returns `(identify from, diagnose)`: copies of the case's data
/// folder, the first with the `measured_loops` records added (the advice says to identify again
/// with them), the second with every advised record.
fn follow_advice(
    case: &suite::Case,
    data: &Path,
    advice: &serde_json::Value,
    dir: &Path,
) -> (std::path::PathBuf, std::path::PathBuf) {
    let params = actuator_params::paper_defaults();
    let rate = case.settings.rate_hz;
    let mut experiments = Vec::new();
    for a in advice.as_array().into_iter().flatten() {
        let recording = a["recording"].as_str().expect("advice names its recording");
        let how = a["how"].as_str().expect("advice gives its command");
        let out = dir.join("excite").join(recording);
        let mut args: Vec<String> = Vec::new();
        let mut words = how.split_whitespace().skip(1); // `maglab`
        while let Some(w) = words.next() {
            match w {
                "-o" | "--sample-rate-hz" => {
                    words.next();
                }
                _ => args.push(w.to_string()),
            }
        }
        args.extend([
            "--sample-rate-hz".to_string(),
            format!("{rate}"),
            "-o".to_string(),
            out.to_str().expect("UTF-8 path").to_string(),
        ]);
        maglab(&args.iter().map(String::as_str).collect::<Vec<_>>())
            .unwrap_or_else(|e| panic!("the advised command `{how}` runs: {e}"));
        let mut files: Vec<_> = std::fs::read_dir(&out)
            .expect("excite wrote its folder")
            .map(|e| e.expect("entry").path())
            .filter(|p| p.extension().is_some_and(|x| x == "csv"))
            .collect();
        files.sort();
        for f in files {
            let text = std::fs::read_to_string(&f).expect("current file");
            let current_a: Vec<f64> = text
                .lines()
                .skip(1)
                .map(|l| {
                    l.split(',')
                        .nth(1)
                        .and_then(|c| c.trim().parse().ok())
                        .unwrap_or_else(|| panic!("{}: line `{l}`", f.display()))
                })
                .collect();
            let stem = f.file_stem().expect("stem").to_string_lossy().to_string();
            experiments.push(maglab_plant::bench::Experiment {
                name: format!("z_{recording}_{stem}"),
                start: maglab_dataset::start::StartState::SwitchOnDemagnetized,
                current_a,
                description: format!("advised ({recording}): {how}"),
            });
        }
    }
    // Another stretch of the bench's noise than the case's own records.
    let mut settings = case.settings;
    settings.seed = settings.seed.wrapping_add(7919);
    let recordings =
        record_all(&params, &case.effects, &experiments, &settings).expect("plant runs");
    let recorded = dir.join("recorded");
    write_dataset(&recorded, &recordings).expect("dataset written");
    // The advice says to identify again with the loops the masses were not measured on
    // (`measured_loops`); the other recordings are for the diagnosis.
    let measured_loops = |name: &str| name.starts_with("z_measured_loops_");
    let identify = merged_folder(&dir.join("identify"), data, &recorded, measured_loops);
    let diagnose = merged_folder(&dir.join("data"), data, &recorded, |_| true);
    (identify, diagnose)
}

/// `folder` with every record of `data` and those of `added` whose file name `keep` accepts,
/// with their `dataset.json` entries.
fn merged_folder(
    folder: &Path,
    data: &Path,
    added: &Path,
    keep: impl Fn(&str) -> bool,
) -> std::path::PathBuf {
    use maglab_dataset::dataset_info::DatasetInfo;
    std::fs::create_dir_all(folder).expect("folder");
    let mut info = DatasetInfo::load(data)
        .expect("dataset.json")
        .unwrap_or_default();
    let extra = DatasetInfo::load(added)
        .expect("dataset.json")
        .expect("written");
    info.files
        .extend(extra.files.into_iter().filter(|(name, _)| keep(name)));
    for (source, all) in [(data, true), (added, false)] {
        for e in std::fs::read_dir(source).expect("folder") {
            let p = e.expect("entry").path();
            let name = p.file_name().expect("name").to_string_lossy().to_string();
            if p.extension().is_some_and(|x| x == "csv") && (all || keep(&name)) {
                std::fs::copy(&p, folder.join(&name)).expect("copied");
            }
        }
    }
    info.write(folder).expect("dataset.json written");
    folder.to_path_buf()
}

fn run_case(seed: u64, index: usize, kind: suite::Kind, root: &Path) -> Outcome {
    let (case, dir, data, identify_from) = write_case(seed, index, kind, root);
    let started = std::time::Instant::now();
    let mut pass = identify_and_diagnose(&case, &dir, &identify_from, &data);
    // `IDENTIFIED_FOLLOW_ADVICE=on`: a user who is advised a recording makes it, adds it to the
    // folder, identifies and diagnoses again; the second pass is scored.
    let follow = match std::env::var("IDENTIFIED_FOLLOW_ADVICE").as_deref() {
        Err(_) | Ok("") | Ok("off") => false,
        Ok("on") => true,
        Ok(other) => panic!("IDENTIFIED_FOLLOW_ADVICE `{other}`: expected `on` or `off`"),
    };
    let mut first = None;
    if follow && !pass.advice.is_empty() {
        let advised_dir = dir.join("advised");
        let (with_loops, advised) = follow_advice(&case, &data, &pass.advice_json, &advised_dir);
        // A separate identification folder stays the one identified from.
        let from = if identify_from == data {
            with_loops
        } else {
            identify_from.clone()
        };
        let second = identify_and_diagnose(&case, &advised_dir, &from, &advised);
        first = Some(std::mem::replace(&mut pass, second).graded_label);
    }
    Outcome {
        label: case.describe(),
        expected: case.kind.expected().iter().map(|s| s.to_string()).collect(),
        pass,
        first_label: first,
        seconds: started.elapsed().as_secs_f64(),
    }
}

#[test]
#[ignore = "below the 90 % goal: lags and loads are absorbed into the identified constants (module docs)"]
fn identified_then_diagnosed_suite_names_the_right_effect() {
    let seed: u64 =
        std::env::var("IDENTIFIED_SEED").map_or(1, |s| s.parse().expect("IDENTIFIED_SEED"));
    // Without IDENTIFIED_CASES, four cases of seed 1 (a short run) that exercise the
    // identification's choices: a ΔE (0), noise only (4), a reversible magnetization that
    // `--reversible auto` must keep (12) and a sensor gain nonlinearity whose sweep a
    // reversible part also fits and which it must not keep (20).
    let indices: Vec<usize> = match std::env::var("IDENTIFIED_CASES") {
        // The suite's noise-only cases.
        Ok(s) if s == "noise" => suite::kinds(seed, 32)
            .iter()
            .enumerate()
            .filter(|(_, k)| matches!(k, suite::Kind::NoiseOnly))
            .map(|(i, _)| i)
            .collect(),
        // A count N (the first N cases) or a list of case numbers, `3,11,14` (one case: `31,`).
        Ok(s) if s.contains(',') => s
            .split(',')
            .filter(|i| !i.trim().is_empty())
            .map(|i| i.trim().parse().expect("IDENTIFIED_CASES: case numbers"))
            .collect(),
        Ok(s) => (0..s.parse::<usize>().expect("IDENTIFIED_CASES")).collect(),
        Err(_) => vec![0, 4, 12, 20],
    };
    let count = indices.len();
    // The kinds of the whole 32-case suite (or more), so that case `i` is the suite's.
    let kinds = suite::kinds(seed, indices.iter().max().map_or(32, |m| (m + 1).max(32)));
    // `IDENTIFIED_DIR` keeps every case's dataset, identified file, log and report there.
    let temp = tempfile::tempdir().expect("temp dir");
    let root_path = std::env::var_os("IDENTIFIED_DIR")
        .map_or_else(|| temp.path().to_path_buf(), std::path::PathBuf::from);
    let next = std::sync::atomic::AtomicUsize::new(0);
    let outcomes = std::sync::Mutex::new(Vec::new());
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    std::thread::scope(|scope| {
        for _ in 0..threads {
            scope.spawn(|| loop {
                let n = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                if n >= count {
                    break;
                }
                let i = indices[n];
                let o = run_case(seed, i, kinds[i].clone(), &root_path);
                println!(
                    "{} {:2} {} -> {} (identified {}; {:.0} s){}",
                    match (o.pass.strict, o.pass.graded) {
                        (true, _) => "ok    ",
                        (false, true) => "graded",
                        (false, false) => "MISS  ",
                    },
                    i,
                    o.label,
                    match &o.first_label {
                        Some(first) =>
                            format!("{first} -> (advice followed) {}", o.pass.graded_label),
                        None => o.pass.graded_label.clone(),
                    },
                    o.pass.identified,
                    o.seconds,
                    if o.pass.strict {
                        String::new()
                    } else {
                        format!("; advice: {}", o.pass.advice.join(", "))
                    }
                );
                outcomes.lock().expect("no panic").push(o);
            });
        }
    });
    let outcomes = outcomes.into_inner().expect("no panic");
    // Noise only: the identified constants against the plant's (point 5: within 3 %).
    let plant = actuator_params::paper_defaults().actuator;
    let truth = [
        plant.eddy_resistance_ohm,
        plant.damping_ratio,
        plant.resonance_hz,
    ];
    let noise_only: Vec<&Outcome> = outcomes.iter().filter(|o| o.expected == ["none"]).collect();
    let mut within = 0;
    for o in &noise_only {
        let errors: Vec<f64> = (0..3)
            .map(|k| 100.0 * (o.pass.constants[k] / truth[k] - 1.0))
            .collect();
        within += usize::from(errors.iter().all(|e| e.abs() <= 3.0));
        println!(
            "  {}: R_eddy {:+.1} %, xi {:+.1} %, f0 {:+.1} % from the plant's",
            o.label, errors[0], errors[1], errors[2]
        );
    }
    if !noise_only.is_empty() {
        println!(
            "noise only, seed {seed}: {within}/{} with R_eddy, xi, f0 all within 3 % of the plant's",
            noise_only.len()
        );
    }
    let strict = outcomes.iter().filter(|o| o.pass.strict).count();
    let correct = outcomes.iter().filter(|o| o.pass.graded).count();
    println!(
        "identify -> diagnose, seed {seed}: {correct}/{} correct (graded, the diagnosis suite's \
         scoring); {strict} strict",
        outcomes.len()
    );
    // Every report short of the truth names a recording that would separate its candidates.
    let unadvised: Vec<&str> = outcomes
        .iter()
        .filter(|o| !o.pass.strict && o.pass.advice.is_empty())
        .map(|o| o.label.as_str())
        .collect();
    assert!(
        unadvised.is_empty(),
        "misses whose report names no recording: {unadvised:?}"
    );
    assert!(10 * correct >= 9 * outcomes.len());
}

/// `maglab identify` on a rod with a two-mode load (seed 1, case 6): the measured lags reach
/// 3.4 rad at 390 Hz, which no R_eddy meets with the file's f0 = 392 Hz; identification must
/// still produce a file (f0 scanned, said in its output) rather than stop with an error.
#[test]
fn identify_scans_f0_when_the_file_cannot_meet_the_lags() {
    let kinds = suite::kinds(1, 32);
    let temp = tempfile::tempdir().expect("temp dir");
    let (case, _, _, data) = write_case(1, 6, kinds[6].clone(), temp.path());
    assert!(
        case.describe().contains("mechanical_load"),
        "the suite's draw changed: case 6 is now {}",
        case.describe()
    );
    let out = temp.path().join("identified.json");
    let log = maglab(&[
        "identify",
        data.to_str().expect("UTF-8 path"),
        "-o",
        out.to_str().expect("UTF-8 path"),
        // Plots into the temp dir, not the crate's working directory.
        "--plot-dir",
        temp.path().join("plots").to_str().expect("UTF-8 path"),
        // The scan is the phase-lag scheme's; the waveform fit after it is tested elsewhere
        // (identify_then_diagnose) and would triple this test's time.
        "--no-waveform-fit",
    ])
    .expect("identify runs");
    println!("{log}");
    assert!(log.contains("phase-lag scheme (f0 scanned)"), "{log}");
    let id = common::json(&out);
    let f0 = id["actuator"]["resonance_hz"].as_f64().expect("f0");
    assert!((392.0 / 3.0..=392.0 * 3.0).contains(&f0), "f0 {f0} Hz");
}
