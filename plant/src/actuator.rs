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
use crate::forms::{
    resolve, Amplifier, AmplifierForm, Backlash, BacklashForm, DeltaEForm, Friction, FrictionForm,
    Resolved, Thermal, ThermalForm, CREEP_TERMS,
};
use crate::preisach::{PreisachGrid, PreisachMemory};
use actuator_params::ActuatorParams;
use std::f64::consts::PI;

/// μ0, H/m.
const MU0: f64 = 4.0e-7 * PI;

/// Longest substep, s.
pub const MAX_SUBSTEP_S: f64 = 5e-6;

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
const Y4: usize = 10;
const V4: usize = 11;
const S1: usize = 12;
const S2: usize = 13;
const T_COIL: usize = 14;
/// The rod's temperature (its outer shell in the distributed form).
const T_ROD: usize = 15;
const T_SHELL2: usize = 16;
const T_SHELL3: usize = 17;
/// The current the sensed PI loop reads (its sense filter's output).
const I_SENSED: usize = 18;
const CREEP0: usize = 19;
const J0: usize = CREEP0 + CREEP_TERMS;

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
    /// `κ = τ_L c1/c0`: the rod's eddy resistance as a coil of time constant `tau_l_s` sees it,
    /// over the coil's own resistance (`L = μ0 N A c0`).
    pub fn reflected_eddy_ratio(&self, tau_l_s: f64) -> f64 {
        tau_l_s * self.c1_per_m_s / self.c0_per_m
    }

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
    /// The play operator's output ahead of a lagging follower; the displacement at the last
    /// commit (smooth play).
    backlash_play: f64,
    backlash_y_prev: f64,
    /// Dahl friction force per unit mass, m/s².
    dahl_accel: f64,
    /// Sensor output (before delay, nonlinearity, offset, noise) at every substep, oldest first,
    /// with the time of the first entry.
    history: Vec<f64>,
    /// The coil current at the start of every substep (what a current monitor reads just
    /// after the command's update: a held command is a staircase, read on its new step), A,
    /// from the same time as `history`.
    current_history: Vec<f64>,
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
            // The sense filter's pole, sped up by the loop's proportional path through the
            // coil: `τ_s i_s' = i − i_s` with `i` falling by `K_p/(1 + κ)` per unit of `i_s`.
            if let AmplifierForm::SensedPiLoop {
                tau_l,
                tau_z,
                omega_sense,
                ..
            } = a.form
            {
                let kappa = constants.reflected_eddy_ratio(tau_l);
                let kp = a.omega * tau_z;
                fastest = fastest.min(1.0 / (omega_sense * (1.0 + kp / (1.0 + kappa))));
            }
        }
        if let Some(s) = fx.sensor {
            fastest = fastest.min(1.0 / (s.omega * (s.zeta + 1.0)));
        }
        if let Some(l) = fx.load {
            let mut top = l.w2 * (1.0 + l.r2).sqrt();
            if l.modes >= 2 {
                top = top.max(l.w3 * (1.0 + l.r3 / l.r2.max(1e-9)).sqrt());
            }
            if l.modes >= 3 {
                top = top.max(l.w4 * (1.0 + l.r4 / l.r3.max(1e-9)).sqrt());
            }
            fastest = fastest.min(1.0 / (top * (1.0 + l.z2.max(l.z3).max(l.z4))));
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
            backlash_play: 0.0,
            backlash_y_prev: 0.0,
            dahl_accel: 0.0,
            history: Vec::new(),
            current_history: Vec::new(),
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

    /// Coil temperature rise, K.
    pub fn coil_temperature_rise_k(&self) -> f64 {
        self.x[T_COIL]
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
        self.current_history.clear();
        self.history_t0_s = 0.0;
        Ok(())
    }

    /// Sets the rod's motion (and a load's, rigidly) at the present instant: displacement `y_m`,
    /// velocity `v_m_per_s` (e.g. the state a controller assumes at its first sample, so a
    /// tracking run starts without a transient).
    pub fn set_motion(&mut self, y_m: f64, v_m_per_s: f64) {
        for i in [Y1, Y2, Y3, Y4] {
            self.x[i] = y_m;
        }
        for i in [V1, V2, V3, V4] {
            self.x[i] = v_m_per_s;
        }
        self.stuck = false;
        self.backlash_z = y_m;
        self.backlash_play = y_m;
        self.backlash_y_prev = y_m;
        self.x[S1] = y_m;
        self.x[S2] = v_m_per_s;
        self.history.clear();
        self.history.push(self.sensor_state_output());
        self.current_history.clear();
        self.history_t0_s = self.t_s;
    }

    /// Static equilibrium under the constant current `current_a`: the memory moved there
    /// quasi-statically, at rest; `cold` resets the temperatures.
    fn settle_at_rest(&mut self, current_a: f64, cold: bool) {
        let h = self.constants.c0_per_m * current_a;
        self.memory.move_to(&self.grid, h);
        let m = self.memory.output_a_per_m(&self.grid) + self.reversible(h).0;
        let n = self.x.len();
        let temperatures = [T_COIL, T_ROD, T_SHELL2, T_SHELL3].map(|k| self.x[k]);
        self.x = vec![0.0; n];
        if !cold {
            for (k, t) in [T_COIL, T_ROD, T_SHELL2, T_SHELL3]
                .into_iter()
                .zip(temperatures)
            {
                self.x[k] = t;
            }
        }
        self.x[I_COIL] = current_a;
        self.x[I_SENSED] = current_a;
        // At rest the PI loop's integrator holds the whole voltage (`v = i`).
        self.x[DI_COIL] = match self.fx.amplifier.map(|a| a.form) {
            Some(AmplifierForm::PiLoop { .. } | AmplifierForm::SensedPiLoop { .. }) => current_a,
            _ => 0.0,
        };
        self.x[H] = h;
        self.x[M] = m;
        let u = self.static_strain(m, self.rod_temperature(&self.x));
        let u_eff = match self.fx.creep {
            Some(c) => {
                for k in 0..c.terms {
                    self.x[CREEP0 + k] = u;
                }
                u * (1.0 + c.ratio)
            }
            None => u,
        };
        for i in [Y1, Y2, Y3, Y4] {
            self.x[i] = u_eff;
        }
        self.stuck = self
            .fx
            .friction
            .is_some_and(|f| !matches!(f.form, FrictionForm::Dahl { .. }));
        self.slide_sign = 0.0;
        self.dahl_accel = 0.0;
        self.backlash_z = u_eff;
        self.backlash_play = u_eff;
        self.backlash_y_prev = u_eff;
        self.x[S1] = u_eff;
    }

    /// `(M_rev(h), dM_rev/dh)`.
    fn reversible(&self, h: f64) -> (f64, f64) {
        match self.fx.reversible {
            Some((0, chi, hr)) => {
                let t = (h / hr).tanh();
                (chi * hr * t, chi * (1.0 - t * t))
            }
            // Langevin: 3 χ0 H_r L(x), x = H/H_r, L(x) = coth x − 1/x (slope 1/3 at 0); the
            // series below |x| = 0.05 (error < 1e-11) avoids the cancellation of coth x − 1/x.
            Some((1, chi, hr)) => {
                let x = h / hr;
                let (l, dl) = if x.abs() < 0.05 {
                    let x2 = x * x;
                    (
                        x / 3.0 - x * x2 / 45.0 + 2.0 * x * x2 * x2 / 945.0,
                        1.0 / 3.0 - x2 / 15.0 + 2.0 * x2 * x2 / 189.0,
                    )
                } else {
                    let sh = x.sinh();
                    (1.0 / x.tanh() - 1.0 / x, 1.0 / (x * x) - 1.0 / (sh * sh))
                };
                (3.0 * chi * hr * l, 3.0 * chi * dl)
            }
            // Fröhlich–Kennelly: χ0 H / (1 + |H|/H_r).
            Some((_, chi, hr)) => {
                let q = 1.0 + h.abs() / hr;
                (chi * h / q, chi / (q * q))
            }
            None => (0.0, 0.0),
        }
    }

    /// The rod temperature the strain sees: its one node, or the mean of its three shells.
    fn rod_temperature(&self, x: &[f64]) -> f64 {
        match self.fx.thermal.map(|t| t.form) {
            Some(ThermalForm::Distributed) => (x[T_ROD] + x[T_SHELL2] + x[T_SHELL3]) / 3.0,
            _ => x[T_ROD],
        }
    }

    /// The creep strain added to the static strain `u`.
    fn creep_strain(&self, x: &[f64]) -> f64 {
        match self.fx.creep {
            Some(c) => {
                let sum: f64 = x[CREEP0..CREEP0 + c.terms].iter().sum();
                c.ratio * sum / c.terms as f64
            }
            None => 0.0,
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
            Some(de) => {
                let m = x[M] / c.saturation_a_per_m;
                let strain = (x[Y1] - u_eff) / c.stroke_m;
                let k = match de.form {
                    DeltaEForm::Quartic => {
                        let q = (1.0 - m * m) * (1.0 - m * m);
                        (1.0 + de.d) / (1.0 + de.d * q)
                    }
                    DeltaEForm::Cubic => 1.0 + de.d * (m * m * m).abs(),
                    DeltaEForm::Field { h_s } => {
                        let t = (x[H] / h_s).tanh();
                        1.0 + de.d * t * t
                    }
                };
                (k + de.s * strain).max(0.05)
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

    /// The coil current at state `x` under `command_a` and, for the PI loop, its integrator's
    /// rate (`None` when the current is a state of its own or the command itself).
    ///
    /// The PI loop drives the coil, `v = R i + N A μ0 w'` (w = H + M the rod's flux per μ0 N A),
    /// in units of `v/R`: `v = i + κ (i − g)` with `w' = c1 (i − g)` (eq. (4)), `g = H/c0 + ΣJ`,
    /// `κ = τ_L c1 / c0` (`L = μ0 N A c0`). Its controller `v = K_p (cmd − i) + z`,
    /// `z' = ω_c (cmd − i)`, `K_p = ω_c τ_L` (the zero on the coil's pole: crossover at ω_c),
    /// gives `i` algebraically; at the voltage limit `v` is clamped and `z` held (anti-windup).
    /// The sensed PI loop reads `i_s` (`τ_s i_s' = i − i_s`) instead of `i`, with
    /// `K_p = ω_c τ_z`: `v` is then known before `i`, and `i = (v + κ g)/(1 + κ)`.
    fn coil_current(&self, command_a: f64, x: &[f64]) -> (f64, Option<f64>) {
        let c = &self.constants;
        let (i, dz) = match self.fx.amplifier {
            Some(Amplifier {
                form: AmplifierForm::PiLoop { tau_l, v_lim },
                omega,
                ..
            }) => {
                let kappa = c.reflected_eddy_ratio(tau_l);
                let kp = omega * tau_l;
                let g = x[H] / c.c0_per_m + x[J0..].iter().sum::<f64>();
                let z = x[DI_COIL];
                let i = (kp * command_a + z + kappa * g) / (1.0 + kp + kappa);
                let v = kp * (command_a - i) + z;
                if v.abs() > v_lim {
                    let v = v.clamp(-v_lim, v_lim);
                    ((v + kappa * g) / (1.0 + kappa), Some(0.0))
                } else {
                    (i, Some(omega * (command_a - i)))
                }
            }
            Some(Amplifier {
                form:
                    AmplifierForm::SensedPiLoop {
                        tau_l,
                        tau_z,
                        v_lim,
                        ..
                    },
                omega,
                ..
            }) => {
                let kappa = c.reflected_eddy_ratio(tau_l);
                let g = x[H] / c.c0_per_m + x[J0..].iter().sum::<f64>();
                let error = command_a - x[I_SENSED];
                let v = omega * tau_z * error + x[DI_COIL];
                let (v, dz) = if v.abs() > v_lim {
                    (v.clamp(-v_lim, v_lim), 0.0)
                } else {
                    (v, omega * error)
                };
                ((v + kappa * g) / (1.0 + kappa), Some(dz))
            }
            Some(_) => (x[I_COIL], None),
            None => (command_a, None),
        };
        // The amplifier's compliance voltage over the heated coil's resistance.
        match self.fx.thermal {
            Some(Thermal {
                form: ThermalForm::VoltageLimited { compliance_a },
                tempco,
                ..
            }) => {
                let cap = compliance_a / (1.0 + tempco * x[T_COIL].clamp(0.0, MAX_RISE_K));
                (i.clamp(-cap, cap), dz)
            }
            _ => (i, dz),
        }
    }

    /// The plant's state derivatives `dx` at the state `x` under the command `command_a`, one
    /// subsystem after the other: the coil current, the eddy currents and the hysteresis, the
    /// temperatures, the strain drive and its creep, the rod head with its friction, the load
    /// masses, the sensor.
    fn derivatives(&self, command_a: f64, x: &[f64], dx: &mut [f64]) {
        let (i, dz) = self.coil_current(command_a, x);
        self.amplifier_derivatives(command_a, x, (i, dz), dx);
        self.magnetic_derivatives(i, x, dx);
        self.thermal_derivatives(i, x, dx);
        // Strain drive, creep.
        let u = self.static_strain(x[M], self.rod_temperature(x));
        self.creep_derivatives(u, x, dx);
        let u_eff = u + self.creep_strain(x);
        // Rod head, with friction.
        dx[Y1] = if self.stuck { 0.0 } else { x[V1] };
        dx[V1] = self.with_friction(x, self.rod_acceleration(x, u_eff));
        self.load_derivatives(x, dx);
        self.sensor_derivatives(x, dx);
    }

    /// The amplifier's states: its current and rate (the second- and first-order forms), the PI
    /// loop's integrator (`dz`, with the coil current `i`), the sensed current's filter.
    fn amplifier_derivatives(
        &self,
        command_a: f64,
        x: &[f64],
        (i, dz): (f64, Option<f64>),
        dx: &mut [f64],
    ) {
        dx[I_COIL] = 0.0;
        dx[DI_COIL] = 0.0;
        match self.fx.amplifier {
            Some(a) if a.form == AmplifierForm::SecondOrder => {
                dx[I_COIL] = x[DI_COIL].clamp(-a.slew, a.slew);
                dx[DI_COIL] = a.omega * a.omega * (command_a - x[I_COIL])
                    - 2.0 * a.zeta * a.omega * x[DI_COIL];
            }
            Some(a) if a.form == AmplifierForm::FirstOrder => {
                dx[I_COIL] = (a.omega * (command_a - x[I_COIL])).clamp(-a.slew, a.slew);
            }
            _ => dx[DI_COIL] = dz.unwrap_or(0.0),
        }
        dx[I_SENSED] = match self.fx.amplifier {
            Some(Amplifier {
                form: AmplifierForm::SensedPiLoop { omega_sense, .. },
                ..
            }) => omega_sense * (i - x[I_SENSED]),
            _ => 0.0,
        };
    }

    /// Eddy currents and hysteresis (module docs) under the coil current `i`.
    fn magnetic_derivatives(&self, i: f64, x: &[f64], dx: &mut [f64]) {
        let c = &self.constants;
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
    }

    /// The coil's and the rod's temperatures under the coil current `i`.
    fn thermal_derivatives(&self, i: f64, x: &[f64], dx: &mut [f64]) {
        for k in [T_COIL, T_ROD, T_SHELL2, T_SHELL3] {
            dx[k] = 0.0;
        }
        let Some(t) = self.fx.thermal else {
            return;
        };
        // Copper resistance rises with temperature (heating ~ I² R(T)); the coil's insulation
        // limit (200 K rise) caps it, so the plant cannot run away.
        let heating = t.rise * i * i * (1.0 + t.tempco * x[T_COIL].clamp(0.0, MAX_RISE_K));
        let heating = if x[T_COIL] >= MAX_RISE_K {
            heating.min(x[T_COIL])
        } else {
            heating
        };
        dx[T_COIL] = (heating - x[T_COIL]) / t.tau_coil;
        if t.form == ThermalForm::Distributed {
            // Three shells in series, each link a third of the rod's time constant.
            let tau = t.tau_rod / 3.0;
            dx[T_ROD] = (x[T_COIL] - x[T_ROD]) / tau - (x[T_ROD] - x[T_SHELL2]) / tau;
            dx[T_SHELL2] = (x[T_ROD] - x[T_SHELL2]) / tau - (x[T_SHELL2] - x[T_SHELL3]) / tau;
            dx[T_SHELL3] = (x[T_SHELL2] - x[T_SHELL3]) / tau;
        } else {
            dx[T_ROD] = (x[T_COIL] - x[T_ROD]) / t.tau_rod;
        }
    }

    /// The creep terms, each relaxing towards the static strain drive `u`.
    fn creep_derivatives(&self, u: f64, x: &[f64], dx: &mut [f64]) {
        for k in 0..CREEP_TERMS {
            dx[CREEP0 + k] = 0.0;
        }
        if let Some(cr) = self.fx.creep {
            for k in 0..cr.terms {
                dx[CREEP0 + k] = (u - x[CREEP0 + k]) / cr.taus_s[k];
            }
        }
    }

    /// The rod head's acceleration `a1` with the friction: Dahl's presliding force; none while
    /// stuck; sliding, Coulomb's or Stribeck's against the direction of motion (of the last
    /// slide, at rest).
    fn with_friction(&self, x: &[f64], a1: f64) -> f64 {
        let Some(f) = self.fx.friction else {
            return a1;
        };
        if let FrictionForm::Dahl { .. } = f.form {
            return a1 - self.dahl_accel;
        }
        if self.stuck {
            return 0.0;
        }
        let dir = if x[V1] != 0.0 {
            x[V1].signum()
        } else {
            self.slide_sign
        };
        let level = match f.form {
            FrictionForm::Stribeck { speed_m_per_s } => {
                let q = x[V1] / speed_m_per_s;
                f.kinetic_accel + (f.static_accel - f.kinetic_accel) * (-q * q).exp()
            }
            _ => f.kinetic_accel,
        };
        a1 - level * dir
    }

    /// The load masses: a chain, each coupling's force shared by the masses it joins.
    fn load_derivatives(&self, x: &[f64], dx: &mut [f64]) {
        for k in [Y2, V2, Y3, V3, Y4, V4] {
            dx[k] = 0.0;
        }
        let Some(l) = self.fx.load else {
            return;
        };
        let coupling = |ya: usize, yb: usize, w: f64, z: f64| {
            w * w * (x[ya] - x[yb]) + 2.0 * z * w * (x[ya + 1] - x[yb + 1])
        };
        let c12 = coupling(Y1, Y2, l.w2, l.z2);
        let c23 = if l.modes >= 2 {
            coupling(Y2, Y3, l.w3, l.z3)
        } else {
            0.0
        };
        let c34 = if l.modes >= 3 {
            coupling(Y3, Y4, l.w4, l.z4)
        } else {
            0.0
        };
        dx[Y2] = x[V2];
        dx[V2] = c12 - l.r3 / l.r2 * c23;
        if l.modes >= 2 {
            dx[Y3] = x[V3];
            dx[V3] = c23 - if l.r3 > 0.0 { l.r4 / l.r3 } else { 0.0 } * c34;
        }
        if l.modes >= 3 {
            dx[Y4] = x[V4];
            dx[V4] = c34;
        }
    }

    /// The sensor's low-pass, driven by the (backlash) follower position.
    fn sensor_derivatives(&self, x: &[f64], dx: &mut [f64]) {
        dx[S1] = 0.0;
        dx[S2] = 0.0;
        if let Some(s) = self.fx.sensor {
            if s.second_order {
                dx[S1] = x[S2];
                dx[S2] =
                    s.omega * s.omega * (self.backlash_z - x[S1]) - 2.0 * s.zeta * s.omega * x[S2];
            } else {
                dx[S1] = s.omega * (self.backlash_z - x[S1]);
            }
        }
    }

    /// Whether the coil current is a state of its own (an amplifier with dynamics) rather than
    /// the command or an algebraic function of it.
    fn current_is_state(&self) -> bool {
        self.fx.amplifier.is_some_and(|a| {
            matches!(
                a.form,
                AmplifierForm::SecondOrder | AmplifierForm::FirstOrder
            )
        })
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
            if self.keep_history {
                self.current_history.push(if self.current_is_state() {
                    self.x[I_COIL]
                } else {
                    self.coil_current(cmd(f0), &self.x).0
                });
            }
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
            if !self.current_is_state() {
                self.x[I_COIL] = self.coil_current(cmd(f1), &self.x).0;
            }
            self.commit(w.x0[V1], w.x0[Y1]);
            self.t_s += dt;
            if self.keep_history {
                let v = self.sensor_state_output();
                self.history.push(v);
            }
        }
        self.scratch = w;
    }

    /// End of a substep: commit the Preisach memory and the discrete states.
    fn commit(&mut self, v1_before: f64, y1_before: f64) {
        let h = self.x[H];
        self.memory.move_to(&self.grid, h);
        self.x[M] = self.memory.output_a_per_m(&self.grid) + self.reversible(h).0;
        if let Some(f) = self.fx.friction {
            self.commit_friction(f, v1_before, self.x[Y1] - y1_before);
        }
        let y = self.observed();
        if let Some(b) = self.fx.backlash {
            self.commit_backlash(b, y);
        } else {
            self.backlash_z = y;
        }
        self.backlash_y_prev = y;
    }

    /// Friction's discrete state at the end of a substep: stuck or sliding (Coulomb, Stribeck),
    /// or the Dahl force moved along the substep's displacement.
    fn commit_friction(&mut self, f: Friction, v1_before: f64, dy: f64) {
        if let FrictionForm::Dahl { presliding_m } = f.form {
            // dF/dy = σ (1 − F/F_c sgn dy), solved exactly over the substep's dy (one sign):
            // F → s F_c + (F − s F_c) exp(−σ |dy| / F_c), σ = F_s / presliding.
            let fc = f.kinetic_accel.max(1e-30);
            let sigma = f.static_accel / presliding_m;
            let target = dy.signum() * fc;
            self.dahl_accel = target + (self.dahl_accel - target) * (-sigma * dy.abs() / fc).exp();
            return;
        }
        let u_eff = self.static_strain(self.x[M], self.rod_temperature(&self.x))
            + self.creep_strain(&self.x);
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

    /// The linkage's follower at the end of a substep, the displacement being `y` (rate
    /// independent forms exact at substep resolution).
    fn commit_backlash(&mut self, b: Backlash, y: f64) {
        let half = 0.5 * b.width_m;
        let play = |z: f64| {
            if y - z > half {
                y - half
            } else if z - y > half {
                y + half
            } else {
                z
            }
        };
        match b.form {
            BacklashForm::Play => self.backlash_z = play(self.backlash_z),
            BacklashForm::Lagging { omega } => {
                self.backlash_play = play(self.backlash_play);
                let dt = self.sample_s / self.substeps as f64;
                let k = 1.0 - (-omega * dt).exp();
                self.backlash_z += k * (self.backlash_play - self.backlash_z);
            }
            BacklashForm::Smooth => {
                // The follower takes the fraction q⁴ of the move, q its distance from the
                // trailing edge over the half width (1 at the edge: it moves with y).
                let dy = y - self.backlash_y_prev;
                let q = ((y - self.backlash_z) * dy.signum() / half.max(1e-15)).clamp(0.0, 1.0);
                let z = self.backlash_z + dy * q * q * q * q;
                self.backlash_z = z.clamp(y - half, y + half);
            }
        }
    }

    /// The sensor reading at experiment time `t_s` (before noise and quantization): the sensor's
    /// continuous output delayed by its conversion delay, through its gain nonlinearity.
    /// `t_s` before the start gives the start value; it must not lie beyond the simulated time.
    pub fn sensor_at(&self, t_s: f64) -> f64 {
        let t = t_s - self.fx.sensor_delay_s;
        let window = self.fx.sensor_window_s;
        let v = if window > 0.0 {
            // The laser's moving average: trapezoids on the substep grid over the window.
            let dt = self.sample_s / self.substeps as f64;
            let n = (window / dt).ceil().max(1.0) as usize;
            let step = window / n as f64;
            let mut sum = 0.5 * (self.history_at(t - window) + self.history_at(t));
            for k in 1..n {
                sum += self.history_at(t - window + k as f64 * step);
            }
            sum / n as f64
        } else {
            self.history_at(t)
        };
        match self.fx.sensor_gain_change {
            // The gain changes by g from the null to the ends of its linear range r.
            Some((form, g, null, range)) => {
                let u = (v - null) / range;
                match form {
                    // An LVDT's odd S-curve.
                    0 => v + g / 3.0 * range * u * u * u,
                    // A capacitive gap's even bow.
                    1 => v + g / 2.0 * range * u * u,
                    // A cyclic error of period r.
                    _ => v + g * range / (2.0 * PI) * (2.0 * PI * u).sin(),
                }
            }
            None => v,
        }
    }

    /// The coil current at experiment time `t_s` (what an ideal current monitor reads, before
    /// its noise): linear between substeps, the start value before the history, the last one
    /// after it. It must not lie beyond the simulated time.
    pub fn coil_current_at(&self, t_s: f64) -> f64 {
        self.at(&self.current_history, t_s)
    }

    /// The sensor's continuous output at `t_s`, linear between substeps; the start value before
    /// the history, the last one after it.
    fn history_at(&self, t_s: f64) -> f64 {
        self.at(&self.history, t_s)
    }

    /// `series` (one value per substep from `history_t0_s`) at `t_s`, linear between substeps.
    fn at(&self, series: &[f64], t_s: f64) -> f64 {
        let dt = self.sample_s / self.substeps as f64;
        let pos = (t_s - self.history_t0_s) / dt;
        if pos <= 0.0 || series.len() < 2 {
            series.first().copied().unwrap_or(0.0)
        } else {
            let i = pos.floor() as usize;
            if i + 1 >= series.len() {
                *series.last().unwrap_or(&0.0)
            } else {
                let frac = pos - i as f64;
                series[i] * (1.0 - frac) + series[i + 1] * frac
            }
        }
    }

    /// Drops sensor history older than `keep_s` before the present (for long closed-loop runs).
    pub fn trim_history(&mut self, keep_s: f64) {
        let dt = self.sample_s / self.substeps as f64;
        let keep =
            ((keep_s + self.fx.sensor_delay_s + self.fx.sensor_window_s) / dt).ceil() as usize + 2;
        if self.history.len() > 2 * keep {
            let drop = self.history.len() - keep;
            self.history.drain(..drop);
            self.current_history
                .drain(..drop.min(self.current_history.len()));
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
