//! The continuous-time bench plant: coil, rod (eddy currents and hysteresis), magnetoelastic
//! dynamics, load, sensor, with the effects of [`crate::effects`] switched on.
//!
//! # Equations (paper eqs (4)-(5), written in differential form)
//!
//! The paper's eddy equation `H' + M' = c1 (I − H/c0)`, `M = Γ[H]` (eq. (4)) is integrated for the
//! field itself: along the branch the input moves on, `M' = χ(H) H'` with `χ = dΓ/dH` the exact
//! branch slope of the plant's own Preisach operator ([`crate::preisach`]), so
//!
//! `H' = c1 (I − H/c0 − Σ J_k) / (1 + χ(H) + χ_rev(H))`,
//!
//! with `J_k` the currents of the distributed eddy paths (`eddy_frequency_dependence`, a Foster
//! ladder: `τ_k J_k' = w'/c1_k − J_k`, `w' = H' + M'`) and `χ_rev` the slope of the reversible
//! term. `M` is carried as a state for the stages of a step and reset to the exact Preisach output
//! when the step is committed. The model under test (`magctl::model`, `maglab_diagnose::model`)
//! instead solves the integral form (8) implicitly for `w = H + M`: the two share no equation
//! beyond the paper's.
//!
//! Mechanics, eq. (5) per unit mass: `y1'' + 2ξω0 y1' + ω0² k (y1 − u) = −(load) − (friction)`,
//! `u = (l_m λ_s(T)/M_s²) M² + e T_rod` (+ creep), `k` the Δ-E stiffness factor.
//!
//! # Integration
//!
//! Classical RK4 with a fixed substep, at most 5 µs and at most a quarter of the fastest time
//! constant of the plant (the eddy mode at `χ = 0` right after a reversal, `c0/c1`; the amplifier,
//! sensor and load modes), so every mode is resolved, not merely stable. The Preisach memory is
//! committed at the end of each substep (stages preview the branch without committing). The
//! command is held or linear over each sample interval, as the bench settings say.

use crate::effects::Effect;
use crate::preisach::{PreisachGrid, PreisachMemory};
use actuator_params::ActuatorParams;
use std::f64::consts::PI;

/// μ0, H/m.
const MU0: f64 = 4.0e-7 * PI;

/// Longest substep, s.
pub const MAX_SUBSTEP_S: f64 = 5e-6;

/// Positive zeros of the Bessel function J0 (radial eddy-current modes of a cylinder).
const BESSEL_J0_ZEROS: [f64; 8] = [
    2.404_825_557_7,
    5.520_078_110_3,
    8.653_727_912_9,
    11.791_534_439_0,
    14.930_917_708_5,
    18.071_063_967_9,
    21.211_636_629_9,
    24.352_471_530_7,
];

use maglab_dataset::StartState;

/// The start states the plant can be put in ([`Plant::start`]): every state but `periodic`.
pub const PLANT_STARTS: [StartState; 6] = [
    StartState::SwitchOnDemagnetized,
    StartState::Demagnetized,
    StartState::DemagnetizedAtFirstInput,
    StartState::NegativeSaturation,
    StartState::PositiveSaturation,
    StartState::Previous,
];

#[derive(Debug, Clone, Copy)]
struct Amplifier {
    omega: f64,
    zeta: f64,
    slew: f64,
}

#[derive(Debug, Clone, Copy)]
struct SensorFilter {
    omega: f64,
    zeta: f64,
}

#[derive(Debug, Clone, Copy)]
struct Thermal {
    rise: f64,
    tau_coil: f64,
    tau_rod: f64,
    tempco: f64,
    loss: f64,
    expansion: f64,
}

#[derive(Debug, Clone, Copy)]
struct LoadModes {
    r2: f64,
    w2: f64,
    z2: f64,
    r3: f64,
    w3: f64,
    z3: f64,
}

#[derive(Debug, Clone, Copy)]
struct Friction {
    static_accel: f64,
    kinetic_accel: f64,
}

