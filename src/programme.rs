//! The identification programme the firmware plays in measurement mode: what `maglab identify`
//! needs to identify an actuator (Section 4 of the paper), generated tick by tick with no table.
//!
//! Experiments, in order, each preceded by the start-up conditioning sequence
//! ([`Conditioning`]: negative saturation, or the sweep of the rod's reach, then slowly to the
//! experiment's first current — the start state `negative-saturation` or `conditioned` of
//! `dataset.json`):
//! 0. the quasi-static **FORC sweep** (first-order reversal curves with a reversal on every line
//!    of `L` equal intervals of the swept range, the path of
//!    `maglab_dataset::excitation::forc_waypoints`): the range is the grid, from `overdrive`
//!    below it to `overdrive` above it, when the coil saturates the rod, else the reach the
//!    conditioning sweeps (no overdrive: the reach is what the identification will model);
//!    then for `r = L−1 … 0` down to line `r` (the bottom for `r = 0`) and back up; straight
//!    segments at the speed of a full-range triangle at [`FORC_SWEEP_HZ`], each a whole number
//!    of ticks so that every reversal is a sample;
//! 1. … the **biased sines**, every frequency of [`SINE_FREQUENCIES_HZ`] at every amplitude of
//!    [`SINE_AMPLITUDES_A`] around [`SINE_BIAS_A`], [`SINE_DURATION_S`] or [`SINE_MIN_PERIODS`]
//!    periods each, whichever is longer.
//!
//! The same generator feeds both measurement paths: the virtual bench streams it from the host
//! (`cargo xtask hil --measure`) and the firmware plays it itself (NUCLEO measurement image,
//! `firmware-hil mode=measure-local`), so both record the same currents.
//!
//! Cost per tick: a few compares, a multiply-add and (sines) one `sinf` — under 100 instructions
//! beside the conditioning's ~15. No allocation, no panic path.

use crate::inverse::{Conditioning, ConditioningError, ConditioningState, OutputLimiter, Sweep};
use crate::preisach::{PreisachMeasure, LEVELS};

/// Speed of the FORC sweep: that of a full-range triangle at this rate, Hz.
pub const FORC_SWEEP_HZ: f32 = 2.0;
/// Overshoot of the FORC sweep beyond the grid at both ends, fraction of the grid's range (the
/// memory is saturated even with a small error in `c0`; the limiter clips at ±I_max).
pub const FORC_OVERDRIVE: f32 = 0.05;
/// Frequencies of the sines, Hz. The first, below the 10 Hz split of `maglab identify`
/// (`maglab_identify::experiments`), is quasi-static data: the minor loops the faster sines run
/// on, measured slowly, so that the masses are fitted where the dynamic fit reads them (on a rod
/// the coil cannot saturate the FORC sweep's reversals from the ends of the reach leave the
/// slope `dM/dH` inside those loops weakly determined, and the eddy fit (4) reads that slope).
pub const SINE_FREQUENCIES_HZ: [f32; 7] = [4.0, 20.0, 50.0, 100.0, 200.0, 300.0, 400.0];
/// Amplitudes of the sines, A (every frequency at every amplitude).
pub const SINE_AMPLITUDES_A: [f32; 3] = [0.2, 0.4, 0.6];
/// DC bias of the sines, A. The loops span 0.2–1.4 A, 0.1–0.7 of the ±2 A limit: the strain
/// goes with `M²`, so the dynamics are seen best where `M` is large; on a rod the coil cannot
/// saturate (plane 4× the reach) sines around 0.55 A strain it by under 6 µm, too little for the
/// eddy lag to be resolved (R_eddy 11 % off), around 0.8 A by up to 12 µm (docs/model.md).
pub const SINE_BIAS_A: f32 = 0.8;
/// Duration of each sine, s, or [`SINE_MIN_PERIODS`] periods when longer.
pub const SINE_DURATION_S: f32 = 0.2;
/// Fewest periods of a sine: the first period is the transient from the conditioned state
/// (`maglab identify` drops it), the second the periodic loop.
pub const SINE_MIN_PERIODS: f32 = 2.0;
/// Number of experiments: the FORC sweep and the sines.
pub const EXPERIMENTS: usize = 1 + SINE_FREQUENCIES_HZ.len() * SINE_AMPLITUDES_A.len();
/// Waypoints of the FORC path: bottom, top, then a reversal and the top again per grid line.
const FORC_WAYPOINTS: usize = 2 + 2 * LEVELS;

