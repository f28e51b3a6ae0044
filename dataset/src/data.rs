//! The measurement format read by every `maglab` command that takes measured data.
//!
//! One experiment per CSV file; the header is exactly `t_s,current_a,displacement_m`, or
//! `t_s,current_a,displacement_m,coil_current_a` when the bench also records the coil current;
//! every row holds that many finite numbers; time increases with a uniform step.
//!
//! **The two currents.** `current_a` is the current the controller commanded (the amplifier's
//! input, held or linear between samples as the bench's DAC and amplifier make it);
//! `coil_current_a`, optional, is the current measured in the coil (the amplifier's
//! current-monitor output), sampled on the displacement's trigger, with the monitor's own noise.
//! They differ by the amplifier's dynamics: the command → current record identifies the
//! amplifier, the current → displacement record the rod. In a dataset either every file has the
//! column or none does (the tools read one design of bench). A *dataset* is a folder of such
//! files (`*.csv`, read in name order). Anything else is an error that names the file, the line
//! (1-based, as an editor shows it), the column and the offending value — no row is skipped, no
//! value is repaired.
//!
//! Uniform sampling: the nominal step is the median step (so one gap does not shift it and the
//! error points at the gap); every step must be within
//! [`STEP_TOLERANCE`] (relative) of it. 0.1 % accepts time stamps printed with 6+ significant
//! digits and logger clock jitter well below a sample, and rejects a dropped sample (a step of
//! 2×, off by 100 %) or a merged file.

pub use crate::error::DataError;
use std::path::{Path, PathBuf};

/// The header every measurement file must have, in this order.
pub const HEADER: [&str; 3] = ["t_s", "current_a", "displacement_m"];

/// The optional fourth column: the measured coil current, A (module docs).
pub const COIL_CURRENT_COLUMN: &str = "coil_current_a";

/// The header of a file with the measured coil current.
pub const HEADER_WITH_COIL_CURRENT: [&str; 4] =
    ["t_s", "current_a", "displacement_m", COIL_CURRENT_COLUMN];

/// Relative tolerance of each time step against the nominal step (see the module docs).
pub const STEP_TOLERANCE: f64 = 1e-3;

/// Fewest samples in one file: two steps are needed to check that the sampling is uniform.
pub const MIN_SAMPLES: usize = 3;

/// One experiment: uniformly sampled current and displacement.
#[derive(Debug, Clone, PartialEq)]
pub struct Measurement {
    /// The file it came from.
    pub path: PathBuf,
    /// Sample times, s.
    pub t_s: Vec<f64>,
    /// Commanded coil current, A (the amplifier's input).
    pub current_a: Vec<f64>,
    /// Displacement of the actuator head, m.
    pub displacement_m: Vec<f64>,
    /// Measured coil current, A, when the bench records it (module docs).
    pub coil_current_a: Option<Vec<f64>>,
    /// Nominal sampling step, s.
    pub step_s: f64,
}

impl Measurement {
    /// Number of samples.
    pub fn len(&self) -> usize {
        self.t_s.len()
    }

    /// True when there are no samples (never for a loaded file).
    pub fn is_empty(&self) -> bool {
        self.t_s.is_empty()
    }
}

/// A folder of measurement files.
#[derive(Debug, Clone, PartialEq)]
pub struct Dataset {
    /// The folder.
    pub dir: PathBuf,
    /// The experiments, in file-name order.
    pub measurements: Vec<Measurement>,
    /// Entries of the folder that are not `*.csv` files and were therefore not read (reported,
    /// not silently ignored).
    pub ignored: Vec<PathBuf>,
}

/// Parses one field as a finite number; the error names the file, line, column and text.
pub fn parse_finite(path: &Path, line: u64, column: &str, text: &str) -> Result<f64, DataError> {
    let trimmed = text.trim();
    let value: f64 = trimmed.parse().map_err(|_| {
        DataError::at(
            path,
            line,
            Some(column),
            format!("`{text}` is not a number"),
        )
    })?;
    if !value.is_finite() {
        return Err(DataError::at(
            path,
            line,
            Some(column),
            format!("`{text}` is not a finite number"),
        ));
    }
    Ok(value)
}

/// A data row: its 1-based line number and its fields.
pub type Row = (u64, Vec<String>);