/// The effects resolved into the plant's coefficients.
#[derive(Debug, Clone, Default)]
struct Resolved {
    /// `(1/c1_k, τ_k)` of the distributed eddy paths.
    paths: Vec<(f64, f64)>,
    amplifier: Option<Amplifier>,
    sensor: Option<SensorFilter>,
    sensor_delay_s: f64,
    reversible: Option<(f64, f64)>,
    thermal: Option<Thermal>,
    delta_e: Option<(f64, f64)>,
    load: Option<LoadModes>,
    backlash_m: Option<f64>,
    friction: Option<Friction>,
    /// `(ratio, τ0)`.
    creep: Option<(f64, f64)>,
    /// `(g, null, half range)`.
    sensor_gain_change: Option<(f64, f64, f64)>,
}

/// Indices of the state vector.
const I_COIL: usize = 0;
const DI_COIL: usize = 1;
const H: usize = 2;
const M: usize = 3;
const Y1: usize = 4;
const V1: usize = 5;
const Y2: usize = 6;
const V2: usize = 7;
const Y3: usize = 8;
const V3: usize = 9;
const S1: usize = 10;
const S2: usize = 11;
const T_COIL: usize = 12;
const T_ROD: usize = 13;
const CREEP0: usize = 14;
const J0: usize = 17;

/// The nominal constants of the plant, f64.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlantConstants {
    /// `c0`, 1/m.
    pub c0_per_m: f64,
    /// `c1 = R_eddy / (μ0 N A)`, 1/(m·s).
    pub c1_per_m_s: f64,
    /// `ω0`, rad/s.
    pub omega0_rad_per_s: f64,
    /// `ξ`.
    pub damping_ratio: f64,
    /// `l_m λ_s / M_s²`, m per (A/m)².
    pub displacement_per_m2_m: f64,
    /// `M_s`, A/m.
    pub saturation_a_per_m: f64,
    /// `l_m λ_s`, m.
    pub stroke_m: f64,
}

impl PlantConstants {
    /// From a parameter file.
    pub fn from_params(p: &ActuatorParams) -> Self {
        let a = &p.actuator;
        PlantConstants {
            c0_per_m: a.coil_factor_per_m,
            c1_per_m_s: a.eddy_resistance_ohm / (MU0 * a.coil_turns * a.rod_area_m2),
            omega0_rad_per_s: 2.0 * PI * a.resonance_hz,
            damping_ratio: a.damping_ratio,
            displacement_per_m2_m: a.rod_length_m * a.saturation_magnetostriction
                / (a.saturation_magnetization_a_per_m * a.saturation_magnetization_a_per_m),
            saturation_a_per_m: a.saturation_magnetization_a_per_m,
            stroke_m: a.rod_length_m * a.saturation_magnetostriction,
        }
    }
}

/// The bench plant (see the module docs).
#[derive(Debug, Clone)]
pub struct Plant {
    grid: PreisachGrid,
    memory: PreisachMemory,
    constants: PlantConstants,
    fx: Resolved,
    x: Vec<f64>,
    sample_s: f64,
    substeps: usize,
    t_s: f64,
    stuck: bool,
    slide_sign: f64,
    backlash_z: f64,
    /// Sensor output (before delay, nonlinearity, offset, noise) at every substep, oldest first,
    /// with the time of the first entry.
    history: Vec<f64>,
    history_t0_s: f64,
    keep_history: bool,
    scratch: Scratch,
}

/// RK4 work vectors (kept to avoid allocating per substep).
#[derive(Debug, Clone, Default)]
struct Scratch {
    x0: Vec<f64>,
    k: [Vec<f64>; 4],
    stage: Vec<f64>,
}

impl Plant {
    /// A plant for `params` with `effects`, sampled at `sample_rate_hz`, at rest and
    /// demagnetized at 0 A (call [`Plant::start`] before an experiment).
    pub fn new(
        params: &ActuatorParams,
        effects: &[Effect],
        sample_rate_hz: f64,
    ) -> Result<Self, String> {
        Self::validated(params)?;
        Self::with_measure(
            params,
            PreisachGrid::from_params(params)?,
            effects,
            sample_rate_hz,
        )
    }

