//! The virtual test rig's plant: the f64 reference dynamics of [`super::dynamics`] (paper eqs
//! (4)-(5), relay-level Preisach operator, RK4 with substeps) extended with physical effects the
//! paper's model leaves out. `maglab rig` (crate `maglab-diagnose`) drives it to produce datasets
//! whose cause of disagreement with the nominal model is known to the test but not to the
//! diagnosis.
//!
//! # State and equations
//!
//! Continuous state `x = (i_coil, w, J_1..J_n, y1, v1, y2, v2, θ)`, integrated together by
//! classical RK4 with `substeps` substeps per sample (the Preisach memory committed at the end of
//! every substep, as in [`super::dynamics`]):
//!
//! * **amplifier_bandwidth**: the coil current follows the command through a first-order lag,
//!   `τ_a i_coil' = I_cmd - i_coil`, `τ_a = 1 / (2π f_a)`. Without it `i_coil = I_cmd`.
//! * **reversible_magnetization**: `M = Γ[H] + χ_r H`, so `w = H + M = (1 + χ_r) H + Γ[H]` and `H`
//!   follows from `w` by the monotone solve with slope `a = 1 + χ_r`.
//! * **eddy_frequency_dependence**: eq. (4) models the eddy currents as one resistor `R` in parallel
//!   with the magnetizing inductance: `I = H / c0 + V / R` with `V = μ0 N A w'`, i.e.
//!   `w' = c1 (I - H / c0)`. Distributed eddy currents (deeper current paths see more of the
//!   rod's own inductance, which is what the skin effect does) are added as a ladder of extra
//!   paths `k`, each a resistor `R_k` in series with an inductance `L_k = R_k τ_k`:
//!   `I = H / c0 + V / R + Σ J_k`, `L_k J_k' = V - R_k J_k`, giving
//!   `w' = c1 (I - H / c0 - Σ J_k)`, `τ_k J_k' = w' / c1_k - J_k` with `c1_k = R_k / (μ0 N A)`.
//!   The effective parallel resistance is `1 / R_eff(f) = 1/R + Σ_k Re[1 / (R_k (1 + j 2π f τ_k))]`:
//!   low at low frequency (all paths conduct), rising to `R` above the corners — R_eddy depends on
//!   frequency, as the paper suspects above 200 Hz.
//! * **thermal_drift**: the coil heats with `I²`: `τ_th θ' = ρ_th i_coil² - θ` (`ρ_th` the steady
//!   temperature rise per A², K/A²), and the magnetostriction scales as `λ_s (1 - κ θ)`, so the
//!   static displacement is `u = (1 - κ θ) l_m λ_s M² / M_s²`.
//! * **delta_e_effect**: the rod's stiffness (Young's modulus) depends on magnetization,
//!   `ω² = ω0² (1 + δ_E (M / M_s)²)`, the damping force `2 ξ ω0 y'` unchanged; eq. (5) becomes
//!   `y'' + 2 ξ ω0 y' + ω² (y - u) = 0`.
//! * **mechanical_load**: a load mass `m2 = r m1` coupled to the rod's head by a spring and damper
//!   (`ω2² = k2 / m2`, `2 ζ2 ω2 = c2 / m2`); the sensor sees the load:
//!   `y1'' = -2ξω0 y1' - ω²(y1 - u) - r (ω2² (y1 - y2) + 2ζ2ω2 (y1' - y2'))`,
//!   `y2'' = ω2² (y1 - y2) + 2ζ2ω2 (y1' - y2')`. Without it the sensor sees `y1`.
//!
//! The sensor chain (output linkage backlash, sensor low-pass and delay, noise, quantization) acts
//! on the sampled output and lives in [`sensor_chain`].
//!
//! # Accuracy
//!
//! RK4's stage product on the fastest mode is `δ c1 / c0 (1 + …)` ≈ `9.8 / substeps` at 10 kHz with
//! the paper's constants; `substeps = 20` keeps it at 0.5 (RK4 local error `≈ 0.5⁵/120` relative),
//! and the unit test below checks 20 against 40 substeps.

use super::dynamics::{MonotoneHysteresis, PlantConstants};

/// μ0, H/m.
const MU0: f64 = 4.0e-7 * std::f64::consts::PI;

/// One extra eddy-current path of the ladder.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EddyPath {
    /// Its resistance `R_k`, Ω (same scaling as `R_eddy` of eq. (4)).
    pub resistance_ohm: f64,
    /// Its corner frequency `1 / (2π τ_k)`, Hz.
    pub corner_hz: f64,
}

