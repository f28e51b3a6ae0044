//! Start-up magnetic conditioning: before tracking starts, the coil current is ramped through a
//! fixed sequence that leaves the rod's Preisach memory in the state the controller assumes
//! ([`Conditioning::memory`]), whatever history the rod had before power-up.
//!
//! Two sequences, chosen from the parameters ([`Sweep`]):
//!
//! * [`Sweep::Saturate`] — the coil saturates the rod: the field at `−I_max`, `−c0·I_max`, lies at
//!   or below the grid's `h_min`. Ramp to `−I_max`, hold, ramp to the controller's first current,
//!   hold. Every relay switches down at `−I_max` (wiping-out property, paper Section 2), the ramp
//!   up leaves one increasing segment: negative saturation, then a monotone rise.
//! * [`Sweep::Reach`] — the rod's plane is wider than the coil reaches (the file's
//!   `preisach.reach_a_per_m`, or the grid cut to `±c0·I_max`): ramp to the top of the reach
//!   `I_hi`, hold, down to its bottom `I_lo`, hold, to the first current, hold. At `H_hi` every
//!   relay with `α <= H_hi` is up; at `H_lo` every relay with `β >= H_lo` is down. So afterwards
//!   the reachable triangle is down, the one-way band `β < H_lo` (it can only switch up) is up, the
//!   band `α > H_hi` (only down) is down — the same state after any history, except the relays
//!   with `α > H_hi` and `β < H_lo`, which no current switches and whose state is part of the
//!   identified offset `M_off` (docs/model.md, "Rods the coil cannot saturate"). The memory the
//!   controller starts from is [`PreisachMeasure::conditioned`] over that reach.
//!
//! Neither refuses to run: a rod the coil cannot saturate gets the reach sweep.
//!
//! With the feedback on, [`Conditioning::with_retarget`] appends a correction of the first
//! current: one hold while the controller moves its target by the stroke gain measured on the
//! hold ([`super::StrokeGainLaw`]), a ramp there in a fixed [`Conditioning::reramp_ticks`], and
//! another hold; the sequence's length does not depend on the correction.
//!
//! The ramps are slow ([`RAMP_FULL_SCALE_S`] for 0 → I_max, never faster than the slew limit)
//! so the eddy-current lag of (4) leaves the field within a small fraction of `c0·I`, and the
//! holds ([`HOLD_S`]) let the field and the rod settle.
//!
//! Cost per tick: a compare and an add (~15 instructions). Duration at the default parameters
//! (2 A, 10 kHz, saturating) from 0 A to a first current of 0.3 A: 20 ms down, 5 ms hold, 23 ms
//! up, 5 ms hold — 535 ticks; the reach sweep adds one ramp and one hold.

use super::OutputLimiter;
use crate::preisach::{PreisachMeasure, PreisachState};

/// Ramp time for a change of the full current limit, s.
pub const RAMP_FULL_SCALE_S: f32 = 0.02;
/// Hold time at each extreme and at the first current, s.
pub const HOLD_S: f32 = 0.005;

/// Which sequence the parameters call for (module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Sweep {
    /// The coil saturates the rod: down to `−I_max`, then to the first current.
    Saturate {
        /// `−I_max`, A.
        low_a: f32,
    },
    /// The coil sweeps its reach: up to `I_hi`, down to `I_lo`, then to the first current.
    Reach {
        /// `I_lo`, A.
        low_a: f32,
        /// `I_hi`, A.
        high_a: f32,
    },
}

/// Coefficients of the conditioning sequence.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Conditioning {
    sweep: Sweep,
    coil_factor_per_m: f32,
    limit_a: f32,
    step_a: f32,
    hold_ticks: u32,
}

/// Rejected conditioning settings (a non-finite or non-positive coil factor or rate, or a reach
/// that is not an increasing pair of finite fields).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ConditioningError {
    /// The coil factor `c0` is not a finite number > 0.
    CoilFactor,
    /// The control rate is not a finite number > 0.
    SampleRate,
    /// The reach is not `H_lo < H_hi`, both finite.
    Reach,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Phase {
    HoldStart,
    UpToHigh,
    HoldHigh,
    Down,
    HoldLow,
    ToTarget,
    HoldTarget,
    Retarget,
    Reramp,
    Done,
}

