//! Scans quasi-static records for drift (`maglab_model::drift`): per file, the counted visits to
//! the largest and the smallest current, their spread as a fraction of the record's displacement
//! range, and whether `maglab identify` would warn. The figures in `drift`'s module docs come from the sweeps the identified suite writes (`IDENTIFIED_DIR=DIR
//! IDENTIFIED_SEED=N cargo test --release -p maglab --test identified_suite -- --ignored`):
//!
//! ```sh
//! cargo run --release -p maglab-identify --example drift_scan -- DIR/case*/data/00_forc.csv
//! ```

use maglab_dataset::data::load_measurement;
use maglab_model::drift::{drift_warning, extreme_visits, DRIFT_LIMIT};
use std::path::Path;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let files: Vec<String> = std::env::args().skip(1).collect();
    if files.is_empty() {
        return Err("usage: drift_scan FILE.csv...".into());
    }
    println!(
        "file  visits_top  spread_top_%  visits_bottom  spread_bottom_%  warned (limit {:.0} %)",
        100.0 * DRIFT_LIMIT
    );
    for file in &files {
        let m = load_measurement(Path::new(file)).map_err(|e| e.to_string())?;
        let (lo, hi) = m
            .displacement_m
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &y| {
                (lo.min(y), hi.max(y))
            });
        let range = (hi - lo).max(f64::MIN_POSITIVE);
        let [top, bottom] = extreme_visits(&m.t_s, &m.current_a, &m.displacement_m);
        let warned = drift_warning(file, &m.t_s, &m.current_a, &m.displacement_m).is_some();
        println!(
            "{file}  {}  {:.3}  {}  {:.3}  {warned}",
            top.visits.len(),
            100.0 * top.spread_m() / range,
            bottom.visits.len(),
            100.0 * bottom.spread_m() / range
        );
    }
    Ok(())
}
