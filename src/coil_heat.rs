//! The coil's temperature rise, estimated from the commanded current, and a bound on how much a
//! stretch of commands can add to it: what lets the measurement programme
//! ([`crate::programme`]) keep the winding under `coil_thermal.max_rise_k` of the parameter file
//! without a temperature sensor.
//!
//! **Model.** The winding as one thermal node, `τ ΔT' = k I² − ΔT` with `k = R_th R_coil` (K/A²;
//! `R_coil` the hot resistance of the file's `amplifier` section, so a cold coil's heat is
//! overestimated, never under). Over a block of [`BLOCK_TICKS`] ticks the heat input is taken as
//! the block's mean `I²`, and the node advances exactly for a constant input:
//! `ΔT ← ΔT + (k ⟨I²⟩ − ΔT)(1 − e^{−T_b/τ})`. Per block rather than per tick because at 10 kHz
//! and `τ` of minutes the per-tick factor (~10⁻⁶) is below an f32's resolution of `ΔT`; per block
//! the rounding stays under 10⁻³ K over an hour.
//!
//! **Bound.** Over a stretch of `T` seconds whose currents stay within `|I| ≤ I_p`, from a rise
//! `ΔT₀`, the rise stays at or below `ΔT₀ + k I_p² (1 − e^{−T/τ})`: the input `k I_p²` bounds
//! the actual one, the linear node is monotone in its input, and `ΔT₀ e^{−t/τ} ≤ ΔT₀`. A stretch
//! of parts `j` (durations `T_j`, bounds `I_j`) adds at most `Σ_j k I_j² (1 − e^{−T_j/τ})`
//! (superposition: each part's contribution is at its largest when the part ends, and decays
//! after). Each part's contribution is also at most `(k/τ) ∫ I² dt` (the kernel `e^{−(t−s)/τ}/τ`
//! is at most `1/τ`), far tighter for a part much shorter than `τ` whose `I²` is mostly below its
//! peak: a ramp from `a` to `b` over `T` has `∫ I² dt = T (a² + ab + b²)/3`, a sine
//! `b + a sin ωt` at most `T (b² + a²/2) + 4|ab|/ω + a²/(4ω)`. Each part takes the smaller of its
//! two bounds. The estimate lags the model by at most one block, `k I_max² (1 − e^{−T_b/τ})`
//! ([`CoilHeat::lag_margin_k`]), which every decision adds.
//!
//! The estimate starts at 0: the programme assumes the coil at ambient when it starts (rested for
//! a few `τ`). Cost per tick: a multiply-add and a compare; per block one more multiply-add.

use crate::params::{ActuatorParameters, CoilThermal};

/// Ticks over which the heat input is averaged before the estimate advances (module docs).
pub const BLOCK_TICKS: u32 = 64;

/// Invalid thermal constants, by field name.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CoilHeatError(pub &'static str);

/// The estimator's coefficients (`&self`; its state is a [`CoilHeatState`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CoilHeat {
    /// `k = R_th R_coil`, steady rise per A², K/A².
    rise_k_per_a2: f32,
    /// `τ` in ticks.
    time_constant_ticks: f32,
    /// `1 − e^{−T_b/τ}` of a block.
    block_factor: f32,
    /// The largest rise the programme may cause, K.
    max_rise_k: f32,
    /// The output limit, A (the largest current the estimate can see).
    limit_a: f32,
}

/// The estimate's progress.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct CoilHeatState {
    /// Estimated rise at the end of the last whole block, K.
    rise_k: f32,
    /// `Σ I²` of the block under way, A².
    block_sum_a2: f32,
    /// Ticks of the block under way.
    block_ticks: u32,
}

impl CoilHeatState {
    /// The estimated rise, K (at the last whole block).
    pub fn rise_k(&self) -> f32 {
        self.rise_k
    }
}

/// `1 − e^{−x}`, accurate for small `x` (no cancellation).
fn one_minus_exp_neg(x: f32) -> f32 {
    -libm::expm1f(-x)
}