/// Where a conditioning sequence stands.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ConditioningState {
    phase: Phase,
    current_a: f32,
    target_a: f32,
    ticks_left: u32,
    /// After the first hold at the target the sequence waits for a corrected target
    /// ([`ConditioningState::retarget`]) and goes there; set once that has happened.
    retarget: RetargetStep,
    /// Step of the ramp to the corrected target, A per tick.
    reramp_step_a: f32,
}

/// Whether the sequence goes to a corrected first current after its first hold there.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum RetargetStep {
    /// No: the first hold ends the sequence.
    Never,
    /// Yes, not yet done.
    Pending,
    /// Done: the next hold at the target ends the sequence.
    Done,
}

impl ConditioningState {
    /// One tick of a hold: moves on to `next` when the hold has run out.
    #[inline(always)]
    fn count_down_to(&mut self, next: Phase) {
        self.ticks_left = self.ticks_left.saturating_sub(1);
        if self.ticks_left == 0 {
            self.phase = next;
        }
    }

    /// Whether the sequence has ended (tracking may start).
    pub fn done(&self) -> bool {
        self.phase == Phase::Done
    }

    /// Whether the sequence is in the second half of its last hold, at the controller's first
    /// current: the rod has come to rest there (the stroke gain's first samples,
    /// [`super::StrokeGainLaw::observe_at_rest`]).
    pub fn at_rest_on_first_current(&self, hold_ticks: u32) -> bool {
        self.phase == Phase::HoldTarget && self.ticks_left <= hold_ticks / 2
    }

    /// Whether the sequence waits for a corrected first current ([`Conditioning::with_retarget`])
    /// and has not been given one yet.
    pub fn retargeting(&self) -> bool {
        self.phase == Phase::Retarget && self.retarget == RetargetStep::Pending
    }

    /// Sets the corrected first current `target_a` (A) while [`ConditioningState::retargeting`]
    /// (the field the controller's memory has reached; `arrived`: it is the final one, stop
    /// asking). When the wait ends the sequence ramps there and holds, then ends.
    pub fn retarget(&mut self, target_a: f32, arrived: bool) {
        if self.phase == Phase::Retarget && target_a.is_finite() {
            self.target_a = target_a;
            if arrived {
                self.retarget = RetargetStep::Done;
            }
        }
    }

    /// The current the sequence commands now, A.
    pub fn current_a(&self) -> f32 {
        self.current_a
    }
}

impl Conditioning {
    /// The sequence for a coil with `coil_factor_per_m` (`c0`) on the grid `[h_min, h_max]` of
    /// `measure`, with the rod's `reach` (`[H_lo, H_hi]`, A/m; `None`: the grid), the output
    /// `limiter` and the control rate `sample_rate_hz`.
    ///
    /// [`Sweep::Saturate`] when no reach is given and `−c0·I_max <= h_min`; otherwise
    /// [`Sweep::Reach`] over the reach cut to `±c0·I_max`.
    pub fn new(
        limiter: &OutputLimiter,
        coil_factor_per_m: f32,
        measure: &PreisachMeasure,
        reach_a_per_m: Option<[f32; 2]>,
        sample_rate_hz: f32,
    ) -> Result<Self, ConditioningError> {
        if !(coil_factor_per_m.is_finite() && coil_factor_per_m > 0.0) {
            return Err(ConditioningError::CoilFactor);
        }
        if !(sample_rate_hz.is_finite() && sample_rate_hz > 0.0) {
            return Err(ConditioningError::SampleRate);
        }
        let limit_a = limiter.limit_a();
        let field_at_limit = coil_factor_per_m * limit_a;
        let sweep = match reach_a_per_m {
            None if -field_at_limit <= measure.h_min_a_per_m() => {
                Sweep::Saturate { low_a: -limit_a }
            }
            reach => {
                let [lo, hi] = reach.unwrap_or([measure.h_min_a_per_m(), measure.h_max_a_per_m()]);
                if !(lo.is_finite() && hi.is_finite() && lo < hi) {
                    return Err(ConditioningError::Reach);
                }
                let clamp = |i: f32| i.max(-limit_a).min(limit_a);
                Sweep::Reach {
                    low_a: clamp(lo / coil_factor_per_m),
                    high_a: clamp(hi / coil_factor_per_m),
                }
            }
        };
        let per_tick = limit_a / (RAMP_FULL_SCALE_S * sample_rate_hz);
        let step_a = if per_tick < limiter.max_step_a() {
            per_tick
        } else {
            limiter.max_step_a()
        };
        Ok(Conditioning {
            sweep,
            coil_factor_per_m,
            limit_a,
            step_a,
            hold_ticks: (HOLD_S * sample_rate_hz) as u32 + 1,
        })
    }

