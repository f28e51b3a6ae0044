//! Independent f64 reference integration of the dynamic model (paper eqs (4)-(5)).
//!
//! Shares no algorithm with the core's fixed-step model:
//! * the eddy-current equation is integrated in the paper's integral form (8): the variable
//!   `w = H + M` obeys `w' = c1 (I - H(w) / c0)`, where `H(w)` solves `H + Γ(H) = w` along the
//!   monotone path from the committed Preisach memory (exactly, on the relay-level operator);
//! * the magnetoelastic equation (5) is integrated as a first-order system together with `w`;
//! * the integrator is classical RK4 with `substeps` (default 100) substeps per control period,
//!   the memory committed at the end of each substep (stage evaluations do not commit).
//!
//! `H(w)` is 1-Lipschitz (`Γ` is non-decreasing along the path), so the `w` equation is a
//! well-posed Lipschitz ODE with rate at most `c1 / c0`; with 100 substeps at 10 kHz the RK4 stage
//! product `δ c1 / c0 ≈ 0.1` is well inside RK4's stability region.
//!
//! The current is a function of time supplied by the caller; for comparisons with the core it is
//! the zero-order-held control sequence (constant over each period, as a DAC makes it).

/// A hysteresis operator the reference can integrate: the relay-level Preisach operator.
pub trait MonotoneHysteresis {
    /// Output `M` at the committed state, A/m.
    fn output_a_per_m(&self) -> f64;
    /// Input at the committed state, A/m.
    fn input_a_per_m(&self) -> f64;
    /// Solves `a·h + Γ(h) = r` (`a > 0`) along the monotone path from the committed state without
    /// changing it; returns `(h, Γ(h))`.
    fn preview_solve(&self, a: f64, r: f64) -> (f64, f64);
    /// Moves the committed state to input `h`; returns `Γ(h)`.
    fn commit(&mut self, h_a_per_m: f64) -> f64;
}

/// Actuator constants the reference needs, f64.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlantConstants {
    /// c1 = R_eddy / (μ0 N_m A_m), 1/(m·s).
    pub c1_per_m_s: f64,
    /// c0, 1/m.
    pub c0_per_m: f64,
    /// ω0 = 2π f0, rad/s.
    pub omega0_rad_per_s: f64,
    /// ξ.
    pub damping_ratio: f64,
    /// l_m λ_s / M_s², m per (A/m)².
    pub displacement_per_m2_m: f64,
}

impl PlantConstants {
    /// From the parameter file.
    pub fn from_params(p: &actuator_params::ActuatorParams) -> Self {
        let a = &p.actuator;
        let mu0 = 4.0e-7 * std::f64::consts::PI;
        PlantConstants {
            c1_per_m_s: a.eddy_resistance_ohm / (mu0 * a.coil_turns * a.rod_area_m2),
            c0_per_m: a.coil_factor_per_m,
            omega0_rad_per_s: 2.0 * std::f64::consts::PI * a.resonance_hz,
            damping_ratio: a.damping_ratio,
            displacement_per_m2_m: a.rod_length_m * a.saturation_magnetostriction
                / (a.saturation_magnetization_a_per_m * a.saturation_magnetization_a_per_m),
        }
    }
}

/// One sample of the reference trajectory.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlantSample {
    /// Time, s.
    pub t_s: f64,
    /// Field H, A/m.
    pub h_a_per_m: f64,
    /// Magnetization M, A/m.
    pub m_a_per_m: f64,
    /// Displacement y, m.
    pub displacement_m: f64,
    /// Velocity y', m/s.
    pub velocity_m_per_s: f64,
}

/// The reference plant: hysteresis operator plus the continuous state `(w, y, y')`.
#[derive(Debug, Clone)]
pub struct ReferencePlant<P> {
    /// Constants.
    pub constants: PlantConstants,
    /// The Preisach memory.
    pub hysteresis: P,
    /// `w = H + M`, A/m.
    w_a_per_m: f64,
    displacement_m: f64,
    velocity_m_per_s: f64,
    t_s: f64,
}

impl<P: MonotoneHysteresis + Clone> ReferencePlant<P> {
    /// Equilibrium under constant current `current_a`: `H = c0 I` applied to the memory, `y` at its
    /// static value, at rest.
    pub fn equilibrium(constants: PlantConstants, mut hysteresis: P, current_a: f64) -> Self {
        let h = constants.c0_per_m * current_a;
        let m = hysteresis.commit(h);
        ReferencePlant {
            constants,
            hysteresis,
            w_a_per_m: h + m,
            displacement_m: constants.displacement_per_m2_m * m * m,
            velocity_m_per_s: 0.0,
            t_s: 0.0,
        }
    }

