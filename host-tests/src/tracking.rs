//! Tracking check of the inverse controller (paper Section 5) against the independent reference
//! plant.
//!
//! The controller is `magctl::inverse::ControlLoop` — the very code the firmware's timer interrupt
//! runs — and the plant is [`crate::reference::dynamics::ReferencePlant`] (f64, RK4 on the integral
//! form (8) with substeps, relay-level Preisach operator): nothing of the controller's
//! discretization is shared with it. Used by `cargo xtask qemu` (on the current commands captured
//! from the firmware), by `maglab track` (Figures 7/8) and by `tests/tracking.rs`.
//!
//! # Timing
//!
//! Tick `k` (`k = 0, 1, …`) returns the current held over `[t_k, t_{k+1}]`, `t_k = k h`, and the
//! desired motion at `t_{k+1}`, which it aims at. The plant is advanced over that period with the
//! held current and its displacement at `t_{k+1}` is compared with `ȳ(t_{k+1})`.
//!
//! # Start
//!
//! The controller starts on the trajectory's limit cycle with its Preisach memory driven from
//! negative saturation to the field `H_0` of the first sample ([`ControlLoop::init`]); the plant
//! starts from the same history (relay field from negative saturation to `H_0`), with `y, ẏ` of
//! the trajectory at `t_0`, so a run has no start-up transient and the error measures the
//! inverse alone.

use crate::reference::dynamics::{
    simulate_held, PlantConstants, ReferencePlant, RelayHysteresis, ReversibleRelayHysteresis,
};
use crate::reference::preisach::{ReferenceError, RelayPreisach};
use magctl::inverse::{ControlLoop, InverseKind, LoopState, TickOutput};
use magctl::params::{Actuator, ActuatorParameters};

/// Relays per Preisach-cell side in the reference field for tracking runs. The relay operator's
/// error is first order in `1/k` (see `reference::preisach`); `k = 32` puts it (measured with the
/// `k = 16` run, `tests/tracking.rs`) well below the 1 % acceptance bound while one second of
/// control time still runs in seconds.
pub const RELAY_SUBDIVISION: usize = 32;

/// RK4 substeps of the reference per control period.
pub const SUBSTEPS: usize = 100;

/// Preisach memory capacity of the controller on the host (the firmware's).
pub const CAPACITY: usize = magctl::preisach::DEFAULT_CAPACITY;

/// The reference plant's constants for the controller's (f32) actuator constants, widened
/// exactly to f64: the *nominal* plant, i.e. the one the controller was designed for.
pub fn plant_constants(actuator: &Actuator) -> PlantConstants {
    let mu0 = magctl::params::VACUUM_PERMEABILITY_H_PER_M as f64;
    let ms = actuator.saturation_magnetization_a_per_m as f64;
    PlantConstants {
        c1_per_m_s: actuator.eddy_resistance_ohm as f64
            / (mu0 * actuator.coil_turns as f64 * actuator.rod_area_m2 as f64),
        c0_per_m: actuator.coil_factor_per_m as f64,
        omega0_rad_per_s: 2.0 * std::f64::consts::PI * actuator.resonance_hz as f64,
        damping_ratio: actuator.damping_ratio as f64,
        displacement_per_m2_m: actuator.rod_length_m as f64
            * actuator.saturation_magnetostriction as f64
            / (ms * ms),
    }
}

/// The relay field of a parameter set's Preisach masses with `subdivision` relays per cell side.
pub fn relay_field(
    params: &ActuatorParameters,
    subdivision: usize,
) -> Result<RelayPreisach, ReferenceError> {
    let p = &params.preisach;
    let w: Vec<f64> = p.weights_a_per_m.iter().map(|&w| w as f64).collect();
    if let Some(lines) = &p.lines_a_per_m {
        let lines: Vec<f64> = lines.iter().map(|&h| h as f64).collect();
        return RelayPreisach::with_lines(&w, &lines, subdivision);
    }
    RelayPreisach::new(
        &w,
        p.h_min_a_per_m as f64,
        p.h_max_a_per_m as f64,
        subdivision,
    )
}

/// Runs `ticks` control interrupts of `kind` on the host (the same `ControlLoop::tick` as the
/// firmware), from [`ControlLoop::init`].
pub fn run_controller(
    control: &ControlLoop<'_>,
    kind: InverseKind,
    ticks: usize,
) -> Vec<TickOutput> {
    let mut state: LoopState<CAPACITY> = control.init(kind);
    (0..ticks).map(|_| control.tick(kind, &mut state)).collect()
}

