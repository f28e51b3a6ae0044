//! Every way a measurement file can be wrong gets an error naming file, line and column.

use maglab_dataset::data::{load_dataset, load_measurement, DataError};
use std::path::{Path, PathBuf};

/// A file written into its own temporary folder, removed with it when dropped.
struct Written {
    _dir: tempfile::TempDir,
    path: PathBuf,
}

impl std::ops::Deref for Written {
    type Target = Path;
    fn deref(&self) -> &Path {
        &self.path
    }
}

fn write(name: &str, text: &str) -> Written {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join(name);
    std::fs::write(&path, text).unwrap();
    Written { _dir: dir, path }
}

fn err(name: &str, text: &str) -> DataError {
    let path = write(name, text);
    let e = load_measurement(&path).expect_err("must be rejected");
    assert_eq!(e.path, path.path);
    assert!(e.to_string().starts_with(&path.display().to_string()));
    e
}

const GOOD: &str = "t_s,current_a,displacement_m\n0,0.1,1e-6\n0.001,0.2,2e-6\n0.002,0.3,3e-6\n";

#[test]
fn a_good_file_loads() {
    let m = load_measurement(&write("good.csv", GOOD)).unwrap();
    assert_eq!(m.len(), 3);
    assert!((m.step_s - 0.001).abs() < 1e-15);
    assert_eq!(m.current_a, vec![0.1, 0.2, 0.3]);
}

#[test]
fn wrong_header_names_the_column() {
    let e = err(
        "header.csv",
        "t_s,current_mA,displacement_m\n0,1,1\n1,1,1\n2,1,1\n",
    );
    assert_eq!(e.line, Some(1));
    assert_eq!(e.column.as_deref(), Some("column 2"));
    assert!(e.reason.contains("t_s,current_a,displacement_m"), "{e}");
    let e = err("header-short.csv", "t_s,current_a\n0,1\n1,1\n2,1\n");
    assert_eq!(e.column.as_deref(), Some("column 3"));
}

#[test]
fn non_numeric_names_line_and_column() {
    let e = err(
        "text.csv",
        "t_s,current_a,displacement_m\n0,0.1,1e-6\n0.001,abc,2e-6\n0.002,0.3,3e-6\n",
    );
    assert_eq!((e.line, e.column.as_deref()), (Some(3), Some("current_a")));
    assert!(e.reason.contains("`abc` is not a number"), "{e}");
}

#[test]
fn nan_and_inf_are_rejected() {
    let e = err(
        "nan.csv",
        "t_s,current_a,displacement_m\n0,0.1,1e-6\n0.001,0.2,NaN\n0.002,0.3,3e-6\n",
    );
    assert_eq!(
        (e.line, e.column.as_deref()),
        (Some(3), Some("displacement_m"))
    );
    assert!(e.reason.contains("not a finite number"), "{e}");
    let e = err(
        "inf.csv",
        "t_s,current_a,displacement_m\n0,0.1,1e-6\n0.001,0.2,2e-6\n0.002,inf,3e-6\n",
    );
    assert_eq!((e.line, e.column.as_deref()), (Some(4), Some("current_a")));
}

#[test]
fn missing_field_is_rejected() {
    let e = err(
        "fields.csv",
        "t_s,current_a,displacement_m\n0,0.1,1e-6\n0.001,0.2\n0.002,0.3,3e-6\n",
    );
    assert_eq!(e.line, Some(3));
    assert!(e.reason.contains("expected 3 fields"), "{e}");
}

#[test]
fn non_increasing_time_is_rejected() {
    let e = err(
        "time.csv",
        "t_s,current_a,displacement_m\n0,0.1,1e-6\n0.001,0.2,2e-6\n0.001,0.3,3e-6\n",
    );
    assert_eq!((e.line, e.column.as_deref()), (Some(4), Some("t_s")));
    assert!(e.reason.contains("does not increase"), "{e}");
}

#[test]
fn non_uniform_time_is_rejected_with_the_tolerance() {
    // A dropped sample: the step doubles.
    let e = err(
        "gap.csv",
        "t_s,current_a,displacement_m\n0,0,0\n0.001,0,0\n0.002,0,0\n0.004,0,0\n0.005,0,0\n",
    );
    assert_eq!((e.line, e.column.as_deref()), (Some(5), Some("t_s")));
    assert!(
        e.reason.contains("non-uniform") && e.reason.contains("0.1 %"),
        "{e}"
    );
    // Jitter of 1e-4 of a step (time stamps rounded to 7 digits) is accepted.
    let ok = "t_s,current_a,displacement_m\n0,0,0\n0.0010001,0,0\n0.002,0,0\n0.0029999,0,0\n";
    load_measurement(&write("jitter.csv", ok)).unwrap();
}

#[test]
fn empty_files_are_rejected() {
    let e = err("empty.csv", "");
    assert!(e.reason.contains("empty file"), "{e}");
    let e = err("header-only.csv", "t_s,current_a,displacement_m\n");
    assert!(e.reason.contains("no data rows"), "{e}");
}

#[test]
fn too_few_samples_are_rejected() {
    let e = err(
        "short.csv",
        "t_s,current_a,displacement_m\n0,0,0\n0.001,0,0\n",
    );
    assert!(e.reason.contains("too few samples: 2"), "{e}");
}

