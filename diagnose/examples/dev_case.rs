use maglab_diagnose::diagnosis::{diagnose, DiagnoseOptions};
use maglab_identify::data::Measurement;
use maglab_plant::bench::{record_all, sine_experiment, BenchSettings};
use maglab_plant::{CurrentBetweenSamples, Effect, StartState};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let effects: Vec<Effect> = args
        .iter()
        .filter(|a| !a.starts_with("--"))
        .map(|a| Effect::parse(a).unwrap())
        .collect();
    let linear = args.iter().any(|a| a == "--linear");
    let skew: f64 = args
        .iter()
        .find_map(|a| a.strip_prefix("--skew="))
        .map_or(0.0, |v| v.parse().unwrap());
    let start = args
        .iter()
        .find_map(|a| a.strip_prefix("--start="))
        .map_or(StartState::Demagnetized, |v| StartState::parse(v).unwrap());
    let params = actuator_params::paper_defaults();
    let settings = BenchSettings {
        current_between_samples: if linear {
            CurrentBetweenSamples::Linear
        } else {
            CurrentBetweenSamples::Hold
        },
        channel_skew_samples: skew,
        sensor_offset_m: 0.7e-6,
        ..Default::default()
    };
    let mut exps = Vec::new();
    for f in [20.0, 50.0, 100.0, 200.0, 300.0, 400.0] {
        for a in [0.2, 0.4] {
            exps.push(sine_experiment(exps.len(), start, 0.5, a, f, 0.5, 1e4));
        }
    }
    let t = std::time::Instant::now();
    let recs = record_all(&params, &effects, &exps, &settings).unwrap();
    println!("plant {:.2} s", t.elapsed().as_secs_f64());
    let ms: Vec<Measurement> = recs
        .iter()
        .map(|r| Measurement {
            path: format!("{}.csv", r.name).into(),
            t_s: r.t_s.clone(),
            current_a: r.current_a.clone(),
            displacement_m: r.displacement_m.clone(),
            step_s: 1e-4,
        })
        .collect();
    let t = std::time::Instant::now();
    let run = diagnose(&params, &ms, None, &DiagnoseOptions::default(), &|_| {}).unwrap();
    let d = &run.diagnosis;
    println!("diagnose {:.2} s", t.elapsed().as_secs_f64());
    println!(
        "verdict {} + {:?}: {}",
        d.verdict, d.additional_effects, d.verdict_reason
    );
    println!("nuisance: {:?}", d.nuisance.estimated);
    println!(
        "starts: {:?}",
        d.experiments
            .iter()
            .map(|e| e.start_state.clone())
            .collect::<Vec<_>>()
    );
    println!(
        "noise {:.3e} file-nominal rms {:.3e} range {:.3e}",
        d.noise_m, d.nominal_rms_m, d.displacement_range_m
    );
    let r = &d.refitted_nominal;
    println!(
        "  {:28} train {:.3e} held {:.3e} sys {:.3e} evals {} {:?}",
        r.effect,
        r.training_rms_m,
        r.held_out_rms_after_m,
        r.systematic_after_m,
        r.evaluations,
        r.parameters
    );
    for c in &d.ranking {
        println!(
            "  {:28} train {:.3e} held {:.3e} sys {:.3e} ({:.0}%) worse {}/{} sig {} evals {} {:?}",
            c.effect,
            c.training_rms_m,
            c.held_out_rms_after_m,
            c.systematic_after_m,
            100.0 * c.systematic_after_m / c.systematic_before_m.max(1e-300),
            c.worse_experiments,
            c.held_out_experiments,
            c.significant,
            c.evaluations,
            c.parameters
        );
    }
}