/// The reference plant in the state the controller assumes at `t_0` (module docs, "Start").
pub fn start_plant<'f>(
    control: &ControlLoop<'_>,
    kind: InverseKind,
    constants: PlantConstants,
    field: &'f RelayPreisach,
) -> ReferencePlant<ReversibleRelayHysteresis<'f>> {
    let start: LoopState<CAPACITY> = control.init(kind);
    let desired = control.trajectory().motion(&start.core.trajectory);
    // The controller's reversible part (none: all zero), evaluated by the reference's own f64
    // definition on the controller's grid lines.
    let measure = control.measure();
    let hysteresis = ReversibleRelayHysteresis::new(
        RelayHysteresis {
            field,
            state: field.negative_saturation(),
        },
        measure
            .grid_lines_a_per_m()
            .iter()
            .map(|&h| h as f64)
            .collect(),
        measure
            .reversible_susceptibility()
            .iter()
            .map(|&c| c as f64)
            .collect(),
    );
    ReferencePlant::at_state(
        constants,
        hysteresis,
        start.core.memory.h_a_per_m as f64,
        desired.displacement_m as f64,
        desired.velocity_m_per_s as f64,
    )
}

/// Feeds a current sequence (each held over one control period) to the plant started as the
/// controller assumes; returns the displacement at the end of every period, m.
pub fn plant_response(
    control: &ControlLoop<'_>,
    kind: InverseKind,
    constants: PlantConstants,
    field: &RelayPreisach,
    period_s: f64,
    currents_a: &[f32],
) -> Vec<f64> {
    let mut plant = start_plant(control, kind, constants, field);
    let currents: Vec<f64> = currents_a.iter().map(|&i| i as f64).collect();
    simulate_held(&mut plant, period_s, SUBSTEPS, &currents)
        .iter()
        .map(|s| s.displacement_m)
        .collect()
}

/// Tracking error statistics of one run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackingStats {
    /// RMS of `y - ȳ`, m.
    pub rms_error_m: f64,
    /// Largest `|y - ȳ|`, m.
    pub max_error_m: f64,
    /// Peak-to-peak of the desired trajectory `ȳ`, m.
    pub peak_to_peak_m: f64,
}

impl TrackingStats {
    /// Statistics of `actual` against `desired` (same length, same sample times).
    pub fn of(desired_m: &[f64], actual_m: &[f64]) -> Self {
        assert_eq!(desired_m.len(), actual_m.len(), "sample counts differ");
        assert!(!desired_m.is_empty(), "no samples");
        let (mut sq, mut max, mut lo, mut hi) = (0.0f64, 0.0f64, f64::MAX, f64::MIN);
        for (&d, &a) in desired_m.iter().zip(actual_m) {
            let e = a - d;
            sq += e * e;
            max = max.max(e.abs());
            lo = lo.min(d);
            hi = hi.max(d);
        }
        TrackingStats {
            rms_error_m: (sq / desired_m.len() as f64).sqrt(),
            max_error_m: max,
            peak_to_peak_m: hi - lo,
        }
    }

    /// RMS error relative to the peak-to-peak, %.
    pub fn rms_percent(&self) -> f64 {
        100.0 * self.rms_error_m / self.peak_to_peak_m
    }

    /// Largest error relative to the peak-to-peak, %.
    pub fn max_percent(&self) -> f64 {
        100.0 * self.max_error_m / self.peak_to_peak_m
    }
}

/// One complete host tracking run: the controller's outputs and the plant's displacement.
#[derive(Debug, Clone)]
pub struct TrackingRun {
    /// Which inverse.
    pub kind: InverseKind,
    /// Controller output of every tick.
    pub ticks: Vec<TickOutput>,
    /// Plant displacement at the end of every period, m.
    pub actual_m: Vec<f64>,
    /// Statistics.
    pub stats: TrackingStats,
}

impl TrackingRun {
    /// Desired displacement at the end of every period, m.
    pub fn desired_m(&self) -> Vec<f64> {
        self.ticks
            .iter()
            .map(|t| t.desired.displacement_m as f64)
            .collect()
    }
}

/// Runs the controller for `ticks` periods on the host and the reference plant on its commands.
pub fn track_on_host(
    control: &ControlLoop<'_>,
    params: &ActuatorParameters,
    kind: InverseKind,
    field: &RelayPreisach,
    ticks: usize,
) -> TrackingRun {
    let outputs = run_controller(control, kind, ticks);
    let currents: Vec<f32> = outputs.iter().map(|t| t.current_a).collect();
    let actual_m = plant_response(
        control,
        kind,
        plant_constants(&params.actuator),
        field,
        1.0 / params.control.sample_rate_hz as f64,
        &currents,
    );
    let desired: Vec<f64> = outputs
        .iter()
        .map(|t| t.desired.displacement_m as f64)
        .collect();
    let stats = TrackingStats::of(&desired, &actual_m);
    TrackingRun {
        kind,
        ticks: outputs,
        actual_m,
        stats,
    }
}
