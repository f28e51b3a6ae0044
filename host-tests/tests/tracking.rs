//! The inverse controller (`magctl::inverse::ControlLoop`, the firmware's interrupt code) against
//! the independent reference plant (`host_tests::tracking`): the closed loop's goal on the host.
//!
//! The trajectory is the baked default (Van der Pol, μ = 1, 100 Hz scale: fundamental ≈ 94 Hz,
//! odd harmonics above), 1 s of control time at 10 kHz.

use host_tests::tracking::{self, TrackingRun};
use magctl::inverse::{ControlLoop, InverseKind};
use magctl::params::{BAKED_MEASURE, BAKED_PARAMETERS};

fn run(kind: InverseKind, relays_per_cell: usize, seconds: f64) -> TrackingRun {
    let p = &BAKED_PARAMETERS;
    let control = ControlLoop::new(&BAKED_MEASURE, p).expect("valid baked control settings");
    let field = tracking::relay_field(p, relays_per_cell).expect("valid relay field");
    let ticks = (seconds * p.control.sample_rate_hz as f64) as usize;
    let r = tracking::track_on_host(&control, p, kind, &field, ticks);
    assert!(
        r.ticks.iter().all(|t| t.flags.0 == 0),
        "{kind:?}: a limiter or clamp flag was raised; the run would not test the inverse alone"
    );
    println!(
        "{kind:?}, {relays_per_cell} relays/cell: RMS {:.4} % max {:.4} % of p2p {:.3e} m",
        r.stats.rms_percent(),
        r.stats.max_percent(),
        r.stats.peak_to_peak_m
    );
    r
}

/// The goal: dynamic-inverse RMS error ≤ 1 % of the trajectory's peak-to-peak on the
/// nominal plant; the static inverse clearly worse. "Clearly": the static inverse ignores (4)-(5),
/// whose phase lag at the ≈ 94 Hz fundamental alone is ≈ 2ξ f / f0 ≈ 0.37 rad, an RMS error of
/// ≈ 13 % of the peak-to-peak, i.e. more than 10× the dynamic inverse's 1 % bound; require 5×.
#[test]
fn dynamic_inverse_tracks_within_one_percent_and_static_is_clearly_worse() {
    let dynamic = run(InverseKind::Dynamic, tracking::RELAY_SUBDIVISION, 1.0);
    let stat = run(InverseKind::Static, tracking::RELAY_SUBDIVISION, 1.0);
    assert!(
        dynamic.stats.rms_error_m <= 0.01 * dynamic.stats.peak_to_peak_m,
        "dynamic RMS {:.3} % of p2p",
        dynamic.stats.rms_percent()
    );
    let ratio = stat.stats.rms_error_m / dynamic.stats.rms_error_m;
    println!("static / dynamic RMS error: {ratio:.1}x");
    assert!(ratio > 5.0, "static/dynamic ratio {ratio}");
}

/// What is left of the dynamic inverse's error is the reference plant's relay discretization,
/// not the inverse: the relay operator's error is first order in 1/k (`reference::preisach`), so
/// doubling k halves that part, while an error of the inverse itself would not depend on k at all
/// (ratio 1). Require the error to fall below 3/4 (halfway between the two) from k = 32 to 64.
#[test]
fn remaining_dynamic_error_is_the_reference_discretization() {
    let coarse = run(InverseKind::Dynamic, 32, 0.3);
    let fine = run(InverseKind::Dynamic, 64, 0.3);
    assert!(
        fine.stats.rms_error_m < 0.75 * coarse.stats.rms_error_m,
        "k = 32: {:e} m, k = 64: {:e} m",
        coarse.stats.rms_error_m,
        fine.stats.rms_error_m
    );
}
