//! `dataset.json`: what the bench documents about a dataset folder beside its measurement files.
//!
//! A recording knows facts the measurement files cannot carry: how each experiment was started
//! (the Preisach memory and the rest state before its first sample) and what the current was
//! meant to excite. The file is optional; every field is optional except `format`:
//!
//! ```json
//! {
//!   "format": "maglab-dataset-1",
//!   "start_state": "demagnetized",
//!   "files": {
//!     "00_forc.csv": { "start_state": "negative-saturation", "excitation": "FORC sweep" },
//!     "01_sine_200hz.csv": { "excitation": "sine 200 Hz, 0.5 ± 0.2 A" }
//!   }
//! }
//! ```
//!
//! `start_state` (per file, or the folder-wide default) is one of [`StartState::BENCH`]:
//! `switch-on-demagnetized` (AC-demagnetized at 0 A and at rest, the command switched on at
//! `t = 0`), `demagnetized` (AC-demagnetized at 0 A, then brought slowly to the first command and
//! at rest there), `negative-saturation` / `positive-saturation` (saturated, then brought slowly
//! to the first command), `previous` (whatever the previous file of the folder, in name order,
//! left: no reset between experiments). Unknown fields, unknown state names and files that are
//! not in the folder are errors naming the field.
//!
//! Tools that need a start state and find none documented estimate it from the data and say so
//! (`maglab diagnose`, `maglab identify`).

use crate::error::DataError;
pub use crate::start::StartState;
use serde_json::{Map, Value};
use std::collections::BTreeMap;
use std::path::Path;

/// The file name inside a dataset folder.
pub const FILE_NAME: &str = "dataset.json";
/// The value of `format`.
pub const FORMAT: &str = "maglab-dataset-1";

/// What one file's entry documents.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FileInfo {
    /// How the experiment was started.
    pub start_state: Option<StartState>,
    /// Free text: what the current was.
    pub excitation: Option<String>,
}

/// The contents of `dataset.json`.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct DatasetInfo {
    /// Folder-wide default start state.
    pub start_state: Option<StartState>,
    /// Per file (file name, not path).
    pub files: BTreeMap<String, FileInfo>,
}

impl DatasetInfo {
    /// The documented start state of `file_name` (its own, else the folder default).
    pub fn start_of(&self, file_name: &str) -> Option<StartState> {
        self.files
            .get(file_name)
            .and_then(|f| f.start_state)
            .or(self.start_state)
    }

    /// Reads `dir/dataset.json` if present (`Ok(None)` when absent).
    pub fn load(dir: &Path) -> Result<Option<Self>, DataError> {
        let path = dir.join(FILE_NAME);
        if !path.exists() {
            return Ok(None);
        }
        let text = std::fs::read_to_string(&path)
            .map_err(|e| DataError::file(&path, format!("cannot read: {e}")))?;
        Self::parse(&text, &path).map(Some)
    }

    /// Parses the document (errors name `path` and the field).
    pub fn parse(text: &str, path: &Path) -> Result<Self, DataError> {
        let value: Value = serde_json::from_str(text)
            .map_err(|e| DataError::file(path, format!("not valid JSON: {e}")))?;
        let field = |name: &str, reason: String| DataError {
            path: path.to_path_buf(),
            line: None,
            column: Some(name.to_string()),
            reason,
        };
        let Value::Object(top) = value else {
            return Err(DataError::file(path, "the document must be a JSON object"));
        };
        let mut info = DatasetInfo::default();
        let mut format_seen = false;
        for (key, v) in &top {
            match key.as_str() {
                "format" => {
                    format_seen = true;
                    if v.as_str() != Some(FORMAT) {
                        return Err(field("format", format!("must be \"{FORMAT}\", got {v}")));
                    }
                }
                "start_state" => info.start_state = Some(parse_state(v, "start_state", &field)?),
                "files" => {
                    let Value::Object(files) = v else {
                        return Err(field(
                            "files",
                            "must be an object keyed by file name".into(),
                        ));
                    };
                    for (name, entry) in files {
                        info.files
                            .insert(name.clone(), parse_file(name, entry, &field)?);
                    }
                }
                other => {
                    return Err(field(
                        other,
                        "unknown field (expected format, start_state, files)".into(),
                    ))
                }
            }
        }
        if !format_seen {
            return Err(field("format", format!("missing; must be \"{FORMAT}\"")));
        }
        Ok(info)
    }

