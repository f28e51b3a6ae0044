//! Which identified constants lie at an end of the identification's search range
//! (`maglab_identify::quality::at_search_bound`, the test behind the warning `maglab identify`
//! prints), for
//! the case folders the identified suite writes (each with the base `datasheet.json` and
//! `identified.json`; `IDENTIFIED_DIR=DIR IDENTIFIED_CASES=32 IDENTIFIED_SEED=N cargo test
//! --release -p maglab --test identified_suite -- --ignored`). The figures in `quality`'s docs:
//!
//! ```sh
//! cargo run --release -p maglab-identify --example bound_scan -- DIR/case*
//! ```

use actuator_params::ActuatorParams;
use maglab_identify::quality::{at_search_bound, DYNAMIC_CONSTANT_NAMES};
use maglab_model::candidates::IDENTIFICATION_RANGE;
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
        let (identified, base) = (constants(&identified), constants(&base));
        let ends: Vec<String> = (0..3)
            .filter_map(|k| {
                at_search_bound(identified[k], base[k], IDENTIFICATION_RANGE[k])
                    .map(|_| format!("{} = {:.4}", DYNAMIC_CONSTANT_NAMES[k], identified[k]))
            })
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
