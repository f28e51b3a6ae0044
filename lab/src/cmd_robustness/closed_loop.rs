//! One case run: the controller in lock-step with the bench plant, every tick as the firmware's
//! interrupt sees it, and the run's errors and learning transient.

use anyhow::Result;
use magctl::inverse::{ControlLoop, InverseKind, LoopState};
use magctl::params::ActuatorParameters;
use magctl::sensor::SensorScale;
use maglab_dataset::StartState;
use maglab_plant::Plant;
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};

use super::cases::Case;

/// Error statistics of one run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RunStats {
    /// RMS error, % of the trajectory's peak-to-peak.
    pub rms_pct: f64,
    /// Largest error, % of the peak-to-peak.
    pub max_pct: f64,
    /// RMS coil current command, A.
    pub current_rms_a: f64,
    /// Commands flagged SENSOR_FAULT.
    pub sensor_fault_ticks: usize,
}

/// One run's traces (every tick).
#[derive(Debug, Clone, Default)]
pub struct Trace {
    /// Desired displacement at the end of each period, m.
    pub desired_m: Vec<f64>,
    /// True displacement at the end of each period, m.
    pub actual_m: Vec<f64>,
    /// Current commands, A.
    pub current_a: Vec<f64>,
    /// Flags.
    pub flags: Vec<u8>,
}

/// Runs the controller `control` (built from `controller`) against `case` for `ticks` ticks.
pub fn run_case(
    controller: &ActuatorParameters,
    control: &ControlLoop<'_>,
    kind: InverseKind,
    case: &Case,
    ticks: usize,
    seed: u64,
) -> Result<Trace> {
    let rate = controller.control.sample_rate_hz as f64;
    let mut plant = Plant::new(&case.plant, &case.effects, rate)
        .map_err(|e| anyhow::anyhow!("{}: {e}", case.name))?;
    let mut state: LoopState<{ magctl::preisach::DEFAULT_CAPACITY }> = control.init(kind);
    // As the firmware starts: the rod demagnetized at 0 A, then the start-up conditioning
    // (`magctl::inverse::Conditioning`) with the sensor read, up to the loop's first current.
    plant
        .start(StartState::SwitchOnDemagnetized, 0.0)
        .map_err(|e| anyhow::anyhow!(e))?;
    let scale = SensorScale::new(&controller.sensor);
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    let noise = Normal::new(0.0, case.noise_m.max(f64::MIN_POSITIVE))
        .map_err(|e| anyhow::anyhow!("noise: {e}"))?;
    // The sensor's documented conversion delay (`sensor.sample_delay_s` of the plant's file).
    let delay_s = case.plant.sensor.sample_delay_s;
    let read = |plant: &Plant, rng: &mut rand::rngs::StdRng| {
        let mut y = plant.sensor_at(plant.time_s() - delay_s);
        if case.noise_m > 0.0 {
            y += noise.sample(rng);
        }
        scale.displacement_m(scale.count_of(y as f32))
    };
    let conditioning = *control.conditioning();
    let mut sequence = control.conditioning_sequence(0.0, &state);
    while !sequence.done() {
        let sample = read(&plant, &mut rng);
        let out = control.condition_sensed(kind, &conditioning, &mut sequence, &mut state, sample);
        let i = out.current_a as f64;
        plant.advance(i, i);
        plant.trim_history(0.01);
    }
    let mut trace = Trace::default();
    for _ in 0..ticks {
        let sample = read(&plant, &mut rng);
        let out = control.tick_sensed(kind, &mut state, sample);
        let i = out.current_a as f64;
        plant.advance(i, i);
        plant.trim_history(0.01);
        trace.desired_m.push(out.desired.displacement_m as f64);
        trace.actual_m.push(plant.displacement_m());
        trace.current_a.push(i);
        trace.flags.push(out.flags.0);
    }
    Ok(trace)
}

impl Trace {
    /// The first tick from which `|y − ȳ|` stays below `pct` % of the whole run's peak-to-peak
    /// (`None` if the last tick is above it).
    pub fn settled_from(&self, pct: f64) -> Option<usize> {
        let (lo, hi) = self
            .desired_m
            .iter()
            .fold((f64::MAX, f64::MIN), |(l, h), &d| (l.min(d), h.max(d)));
        let bound = pct / 100.0 * (hi - lo);
        let n = self.desired_m.len();
        match (0..n)
            .rev()
            .find(|&k| (self.actual_m[k] - self.desired_m[k]).abs() >= bound)
        {
            None => Some(0),
            Some(k) if k + 1 < n => Some(k + 1),
            Some(_) => None,
        }
    }

    /// The learning transient: whole-run RMS and the settling time, with the trajectory's period
    /// `period_ticks` (control ticks per cycle) and the control rate.
    pub fn transient(&self, period_ticks: f64, rate_hz: f64) -> Transient {
        let settled = self.settled_from(SETTLED_PCT);
        Transient {
            whole_run_rms_pct: self.stats(0).rms_pct,
            settle_s: settled.map(|k| k as f64 / rate_hz),
            settle_cycles: settled.map(|k| k as f64 / period_ticks),
        }
    }

    /// Statistics over the ticks from `from`.
    pub fn stats(&self, from: usize) -> RunStats {
        let (mut sq, mut max, mut lo, mut hi, mut isq) = (0.0f64, 0.0f64, f64::MAX, f64::MIN, 0.0);
        let n = self.desired_m.len().saturating_sub(from).max(1);
        for k in from..self.desired_m.len() {
            let (d, a) = (self.desired_m[k], self.actual_m[k]);
            let e = a - d;
            sq += e * e;
            max = max.max(e.abs());
            lo = lo.min(d);
            hi = hi.max(d);
            isq += self.current_a[k] * self.current_a[k];
        }
        let p2p = (hi - lo).max(1e-300);
        RunStats {
            rms_pct: 100.0 * (sq / n as f64).sqrt() / p2p,
            max_pct: 100.0 * max / p2p,
            current_rms_a: (isq / n as f64).sqrt(),
            sensor_fault_ticks: self
                .flags
                .iter()
                .filter(|&&f| f & magctl::inverse::CommandFlags::SENSOR_FAULT != 0)
                .count(),
        }
    }
}

/// The error below which a run counts as settled, % of the trajectory's peak-to-peak.
pub const SETTLED_PCT: f64 = 1.0;

/// The learning transient of a closed-loop run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Transient {
    /// RMS error over the whole run (the first cycles included), % of the peak-to-peak.
    pub whole_run_rms_pct: f64,
    /// Time from which the error stays below [`SETTLED_PCT`], s (`None`: it never does).
    pub settle_s: Option<f64>,
    /// The same in cycles of the trajectory.
    pub settle_cycles: Option<f64>,
}