    /// The plant's constants must validate before its measure is built from them.
    fn validated(params: &ActuatorParams) -> Result<(), String> {
        params
            .validate("plant parameters")
            .map_err(|e| e.to_string())
    }

    /// A plant with the constants of `params` but the rod's own Preisach measure `grid` (a
    /// [`crate::rods::Rod`] on the plant's grid; the file's grid and masses are not used).
    pub fn with_rod(
        params: &ActuatorParams,
        rod: &crate::rods::Rod,
        effects: &[Effect],
        sample_rate_hz: f64,
    ) -> Result<Self, String> {
        Self::validated(params)?;
        Self::with_measure(params, rod.grid(params)?, effects, sample_rate_hz)
    }

    fn with_measure(
        params: &ActuatorParams,
        grid: PreisachGrid,
        effects: &[Effect],
        sample_rate_hz: f64,
    ) -> Result<Self, String> {
        crate::effects::check_unique(effects)?;
        if !(sample_rate_hz.is_finite() && sample_rate_hz > 0.0) {
            return Err(format!("sample rate must be > 0 Hz, got {sample_rate_hz}"));
        }
        let constants = PlantConstants::from_params(params);
        let fx = resolve(&constants, effects);
        let n_paths = fx.paths.len();
        let sample_s = 1.0 / sample_rate_hz;
        // Fastest time constant (module docs).
        let mut fastest = params.actuator.coil_factor_per_m / constants.c1_per_m_s;
        for &(_, tau) in &fx.paths {
            fastest = fastest.min(tau);
        }
        if let Some(a) = fx.amplifier {
            fastest = fastest.min(1.0 / (a.omega * (a.zeta + 1.0)));
        }
        if let Some(s) = fx.sensor {
            fastest = fastest.min(1.0 / (s.omega * (s.zeta + 1.0)));
        }
        if let Some(l) = fx.load {
            let top = (l.w2 * (1.0 + l.r2).sqrt()).max(l.w3 * (1.0 + l.r3 / l.r2.max(1e-9)).sqrt());
            fastest = fastest.min(1.0 / (top * (1.0 + l.z2.max(l.z3))));
        }
        let max_substep = MAX_SUBSTEP_S.min(0.25 * fastest);
        let substeps = (sample_s / max_substep).ceil().max(1.0) as usize;
        let memory = PreisachMemory::ac_demagnetized(&grid, 0.0, DEMAG_RATIO, DEMAG_FLOOR_A_PER_M);
        let mut plant = Plant {
            grid,
            memory,
            constants,
            fx,
            x: vec![0.0; J0 + n_paths],
            sample_s,
            substeps,
            t_s: 0.0,
            stuck: false,
            slide_sign: 0.0,
            backlash_z: 0.0,
            history: Vec::new(),
            history_t0_s: 0.0,
            keep_history: true,
            scratch: Scratch::default(),
        };
        plant.settle_at_rest(0.0, true);
        Ok(plant)
    }

    /// Substeps per sample interval.
    pub fn substeps(&self) -> usize {
        self.substeps
    }

    /// Time since the start of the current experiment, s.
    pub fn time_s(&self) -> f64 {
        self.t_s
    }

    /// Field H, A/m.
    pub fn field_a_per_m(&self) -> f64 {
        self.x[H]
    }

    /// Magnetization M (hysteretic plus reversible), A/m.
    pub fn magnetization_a_per_m(&self) -> f64 {
        self.x[M]
    }

    /// Displacement at the sensor's target (before the sensor), m.
    pub fn displacement_m(&self) -> f64 {
        self.observed()
    }

    /// Coil current, A.
    pub fn coil_current_a(&self) -> f64 {
        self.x[I_COIL]
    }

    /// Rod temperature rise, K.
    pub fn rod_temperature_rise_k(&self) -> f64 {
        self.x[T_ROD]
    }

