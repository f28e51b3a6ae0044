//! Writes the default parameter file: `cargo run -p actuator-params --example write_default > params/actuator.json`.
fn main() {
    print!("{}", actuator_params::paper_defaults().to_json_pretty());
}