/// The second mechanical mode (load mass on a spring).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MechanicalLoad {
    /// `m2 / m1`.
    pub mass_ratio: f64,
    /// `√(k2 / m2) / 2π`, Hz.
    pub coupling_hz: f64,
    /// `ζ2` of the coupling.
    pub coupling_damping_ratio: f64,
}

/// Thermal drift of the output scale.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ThermalDrift {
    /// `τ_th`, s.
    pub time_constant_s: f64,
    /// `ρ_th`: steady temperature rise per A² of coil current, K/A².
    pub rise_k_per_a2: f64,
    /// `κ`: relative loss of magnetostriction per K, 1/K.
    pub scale_per_k: f64,
}

/// The effects of the plant (the sensor-side ones are in [`sensor_chain`]).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PlantEffects {
    /// Amplifier corner `f_a`, Hz.
    pub amplifier_corner_hz: Option<f64>,
    /// Extra eddy-current paths.
    pub eddy_paths: Vec<EddyPath>,
    /// `χ_r`.
    pub reversible_susceptibility: Option<f64>,
    /// Thermal drift.
    pub thermal: Option<ThermalDrift>,
    /// `δ_E`: relative stiffness change at saturation.
    pub delta_e: Option<f64>,
    /// Load mode.
    pub load: Option<MechanicalLoad>,
}

/// Extra constants the rig needs beyond [`PlantConstants`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RigConstants {
    /// The nominal constants.
    pub plant: PlantConstants,
    /// `μ0 N A`, V·s·m/A per (A/m/s)… i.e. `R / c1`, Ω·m·s.
    pub mu0_n_a: f64,
    /// `M_s`, A/m.
    pub saturation_a_per_m: f64,
}

impl RigConstants {
    /// From the parameter file.
    pub fn from_params(p: &actuator_params::ActuatorParams) -> Self {
        RigConstants {
            plant: PlantConstants::from_params(p),
            mu0_n_a: MU0 * p.actuator.coil_turns * p.actuator.rod_area_m2,
            saturation_a_per_m: p.actuator.saturation_magnetization_a_per_m,
        }
    }
}

/// The rig plant.
#[derive(Debug, Clone)]
pub struct RigPlant<P> {
    constants: RigConstants,
    effects: PlantEffects,
    /// The Preisach memory.
    pub hysteresis: P,
    /// `[i_coil, w, y1, v1, y2, v2, θ, J_1..J_n]`.
    x: Vec<f64>,
    /// `c1_k` and `τ_k` of the extra paths.
    paths: Vec<(f64, f64)>,
    t_s: f64,
}

const I_COIL: usize = 0;
const W: usize = 1;
const Y1: usize = 2;
const V1: usize = 3;
const Y2: usize = 4;
const V2: usize = 5;
const THETA: usize = 6;
const J0: usize = 7;

impl<P: MonotoneHysteresis + Clone> RigPlant<P> {
    /// Equilibrium under the constant command `current_a` from the given memory: `H = c0 I`, `M`
    /// from the memory (plus `χ_r H`), at rest, at ambient temperature, no eddy currents.
    pub fn equilibrium(
        constants: RigConstants,
        effects: PlantEffects,
        mut hysteresis: P,
        current_a: f64,
    ) -> Self {
        let chi = effects.reversible_susceptibility.unwrap_or(0.0);
        let h = constants.plant.c0_per_m * current_a;
        let m = hysteresis.commit(h) + chi * h;
        let u = constants.plant.displacement_per_m2_m * m * m;
        let paths: Vec<(f64, f64)> = effects
            .eddy_paths
            .iter()
            .map(|p| {
                (
                    p.resistance_ohm / constants.mu0_n_a,
                    1.0 / (2.0 * std::f64::consts::PI * p.corner_hz),
                )
            })
            .collect();
        let mut x = vec![0.0; J0 + paths.len()];
        x[I_COIL] = current_a;
        x[W] = h + m;
        x[Y1] = u;
        x[Y2] = u;
        RigPlant {
            constants,
            effects,
            hysteresis,
            x,
            paths,
            t_s: 0.0,
        }
    }

    /// Time, s.
    pub fn time_s(&self) -> f64 {
        self.t_s
    }

    /// `(H, M)` for `w` from the committed memory.
    fn field_of(&self, w: f64) -> (f64, f64) {
        let chi = self.effects.reversible_susceptibility.unwrap_or(0.0);
        let (h, g) = self.hysteresis.preview_solve(1.0 + chi, w);
        (h, g + chi * h)
    }