/// What an experiment excites.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ExperimentKind {
    /// The quasi-static FORC sweep.
    Forc {
        /// Sweep speed as a full-range triangle rate, Hz.
        sweep_hz: f32,
    },
    /// A biased sine `bias + amplitude·sin(2π f t)`.
    Sine {
        /// Frequency, Hz.
        frequency_hz: f32,
        /// Amplitude, A.
        amplitude_a: f32,
        /// Bias, A.
        bias_a: f32,
    },
}

impl ExperimentKind {
    /// `(name, a, b, c)` for a record header: `("forc", sweep Hz, 0, 0)` or `("sine", Hz, A, bias
    /// A)`.
    pub fn fields(&self) -> (&'static str, f32, f32, f32) {
        match *self {
            ExperimentKind::Forc { sweep_hz } => ("forc", sweep_hz, 0.0, 0.0),
            ExperimentKind::Sine {
                frequency_hz,
                amplitude_a,
                bias_a,
            } => ("sine", frequency_hz, amplitude_a, bias_a),
        }
    }
}

/// One experiment of the programme.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Experiment {
    /// What it excites.
    pub kind: ExperimentKind,
    /// Recorded ticks (the conditioning before it not included).
    pub ticks: u32,
}

/// A rejected programme.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ProgrammeError {
    /// The conditioning's settings are invalid (see [`ConditioningError`]).
    Conditioning(ConditioningError),
    /// The FORC sweep would move more than a quarter of a grid cell per tick (every cell must be
    /// crossed by several samples): the control rate is too low for [`FORC_SWEEP_HZ`].
    SweepTooFast {
        /// Grid cells per tick.
        cells_per_tick: f32,
    },
    /// A non-finite or non-positive setting (coil factor, rate, grid range), named.
    Invalid(&'static str),
}

/// The programme's coefficients (`&self`; its progress is a [`ProgrammeState`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IdentificationProgramme {
    conditioning: Conditioning,
    limit_a: f32,
    /// Bottom of the swept range, A/m.
    h_min_a_per_m: f32,
    /// Width of one of its `L` intervals, A/m.
    cell_width_a_per_m: f32,
    /// The sweep's overshoot beyond the range, fraction of it.
    overdrive: f32,
    coil_factor_per_m: f32,
    cells_per_tick: f32,
    /// Recorded ticks of the FORC sweep (computed once).
    forc_ticks: u32,
    /// Recorded ticks of each sine frequency.
    sine_ticks: [u32; SINE_FREQUENCIES_HZ.len()],
    /// Phase step per tick of each sine frequency, turns × 2³² (exact wrap-around: the phase
    /// error after `n` ticks is at most `n·2⁻³³` turn).
    sine_step_q32: [u32; SINE_FREQUENCIES_HZ.len()],
}

/// Where a programme stands.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProgrammeState {
    experiment: usize,
    conditioning: Option<ConditioningState>,
    /// Tick within the experiment.
    sample: u32,
    /// FORC: the segment (index of its end waypoint) and the tick within it.
    segment: usize,
    segment_tick: u32,
    /// Ticks of the current FORC segment (computed when it is entered).
    segment_steps: u32,
    last_a: f32,
    done: bool,
}

/// One tick of the programme.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProgrammeTick {
    /// Current to command, A (before the output limiter).
    pub current_a: f32,
    /// The experiment this tick belongs to (or is conditioning for).
    pub experiment: usize,
    /// Recorded tick within the experiment (`None`: conditioning before it).
    pub sample: Option<u32>,
}

