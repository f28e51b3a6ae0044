//! What the identification tests on the bench plant share: a recorded dataset written to a
//! temporary folder and loaded as `maglab identify` loads it, the identification from a base
//! file, and the identified constants' errors against the plant's.
// Each test binary uses the part it needs.
#![allow(dead_code)]

use actuator_params::ActuatorParams;
use maglab_identify::experiments::ClassifyOptions;
use maglab_identify::pipeline::{identify, Base, Identified, IdentifyOptions, RecordedDataset};
use maglab_plant::bench;
use maglab_plant::Recording;
use std::path::PathBuf;

/// A dataset folder in the temporary directory, removed when dropped unless the environment
/// variable named at its creation is set (then its path is printed).
pub struct BenchFolder {
    /// The folder.
    pub dir: PathBuf,
    /// The dataset loaded from it.
    pub dataset: RecordedDataset,
    keep: bool,
}

impl BenchFolder {
    /// Writes `recordings` to a fresh folder named after `tag` and loads it; `documented: false`
    /// removes its `dataset.json` (the start states are then estimated).
    pub fn write(tag: &str, recordings: &[Recording], documented: bool, keep_var: &str) -> Self {
        let dir = std::env::temp_dir().join(format!("maglab-{tag}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        bench::write_dataset(&dir, recordings).expect("write");
        if !documented {
            std::fs::remove_file(dir.join("dataset.json")).expect("undocument");
        }
        let dataset = RecordedDataset::load(&dir, &ClassifyOptions::default()).expect("load");
        BenchFolder {
            dir,
            dataset,
            keep: std::env::var(keep_var).is_ok(),
        }
    }

    /// `maglab identify` of the folder from `base` with the default options.
    pub fn identify(&self, base: &ActuatorParams, name: &str) -> Identified {
        identify(
            &self.dataset,
            Base { params: base, name },
            &IdentifyOptions::default(),
            &|_, _, _| {},
        )
        .expect("identify")
    }
}

impl Drop for BenchFolder {
    fn drop(&mut self) {
        if self.keep {
            println!("kept {}", self.dir.display());
        } else {
            let _ = std::fs::remove_dir_all(&self.dir);
        }
    }
}

/// Relative errors of the identified `R_eddy`, `ξ`, `f0` against the plant's.
pub fn constant_errors(identified: &ActuatorParams, truth: &ActuatorParams) -> [f64; 3] {
    let (a, t) = (&identified.actuator, &truth.actuator);
    [
        a.eddy_resistance_ohm / t.eddy_resistance_ohm - 1.0,
        a.damping_ratio / t.damping_ratio - 1.0,
        a.resonance_hz / t.resonance_hz - 1.0,
    ]
}

/// The errors as a line of a table.
pub fn pct(e: [f64; 3]) -> String {
    format!(
        "R_eddy {:+.1} %, xi {:+.1} %, f0 {:+.1} %",
        100.0 * e[0],
        100.0 * e[1],
        100.0 * e[2]
    )
}
