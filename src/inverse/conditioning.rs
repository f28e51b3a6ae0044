//! Start-up magnetic conditioning: before tracking starts, the coil current is ramped to the
//! negative current limit, held, ramped up to the controller's first current and held again, so
//! that the rod's Preisach memory is the one the controller assumes
//! ([`ControlLoop::initial_preisach`](super::ControlLoop::initial_preisach): negative saturation,
//! then a monotone rise to the first field), whatever history the rod had before power-up.
//!
//! Why it works: the field at `−I_max` is `−c0·I_max`, below the Preisach grid's `h_min` when
//! [`Conditioning::new`] accepts the parameters, so every relay switches down and the memory is
//! wiped (paper Section 4, the wiping-out property); the monotone ramp up then leaves exactly one
//! increasing segment, the staircase the controller starts from. The ramps are slow
//! ([`RAMP_FULL_SCALE_S`] for 0 → I_max, never faster than the slew limit) so the eddy-current
//! lag of (4) leaves the field within a small fraction of `c0·I`, and the holds
//! ([`HOLD_S`]) let the field and the rod settle.
//!
//! Cost per tick: a compare and an add (~15 instructions). Duration at the default parameters
//! (2 A, 10 kHz) from 0 A to a first current of 0.3 A: 20 ms down, 5 ms hold, 23 ms up, 5 ms
//! hold — 535 ticks.

use super::OutputLimiter;

/// Ramp time for a change of the full current limit, s.
pub const RAMP_FULL_SCALE_S: f32 = 0.02;
/// Hold time at negative saturation and at the first current, s.
pub const HOLD_S: f32 = 0.005;

/// Coefficients of the conditioning sequence.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Conditioning {
    low_a: f32,
    step_a: f32,
    hold_ticks: u32,
}

/// Rejected conditioning settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ConditioningError {
    /// The field at the current limit, `c0·I_max` (A/m), does not reach the grid's `|h_min|`:
    /// the rod cannot be saturated, the memory cannot be wiped.
    CannotSaturate {
        /// `c0·I_max`, A/m.
        field_at_limit_a_per_m: f32,
        /// `|h_min|` of the grid, A/m.
        needed_a_per_m: f32,
    },
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Phase {
    HoldStart,
    Down,
    HoldLow,
    Up,
    HoldTarget,
    Done,
}

/// Where a conditioning sequence stands.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ConditioningState {
    phase: Phase,
    current_a: f32,
    target_a: f32,
    ticks_left: u32,
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

    /// The current the sequence commands now, A.
    pub fn current_a(&self) -> f32 {
        self.current_a
    }
}

impl Conditioning {
    /// The sequence for a coil with `coil_factor_per_m` (`c0`), a grid starting at
    /// `h_min_a_per_m`, the output `limiter` and the control rate `sample_rate_hz`.
    pub fn new(
        limiter: &OutputLimiter,
        coil_factor_per_m: f32,
        h_min_a_per_m: f32,
        sample_rate_hz: f32,
    ) -> Result<Self, ConditioningError> {
        let field = coil_factor_per_m * limiter.limit_a();
        let needed = -h_min_a_per_m;
        if field.is_nan() || field < needed {
            return Err(ConditioningError::CannotSaturate {
                field_at_limit_a_per_m: field,
                needed_a_per_m: needed,
            });
        }
        let per_tick = limiter.limit_a() / (RAMP_FULL_SCALE_S * sample_rate_hz);
        let step_a = if per_tick < limiter.max_step_a() {
            per_tick
        } else {
            limiter.max_step_a()
        };
        Ok(Conditioning {
            low_a: -limiter.limit_a(),
            step_a,
            hold_ticks: (HOLD_S * sample_rate_hz) as u32 + 1,
        })
    }

    /// A sequence from the current now on the coil, `from_a`, to the controller's first current
    /// `target_a` (`LoopCore::last_current_a` of a fresh loop state).
    pub fn start(&self, from_a: f32, target_a: f32) -> ConditioningState {
        ConditioningState {
            phase: Phase::HoldStart,
            current_a: if from_a.is_finite() { from_a } else { 0.0 },
            target_a,
            ticks_left: 1,
        }
    }

    /// Ticks the whole sequence takes from `from_a` to `target_a` (for a run's tick budget).
    pub fn ticks(&self, from_a: f32, target_a: f32) -> u32 {
        let mut s = self.start(from_a, target_a);
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
        match s.phase {
            Phase::HoldStart => s.count_down_to(Phase::Down),
            Phase::Down => {
                s.current_a -= self.step_a;
                if s.current_a <= self.low_a {
                    s.current_a = self.low_a;
                    s.phase = Phase::HoldLow;
                    s.ticks_left = self.hold_ticks;
                }
            }
            Phase::HoldLow => s.count_down_to(Phase::Up),
            Phase::Up => {
                s.current_a += self.step_a;
                if s.current_a >= s.target_a {
                    s.current_a = s.target_a;
                    s.phase = Phase::HoldTarget;
                    s.ticks_left = self.hold_ticks;
                }
            }
            Phase::HoldTarget => s.count_down_to(Phase::Done),
            Phase::Done => {}
        }
        s.current_a
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
            BAKED_MEASURE.h_min_a_per_m(),
            p.control.sample_rate_hz,
        )
        .unwrap();
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
        let out = control.condition_sensed(&c, &mut seq, &mut state, Err(SensorFault::Missing));
        assert!(out.flags.has(CommandFlags::SENSOR_FAULT));
        assert!((out.current_a - held).abs() <= limiter.max_step_a() * 1.0001);
        let mut last = out.current_a;
        for _ in 0..10 {
            last = control
                .condition_sensed(&c, &mut seq, &mut state, Ok(20e-6))
                .current_a;
        }
        assert_eq!(last, 0.0);
        // Run to the end on a fresh state: tracking starts from the loop's own first current.
        let mut state: LoopState<64> = control.init(InverseKind::Dynamic);
        let mut seq = c.start(0.0, first);
        while !seq.done() {
            control.condition_sensed(&c, &mut seq, &mut state, Ok(20e-6));
        }
        assert_eq!(state.core.last_current_a, first);
    }

    #[test]
    fn a_coil_that_cannot_saturate_the_rod_is_rejected() {
        let (_, limiter) = baked();
        let e = Conditioning::new(&limiter, 1000.0, -30_000.0, 10_000.0);
        assert_eq!(
            e,
            Err(ConditioningError::CannotSaturate {
                field_at_limit_a_per_m: 2000.0,
                needed_a_per_m: 30_000.0
            })
        );
    }
}
