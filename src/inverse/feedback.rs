//! Displacement feedback around the inverse: the correction the control interrupt adds to the
//! desired motion before the inverse computes the current.
//!
//! # Why through the inverse
//!
//! The dynamic inverse ([`super::DynamicInverse`]) maps a desired motion `(ȳ, ẏ, ÿ)` to the
//! current that puts the *model* on it one period later. A correction `δ(t)` added to the desired
//! motion *with its derivatives* therefore reaches the plant through the inverse and the plant:
//! where the model is right that path is the identity (one period ahead), whatever the bias
//! point, the hysteresis branch or the `M²` nonlinearity, so the feedback only has to correct the
//! model's error, with a loop gain near 1 everywhere. A PI on the current instead (no inverse in
//! the loop) would see the actuator's `dy/dI`, which varies about tenfold over the band and with
//! the hysteresis branch, and the lag of the magnetoelastic stage (f0 = 392 Hz, ξ = 0.78 on the
//! default actuator, right among the trajectory's harmonics).
//!
//! # Structures ([`FeedbackStructure`])
//!
//! * `Integral`: a PI on the displacement error acting on `ȳ` only (the derivatives of a noisy
//!   error are not usable): `δ = K_p e_k + K_i h Σ e`. The correction then passes through the
//!   magnetoelastic stage's low-pass, which keeps its useful bandwidth well below the trajectory's
//!   fundamental (≈ 94 Hz); it removes offsets and slow drift only.
//! * `Repetitive`: the trajectory is periodic (the Van der Pol limit cycle), and so is the error a
//!   wrong model leaves. The correction is a Fourier series over the cycle's phase `φ`,
//!   `c(φ) = Σ_{n=1..N} a_n cos nφ + b_n sin nφ` (plus a constant `a_0`), learned cycle to cycle
//!   (batch iterative learning control / repetitive control in the harmonic domain):
//!
//!   ```text
//!   a_n ← (1 − λ) a_n + γ · (2/T_steps) Σ_k e_k cos n(φ_k − Ω d)      at the end of each cycle
//!   b_n ← (1 − λ) b_n + γ · (2/T_steps) Σ_k e_k sin n(φ_k − Ω d)      (a_0 with 1/T_steps)
//!   ```
//!
//!   `e_k` the error of the sample at `t_k`, whose displacement is that of `t_k − d` (`d` the
//!   sensor's `sample_delay_s`), `γ` the fraction of each harmonic's error corrected per cycle,
//!   `λ` a leak. The correction is applied with its exact derivatives,
//!   `δ̇ = Ω Σ n (b_n cos nφ − a_n sin nφ)`, `δ̈ = −Ω² Σ n² (a_n cos nφ + b_n sin nφ)`
//!   (`Ω = 2π/T`): no differentiation of measured data.
//!
//!   **Convergence** (the lifted-system argument of ILC, per harmonic): with `P_n` the true
//!   response of the loop "correction → displacement" at harmonic `n`, relative to the model's
//!   (1 where the model is right), the harmonic's error shrinks per cycle by the factor
//!   `|1 − γ P_n| + λ`; it converges while `|1 − γ P_n| < 1 − λ`: a gain error of the model up to
//!   `(2 − λ)/γ − 1` (300 % at γ = 0.5), a phase error up to ±90° (less as `γ |P_n|` grows).
//!   Harmonics above `N` are not learned at all — the Q-filter of ILC, with a sharp edge — so an
//!   unmodelled resonance above `N Ω` cannot be excited by the learning. The margins measured on
//!   the robustness matrix are in BENCHMARKS.md (`maglab robustness --gain-scale`).
//!
//!   Updating once per cycle keeps the correction fixed within a cycle: the loop never reacts
//!   within the cycle to its own learning (which, through the derivative terms, would close a fast
//!   inner loop).
//!
//! # Phase
//!
//! `(cos φ, sin φ)` advance by a rotation of `2π/T_steps` per tick (`T_steps` the period in ticks
//! measured by [`crate::trajectory::VanDerPol::period_steps`]) and are re-synchronised at every
//! upward zero crossing of the oscillator's `x` (linear interpolation between the ticks), so the
//! phase never drifts, however long the run. The harmonics come from the recurrence
//! `e^{inφ} = e^{i(n−1)φ} e^{iφ}`.
//!
//! # Limits and anti-windup
//!
//! The correction `δ` (learned plus PI) is clamped to `±correction_limit_m`, and so is the
//! integrator; a tick whose previous command was current- or `u`-limited (the plant did not get
//! what was asked) neither learns nor integrates, so no state winds up under the output limits.
//!
//! # Sensor faults
//!
//! A sample that is missing, non-finite, out of range, or **stuck** (bit-identical for
//! `stuck_sensor_ticks` ticks, the desired displacement having meanwhile moved more than a tenth
//! of the trajectory's band: [`FeedbackLaw::with_stuck_motion`]) switches the loop back to pure
//! feedforward for good ([`FeedbackState::fell_back`]): the correction is dropped (ramped out by
//! the slew limiter) and every later command is flagged `SENSOR_FAULT | FEEDFORWARD`.
//!
//! # Cost
//!
//! Per tick: the phase rotation, `N` harmonic recurrences, the series and its two derivatives, and
//! `2N` projections of the error; once per cycle the coefficient update. The handler's total is
//! measured under QEMU (BENCHMARKS.md).