#[test]
fn a_dataset_reads_csv_files_in_order_and_lists_the_rest() {
    let folder = tempfile::tempdir().unwrap();
    let dir = folder.path();
    std::fs::write(dir.join("b.csv"), GOOD).unwrap();
    std::fs::write(dir.join("a.csv"), GOOD).unwrap();
    std::fs::write(dir.join("notes.txt"), "rig notes").unwrap();
    let ds = load_dataset(dir).unwrap();
    let names: Vec<_> = ds
        .measurements
        .iter()
        .map(|m| m.path.file_name().unwrap().to_owned())
        .collect();
    assert_eq!(names, ["a.csv", "b.csv"]);
    assert_eq!(ds.ignored, vec![dir.join("notes.txt")]);
    // One bad file fails the dataset, naming that file.
    std::fs::write(dir.join("c.csv"), "t_s,current_a,displacement_m\n0,0,0\n").unwrap();
    let e = load_dataset(dir).unwrap_err();
    assert_eq!(e.path, dir.join("c.csv"));
    let empty = dir.join("empty-folder");
    std::fs::create_dir_all(&empty).unwrap();
    assert!(load_dataset(&empty)
        .unwrap_err()
        .reason
        .contains("no measurement files"));
}

#[test]
fn the_coil_current_column_is_read_checked_and_written_back() {
    let with =
        "t_s,current_a,displacement_m,coil_current_a\n0,0.1,1e-6,0.09\n0.001,0.2,2e-6,0.19\n\
                0.002,0.3,3e-6,0.29\n";
    let m = load_measurement(&write("coil.csv", with)).unwrap();
    assert_eq!(m.coil_current_a, Some(vec![0.09, 0.19, 0.29]));
    assert_eq!(
        load_measurement(&write("plain.csv", GOOD))
            .unwrap()
            .coil_current_a,
        None
    );
    // A bad value names the column.
    let e = err(
        "coil-nan.csv",
        "t_s,current_a,displacement_m,coil_current_a\n0,0.1,1e-6,0.1\n0.001,0.2,2e-6,x\n\
         0.002,0.3,3e-6,0.3\n",
    );
    assert_eq!(
        (e.line, e.column.as_deref()),
        (Some(3), Some("coil_current_a"))
    );
    // A fourth column of another name names it and both headers.
    let e = err(
        "coil-name.csv",
        "t_s,current_a,displacement_m,coil_current_mA\n0,1,1,1\n1,1,1,1\n2,1,1,1\n",
    );
    assert_eq!(e.column.as_deref(), Some("column 4"));
    assert!(e.reason.contains("coil_current_a"), "{e}");
    // Written back with the column, read back equal.
    let path = write("coil-written.csv", "");
    maglab_dataset::data::write_measurement(
        &path,
        &m.t_s,
        &m.current_a,
        &m.displacement_m,
        m.coil_current_a.as_deref(),
    )
    .unwrap();
    assert_eq!(
        load_measurement(&path).unwrap().coil_current_a,
        m.coil_current_a
    );
    // A column of another length than the time stamps is refused, naming it.
    let e = maglab_dataset::data::write_measurement(
        &path,
        &m.t_s,
        &m.current_a,
        &m.displacement_m,
        Some(&[0.1]),
    )
    .unwrap_err();
    assert!(e.reason.contains("coil_current_a"), "{e}");
}

#[test]
fn a_dataset_records_the_coil_current_in_every_file_or_in_none() {
    let folder = tempfile::tempdir().unwrap();
    let dir = folder.path();
    std::fs::write(dir.join("a.csv"), GOOD).unwrap();
    std::fs::write(
        dir.join("b.csv"),
        "t_s,current_a,displacement_m,coil_current_a\n0,0.1,1e-6,0.1\n0.001,0.2,2e-6,0.2\n\
         0.002,0.3,3e-6,0.3\n",
    )
    .unwrap();
    let e = load_dataset(dir).unwrap_err();
    assert_eq!(e.path, dir.join("a.csv"));
    assert_eq!(e.column.as_deref(), Some("coil_current_a"));
    assert!(e.reason.contains("b.csv"), "{e}");
}

#[test]
fn an_identification_folder_records_the_coil_current_in_both_sub_folders_or_in_neither() {
    let folder = tempfile::tempdir().unwrap();
    let dir = folder.path();
    let quasi_static = dir.join("quasi-static");
    let dynamic = dir.join("dynamic");
    std::fs::create_dir_all(&quasi_static).unwrap();
    std::fs::create_dir_all(&dynamic).unwrap();
    std::fs::write(quasi_static.join("a.csv"), GOOD).unwrap();
    // Each sub-folder is consistent on its own; the dynamic one records the current, 50 Hz.
    let mut sine = String::from("t_s,current_a,displacement_m,coil_current_a\n");
    for k in 0..200 {
        let t = k as f64 * 1e-4;
        let i = 0.8 + 0.2 * (2.0 * std::f64::consts::PI * 50.0 * t).sin();
        sine += &format!("{t},{i},{},{i}\n", 1e-5 * i);
    }
    std::fs::write(dynamic.join("b.csv"), sine).unwrap();
    let Err(e) = maglab_identify::RecordedDataset::load(dir, &Default::default()) else {
        panic!("a folder with the column in some files only is refused");
    };
    assert_eq!(e.path, quasi_static.join("a.csv"));
    assert_eq!(e.column.as_deref(), Some("coil_current_a"));
    assert!(e.reason.contains("b.csv"), "{e}");
}
