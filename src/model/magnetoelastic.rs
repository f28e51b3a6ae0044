//! The magnetoelastic dynamics (5), `y'' + 2ξω0 y' + ω0² y = ω0² (l_m λ_s / M_s²) M²`,
//! discretized exactly.
//!
//! Write `u = (l_m λ_s / M_s²) M²` (the static displacement (6) of the current magnetization). Over
//! one step the input is taken linear in time between its values at the two ends (first-order
//! hold): `u(t_k + τ) = u_k + (τ / h)(u_{k+1} - u_k)`. The linear system is then integrated
//! exactly: `x⁺ = Φ x + g0 u_k + g1 (u_{k+1} - u_k)` with `x = (y, y')`, where `Φ = e^{Ah}` and
//! `g0, g1` are the last two columns of the exponential of the augmented matrix
//!
//! ```text
//!      | A  b  0   |        A = | 0     1    |,  b = | 0   |
//! h ·  | 0  0  1/h |            | -ω0²  -2ξω0|       | ω0² |
//!      | 0  0  0   |
//! ```
//!
//! Exact for any `h` (stable at every rate, no Euler), and exact whenever `M²` is linear over the
//! step. A zero-order hold of `M²` would add half a sample of delay (7° of phase at 400 Hz and
//! 10 kHz); the first-order hold does not. The exponential is computed once, at construction, in
//! f64 with scaling and squaring on the velocity-scaled system (`y' / ω0`), whose norm is
//! `O(ω0 h + 1)`; coefficients are then rounded to f32.
//!
//! Cost per step: 8 multiply-adds.

use crate::params::Actuator;

/// Coefficients of the exact step of (5).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MagnetoelasticStep {
    /// `Φ` in `(y [m], y' [m/s])` coordinates.
    pub(crate) phi: [[f32; 2]; 2],
    /// Response to `u_k` held over the step.
    pub(crate) g0: [f32; 2],
    /// Response to the ramp `u_{k+1} - u_k` over the step.
    pub(crate) g1: [f32; 2],
    /// `l_m λ_s / M_s²`, m per (A/m)².
    pub(crate) displacement_per_m2_m: f32,
}

type Mat4 = [[f64; 4]; 4];

fn mat_mul(a: &Mat4, b: &Mat4) -> Mat4 {
    let mut c = [[0.0; 4]; 4];
    for (i, row) in c.iter_mut().enumerate() {
        for (j, cell) in row.iter_mut().enumerate() {
            let mut s = 0.0;
            for (k, bk) in b.iter().enumerate() {
                s += a[i][k] * bk[j];
            }
            *cell = s;
        }
    }
    c
}

/// `e^N` by scaling and squaring with a degree-20 Taylor series (f64; `|N|` is O(1) here, so
/// the truncation error is far below f64 rounding).
fn expm(n: &Mat4) -> Mat4 {
    let norm = n
        .iter()
        .map(|row| row.iter().map(|v| v.abs()).sum::<f64>())
        .fold(0.0, f64::max);
    let mut squarings = 0u32;
    let mut scale = 1.0;
    while norm * scale > 0.5 && squarings < 60 {
        scale *= 0.5;
        squarings += 1;
    }
    let mut scaled = *n;
    for row in scaled.iter_mut() {
        for v in row.iter_mut() {
            *v *= scale;
        }
    }
    let mut result = [[0.0; 4]; 4];
    let mut term = [[0.0; 4]; 4];
    for i in 0..4 {
        result[i][i] = 1.0;
        term[i][i] = 1.0;
    }
    for k in 1..=20 {
        term = mat_mul(&term, &scaled);
        let inv = 1.0 / k as f64;
        for row in term.iter_mut() {
            for v in row.iter_mut() {
                *v *= inv;
            }
        }
        for i in 0..4 {
            for j in 0..4 {
                result[i][j] += term[i][j];
            }
        }
    }
    for _ in 0..squarings {
        result = mat_mul(&result, &result);
    }
    result
}

impl MagnetoelasticStep {
    /// Coefficients for period `step_s` (s) from `f0`, `ξ`, `l_m`, `λ_s`, `M_s`.
    pub fn new(actuator: &Actuator, step_s: f32) -> Self {
        let omega = 2.0 * core::f64::consts::PI * actuator.resonance_hz as f64;
        let xi = actuator.damping_ratio as f64;
        let h = step_s as f64;
        // Velocity-scaled state (y, y'/ω0, u, Δu): y' = ω0 v, v' = -ω0 y - 2ξω0 v + ω0 u.
        let n: Mat4 = [
            [0.0, omega * h, 0.0, 0.0],
            [-omega * h, -2.0 * xi * omega * h, omega * h, 0.0],
            [0.0, 0.0, 0.0, 1.0],
            [0.0, 0.0, 0.0, 0.0],
        ];
        let e = expm(&n);
        // Back to (y, y'): scale the velocity row by ω0 and the velocity column by 1/ω0.
        let phi = [
            [e[0][0] as f32, (e[0][1] / omega) as f32],
            [(e[1][0] * omega) as f32, e[1][1] as f32],
        ];
        let g0 = [e[0][2] as f32, (e[1][2] * omega) as f32];
        let g1 = [e[0][3] as f32, (e[1][3] * omega) as f32];
        let m_s = actuator.saturation_magnetization_a_per_m as f64;
        let gain = actuator.rod_length_m as f64 * actuator.saturation_magnetostriction as f64
            / (m_s * m_s);
        MagnetoelasticStep {
            phi,
            g0,
            g1,
            displacement_per_m2_m: gain as f32,
        }
    }

    /// Static displacement `(l_m λ_s / M_s²) M²` of magnetization `m_a_per_m` (equation (6)), m.
    #[inline]
    pub fn static_displacement_m(&self, m_a_per_m: f32) -> f32 {
        self.displacement_per_m2_m * m_a_per_m * m_a_per_m
    }

    /// Advances `(y, y')` over one step with the static displacement going linearly from
    /// `u_start_m` to `u_end_m`. Returns the new `(y, y')` in (m, m/s).
    #[inline]
    pub fn step(
        &self,
        displacement_m: f32,
        velocity_m_per_s: f32,
        u_start_m: f32,
        u_end_m: f32,
    ) -> (f32, f32) {
        let du = u_end_m - u_start_m;
        let y = self.phi[0][0] * displacement_m
            + self.phi[0][1] * velocity_m_per_s
            + self.g0[0] * u_start_m
            + self.g1[0] * du;
        let v = self.phi[1][0] * displacement_m
            + self.phi[1][1] * velocity_m_per_s
            + self.g0[1] * u_start_m
            + self.g1[1] * du;
        (y, v)
    }
}