    /// Puts the plant in `start` before an experiment whose first command is `first_command_a`;
    /// the experiment's time starts at 0. `periodic` is a property of a whole record, not a
    /// state the plant can be put in: an error.
    pub fn start(&mut self, start: StartState, first_command_a: f64) -> Result<(), String> {
        match start {
            StartState::Previous => {}
            StartState::SwitchOnDemagnetized => {
                self.memory = PreisachMemory::ac_demagnetized(
                    &self.grid,
                    0.0,
                    DEMAG_RATIO,
                    DEMAG_FLOOR_A_PER_M,
                );
                self.settle_at_rest(0.0, true);
            }
            StartState::Demagnetized => {
                self.memory = PreisachMemory::ac_demagnetized(
                    &self.grid,
                    0.0,
                    DEMAG_RATIO,
                    DEMAG_FLOOR_A_PER_M,
                );
                self.settle_at_rest(first_command_a, true);
            }
            StartState::NegativeSaturation => {
                self.memory = PreisachMemory::negative_saturation(&self.grid);
                self.settle_at_rest(first_command_a, true);
            }
            StartState::PositiveSaturation => {
                self.memory = PreisachMemory::positive_saturation(&self.grid);
                self.settle_at_rest(first_command_a, true);
            }
            StartState::DemagnetizedAtFirstInput => {
                self.memory = PreisachMemory::ac_demagnetized(
                    &self.grid,
                    self.constants.c0_per_m * first_command_a,
                    DEMAG_RATIO,
                    DEMAG_FLOOR_A_PER_M,
                );
                self.settle_at_rest(first_command_a, true);
            }
            StartState::Periodic => {
                return Err(
                    "the bench plant cannot start `periodic`: it is a property of a \
                     record, not a state (play the record once, then record it again with \
                     `previous`)"
                        .into(),
                )
            }
            StartState::Conditioned => {
                return Err(
                    "the bench plant cannot start `conditioned`: the reach a conditioning sweeps \
                     is the controller's, not the rod's (command the sweep, then record with \
                     `previous`)"
                        .into(),
                )
            }
        }
        self.t_s = 0.0;
        let s = self.sensor_state_output();
        self.history.clear();
        self.history.push(s);
        self.history_t0_s = 0.0;
        Ok(())
    }

    /// Sets the rod's motion (and a load's, rigidly) at the present instant: displacement `y_m`,
    /// velocity `v_m_per_s` (e.g. the state a controller assumes at its first sample, so a
    /// tracking run starts without a transient).
    pub fn set_motion(&mut self, y_m: f64, v_m_per_s: f64) {
        for i in [Y1, Y2, Y3] {
            self.x[i] = y_m;
        }
        for i in [V1, V2, V3] {
            self.x[i] = v_m_per_s;
        }
        self.stuck = false;
        self.backlash_z = y_m;
        self.x[S1] = y_m;
        self.x[S2] = v_m_per_s;
        self.history.clear();
        self.history.push(self.sensor_state_output());
        self.history_t0_s = self.t_s;
    }

    /// Static equilibrium under the constant current `current_a`: the memory moved there
    /// quasi-statically, at rest; `cold` resets the temperatures.
    fn settle_at_rest(&mut self, current_a: f64, cold: bool) {
        let h = self.constants.c0_per_m * current_a;
        self.memory.move_to(&self.grid, h);
        let m = self.memory.output_a_per_m(&self.grid) + self.reversible(h).0;
        let n = self.x.len();
        let (tc, tr) = (self.x[T_COIL], self.x[T_ROD]);
        self.x = vec![0.0; n];
        if !cold {
            self.x[T_COIL] = tc;
            self.x[T_ROD] = tr;
        }
        self.x[I_COIL] = current_a;
        self.x[H] = h;
        self.x[M] = m;
        let u = self.static_strain(m, self.x[T_ROD]);
        let u_eff = match self.fx.creep {
            Some((ratio, _)) => {
                for k in 0..3 {
                    self.x[CREEP0 + k] = u;
                }
                u * (1.0 + ratio)
            }
            None => u,
        };
        for i in [Y1, Y2, Y3] {
            self.x[i] = u_eff;
        }
        self.stuck = self.fx.friction.is_some();
        self.slide_sign = 0.0;
        self.backlash_z = u_eff;
        self.x[S1] = u_eff;
    }