impl ProgrammeState {
    /// Whether the programme has ended.
    pub fn done(&self) -> bool {
        self.done
    }
}

/// The FORC path in units of the swept range's intervals (`0` = its bottom, `LEVELS` = its top),
/// overshooting both ends by `overdrive` of the range.
fn forc_waypoint(i: usize, overdrive: f32) -> f32 {
    let top = LEVELS as f32 * (1.0 + overdrive);
    let bottom = -(LEVELS as f32) * overdrive;
    match i {
        0 => bottom,
        _ if i % 2 == 1 => top,
        _ => {
            // i = 2, 4, …: reversal at grid line L−1, L−2, …, the bottom for line 0.
            let line = LEVELS.saturating_sub(i / 2);
            if line == 0 {
                bottom
            } else {
                line as f32
            }
        }
    }
}

impl IdentificationProgramme {
    /// The programme for the output `limiter`, coil factor `c0`, the Preisach grid of `measure`
    /// with the rod's reach (`preisach.reach_a_per_m`; `None`: the grid) and the control rate.
    pub fn new(
        limiter: &OutputLimiter,
        coil_factor_per_m: f32,
        measure: &PreisachMeasure,
        reach_a_per_m: Option<[f32; 2]>,
        sample_rate_hz: f32,
    ) -> Result<Self, ProgrammeError> {
        let (h_min_a_per_m, h_max_a_per_m) = (measure.h_min_a_per_m(), measure.h_max_a_per_m());
        if !(coil_factor_per_m.is_finite() && coil_factor_per_m > 0.0) {
            return Err(ProgrammeError::Invalid("coil_factor_per_m"));
        }
        if !(sample_rate_hz.is_finite() && sample_rate_hz > 0.0) {
            return Err(ProgrammeError::Invalid("sample_rate_hz"));
        }
        if !(h_min_a_per_m.is_finite()
            && h_max_a_per_m.is_finite()
            && h_min_a_per_m < h_max_a_per_m)
        {
            return Err(ProgrammeError::Invalid("h_min_a_per_m < h_max_a_per_m"));
        }
        let conditioning = Conditioning::new(
            limiter,
            coil_factor_per_m,
            measure,
            reach_a_per_m,
            sample_rate_hz,
        )
        .map_err(ProgrammeError::Conditioning)?;
        let (sweep_lo, sweep_hi, overdrive) = match conditioning.sweep() {
            Sweep::Saturate { .. } => (h_min_a_per_m, h_max_a_per_m, FORC_OVERDRIVE),
            Sweep::Reach { low_a, high_a } => {
                (low_a * coil_factor_per_m, high_a * coil_factor_per_m, 0.0)
            }
        };
        // A full-range triangle at f travels 2L cells per period.
        let cells_per_tick = 2.0 * LEVELS as f32 * FORC_SWEEP_HZ / sample_rate_hz;
        if cells_per_tick > 0.25 {
            return Err(ProgrammeError::SweepTooFast { cells_per_tick });
        }
        let mut programme = IdentificationProgramme {
            conditioning,
            limit_a: limiter.limit_a(),
            h_min_a_per_m: sweep_lo,
            cell_width_a_per_m: (sweep_hi - sweep_lo) / LEVELS as f32,
            overdrive,
            coil_factor_per_m,
            cells_per_tick,
            forc_ticks: 0,
            sine_ticks: SINE_FREQUENCIES_HZ.map(|f| {
                let duration_s = if SINE_MIN_PERIODS / f > SINE_DURATION_S {
                    SINE_MIN_PERIODS / f
                } else {
                    SINE_DURATION_S
                };
                libm::roundf(duration_s * sample_rate_hz) as u32
            }),
            sine_step_q32: SINE_FREQUENCIES_HZ.map(|f| {
                // Once, at start-up: f64 for the 32-bit step (soft float on the M4F).
                let turns = f as f64 / sample_rate_hz as f64;
                libm::round((turns - libm::floor(turns)) * 4_294_967_296.0) as u32
            }),
        };
        programme.forc_ticks = 1
            + (1..FORC_WAYPOINTS)
                .map(|i| programme.segment_ticks(i))
                .sum::<u32>();
        Ok(programme)
    }