    /// A given state at time 0: the memory moved monotonically to field `h_a_per_m`, `w = H + M`
    /// consistent with it, and the mechanical state `(y, y')` as given (e.g. the state a
    /// controller assumes at its first sample, so a tracking run starts without a transient).
    pub fn at_state(
        constants: PlantConstants,
        mut hysteresis: P,
        h_a_per_m: f64,
        displacement_m: f64,
        velocity_m_per_s: f64,
    ) -> Self {
        let m = hysteresis.commit(h_a_per_m);
        ReferencePlant {
            constants,
            hysteresis,
            w_a_per_m: h_a_per_m + m,
            displacement_m,
            velocity_m_per_s,
            t_s: 0.0,
        }
    }

    /// Current sample.
    pub fn sample(&self) -> PlantSample {
        let (h, m) = self.field_of(self.w_a_per_m);
        PlantSample {
            t_s: self.t_s,
            h_a_per_m: h,
            m_a_per_m: m,
            displacement_m: self.displacement_m,
            velocity_m_per_s: self.velocity_m_per_s,
        }
    }

    /// `(H, M)` with `H + Γ(H) = w` along the path from the committed memory.
    fn field_of(&self, w: f64) -> (f64, f64) {
        self.hysteresis.preview_solve(1.0, w)
    }

    /// Right-hand side of the first-order system `(w, y, y')` at current `i`.
    fn derivatives(&self, i: f64, w: f64, y: f64, v: f64) -> [f64; 3] {
        let c = &self.constants;
        let (h, m) = self.field_of(w);
        let u = c.displacement_per_m2_m * m * m;
        let w_dot = c.c1_per_m_s * (i - h / c.c0_per_m);
        let om = c.omega0_rad_per_s;
        let v_dot = -2.0 * c.damping_ratio * om * v - om * om * y + om * om * u;
        [w_dot, v, v_dot]
    }

    /// Advances by `duration_s` in `substeps` RK4 substeps with the current given by `current_a`
    /// (a function of absolute time, evaluated at the stage times).
    pub fn advance(
        &mut self,
        duration_s: f64,
        substeps: usize,
        current_a: &dyn Fn(f64) -> f64,
    ) -> PlantSample {
        let dt = duration_s / substeps as f64;
        for _ in 0..substeps {
            let t = self.t_s;
            let (w, y, v) = (self.w_a_per_m, self.displacement_m, self.velocity_m_per_s);
            // Stage currents: evaluate just inside the substep so a zero-order-held input that
            // changes exactly at period boundaries is sampled on the correct side.
            let i0 = current_a(t + 1e-9 * dt);
            let im = current_a(t + 0.5 * dt);
            let i1 = current_a(t + (1.0 - 1e-9) * dt);
            let k1 = self.derivatives(i0, w, y, v);
            let k2 = self.derivatives(
                im,
                w + 0.5 * dt * k1[0],
                y + 0.5 * dt * k1[1],
                v + 0.5 * dt * k1[2],
            );
            let k3 = self.derivatives(
                im,
                w + 0.5 * dt * k2[0],
                y + 0.5 * dt * k2[1],
                v + 0.5 * dt * k2[2],
            );
            let k4 = self.derivatives(i1, w + dt * k3[0], y + dt * k3[1], v + dt * k3[2]);
            self.w_a_per_m = w + dt / 6.0 * (k1[0] + 2.0 * k2[0] + 2.0 * k3[0] + k4[0]);
            self.displacement_m = y + dt / 6.0 * (k1[1] + 2.0 * k2[1] + 2.0 * k3[1] + k4[1]);
            self.velocity_m_per_s = v + dt / 6.0 * (k1[2] + 2.0 * k2[2] + 2.0 * k3[2] + k4[2]);
            let (h, _) = self.field_of(self.w_a_per_m);
            self.hysteresis.commit(h);
            self.t_s = t + dt;
        }
        self.sample()
    }
}

/// Runs the reference on a zero-order-held current sequence (`currents_a[k]` held over
/// `[k T, (k+1) T)`), returning one sample at the end of every period.
pub fn simulate_held<P: MonotoneHysteresis + Clone>(
    plant: &mut ReferencePlant<P>,
    period_s: f64,
    substeps: usize,
    currents_a: &[f64],
) -> Vec<PlantSample> {
    currents_a
        .iter()
        .map(|&i| plant.advance(period_s, substeps, &|_t| i))
        .collect()
}

/// The relay-level Preisach operator of [`super::preisach`] with its state, as the hysteresis of
/// the reference plant.
#[derive(Debug, Clone)]
pub struct RelayHysteresis<'a> {
    /// The relay field (coefficients).
    pub field: &'a super::preisach::RelayPreisach,
    /// Its state.
    pub state: super::preisach::RelayState,
}

