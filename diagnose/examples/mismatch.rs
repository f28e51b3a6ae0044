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
    let stroke = p.actuator.rod_length_m * p.actuator.saturation_magnetostriction;
    let k: usize = std::env::args()
        .nth(1)
        .map(|s| s.parse().unwrap())
        .unwrap_or(16);
    let opts = RigOptions {
        duration_s: 0.2,
        noise_m: 0.0,
        quantization_m: 0.0,
        relay_subdivision: k,
        ..Default::default()
    };
    let exc = sine_sweep(&[10.0, 50.0, 100.0, 200.0, 400.0], &[0.4], 0.5);
    let t = std::time::Instant::now();
    let exps = generate(&p, &[], &exc, &opts, &|_| {}).unwrap();
    println!("rig {:?}", t.elapsed());
    for e in &exps {
        let range = e.displacement_m.iter().cloned().fold(f64::MIN, f64::max)
            - e.displacement_m.iter().cloned().fold(f64::MAX, f64::min);
        let mut line = format!("{} range {:.2}um:", e.name, range * 1e6);
        for s in [1, 2, 4, 8, 16] {
            let t = std::time::Instant::now();
            let y = simulate(
                &nominal,
                &measure,
                &Augmentation::default(),
                &e.current_a,
                1e-4,
                s,
            );
            let el = t.elapsed();
            let n = y.len();
            let rms = (y
                .iter()
                .zip(&e.displacement_m)
                .skip(n / 10)
                .map(|(a, b)| (a - b) * (a - b))
                .sum::<f64>()
                / (n - n / 10) as f64)
                .sqrt();
            line += &format!(" S{s}: {:.3}% ({:?})", 100.0 * rms / range, el);
        }
        let y4 = simulate(
            &nominal,
            &measure,
            &Augmentation::default(),
            &e.current_a,
            1e-4,
            4,
        );
        let y8 = simulate(
            &nominal,
            &measure,
            &Augmentation::default(),
            &e.current_a,
            1e-4,
            8,
        );
        let n = y4.len();
        let rms = (0..n)
            .skip(n / 10)
            .map(|k| {
                let r = 2.0 * y8[k] - y4[k] - e.displacement_m[k];
                r * r
            })
            .sum::<f64>()
            / (n - n / 10) as f64;
        line += &format!(" R4/8: {:.3}%", 100.0 * rms.sqrt() / range);
        println!("{line}  stroke {:.1}um", stroke * 1e6);
    }
}
