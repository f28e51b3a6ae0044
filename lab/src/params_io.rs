//! Loading actuator parameters for the host tools.
//!
//! Every `maglab` command that models the actuator takes `--params FILE`. Without it the command
//! uses the parameters baked into this build of the core (`magctl::params::BAKED_PARAMETERS`,
//! from `params/actuator.json` or `ACTUATOR_PARAMS` at build time), so the host tools and the
//! firmware agree by default. A file is read and validated with `actuator_params` (errors name
//! the file, the field and the reason) and converted to the core's f32 types, exactly as
//! `build.rs` does for the firmware.

use actuator_params::ActuatorParams;
use anyhow::{Context, Result};
use magctl::params::{
    ActuatorParameters, BAKED_PARAMETERS, BAKED_PARAMETERS_PROVENANCE, BAKED_PARAMETERS_SOURCE,
};
use magctl::preisach::PreisachMeasure;
use std::path::Path;

/// Parameters in the core's f32 form, with where they came from.
#[derive(Debug, Clone)]
pub struct LoadedParams {
    /// The parameters, as the core uses them.
    pub params: ActuatorParameters,
    /// A human-readable description of the origin (file path, or "baked into this build").
    pub origin: String,
    /// The file's `provenance.source`.
    pub provenance: String,
    /// The same parameters as a parameter file (f64; for the baked ones, widened from the f32
    /// constants), for the f64 tools (the bench plant).
    pub file: ActuatorParams,
}

impl LoadedParams {
    /// The Preisach operator's coefficients for these parameters.
    pub fn measure(&self) -> PreisachMeasure {
        self.params.preisach.measure()
    }
}

/// The baked parameters, or the validated contents of `path`.
pub fn load(path: Option<&Path>) -> Result<LoadedParams> {
    match path {
        None => Ok(LoadedParams {
            params: BAKED_PARAMETERS,
            origin: format!("baked into this build from {BAKED_PARAMETERS_SOURCE}"),
            provenance: BAKED_PARAMETERS_PROVENANCE.to_string(),
            file: widen(&BAKED_PARAMETERS),
        }),
        Some(path) => {
            let file = ActuatorParams::load(path).context("invalid parameter file")?;
            Ok(LoadedParams {
                params: to_core(&file).with_context(|| format!("converting {}", path.display()))?,
                origin: path.display().to_string(),
                provenance: file.provenance.source.clone(),
                file,
            })
        }
    }
}

/// The core's f32 parameters as a parameter file (every value widened exactly to f64; the
/// rest of the paper defaults).
pub fn widen(p: &ActuatorParameters) -> ActuatorParams {
    let mut file = p.to_file(actuator_params::paper_defaults());
    file.provenance.source = format!("baked into this build from {BAKED_PARAMETERS_SOURCE}");
    file
}

/// Converts a validated parameter file to the core's f32 types (the same narrowing `build.rs`
/// applies when it bakes a file).
pub fn to_core(file: &ActuatorParams) -> Result<ActuatorParameters> {
    Ok(ActuatorParameters::from_file(file, "parameter file")?)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The shipped default file, converted here, must equal what `build.rs` baked from it (both
    /// narrow the same f64 values to f32). Holds when the build used the default file.
    #[test]
    fn default_file_converts_to_the_baked_constants() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
        let default_file = root.join("params").join("actuator.json");
        if !BAKED_PARAMETERS_SOURCE.ends_with("params/actuator.json") {
            // Built with ACTUATOR_PARAMS pointing elsewhere: nothing to compare with.
            return;
        }
        let loaded = load(Some(&default_file)).expect("the shipped default file is valid");
        assert_eq!(loaded.params, BAKED_PARAMETERS);
    }

    /// Grid lines in a file reach the core: the measure is not uniform, has the file's lines
    /// (in f32), and the conversion back to a file keeps them.
    #[test]
    fn grid_lines_reach_the_core() {
        let mut file = actuator_params::paper_defaults();
        let lines: Vec<f64> = (0..=25)
            .map(|k| {
                let s = 2.0 * k as f64 / 25.0 - 1.0;
                3.0e4 * s.signum() * s.abs().powf(1.5)
            })
            .collect();
        file.preisach.grid_lines_a_per_m = Some(lines.clone());
        file.validate("lines").expect("valid");
        let core = to_core(&file).unwrap();
        let measure = core.preisach.measure();
        assert!(!measure.is_uniform());
        for (a, b) in measure.grid_lines_a_per_m().iter().zip(&lines) {
            assert_eq!(*a, *b as f32);
        }
        let loaded = LoadedParams {
            params: core,
            origin: "test".into(),
            provenance: String::new(),
            file: file.clone(),
        };
        assert_eq!(loaded.measure(), measure);
    }

    /// Narrowing and widening are derived from the same field list: a file narrowed, widened
    /// and narrowed again is the same core value, the optional Preisach parts included.
    #[test]
    fn narrowing_and_widening_round_trip() {
        assert_eq!(
            to_core(&widen(&BAKED_PARAMETERS)).unwrap(),
            BAKED_PARAMETERS
        );
        let mut file = actuator_params::paper_defaults();
        file.preisach.reversible_susceptibility = Some(vec![2.0; file.preisach.levels]);
        let core = to_core(&file).unwrap();
        assert!(core.preisach.reversible_susceptibility.is_some());
        assert_eq!(to_core(&widen(&core)).unwrap(), core);
        // A vector of the wrong length names its field.
        file.preisach.weights_a_per_m.pop();
        let e = to_core(&file).unwrap_err();
        assert!(
            format!("{e:#}").contains("preisach.weights_a_per_m"),
            "{e:#}"
        );
    }

    #[test]
    fn invalid_file_error_names_the_field() {
        let mut file = actuator_params::paper_defaults();
        file.actuator.eddy_resistance_ohm = -1.0;
        let dir = std::env::temp_dir().join(format!("maglab-params-io-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("bad.json");
        std::fs::write(&path, file.to_json_pretty()).unwrap();
        let err = load(Some(&path)).unwrap_err();
        let message = format!("{err:#}");
        std::fs::remove_dir_all(&dir).ok();
        assert!(
            message.contains("actuator.eddy_resistance_ohm"),
            "message: {message}"
        );
        assert!(err.chain().any(|c| c.is::<actuator_params::ParamsError>()));
    }
}