impl MonotoneHysteresis for RelayHysteresis<'_> {
    fn output_a_per_m(&self) -> f64 {
        self.field.output_a_per_m(&self.state)
    }
    fn input_a_per_m(&self) -> f64 {
        let (lo, hi) = self.field.range_a_per_m();
        lo + self.state.input_normalized() * (hi - lo) / magctl::preisach::LEVELS as f64
    }
    fn preview_solve(&self, a: f64, r: f64) -> (f64, f64) {
        self.field.preview_solve(&self.state, a, r)
    }
    fn commit(&mut self, h_a_per_m: f64) -> f64 {
        self.field.apply_a_per_m(&mut self.state, h_a_per_m)
    }
}

/// The relay operator plus a reversible part `R` (see
/// [`super::preisach::reversible_a_per_m`]): `M = Γ(h) + R(h)`. Its solve is exact: on each
/// interval of `R` (between two grid lines, or beyond the grid where `R` is flat)
/// `a·h + R(h) = (a + χ_k) h + c_k` is linear, so `a·h + Γ(h) + R(h) = r` there is the relay
/// operator's own exact solve with slope `a + χ_k` and target `r − c_k`; the intervals are tried
/// along the path's direction until the solution falls inside one (the left side is monotone, so
/// the first one that holds it is the answer).
#[derive(Clone)]
pub struct ReversibleRelayHysteresis<'a> {
    relays: RelayHysteresis<'a>,
    lines_a_per_m: Vec<f64>,
    susceptibility: Vec<f64>,
    /// Whether any `χ_k` is nonzero (without, the solve is the relay operator's own).
    has_reversible: bool,
}

impl<'a> ReversibleRelayHysteresis<'a> {
    /// The relay operator with its state, plus `R` on the `L + 1` grid lines (A/m) with one
    /// susceptibility `χ_k` per interval.
    pub fn new(
        relays: RelayHysteresis<'a>,
        lines_a_per_m: Vec<f64>,
        susceptibility: Vec<f64>,
    ) -> Self {
        let has_reversible = susceptibility.iter().any(|&c| c != 0.0);
        ReversibleRelayHysteresis {
            relays,
            lines_a_per_m,
            susceptibility,
            has_reversible,
        }
    }

    fn reversible(&self, h_a_per_m: f64) -> f64 {
        super::preisach::reversible_a_per_m(&self.lines_a_per_m, &self.susceptibility, h_a_per_m)
    }

    /// Interval `k` of `R` as `(lower, upper, χ)`: `k = 0` below the grid, `1..=L` the grid's
    /// intervals, `L + 1` above the grid.
    fn piece(&self, k: usize) -> (f64, f64, f64) {
        let lines = &self.lines_a_per_m;
        let n = lines.len() - 1;
        if k == 0 {
            (f64::NEG_INFINITY, lines[0], 0.0)
        } else if k > n {
            (lines[n], f64::INFINITY, 0.0)
        } else {
            (lines[k - 1], lines[k], self.susceptibility[k - 1])
        }
    }
}

impl MonotoneHysteresis for ReversibleRelayHysteresis<'_> {
    fn output_a_per_m(&self) -> f64 {
        self.relays.output_a_per_m() + self.reversible(self.input_a_per_m())
    }
    fn input_a_per_m(&self) -> f64 {
        // (on the grid's own lines, equal or not)
        self.relays
            .field
            .field_of(self.relays.state.input_normalized())
    }
    fn preview_solve(&self, a: f64, r: f64) -> (f64, f64) {
        if !self.has_reversible {
            return self.relays.preview_solve(a, r);
        }
        let h0 = self.input_a_per_m();
        let rising = a * h0 + self.output_a_per_m() < r;
        let n = self.lines_a_per_m.len() - 1;
        // The piece holding h0 (on a line: the one the path enters).
        let mut k = (1..=n + 1)
            .find(|&k| {
                let (lo, hi, _) = self.piece(k);
                if rising {
                    h0 >= lo && h0 < hi
                } else {
                    h0 > lo && h0 <= hi
                }
            })
            .unwrap_or(0);
        loop {
            let (lo, hi, chi) = self.piece(k);
            // R(h) = R(anchor) + χ (h − anchor) on this piece.
            let anchor = if lo.is_finite() { lo } else { hi };
            let c = self.reversible(anchor) - chi * anchor;
            let (h, m) = self.relays.preview_solve(a + chi, r - c);
            let inside = if rising { h <= hi } else { h >= lo };
            let last = if rising { k == n + 1 } else { k == 0 };
            if inside || last {
                return (h, m + self.reversible(h));
            }
            k = if rising { k + 1 } else { k - 1 };
        }
    }
    fn commit(&mut self, h_a_per_m: f64) -> f64 {
        self.relays.commit(h_a_per_m) + self.reversible(h_a_per_m)
    }
}
