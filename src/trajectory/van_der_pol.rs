//! Van der Pol desired trajectory, integrated with RK4 at the control rate.
//!
//! # Oscillator
//!
//! In scaled time `τ = ω t` with `ω = 2π · frequency_scale_hz`:
//!
//! ```text
//! x'' - μ (1 - x²) x' + x = 0,     ' = d/dτ,
//! ```
//!
//! written as the first-order system `x' = v`, `v' = μ (1 - x²) v - x`. Every solution except the
//! origin converges to a unique limit cycle whose amplitude in `x` is ≈ 2 for every μ (2.0086 at
//! μ = 1, → 2 as μ → 0 and μ → ∞).
//!
//! # Integration
//!
//! Classical RK4 with the fixed step `h_τ = ω / sample_rate_hz` (one step per control interrupt).
//! Stability: RK4's real stability interval is `[-2.785, 0]`; the stiffest eigenvalue of the
//! linearization is bounded by `|∂v'/∂v| = μ |1 - x²| <= 3 μ` on the cycle (|x| <= 2.01), and the
//! rotation part by 1, so [`VanDerPol::new`] requires `h_τ · max(1, 3 μ) <= 1` (a margin of 2.7 on
//! the stability bound, and at least 2π steps per unit of scaled time for accuracy); otherwise it
//! returns [`TrajectoryError::StepTooLarge`].
//!
//! # Start on the limit cycle
//!
//! [`VanDerPol::new`] integrates a settling transient from `(x, v) = (2, 0)` for
//! [`SETTLE_CYCLES`] estimated periods, then measures the peak `x_peak = max |x|` over
//! [`MEASURE_CYCLES`] more periods with the same RK4 step. The state at the end is the start
//! state handed out by [`VanDerPol::start_state`]. Period estimate (upper bound over all μ):
//! `T(μ) ≈ 2π + (3 - 2 ln 2) μ` (harmonic limit 2π, relaxation limit 1.614 μ).
//!
//! # Mapping into the displacement band
//!
//! With `y_mid = (y_min + y_max) / 2` and `y_half = (y_max - y_min) / 2`,
//!
//! ```text
//! ȳ = y_mid + (y_half / x_peak) · x,
//! ẏ = (y_half / x_peak) · ω  · v,                     (exact: dx/dt = ω x')
//! ÿ = (y_half / x_peak) · ω² · (μ (1 - x²) v - x),    (the oscillator's own equation)
//! ```
//!
//! so the trajectory spans the band `[y_min, y_max]`: the measured sampled peak is inflated by the
//! worst-case sampling deficit at an extremum (`x_peak h_τ² / 8`, see [`VanDerPol::new`]), so the
//! samples stay inside the band and reach it to within that fraction (2·10⁻⁴ at 50 Hz / 10 kHz). The derivatives come from
//! the state, never from finite differences.

use crate::params::{Control, Trajectory};

/// Settling transient length, in estimated periods.
pub const SETTLE_CYCLES: f32 = 12.0;
/// Peak-measurement window, in estimated periods (more than one full period, so both the
/// positive and the negative peak are seen).
pub const MEASURE_CYCLES: f32 = 2.0;

/// Upper bound on the number of steps spent at construction (settling plus measurement); larger
/// requests fail with [`TrajectoryError::StepTooLarge`]-like [`TrajectoryError::TooManySteps`].
pub const MAX_INIT_STEPS: u32 = 2_000_000;

/// A desired displacement sample with its first two time derivatives.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct DesiredMotion {
    /// ȳ, m.
    pub displacement_m: f32,
    /// dȳ/dt, m/s.
    pub velocity_m_per_s: f32,
    /// d²ȳ/dt², m/s².
    pub acceleration_m_per_s2: f32,
}

impl DesiredMotion {
    /// Whether all three components are finite.
    pub fn is_finite(&self) -> bool {
        self.displacement_m.is_finite()
            && self.velocity_m_per_s.is_finite()
            && self.acceleration_m_per_s2.is_finite()
    }
}

