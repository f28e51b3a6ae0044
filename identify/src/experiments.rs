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
//!    [`ClassifyOptions::dynamic_min_hz`] (default 10 Hz). Every other file is quasi-static when
//!    its current holds no stretch of sinusoid and is **slow everywhere** (slow sines, reversal
//!    sequences such as `maglab excite --design forc`, slow sweeps, holds), and **not used**
//!    otherwise (a thermal soak: a sine, a hold, the sine again; a step), with the
//!    classification saying where and why: the static model (6) does not describe its fast
//!    parts, and one sinusoid does not describe the whole.
//!
//! A stretch of sinusoid: [`STRETCH_PERIODS`] periods of `dynamic_min_hz` on which the current
//! passes the test above for a dynamic sinusoid ([`sinusoidal_stretch`]). A record holding one
//! mixes a dynamic experiment with other excitation; a soak's sines can be slow against its
//! range, yet its hold heats the rod, and the static model describes neither.
//!
//! Slow everywhere: over every interval `Δt` of 1, 2, 4, … samples up to
//! `SLOW_WINDOW_PERIODS / dynamic_min_hz`, the current changes by at most what a sine at
//! `dynamic_min_hz` spanning the record's range `r` does at its steepest, `r sin(π
//! dynamic_min_hz Δt)`, plus [`NOISE_Z`] standard deviations of the noise of a difference
//! ([`steepest_change`]). The static model's error on a record is the lag of (4)-(5) times the
//! current's rate of change; the rule bounds that rate by the one rule 2 accepts for a sinusoid,
//! so both admit the same error. Short intervals catch a fast sine of small amplitude, long ones
//! a slope the noise hides from one sample to the next; the noise allowance is calibrated to a
//! false-alarm rate, not chosen on records.
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
//! better (e.g. a 20 Hz sine meant as quasi-static data for a slow material, or a record that
//! is not slow everywhere but should be fitted as quasi-static all the same).

use maglab_dataset::data::{load_measurement, DataError, Measurement};
use maglab_signal::noise::white_noise_sigma;
use maglab_signal::spectrum::{dominant_tone, refine_frequency, Tone};
use std::path::{Path, PathBuf};

/// Sub-folder of quasi-static files (rule 1).
pub const QUASI_STATIC_DIR: &str = "quasi-static";
/// Sub-folder of dynamic files (rule 1).
pub const DYNAMIC_DIR: &str = "dynamic";

/// The longest interval over which rule 2 measures how fast a current changes, in periods of
/// `dynamic_min_hz` (module docs): short enough that a change still compares slopes
/// (`sin(π/20)` is `π/20` within 0.4 %), long enough (50 samples at 10 kHz and 10 Hz) that a
/// slope is measured above the noise.
pub const SLOW_WINDOW_PERIODS: f64 = 0.05;

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

/// What a file is used for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// The Preisach masses, through the static model (6).
    QuasiStatic,
    /// R_eddy, ξ, f0, through (4)-(5).
    Dynamic,
    /// Not a dynamic sinusoid, and either not slow everywhere or holding a stretch of one: not
    /// read by the identification.
    NotUsed,
}

impl Kind {
    /// The name in reports and in `dataset_classification`.
    pub fn name(self) -> &'static str {
        match self {
            Kind::QuasiStatic => "quasi-static",
            Kind::Dynamic => "dynamic",
            Kind::NotUsed => "not used",
        }
    }
}