    fn derivatives(&self, command_a: f64, x: &[f64], dx: &mut [f64]) {
        let c = &self.constants.plant;
        let i = match self.effects.amplifier_corner_hz {
            Some(f) => {
                dx[I_COIL] = 2.0 * std::f64::consts::PI * f * (command_a - x[I_COIL]);
                x[I_COIL]
            }
            None => {
                dx[I_COIL] = 0.0;
                command_a
            }
        };
        let (h, m) = self.field_of(x[W]);
        let j_sum: f64 = x[J0..].iter().sum();
        let w_dot = c.c1_per_m_s * (i - h / c.c0_per_m - j_sum);
        dx[W] = w_dot;
        for (k, &(c1k, tau)) in self.paths.iter().enumerate() {
            dx[J0 + k] = (w_dot / c1k - x[J0 + k]) / tau;
        }
        let scale = match self.effects.thermal {
            Some(t) => {
                dx[THETA] = (t.rise_k_per_a2 * i * i - x[THETA]) / t.time_constant_s;
                1.0 - t.scale_per_k * x[THETA]
            }
            None => {
                dx[THETA] = 0.0;
                1.0
            }
        };
        let u = scale * c.displacement_per_m2_m * m * m;
        let om0 = c.omega0_rad_per_s;
        let om2 = match self.effects.delta_e {
            Some(d) => {
                let r = m / self.constants.saturation_a_per_m;
                om0 * om0 * (1.0 + d * r * r)
            }
            None => om0 * om0,
        };
        let mut a1 = -2.0 * c.damping_ratio * om0 * x[V1] - om2 * (x[Y1] - u);
        dx[Y1] = x[V1];
        match self.effects.load {
            Some(l) => {
                let w2 = 2.0 * std::f64::consts::PI * l.coupling_hz;
                let coupling = w2 * w2 * (x[Y1] - x[Y2])
                    + 2.0 * l.coupling_damping_ratio * w2 * (x[V1] - x[V2]);
                a1 -= l.mass_ratio * coupling;
                dx[Y2] = x[V2];
                dx[V2] = coupling;
            }
            None => {
                dx[Y2] = 0.0;
                dx[V2] = 0.0;
            }
        }
        dx[V1] = a1;
    }

    /// Advances by `duration_s` in `substeps` RK4 substeps under the command `command_a` held
    /// constant; returns the displacement the sensor sees (load if present, else the rod's head).
    pub fn advance_held(&mut self, duration_s: f64, substeps: usize, command_a: f64) -> f64 {
        let dt = duration_s / substeps as f64;
        let n = self.x.len();
        let (mut k1, mut k2, mut k3, mut k4) =
            (vec![0.0; n], vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        let mut x0 = vec![0.0; n];
        let mut stage = vec![0.0; n];
        for _ in 0..substeps {
            x0.copy_from_slice(&self.x);
            self.derivatives(command_a, &x0, &mut k1);
            for q in 0..n {
                stage[q] = x0[q] + 0.5 * dt * k1[q];
            }
            self.derivatives(command_a, &stage, &mut k2);
            for q in 0..n {
                stage[q] = x0[q] + 0.5 * dt * k2[q];
            }
            self.derivatives(command_a, &stage, &mut k3);
            for q in 0..n {
                stage[q] = x0[q] + dt * k3[q];
            }
            self.derivatives(command_a, &stage, &mut k4);
            for q in 0..n {
                self.x[q] = x0[q] + dt / 6.0 * (k1[q] + 2.0 * k2[q] + 2.0 * k3[q] + k4[q]);
            }
            if self.effects.amplifier_corner_hz.is_none() {
                self.x[I_COIL] = command_a;
            }
            let (h, _) = self.field_of(self.x[W]);
            self.hysteresis.commit(h);
            self.t_s += dt;
        }
        self.output_m()
    }

    /// The displacement the sensor sees, m.
    pub fn output_m(&self) -> f64 {
        if self.effects.load.is_some() {
            self.x[Y2]
        } else {
            self.x[Y1]
        }
    }

    /// Coil temperature rise θ, K.
    pub fn temperature_rise_k(&self) -> f64 {
        self.x[THETA]
    }
}

/// Effective parallel eddy resistance of eq. (4) with the ladder at frequency `f_hz`, Ω.
pub fn effective_eddy_resistance_ohm(main_ohm: f64, paths: &[EddyPath], f_hz: f64) -> f64 {
    let mut g = 1.0 / main_ohm;
    for p in paths {
        let wt = f_hz / p.corner_hz;
        g += 1.0 / (p.resistance_ohm * (1.0 + wt * wt));
    }
    1.0 / g
}

/// The sensor side of the rig, acting on the sampled displacement.
pub mod sensor_chain {
    /// Play (backlash) of width `width_m` in the output linkage: the follower moves only when the
    /// driver pushes it at one end of the gap (the play operator; rate independent, so exact on
    /// samples of a piecewise-linear motion). Starts centred.
    pub fn backlash(y_m: &[f64], width_m: f64) -> Vec<f64> {
        let half = 0.5 * width_m;
        let mut out = Vec::with_capacity(y_m.len());
        let mut z = y_m.first().copied().unwrap_or(0.0);
        for &y in y_m {
            if y - z > half {
                z = y - half;
            } else if z - y > half {
                z = y + half;
            }
            out.push(z);
        }
        out
    }

