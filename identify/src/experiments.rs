//! The dataset convention: which files of a dataset are quasi-static (Preisach masses, model (6))
//! and which are dynamic (sinusoidal currents for R_eddy, ξ, f0, models (4)-(5)).
//!
//! A dataset is a folder of measurement files (`maglab_dataset::data`). Each file is classified by one of
//! two rules, and the classification of every file (with the reason) is reported:
//!
//! 1. **Sub-folders (explicit).** Files in `DATASET/quasi-static/` are quasi-static, files in
//!    `DATASET/dynamic/` are dynamic, whatever their content. A file in `dynamic/` must still be a
//!    sinusoid (its frequency is measured from it): otherwise it is an error naming the file.
//! 2. **Spectrum (files directly in `DATASET/`).** The current's excitation frequency is the
//!    largest peak of its Hann-windowed spectrum ([`maglab_signal::spectrum::dominant_tone`]). A file is
//!    dynamic when the current is a sinusoid — at least [`ClassifyOptions::tonal_min_fraction`]
//!    (default 0.9) of its AC power within ±3 bins of the peak — at a frequency of at least
//!    [`ClassifyOptions::dynamic_min_hz`] (default 10 Hz); every other file (reversal sequences
//!    such as `maglab excite`, slow sweeps, slow sines) is quasi-static.
//!
//! Why these thresholds: a pure sine puts > 99.9 % of its Hann-windowed power within ±2 bins; a
//! sequence of reversals at a constant sweep rate (every FORC excitation) spreads it over the
//! many periods of its shrinking reversals, far below 90 %. Rate dependence at 10 Hz, with the
//! paper's constants (`f0` = 392 Hz, `ξ` = 0.78, `R_eddy` = 70 Ω), is a phase lag of
//! `2ξ f / f0` ≈ 2.3° from (5) plus a smaller one from (4): small enough that a slower sine is
//! still usable as quasi-static data, large enough that a faster one carries the dynamics.
//!
//! Rule 2 needs nothing from the producer of the data, so datasets written by other tools
//! (`maglab rig`, a lab logger) work as they are; rule 1 overrides it when the producer knows
//! better (e.g. a 20 Hz sine meant as quasi-static data for a slow material).

use maglab_dataset::data::{load_measurement, DataError, Measurement};
use maglab_signal::spectrum::{dominant_tone, refine_frequency, Tone};
use std::path::{Path, PathBuf};

/// Sub-folder of quasi-static files (rule 1).
pub const QUASI_STATIC_DIR: &str = "quasi-static";
/// Sub-folder of dynamic files (rule 1).
pub const DYNAMIC_DIR: &str = "dynamic";

/// Thresholds of rule 2.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ClassifyOptions {
    /// Lowest excitation frequency of a dynamic file, Hz.
    pub dynamic_min_hz: f64,
    /// Smallest share of the current's AC power in the spectral peak for a sinusoid.
    pub tonal_min_fraction: f64,
}

impl Default for ClassifyOptions {
    fn default() -> Self {
        ClassifyOptions {
            dynamic_min_hz: 10.0,
            tonal_min_fraction: 0.9,
        }
    }
}

/// How a file was classified.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Rule {
    /// By its sub-folder.
    Folder,
    /// By the spectrum of its current.
    Spectrum,
}

/// A dynamic experiment: a sinusoidal current (with DC bias) and its excitation frequency.
#[derive(Debug, Clone, PartialEq)]
pub struct DynamicExperiment {
    /// The measurement.
    pub measurement: Measurement,
    /// Excitation frequency, Hz (FFT peak refined by harmonic least squares).
    pub frequency_hz: f64,
    /// The FFT peak.
    pub tone: Tone,
}