/// Classification record of one file.
#[derive(Debug, Clone, PartialEq)]
pub struct Classified {
    /// The file.
    pub path: PathBuf,
    /// What it is used for.
    pub kind: Kind,
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

/// Rule 2 for one file: its kind and one line saying why.
fn classify_by_spectrum(
    m: &Measurement,
    tone: Option<Tone>,
    options: &ClassifyOptions,
) -> (Kind, String) {
    let Some(t) = tone else {
        return (
            Kind::QuasiStatic,
            "constant current: no excitation frequency".to_string(),
        );
    };
    let tonal = t.tonal_fraction >= options.tonal_min_fraction;
    if tonal && t.frequency_hz >= options.dynamic_min_hz {
        return (
            Kind::Dynamic,
            format!(
                "sinusoid at {:.3} Hz ({:.1} % of the AC power in the peak)",
                t.frequency_hz,
                100.0 * t.tonal_fraction
            ),
        );
    }
    // Quasi-static only if slow everywhere: a record whose power sits at a low peak (a long hold
    // between short fast parts does) is not thereby slow.
    let shape = if tonal {
        format!(
            "sinusoid at {:.3} Hz < {} Hz",
            t.frequency_hz, options.dynamic_min_hz
        )
    } else {
        format!(
            "not a sinusoid ({:.1} % of the current's AC power in its peak at {:.3} Hz, < {:.0} %)",
            100.0 * t.tonal_fraction,
            t.frequency_hz,
            100.0 * options.tonal_min_fraction
        )
    };
    if let Some(stretch) = sinusoidal_stretch(&m.current_a, m.step_s, options) {
        return (
            Kind::NotUsed,
            format!(
                "{shape}, but from t = {:.3} s to {:.3} s a sinusoid at {:.3} Hz ({:.1} % of that \
                 stretch's AC power in its peak): a dynamic excitation among others, which \
                 neither the static model (6) nor one sinusoid describes (put it in \
                 `{QUASI_STATIC_DIR}/` to fit it as quasi-static data)",
                stretch.start_s,
                stretch.end_s,
                stretch.tone.frequency_hz,
                100.0 * stretch.tone.tonal_fraction
            ),
        );
    }
    let steepest = steepest_change(&m.current_a, m.step_s, options.dynamic_min_hz);
    if steepest.change_a <= steepest.limit_a {
        (
            Kind::QuasiStatic,
            format!("{shape}, slow everywhere: the static model (6)"),
        )
    } else {
        (
            Kind::NotUsed,
            format!(
                "{shape}, but not slow everywhere: its current changes by {:.4} A within \
                 {:.2} ms at t = {:.3} s, more than a {} Hz sine spanning its {:.4} A range does \
                 (with the noise, {:.4} A); neither the static model (6) nor one sinusoid \
                 describes it (put it in `{QUASI_STATIC_DIR}/` to fit it as quasi-static data)",
                steepest.change_a,
                1e3 * steepest.window_s,
                steepest.at_s,
                options.dynamic_min_hz,
                steepest.range_a,
                steepest.limit_a
            ),
        )
    }
}

/// The length of the stretches [`sinusoidal_stretch`] tests, in periods of `dynamic_min_hz`:
/// the shortest on which rule 2's test resolves a sine at `dynamic_min_hz` (its peak falls 5 bins
/// above DC, the Hann window's leakage of the stretch's mean and of the peak spans 2 bins each).
pub const STRETCH_PERIODS: f64 = 5.0;

/// A stretch of a record on which the current passes rule 2's test for a dynamic sinusoid.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SinusoidalStretch {
    /// Its first sample's time from the record's start, s.
    pub start_s: f64,
    /// Its end, s.
    pub end_s: f64,
    /// Its dominant tone.
    pub tone: Tone,
}

/// The first stretch of [`STRETCH_PERIODS`] periods of `dynamic_min_hz` (hops of a quarter of
/// it, and the record's last stretch) on which `current_a` is a dynamic sinusoid by rule 2: a
/// record that holds one beside other excitation (a thermal soak: a sine, a hold, the sine
/// again) mixes a dynamic experiment into whatever else it is. `None` for a record shorter than
/// two stretches (the whole-record test is the one that applies).
pub fn sinusoidal_stretch(
    current_a: &[f64],
    step_s: f64,
    options: &ClassifyOptions,
) -> Option<SinusoidalStretch> {
    let n = current_a.len();
    let len = (STRETCH_PERIODS / (options.dynamic_min_hz * step_s)).round() as usize;
    if len < 8 || n < 2 * len {
        return None;
    }
    let hop = (len / 4).max(1);
    let starts = (0..=n - len).step_by(hop).chain(std::iter::once(n - len));
    starts.into_iter().find_map(|k| {
        dominant_tone(&current_a[k..k + len], step_s)
            .filter(|t| {
                t.tonal_fraction >= options.tonal_min_fraction
                    && t.frequency_hz >= options.dynamic_min_hz
            })
            .map(|tone| SinusoidalStretch {
                start_s: k as f64 * step_s,
                end_s: (k + len) as f64 * step_s,
                tone,
            })
    })
}