    /// Ticks of FORC segment `i` (from waypoint `i − 1` to `i`).
    fn segment_ticks(&self, i: usize) -> u32 {
        let length =
            libm::fabsf(forc_waypoint(i, self.overdrive) - forc_waypoint(i - 1, self.overdrive));
        let steps = libm::ceilf(length / self.cells_per_tick);
        if steps < 1.0 {
            1
        } else {
            steps as u32
        }
    }

    /// Experiment `k` (`None` past the last).
    pub fn experiment(&self, k: usize) -> Option<Experiment> {
        if k == 0 {
            return Some(Experiment {
                kind: ExperimentKind::Forc {
                    sweep_hz: FORC_SWEEP_HZ,
                },
                ticks: self.forc_ticks,
            });
        }
        let j = k - 1;
        let i = j / SINE_AMPLITUDES_A.len();
        let f = *SINE_FREQUENCIES_HZ.get(i)?;
        let a = *SINE_AMPLITUDES_A.get(j % SINE_AMPLITUDES_A.len())?;
        Some(Experiment {
            kind: ExperimentKind::Sine {
                frequency_hz: f,
                amplitude_a: a,
                bias_a: SINE_BIAS_A,
            },
            ticks: *self.sine_ticks.get(i)?,
        })
    }

    /// The conditioning that precedes each experiment.
    pub fn conditioning(&self) -> &Conditioning {
        &self.conditioning
    }

