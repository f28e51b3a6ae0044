//! The record's timing and the first-order lags of a finite-rate quasi-static sweep: what turns
//! `c0 I` and `y` into the `H` and `u` the static model (6) relates.

use actuator_params::ActuatorParams;

/// `x` read `shift` samples later: linear between samples, held at the ends.
pub fn shifted(x: &[f64], shift: f64) -> Vec<f64> {
    let n = x.len();
    if n == 0 {
        return Vec::new();
    }
    (0..n)
        .map(|k| {
            let t = (k as f64 + shift).clamp(0.0, (n - 1) as f64);
            let i = (t.floor() as usize).min(n - 1);
            let j = (i + 1).min(n - 1);
            x[i] + (t - i as f64) * (x[j] - x[i])
        })
        .collect()
}

/// First-order lag corrections of a finite-rate quasi-static record (the static model (6)
/// relates `H` and `u = l_m λ_s M²/M_s²`, not `c0 I` and `y`):
///
/// * mechanics, eq. (5): `u = y + (2ξ/ω0) y' + y''/ω0²` ([`LagCorrection::displacement`]; the rod
///   lags `u` by `2ξ/ω0` ≈ 0.6 ms);
/// * eddy currents, eq. (4): `H = c0 I − τ_e (H' + M')` with `τ_e = c0/c1`, to first order
///   `H ≈ c0 I − τ_e (c0 I' + M')` ([`LagCorrection::field`]): on a steep branch `M' = χ H'` with
///   χ in the hundreds, so even a 1 Hz sweep lags by ~0.1 cell there, a few % of `M_s` in `M`.
///
/// Derivatives are central differences across `±w` samples of a centred moving average over
/// `2w + 1` samples, `w` ≈ 0.5 ms: the noise of `y''` falls as `w⁻²·⁵` while a sweep slower than
/// ~10 Hz is not distorted.
#[derive(Debug, Clone, Copy)]
pub struct LagCorrection {
    tau_e: f64,
    damping_ratio: f64,
    omega0: f64,
    c0: f64,
}

impl LagCorrection {
    /// For the constants of `base` with `[R_eddy Ω, ξ, f0 Hz]`.
    pub fn new(base: &ActuatorParams, [r_eddy, xi, f0]: [f64; 3]) -> Self {
        let a = &base.actuator;
        let mu0 = 4e-7 * std::f64::consts::PI;
        let c1 = r_eddy / (mu0 * a.coil_turns * a.rod_area_m2);
        LagCorrection {
            tau_e: a.coil_factor_per_m / c1,
            damping_ratio: xi,
            omega0: 2.0 * std::f64::consts::PI * f0,
            c0: a.coil_factor_per_m,
        }
    }

    fn half_width(step_s: f64) -> usize {
        ((0.5e-3 / step_s).round() as usize).max(1)
    }

    fn smooth(x: &[f64], w: usize) -> Vec<f64> {
        let n = x.len();
        let mut prefix = vec![0.0; n + 1];
        for k in 0..n {
            prefix[k + 1] = prefix[k] + x[k];
        }
        (0..n)
            .map(|k| {
                let (lo, hi) = (k.saturating_sub(w), (k + w).min(n - 1));
                (prefix[hi + 1] - prefix[lo]) / (hi - lo + 1) as f64
            })
            .collect()
    }

    fn d1(x: &[f64], k: usize, w: usize, step_s: f64) -> f64 {
        let (lo, hi) = (k.saturating_sub(w), (k + w).min(x.len() - 1));
        if hi == lo {
            0.0
        } else {
            (x[hi] - x[lo]) / ((hi - lo) as f64 * step_s)
        }
    }

    /// `u` from the displacement `y` (offset already removed).
    pub fn displacement(&self, y: &[f64], step_s: f64) -> Vec<f64> {
        let n = y.len();
        let w = Self::half_width(step_s);
        let ys = Self::smooth(y, w);
        (0..n)
            .map(|k| {
                let d2 = if k < w || k + w >= n {
                    0.0
                } else {
                    (ys[k + w] - 2.0 * ys[k] + ys[k - w]) / (w as f64 * step_s).powi(2)
                };
                y[k] + 2.0 * self.damping_ratio / self.omega0 * Self::d1(&ys, k, w, step_s)
                    + d2 / (self.omega0 * self.omega0)
            })
            .collect()
    }

    /// How much [`LagCorrection::displacement`] amplifies white noise in `y`: the RMS of its
    /// output for white noise of unit RMS (the root sum of squares of its impulse response, away
    /// from the record's ends).
    pub fn noise_gain(&self, step_s: f64) -> f64 {
        let w = Self::half_width(step_s);
        let n = 8 * w + 1;
        let mut impulse = vec![0.0; n];
        impulse[n / 2] = 1.0;
        self.displacement(&impulse, step_s)
            .iter()
            .map(|v| v * v)
            .sum::<f64>()
            .sqrt()
    }

    /// `H` from the current and the (signed) magnetization.
    pub fn field(&self, current_a: &[f64], m_a_per_m: &[f64], step_s: f64) -> Vec<f64> {
        let w = Self::half_width(step_s);
        let is = Self::smooth(current_a, w);
        let ms = Self::smooth(m_a_per_m, w);
        (0..current_a.len())
            .map(|k| {
                self.c0 * current_a[k]
                    - self.tau_e
                        * (self.c0 * Self::d1(&is, k, w, step_s) + Self::d1(&ms, k, w, step_s))
            })
            .collect()
    }
}