    /// Ticks of each hold.
    pub fn hold_ticks(&self) -> u32 {
        self.hold_ticks
    }

    /// The sequence the parameters called for.
    pub fn sweep(&self) -> Sweep {
        self.sweep
    }

    /// The Preisach memory the sequence leaves before its last ramp (to the controller's first
    /// current): negative saturation, or [`PreisachMeasure::conditioned`] over the fields
    /// `c0·I_lo`, `c0·I_hi` of the reach sweep.
    pub fn memory<const N: usize>(&self, measure: &PreisachMeasure) -> PreisachState<N> {
        match self.sweep {
            Sweep::Saturate { .. } => measure.negative_saturation(),
            Sweep::Reach { low_a, high_a } => measure.conditioned(
                low_a * self.coil_factor_per_m,
                high_a * self.coil_factor_per_m,
            ),
        }
    }

    /// A sequence from the current now on the coil, `from_a`, to the controller's first current
    /// `target_a` (`LoopCore::last_current_a` of a fresh loop state).
    pub fn start(&self, from_a: f32, target_a: f32) -> ConditioningState {
        ConditioningState {
            phase: Phase::HoldStart,
            current_a: if from_a.is_finite() { from_a } else { 0.0 },
            target_a,
            ticks_left: 1,
            retarget: RetargetStep::Never,
            reramp_step_a: 0.0,
        }
    }

    /// A sequence like [`Conditioning::start`] that, after its hold at `target_a`, waits one hold
    /// for a corrected first current ([`ConditioningState::retarget`]; without one it keeps
    /// `target_a`), ramps to it in a fixed [`Conditioning::reramp_ticks`] (never faster than the
    /// sequence's own ramps, whatever the correction, so the length of the sequence does not
    /// depend on it) and holds again.
    pub fn with_retarget(&self, from_a: f32, target_a: f32) -> ConditioningState {
        ConditioningState {
            retarget: RetargetStep::Pending,
            ..self.start(from_a, target_a)
        }
    }

    /// Ticks of the ramp to a corrected first current: the time to cross twice the current limit
    /// at the sequence's ramp rate.
    pub fn reramp_ticks(&self) -> u32 {
        (2.0 * self.limit_a / self.step_a) as u32 + 1
    }

    /// Ticks the whole sequence takes from `from_a` to `target_a` (for a run's tick budget).
    pub fn ticks(&self, from_a: f32, target_a: f32) -> u32 {
        self.remaining_ticks(&self.start(from_a, target_a))
    }

    /// Ticks the sequence `s` still takes (the same whatever target a retarget sets).
    pub fn remaining_ticks(&self, s: &ConditioningState) -> u32 {
        let mut s = *s;
        let mut n = 0u32;
        while !s.done() && n < u32::MAX {
            self.step(&mut s);
            n += 1;
        }
        n
    }

    /// The current of the next tick, A; after the sequence ends it keeps returning the target.
    #[inline]
    pub fn step(&self, s: &mut ConditioningState) -> f32 {
        let (low_a, high_a) = match self.sweep {
            Sweep::Saturate { low_a } => (low_a, None),
            Sweep::Reach { low_a, high_a } => (low_a, Some(high_a)),
        };
        match s.phase {
            Phase::HoldStart => s.count_down_to(if high_a.is_some() {
                Phase::UpToHigh
            } else {
                Phase::Down
            }),
            Phase::UpToHigh => {
                let high = high_a.unwrap_or(s.current_a);
                if self.ramp(&mut s.current_a, high) {
                    s.phase = Phase::HoldHigh;
                    s.ticks_left = self.hold_ticks;
                }
            }
            Phase::HoldHigh => s.count_down_to(Phase::Down),
            Phase::Down => {
                if self.ramp(&mut s.current_a, low_a) {
                    s.phase = Phase::HoldLow;
                    s.ticks_left = self.hold_ticks;
                }
            }
            Phase::HoldLow => s.count_down_to(Phase::ToTarget),
            Phase::ToTarget => {
                if self.ramp(&mut s.current_a, s.target_a) {
                    s.phase = Phase::HoldTarget;
                    s.ticks_left = self.hold_ticks;
                }
            }
            Phase::HoldTarget => {
                if s.retarget == RetargetStep::Pending {
                    s.count_down_to(Phase::Retarget);
                    if s.phase == Phase::Retarget {
                        s.ticks_left = self.hold_ticks;
                    }
                } else {
                    s.count_down_to(Phase::Done);
                }
            }
            Phase::Retarget => {
                s.count_down_to(Phase::Reramp);
                if s.phase == Phase::Reramp {
                    s.retarget = RetargetStep::Done;
                    s.ticks_left = self.reramp_ticks();
                    s.reramp_step_a = (s.target_a - s.current_a) / s.ticks_left as f32;
                }
            }
            Phase::Reramp => {
                s.current_a += s.reramp_step_a;
                s.count_down_to(Phase::HoldTarget);
                if s.phase == Phase::HoldTarget {
                    s.current_a = s.target_a;
                    s.ticks_left = self.hold_ticks;
                }
            }
            Phase::Done => {}
        }
        s.current_a
    }

