//! The build of the core really fails on every broken parameter file, naming the field: for each
//! case of `common::cases()` this runs `cargo check -p magctl` with `ACTUATOR_PARAMS` pointing at
//! the broken file and checks the exit status and the message `build.rs` prints. A control run
//! with a valid copy of the default file must succeed, so a build broken for another reason
//! cannot pass for a rejection.
//!
//! The nested cargo uses its own target directory (`target/params-check`) so it neither waits for
//! nor invalidates the main build; after the first case only `build.rs` re-runs (it declares
//! `rerun-if-env-changed=ACTUATOR_PARAMS`).

mod common;

use common::{cases, valid_text};
use std::path::{Path, PathBuf};
use std::process::Command;

fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("params/ lives in the workspace root")
        .to_path_buf()
}

/// `cargo check -p magctl` with `ACTUATOR_PARAMS=file`: (success, stderr).
fn check_core_with(file: &Path) -> (bool, String) {
    let root = workspace_root();
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let output = Command::new(cargo)
        .current_dir(&root)
        .args([
            "check",
            "-p",
            "magctl",
            "--lib",
            "--message-format",
            "short",
        ])
        .arg("--target-dir")
        .arg(root.join("target").join("params-check"))
        .env("ACTUATOR_PARAMS", file)
        .env_remove("CARGO_TARGET_DIR")
        .env_remove("RUSTFLAGS")
        .output()
        .expect("cargo runs");
    (
        output.status.success(),
        String::from_utf8_lossy(&output.stderr).into_owned(),
    )
}

#[test]
fn cargo_check_fails_naming_the_field_for_every_broken_file() {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("broken-params");
    std::fs::create_dir_all(&dir).expect("create the scratch directory");

    let valid = dir.join("valid.json");
    std::fs::write(&valid, valid_text()).expect("write the control file");
    let (ok, stderr) = check_core_with(&valid);
    assert!(ok, "the control build with a valid file failed:\n{stderr}");

    let mut failures = Vec::new();
    for case in cases() {
        let file = dir.join(format!("{}.json", case.name));
        std::fs::write(&file, &case.text).expect("write the broken file");
        let (ok, stderr) = check_core_with(&file);
        let expected = format!(
            "invalid actuator parameters: {}: field `{}`: ",
            file.display(),
            case.field
        );
        if ok {
            failures.push(format!("{}: the build succeeded", case.name));
        } else if !stderr.contains(&expected) || !stderr.contains(case.reason_contains) {
            failures.push(format!(
                "{}: stderr lacks {expected:?} / {:?}:\n{stderr}",
                case.name, case.reason_contains
            ));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n\n"));
}