    /// `(M_rev(h), dM_rev/dh)`.
    fn reversible(&self, h: f64) -> (f64, f64) {
        match self.fx.reversible {
            Some((chi, hr)) => {
                let t = (h / hr).tanh();
                (chi * hr * t, chi * (1.0 - t * t))
            }
            None => (0.0, 0.0),
        }
    }

    /// `(l_m λ_s(T)/M_s²) M² + e T`.
    fn static_strain(&self, m: f64, t_rod: f64) -> f64 {
        let k = self.constants.displacement_per_m2_m;
        match self.fx.thermal {
            Some(t) => k * (1.0 - t.loss * t_rod).max(0.0) * m * m + t.expansion * t_rod,
            None => k * m * m,
        }
    }

    fn observed_of(&self, x: &[f64]) -> f64 {
        if self.fx.load.is_some() {
            x[Y2]
        } else {
            x[Y1]
        }
    }

    fn observed(&self) -> f64 {
        self.observed_of(&self.x)
    }

    /// The sensor's continuous output before its delay and nonlinearity.
    fn sensor_state_output(&self) -> f64 {
        if self.fx.sensor.is_some() {
            self.x[S1]
        } else {
            self.backlash_z
        }
    }

    /// Net acceleration of the rod head without friction.
    fn rod_acceleration(&self, x: &[f64], u_eff: f64) -> f64 {
        let c = &self.constants;
        let om0 = c.omega0_rad_per_s;
        let stiffness = match self.fx.delta_e {
            Some((d, s)) => {
                let m = x[M] / c.saturation_a_per_m;
                let m2 = m * m;
                let strain = (x[Y1] - u_eff) / c.stroke_m;
                let q = (1.0 - m2) * (1.0 - m2);
                ((1.0 + d) / (1.0 + d * q) + s * strain).max(0.05)
            }
            None => 1.0,
        };
        let mut a1 = -2.0 * c.damping_ratio * om0 * x[V1] - om0 * om0 * stiffness * (x[Y1] - u_eff);
        if let Some(l) = self.fx.load {
            let coupling = l.w2 * l.w2 * (x[Y1] - x[Y2]) + 2.0 * l.z2 * l.w2 * (x[V1] - x[V2]);
            a1 -= l.r2 * coupling;
        }
        a1
    }