    /// First-order low-pass `τ s' = y - s` (corner `corner_hz`) on a signal linear between samples
    /// (exact first-order-hold discretization), started at rest on the first sample.
    pub fn low_pass(y_m: &[f64], step_s: f64, corner_hz: f64) -> Vec<f64> {
        let a = (-step_s * 2.0 * std::f64::consts::PI * corner_hz).exp();
        // For input ramping from y_k to y_{k+1}: s⁺ = a s + (1 - a) y_k + g1 (y_{k+1} - y_k) with
        // g1 = 1 - τ (1 - a) / h.
        let tau = 1.0 / (2.0 * std::f64::consts::PI * corner_hz);
        let g1 = 1.0 - tau * (1.0 - a) / step_s;
        let mut out = Vec::with_capacity(y_m.len());
        let mut s = y_m.first().copied().unwrap_or(0.0);
        for k in 0..y_m.len() {
            out.push(s);
            if k + 1 < y_m.len() {
                s = a * s + (1.0 - a) * y_m[k] + g1 * (y_m[k + 1] - y_m[k]);
            }
        }
        out
    }

    /// Pure delay `delay_s` (linear interpolation between samples; the first sample is held
    /// before the start).
    pub fn delay(y_m: &[f64], step_s: f64, delay_s: f64) -> Vec<f64> {
        let d = delay_s / step_s;
        (0..y_m.len())
            .map(|k| {
                let pos = k as f64 - d;
                if pos <= 0.0 {
                    return y_m[0];
                }
                let i = pos.floor() as usize;
                let frac = pos - i as f64;
                if i + 1 >= y_m.len() {
                    y_m[y_m.len() - 1]
                } else {
                    y_m[i] * (1.0 - frac) + y_m[i + 1] * frac
                }
            })
            .collect()
    }

