use magctl::preisach::PreisachMeasure;
use maglab_diagnose::model::{simulate, Augmentation, Nominal};
use maglab_diagnose::rig::*;
fn main() {
    let p = actuator_params::paper_defaults();
    let core = to_core(&p).unwrap();
    let measure = PreisachMeasure::new(
        &core.preisach.weights_a_per_m,
        core.preisach.h_min_a_per_m,
        core.preisach.h_max_a_per_m,
    );
    let nominal = Nominal::from_params(&p);
    let opts = RigOptions {
        duration_s: 0.3,
        noise_m: 0.0,
        quantization_m: 0.0,
        relay_subdivision: 64,
        ..Default::default()
    };
    let exc = sine_sweep(&[10.0], &[0.4], 0.5);
    let e = &generate(&p, &[], &exc, &opts, &|_| {}).unwrap()[0];
    let y = simulate(
        &nominal,
        &measure,
        &Augmentation::default(),
        &e.current_a,
        1e-4,
        16,
    );
    for k in (0..3000).step_by(125) {
        println!(
            "{k} I={:.3} rig={:.4}um model={:.4}um d={:.4}um",
            e.current_a[k],
            e.displacement_m[k] * 1e6,
            y[k] * 1e6,
            (y[k] - e.displacement_m[k]) * 1e6
        );
    }
}
