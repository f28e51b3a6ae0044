//! The error of every reader and writer of the dataset format: the file, the line, the column or
//! field, and what is wrong.

use std::fmt;
use std::path::{Path, PathBuf};

/// A measurement file or dataset that cannot be used.
#[derive(Debug, Clone, PartialEq)]
pub struct DataError {
    /// The file (or folder).
    pub path: PathBuf,
    /// 1-based line number, when the problem is on a line.
    pub line: Option<u64>,
    /// Column name (or `column N` when the header itself is wrong), when the problem is in a field.
    pub column: Option<String>,
    /// What is wrong.
    pub reason: String,
}

impl fmt::Display for DataError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.path.display())?;
        if let Some(line) = self.line {
            write!(f, ":{line}")?;
        }
        if let Some(column) = &self.column {
            write!(f, ": column `{column}`")?;
        }
        write!(f, ": {}", self.reason)
    }
}

impl std::error::Error for DataError {}

impl DataError {
    /// An error about the whole file (it cannot be opened, it is empty, ...).
    pub fn file(path: &Path, reason: impl Into<String>) -> Self {
        DataError {
            path: path.to_path_buf(),
            line: None,
            column: None,
            reason: reason.into(),
        }
    }

    /// An error at a 1-based line of the file, in a named column if there is one.
    pub fn at(path: &Path, line: u64, column: Option<&str>, reason: impl Into<String>) -> Self {
        DataError {
            path: path.to_path_buf(),
            line: Some(line),
            column: column.map(str::to_string),
            reason: reason.into(),
        }
    }
}