    /// One ramp step of `current_a` toward `goal_a`; `true` once it is there. A NaN goal ends
    /// the ramp where it stands.
    #[inline(always)]
    fn ramp(&self, current_a: &mut f32, goal_a: f32) -> bool {
        if goal_a.is_nan() {
            return true;
        }
        if *current_a < goal_a {
            *current_a += self.step_a;
            if *current_a >= goal_a {
                *current_a = goal_a;
                return true;
            }
        } else {
            *current_a -= self.step_a;
            if *current_a <= goal_a {
                *current_a = goal_a;
                return true;
            }
        }
        false
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::params::{BAKED_MEASURE, BAKED_PARAMETERS};

    fn baked() -> (Conditioning, OutputLimiter) {
        let p = &BAKED_PARAMETERS;
        let limiter = OutputLimiter::new(&p.control).unwrap();
        let c = Conditioning::new(
            &limiter,
            p.actuator.coil_factor_per_m,
            &BAKED_MEASURE,
            p.preisach.reach_a_per_m,
            p.control.sample_rate_hz,
        )
        .unwrap();
        assert!(matches!(c.sweep(), Sweep::Saturate { .. }));
        (c, limiter)
    }

    #[test]
    fn the_sequence_saturates_then_rises_monotonically_within_the_limits() {
        let (c, limiter) = baked();
        for (from, target) in [(0.0f32, 0.3f32), (1.5, 0.3), (-0.7, 1.1), (f32::NAN, 0.2)] {
            let mut s = c.start(from, target);
            let mut last = s.current_a();
            let mut reached_low = false;
            let mut n = 0;
            while !s.done() {
                let i = c.step(&mut s);
                assert!(i.abs() <= limiter.limit_a() + 1e-6, "{i}");
                assert!(
                    (i - last).abs() <= limiter.max_step_a() * 1.0001,
                    "{last} -> {i}"
                );
                if reached_low {
                    assert!(i >= last, "not monotone after saturation: {last} -> {i}");
                }
                reached_low |= i == -limiter.limit_a();
                last = i;
                n += 1;
                assert!(n < 100_000);
            }
            assert!(reached_low);
            assert_eq!(last, target);
            assert_eq!(c.ticks(from, target), n);
        }
        // 0 → −2 A in 20 ms, 5 ms hold, −2 → 0.3 A in 23 ms, 5 ms hold at 10 kHz (+1 start tick).
        let n = c.ticks(0.0, 0.3);
        assert!((525..=545).contains(&n), "{n}");
    }

    #[test]
    fn conditioning_ticks_tolerate_a_saturated_sensor_but_latch_real_faults() {
        use crate::inverse::{CommandFlags, ControlLoop, InverseKind, LoopState};
        use crate::sensor::SensorFault;
        let (c, limiter) = baked();
        let control = ControlLoop::new(&BAKED_MEASURE, &BAKED_PARAMETERS).unwrap();
        let mut state: LoopState<64> = control.init(InverseKind::Dynamic);
        let first = state.core.last_current_a;
        let mut seq = c.start(0.0, first);
        // A reading beyond the valid range (the rod at full stroke) is expected while saturating.
        for _ in 0..300 {
            let out = control.condition_sensed(
                InverseKind::Dynamic,
                &c,
                &mut seq,
                &mut state,
                Err(SensorFault::OutOfValidRange),
            );
            assert_eq!(out.flags.0, CommandFlags::CONDITIONING);
        }
        assert!(state.core.sensor_fault.is_none());
        let held = state.core.last_current_a;
        assert!(held < 0.0, "{held}");
        // A missing sample latches the fault: the coil ramps to 0 A at the slew limit.
        let out = control.condition_sensed(
            InverseKind::Dynamic,
            &c,
            &mut seq,
            &mut state,
            Err(SensorFault::Missing),
        );
        assert!(out.flags.has(CommandFlags::SENSOR_FAULT));
        assert!((out.current_a - held).abs() <= limiter.max_step_a() * 1.0001);
        let mut last = out.current_a;
        for _ in 0..10 {
            last = control
                .condition_sensed(InverseKind::Dynamic, &c, &mut seq, &mut state, Ok(20e-6))
                .current_a;
        }
        assert_eq!(last, 0.0);
        // Run to the end on a fresh state: tracking starts from the loop's own first current.
        let mut state: LoopState<64> = control.init(InverseKind::Dynamic);
        let mut seq = c.start(0.0, first);
        while !seq.done() {
            control.condition_sensed(InverseKind::Dynamic, &c, &mut seq, &mut state, Ok(20e-6));
        }
        assert_eq!(state.core.last_current_a, first);
    }

    #[test]
    fn a_coil_that_cannot_saturate_the_rod_sweeps_its_reach_and_leaves_a_known_memory() {
        let (_, limiter) = baked();
        let m = &BAKED_MEASURE;
        // c0 = 1000 /m: 2 kA/m at 2 A, far inside the ±30 kA/m grid.
        let c = Conditioning::new(&limiter, 1000.0, m, None, 10_000.0).unwrap();
        assert_eq!(
            c.sweep(),
            Sweep::Reach {
                low_a: -2.0,
                high_a: 2.0
            }
        );
        // Up first, then down, then to the target: within the limits, at most one step a tick.
        let mut s = c.start(0.0, 0.5);
        let (mut last, mut peak, mut trough) = (0.0f32, 0.0f32, 0.0f32);
        let mut went_down_after_peak = false;
        while !s.done() {
            let i = c.step(&mut s);
            assert!(i.abs() <= limiter.limit_a() + 1e-6);
            assert!((i - last).abs() <= limiter.max_step_a() * 1.0001);
            if peak == 2.0 && i < last {
                went_down_after_peak = true;
            }
            peak = peak.max(i);
            trough = trough.min(i);
            last = i;
        }
        assert_eq!((peak, trough, last), (2.0, -2.0, 0.5));
        assert!(went_down_after_peak);
        // Whatever the history, the sweep leaves the memory `memory` describes, up to the cells
        // with α beyond the reach's top and β below its bottom, which no current switches.
        let expected: PreisachState<64> = c.memory(m);
        for history in [&[0.3f32, -0.8, 0.1][..], &[-1.0, 1.0, -0.2, 0.4], &[]] {
            let mut state = m.demagnetized::<64>();
            for &h in history {
                m.apply(&mut state, h * 30_000.0).unwrap();
            }
            m.apply(&mut state, 2000.0).unwrap();
            m.apply(&mut state, -2000.0).unwrap();
            let (a, b) = (m.output_a_per_m(&state), m.output_a_per_m(&expected));
            // Only the cells with α > 2 kA/m and β < −2 kA/m remember the history.
            let untouched: f32 = (0..25)
                .flat_map(|i| (i..25).map(move |j| (i, j)))
                .filter(|&(i, j)| i < 12 && j > 12)
                .map(|(i, j)| m.cell_mass_a_per_m(i, j))
                .sum();
            assert!((a - b).abs() <= 2.0 * untouched + 1.0, "{a} vs {b}");
        }
    }

    #[test]
    fn a_given_reach_is_swept_even_when_the_coil_could_saturate_the_grid() {
        let (_, limiter) = baked();
        let m = &BAKED_MEASURE;
        let c = Conditioning::new(&limiter, 15_400.0, m, Some([0.0, 21_560.0]), 10_000.0).unwrap();
        assert_eq!(
            c.sweep(),
            Sweep::Reach {
                low_a: 0.0,
                high_a: 1.4
            }
        );
        assert_eq!(
            Conditioning::new(&limiter, 15_400.0, m, Some([1.0, 1.0]), 10_000.0),
            Err(ConditioningError::Reach)
        );
        assert_eq!(
            Conditioning::new(&limiter, f32::NAN, m, None, 10_000.0),
            Err(ConditioningError::CoilFactor)
        );
    }
}