    fn derivatives(&self, command_a: f64, x: &[f64], dx: &mut [f64]) {
        let c = &self.constants;
        // Coil current.
        let i = match self.fx.amplifier {
            Some(a) => {
                dx[I_COIL] = x[DI_COIL].clamp(-a.slew, a.slew);
                dx[DI_COIL] = a.omega * a.omega * (command_a - x[I_COIL])
                    - 2.0 * a.zeta * a.omega * x[DI_COIL];
                x[I_COIL]
            }
            None => {
                dx[I_COIL] = 0.0;
                dx[DI_COIL] = 0.0;
                command_a
            }
        };
        // Eddy currents and hysteresis (module docs).
        let h = x[H];
        let j_sum: f64 = x[J0..].iter().sum();
        let w_dot = c.c1_per_m_s * (i - h / c.c0_per_m - j_sum);
        let chi = self.memory.slope_towards(&self.grid, h) + self.reversible(h).1;
        let h_dot = w_dot / (1.0 + chi);
        dx[H] = h_dot;
        dx[M] = chi * h_dot;
        for (k, &(inv_c1k, tau)) in self.fx.paths.iter().enumerate() {
            dx[J0 + k] = (w_dot * inv_c1k - x[J0 + k]) / tau;
        }
        // Temperatures.
        match self.fx.thermal {
            Some(t) => {
                // Copper resistance rises with temperature (heating ~ I² R(T)); the coil's
                // insulation limit (200 K rise) caps it, so the plant cannot run away.
                let heating = t.rise * i * i * (1.0 + t.tempco * x[T_COIL].clamp(0.0, MAX_RISE_K));
                let heating = if x[T_COIL] >= MAX_RISE_K {
                    heating.min(x[T_COIL])
                } else {
                    heating
                };
                dx[T_COIL] = (heating - x[T_COIL]) / t.tau_coil;
                dx[T_ROD] = (x[T_COIL] - x[T_ROD]) / t.tau_rod;
            }
            None => {
                dx[T_COIL] = 0.0;
                dx[T_ROD] = 0.0;
            }
        }
        // Strain drive, creep.
        let u = self.static_strain(x[M], x[T_ROD]);
        let u_eff = match self.fx.creep {
            Some((ratio, tau0)) => {
                let mut tau = tau0;
                let mut acc = 0.0;
                for k in 0..3 {
                    dx[CREEP0 + k] = (u - x[CREEP0 + k]) / tau;
                    acc += x[CREEP0 + k];
                    tau *= 10.0;
                }
                u + ratio * acc / 3.0
            }
            None => {
                for k in 0..3 {
                    dx[CREEP0 + k] = 0.0;
                }
                u
            }
        };
        // Rod head, with friction.
        let mut a1 = self.rod_acceleration(x, u_eff);
        if let Some(f) = self.fx.friction {
            if self.stuck {
                a1 = 0.0;
            } else {
                let dir = if x[V1] != 0.0 {
                    x[V1].signum()
                } else {
                    self.slide_sign
                };
                a1 -= f.kinetic_accel * dir;
            }
        }
        dx[Y1] = if self.stuck { 0.0 } else { x[V1] };
        dx[V1] = a1;
        // Load masses.
        match self.fx.load {
            Some(l) => {
                let c12 = l.w2 * l.w2 * (x[Y1] - x[Y2]) + 2.0 * l.z2 * l.w2 * (x[V1] - x[V2]);
                let c23 = l.w3 * l.w3 * (x[Y2] - x[Y3]) + 2.0 * l.z3 * l.w3 * (x[V2] - x[V3]);
                dx[Y2] = x[V2];
                dx[V2] = c12 - if l.r2 > 0.0 { l.r3 / l.r2 } else { 0.0 } * c23;
                dx[Y3] = x[V3];
                dx[V3] = c23;
            }
            None => {
                dx[Y2] = 0.0;
                dx[V2] = 0.0;
                dx[Y3] = 0.0;
                dx[V3] = 0.0;
            }
        }
        // Sensor low-pass, driven by the (backlash) follower position.
        match self.fx.sensor {
            Some(s) => {
                dx[S1] = x[S2];
                dx[S2] =
                    s.omega * s.omega * (self.backlash_z - x[S1]) - 2.0 * s.zeta * s.omega * x[S2];
            }
            None => {
                dx[S1] = 0.0;
                dx[S2] = 0.0;
            }
        }
    }

    /// Advances one sample interval with the command going from `command_start_a` to
    /// `command_end_a` (equal for a held command).
    pub fn advance(&mut self, command_start_a: f64, command_end_a: f64) {
        let n = self.x.len();
        let dt = self.sample_s / self.substeps as f64;
        let mut w = std::mem::take(&mut self.scratch);
        w.x0.resize(n, 0.0);
        w.stage.resize(n, 0.0);
        for k in w.k.iter_mut() {
            k.resize(n, 0.0);
        }
        let cmd = |frac: f64| command_start_a + (command_end_a - command_start_a) * frac;
        for s in 0..self.substeps {
            let f0 = s as f64 / self.substeps as f64;
            let fh = (s as f64 + 0.5) / self.substeps as f64;
            let f1 = (s as f64 + 1.0) / self.substeps as f64;
            w.x0.copy_from_slice(&self.x);
            let [k1, k2, k3, k4] = &mut w.k;
            self.derivatives(cmd(f0), &w.x0, k1);
            for ((st, x0), k) in w.stage.iter_mut().zip(&w.x0).zip(k1.iter()) {
                *st = x0 + 0.5 * dt * k;
            }
            self.derivatives(cmd(fh), &w.stage, k2);
            for ((st, x0), k) in w.stage.iter_mut().zip(&w.x0).zip(k2.iter()) {
                *st = x0 + 0.5 * dt * k;
            }
            self.derivatives(cmd(fh), &w.stage, k3);
            for ((st, x0), k) in w.stage.iter_mut().zip(&w.x0).zip(k3.iter()) {
                *st = x0 + dt * k;
            }
            self.derivatives(cmd(f1), &w.stage, k4);
            for q in 0..n {
                self.x[q] = w.x0[q] + dt / 6.0 * (k1[q] + 2.0 * k2[q] + 2.0 * k3[q] + k4[q]);
            }
            if self.fx.amplifier.is_none() {
                self.x[I_COIL] = cmd(f1);
            }
            self.commit(w.x0[V1]);
            self.t_s += dt;
            if self.keep_history {
                let v = self.sensor_state_output();
                self.history.push(v);
            }
        }
        self.scratch = w;
    }