    /// Rounds to the nearest multiple of `lsb_m`.
    pub fn quantize(y_m: &[f64], lsb_m: f64) -> Vec<f64> {
        y_m.iter().map(|y| (y / lsb_m).round() * lsb_m).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::sensor_chain::*;
    use super::*;
    use crate::reference::dynamics::{simulate_held, ReferencePlant, RelayHysteresis};
    use crate::reference::preisach::RelayPreisach;

    fn field(k: usize) -> (actuator_params::ActuatorParams, RelayPreisach) {
        let p = actuator_params::paper_defaults();
        let f = RelayPreisach::new(
            &p.preisach.weights_a_per_m,
            p.preisach.h_min_a_per_m,
            p.preisach.h_max_a_per_m,
            k,
        )
        .unwrap();
        (p, f)
    }

    fn sine(n: usize, f: f64) -> Vec<f64> {
        (0..n)
            .map(|k| 0.5 + 0.4 * (2.0 * std::f64::consts::PI * f * k as f64 * 1e-4).sin())
            .collect()
    }

    /// Without effects the rig is the reference plant of `dynamics` (same equations, same RK4):
    /// agreement to rounding-level differences in the operation order, far below 1e-6 of stroke.
    #[test]
    fn no_effects_equals_reference_dynamics() {
        let (p, f) = field(8);
        let currents = sine(400, 200.0);
        let consts = RigConstants::from_params(&p);
        let mut rig = RigPlant::equilibrium(
            consts,
            PlantEffects::default(),
            RelayHysteresis {
                field: &f,
                state: f.demagnetized(),
            },
            currents[0],
        );
        let rig_y: Vec<f64> = currents
            .iter()
            .map(|&i| rig.advance_held(1e-4, 20, i))
            .collect();
        let mut reference = ReferencePlant::equilibrium(
            consts.plant,
            RelayHysteresis {
                field: &f,
                state: f.demagnetized(),
            },
            currents[0],
        );
        let ref_y = simulate_held(&mut reference, 1e-4, 20, &currents);
        let stroke = p.actuator.rod_length_m * p.actuator.saturation_magnetostriction;
        for (a, b) in rig_y.iter().zip(&ref_y) {
            assert!(
                (a - b.displacement_m).abs() < 1e-9 * stroke,
                "{a} vs {}",
                b.displacement_m
            );
        }
    }

    /// 20 substeps against 40 with every plant effect on: RK4 is fourth order, so the 20-substep
    /// error is about `16/15 |y20 - y40|`; it must be far below a sensor's noise (1e-4 of stroke).
    #[test]
    fn substep_convergence_with_all_effects() {
        let (p, f) = field(8);
        let currents = sine(600, 300.0);
        let consts = RigConstants::from_params(&p);
        let effects = PlantEffects {
            amplifier_corner_hz: Some(800.0),
            eddy_paths: vec![EddyPath {
                resistance_ohm: 60.0,
                corner_hz: 150.0,
            }],
            reversible_susceptibility: Some(2.0),
            thermal: Some(ThermalDrift {
                time_constant_s: 0.05,
                rise_k_per_a2: 40.0,
                scale_per_k: 2e-3,
            }),
            delta_e: Some(0.4),
            load: Some(MechanicalLoad {
                mass_ratio: 0.5,
                coupling_hz: 900.0,
                coupling_damping_ratio: 0.1,
            }),
        };
        let run = |substeps: usize| -> Vec<f64> {
            let mut rig = RigPlant::equilibrium(
                consts,
                effects.clone(),
                RelayHysteresis {
                    field: &f,
                    state: f.demagnetized(),
                },
                currents[0],
            );
            currents
                .iter()
                .map(|&i| rig.advance_held(1e-4, substeps, i))
                .collect()
        };
        let (a, b) = (run(20), run(40));
        let stroke = p.actuator.rod_length_m * p.actuator.saturation_magnetostriction;
        let worst = a
            .iter()
            .zip(&b)
            .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()));
        assert!(
            16.0 / 15.0 * worst < 1e-4 * stroke,
            "substep error {worst:e} m"
        );
    }

    #[test]
    fn ladder_resistance_rises_with_frequency() {
        let paths = [EddyPath {
            resistance_ohm: 70.0,
            corner_hz: 200.0,
        }];
        let low = effective_eddy_resistance_ohm(70.0, &paths, 0.0);
        let corner = effective_eddy_resistance_ohm(70.0, &paths, 200.0);
        let high = effective_eddy_resistance_ohm(70.0, &paths, 1e6);
        assert!((low - 35.0).abs() < 1e-9);
        // At the corner the extra path carries half its DC conductance: 1/(1/70 + 1/140).
        assert!((corner - 70.0 / 1.5).abs() < 1e-9);
        assert!((high - 70.0).abs() < 1e-3);
    }

    #[test]
    fn sensor_chain_pieces() {
        // Backlash: a ramp up then down by more than the gap lags by half the gap on each branch.
        let y: Vec<f64> = (0..=20)
            .map(|k| k as f64)
            .chain((0..20).map(|k| 19.0 - k as f64))
            .collect();
        let b = backlash(&y, 4.0);
        assert_eq!(b[10], 8.0);
        assert_eq!(b[25], 17.0); // driver at 15 going down, follower stays until pushed: 15 + 2
                                 // Low-pass of a ramp lags by τ in steady state.
        let h = 1e-4;
        let ramp: Vec<f64> = (0..20000).map(|k| k as f64 * h).collect();
        let lp = low_pass(&ramp, h, 100.0);
        let tau = 1.0 / (2.0 * std::f64::consts::PI * 100.0);
        assert!((ramp[19999] - lp[19999] - tau).abs() < 1e-9);
        // Delay of a ramp by 2.5 samples.
        let d = delay(&ramp, h, 2.5e-4);
        assert!((ramp[100] - d[100] - 2.5e-4).abs() < 1e-12);
        assert_eq!(quantize(&[0.26, -0.74], 0.5), vec![0.5, -0.5]);
    }
}