/// Where a current changes fastest against what rule 2 allows (module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SteepestChange {
    /// The change `|i(t + Δt) − i(t)|` that exceeds its allowance most (or comes closest), A.
    pub change_a: f64,
    /// Where it starts (`t` from the first sample), s.
    pub at_s: f64,
    /// Its interval `Δt`, s (a whole number of samples).
    pub window_s: f64,
    /// The record's range `r = max i − min i`, A.
    pub range_a: f64,
    /// What rule 2 allows over `Δt`: a sine at `dynamic_min_hz` spanning `r`, `r sin(π f Δt)`,
    /// plus [`NOISE_Z`] standard deviations of the noise of a difference, A.
    pub limit_a: f64,
}

/// Standard deviations of a difference's noise (`√2 σ`, σ the current's white noise) that rule 2
/// adds to its allowance: a record of 10⁶ samples is compared over ≈ 10 intervals, 10⁷
/// differences, and with Gaussian noise the chance that any exceeds 6.5 standard deviations is
/// below 10⁷ · 8·10⁻¹¹ ≈ 10⁻³ (union bound). So noise alone calls a slow record fast less
/// than once in a thousand records.
pub const NOISE_Z: f64 = 6.5;

/// How fast `current_a` (sampled every `step_s`) changes against a sine at `dynamic_min_hz`
/// spanning its range (module docs), over intervals of 1, 2, 4, … samples up to
/// `SLOW_WINDOW_PERIODS / dynamic_min_hz`: the short ones catch a fast sine of small amplitude
/// (over a long interval its change saturates at twice its amplitude), the long ones a slope
/// that the noise hides from sample to sample. Returns the interval whose change exceeds its
/// allowance by the largest factor.
pub fn steepest_change(current_a: &[f64], step_s: f64, dynamic_min_hz: f64) -> SteepestChange {
    let n = current_a.len();
    let (lo, hi) = current_a
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &i| {
            (lo.min(i), hi.max(i))
        });
    let range_a = if n == 0 { 0.0 } else { hi - lo };
    let noise_a = NOISE_Z * std::f64::consts::SQRT_2 * white_noise_sigma(current_a);
    let longest = ((SLOW_WINDOW_PERIODS / (dynamic_min_hz * step_s)).round() as usize)
        .clamp(1, n.saturating_sub(1).max(1));
    let windows = std::iter::successors(Some(1usize), |&w| Some(2 * w))
        .take_while(|&w| w < longest)
        .chain(std::iter::once(longest));
    let mut worst: Option<(f64, SteepestChange)> = None;
    for window in windows {
        let window_s = window as f64 * step_s;
        // A sine of amplitude r/2 at f changes by at most r sin(π f Δt) over Δt (up to 1/2f).
        let phase =
            (std::f64::consts::PI * dynamic_min_hz * window_s).min(std::f64::consts::FRAC_PI_2);
        let limit_a = range_a * phase.sin() + noise_a;
        let (at, change_a) = (0..n.saturating_sub(window))
            .map(|k| (k, (current_a[k + window] - current_a[k]).abs()))
            .fold((0, 0.0f64), |best, c| if c.1 > best.1 { c } else { best });
        let ratio = if limit_a > 0.0 {
            change_a / limit_a
        } else {
            0.0
        };
        if worst.as_ref().is_none_or(|(r, _)| ratio > *r) {
            let c = SteepestChange {
                change_a,
                at_s: at as f64 * step_s,
                window_s,
                range_a,
                limit_a,
            };
            worst = Some((ratio, c));
        }
    }
    worst.map(|(_, c)| c).unwrap_or(SteepestChange {
        change_a: 0.0,
        at_s: 0.0,
        window_s: 0.0,
        range_a,
        limit_a: 0.0,
    })
}

/// Reads and classifies a dataset folder (see the module docs).
pub fn load_split_dataset(
    dir: &Path,
    options: &ClassifyOptions,
) -> Result<SplitDataset, DataError> {
    let (top_files, dirs, mut ignored) = list(dir)?;
    let mut sorted = Sorted::default();
    for sub in &dirs {
        let Some(is_dynamic) = folder_rule(sub) else {
            ignored.push(sub.clone());
            continue;
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
            sorted.by_folder(path, is_dynamic, options)?;
        }
    }
    for path in top_files {
        sorted.by_spectrum(path, options)?;
    }
    sorted.check_usable(dir)?;
    let Sorted {
        quasi_static,
        mut dynamic,
        classification,
    } = sorted;
    dynamic.sort_by(|a, b| a.frequency_hz.total_cmp(&b.frequency_hz));
    Ok(SplitDataset {
        dir: dir.to_path_buf(),
        quasi_static,
        dynamic,
        classification,
        ignored,
    })
}

