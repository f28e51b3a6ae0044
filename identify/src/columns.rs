//! Two numeric columns of an arbitrary CSV file, for the generic hysteresis fit
//! (`maglab preisach-fit` / `preisach-predict`).
//!
//! The file needs a header; the input and output columns are chosen by name. Optionally a group
//! column splits the rows into experiments (each run of consecutive rows with the same group value
//! is one experiment with its own initial memory state), and a row filter selects the rows that
//! enter the regression or the score. The filter never shortens the input history: the model
//! always runs over every row of an experiment, in file order, so the memory state at a selected
//! row is the one the full history produced.
//!
//! Errors name the file, the line and the column, like `maglab_dataset::data`; every row must parse
//! (finite numbers in the used columns), nothing is skipped.

use maglab_dataset::data::{parse_finite, read_records, DataError};
use std::path::{Path, PathBuf};

/// Which rows count (for the fit or for the score).
#[derive(Debug, Clone, PartialEq)]
pub enum RowFilter {
    /// Every row.
    All,
    /// Rows whose `column` value equals one of `values`.
    Select {
        /// Column name.
        column: String,
        /// Accepted values.
        values: Vec<f64>,
    },
    /// Rows with `lo <= column < hi`.
    Between {
        /// Column name.
        column: String,
        /// Lower bound, inclusive.
        lo: f64,
        /// Upper bound, exclusive.
        hi: f64,
    },
}

impl RowFilter {
    /// Parses `COL=V1,V2,...` (select) or `COL=LO..HI` (between).
    pub fn parse(text: &str) -> Result<Self, String> {
        let (column, rest) = text
            .split_once('=')
            .ok_or_else(|| format!("`{text}`: expected COL=V1,V2 or COL=LO..HI"))?;
        let number = |s: &str| -> Result<f64, String> {
            s.trim()
                .parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| format!("`{text}`: `{s}` is not a finite number"))
        };
        if let Some((lo, hi)) = rest.split_once("..") {
            let (lo, hi) = (number(lo)?, number(hi)?);
            if lo >= hi {
                return Err(format!("`{text}`: empty range {lo}..{hi}"));
            }
            return Ok(RowFilter::Between {
                column: column.trim().to_string(),
                lo,
                hi,
            });
        }
        let values = rest.split(',').map(number).collect::<Result<Vec<_>, _>>()?;
        Ok(RowFilter::Select {
            column: column.trim().to_string(),
            values,
        })
    }

    fn column(&self) -> Option<&str> {
        match self {
            RowFilter::All => None,
            RowFilter::Select { column, .. } | RowFilter::Between { column, .. } => Some(column),
        }
    }

    fn accepts(&self, value: f64) -> bool {
        match self {
            RowFilter::All => true,
            RowFilter::Select { values, .. } => values.contains(&value),
            RowFilter::Between { lo, hi, .. } => *lo <= value && value < *hi,
        }
    }

    /// Human-readable form for reports.
    pub fn describe(&self) -> String {
        match self {
            RowFilter::All => "all rows".into(),
            RowFilter::Select { column, values } => format!(
                "{column} in {{{}}}",
                values
                    .iter()
                    .map(|v| v.to_string())
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
            RowFilter::Between { column, lo, hi } => format!("{lo} <= {column} < {hi}"),
        }
    }
}

/// One experiment: an input and an output sequence, with a per-row selection flag.
#[derive(Debug, Clone, PartialEq)]
pub struct Series {
    /// A label for reports: the group value, or the file name.
    pub label: String,
    /// 1-based line of each row.
    pub lines: Vec<u64>,
    /// Input values.
    pub input: Vec<f64>,
    /// Output values.
    pub output: Vec<f64>,
    /// Rows the filter selected.
    pub selected: Vec<bool>,
}

impl Table {
    /// The smallest and largest input over every row of every experiment (selected or not);
    /// `(∞, −∞)` for a table without rows.
    pub fn input_range(&self) -> (f64, f64) {
        self.series
            .iter()
            .flat_map(|s| s.input.iter())
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &u| {
                (a.min(u), b.max(u))
            })
    }
}

impl Series {
    /// Number of selected rows.
    pub fn selected_count(&self) -> usize {
        self.selected.iter().filter(|&&s| s).count()
    }
}

/// What to read from a file.
#[derive(Debug, Clone, PartialEq)]
pub struct ColumnSpec {
    /// Input column name.
    pub input: String,
    /// Output column name.
    pub output: String,
    /// Optional group column: each run of equal values is one experiment.
    pub group: Option<String>,
    /// Which rows are selected.
    pub filter: RowFilter,
}

/// The experiments read from one file.
#[derive(Debug, Clone, PartialEq)]
pub struct Table {
    /// The file.
    pub path: PathBuf,
    /// The experiments in file order.
    pub series: Vec<Series>,
}

impl Table {
    /// Total rows.
    pub fn rows(&self) -> usize {
        self.series.iter().map(|s| s.input.len()).sum()
    }

    /// Total selected rows.
    pub fn selected_rows(&self) -> usize {
        self.series.iter().map(Series::selected_count).sum()
    }
}

/// Reads the columns of `spec` from `path`.
pub fn read_columns(path: &Path, spec: &ColumnSpec) -> Result<Table, DataError> {
    let (header, rows) = read_records(path)?;
    let find = |name: &str| -> Result<usize, DataError> {
        header.iter().position(|h| h.trim() == name).ok_or_else(|| {
            DataError::at(
                path,
                1,
                Some(name),
                format!("no such column; the header is `{}`", header.join(",")),
            )
        })
    };
    let input_k = find(&spec.input)?;
    let output_k = find(&spec.output)?;
    let group_k = spec.group.as_deref().map(find).transpose()?;
    let filter_k = spec.filter.column().map(find).transpose()?;
    if rows.is_empty() {
        return Err(DataError::file(
            path,
            "empty file: a header but no data rows",
        ));
    }
    let mut series: Vec<Series> = Vec::new();
    let mut last_group: Option<f64> = None;
    let file_label = path.file_name().map_or_else(
        || path.display().to_string(),
        |n| n.to_string_lossy().into(),
    );
    for (line, fields) in &rows {
        let input = parse_finite(path, *line, &spec.input, &fields[input_k])?;
        let output = parse_finite(path, *line, &spec.output, &fields[output_k])?;
        let group = match (group_k, &spec.group) {
            (Some(k), Some(name)) => Some(parse_finite(path, *line, name, &fields[k])?),
            _ => None,
        };
        let selected = match (filter_k, spec.filter.column()) {
            (Some(k), Some(name)) => spec
                .filter
                .accepts(parse_finite(path, *line, name, &fields[k])?),
            _ => true,
        };
        if series.is_empty() || group != last_group {
            let label = match (&spec.group, group) {
                (Some(name), Some(g)) => format!("{file_label} {name}={g}"),
                _ => file_label.clone(),
            };
            series.push(Series {
                label,
                lines: Vec::new(),
                input: Vec::new(),
                output: Vec::new(),
                selected: Vec::new(),
            });
            last_group = group;
        }
        if let Some(s) = series.last_mut() {
            s.lines.push(*line);
            s.input.push(input);
            s.output.push(output);
            s.selected.push(selected);
        }
    }
    Ok(Table {
        path: path.to_path_buf(),
        series,
    })
}
