use host_tests::tracking::*;
use magctl::inverse::{ControlLoop, InverseKind};
use magctl::params::{BAKED_MEASURE, BAKED_PARAMETERS};
fn main() {
    let args: Vec<String> = std::env::args().collect();
    let k: usize = args.get(1).map(|s| s.parse().unwrap()).unwrap_or(32);
    let ticks: usize = args.get(2).map(|s| s.parse().unwrap()).unwrap_or(10000);
    let mut p = BAKED_PARAMETERS;
    if let Some(f) = args.get(3) {
        p.trajectory.frequency_scale_hz = f.parse().unwrap();
    }
    let measure = magctl::preisach::PreisachMeasure::new(
        &p.preisach.weights_a_per_m,
        p.preisach.h_min_a_per_m,
        p.preisach.h_max_a_per_m,
    );
    let _ = &BAKED_MEASURE;
    let control = ControlLoop::new(&measure, &p).unwrap();
    let field = relay_field(&p, k).unwrap();
    for kind in [InverseKind::Dynamic, InverseKind::Static] {
        let t = std::time::Instant::now();
        let run = track_on_host(&control, &p, kind, &field, ticks);
        let s = run.stats;
        let cl = run.ticks.iter().filter(|t| t.flags.0 != 0).count();
        println!(
            "{kind:?} k={k} f={}: rms {:.4} % max {:.4} % of p2p {:.3e} ({:.1}s) flagged {cl}",
            p.trajectory.frequency_scale_hz,
            s.rms_percent(),
            s.max_percent(),
            s.peak_to_peak_m,
            t.elapsed().as_secs_f64()
        );
    }
}