/// Rejected trajectory settings (the field is named as in the JSON schema).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum TrajectoryError {
    /// A setting is NaN/inf or out of its domain.
    Invalid {
        /// JSON field path.
        field: &'static str,
        /// The value.
        value: f32,
    },
    /// `h_τ · max(1, 3 μ)` exceeds 1 (RK4 unstable or inaccurate at this control rate).
    StepTooLarge {
        /// The scaled step `h_τ = ω / sample_rate_hz`.
        step_scaled: f32,
        /// μ.
        mu: f32,
    },
    /// The settling transient would need more than [`MAX_INIT_STEPS`] steps.
    TooManySteps {
        /// Steps needed.
        steps: f32,
    },
}

/// Oscillator state `(x, v = dx/dτ)`, dimensionless.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VanDerPolState {
    /// x.
    pub x: f32,
    /// dx/dτ.
    pub v: f32,
}

/// Coefficients of the trajectory generator (computed once by [`VanDerPol::new`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VanDerPol {
    mu: f32,
    step_scaled: f32,
    /// `step_scaled / 6`, the RK4 weight (a division saved per step).
    step_sixth: f32,
    omega_rad_per_s: f32,
    mid_m: f32,
    /// y_half / x_peak, m per unit of x.
    scale_m: f32,
    peak_x: f32,
    start: VanDerPolState,
    /// The limit cycle's period in control steps (measured, fractional).
    period_steps: f32,
    /// Phase of the start state, cycles after an upward zero crossing of `x`, in `[0, 1)`.
    start_phase_cycles: f32,
}

impl VanDerPol {
    /// Builds the generator for the trajectory settings at the control rate of `control`, running
    /// the settling transient (see the module documentation).
    pub fn new(trajectory: &Trajectory, control: &Control) -> Result<Self, TrajectoryError> {
        let mu = trajectory.van_der_pol_mu;
        let f = trajectory.frequency_scale_hz;
        let rate = control.sample_rate_hz;
        let (y_min, y_max) = (trajectory.displacement_min_m, trajectory.displacement_max_m);
        if !(mu.is_finite() && mu >= 0.0) {
            return Err(TrajectoryError::Invalid {
                field: "trajectory.van_der_pol_mu",
                value: mu,
            });
        }
        if !(f.is_finite() && f > 0.0) {
            return Err(TrajectoryError::Invalid {
                field: "trajectory.frequency_scale_hz",
                value: f,
            });
        }
        if !(rate.is_finite() && rate > 0.0) {
            return Err(TrajectoryError::Invalid {
                field: "control.sample_rate_hz",
                value: rate,
            });
        }
        if !y_min.is_finite() {
            return Err(TrajectoryError::Invalid {
                field: "trajectory.displacement_min_m",
                value: y_min,
            });
        }
        if !(y_max.is_finite() && y_max > y_min) {
            return Err(TrajectoryError::Invalid {
                field: "trajectory.displacement_max_m",
                value: y_max,
            });
        }
        let omega = 2.0 * core::f32::consts::PI * f;
        let step_scaled = omega / rate;
        let stiffness = if 3.0 * mu > 1.0 { 3.0 * mu } else { 1.0 };
        if step_scaled * stiffness > 1.0 {
            return Err(TrajectoryError::StepTooLarge { step_scaled, mu });
        }
        let period_scaled =
            2.0 * core::f32::consts::PI + (3.0 - 2.0 * core::f32::consts::LN_2) * mu;
        let settle_steps = SETTLE_CYCLES * period_scaled / step_scaled;
        let measure_steps = MEASURE_CYCLES * period_scaled / step_scaled;
        if settle_steps + measure_steps > MAX_INIT_STEPS as f32 {
            return Err(TrajectoryError::TooManySteps {
                steps: settle_steps + measure_steps,
            });
        }
        let mut generator = VanDerPol {
            mu,
            step_scaled,
            step_sixth: step_scaled / 6.0,
            omega_rad_per_s: omega,
            mid_m: 0.5 * (y_min + y_max),
            scale_m: 0.0,
            peak_x: 0.0,
            start: VanDerPolState { x: 2.0, v: 0.0 },
            period_steps: 0.0,
            start_phase_cycles: 0.0,
        };
        let mut state = generator.start;
        for _ in 0..(settle_steps as u32) {
            generator.rk4(&mut state);
        }
        let mut peak = 0.0f32;
        // Upward zero crossings of x (linearly interpolated, in steps from the window's start):
        // the window spans two estimated periods, each an upper bound of the true one, so it
        // holds at least two crossings.
        let (mut first, mut last, mut crossings) = (0.0f32, 0.0f32, 0u32);
        let n_measure = measure_steps as u32;
        for k in 0..n_measure {
            let before = state.x;
            generator.rk4(&mut state);
            peak = peak.max(libm::fabsf(state.x));
            if before < 0.0 && state.x >= 0.0 {
                let at = k as f32 + before / (before - state.x);
                if crossings == 0 {
                    first = at;
                }
                last = at;
                crossings += 1;
            }
        }
        if crossings < 2 {
            // Not an oscillation over the window (cannot happen for μ >= 0 on the cycle).
            return Err(TrajectoryError::Invalid {
                field: "trajectory.van_der_pol_mu",
                value: mu,
            });
        }
        generator.period_steps = (last - first) / (crossings - 1) as f32;
        let phase = (n_measure as f32 - last) / generator.period_steps;
        generator.start_phase_cycles = phase - libm::floorf(phase);
        // The samples miss the true extremum by at most the parabola deficit: at an extremum
        // v = 0, so x'' = v' = -x there, and the nearest sample is within h/2, hence
        // x_peak - x_sample <= x_peak · h² / 8. Inflating by that keeps every sample in the band.
        generator.peak_x = peak * (1.0 + 0.125 * step_scaled * step_scaled);
        generator.scale_m = 0.5 * (y_max - y_min) / generator.peak_x;
        generator.start = state;
        Ok(generator)
    }