use crate::params::{Feedback, FeedbackStructure};
use crate::trajectory::DesiredMotion;

/// Most harmonics the learning can hold.
pub const MAX_HARMONICS: usize = 16;
/// Shortest trajectory period the phase rotation accepts, ticks (the re-synchronisation's series
/// for `cos`, `sin` is accurate to 1e-7 up to a step of 2π/16 rad).
pub const MIN_PERIOD_STEPS: f32 = 16.0;

/// Rejected feedback settings (field named as in the parameter file).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FeedbackError {
    /// The field.
    pub field: &'static str,
    /// The rejected value.
    pub value: f32,
}

/// Coefficients of the feedback (`&self`; the learned series and counters are in
/// [`FeedbackState`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FeedbackLaw {
    structure: FeedbackStructure,
    harmonics: usize,
    /// Phase step per tick, rad, and its cosine and sine.
    step_rad: f32,
    step_cos: f32,
    step_sin: f32,
    /// Ω = 2π/T, rad/s.
    omega_rad_per_s: f32,
    /// γ · 2/T_steps.
    learn_per_sum: f32,
    /// 1 − λ.
    keep_per_cycle: f32,
    /// cos n(Δ + Ωd), sin n(Δ + Ωd): each error is summed with the harmonics of the target
    /// after its sample, one step `Δ` ahead of the sample's time, whose displacement is that of
    /// `d` earlier still; the sums are rotated back by this angle when they are applied.
    back_cos: [f32; MAX_HARMONICS],
    back_sin: [f32; MAX_HARMONICS],
    delay_s: f32,
    proportional_gain: f32,
    /// K_i · h.
    integral_per_tick: f32,
    limit_m: f32,
    stuck_ticks: u32,
    /// How far the desired displacement must have moved since the sample last changed for an
    /// unchanged sample to count as stuck, m.
    stuck_motion_m: f32,
}

/// The feedback's state (lives in the loop state).
#[derive(Debug, Clone, PartialEq)]
pub struct FeedbackState {
    /// Learned cosine coefficients `a_1..a_N`, m.
    pub cos_m: [f32; MAX_HARMONICS],
    /// Learned sine coefficients `b_1..b_N`, m.
    pub sin_m: [f32; MAX_HARMONICS],
    /// Learned constant `a_0`, m.
    pub mean_m: f32,
    /// The sums `Σ e cos nφ`, `Σ e sin nφ`, `Σ e` (m) of two cycles: the one being summed
    /// (`bank`) and the last complete one, applied one coefficient per tick after the cycle's end
    /// (so no tick pays for the whole update).
    sum_cos: [[f32; MAX_HARMONICS]; 2],
    sum_sin: [[f32; MAX_HARMONICS]; 2],
    sum_mean: [f32; 2],
    bank: usize,
    /// Next coefficient of the complete bank to apply (0: the constant, n: harmonic n; past N:
    /// nothing pending).
    pending: usize,
    /// The error the next [`FeedbackLaw::correct`] adds to the sums (0 when it must not learn).
    learn_error_m: f32,
    /// `cos φ`, `sin φ` at the last target.
    phase_cos: f32,
    phase_sin: f32,
    /// A zero crossing has been seen (the sums cover a whole cycle from the next one on).
    synchronised: bool,
    /// Oscillator `x` at the last target (zero-crossing detection).
    last_x: f32,
    /// PI integrator, m.
    pub integral_m: f32,
    /// Bits of the last sample.
    last_sample_bits: u32,
    /// The desired displacement when the sample last changed, m.
    desired_at_change_m: f32,
    /// Ticks in a row with an identical sample.
    pub same_sample_ticks: u32,
    /// The loop fell back to feedforward (a sensor fault); permanent until re-initialized.
    pub fell_back: bool,
    /// Error at the last sample, m (NaN before the first).
    pub last_error_m: f32,
    /// Completed learning cycles.
    pub cycles: u32,
}

