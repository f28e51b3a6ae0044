//! The measurement format read by every `maglab` command that takes measured data.
//!
//! One experiment per CSV file; the header is exactly `t_s,current_a,displacement_m`; every row
//! holds three finite numbers; time increases with a uniform step. A *dataset* is a folder of such
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
    /// Coil current, A.
    pub current_a: Vec<f64>,
    /// Displacement of the actuator head, m.
    pub displacement_m: Vec<f64>,
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
    if trimmed != HEADER {
        let wrong = (0..HEADER.len().max(trimmed.len()))
            .find(|&k| trimmed.get(k) != HEADER.get(k))
            .unwrap_or(0);
        return Err(DataError::at(
            path,
            1,
            Some(&format!("column {}", wrong + 1)),
            format!(
                "wrong header `{}`: expected exactly `{}`",
                header.join(","),
                HEADER.join(",")
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
    let mut lines = Vec::with_capacity(n);
    for (line, fields) in &rows {
        t_s.push(parse_finite(path, *line, HEADER[0], &fields[0])?);
        current_a.push(parse_finite(path, *line, HEADER[1], &fields[1])?);
        displacement_m.push(parse_finite(path, *line, HEADER[2], &fields[2])?);
        lines.push(*line);
    }
    let step_s = check_uniform_time(path, HEADER[0], &t_s, &lines)?;
    Ok(Measurement {
        path: path.to_path_buf(),
        t_s,
        current_a,
        displacement_m,
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
    Ok(Dataset {
        dir: dir.to_path_buf(),
        measurements,
        ignored,
    })
}

/// Writes a measurement file in the format above (full f64 precision).
pub fn write_measurement(
    path: &Path,
    t_s: &[f64],
    current_a: &[f64],
    displacement_m: &[f64],
) -> Result<(), DataError> {
    let mut writer = csv::Writer::from_path(path)
        .map_err(|e| DataError::file(path, format!("cannot create: {e}")))?;
    let io = |e: csv::Error| DataError::file(path, format!("cannot write: {e}"));
    writer.write_record(HEADER).map_err(io)?;
    for k in 0..t_s.len().min(current_a.len()).min(displacement_m.len()) {
        writer
            .write_record([
                format!("{:e}", t_s[k]),
                format!("{:e}", current_a[k]),
                format!("{:e}", displacement_m[k]),
            ])
            .map_err(io)?;
    }
    writer
        .flush()
        .map_err(|e| DataError::file(path, format!("cannot write: {e}")))?;
    Ok(())
}
