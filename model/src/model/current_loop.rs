//! The library's amplifier: a current loop around the coil, as a model of the electromagnetic
//! stage sees it.
//!
//! **The loop.** The coil in units of `v/R` is `v = i + (τ_L/c0) w'`, `w = H + M` (the rod's
//! flux per `μ0 N A`, `L = μ0 N A c0`): resistive for the loop, with the whole flux EMF, the
//! coil's own inductance and the rod's eddy currents alike, a disturbance entering through
//! `w'`. A controller `C(s)` closing `v = C (i_cmd − i)` gives
//!
//! ```text
//! i = T i_cmd − (1 − T)(τ_L/c0) w',    T = C/(1 + C)
//! ```
//!
//! for any `C`: the loop passes the command through its closed-loop response `T` and leaves
//! `1 − T` of the EMF current. With eq. (4) this is `(Z + (τ_L/c0)(1 − T)) w' = T i_cmd − H/c0`
//! (`Z = 1/c1` the eddy impedance): the EMF the loop does not reject is an extra eddy impedance.
//!
//! **The controller** is a PI with its zero on the coil's pole and a filter pole,
//! `C(s) = K (1 + s τ_L)/(s (1 + s τ_f))`, so that
//!
//! ```text
//! T(s) = K (1 + s τ_L) / (τ_f s² + (1 + K τ_L) s + K)
//! ```
//!
//! parametrized by `(ωn, ζ, τ_L)` with `τ_f = 1/(2ζωn)`, `K = ωn/(2ζ)`. At `τ_L = 0` (an ideal
//! current source: no EMF reaches the current) it is the second-order low-pass
//! `ωn²/(s² + 2ζωn s + ωn²)` exactly. With `τ_f → 0` (ζ large) it is the PI loop tuned on the
//! coil (`K_p = ω_c τ_L`, crossover `ω_c = K`), whose `T = 1 − s/((1 + ω_c τ_L) s + ω_c)` is a
//! lag-lead, and whose EMF term below the crossover is one extra eddy path of impedance step
//! `(τ_L/c0)/(1 + ω_c τ_L)` (`docs/diagnosis.md`, "A PI loop of low crossover").
//!
//! **Discretization.** Both `T`s, on the command and on `w'`, are the same linear system
//! `x₁' = x₂`, `x₂' = −a₀ x₁ − a₁ x₂ + c`, `y = b₀ x₁ + b₁ x₂` (`a₀ = b₀ = K/τ_f`,
//! `a₁ = (1 + K τ_L)/τ_f`, `b₁ = K τ_L/τ_f`), stepped exactly
//! ([`super::LinearStep`]) with the command linear and `w'` constant over a substep. The eddy
//! step is backward Euler ([`super`]'s module docs): at the substep's end
//! `T(w') = C Φ x + g w'` with `g = C Γ₀`, so the loop adds `(τ_L/c0)(1 − g)` to the implicit
//! impedance and `(τ_L/c0) C Φ x` to the explicit current.

use super::LinearStep;

/// One current loop, discretized for a substep of `δ`.
#[derive(Debug, Clone, Copy)]
pub struct CurrentLoop {
    /// `T` over a substep with a linear input.
    step: LinearStep<2>,
    /// `(b₀, b₁)`: `y = b₀ x₁ + b₁ x₂`.
    output: [f64; 2],
    /// `T`'s state after a substep of zero input from `x`, projected on the output: `C Φ`.
    free: [f64; 2],
    /// `C Γ₀`: the output at a substep's end per unit of a constant input over it.
    forced: f64,
    /// `τ_L/c0`, the EMF's impedance, m·s.
    emf_impedance: f64,
}

impl CurrentLoop {
    /// The loop of closed-loop natural frequency `natural_hz`, damping `zeta` (both at
    /// `τ_L = 0`), coil time constant `coil_time_constant_s`, on a rod of `c0_per_m`, for
    /// substeps of `delta_s`.
    pub fn new(
        natural_hz: f64,
        zeta: f64,
        coil_time_constant_s: f64,
        c0_per_m: f64,
        delta_s: f64,
    ) -> Self {
        let omega = 2.0 * std::f64::consts::PI * natural_hz;
        let tau_f = 1.0 / (2.0 * zeta * omega);
        let k = omega / (2.0 * zeta);
        let tau_l = coil_time_constant_s.max(0.0);
        let a0 = k / tau_f;
        let a1 = (1.0 + k * tau_l) / tau_f;
        let step = LinearStep::new([[0.0, 1.0], [-a0, -a1]], [0.0, 1.0], delta_s);
        let mut current_loop = CurrentLoop {
            step,
            output: [a0, k * tau_l / tau_f],
            free: [0.0; 2],
            forced: 0.0,
            emf_impedance: tau_l / c0_per_m,
        };
        let response = |x: [f64; 2], c: f64| current_loop.output(step.step(x, c, c));
        let free = [response([1.0, 0.0], 0.0), response([0.0, 1.0], 0.0)];
        let forced = response([0.0, 0.0], 1.0);
        current_loop.free = free;
        current_loop.forced = forced;
        current_loop
    }

    /// The state at rest under a constant input `c` (`T(0) = 1`: the output is `c`).
    pub fn rest(&self, c: f64) -> [f64; 2] {
        [c / self.output[0], 0.0]
    }

    /// The output at state `x`.
    pub fn output(&self, x: [f64; 2]) -> f64 {
        self.output[0] * x[0] + self.output[1] * x[1]
    }

    /// The state after a substep with the input going linearly from `c_start` to `c_end`.
    pub fn advance(&self, x: [f64; 2], c_start: f64, c_end: f64) -> [f64; 2] {
        self.step.step(x, c_start, c_end)
    }

    /// The impedance the loop adds to the eddy step's implicit side, `(τ_L/c0)(1 − g)`, m·s.
    pub fn implicit_impedance(&self) -> f64 {
        self.emf_impedance * (1.0 - self.forced)
    }

    /// The current the EMF filter's state `x` (input `w'`) adds to the eddy step's explicit
    /// side at the end of the next substep, `(τ_L/c0) C Φ x`, A.
    pub fn explicit_current(&self, x: [f64; 2]) -> f64 {
        self.emf_impedance * (self.free[0] * x[0] + self.free[1] * x[1])
    }

    /// The EMF current the loop leaves in the coil over a substep whose flux rate was `w_rate`
    /// (per second) and whose EMF filter started at `x`: `(τ_L/c0)(w' − T(w'))`, A.
    pub fn emf_current(&self, x: [f64; 2], w_rate: f64) -> f64 {
        self.emf_impedance * (w_rate * (1.0 - self.forced)) - self.explicit_current(x)
    }
}
