use maglab_diagnose::diagnosis::{diagnose, DiagnoseOptions};
use maglab_diagnose::effects::RigEffect;
use maglab_diagnose::rig::*;
use maglab_identify::data::Measurement;
fn main() {
    let p = actuator_params::paper_defaults();
    let effects: Vec<RigEffect> = std::env::args()
        .skip(1)
        .map(|a| RigEffect::parse(&a).unwrap())
        .collect();
    let opts = RigOptions {
        duration_s: 0.4,
        ..Default::default()
    };
    let exc = sine_sweep(&[20.0, 50.0, 100.0, 200.0, 300.0, 400.0], &[0.2, 0.4], 0.5);
    let t = std::time::Instant::now();
    let exps = generate(&p, &effects, &exc, &opts, &|_| {}).unwrap();
    let rig_t = t.elapsed();
    let ms: Vec<Measurement> = exps
        .iter()
        .map(|e| Measurement {
            path: e.name.clone().into(),
            t_s: e.t_s.clone(),
            current_a: e.current_a.clone(),
            displacement_m: e.displacement_m.clone(),
            step_s: 1e-4,
        })
        .collect();
    let t = std::time::Instant::now();
    let run = diagnose(&p, &ms, &DiagnoseOptions::default(), &|_| {}).unwrap();
    let d = &run.diagnosis;
    println!("rig {:?} diag {:?}", rig_t, t.elapsed());
    println!("VERDICT {} :: {}", d.verdict, d.verdict_reason);
    println!(
        "noise {:.3e} range {:.3e} nominal rms {:.3e} sys {:.3e} gap_start {:?}",
        d.noise_m,
        d.displacement_range_m,
        d.nominal_rms_m,
        d.nominal_systematic_m,
        d.where_.gap_start_hz
    );
    for c in &d.ranking {
        println!("  {:28} before {:.3e} after {:.3e} x{:.2} sys {:.3e}->{:.3e} impr {}/{} sig {} evals {} {:?}", c.effect, c.held_out_rms_before_m, c.held_out_rms_after_m, c.held_out_reduction, c.systematic_before_m, c.systematic_after_m, c.improved_experiments, c.held_out_experiments, c.significant, c.evaluations, c.parameters);
    }
    for s in &d.where_.summary {
        println!("  * {s}");
    }
}
