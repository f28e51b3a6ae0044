//! One blind-suite case in detail: `cargo run --release -p maglab-diagnose --example suite_case
//! -- SEED INDEX [COUNT]` (`BLIND_DESIGN=varied`: the varied experiment design; `BLIND_FORMS`: the effects' form set;
//! `BLIND_RODS=families`: the case's rod and its identified file).
#[path = "../tests/blind/mod.rs"]
mod blind;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let seed: u64 = args[0].parse().unwrap();
    let index: usize = args[1].parse().unwrap();
    let count: usize = args.get(2).map_or(32, |s| s.parse().unwrap());
    let params = actuator_params::paper_defaults();
    let kind = maglab_plant::suite::kinds(seed, count)[index].clone();
    // `BLIND_RODS=families`: the case on its rod, against the file identified from that rod.
    let rod = blind::rods_from_env().then(|| blind::rod_of_case(index));
    let case = maglab_plant::suite::draw_on(
        &params,
        rod.as_ref(),
        seed.wrapping_mul(1000).wrapping_add(index as u64),
        kind,
        blind::design_from_env(),
        blind::forms_from_env(),
    )
    .unwrap();
    let case = blind::with_coil_current_from_env(case);
    let nominal = rod.as_ref().map_or_else(
        || params.clone(),
        |r| {
            let loops =
                maglab_plant::bench::operating_loops(&case.experiments, blind::LOOP_TOLERANCE_A);
            blind::identified_nominal(&params, r, &loops)
        },
    );
    println!("{}", case.describe());
    let o = blind::run_case(&params, &nominal, case);
    let d = &o.diagnosis;
    println!(
        "named {:?} correct {} ({:.1} s)\n{}",
        o.named, o.correct, o.seconds, d.verdict_reason
    );
    println!("nuisance {:?}", d.nuisance.estimated);
    if let Some(c) = &d.coil_current {
        println!("coil current: {c:?}");
    }
    println!(
        "noise {:.3e} range {:.3e} file-nominal rms {:.3e}",
        d.noise_m, d.displacement_range_m, d.nominal_rms_m
    );
    let show = |c: &maglab_diagnose::diagnosis::CandidateResult| {
        println!(
            "  {:40} train {:.3e} held {:.3e} sys {:.3e} ({:.0}%) ko {:.3e} pinned {:?} at-end {:?} worse {}/{} sig {} evals {}\n      {}",
            c.effect, c.training_rms_m, c.held_out_rms_after_m, c.systematic_after_m,
            100.0 * c.systematic_after_m / c.systematic_before_m.max(1e-300),
            c.knocked_out_rms_m, c.pinned, c.constants_at_range_end,
            c.worse_experiments, c.held_out_experiments, c.significant, c.evaluations,
            c.parameters.iter().map(|(k, v)| format!("{k}={v:.4}")).collect::<Vec<_>>().join(" ")
        );
        println!(
            "      bands: {}",
            c.per_band
                .iter()
                .map(|b| format!(
                    "{:.0}Hz{} {:.2}->{:.2}",
                    b.frequency_hz,
                    if b.held_out { "*" } else { "" },
                    b.before_m * 1e6,
                    b.after_m * 1e6
                ))
                .collect::<Vec<_>>()
                .join(", ")
        );
    };
    show(&d.refitted_nominal);
    for c in &d.ranking {
        show(c);
    }
    println!("second stage: {}", d.second_stage_reason);
    for c in &d.second_stage {
        show(c);
    }
    println!("additional {:?}", d.additional_effects);
    println!("held-out tie {:?}", d.held_out_tie);
}