/// Reads all records of a CSV file with their 1-based line numbers; the first record is the
/// header. Rows with a different field count than the header are an error.
pub fn read_records(path: &Path) -> Result<(Vec<String>, Vec<Row>), DataError> {
    let mut reader = csv::ReaderBuilder::new()
        .has_headers(false)
        .flexible(true)
        .from_path(path)
        .map_err(|e| DataError::file(path, format!("cannot open: {e}")))?;
    let mut header: Option<Vec<String>> = None;
    let mut rows = Vec::new();
    for result in reader.records() {
        let record = result.map_err(|e| {
            let line = e.position().map_or(0, |p| p.line());
            DataError::at(path, line, None, format!("not readable as CSV: {e}"))
        })?;
        let line = record.position().map_or(0, |p| p.line());
        let fields: Vec<String> = record.iter().map(str::to_string).collect();
        match &header {
            None => header = Some(fields),
            Some(h) => {
                if fields.len() != h.len() {
                    return Err(DataError::at(
                        path,
                        line,
                        None,
                        format!(
                            "expected {} fields (as in the header), found {}",
                            h.len(),
                            fields.len()
                        ),
                    ));
                }
                rows.push((line, fields));
            }
        }
    }
    let header = header.ok_or_else(|| DataError::file(path, "empty file: no header, no data"))?;
    Ok((header, rows))
}

/// Checks that `t` (at least 2 samples) increases with a uniform step; `lines[k]` is the line of
/// sample `k`. Returns the nominal (median) step.
pub fn check_uniform_time(
    path: &Path,
    column: &str,
    t: &[f64],
    lines: &[u64],
) -> Result<f64, DataError> {
    let line_of = |k: usize| lines.get(k).copied().unwrap_or(0);
    for k in 1..t.len() {
        if t[k] <= t[k - 1] {
            return Err(DataError::at(
                path,
                line_of(k),
                Some(column),
                format!(
                    "time does not increase: {} after {} (line {})",
                    t[k],
                    t[k - 1],
                    line_of(k - 1)
                ),
            ));
        }
    }
    let n = t.len();
    let mut steps: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
    steps.sort_by(f64::total_cmp);
    let step = steps[steps.len() / 2];
    for k in 1..n {
        let dt = t[k] - t[k - 1];
        if (dt - step).abs() > STEP_TOLERANCE * step {
            return Err(DataError::at(
                path,
                line_of(k),
                Some(column),
                format!(
                    "non-uniform sampling: step {dt:.6e} s from the previous line, nominal step \
                     {step:.6e} s (tolerance {:.1} %)",
                    STEP_TOLERANCE * 100.0
                ),
            ));
        }
    }
    Ok(step)
}

/// Reads and checks one measurement file.
pub fn load_measurement(path: &Path) -> Result<Measurement, DataError> {
    let (header, rows) = read_records(path)?;
    let trimmed: Vec<&str> = header.iter().map(|h| h.trim()).collect();
    let with_coil_current = trimmed == HEADER_WITH_COIL_CURRENT;
    if trimmed != HEADER && !with_coil_current {
        let expected: &[&str] = if trimmed.len() > HEADER.len() {
            &HEADER_WITH_COIL_CURRENT
        } else {
            &HEADER
        };
        let wrong = (0..expected.len().max(trimmed.len()))
            .find(|&k| trimmed.get(k) != expected.get(k))
            .unwrap_or(0);
        return Err(DataError::at(
            path,
            1,
            Some(&format!("column {}", wrong + 1)),
            format!(
                "wrong header `{}`: expected exactly `{}` or `{}`",
                header.join(","),
                HEADER.join(","),
                HEADER_WITH_COIL_CURRENT.join(",")
            ),
        ));
    }
    if rows.is_empty() {
        return Err(DataError::file(
            path,
            "empty file: a header but no data rows",
        ));
    }
    if rows.len() < MIN_SAMPLES {
        return Err(DataError::file(
            path,
            format!(
                "too few samples: {} data rows, at least {MIN_SAMPLES} are needed",
                rows.len()
            ),
        ));
    }
    let n = rows.len();
    let mut t_s = Vec::with_capacity(n);
    let mut current_a = Vec::with_capacity(n);
    let mut displacement_m = Vec::with_capacity(n);
    let mut coil_current_a = Vec::with_capacity(if with_coil_current { n } else { 0 });
    let mut lines = Vec::with_capacity(n);
    for (line, fields) in &rows {
        t_s.push(parse_finite(path, *line, HEADER[0], &fields[0])?);
        current_a.push(parse_finite(path, *line, HEADER[1], &fields[1])?);
        displacement_m.push(parse_finite(path, *line, HEADER[2], &fields[2])?);
        if with_coil_current {
            coil_current_a.push(parse_finite(path, *line, COIL_CURRENT_COLUMN, &fields[3])?);
        }
        lines.push(*line);
    }
    let step_s = check_uniform_time(path, HEADER[0], &t_s, &lines)?;
    Ok(Measurement {
        path: path.to_path_buf(),
        t_s,
        current_a,
        displacement_m,
        coil_current_a: with_coil_current.then_some(coil_current_a),
        step_s,
    })
}

