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
//! **Coil heating.** With the parameter file's `coil_thermal` section
//! ([`IdentificationProgramme::with_coil_heat`]) the programme keeps the winding's temperature
//! rise, as [`crate::coil_heat`] estimates it from the commanded currents, at or below
//! `max_rise_k`: before each stretch it could not finish under the limit it pauses, unrecorded,
//! at a current that cools the coil, until the stretch fits. Pauses are taken only where they
//! leave the rod's state as it was: before an experiment's conditioning (which rebuilds the
//! memory), and inside the FORC sweep at the top of a reversal curve — the top is the largest
//! input since the sweep's bottom, so a dip to the pause current (not below the bottom) and back
//! is wiped out on the return (Preisach's wiping-out property, paper Section 2) and the next
//! curve starts from the same memory. The recorded currents are the same bit for bit with and
//! without pauses; the order stays FORC first (the masses are read from the coolest coil). The
//! bound each stretch is checked against, and why a hold ends, are in [`crate::coil_heat`]; a
//! stretch that cannot fit even from a cold coil is refused ([`ProgrammeError::TooHot`]).
//!
//! The same generator feeds both measurement paths: the virtual bench streams it from the host
//! (`cargo xtask hil --measure`) and the firmware plays it itself (NUCLEO measurement image,
//! `firmware-hil mode=measure-local`), so both record the same currents.
//!
//! Cost per tick: a few compares, a multiply-add and (sines) one `sinf` — under 100 instructions
//! beside the conditioning's ~15. No allocation, no panic path.

use crate::coil_heat::{CoilHeat, CoilHeatError, CoilHeatState};
use crate::inverse::{Conditioning, ConditioningError, ConditioningState, OutputLimiter, Sweep};
use crate::params::ActuatorParameters;
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
    /// Invalid thermal constants (see [`CoilHeatError`]).
    CoilHeat(CoilHeatError),
    /// A stretch of experiment `experiment` can heat the coil by up to `heating_k` even from
    /// cold, more than `coil_thermal.max_rise_k` allows (lower the current limit or raise the
    /// limit).
    TooHot {
        /// The experiment.
        experiment: usize,
        /// The stretch's bound, K (with the estimate's lag and the pause's own heating).
        heating_k: f32,
    },
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
    sample_rate_hz: f32,
    cells_per_tick: f32,
    /// Recorded ticks of the FORC sweep (computed once).
    forc_ticks: u32,
    /// Recorded ticks of each sine frequency.
    sine_ticks: [u32; SINE_FREQUENCIES_HZ.len()],
    /// Phase step per tick of each sine frequency, turns × 2³² (exact wrap-around: the phase
    /// error after `n` ticks is at most `n·2⁻³³` turn).
    sine_step_q32: [u32; SINE_FREQUENCIES_HZ.len()],
    /// The coil's heat budget (`None`: no pauses).
    heat: Option<HeatBudget>,
}

/// What the pauses need, computed once by [`IdentificationProgramme::with_coil_heat`].
#[derive(Debug, Clone, Copy, PartialEq)]
struct HeatBudget {
    heat: CoilHeat,
    /// Ramp step into and out of a pause, A per tick (the FORC sweep's speed).
    ramp_step_a: f32,
    /// Current held in a pause inside the FORC sweep, A: 0 A, or the sweep's bottom when that
    /// lies above 0 A (never below the bottom: the dip must be wiped out).
    forc_hold_a: f32,
    /// Bound on what reversal curve `j` (1-based; index `j − 1`) adds, with a ramp up from a
    /// pause before it and down to one after it, K.
    forc_curve_heating_k: [f32; LEVELS],
    /// Bound on what experiment `k`'s conditioning (from any current), its stretch up to its
    /// first pause point (the FORC sweep's first top; a sine's end) and the ramp to a pause
    /// after it add, K.
    experiment_heating_k: [f32; EXPERIMENTS],
}

/// A pause while the coil cools (unrecorded ticks).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Pause {
    /// The current the ramp is at, A.
    current_a: f32,
    /// The current held, A.
    hold_a: f32,
    /// The current to ramp back to (`None`: the next experiment's conditioning follows).
    return_a: Option<f32>,
    /// What the stretch after the pause may add, K: the hold ends when it fits.
    heating_k: f32,
    phase: PausePhase,
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum PausePhase {
    Down,
    Hold,
    Up,
    Done,
}