/// Rule 1 for a sub-folder: `Some(true)` for `dynamic/`, `Some(false)` for `quasi-static/`,
/// `None` for any other (not read, reported as ignored).
fn folder_rule(sub: &Path) -> Option<bool> {
    match sub.file_name()?.to_str()? {
        QUASI_STATIC_DIR => Some(false),
        DYNAMIC_DIR => Some(true),
        _ => None,
    }
}

/// The files read so far, by what they are used for, and every file's classification.
#[derive(Default)]
struct Sorted {
    quasi_static: Vec<Measurement>,
    dynamic: Vec<DynamicExperiment>,
    classification: Vec<Classified>,
}

impl Sorted {
    /// Rule 1: a file of `dynamic/` (`is_dynamic`) or `quasi-static/`; a file of `dynamic/` that
    /// is not a sinusoid is an error naming it.
    fn by_folder(
        &mut self,
        path: PathBuf,
        is_dynamic: bool,
        options: &ClassifyOptions,
    ) -> Result<(), DataError> {
        let m = load_measurement(&path)?;
        let tone = tone_of(&m);
        if !is_dynamic {
            self.classification.push(Classified {
                path,
                kind: Kind::QuasiStatic,
                rule: Rule::Folder,
                tone,
                reason: format!("in `{QUASI_STATIC_DIR}/`"),
            });
            self.quasi_static.push(m);
            return Ok(());
        }
        let Some(t) = tone.filter(|t| t.tonal_fraction >= options.tonal_min_fraction) else {
            return Err(DataError::file(
                &path,
                format!(
                    "column `current_a`: a file in `{DYNAMIC_DIR}/` must be a sinusoidal current, \
                     but only {:.1} % of its AC power is in the spectral peak (needs {:.0} %)",
                    100.0 * tone.map_or(0.0, |t| t.tonal_fraction),
                    100.0 * options.tonal_min_fraction
                ),
            ));
        };
        self.classification.push(Classified {
            path,
            kind: Kind::Dynamic,
            rule: Rule::Folder,
            tone,
            reason: format!("in `{DYNAMIC_DIR}/`: sinusoid at {:.3} Hz", t.frequency_hz),
        });
        self.dynamic.push(dynamic_experiment(m, t));
        Ok(())
    }

    /// Rule 2: a file directly in the dataset folder, by the spectrum of its current.
    fn by_spectrum(&mut self, path: PathBuf, options: &ClassifyOptions) -> Result<(), DataError> {
        let m = load_measurement(&path)?;
        let tone = tone_of(&m);
        let (kind, reason) = classify_by_spectrum(&m, tone, options);
        self.classification.push(Classified {
            path,
            kind,
            rule: Rule::Spectrum,
            tone,
            reason,
        });
        match (kind, tone) {
            (Kind::Dynamic, Some(t)) => self.dynamic.push(dynamic_experiment(m, t)),
            (Kind::QuasiStatic, _) => self.quasi_static.push(m),
            _ => {}
        }
        Ok(())
    }

    /// An error naming the folder when it holds no measurement file, or none that can be used.
    fn check_usable(&self, dir: &Path) -> Result<(), DataError> {
        if self.classification.is_empty() {
            return Err(DataError::file(
                dir,
                format!(
                    "no measurement files (`*.csv`) in the dataset folder or its \
                     `{QUASI_STATIC_DIR}/` and `{DYNAMIC_DIR}/` sub-folders"
                ),
            ));
        }
        if self.quasi_static.is_empty() && self.dynamic.is_empty() {
            return Err(DataError::file(
                dir,
                format!(
                    "no file of the dataset folder can be used: none is a sinusoid or slow \
                     everywhere ({}); put the files to fit as quasi-static data in \
                     `{QUASI_STATIC_DIR}/`",
                    self.classification[0].reason
                ),
            ));
        }
        Ok(())
    }
}