/// Reads every `*.csv` file of a folder (name order). Other entries are listed in
/// [`Dataset::ignored`]. A folder without any `*.csv` file is an error.
pub fn load_dataset(dir: &Path) -> Result<Dataset, DataError> {
    let entries = std::fs::read_dir(dir)
        .map_err(|e| DataError::file(dir, format!("cannot read the dataset folder: {e}")))?;
    let mut files = Vec::new();
    let mut ignored = Vec::new();
    for entry in entries {
        let entry = entry.map_err(|e| DataError::file(dir, format!("cannot list: {e}")))?;
        let path = entry.path();
        if path.is_file() && path.extension().is_some_and(|e| e == "csv") {
            files.push(path);
        } else if path
            .file_name()
            .is_some_and(|n| n == crate::dataset_info::FILE_NAME)
        {
            // The dataset's documentation, read by `dataset_info`.
        } else {
            ignored.push(path);
        }
    }
    files.sort();
    ignored.sort();
    if files.is_empty() {
        return Err(DataError::file(
            dir,
            "no measurement files (`*.csv`) in the dataset folder",
        ));
    }
    let measurements = files
        .iter()
        .map(|p| load_measurement(p))
        .collect::<Result<Vec<_>, _>>()?;
    coil_current_recorded(&measurements.iter().collect::<Vec<_>>())?;
    Ok(Dataset {
        dir: dir.to_path_buf(),
        measurements,
        ignored,
    })
}

/// Whether the files of one dataset, `records`, hold the coil-current column: every file records
/// it or none does, and a dataset with it in some files only is an error naming a file without
/// it and one with it.
pub fn coil_current_recorded(records: &[&Measurement]) -> Result<bool, DataError> {
    let Some(first) = records.first() else {
        return Ok(false);
    };
    let has = |m: &Measurement| m.coil_current_a.is_some();
    match records.iter().find(|m| has(m) != has(first)) {
        None => Ok(has(first)),
        Some(other) => {
            let (with, without) = if has(first) {
                (*first, *other)
            } else {
                (*other, *first)
            };
            Err(DataError::at(
                &without.path,
                1,
                Some(COIL_CURRENT_COLUMN),
                format!(
                    "no `{COIL_CURRENT_COLUMN}` column, but {} has one: in a dataset every file \
                     records the coil current or none does",
                    with.path.display()
                ),
            ))
        }
    }
}

/// Writes a measurement file in the format above (full f64 precision), with the
/// `coil_current_a` column when `coil_current_a` is given. Every column must have the samples
/// of `t_s`.
pub fn write_measurement(
    path: &Path,
    t_s: &[f64],
    current_a: &[f64],
    displacement_m: &[f64],
    coil_current_a: Option<&[f64]>,
) -> Result<(), DataError> {
    let n = t_s.len();
    for (column, len) in [
        (HEADER[1], current_a.len()),
        (HEADER[2], displacement_m.len()),
        (COIL_CURRENT_COLUMN, coil_current_a.map_or(n, <[f64]>::len)),
    ] {
        if len != n {
            return Err(DataError::file(
                path,
                format!("column `{column}`: {len} samples to write, but {n} time stamps"),
            ));
        }
    }
    let mut writer = csv::Writer::from_path(path)
        .map_err(|e| DataError::file(path, format!("cannot create: {e}")))?;
    let io = |e: csv::Error| DataError::file(path, format!("cannot write: {e}"));
    match coil_current_a {
        Some(_) => writer.write_record(HEADER_WITH_COIL_CURRENT),
        None => writer.write_record(HEADER),
    }
    .map_err(io)?;
    for k in 0..n {
        let mut row = vec![
            format!("{:e}", t_s[k]),
            format!("{:e}", current_a[k]),
            format!("{:e}", displacement_m[k]),
        ];
        if let Some(c) = coil_current_a {
            row.push(format!("{:e}", c[k]));
        }
        writer.write_record(row).map_err(io)?;
    }
    writer
        .flush()
        .map_err(|e| DataError::file(path, format!("cannot write: {e}")))?;
    Ok(())
}