impl CoilHeat {
    /// The estimator for `thermal`, the coil's hot resistance, the output limit and the tick rate.
    pub fn new(
        thermal: &CoilThermal,
        coil_resistance_ohm: f32,
        limit_a: f32,
        sample_rate_hz: f32,
    ) -> Result<Self, CoilHeatError> {
        let positive = |v: f32| v.is_finite() && v > 0.0;
        for (name, value) in [
            (
                "coil_thermal.thermal_resistance_k_per_w",
                thermal.thermal_resistance_k_per_w,
            ),
            ("coil_thermal.time_constant_s", thermal.time_constant_s),
            ("coil_thermal.max_rise_k", thermal.max_rise_k),
            ("amplifier.coil_resistance_ohm", coil_resistance_ohm),
            ("control.current_limit_a", limit_a),
            ("control.sample_rate_hz", sample_rate_hz),
        ] {
            if !positive(value) {
                return Err(CoilHeatError(name));
            }
        }
        let time_constant_ticks = thermal.time_constant_s * sample_rate_hz;
        Ok(CoilHeat {
            rise_k_per_a2: thermal.thermal_resistance_k_per_w * coil_resistance_ohm,
            time_constant_ticks,
            block_factor: one_minus_exp_neg(BLOCK_TICKS as f32 / time_constant_ticks),
            max_rise_k: thermal.max_rise_k,
            limit_a,
        })
    }

    /// The estimator of a parameter set (`None` without a `coil_thermal` section).
    pub fn from_parameters(p: &ActuatorParameters) -> Option<Result<Self, CoilHeatError>> {
        p.coil_thermal.map(|t| {
            CoilHeat::new(
                &t,
                p.amplifier.coil_resistance_ohm,
                p.control.current_limit_a,
                p.control.sample_rate_hz,
            )
        })
    }

    /// The largest rise the programme may cause, K.
    pub fn max_rise_k(&self) -> f32 {
        self.max_rise_k
    }

    /// Steady rise at a constant `current_a`, K.
    pub fn steady_rise_k(&self, current_a: f32) -> f32 {
        self.rise_k_per_a2 * current_a * current_a
    }

    /// Accounts for one tick at `current_a` (the current the limiter let onto the coil).
    #[inline]
    pub fn step(&self, s: &mut CoilHeatState, current_a: f32) {
        s.block_sum_a2 += current_a * current_a;
        s.block_ticks += 1;
        if s.block_ticks >= BLOCK_TICKS {
            let heat_k = self.rise_k_per_a2 * s.block_sum_a2 / BLOCK_TICKS as f32;
            s.rise_k += (heat_k - s.rise_k) * self.block_factor;
            s.block_sum_a2 = 0.0;
            s.block_ticks = 0;
        }
    }

    /// The most `ticks` ticks with currents within `±peak_a` can add to the rise, K (module docs).
    pub fn heating_k(&self, peak_a: f32, ticks: u32) -> f32 {
        self.steady_rise_k(peak_a) * one_minus_exp_neg(ticks as f32 / self.time_constant_ticks)
    }

    /// The energy bound of a part with `∫ I² dt` = `integral_a2_ticks` (A²·ticks), K.
    fn energy_heating_k(&self, integral_a2_ticks: f32) -> f32 {
        self.rise_k_per_a2 * integral_a2_ticks / self.time_constant_ticks
    }

    /// The most a linear ramp from `from_a` to `to_a` over `ticks` can add, K (module docs).
    pub fn ramp_heating_k(&self, from_a: f32, to_a: f32, ticks: u32) -> f32 {
        let peak_a = libm::fabsf(from_a).max(libm::fabsf(to_a));
        let mean_a2 = (from_a * from_a + from_a * to_a + to_a * to_a) / 3.0;
        self.heating_k(peak_a, ticks)
            .min(self.energy_heating_k(mean_a2 * ticks as f32))
    }

    /// The most `bias_a + amplitude_a·sin(ω t)` over `ticks` can add, K, with `ω` in radians
    /// per tick (module docs).
    pub fn sine_heating_k(
        &self,
        bias_a: f32,
        amplitude_a: f32,
        omega_per_tick: f32,
        ticks: u32,
    ) -> f32 {
        let (b, a) = (libm::fabsf(bias_a), libm::fabsf(amplitude_a));
        let integral_a2_ticks =
            ticks as f32 * (b * b + a * a / 2.0) + (4.0 * a * b + a * a / 4.0) / omega_per_tick;
        self.heating_k(b + a, ticks)
            .min(self.energy_heating_k(integral_a2_ticks))
    }

    /// How far the estimate can lag the model: one block at the output limit, K.
    pub fn lag_margin_k(&self) -> f32 {
        self.steady_rise_k(self.limit_a) * self.block_factor
    }

