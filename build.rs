//! Bakes the actuator parameter file into typed constants.
//!
//! Reads `params/actuator.json`, or the file named by the `ACTUATOR_PARAMS` environment variable
//! (a path relative to this crate's root, or absolute), validates it with `actuator-params`, and
//! writes `$OUT_DIR/baked_params.rs`, which `src/params.rs` includes. An invalid file fails the
//! build with the field and the reason.

use std::path::PathBuf;

fn main() {
    println!("cargo:rerun-if-env-changed=ACTUATOR_PARAMS");
    let manifest_dir =
        PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").expect("cargo sets CARGO_MANIFEST_DIR"));
    let path = match std::env::var("ACTUATOR_PARAMS") {
        Ok(p) if !p.is_empty() => {
            let p = PathBuf::from(p);
            if p.is_absolute() {
                p
            } else {
                manifest_dir.join(p)
            }
        }
        _ => manifest_dir.join("params").join("actuator.json"),
    };
    println!("cargo:rerun-if-changed={}", path.display());
    let name = path.display().to_string();
    let params = match actuator_params::ActuatorParams::load(&path)
        .and_then(|p| p.validate_for_firmware(&name).map(|()| p))
    {
        Ok(p) => p,
        Err(e) => {
            // `cargo:warning` makes the reason visible in the summary; the panic fails the build.
            println!("cargo:warning=invalid actuator parameters: {e}");
            eprintln!("error: invalid actuator parameters: {e}");
            std::process::exit(1);
        }
    };
    let code = actuator_params::codegen::rust_constants(&params, &path.display().to_string());
    let out = PathBuf::from(std::env::var("OUT_DIR").expect("cargo sets OUT_DIR"))
        .join("baked_params.rs");
    std::fs::write(&out, code).unwrap_or_else(|e| panic!("cannot write {}: {e}", out.display()));
    firmware_link_setup(&manifest_dir);
}

/// Firmware builds (`target_os = "none"`): puts the selected board's directory `boards/<board>/`
/// on the linker search path (its `board_memory.x`, which the root `memory.x` includes, and its
/// `device.x`) and adds defmt's linker script to the firmware binaries. Host builds are
/// untouched. (See src/board.)
fn firmware_link_setup(manifest_dir: &std::path::Path) {
    if std::env::var("CARGO_CFG_TARGET_OS").as_deref() != Ok("none") {
        return;
    }
    let boards = [
        ("CARGO_FEATURE_BOARD_MPS2_AN386", "mps2-an386"),
        ("CARGO_FEATURE_BOARD_NUCLEO_F446RE", "nucleo-f446re"),
    ];
    let selected: Vec<&str> = boards
        .iter()
        .filter(|(feature, _)| std::env::var_os(feature).is_some())
        .map(|(_, board)| *board)
        .collect();
    match selected.as_slice() {
        [] => {}
        [board] => {
            let dir = manifest_dir.join("boards").join(board);
            println!("cargo:rerun-if-changed={}", dir.display());
            println!("cargo:rustc-link-search={}", dir.display());
            println!("cargo:rustc-link-arg-bins=-Tdefmt.x");
        }
        many => {
            eprintln!("error: enable exactly one board feature, got {many:?}");
            std::process::exit(1);
        }
    }
}
