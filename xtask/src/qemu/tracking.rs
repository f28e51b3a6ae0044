//! Steps 4–5: the host replays the captured commands bit for bit, and the independent reference
//! plant tracks them (`out/qemu/tracking.csv`).

use super::capture::Record;
use anyhow::{ensure, Context, Result};
use host_tests::reference::preisach::RelayPreisach;
use host_tests::tracking::{self, TrackingStats};
use magctl::inverse::{ControlLoop, InverseKind, LoopState};
use magctl::params::{BAKED_MEASURE, BAKED_PARAMETERS};
use std::fmt::Write as _;
use std::path::Path;

/// "Clearly worse": the static inverse's RMS tracking error must exceed the dynamic one's by this
/// factor. The dynamic inverse must stay within 1 % of the peak-to-peak; the static inverse
/// ignores (4)-(5), whose phase lag at the trajectory's ≈ 94 Hz fundamental alone is
/// ≈ 2ξ f / f0 ≈ 0.37 rad, i.e. an RMS error of ≈ 13 % of the peak-to-peak — more than 10 times
/// the dynamic inverse's bound. 5 leaves room for a plant whose reference error eats into that.
const MIN_STATIC_OVER_DYNAMIC: f64 = 5.0;

/// Feeds the captured currents of one phase (each held over its control period) to the
/// independent f64 reference plant (`host_tests::reference::dynamics`: RK4 on the integral form
/// (8), [`tracking::SUBSTEPS`] substeps per period, relay-level Preisach operator with
/// `field.subdivision()` relays per cell side), started in the state the controller assumes
/// (`host_tests::tracking::start_plant`), and compares its displacement with the captured Van der
/// Pol trajectory. Returns the statistics and the plant's displacement.
fn track(
    records: &[Record],
    kind: InverseKind,
    field: &RelayPreisach,
) -> Result<(TrackingStats, Vec<f64>)> {
    let p = &BAKED_PARAMETERS;
    let control = ControlLoop::new(&BAKED_MEASURE, p).map_err(|e| anyhow::anyhow!("{e:?}"))?;
    let currents: Vec<f32> = records.iter().map(|r| r.current_a).collect();
    let actual = tracking::plant_response(
        &control,
        kind,
        tracking::plant_constants(&p.actuator),
        field,
        1.0 / p.control.sample_rate_hz as f64,
        &currents,
    );
    let desired: Vec<f64> = records.iter().map(|r| r.y_m as f64).collect();
    Ok((TrackingStats::of(&desired, &actual), actual))
}

/// The host recomputation must reproduce the firmware's stream bit for bit.
fn replay_on_host(records: &[Record], kind: InverseKind) -> Result<()> {
    let control = ControlLoop::new(&BAKED_MEASURE, &BAKED_PARAMETERS)
        .map_err(|e| anyhow::anyhow!("{e:?}"))?;
    let mut state: LoopState<64> = control.init(kind);
    for r in records {
        let out = control.tick(kind, &mut state);
        ensure!(
            out.current_a.to_bits() == r.current_a.to_bits()
                && out.desired.displacement_m.to_bits() == r.y_m.to_bits(),
            "{kind:?} tick {}: firmware current {} A / ȳ {} m, host {} A / {} m",
            r.index,
            r.current_a,
            r.y_m,
            out.current_a,
            out.desired.displacement_m
        );
    }
    Ok(())
}

/// Columns of `out/qemu/tracking.csv`: one row per control period of the dynamic and static
/// phases; `t_s` is the end of the period (the time of `y_desired_m` and of the plant's `y_plant_m`).
pub const TRACKING_CSV_HEADER: &str = "phase,index,t_s,current_a,y_desired_m,y_plant_m,error_m";

fn write_tracking_csv(
    out_dir: &Path,
    dynamic: &[Record],
    dyn_y: &[f64],
    stat: &[Record],
    stat_y: &[f64],
    rate: f64,
) -> Result<()> {
    let mut csv = String::from(TRACKING_CSV_HEADER);
    csv.push('\n');
    for (name, records, ys) in [("dynamic", dynamic, dyn_y), ("static", stat, stat_y)] {
        for (r, &y) in records.iter().zip(ys) {
            let _ = writeln!(
                csv,
                "{name},{},{:.6},{:e},{:e},{:e},{:e}",
                r.index,
                (r.index as f64 + 1.0) / rate,
                r.current_a,
                r.y_m,
                y,
                y - r.y_m as f64
            );
        }
    }
    let path = out_dir.join("tracking.csv");
    std::fs::write(&path, csv).with_context(|| format!("writing {}", path.display()))
}

/// Steps 4-5: the host replays the captured commands bit for bit, and the reference plant
/// tracks them.
pub(super) fn check_replay_and_tracking(
    out_dir: &Path,
    dynamic: &[Record],
    stat: &[Record],
    summary: &mut String,
) -> Result<()> {
    let rate = BAKED_PARAMETERS.control.sample_rate_hz as f64;
    // 4. host replay
    replay_on_host(dynamic, InverseKind::Dynamic)?;
    replay_on_host(stat, InverseKind::Static)?;
    say!(summary, "host replay: firmware currents and trajectory identical bit for bit (dynamic and static phases)");

    // 5. tracking
    let field = tracking::relay_field(&BAKED_PARAMETERS, tracking::RELAY_SUBDIVISION)
        .map_err(|e| anyhow::anyhow!("reference relay field: {}", e.0))?;
    let (dyn_stats, dyn_y) = track(dynamic, InverseKind::Dynamic, &field)?;
    let (stat_stats, stat_y) = track(stat, InverseKind::Static, &field)?;
    let ratio = stat_stats.rms_error_m / dyn_stats.rms_error_m;
    say!(
        summary,
        "tracking (reference plant: f64 RK4, {} substeps/period, {} relays per cell side), trajectory p2p {:.3e} m:",
        tracking::SUBSTEPS,
        field.subdivision(),
        dyn_stats.peak_to_peak_m
    );
    say!(
        summary,
        "  dynamic inverse: RMS {:.3e} m = {:.3} % of p2p, max {:.3e} m = {:.3} %",
        dyn_stats.rms_error_m,
        dyn_stats.rms_percent(),
        dyn_stats.max_error_m,
        dyn_stats.max_percent()
    );
    say!(
        summary,
        "  static inverse:  RMS {:.3e} m = {:.3} % of p2p, max {:.3e} m = {:.3} %",
        stat_stats.rms_error_m,
        stat_stats.rms_percent(),
        stat_stats.max_error_m,
        stat_stats.max_percent()
    );
    say!(summary, "  static / dynamic RMS error: {ratio:.1}x");
    ensure!(
        dyn_stats.rms_error_m <= 0.01 * dyn_stats.peak_to_peak_m,
        "dynamic-inverse RMS error {:.3} % is above 1 % of the peak-to-peak",
        dyn_stats.rms_percent()
    );
    ensure!(
        ratio > MIN_STATIC_OVER_DYNAMIC,
        "static inverse not clearly worse than the dynamic one (ratio {ratio:.2}, need > {MIN_STATIC_OVER_DYNAMIC})"
    );
    write_tracking_csv(out_dir, dynamic, &dyn_y, stat, &stat_y, rate)?;
    say!(summary, "wrote out/qemu/tracking.csv");

    Ok(())
}