/// Moves `current_a` towards `target_a` by at most `step_a`; whether it arrived.
fn ramp(current_a: &mut f32, target_a: f32, step_a: f32) -> bool {
    let gap = target_a - *current_a;
    if libm::fabsf(gap) <= step_a {
        *current_a = target_a;
        true
    } else {
        *current_a += if gap > 0.0 { step_a } else { -step_a };
        false
    }
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
    /// The coil's estimated temperature rise (with a heat budget).
    heat: CoilHeatState,
    /// A pause under way.
    pause: Option<Pause>,
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

    /// The coil's estimated temperature rise, K (0 without a heat budget).
    pub fn coil_rise_k(&self) -> f32 {
        self.heat.rise_k()
    }

    /// A state at the start of experiment `experiment`'s recorded ticks.
    fn at(experiment: usize) -> Self {
        ProgrammeState {
            experiment,
            conditioning: None,
            sample: 0,
            segment: 0,
            segment_tick: 0,
            segment_steps: 0,
            last_a: 0.0,
            done: false,
            heat: CoilHeatState::default(),
            pause: None,
        }
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
            sample_rate_hz,
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
            heat: None,
        };
        programme.forc_ticks = 1
            + (1..FORC_WAYPOINTS)
                .map(|i| programme.segment_ticks(i))
                .sum::<u32>();
        Ok(programme)
    }

    /// The programme of a parameter set: its coil factor, grid, reach and rate, and the coil's
    /// heat budget when the set has a `coil_thermal` section ([`Self::with_coil_heat`]).
    pub fn for_parameters(
        limiter: &OutputLimiter,
        p: &ActuatorParameters,
        measure: &PreisachMeasure,
    ) -> Result<Self, ProgrammeError> {
        let programme = Self::new(
            limiter,
            p.actuator.coil_factor_per_m,
            measure,
            p.preisach.reach_a_per_m,
            p.control.sample_rate_hz,
        )?;
        match CoilHeat::from_parameters(p) {
            None => Ok(programme),
            Some(heat) => programme.with_coil_heat(heat.map_err(ProgrammeError::CoilHeat)?),
        }
    }

    /// This programme with pauses that keep the coil's estimated rise at or below `heat`'s limit
    /// (module docs). Refused when a stretch between pause points could exceed it from a cold
    /// coil.
    pub fn with_coil_heat(mut self, heat: CoilHeat) -> Result<Self, ProgrammeError> {
        let clamp = |i: f32| i.max(-self.limit_a).min(self.limit_a);
        let ramp_step_a = self.cells_per_tick * self.cell_width_a_per_m / self.coil_factor_per_m;
        let ramp_ticks = |from_a: f32| libm::ceilf(libm::fabsf(from_a) / ramp_step_a) as u32 + 1;
        let bottom_a = clamp(self.forc_current_a(forc_waypoint(0, self.overdrive)));
        let top_a = clamp(self.forc_current_a(forc_waypoint(1, self.overdrive)));
        let forc_hold_a = 0.0f32.max(bottom_a).min(top_a);
        // A ramp between the top and 0 A, before and after a curve (module docs of `coil_heat`:
        // one term per part).
        let top_ramp_k = heat.ramp_heating_k(top_a, 0.0, ramp_ticks(top_a));
        // What a stretch of experiment `experiment` can reach from a cold coil, with the pause's
        // own heating and the lag; refused at or above the limit.
        let fits_from_cold = |experiment: usize, heating_k: f32, hold_a: f32| {
            let reach_k = heat.lag_margin_k() + heating_k + heat.steady_rise_k(hold_a);
            if reach_k >= heat.max_rise_k() {
                Err(ProgrammeError::TooHot {
                    experiment,
                    heating_k: reach_k,
                })
            } else {
                Ok(())
            }
        };
        let mut forc_curve_heating_k = [0.0f32; LEVELS];
        for (j0, bound) in forc_curve_heating_k.iter_mut().enumerate() {
            let i = 2 * (j0 + 1);
            let line_a = clamp(self.forc_current_a(forc_waypoint(i, self.overdrive)));
            let down_k = heat.ramp_heating_k(top_a, line_a, self.segment_ticks(i));
            let up_k = heat.ramp_heating_k(line_a, top_a, self.segment_ticks(i + 1));
            *bound = 2.0 * top_ramp_k + down_k + up_k;
            fits_from_cold(0, *bound, forc_hold_a)?;
        }
        let mut experiment_heating_k = [0.0f32; EXPERIMENTS];
        for (k, bound) in experiment_heating_k.iter_mut().enumerate() {
            let Some(e) = self.experiment(k) else { break };
            let first = self.first_current_a(k);
            let conditioning_ticks = [-self.limit_a, 0.0, self.limit_a]
                .iter()
                .map(|&from| self.conditioning.ticks(from, first))
                .max()
                .unwrap_or(0);
            // The stretch after the conditioning, and the current it ends on.
            let (head_k, end_a) = match e.kind {
                ExperimentKind::Forc { .. } => (
                    heat.ramp_heating_k(bottom_a, top_a, 1 + self.segment_ticks(1)),
                    top_a,
                ),
                ExperimentKind::Sine {
                    frequency_hz,
                    amplitude_a,
                    bias_a,
                } => {
                    let omega = core::f32::consts::TAU * frequency_hz / self.sample_rate_hz;
                    let peak_a = clamp(libm::fabsf(bias_a) + amplitude_a);
                    (
                        heat.sine_heating_k(bias_a, amplitude_a, omega, e.ticks),
                        peak_a,
                    )
                }
            };
            *bound = heat.heating_k(self.limit_a, conditioning_ticks)
                + head_k
                + heat.ramp_heating_k(end_a, 0.0, ramp_ticks(end_a));
            fits_from_cold(k, *bound, 0.0)?;
        }
        self.heat = Some(HeatBudget {
            heat,
            ramp_step_a,
            forc_hold_a,
            forc_curve_heating_k,
            experiment_heating_k,
        });
        Ok(self)
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
        self.current_a(k, &ProgrammeState::at(k))
            .max(-self.limit_a)
            .min(self.limit_a)
    }

    /// A programme starting from `from_a` on the coil (0 A after power-up).
    pub fn start(&self, from_a: f32) -> ProgrammeState {
        ProgrammeState {
            conditioning: Some(self.conditioning.start(from_a, self.first_current_a(0))),
            last_a: from_a,
            ..ProgrammeState::at(0)
        }
    }

    /// Ticks of the whole programme from `from_a`, conditioning and pauses included (with a
    /// heat budget the pauses are counted by playing the programme: ~100 instructions a tick).
    pub fn total_ticks(&self, from_a: f32) -> u32 {
        if self.heat.is_some() {
            let mut s = self.start(from_a);
            let mut n = 0u32;
            while self.step(&mut s).is_some() {
                n = n.saturating_add(1);
            }
            return n;
        }
        let mut last = from_a;
        let mut n = 0u32;
        for k in 0..EXPERIMENTS {
            let Some(e) = self.experiment(k) else { break };
            let first = self.first_current_a(k);
            n = n
                .saturating_add(self.conditioning.ticks(last, first))
                .saturating_add(e.ticks);
            let end = ProgrammeState {
                sample: e.ticks.saturating_sub(1),
                segment: FORC_WAYPOINTS - 1,
                segment_tick: self.segment_ticks(FORC_WAYPOINTS - 1),
                segment_steps: self.segment_ticks(FORC_WAYPOINTS - 1),
                ..ProgrammeState::at(k)
            };
            last = self.current_a(k, &end).max(-self.limit_a).min(self.limit_a);
        }
        n
    }

    /// The next tick (`None` once the programme has ended; the caller then ramps to 0 A).
    #[inline]
    pub fn step(&self, s: &mut ProgrammeState) -> Option<ProgrammeTick> {
        let tick = self.next_tick(s)?;
        if let Some(b) = &self.heat {
            let applied_a = tick.current_a.max(-self.limit_a).min(self.limit_a);
            b.heat.step(&mut s.heat, applied_a);
        }
        Some(tick)
    }

    /// The next tick of a pause under way (`None`: it has ended; the conditioning it was taken
    /// before has been started).
    fn pause_tick(&self, s: &mut ProgrammeState) -> Option<f32> {
        let (Some(b), Some(p)) = (&self.heat, &mut s.pause) else {
            return None;
        };
        loop {
            match p.phase {
                PausePhase::Down => {
                    if ramp(&mut p.current_a, p.hold_a, b.ramp_step_a) {
                        p.phase = PausePhase::Hold;
                    }
                    return Some(p.current_a);
                }
                PausePhase::Hold => {
                    if !b.heat.fits(&s.heat, p.heating_k) {
                        return Some(p.current_a);
                    }
                    p.phase = if p.return_a.is_some() {
                        PausePhase::Up
                    } else {
                        PausePhase::Done
                    };
                }
                PausePhase::Up => {
                    let target = p.return_a.unwrap_or(p.current_a);
                    if ramp(&mut p.current_a, target, b.ramp_step_a) {
                        p.phase = PausePhase::Done;
                    }
                    return Some(p.current_a);
                }
                PausePhase::Done => {
                    let from_a = p.current_a;
                    let between_experiments = p.return_a.is_none();
                    s.pause = None;
                    s.last_a = from_a;
                    if between_experiments {
                        s.conditioning = Some(
                            self.conditioning
                                .start(from_a, self.first_current_a(s.experiment)),
                        );
                    }
                    return None;
                }
            }
        }
    }

    /// A pause at `hold_a` when a stretch adding `heating_k` would not fit now (module docs).
    fn pause_if_hot(
        &self,
        s: &ProgrammeState,
        heating_k: impl Fn(&HeatBudget) -> f32,
        hold_a: f32,
        return_a: Option<f32>,
    ) -> Option<Pause> {
        let b = self.heat.as_ref()?;
        let heating_k = heating_k(b);
        if b.heat.fits(&s.heat, heating_k) {
            return None;
        }
        Some(Pause {
            current_a: s.last_a,
            hold_a,
            return_a,
            heating_k,
            phase: PausePhase::Down,
        })
    }

    /// The next tick, before the heat estimate accounts for it.
    fn next_tick(&self, s: &mut ProgrammeState) -> Option<ProgrammeTick> {
        if s.done {
            return None;
        }
        if s.pause.is_some() {
            if let Some(current_a) = self.pause_tick(s) {
                s.last_a = current_a;
                return Some(ProgrammeTick {
                    current_a,
                    experiment: s.experiment,
                    sample: None,
                });
            }
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
                    // At the top of a curve (segment `2j` goes down to line `L − j`): a pause
                    // point.
                    if s.segment % 2 == 0 {
                        let j0 = s.segment / 2 - 1;
                        let hold_a = self.heat.as_ref().map_or(0.0, |b| b.forc_hold_a);
                        s.pause = self.pause_if_hot(
                            s,
                            |b| {
                                b.forc_curve_heating_k
                                    .get(j0)
                                    .copied()
                                    .unwrap_or(f32::INFINITY)
                            },
                            hold_a,
                            Some(s.last_a),
                        );
                    }
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
                let k = s.experiment;
                s.pause = self.pause_if_hot(
                    s,
                    |b| {
                        b.experiment_heating_k
                            .get(k)
                            .copied()
                            .unwrap_or(f32::INFINITY)
                    },
                    0.0,
                    None,
                );
                if s.pause.is_none() {
                    s.conditioning = Some(
                        self.conditioning
                            .start(s.last_a, self.first_current_a(s.experiment)),
                    );
                }
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

    /// The baked programme with a heat budget: 1 K/W on the 5.8 Ω coil, `τ`, the limit.
    fn programme_with_heat(
        time_constant_s: f32,
        max_rise_k: f32,
    ) -> Result<IdentificationProgramme, ProgrammeError> {
        let mut p = BAKED_PARAMETERS;
        p.amplifier.coil_resistance_ohm = 5.8;
        p.coil_thermal = Some(crate::params::CoilThermal {
            thermal_resistance_k_per_w: 1.0,
            time_constant_s,
            max_rise_k,
        });
        let limiter = OutputLimiter::new(&p.control).unwrap();
        IdentificationProgramme::for_parameters(&limiter, &p, &BAKED_MEASURE)
    }

    /// Every tick of a programme: `(experiment, recorded tick, current)`, and the state after it.
    fn play(prog: &IdentificationProgramme) -> Vec<(ProgrammeTick, f32)> {
        let mut s = prog.start(0.0);
        let mut out = Vec::new();
        while let Some(t) = prog.step(&mut s) {
            out.push((t, s.coil_rise_k()));
            assert!(out.len() < 10_000_000, "the programme must end");
        }
        out
    }

    #[test]
    fn pauses_keep_the_coil_under_its_limit_and_leave_the_recorded_currents_unchanged() {
        let plain = play(&programme());
        let prog = programme_with_heat(2.0, 6.0).unwrap();
        let paused = play(&prog);
        // The recorded ticks are the same, bit for bit, in the same order.
        let recorded = |ticks: &[(ProgrammeTick, f32)]| -> Vec<(usize, u32, u32)> {
            ticks
                .iter()
                .filter_map(|(t, _)| t.sample.map(|k| (t.experiment, k, t.current_a.to_bits())))
                .collect()
        };
        assert_eq!(recorded(&plain), recorded(&paused));
        assert_eq!(paused.len() as u32, prog.total_ticks(0.0));
        // The heat model, stepped exactly tick by tick in f64 (τ ΔT' = k I² − ΔT, k = 5.8 K/A²):
        // without pauses it goes beyond 10 K; with them it stays at or below.
        let exact_peak = |ticks: &[(ProgrammeTick, f32)]| {
            let decay = (-1.0 / (2.0 * 10_000.0f64)).exp();
            let mut rise = 0.0f64;
            let mut peak = 0.0f64;
            for (t, _) in ticks {
                let i = t.current_a.clamp(-2.0, 2.0) as f64;
                rise = 5.8 * i * i + (rise - 5.8 * i * i) * decay;
                peak = peak.max(rise);
            }
            peak
        };
        let (without, with) = (exact_peak(&plain), exact_peak(&paused));
        std::println!(
            "peak rise without pauses {without:.2} K, with {with:.2} K; {} ticks instead of {}",
            paused.len(),
            plain.len()
        );
        assert!(without > 7.0, "{without}");
        assert!(with <= 6.0, "{with}");
        let estimate_peak = paused.iter().map(|(_, r)| *r).fold(0.0f32, f32::max);
        assert!(estimate_peak <= 6.0, "{estimate_peak}");
        // Pauses inside the FORC sweep never go below its bottom (the dip must be wiped out).
        let forc_bottom = plain
            .iter()
            .filter(|(t, _)| t.experiment == 0 && t.sample.is_some())
            .map(|(t, _)| t.current_a.max(-2.0))
            .fold(f32::INFINITY, f32::min);
        let first_forc = paused
            .iter()
            .position(|(t, _)| t.experiment == 0 && t.sample.is_some())
            .unwrap();
        let last_forc = paused
            .iter()
            .rposition(|(t, _)| t.experiment == 0 && t.sample.is_some())
            .unwrap();
        let inside: Vec<f32> = paused[first_forc..=last_forc]
            .iter()
            .filter(|(t, _)| t.sample.is_none())
            .map(|(t, _)| t.current_a)
            .collect();
        assert!(!inside.is_empty(), "the sweep pauses at least once");
        assert!(inside.iter().all(|&i| i >= forc_bottom - 1e-6));
    }

    #[test]
    fn a_budget_no_stretch_can_meet_is_refused_and_no_section_means_no_pauses() {
        let e = programme_with_heat(2.0, 2.0);
        assert!(
            matches!(e, Err(ProgrammeError::TooHot { experiment: 0, heating_k }) if heating_k > 2.0),
            "{e:?}"
        );
        let e = programme_with_heat(-1.0, 10.0);
        assert_eq!(
            e,
            Err(ProgrammeError::CoilHeat(CoilHeatError(
                "coil_thermal.time_constant_s"
            )))
        );
        let p = &BAKED_PARAMETERS;
        assert!(p.coil_thermal.is_none());
        let limiter = OutputLimiter::new(&p.control).unwrap();
        assert_eq!(
            IdentificationProgramme::for_parameters(&limiter, p, &BAKED_MEASURE),
            Ok(programme())
        );
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
