use maglab_plant::suite;
fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let name = &args[0];
    let params = actuator_params::paper_defaults();
    let case = suite::draw(&params, 999, suite::Kind::NoiseOnly).unwrap();
    let base = maglab_plant::Effect::default_for(name).unwrap();
    let key = base.spec.magnitude.0;
    for v in args[1..].iter().map(|s| s.parse::<f64>().unwrap()) {
        let e = base.clone().with(key, v).unwrap();
        let g = suite::gap(&params, &[e], &case.experiments, &case.settings).unwrap();
        println!("{name} {key}={v}: gap {:.2} %", 100.0 * g);
    }
}