/// Classification record of one file.
#[derive(Debug, Clone, PartialEq)]
pub struct Classified {
    /// The file.
    pub path: PathBuf,
    /// Dynamic (true) or quasi-static.
    pub dynamic: bool,
    /// Which rule decided.
    pub rule: Rule,
    /// The current's dominant tone (None for a constant current).
    pub tone: Option<Tone>,
    /// One line: why.
    pub reason: String,
}

/// A dataset split into quasi-static and dynamic experiments.
#[derive(Debug, Clone, PartialEq)]
pub struct SplitDataset {
    /// The dataset folder.
    pub dir: PathBuf,
    /// Quasi-static experiments (file-name order, sub-folder first).
    pub quasi_static: Vec<Measurement>,
    /// Dynamic experiments, by increasing frequency.
    pub dynamic: Vec<DynamicExperiment>,
    /// Every file's classification.
    pub classification: Vec<Classified>,
    /// Entries that are not `*.csv` files (and not the two sub-folders): not read, reported.
    pub ignored: Vec<PathBuf>,
}

impl SplitDataset {
    /// The field range every record (quasi-static and dynamic) reaches through a coil of factor
    /// `c0` ([`crate::reach`]).
    pub fn reach(&self, coil_factor_per_m: f64) -> Option<crate::reach::Reach> {
        let currents = self
            .quasi_static
            .iter()
            .chain(self.dynamic.iter().map(|d| &d.measurement))
            .map(|m| &m.current_a[..]);
        crate::reach::Reach::of_currents(currents, coil_factor_per_m)
    }

    /// The quasi-static part as a [`maglab_dataset::data::Dataset`] (what the Preisach fit reads).
    pub fn quasi_static_dataset(&self) -> maglab_dataset::data::Dataset {
        maglab_dataset::data::Dataset {
            dir: self.dir.clone(),
            measurements: self.quasi_static.clone(),
            ignored: self.ignored.clone(),
        }
    }
}

/// Harmonics used to refine the excitation frequency (the current's own distortion).
const CURRENT_HARMONICS: usize = 3;

/// Entries of a folder: `(*.csv files, sub-folders, other entries)`, each sorted.
type Listing = (Vec<PathBuf>, Vec<PathBuf>, Vec<PathBuf>);

fn list(dir: &Path) -> Result<Listing, DataError> {
    let entries = std::fs::read_dir(dir)
        .map_err(|e| DataError::file(dir, format!("cannot read the dataset folder: {e}")))?;
    let (mut files, mut dirs, mut other) = (Vec::new(), Vec::new(), Vec::new());
    for entry in entries {
        let entry = entry.map_err(|e| DataError::file(dir, format!("cannot list: {e}")))?;
        let path = entry.path();
        if path.is_file() && path.extension().is_some_and(|e| e == "csv") {
            files.push(path);
        } else if path
            .file_name()
            .is_some_and(|n| n == maglab_dataset::dataset_info::FILE_NAME)
        {
            // The dataset's documentation, read by `dataset_info`.
        } else if path.is_dir() {
            dirs.push(path);
        } else {
            other.push(path);
        }
    }
    files.sort();
    dirs.sort();
    other.sort();
    Ok((files, dirs, other))
}

fn tone_of(m: &Measurement) -> Option<Tone> {
    dominant_tone(&m.current_a, m.step_s)
}

fn dynamic_experiment(m: Measurement, tone: Tone) -> DynamicExperiment {
    let frequency_hz = refine_frequency(&m.current_a, m.step_s, &tone, CURRENT_HARMONICS);
    DynamicExperiment {
        measurement: m,
        frequency_hz,
        tone,
    }
}