/// `cos x`, `sin x` for `|x| <= 2π/16` by their series to `x⁹` (error below 1e-9 there, far
/// below f32 resolution).
#[inline(always)]
fn cos_sin_small(x: f32) -> (f32, f32) {
    let x2 = x * x;
    let c = 1.0 - x2 / 2.0 * (1.0 - x2 / 12.0 * (1.0 - x2 / 30.0 * (1.0 - x2 / 56.0)));
    let s = x * (1.0 - x2 / 6.0 * (1.0 - x2 / 20.0 * (1.0 - x2 / 42.0 * (1.0 - x2 / 72.0))));
    (c, s)
}

impl FeedbackLaw {
    /// Coefficients for the settings at the control rate, for a periodic trajectory of
    /// `period_steps` ticks; `sample_delay_s` is the sensor's (from the `sensor` section).
    pub fn new(
        settings: &Feedback,
        sample_rate_hz: f32,
        period_steps: f32,
        sample_delay_s: f32,
    ) -> Result<Self, FeedbackError> {
        let check = |ok: bool, field: &'static str, value: f32| {
            if ok {
                Ok(())
            } else {
                Err(FeedbackError { field, value })
            }
        };
        let s = settings;
        check(
            s.learning_gain.is_finite() && s.learning_gain >= 0.0 && s.learning_gain <= 2.0,
            "control.feedback.learning_gain",
            s.learning_gain,
        )?;
        check(
            s.learning_harmonics >= 1 && s.learning_harmonics as usize <= MAX_HARMONICS,
            "control.feedback.learning_harmonics",
            s.learning_harmonics as f32,
        )?;
        check(
            s.learning_leak_per_cycle.is_finite()
                && s.learning_leak_per_cycle >= 0.0
                && s.learning_leak_per_cycle < 1.0,
            "control.feedback.learning_leak_per_cycle",
            s.learning_leak_per_cycle,
        )?;
        check(
            s.proportional_gain.is_finite()
                && s.proportional_gain >= 0.0
                && s.proportional_gain < 1.0,
            "control.feedback.proportional_gain",
            s.proportional_gain,
        )?;
        check(
            s.integral_gain_per_s.is_finite()
                && s.integral_gain_per_s >= 0.0
                && s.integral_gain_per_s * 2.0 <= sample_rate_hz,
            "control.feedback.integral_gain_per_s",
            s.integral_gain_per_s,
        )?;
        check(
            s.correction_limit_m.is_finite() && s.correction_limit_m > 0.0,
            "control.feedback.correction_limit_m",
            s.correction_limit_m,
        )?;
        check(
            s.stuck_sensor_ticks >= 2,
            "control.feedback.stuck_sensor_ticks",
            s.stuck_sensor_ticks as f32,
        )?;
        check(
            period_steps.is_finite() && period_steps >= MIN_PERIOD_STEPS,
            "trajectory.frequency_scale_hz",
            period_steps,
        )?;
        check(
            sample_delay_s.is_finite() && sample_delay_s >= 0.0,
            "sensor.sample_delay_s",
            sample_delay_s,
        )?;
        let step_rad = 2.0 * core::f32::consts::PI / period_steps;
        let (step_cos, step_sin) = cos_sin_small(step_rad);
        let omega = step_rad * sample_rate_hz;
        let mut back_cos = [0.0; MAX_HARMONICS];
        let mut back_sin = [0.0; MAX_HARMONICS];
        for (n, (c, s)) in back_cos.iter_mut().zip(back_sin.iter_mut()).enumerate() {
            let angle = (n + 1) as f32 * (step_rad + omega * sample_delay_s);
            *c = libm::cosf(angle);
            *s = libm::sinf(angle);
        }
        Ok(FeedbackLaw {
            structure: s.structure,
            harmonics: s.learning_harmonics as usize,
            step_rad,
            step_cos,
            step_sin,
            omega_rad_per_s: omega,
            learn_per_sum: s.learning_gain * 2.0 / period_steps,
            keep_per_cycle: 1.0 - s.learning_leak_per_cycle,
            back_cos,
            back_sin,
            delay_s: sample_delay_s,
            proportional_gain: s.proportional_gain,
            integral_per_tick: s.integral_gain_per_s / sample_rate_hz,
            limit_m: s.correction_limit_m,
            stuck_ticks: s.stuck_sensor_ticks,
            stuck_motion_m: 0.0,
        })
    }

    /// The structure.
    pub fn structure(&self) -> FeedbackStructure {
        self.structure
    }

    /// The same law, with a sample counted as stuck only once the desired displacement has moved
    /// more than `motion_m` since the sample last changed (a slow trajectory can legitimately
    /// dwell within one ADC count for many ticks at its extremes). `ControlLoop::new` sets a tenth
    /// of the trajectory's band.
    pub fn with_stuck_motion(self, motion_m: f32) -> Self {
        FeedbackLaw {
            stuck_motion_m: if motion_m > 0.0 { motion_m } else { 0.0 },
            ..self
        }
    }

    /// The same coefficients with the feedback off (feedforward only).
    pub fn off(&self) -> Self {
        FeedbackLaw {
            structure: FeedbackStructure::Off,
            ..*self
        }
    }

    /// Whether any feedback runs.
    #[inline(always)]
    pub fn enabled(&self) -> bool {
        self.structure != FeedbackStructure::Off
    }

    /// The initial state for a trajectory whose first target lies `start_phase_cycles` after an
    /// upward zero crossing, at oscillator coordinate `x0`.
    pub fn init(&self, start_phase_cycles: f32, x0: f32) -> FeedbackState {
        let angle = 2.0 * core::f32::consts::PI * start_phase_cycles;
        FeedbackState {
            cos_m: [0.0; MAX_HARMONICS],
            sin_m: [0.0; MAX_HARMONICS],
            mean_m: 0.0,
            sum_cos: [[0.0; MAX_HARMONICS]; 2],
            sum_sin: [[0.0; MAX_HARMONICS]; 2],
            sum_mean: [0.0; 2],
            bank: 0,
            pending: MAX_HARMONICS + 1,
            learn_error_m: 0.0,
            phase_cos: libm::cosf(angle),
            phase_sin: libm::sinf(angle),
            synchronised: false,
            last_x: x0,
            integral_m: 0.0,
            last_sample_bits: 0,
            desired_at_change_m: f32::NAN,
            same_sample_ticks: 0,
            fell_back: false,
            last_error_m: f32::NAN,
            cycles: 0,
        }
    }

    /// Takes the sample of tick `k` against the desired motion at `t_k` and adds its error to
    /// this cycle's sums. Returns `false` when the sample is stuck (the caller latches the fault
    /// and the loop falls back to feedforward). `limited` says the previous command was current-
    /// or `u`-limited (no learning, no integration: anti-windup).
    #[inline]
    pub fn observe(
        &self,
        state: &mut FeedbackState,
        sample_bits: u32,
        measured_m: f32,
        desired_now: &DesiredMotion,
        limited: bool,
    ) -> bool {
        if state.fell_back {
            return false;
        }
        if sample_bits == state.last_sample_bits {
            state.same_sample_ticks = state.same_sample_ticks.saturating_add(1);
            let moved = libm::fabsf(desired_now.displacement_m - state.desired_at_change_m);
            // (NaN before the first change: `moved > x` is false, nothing is stuck yet.)
            if state.same_sample_ticks >= self.stuck_ticks && moved > self.stuck_motion_m {
                state.fell_back = true;
                return false;
            }
        } else {
            state.same_sample_ticks = 0;
            state.last_sample_bits = sample_bits;
            state.desired_at_change_m = desired_now.displacement_m;
        }
        // ȳ at the sample's time t_k − d (Taylor from t_k; d is a few ticks at most).
        let d = self.delay_s;
        let desired_m = desired_now.displacement_m - d * desired_now.velocity_m_per_s
            + 0.5 * d * d * desired_now.acceleration_m_per_s2;
        let e = desired_m - measured_m;
        state.last_error_m = e;
        state.learn_error_m = 0.0;
        if limited || !e.is_finite() {
            return true;
        }
        if self.integral_per_tick > 0.0 {
            state.integral_m = clamp(state.integral_m + self.integral_per_tick * e, self.limit_m);
        }
        state.learn_error_m = e;
        true
    }

    /// Applies coefficient `j` (0: the constant, n: harmonic n) of the complete bank: its sums,
    /// rotated back by `n(Δ + Ωd)`, update it, and are cleared.
    #[inline(always)]
    fn apply_one(&self, state: &mut FeedbackState, j: usize) {
        let done = 1 - (state.bank & 1);
        let g = self.learn_per_sum;
        let keep = self.keep_per_cycle;
        if j == 0 {
            state.mean_m = clamp(
                keep * state.mean_m + 0.5 * g * state.sum_mean[done],
                self.limit_m,
            );
            state.sum_mean[done] = 0.0;
            return;
        }
        let n = (j - 1).min(MAX_HARMONICS - 1);
        let (sc, ss) = (state.sum_cos[done][n], state.sum_sin[done][n]);
        // Σ e cos n(φ − θ) = cos nθ Σ e cos nφ + sin nθ Σ e sin nφ, and the sine likewise.
        let (bc, bs) = (self.back_cos[n], self.back_sin[n]);
        state.cos_m[n] = clamp(
            keep * state.cos_m[n] + g * (bc * sc + bs * ss),
            self.limit_m,
        );
        state.sin_m[n] = clamp(
            keep * state.sin_m[n] + g * (bc * ss - bs * sc),
            self.limit_m,
        );
        state.sum_cos[done][n] = 0.0;
        state.sum_sin[done][n] = 0.0;
        if n + 1 == self.harmonics {
            state.cycles = state.cycles.wrapping_add(1);
        }
    }

    /// Advances the phase to the new target (oscillator coordinate `x` after the trajectory
    /// step), closes a learning cycle at an upward zero crossing, and returns the desired motion
    /// with the correction added.
    #[inline]
    pub fn correct(
        &self,
        state: &mut FeedbackState,
        x: f32,
        desired: &DesiredMotion,
    ) -> DesiredMotion {
        let bank = state.bank & 1;
        if state.last_x < 0.0 && x >= 0.0 {
            // Upward zero crossing between the last target and this one, at fraction f.
            let f = state.last_x / (state.last_x - x);
            let (c, s) = cos_sin_small((1.0 - f) * self.step_rad);
            state.phase_cos = c;
            state.phase_sin = s;
            if state.synchronised {
                // The cycle is complete: sum the next one in the other bank, apply this one.
                state.bank = 1 - bank;
                state.pending = 0;
            } else {
                // The first, partial cycle's sums are not a whole period: drop them.
                state.sum_cos[bank] = [0.0; MAX_HARMONICS];
                state.sum_sin[bank] = [0.0; MAX_HARMONICS];
                state.sum_mean[bank] = 0.0;
                state.synchronised = true;
            }
        } else {
            let (c, s) = (state.phase_cos, state.phase_sin);
            state.phase_cos = c * self.step_cos - s * self.step_sin;
            state.phase_sin = s * self.step_cos + c * self.step_sin;
        }
        state.last_x = x;
        if state.pending <= self.harmonics {
            self.apply_one(state, state.pending);
            state.pending += 1;
        }
        if state.fell_back || self.structure == FeedbackStructure::Off {
            return *desired;
        }
        let e = if state.last_error_m.is_finite() {
            state.last_error_m
        } else {
            0.0
        };
        let pi = state.integral_m + self.proportional_gain * e;
        if self.structure != FeedbackStructure::Repetitive {
            return DesiredMotion {
                displacement_m: desired.displacement_m + clamp(pi, self.limit_m),
                ..*desired
            };
        }
        // One pass over the harmonics of the new target's phase: the series, its derivatives
        //   c = Σ a cos + b sin;  c' = Ω Σ n (b cos − a sin);  c'' = −Ω² Σ n² (a cos + b sin),
        // and the sums of the last sample's error (rotated back when applied).
        let learn = state.learn_error_m;
        let bank = state.bank & 1;
        let (c1, s1) = (state.phase_cos, state.phase_sin);
        let (mut c, mut s) = (c1, s1);
        let (mut value, mut slope, mut curvature, mut order) =
            (state.mean_m, 0.0f32, 0.0f32, 0.0f32);
        for n in 0..self.harmonics.min(MAX_HARMONICS) {
            order += 1.0;
            let (a, b) = (state.cos_m[n], state.sin_m[n]);
            let in_phase = a * c + b * s;
            value += in_phase;
            slope += order * (b * c - a * s);
            curvature += order * order * in_phase;
            state.sum_cos[bank][n] += learn * c;
            state.sum_sin[bank][n] += learn * s;
            let next_c = c * c1 - s * s1;
            s = s * c1 + c * s1;
            c = next_c;
        }
        state.sum_mean[bank] += learn;
        let w = self.omega_rad_per_s;
        let total = value + pi;
        let limited = clamp(total, self.limit_m);
        // Beyond the limit the derivatives would describe a correction that is not applied.
        let (slope, curvature) = if limited == total {
            (w * slope, -w * w * curvature)
        } else {
            (0.0, 0.0)
        };
        DesiredMotion {
            displacement_m: desired.displacement_m + limited,
            velocity_m_per_s: desired.velocity_m_per_s + slope,
            acceleration_m_per_s2: desired.acceleration_m_per_s2 + curvature,
        }
    }
}