    /// The settled state on the limit cycle to start from.
    pub fn start_state(&self) -> VanDerPolState {
        self.start
    }

    /// The limit cycle's period in control steps, measured between upward zero crossings of `x`
    /// (fractional: the cycle is not a whole number of steps in general).
    pub fn period_steps(&self) -> f32 {
        self.period_steps
    }

    /// The phase of [`VanDerPol::start_state`] on the cycle, in cycles since an upward zero
    /// crossing of `x` (`[0, 1)`).
    pub fn start_phase_cycles(&self) -> f32 {
        self.start_phase_cycles
    }

    /// The measured limit-cycle peak `max |x|` (≈ 2).
    pub fn peak_x(&self) -> f32 {
        self.peak_x
    }

    /// ω = 2π · frequency_scale_hz, rad/s.
    pub fn omega_rad_per_s(&self) -> f32 {
        self.omega_rad_per_s
    }

    /// The scaled RK4 step h_τ.
    pub fn step_scaled(&self) -> f32 {
        self.step_scaled
    }

    /// `(x', v')` of the oscillator.
    #[inline(always)]
    fn field(&self, x: f32, v: f32) -> (f32, f32) {
        (v, self.mu * (1.0 - x * x) * v - x)
    }

    #[inline(always)]
    fn rk4(&self, s: &mut VanDerPolState) {
        let h = self.step_scaled;
        let (k1x, k1v) = self.field(s.x, s.v);
        let (k2x, k2v) = self.field(s.x + 0.5 * h * k1x, s.v + 0.5 * h * k1v);
        let (k3x, k3v) = self.field(s.x + 0.5 * h * k2x, s.v + 0.5 * h * k2v);
        let (k4x, k4v) = self.field(s.x + h * k3x, s.v + h * k3v);
        s.x += self.step_sixth * (k1x + 2.0 * k2x + 2.0 * k3x + k4x);
        s.v += self.step_sixth * (k1v + 2.0 * k2v + 2.0 * k3v + k4v);
    }