    /// Checks that every documented file exists among `file_names`.
    pub fn check_files<'a>(
        &self,
        dir: &Path,
        file_names: impl IntoIterator<Item = &'a str> + Clone,
    ) -> Result<(), DataError> {
        for name in self.files.keys() {
            if !file_names.clone().into_iter().any(|f| f == name) {
                return Err(DataError {
                    path: dir.join(FILE_NAME),
                    line: None,
                    column: Some(format!("files.{name}")),
                    reason: "documents a file that is not a measurement file of the folder".into(),
                });
            }
        }
        Ok(())
    }

    /// Writes `dir/dataset.json`.
    pub fn write(&self, dir: &Path) -> Result<(), DataError> {
        let mut top = Map::new();
        top.insert("format".into(), Value::from(FORMAT));
        if let Some(s) = self.start_state {
            top.insert("start_state".into(), Value::from(s.name()));
        }
        let mut files = Map::new();
        for (name, f) in &self.files {
            let mut entry = Map::new();
            if let Some(s) = f.start_state {
                entry.insert("start_state".into(), Value::from(s.name()));
            }
            if let Some(e) = &f.excitation {
                entry.insert("excitation".into(), Value::from(e.clone()));
            }
            files.insert(name.clone(), Value::Object(entry));
        }
        top.insert("files".into(), Value::Object(files));
        let path = dir.join(FILE_NAME);
        let text = serde_json::to_string_pretty(&Value::Object(top))
            .map_err(|e| DataError::file(&path, format!("cannot encode: {e}")))?;
        std::fs::write(&path, text)
            .map_err(|e| DataError::file(&path, format!("cannot write: {e}")))
    }
}

fn parse_state(
    v: &Value,
    name: &str,
    field: &impl Fn(&str, String) -> DataError,
) -> Result<StartState, DataError> {
    let text = v
        .as_str()
        .ok_or_else(|| field(name, format!("must be a string, got {v}")))?;
    StartState::parse_among(text, &StartState::BENCH).map_err(|e| field(name, e))
}

fn parse_file(
    name: &str,
    entry: &Value,
    field: &impl Fn(&str, String) -> DataError,
) -> Result<FileInfo, DataError> {
    let Value::Object(map) = entry else {
        return Err(field(&format!("files.{name}"), "must be an object".into()));
    };
    let mut info = FileInfo::default();
    for (key, v) in map {
        let path = format!("files.{name}.{key}");
        match key.as_str() {
            "start_state" => info.start_state = Some(parse_state(v, &path, field)?),
            "excitation" => {
                info.excitation = Some(
                    v.as_str()
                        .ok_or_else(|| field(&path, format!("must be a string, got {v}")))?
                        .to_string(),
                )
            }
            _ => {
                return Err(field(
                    &path,
                    "unknown field (expected start_state, excitation)".into(),
                ))
            }
        }
    }
    Ok(info)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_and_errors_name_the_field() {
        let dir = std::env::temp_dir().join(format!("dataset-info-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let mut info = DatasetInfo {
            start_state: Some(StartState::Demagnetized),
            ..Default::default()
        };
        info.files.insert(
            "a.csv".into(),
            FileInfo {
                start_state: Some(StartState::NegativeSaturation),
                excitation: Some("FORC".into()),
            },
        );
        info.write(&dir).unwrap();
        let back = DatasetInfo::load(&dir).unwrap().unwrap();
        assert_eq!(back, info);
        assert_eq!(back.start_of("a.csv"), Some(StartState::NegativeSaturation));
        assert_eq!(back.start_of("b.csv"), Some(StartState::Demagnetized));
        let p = Path::new("d/dataset.json");
        let e = DatasetInfo::parse(r#"{"format":"maglab-dataset-1","start_state":"hot"}"#, p)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("column `start_state`") && e.contains("unknown start state `hot`"),
            "{e}"
        );
        let e = DatasetInfo::parse(r#"{"format":"x"}"#, p)
            .unwrap_err()
            .to_string();
        assert!(e.contains("`format`"), "{e}");
        let e = DatasetInfo::parse(
            r#"{"format":"maglab-dataset-1","files":{"a.csv":{"start":"previous"}}}"#,
            p,
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("files.a.csv.start"), "{e}");
        let e = info.check_files(&dir, ["b.csv"]).unwrap_err().to_string();
        assert!(e.contains("files.a.csv"), "{e}");
        std::fs::remove_dir_all(&dir).ok();
    }
}