    /// Whether a stretch that adds at most `heating_k` keeps the rise at or below the limit from
    /// the estimate `s`.
    #[inline]
    pub fn fits(&self, s: &CoilHeatState, heating_k: f32) -> bool {
        s.rise_k + self.lag_margin_k() + heating_k <= self.max_rise_k
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn heat(time_constant_s: f32) -> CoilHeat {
        let thermal = CoilThermal {
            thermal_resistance_k_per_w: 2.0,
            time_constant_s,
            max_rise_k: 10.0,
        };
        CoilHeat::new(&thermal, 5.0, 2.0, 10_000.0).unwrap()
    }

    /// The estimate follows the node's exact solution, `k I² (1 − e^{−t/τ})` under a constant
    /// current, within one block's lag and 0.1 % — for τ of seconds and of minutes.
    #[test]
    fn the_estimate_follows_the_exact_solution_for_short_and_long_time_constants() {
        for tau in [0.5f32, 120.0] {
            let h = heat(tau);
            let mut s = CoilHeatState::default();
            let ticks = (3.0 * tau * 10_000.0) as u32;
            for n in 1..=ticks {
                h.step(&mut s, 1.5);
                if n % BLOCK_TICKS == 0 {
                    let t = n as f64 / 10_000.0;
                    let exact = 10.0 * 2.25 * (1.0 - (-t / tau as f64).exp());
                    let err = (s.rise_k() as f64 - exact).abs();
                    assert!(
                        err <= 1e-3 * exact + 1e-4,
                        "tau {tau}: {t} s: {} vs {exact}",
                        s.rise_k()
                    );
                }
            }
        }
    }

    /// The bound holds for any currents within the peak, here a square wave between ±peak and 0.
    #[test]
    fn the_bound_covers_every_path_within_the_peak() {
        let h = heat(2.0);
        let mut s = CoilHeatState::default();
        for _ in 0..5_000 {
            h.step(&mut s, 1.0);
        }
        let start = s.rise_k();
        let ticks = 20_000u32;
        let mut highest = start;
        for n in 0..ticks {
            let i = if (n / 700) % 2 == 0 { 1.8 } else { 0.0 };
            h.step(&mut s, i);
            highest = highest.max(s.rise_k());
        }
        let bound = start + h.heating_k(1.8, ticks);
        assert!(highest <= bound, "{highest} > {bound}");
        // The energy bounds against the exact node, stepped per tick in f64, from cold.
        let exact_peak = |current: &dyn Fn(u32) -> f64, ticks: u32| {
            let decay = (-1.0f64 / 20_000.0).exp();
            let (mut rise, mut peak) = (0.0f64, 0.0f64);
            for n in 0..ticks {
                let i = current(n);
                rise = 10.0 * i * i + (rise - 10.0 * i * i) * decay;
                peak = peak.max(rise);
            }
            peak
        };
        let ramp = exact_peak(&|n| -1.5 + 3.0 * n as f64 / 4000.0, 4000);
        let ramp_bound = h.ramp_heating_k(-1.5, 1.5, 4000) as f64;
        assert!(
            ramp <= ramp_bound && ramp_bound < 0.4 * h.heating_k(1.5, 4000) as f64,
            "{ramp} {ramp_bound}"
        );
        let omega = 2.0 * core::f64::consts::PI * 30.0 / 10_000.0;
        let sine = exact_peak(&|n| 0.8 + 0.6 * (omega * n as f64).sin(), 1234);
        let sine_bound = h.sine_heating_k(0.8, 0.6, omega as f32, 1234) as f64;
        assert!(
            sine <= sine_bound && sine_bound < 0.6 * h.heating_k(1.4, 1234) as f64,
            "{sine} {sine_bound}"
        );
        assert!(h.fits(&CoilHeatState::default(), 9.0));
        assert!(!h.fits(&CoilHeatState::default(), 10.0));
    }

    #[test]
    fn invalid_constants_are_named() {
        let bad = CoilThermal {
            thermal_resistance_k_per_w: 2.0,
            time_constant_s: f32::NAN,
            max_rise_k: 10.0,
        };
        assert_eq!(
            CoilHeat::new(&bad, 5.0, 2.0, 1e4),
            Err(CoilHeatError("coil_thermal.time_constant_s"))
        );
    }
}