    /// The desired motion at a state (displacement and its exact derivatives, module docs).
    pub fn motion(&self, s: &VanDerPolState) -> DesiredMotion {
        let (_, accel_scaled) = self.field(s.x, s.v);
        DesiredMotion {
            displacement_m: self.mid_m + self.scale_m * s.x,
            velocity_m_per_s: self.scale_m * self.omega_rad_per_s * s.v,
            acceleration_m_per_s2: self.scale_m
                * self.omega_rad_per_s
                * self.omega_rad_per_s
                * accel_scaled,
        }
    }

    /// Advances one control period and returns the motion at the new time.
    pub fn step(&self, state: &mut VanDerPolState) -> DesiredMotion {
        self.rk4(state);
        self.motion(state)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::params::BAKED_PARAMETERS;

    fn settings(mu: f32, f: f32) -> (Trajectory, Control) {
        let mut t = BAKED_PARAMETERS.trajectory;
        t.van_der_pol_mu = mu;
        t.frequency_scale_hz = f;
        (t, BAKED_PARAMETERS.control)
    }

    #[test]
    fn period_and_start_phase_match_the_zero_crossings() {
        // Run on from the start state: the first upward crossing must come after
        // (1 − start phase) periods, and the later ones one period apart, to 0.05 steps.
        for &(mu, f) in &[(0.2f32, 50.0f32), (1.0, 100.0), (3.0, 20.0)] {
            let (t, c) = settings(mu, f);
            let vdp = VanDerPol::new(&t, &c).expect("valid settings");
            let period = vdp.period_steps();
            let mut s = vdp.start_state();
            let mut crossings = heapless::Vec::<f32, 16>::new();
            for k in 0..(4.5 * period) as usize {
                let before = s.x;
                vdp.step(&mut s);
                if before < 0.0 && s.x >= 0.0 {
                    crossings.push(k as f32 + before / (before - s.x)).unwrap();
                }
            }
            let expected_first = (1.0 - vdp.start_phase_cycles()) * period;
            assert!(
                (crossings[0] - expected_first).abs() < 0.05,
                "mu {mu}: first crossing {} vs {expected_first}",
                crossings[0]
            );
            for w in crossings.windows(2) {
                assert!(
                    (w[1] - w[0] - period).abs() < 0.05,
                    "mu {mu}: {} vs {period}",
                    w[1] - w[0]
                );
            }
        }
    }

    #[test]
    fn stays_in_band_and_on_the_cycle() {
        for &(mu, f) in &[(0.2f32, 50.0f32), (1.0, 50.0), (3.0, 20.0)] {
            let (t, c) = settings(mu, f);
            let vdp = VanDerPol::new(&t, &c).expect("valid settings");
            // Limit-cycle amplitude ≈ 2 (2.0086 at μ = 1); RK4 at h_τ <= 0.1 and the sampled
            // peak change it by far less than 1 %.
            assert!(
                (vdp.peak_x() - 2.0).abs() < 0.03,
                "mu {mu}: peak {}",
                vdp.peak_x()
            );
            let mut s = vdp.start_state();
            let (mut lo, mut hi) = (f32::MAX, f32::MIN);
            for _ in 0..(c.sample_rate_hz as usize) {
                let m = vdp.step(&mut s);
                lo = lo.min(m.displacement_m);
                hi = hi.max(m.displacement_m);
            }
            let band = t.displacement_max_m - t.displacement_min_m;
            // Inside the band up to f32 rounding of the mapping (a few ulp of y_max).
            let slack = 4.0 * f32::EPSILON * t.displacement_max_m;
            assert!(lo >= t.displacement_min_m - slack && hi <= t.displacement_max_m + slack);
            // And it fills it: the peak was measured with the same step, so the sampled extremes
            // of one second (many cycles) reach it within the peak's sampling error (0.5 %).
            assert!(
                hi - lo > 0.995 * band,
                "mu {mu}: span {} of {band}",
                hi - lo
            );
        }
    }

    #[test]
    fn derivatives_match_finite_differences_of_the_displacement() {
        // Central differences of ȳ approximate ẏ and ÿ with error O(h²) of the scaled step
        // (h_τ = 0.0314 at 50 Hz / 10 kHz): relative error ~ h_τ² · |x'''| / 6 ≈ 3e-4 of the
        // derivative scale; f32 rounding of the difference adds ~ ε·y/(h·ẏ_max) ≈ 1e-3 for ÿ.
        // Bound: 1 % of the derivative's peak.
        let (t, c) = settings(1.0, 50.0);
        let vdp = VanDerPol::new(&t, &c).unwrap();
        let h = 1.0 / c.sample_rate_hz;
        let mut s = vdp.start_state();
        let mut prev = vdp.motion(&s);
        let mut cur = vdp.step(&mut s);
        let mut samples = [(0.0f32, 0.0f32, 0.0f32, 0.0f32); 600];
        for slot in samples.iter_mut() {
            let next = vdp.step(&mut s);
            let v_fd = (next.displacement_m - prev.displacement_m) / (2.0 * h);
            let a_fd =
                (next.displacement_m - 2.0 * cur.displacement_m + prev.displacement_m) / (h * h);
            *slot = (v_fd, cur.velocity_m_per_s, a_fd, cur.acceleration_m_per_s2);
            prev = cur;
            cur = next;
        }
        let v_peak = samples.iter().map(|s| s.1.abs()).fold(0.0, f32::max);
        let a_peak = samples.iter().map(|s| s.3.abs()).fold(0.0, f32::max);
        for (v_fd, v, a_fd, a) in samples {
            assert!((v_fd - v).abs() < 0.01 * v_peak, "velocity {v_fd} vs {v}");
            assert!(
                (a_fd - a).abs() < 0.01 * a_peak,
                "acceleration {a_fd} vs {a}"
            );
        }
    }

    #[test]
    fn period_matches_the_known_van_der_pol_period() {
        // Known period of the μ = 1 limit cycle in scaled time: T = 6.6633. Measured from upward
        // zero crossings (interpolated) over 20 cycles; RK4 phase error at h_τ = 0.0314 is
        // ~ h⁴ ≈ 1e-6, interpolation error ~ h² ≈ 1e-3 per crossing, averaged: bound 0.2 %.
        let (t, c) = settings(1.0, 50.0);
        let vdp = VanDerPol::new(&t, &c).unwrap();
        let mut s = vdp.start_state();
        let mut crossings = [0.0f32; 21];
        let mut n = 0;
        let mut k = 0u32;
        while n < crossings.len() {
            let prev = s;
            vdp.rk4(&mut s);
            k += 1;
            if prev.x < 0.0 && s.x >= 0.0 {
                let frac = -prev.x / (s.x - prev.x);
                crossings[n] = (k as f32 - 1.0 + frac) * vdp.step_scaled();
                n += 1;
            }
        }
        let period = (crossings[20] - crossings[0]) / 20.0;
        assert!((period - 6.6633).abs() < 0.002 * 6.6633, "period {period}");
    }

    #[test]
    fn rejects_bad_settings_with_the_field() {
        let (mut t, c) = settings(1.0, 50.0);
        t.van_der_pol_mu = f32::NAN;
        assert!(matches!(
            VanDerPol::new(&t, &c),
            Err(TrajectoryError::Invalid {
                field: "trajectory.van_der_pol_mu",
                ..
            })
        ));
        let (mut t, c) = settings(1.0, 50.0);
        t.displacement_max_m = t.displacement_min_m;
        assert!(matches!(
            VanDerPol::new(&t, &c),
            Err(TrajectoryError::Invalid {
                field: "trajectory.displacement_max_m",
                ..
            })
        ));
        // μ = 200 at 50 Hz / 10 kHz: h_τ · 3μ = 18.8 > 1.
        let (t, c) = settings(200.0, 50.0);
        assert!(matches!(
            VanDerPol::new(&t, &c),
            Err(TrajectoryError::StepTooLarge { .. })
        ));
    }
}