    /// The start state every experiment has, by its `dataset.json` name: `negative-saturation`
    /// after the saturating conditioning, `conditioned` after the sweep of the reach.
    pub fn start_state_name(&self) -> &'static str {
        match self.conditioning.sweep() {
            Sweep::Saturate { .. } => "negative-saturation",
            Sweep::Reach { .. } => "conditioned",
        }
    }

    /// Swept-range units → coil current, A.
    fn forc_current_a(&self, x: f32) -> f32 {
        (self.h_min_a_per_m + x * self.cell_width_a_per_m) / self.coil_factor_per_m
    }

    /// The current of recorded tick `sample` of experiment `k` (FORC: the state's segment).
    fn current_a(&self, k: usize, s: &ProgrammeState) -> f32 {
        match self.experiment(k).map(|e| e.kind) {
            Some(ExperimentKind::Forc { .. }) => {
                if s.segment == 0 {
                    return self.forc_current_a(forc_waypoint(0, self.overdrive));
                }
                let (a, b) = (
                    forc_waypoint(s.segment - 1, self.overdrive),
                    forc_waypoint(s.segment, self.overdrive),
                );
                let steps = s.segment_steps.max(1);
                self.forc_current_a(a + (b - a) * s.segment_tick as f32 / steps as f32)
            }
            Some(ExperimentKind::Sine {
                amplitude_a,
                bias_a,
                ..
            }) => {
                let step = self
                    .sine_step_q32
                    .get(k.saturating_sub(1) / SINE_AMPLITUDES_A.len())
                    .copied()
                    .unwrap_or(0);
                // Phase in turns, wrapped exactly by the 32-bit multiply.
                let phase = s.sample.wrapping_mul(step) as f32 * (1.0 / 4_294_967_296.0);
                bias_a + amplitude_a * libm::sinf(core::f32::consts::TAU * phase)
            }
            None => 0.0,
        }
    }

    /// The first current of experiment `k`, as the limiter will let it onto the coil.
    fn first_current_a(&self, k: usize) -> f32 {
        let s = ProgrammeState {
            experiment: k,
            conditioning: None,
            sample: 0,
            segment: 0,
            segment_tick: 0,
            segment_steps: 0,
            last_a: 0.0,
            done: false,
        };
        self.current_a(k, &s).max(-self.limit_a).min(self.limit_a)
    }

    /// A programme starting from `from_a` on the coil (0 A after power-up).
    pub fn start(&self, from_a: f32) -> ProgrammeState {
        ProgrammeState {
            experiment: 0,
            conditioning: Some(self.conditioning.start(from_a, self.first_current_a(0))),
            sample: 0,
            segment: 0,
            segment_tick: 0,
            segment_steps: 0,
            last_a: from_a,
            done: false,
        }
    }

    /// Ticks of the whole programme from `from_a`, conditioning included.
    pub fn total_ticks(&self, from_a: f32) -> u32 {
        let mut last = from_a;
        let mut n = 0u32;
        for k in 0..EXPERIMENTS {
            let Some(e) = self.experiment(k) else { break };
            let first = self.first_current_a(k);
            n = n
                .saturating_add(self.conditioning.ticks(last, first))
                .saturating_add(e.ticks);
            let end = ProgrammeState {
                experiment: k,
                conditioning: None,
                sample: e.ticks.saturating_sub(1),
                segment: FORC_WAYPOINTS - 1,
                segment_tick: self.segment_ticks(FORC_WAYPOINTS - 1),
                segment_steps: self.segment_ticks(FORC_WAYPOINTS - 1),
                last_a: 0.0,
                done: false,
            };
            last = self.current_a(k, &end).max(-self.limit_a).min(self.limit_a);
        }
        n
    }

    /// The next tick (`None` once the programme has ended; the caller then ramps to 0 A).
    #[inline]
    pub fn step(&self, s: &mut ProgrammeState) -> Option<ProgrammeTick> {
        if s.done {
            return None;
        }
        if let Some(c) = &mut s.conditioning {
            if !c.done() {
                let current_a = self.conditioning.step(c);
                s.last_a = current_a;
                return Some(ProgrammeTick {
                    current_a,
                    experiment: s.experiment,
                    sample: None,
                });
            }
            s.conditioning = None;
        }
        let current_a = self.current_a(s.experiment, s);
        let tick = ProgrammeTick {
            current_a,
            experiment: s.experiment,
            sample: Some(s.sample),
        };
        s.last_a = current_a.max(-self.limit_a).min(self.limit_a);
        // Advance.
        let ticks = self.experiment(s.experiment).map_or(0, |e| e.ticks);
        s.sample += 1;
        if s.experiment == 0 && s.segment < FORC_WAYPOINTS {
            s.segment_tick += 1;
            if s.segment == 0 || s.segment_tick > s.segment_steps {
                s.segment += 1;
                s.segment_tick = 1;
                if s.segment < FORC_WAYPOINTS {
                    s.segment_steps = self.segment_ticks(s.segment);
                }
            }
        }
        if s.sample >= ticks {
            s.experiment += 1;
            s.sample = 0;
            s.segment = 0;
            s.segment_tick = 0;
            s.segment_steps = 0;
            if s.experiment >= EXPERIMENTS {
                s.done = true;
            } else {
                s.conditioning = Some(
                    self.conditioning
                        .start(s.last_a, self.first_current_a(s.experiment)),
                );
            }
        }
        Some(tick)
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use crate::params::{BAKED_MEASURE, BAKED_PARAMETERS};
    use std::vec::Vec;

    fn programme() -> IdentificationProgramme {
        let p = &BAKED_PARAMETERS;
        let limiter = OutputLimiter::new(&p.control).unwrap();
        IdentificationProgramme::new(
            &limiter,
            p.actuator.coil_factor_per_m,
            &BAKED_MEASURE,
            p.preisach.reach_a_per_m,
            p.control.sample_rate_hz,
        )
        .unwrap()
    }

    #[test]
    fn the_forc_sweep_reverses_on_every_grid_line_and_has_its_announced_length() {
        let prog = programme();
        let mut s = prog.start(0.0);
        let e = prog.experiment(0).unwrap();
        let mut forc = Vec::new();
        let mut conditioning = 0;
        while let Some(t) = prog.step(&mut s) {
            if t.experiment > 0 {
                break;
            }
            match t.sample {
                None => conditioning += 1,
                Some(k) => {
                    assert_eq!(k as usize, forc.len());
                    forc.push(t.current_a);
                }
            }
        }
        assert!(conditioning > 100);
        assert_eq!(forc.len() as u32, e.ticks);
        // Reversals (local extremes) sit exactly on the grid lines in field units.
        let m = &BAKED_MEASURE;
        let c0 = BAKED_PARAMETERS.actuator.coil_factor_per_m;
        let width = (m.h_max_a_per_m() - m.h_min_a_per_m()) / LEVELS as f32;
        let mut minima = Vec::new();
        for w in forc.windows(3) {
            if w[1] < w[0] && w[1] < w[2] {
                minima.push((w[1] * c0 - m.h_min_a_per_m()) / width);
            }
        }
        assert_eq!(
            minima.len(),
            LEVELS,
            "a reversal per inner grid line, then the bottom"
        );
        for (i, x) in minima.iter().enumerate() {
            let want = if i + 1 == LEVELS {
                -(LEVELS as f32) * FORC_OVERDRIVE
            } else {
                (LEVELS - 1 - i) as f32
            };
            assert!((x - want).abs() < 1e-3, "reversal {i} at {x}, want {want}");
        }
        // Steps never exceed a quarter cell.
        for w in forc.windows(2) {
            assert!(((w[1] - w[0]) * c0 / width).abs() <= 0.25 + 1e-4);
        }
    }

    #[test]
    fn the_sines_follow_their_formula_and_the_total_counts_every_tick() {
        let prog = programme();
        let rate = BAKED_PARAMETERS.control.sample_rate_hz;
        let mut s = prog.start(0.0);
        let mut n = 0u32;
        let mut per_experiment = [0u32; EXPERIMENTS];
        while let Some(t) = prog.step(&mut s) {
            n += 1;
            if let (Some(k), Some(Experiment { kind, .. })) =
                (t.sample, prog.experiment(t.experiment))
            {
                per_experiment[t.experiment] += 1;
                if let ExperimentKind::Sine {
                    frequency_hz,
                    amplitude_a,
                    bias_a,
                } = kind
                {
                    let want = bias_a as f64
                        + amplitude_a as f64
                            * (2.0 * core::f64::consts::PI * frequency_hz as f64 * k as f64
                                / rate as f64)
                                .sin();
                    assert!(
                        (t.current_a as f64 - want).abs() < 2e-6,
                        "{k}: {}",
                        t.current_a
                    );
                }
            }
            assert!(n < 10_000_000, "the programme must end");
        }
        assert!(s.done());
        assert_eq!(n, prog.total_ticks(0.0));
        for (k, &count) in per_experiment.iter().enumerate() {
            assert_eq!(count, prog.experiment(k).unwrap().ticks, "experiment {k}");
        }
        assert!(prog.experiment(EXPERIMENTS).is_none());
    }

    #[test]
    fn a_control_rate_too_low_for_the_sweep_is_rejected() {
        let p = &BAKED_PARAMETERS;
        let limiter = OutputLimiter::new(&p.control).unwrap();
        let e = IdentificationProgramme::new(
            &limiter,
            p.actuator.coil_factor_per_m,
            &BAKED_MEASURE,
            None,
            100.0,
        );
        assert!(
            matches!(e, Err(ProgrammeError::SweepTooFast { .. })),
            "{e:?}"
        );
        let e = IdentificationProgramme::new(&limiter, f32::NAN, &BAKED_MEASURE, None, 1e4);
        assert_eq!(e, Err(ProgrammeError::Invalid("coil_factor_per_m")));
    }
}
