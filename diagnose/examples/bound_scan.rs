//! Which identified constants lie at an end of the identification's search range
//! (`maglab_identify::quality::search_bound_warnings`, the warning `maglab identify` prints), for
//! the case folders the identified suite writes (each with the base `datasheet.json` and
//! `identified.json`; `IDENTIFIED_DIR=DIR IDENTIFIED_CASES=32 IDENTIFIED_SEED=N cargo test
//! --release -p maglab --test identified_suite -- --ignored`). The figures in `quality`'s docs:
//!
//! ```sh
//! cargo run --release -p maglab-diagnose --example bound_scan -- DIR/case*
//! ```

use actuator_params::ActuatorParams;
use maglab_diagnose::identification::IDENTIFICATION_RANGE;
use maglab_identify::quality::search_bound_warnings;
use std::path::Path;

fn constants(p: &ActuatorParams) -> [f64; 3] {
    let a = &p.actuator;
    [a.eddy_resistance_ohm, a.damping_ratio, a.resonance_hz]
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let folders: Vec<String> = std::env::args().skip(1).collect();
    if folders.is_empty() {
        return Err("usage: bound_scan CASE_FOLDER...".into());
    }
    let mut at_bound = 0;
    for folder in &folders {
        let dir = Path::new(folder);
        let base = ActuatorParams::load(&dir.join("datasheet.json"))?;
        let identified = ActuatorParams::load(&dir.join("identified.json"))?;
        let warnings = search_bound_warnings(
            constants(&identified),
            constants(&base),
            IDENTIFICATION_RANGE,
        );
        let ends: Vec<&str> = warnings
            .iter()
            .filter_map(|w| w.split(" lies at the ").next())
            .collect();
        if !ends.is_empty() {
            at_bound += 1;
        }
        println!(
            "{folder}  {}",
            if ends.is_empty() {
                "-".to_string()
            } else {
                ends.join("; ")
            }
        );
    }
    println!(
        "{at_bound} of {} folders have a constant at an end of its search",
        folders.len()
    );
    Ok(())
}
