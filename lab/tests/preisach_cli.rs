//! `maglab preisach-fit` / `preisach-predict` as a user runs them, on the shipped real B–H data:
//! the defaults (piecewise reversible part and offset on, initial state chosen from the data, predict grouped like the
//! fit), per-experiment scores, negative `--levels-range` ends, and a model that agrees with its
//! own fit when the grid is narrower than the data.
mod common;
use common::maglab;

use std::path::{Path, PathBuf};

fn data() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .join("identify/tests/data/real/bh-loops/mnzn-ferrite.csv")
}

fn number_after(text: &str, key: &str) -> f64 {
    // The last occurrence: the pooled score is the final line.
    let rest = text
        .rsplit(key)
        .next()
        .filter(|_| text.contains(key))
        .unwrap_or_else(|| panic!("`{key}` not in:\n{text}"));
    rest.trim_start()
        .split(|c: char| c.is_whitespace() || c == '%' || c == ';' || c == ',')
        .next()
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| panic!("no number after `{key}` in:\n{text}"))
}

#[test]
fn defaults_choose_periodic_affine_and_the_models_grouping() {
    let folder = tempfile::tempdir().unwrap();
    let dir = folder.path();
    let model = dir.join("ferrite.json");
    let file = data();
    let fit = maglab(&[
        "preisach-fit",
        file.to_str().unwrap(),
        "--input-col",
        "h_a_per_m",
        "--output-col",
        "b_t",
        "--group-col",
        "loop",
        "--fit-rows",
        "loop=1,3",
        "-o",
        model.to_str().unwrap(),
        "--plot-dir",
        dir.to_str().unwrap(),
    ]);
    assert!(fit.contains("initial state auto: periodic"), "{fit}");
    assert!(
        fit.contains("reversible part (piecewise): offset"),
        "the piecewise reversible part and an offset are on by default:\n{fit}"
    );
    let predict = maglab(&[
        "preisach-predict",
        model.to_str().unwrap(),
        file.to_str().unwrap(),
        "--score-rows",
        "loop=0,2",
        "-o",
        dir.join("p.csv").to_str().unwrap(),
        "--plot",
        dir.join("p").to_str().unwrap(),
    ]);
    assert!(predict.contains("the model's group column"), "{predict}");
    assert!(
        predict.contains("loop=0:") && predict.contains("loop=2:"),
        "{predict}"
    );
    let nrmse = number_after(&predict, "NRMSE");
    // The docs' figure with explicit options; the defaults must reach it.
    assert!(nrmse < 2.1, "defaults give {nrmse} %:\n{predict}");
    // Pooled as one experiment (the old behaviour) is far worse: the grouping matters.
    let pooled = maglab(&[
        "preisach-predict",
        model.to_str().unwrap(),
        file.to_str().unwrap(),
        "--score-rows",
        "loop=0,2",
        "--no-group",
        "-o",
        dir.join("q.csv").to_str().unwrap(),
        "--plot",
        dir.join("q").to_str().unwrap(),
    ]);
    assert!(number_after(&pooled, "NRMSE") > 2.0 * nrmse, "{pooled}");
}

#[test]
fn a_narrow_grid_with_negative_ends_agrees_with_its_own_fit() {
    let folder = tempfile::tempdir().unwrap();
    let dir = folder.path();
    let model = dir.join("narrow.json");
    let file = data();
    let fit = maglab(&[
        "preisach-fit",
        file.to_str().unwrap(),
        "--input-col",
        "h_a_per_m",
        "--output-col",
        "b_t",
        "--group-col",
        "loop",
        "--levels-range",
        "-40..40",
        "-o",
        model.to_str().unwrap(),
        "--plot-dir",
        dir.to_str().unwrap(),
    ]);
    assert!(fit.contains("samples outside the grid"), "{fit}");
    // The regression's own residual (the design matrix) against the model file's prediction.
    let fitted = number_after(&fit, "RMS residual");
    let predict = maglab(&[
        "preisach-predict",
        model.to_str().unwrap(),
        file.to_str().unwrap(),
        "-o",
        dir.join("p.csv").to_str().unwrap(),
        "--plot",
        dir.join("p").to_str().unwrap(),
    ]);
    let predicted = number_after(&predict, "; RMS");
    assert!(
        (predicted - fitted).abs() <= 1e-3 * fitted,
        "the model disagrees with its own fit: regression RMS residual {fitted}, prediction RMS {predicted}"
    );
}