    /// End of a substep: commit the Preisach memory and the discrete states.
    fn commit(&mut self, v1_before: f64) {
        let h = self.x[H];
        self.memory.move_to(&self.grid, h);
        self.x[M] = self.memory.output_a_per_m(&self.grid) + self.reversible(h).0;
        if let Some(f) = self.fx.friction {
            let u = self.static_strain(self.x[M], self.x[T_ROD]);
            let u_eff = match self.fx.creep {
                Some((ratio, _)) => {
                    u + ratio * (self.x[CREEP0] + self.x[CREEP0 + 1] + self.x[CREEP0 + 2]) / 3.0
                }
                None => u,
            };
            if self.stuck {
                self.x[V1] = 0.0;
                let a = self.rod_acceleration(&self.x, u_eff);
                if a.abs() > f.static_accel {
                    self.stuck = false;
                    self.slide_sign = a.signum();
                }
            } else if self.x[V1] * v1_before < 0.0 || self.x[V1] == 0.0 {
                // The head stopped within the substep: it sticks unless the force breaks it
                // away again at once.
                self.x[V1] = 0.0;
                let a = self.rod_acceleration(&self.x, u_eff);
                if a.abs() <= f.static_accel {
                    self.stuck = true;
                } else {
                    self.slide_sign = a.signum();
                }
            } else {
                self.slide_sign = self.x[V1].signum();
            }
        }
        // The play operator of the linkage (rate independent: exact at substep resolution).
        let y = self.observed();
        self.backlash_z = match self.fx.backlash_m {
            Some(width) => {
                let half = 0.5 * width;
                if y - self.backlash_z > half {
                    y - half
                } else if self.backlash_z - y > half {
                    y + half
                } else {
                    self.backlash_z
                }
            }
            None => y,
        };
    }

    /// The sensor reading at experiment time `t_s` (before noise and quantization): the sensor's
    /// continuous output delayed by its conversion delay, through its gain nonlinearity.
    /// `t_s` before the start gives the start value; it must not lie beyond the simulated time.
    pub fn sensor_at(&self, t_s: f64) -> f64 {
        let t = t_s - self.fx.sensor_delay_s;
        let dt = self.sample_s / self.substeps as f64;
        let pos = (t - self.history_t0_s) / dt;
        let v = if pos <= 0.0 || self.history.len() < 2 {
            self.history.first().copied().unwrap_or(0.0)
        } else {
            let i = pos.floor() as usize;
            if i + 1 >= self.history.len() {
                *self.history.last().unwrap_or(&0.0)
            } else {
                let frac = pos - i as f64;
                self.history[i] * (1.0 - frac) + self.history[i + 1] * frac
            }
        };
        match self.fx.sensor_gain_change {
            // An odd (S-shaped) gain error about the sensor's null, as an LVDT has: the gain
            // changes by g from the null to the ends of its linear range.
            Some((g, null, range)) => {
                let u = (v - null) / range;
                v + g / 3.0 * range * u * u * u
            }
            None => v,
        }
    }

    /// Drops sensor history older than `keep_s` before the present (for long closed-loop runs).
    pub fn trim_history(&mut self, keep_s: f64) {
        let dt = self.sample_s / self.substeps as f64;
        let keep = ((keep_s + self.fx.sensor_delay_s) / dt).ceil() as usize + 2;
        if self.history.len() > 2 * keep {
            let drop = self.history.len() - keep;
            self.history.drain(..drop);
            self.history_t0_s += drop as f64 * dt;
        }
    }
}