/// Reads and classifies a dataset folder (see the module docs).
pub fn load_split_dataset(
    dir: &Path,
    options: &ClassifyOptions,
) -> Result<SplitDataset, DataError> {
    let (top_files, dirs, mut ignored) = list(dir)?;
    let mut quasi_static = Vec::new();
    let mut dynamic = Vec::new();
    let mut classification = Vec::new();
    for sub in &dirs {
        let name = sub.file_name().map(|n| n.to_string_lossy().to_string());
        let is_dynamic = match name.as_deref() {
            Some(QUASI_STATIC_DIR) => false,
            Some(DYNAMIC_DIR) => true,
            _ => {
                ignored.push(sub.clone());
                continue;
            }
        };
        let (files, subdirs, other) = list(sub)?;
        ignored.extend(subdirs);
        ignored.extend(other);
        if files.is_empty() {
            return Err(DataError::file(
                sub,
                "no measurement files (`*.csv`) in this sub-folder of the dataset",
            ));
        }
        for path in files {
            let m = load_measurement(&path)?;
            let tone = tone_of(&m);
            if is_dynamic {
                let t = tone
                    .filter(|t| t.tonal_fraction >= options.tonal_min_fraction)
                    .ok_or_else(|| {
                        DataError::file(
                            &path,
                            format!(
                                "column `current_a`: a file in `{DYNAMIC_DIR}/` must be a sinusoidal \
                                 current, but only {:.1} % of its AC power is in the spectral peak \
                                 (needs {:.0} %)",
                                100.0 * tone.map_or(0.0, |t| t.tonal_fraction),
                                100.0 * options.tonal_min_fraction
                            ),
                        )
                    })?;
                classification.push(Classified {
                    path: path.clone(),
                    dynamic: true,
                    rule: Rule::Folder,
                    tone,
                    reason: format!("in `{DYNAMIC_DIR}/`: sinusoid at {:.3} Hz", t.frequency_hz),
                });
                dynamic.push(dynamic_experiment(m, t));
            } else {
                classification.push(Classified {
                    path: path.clone(),
                    dynamic: false,
                    rule: Rule::Folder,
                    tone,
                    reason: format!("in `{QUASI_STATIC_DIR}/`"),
                });
                quasi_static.push(m);
            }
        }
    }
    for path in top_files {
        let m = load_measurement(&path)?;
        let tone = tone_of(&m);
        let (is_dynamic, reason) = match tone {
            None => (
                false,
                "constant current: no excitation frequency".to_string(),
            ),
            Some(t) if t.tonal_fraction < options.tonal_min_fraction => (
                false,
                format!(
                    "not a sinusoid ({:.1} % of the current's AC power in its peak at {:.3} Hz, \
                     < {:.0} %)",
                    100.0 * t.tonal_fraction,
                    t.frequency_hz,
                    100.0 * options.tonal_min_fraction
                ),
            ),
            Some(t) if t.frequency_hz < options.dynamic_min_hz => (
                false,
                format!(
                    "sinusoid at {:.3} Hz < {} Hz: slow enough for the static model (6)",
                    t.frequency_hz, options.dynamic_min_hz
                ),
            ),
            Some(t) => (
                true,
                format!(
                    "sinusoid at {:.3} Hz ({:.1} % of the AC power in the peak)",
                    t.frequency_hz,
                    100.0 * t.tonal_fraction
                ),
            ),
        };
        classification.push(Classified {
            path: path.clone(),
            dynamic: is_dynamic,
            rule: Rule::Spectrum,
            tone,
            reason,
        });
        match (is_dynamic, tone) {
            (true, Some(t)) => dynamic.push(dynamic_experiment(m, t)),
            _ => quasi_static.push(m),
        }
    }
    if quasi_static.is_empty() && dynamic.is_empty() {
        return Err(DataError::file(
            dir,
            format!(
                "no measurement files (`*.csv`) in the dataset folder or its `{QUASI_STATIC_DIR}/` \
                 and `{DYNAMIC_DIR}/` sub-folders"
            ),
        ));
    }
    dynamic.sort_by(|a, b| a.frequency_hz.total_cmp(&b.frequency_hz));
    Ok(SplitDataset {
        dir: dir.to_path_buf(),
        quasi_static,
        dynamic,
        classification,
        ignored,
    })
}