#[inline(always)]
fn clamp(v: f32, limit: f32) -> f32 {
    if v > limit {
        limit
    } else if v < -limit {
        -limit
    } else if v.is_nan() {
        0.0
    } else {
        v
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use crate::inverse::{CommandFlags, ControlLoop, InverseKind, LoopState};
    use crate::model::{DynamicModel, ModelFaults, ModelState};
    use crate::params::{ActuatorParameters, BAKED_MEASURE, BAKED_PARAMETERS};
    use crate::sensor::SensorFault;

    const N: usize = crate::preisach::DEFAULT_CAPACITY;

    /// Runs the loop (feedback as in `params`) against the core model with the actuator
    /// constants of `plant` (4 substeps per period, the sample the model's displacement at the
    /// tick), and returns the RMS error over the last `scored` ticks and the p-p, metres.
    fn closed_loop(
        params: &ActuatorParameters,
        plant: &ActuatorParameters,
        ticks: usize,
        scored: usize,
    ) -> (f32, f32, LoopState<N>) {
        // The learning alone (the stroke gain has its own tests).
        let control = ControlLoop::new(&BAKED_MEASURE, params)
            .unwrap()
            .without_stroke_gain();
        let mut st: LoopState<N> = control.init(InverseKind::Dynamic);
        let d0 = control.trajectory().motion(&st.core.trajectory);
        let substeps = 4;
        let model = DynamicModel::new(
            &BAKED_MEASURE,
            &plant.actuator,
            1.0 / (params.control.sample_rate_hz * substeps as f32),
        );
        let mut x = ModelState {
            preisach: st.preisach.clone(),
            h_a_per_m: st.core.memory.h_a_per_m,
            m_a_per_m: st.core.memory.m_a_per_m,
            displacement_m: d0.displacement_m,
            velocity_m_per_s: d0.velocity_m_per_s,
            current_a: st.core.last_current_a,
            faults: ModelFaults::default(),
        };
        let (mut sq, mut lo, mut hi) = (0.0f64, f32::MAX, f32::MIN);
        let mut y = d0.displacement_m;
        for k in 0..ticks {
            let out = control.tick_sensed(InverseKind::Dynamic, &mut st, Ok(y));
            for _ in 0..substeps {
                y = model.step(&mut x, out.current_a).displacement_m;
            }
            if k + scored >= ticks {
                let e = (y - out.desired.displacement_m) as f64;
                sq += e * e;
                lo = lo.min(out.desired.displacement_m);
                hi = hi.max(out.desired.displacement_m);
            }
        }
        ((sq / scored as f64).sqrt() as f32, hi - lo, st)
    }

    fn with_structure(s: FeedbackStructure) -> ActuatorParameters {
        let mut p = BAKED_PARAMETERS;
        p.control.feedback.structure = s;
        p.sensor.sample_delay_s = 0.0;
        p
    }

    #[test]
    fn learning_removes_a_model_gain_error_the_feedforward_leaves() {
        // The plant's λ_s is 20 % below the model's: the feedforward misses by ~18 % of the
        // p-p; the learning must bring it under 1 % within 40 cycles (γ = 0.3: 0.7^40 ≈ 1e-6).
        let mut plant = BAKED_PARAMETERS;
        plant.actuator.saturation_magnetostriction *= 0.8;
        let (open, p2p, _) = closed_loop(
            &with_structure(FeedbackStructure::Off),
            &plant,
            5_000,
            1_000,
        );
        let (closed, _, st) = closed_loop(
            &with_structure(FeedbackStructure::Repetitive),
            &plant,
            5_000,
            1_000,
        );
        std::println!(
            "lambda_s -20 %: open {:.2} %, closed {:.3} % of p-p",
            100.0 * open / p2p,
            100.0 * closed / p2p
        );
        assert!(
            open > 0.1 * p2p,
            "the case has a large open-loop error: {open}"
        );
        assert!(closed < 0.01 * p2p, "closed loop {closed} m of p-p {p2p} m");
        assert!(st.core.feedback.cycles >= 40);
        assert!(st.core.sensor_fault.is_none());
    }

    #[test]
    fn the_integral_structure_removes_an_offset_only() {
        // PI on ȳ: better than the feedforward on a gain error (it removes the mean), far from
        // the learning's result (it cannot follow the 94 Hz error through the plant's lag).
        let mut plant = BAKED_PARAMETERS;
        plant.actuator.saturation_magnetostriction *= 0.8;
        let mut pi = with_structure(FeedbackStructure::Integral);
        pi.control.feedback.integral_gain_per_s = 1000.0;
        pi.control.feedback.proportional_gain = 0.3;
        let (open, p2p, _) = closed_loop(
            &with_structure(FeedbackStructure::Off),
            &plant,
            5_000,
            1_000,
        );
        let (closed, _, _) = closed_loop(&pi, &plant, 5_000, 1_000);
        assert!(closed < open, "PI {closed} vs open {open}");
        assert!(
            closed > 0.01 * p2p,
            "PI alone reaches {closed} m of p-p {p2p} m"
        );
    }

    #[test]
    fn a_stuck_sensor_falls_back_to_the_feedforward_and_flags_it() {
        let p = with_structure(FeedbackStructure::Repetitive);
        let control = ControlLoop::new(&BAKED_MEASURE, &p).unwrap();
        let mut st: LoopState<N> = control.init(InverseKind::Dynamic);
        let stuck = p.control.feedback.stuck_sensor_ticks as usize;
        let mut fell_back_at = None;
        for k in 0..stuck + 200 {
            let out = control.tick_sensed(InverseKind::Dynamic, &mut st, Ok(20e-6));
            if out.flags.has(CommandFlags::FEEDFORWARD) {
                fell_back_at.get_or_insert(k);
                assert!(out.flags.has(CommandFlags::SENSOR_FAULT));
            }
            if fell_back_at.is_some() {
                assert!(
                    out.flags.has(CommandFlags::FEEDFORWARD),
                    "tick {k}: latched"
                );
                assert!(out.current_a.abs() <= p.control.current_limit_a);
            }
        }
        // Stuck once the count has not changed for `stuck` ticks *and* the trajectory has moved
        // a tenth of its band since (it does within a quarter period here).
        let at = fell_back_at.expect("the stuck sensor is detected");
        assert!((stuck..stuck + 30).contains(&at), "detected at tick {at}");
        assert!(st.core.feedback.fell_back);
        assert_eq!(st.core.sensor_fault, Some(SensorFault::Stuck));
    }

    #[test]
    fn an_unchanged_sample_is_not_stuck_while_the_trajectory_dwells() {
        // A slow trajectory can stay within one ADC count at an extreme for many ticks.
        let law = FeedbackLaw::new(&BAKED_PARAMETERS.control.feedback, 10_000.0, 106.0, 0.0)
            .unwrap()
            .with_stuck_motion(3e-6);
        let mut st = law.init(0.0, -0.1);
        let mut d = DesiredMotion {
            displacement_m: 20e-6,
            velocity_m_per_s: 0.0,
            acceleration_m_per_s2: 0.0,
        };
        for _ in 0..5_000 {
            assert!(
                law.observe(&mut st, 7, 20e-6, &d, false),
                "dwelling is not stuck"
            );
        }
        // The same count while the target moves away by more than 3 µm: stuck.
        d.displacement_m = 24e-6;
        assert!(!law.observe(&mut st, 7, 20e-6, &d, false));
        assert!(st.fell_back);
    }

    #[test]
    fn an_out_of_range_sample_falls_back_but_a_missing_one_ramps_to_zero() {
        let p = with_structure(FeedbackStructure::Repetitive);
        let control = ControlLoop::new(&BAKED_MEASURE, &p).unwrap();
        let mut a: LoopState<N> = control.init(InverseKind::Dynamic);
        let mut b = a.clone();
        for _ in 0..300 {
            let y = control
                .trajectory()
                .motion(&a.core.trajectory)
                .displacement_m;
            control.tick_sensed(InverseKind::Dynamic, &mut a, Ok(y));
            control.tick_sensed(InverseKind::Dynamic, &mut b, Ok(y));
        }
        let out = control.tick_sensed(
            InverseKind::Dynamic,
            &mut a,
            Err(SensorFault::OutOfValidRange),
        );
        assert!(out.flags.has(CommandFlags::FEEDFORWARD));
        let mut last = 0.0;
        for _ in 0..2_000 {
            last = control
                .tick_sensed(InverseKind::Dynamic, &mut a, Ok(20e-6))
                .current_a;
            control.tick_sensed(InverseKind::Dynamic, &mut b, Err(SensorFault::Missing));
        }
        assert!(
            last.abs() > 0.1,
            "the feedforward keeps driving the coil: {last}"
        );
        assert_eq!(b.core.last_current_a, 0.0, "a missing sample ramps to 0 A");
        assert!(b.core.stopped);
    }

    #[test]
    fn no_learning_and_no_integration_while_the_command_is_limited() {
        let mut f = BAKED_PARAMETERS.control.feedback;
        f.integral_gain_per_s = 100.0;
        let law = FeedbackLaw::new(&f, 10_000.0, 106.0, 0.0).unwrap();
        let mut st = law.init(0.0, -0.1);
        let d = DesiredMotion {
            displacement_m: 20e-6,
            velocity_m_per_s: 0.0,
            acceleration_m_per_s2: 0.0,
        };
        let mut x = -0.1f32;
        for k in 0..2_000u32 {
            assert!(law.observe(&mut st, k, 10e-6, &d, true));
            // An oscillator coordinate with one upward crossing per 106 ticks.
            x = libm::sinf(2.0 * core::f32::consts::PI * k as f32 / 106.0 - 0.05);
            law.correct(&mut st, x, &d);
        }
        let _ = x;
        assert!(st.cycles > 10);
        assert_eq!(st.integral_m, 0.0);
        assert!(st.cos_m.iter().chain(st.sin_m.iter()).all(|&c| c == 0.0));
        assert_eq!(st.mean_m, 0.0);
    }

    #[test]
    fn the_correction_never_exceeds_its_limit() {
        let mut f = BAKED_PARAMETERS.control.feedback;
        f.learning_gain = 2.0;
        f.integral_gain_per_s = 5_000.0;
        f.proportional_gain = 0.9;
        let law = FeedbackLaw::new(&f, 10_000.0, 106.0, 0.0).unwrap();
        let mut st = law.init(0.0, -0.1);
        let d = DesiredMotion {
            displacement_m: 20e-6,
            velocity_m_per_s: 0.0,
            acceleration_m_per_s2: 0.0,
        };
        for k in 0..5_000u32 {
            // A huge, always positive error.
            law.observe(&mut st, k, -1.0, &d, false);
            let x = libm::sinf(2.0 * core::f32::consts::PI * k as f32 / 106.0 - 0.05);
            let c = law.correct(&mut st, x, &d);
            assert!((c.displacement_m - d.displacement_m).abs() <= f.correction_limit_m * 1.0001);
            assert!(c.velocity_m_per_s.is_finite() && c.acceleration_m_per_s2.is_finite());
        }
    }

    #[test]
    fn the_phase_follows_the_trajectory_to_a_small_fraction_of_a_tick() {
        // The rotation's phase against the trajectory's own zero crossings: at every tick of 30
        // cycles, within 0.01 rad (0.17 tick at 106 ticks per cycle).
        let control = ControlLoop::new(&BAKED_MEASURE, &BAKED_PARAMETERS).unwrap();
        let vdp = control.trajectory();
        let law = control.feedback();
        let mut traj = vdp.start_state();
        let mut st = law.init(vdp.start_phase_cycles(), traj.x);
        let period = vdp.period_steps();
        let d = vdp.motion(&traj);
        let mut phase = vdp.start_phase_cycles() * period;
        for _ in 0..(30.0 * period) as usize {
            let before = traj.x;
            vdp.step(&mut traj);
            phase += 1.0;
            if before < 0.0 && traj.x >= 0.0 {
                phase = 1.0 - before / (before - traj.x);
            }
            law.correct(&mut st, traj.x, &d);
            let angle = 2.0 * core::f32::consts::PI * phase / period;
            let err =
                (st.phase_cos - libm::cosf(angle)).abs() + (st.phase_sin - libm::sinf(angle)).abs();
            assert!(err < 0.01, "phase error {err}");
        }
    }

    #[test]
    fn bad_settings_name_their_field() {
        let base = BAKED_PARAMETERS.control.feedback;
        type Edit = fn(&mut Feedback);
        let cases: [(&str, Edit); 5] = [
            ("control.feedback.learning_gain", |f| {
                f.learning_gain = f32::NAN
            }),
            ("control.feedback.learning_harmonics", |f| {
                f.learning_harmonics = 17
            }),
            ("control.feedback.learning_leak_per_cycle", |f| {
                f.learning_leak_per_cycle = 1.0
            }),
            ("control.feedback.correction_limit_m", |f| {
                f.correction_limit_m = 0.0
            }),
            ("control.feedback.stuck_sensor_ticks", |f| {
                f.stuck_sensor_ticks = 1
            }),
        ];
        for (field, edit) in cases {
            let mut f = base;
            edit(&mut f);
            assert_eq!(
                FeedbackLaw::new(&f, 10_000.0, 106.0, 0.0)
                    .unwrap_err()
                    .field,
                field
            );
        }
        assert_eq!(
            FeedbackLaw::new(&base, 10_000.0, 8.0, 0.0)
                .unwrap_err()
                .field,
            "trajectory.frequency_scale_hz"
        );
    }
}