/// Largest coil temperature rise the thermal model reaches (insulation limit), K.
pub const MAX_RISE_K: f64 = 200.0;

/// Amplitude ratio per half cycle of the plant's AC demagnetization.
pub const DEMAG_RATIO: f64 = 0.98;
/// The demagnetizing field stops below this amplitude, A/m.
pub const DEMAG_FLOOR_A_PER_M: f64 = 1.0;

fn resolve(c: &PlantConstants, effects: &[Effect]) -> Resolved {
    let mut r = Resolved::default();
    for e in effects {
        match e.name() {
            "eddy_frequency_dependence" => {
                let share = e.get("share");
                let f1 = e.get("first_corner_hz");
                let n = (e.get("paths").round() as usize).clamp(3, BESSEL_J0_ZEROS.len());
                let norm: f64 = BESSEL_J0_ZEROS[..n].iter().map(|j| 1.0 / (j * j)).sum();
                // Σ 1/c1_k = (1/c1) share / (1 - share): conductances add (module docs).
                let total_inv = share / (1.0 - share) / c.c1_per_m_s;
                let j1 = BESSEL_J0_ZEROS[0];
                r.paths = BESSEL_J0_ZEROS[..n]
                    .iter()
                    .map(|&j| {
                        let inv_c1k = total_inv * (1.0 / (j * j)) / norm;
                        let corner = f1 * (j / j1) * (j / j1);
                        (inv_c1k, 1.0 / (2.0 * PI * corner))
                    })
                    .collect();
            }
            "amplifier_bandwidth" => {
                r.amplifier = Some(Amplifier {
                    omega: 2.0 * PI * e.get("natural_hz"),
                    zeta: e.get("damping_ratio"),
                    slew: e.get("slew_a_per_s"),
                })
            }
            "sensor_dynamics" => {
                r.sensor = Some(SensorFilter {
                    omega: 2.0 * PI * e.get("natural_hz"),
                    zeta: e.get("damping_ratio"),
                });
                r.sensor_delay_s = e.get("delay_s");
            }
            "reversible_magnetization" => {
                r.reversible = Some((e.get("susceptibility"), e.get("saturation_field_a_per_m")))
            }
            "thermal_drift" => {
                r.thermal = Some(Thermal {
                    rise: e.get("coil_rise_k_per_a2"),
                    tau_coil: e.get("coil_time_constant_s"),
                    tau_rod: e.get("rod_time_constant_s"),
                    tempco: e.get("copper_tempco_per_k"),
                    loss: e.get("magnetostriction_loss_per_k"),
                    expansion: e.get("expansion_m_per_k"),
                })
            }
            "delta_e_effect" => {
                r.delta_e = Some((
                    e.get("magnetization_stiffening"),
                    e.get("stress_stiffening"),
                ))
            }
            "mechanical_load" => {
                let r2 = e.get("mass_ratio").max(1e-6);
                r.load = Some(LoadModes {
                    r2,
                    w2: 2.0 * PI * e.get("coupling_hz"),
                    z2: e.get("damping_ratio"),
                    // The second mass is given relative to the first.
                    r3: r2 * e.get("second_mass_ratio"),
                    w3: 2.0 * PI * e.get("second_coupling_hz"),
                    z3: e.get("second_damping_ratio"),
                })
            }
            "backlash" => r.backlash_m = Some(e.get("width_m")),
            "stick_slip" => {
                let w2 = c.omega0_rad_per_s * c.omega0_rad_per_s;
                let s = w2 * e.get("breakaway_m");
                r.friction = Some(Friction {
                    static_accel: s,
                    kinetic_accel: s * e.get("kinetic_ratio"),
                })
            }
            "creep" => r.creep = Some((e.get("ratio"), e.get("time_constant_s"))),
            "sensor_nonlinearity" => {
                r.sensor_gain_change =
                    Some((e.get("gain_change"), e.get("null_m"), e.get("range_m")))
            }
            other => unreachable!("effect `{other}` has a spec but no plant form"),
        }
    }
    r
}
