//! The effects' forms (`crate::effects`) resolved into the coefficients the plant's equations
//! use ([`resolve`]): which current loop, sensor filter, thermal network, ΔE law, load chain,
//! friction, backlash, creep spectrum and eddy-path ladder each effect and form means.

use crate::actuator::PlantConstants;
use crate::effects::Effect;
use std::f64::consts::PI;

/// The current loop's form (`amplifier_bandwidth`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum AmplifierForm {
    /// `i'' = ω² (cmd − i) − 2ζω i'`, `|i'| ≤ slew`.
    SecondOrder,
    /// `i' = ω (cmd − i)`, `|i'| ≤ slew`.
    FirstOrder,
    /// A PI loop with crossover `ω` on the coil (`v = i + τ_L w'/c0`, see
    /// [`crate::actuator::Plant`]'s `coil_current`), `|v| ≤ v_lim`.
    PiLoop { tau_l: f64, v_lim: f64 },
    /// The PI loop with its zero at `tau_z` instead of on the coil's `tau_l`, fed back through a
    /// current-sense filter of corner `omega_sense`.
    SensedPiLoop {
        tau_l: f64,
        tau_z: f64,
        omega_sense: f64,
        v_lim: f64,
    },
}

#[derive(Debug, Clone, Copy)]
pub(crate) struct Amplifier {
    pub(crate) form: AmplifierForm,
    pub(crate) omega: f64,
    pub(crate) zeta: f64,
    pub(crate) slew: f64,
}

/// The sensor's low-pass with a state (`sensor_dynamics` forms 0 and 1; the laser's moving
/// average works on the history instead: `Resolved::sensor_window_s`).
#[derive(Debug, Clone, Copy)]
pub(crate) struct SensorFilter {
    pub(crate) omega: f64,
    pub(crate) zeta: f64,
    pub(crate) second_order: bool,
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum ThermalForm {
    Lumped,
    /// The rod as three shells in series (`T_ROD`, `T_SHELL2`, `T_SHELL3`).
    Distributed,
    /// The current capped at `compliance_a / R(T)`.
    VoltageLimited {
        compliance_a: f64,
    },
}

#[derive(Debug, Clone, Copy)]
pub(crate) struct Thermal {
    pub(crate) form: ThermalForm,
    pub(crate) rise: f64,
    pub(crate) tau_coil: f64,
    pub(crate) tau_rod: f64,
    pub(crate) tempco: f64,
    pub(crate) loss: f64,
    pub(crate) expansion: f64,
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum DeltaEForm {
    Quartic,
    Cubic,
    Field { h_s: f64 },
}

#[derive(Debug, Clone, Copy)]
pub(crate) struct DeltaE {
    pub(crate) form: DeltaEForm,
    pub(crate) d: f64,
    pub(crate) s: f64,
}

/// A chain of `modes` (1-3) load masses; `r_k` each mass over the rod's, `w_k`, `z_k` its
/// coupling to the one before.
#[derive(Debug, Clone, Copy)]
pub(crate) struct LoadModes {
    pub(crate) modes: usize,
    pub(crate) r2: f64,
    pub(crate) w2: f64,
    pub(crate) z2: f64,
    pub(crate) r3: f64,
    pub(crate) w3: f64,
    pub(crate) z3: f64,
    pub(crate) r4: f64,
    pub(crate) w4: f64,
    pub(crate) z4: f64,
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum FrictionForm {
    Coulomb,
    Stribeck {
        speed_m_per_s: f64,
    },
    /// Dahl: the force (per unit mass) `Plant::dahl_accel` follows the displacement.
    Dahl {
        presliding_m: f64,
    },
}

#[derive(Debug, Clone, Copy)]
pub(crate) struct Friction {
    pub(crate) form: FrictionForm,
    pub(crate) static_accel: f64,
    pub(crate) kinetic_accel: f64,
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum BacklashForm {
    Play,
    /// The follower reaches the play's output with `1 − exp(−ω dt)` per substep.
    Lagging {
        omega: f64,
    },
    Smooth,
}

#[derive(Debug, Clone, Copy)]
pub(crate) struct Backlash {
    pub(crate) form: BacklashForm,
    pub(crate) width_m: f64,
}

/// Relaxation terms of the creep strain, equal shares.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Creep {
    pub(crate) ratio: f64,
    pub(crate) taus_s: [f64; CREEP_TERMS],
    pub(crate) terms: usize,
}

/// Most creep terms of any form.
pub(crate) const CREEP_TERMS: usize = 5;

/// The effects resolved into the plant's coefficients.
#[derive(Debug, Clone, Default)]
pub(crate) struct Resolved {
    /// `(1/c1_k, τ_k)` of the distributed eddy paths.
    pub(crate) paths: Vec<(f64, f64)>,
    pub(crate) amplifier: Option<Amplifier>,
    pub(crate) sensor: Option<SensorFilter>,
    /// The laser's moving-average window, s (0: none).
    pub(crate) sensor_window_s: f64,
    pub(crate) sensor_delay_s: f64,
    /// `(form, χ0, H_r)`.
    pub(crate) reversible: Option<(usize, f64, f64)>,
    pub(crate) thermal: Option<Thermal>,
    pub(crate) delta_e: Option<DeltaE>,
    pub(crate) load: Option<LoadModes>,
    pub(crate) backlash: Option<Backlash>,
    pub(crate) friction: Option<Friction>,
    pub(crate) creep: Option<Creep>,
    /// `(form, g, null, half range)`.
    pub(crate) sensor_gain_change: Option<(usize, f64, f64, f64)>,
}

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

/// The coefficients of `effects` (each named once: `crate::effects::check_unique`) for a plant
/// with the nominal constants `c`.
pub(crate) fn resolve(c: &PlantConstants, effects: &[Effect]) -> Resolved {
    let mut r = Resolved::default();
    for e in effects {
        match e.name() {
            "eddy_frequency_dependence" => r.paths = eddy_paths(c, e),
            "amplifier_bandwidth" => r.amplifier = Some(amplifier(e)),
            "sensor_dynamics" => {
                (r.sensor, r.sensor_window_s) = sensor(e);
                r.sensor_delay_s = e.get("delay_s");
            }
            "reversible_magnetization" => {
                r.reversible = Some((
                    e.form(),
                    e.get("susceptibility"),
                    e.get("saturation_field_a_per_m"),
                ))
            }
            "thermal_drift" => r.thermal = Some(thermal(e)),
            "delta_e_effect" => r.delta_e = Some(delta_e(e)),
            "mechanical_load" => r.load = Some(load(e)),
            "backlash" => r.backlash = Some(backlash(e)),
            "stick_slip" => r.friction = Some(friction(c, e)),
            "creep" => r.creep = Some(creep(e)),
            "sensor_nonlinearity" => {
                r.sensor_gain_change = Some((
                    e.form(),
                    e.get("gain_change"),
                    e.get("null_m"),
                    e.get("range_m"),
                ))
            }
            other => unreachable!("effect `{other}` has a spec but no plant form"),
        }
    }
    r
}

/// The amplifier of `amplifier_bandwidth`'s form.
fn amplifier(e: &Effect) -> Amplifier {
    Amplifier {
        form: match e.form() {
            0 => AmplifierForm::SecondOrder,
            1 => AmplifierForm::FirstOrder,
            2 => AmplifierForm::PiLoop {
                tau_l: e.get("coil_time_constant_s"),
                v_lim: e.get("voltage_limit_a"),
            },
            _ => AmplifierForm::SensedPiLoop {
                tau_l: e.get("coil_time_constant_s"),
                tau_z: e.get("coil_time_constant_s") * e.get("zero_to_coil_ratio"),
                omega_sense: 2.0 * PI * e.get("natural_hz") * e.get("sense_to_crossover"),
                v_lim: e.get("voltage_limit_a"),
            },
        },
        omega: 2.0 * PI * e.get("natural_hz"),
        zeta: e.get("damping_ratio"),
        slew: e.get("slew_a_per_s"),
    }
}

/// `sensor_dynamics`' filter (the LVDT's second-order and the probe's first-order forms) or the
/// laser's moving-average window, s (0 for the filters).
fn sensor(e: &Effect) -> (Option<SensorFilter>, f64) {
    let form = e.form();
    match form {
        0 | 1 => (
            Some(SensorFilter {
                omega: 2.0 * PI * e.get("natural_hz"),
                zeta: if form == 0 {
                    e.get("damping_ratio")
                } else {
                    0.0
                },
                second_order: form == 0,
            }),
            0.0,
        ),
        // A boxcar of length T has its −3 dB point at 0.443 / T.
        _ => (None, 0.443 / e.get("natural_hz")),
    }
}

/// The coil and rod heating of `thermal_drift`'s form.
fn thermal(e: &Effect) -> Thermal {
    Thermal {
        form: match e.form() {
            0 => ThermalForm::Lumped,
            1 => ThermalForm::Distributed,
            _ => ThermalForm::VoltageLimited {
                compliance_a: e.get("compliance_a"),
            },
        },
        rise: e.get("coil_rise_k_per_a2"),
        tau_coil: e.get("coil_time_constant_s"),
        tau_rod: e.get("rod_time_constant_s"),
        tempco: e.get("copper_tempco_per_k"),
        loss: e.get("magnetostriction_loss_per_k"),
        expansion: e.get("expansion_m_per_k"),
    }
}

/// The stiffening of `delta_e_effect`'s form.
fn delta_e(e: &Effect) -> DeltaE {
    DeltaE {
        form: match e.form() {
            0 => DeltaEForm::Quartic,
            1 => DeltaEForm::Cubic,
            _ => DeltaEForm::Field {
                h_s: e.get("field_scale_a_per_m"),
            },
        },
        d: e.get("magnetization_stiffening"),
        s: e.get("stress_stiffening"),
    }
}

/// The masses of `mechanical_load`'s form; each further mass is given relative to the one before,
/// and a third mode couples at 1.7 times the second's frequency.
fn load(e: &Effect) -> LoadModes {
    let r2 = e.get("mass_ratio").max(1e-6);
    let modes = form_modes(e.form());
    let r3 = if modes >= 2 {
        r2 * e.get("second_mass_ratio")
    } else {
        0.0
    };
    let r4 = if modes >= 3 {
        r3 * e.get("second_mass_ratio")
    } else {
        0.0
    };
    let w3 = 2.0 * PI * e.get("second_coupling_hz");
    LoadModes {
        modes,
        r2,
        w2: 2.0 * PI * e.get("coupling_hz"),
        z2: e.get("damping_ratio"),
        r3,
        w3,
        z3: e.get("second_damping_ratio"),
        r4,
        w4: 1.7 * w3,
        z4: e.get("second_damping_ratio"),
    }
}

/// The play of `backlash`'s form.
fn backlash(e: &Effect) -> Backlash {
    Backlash {
        form: match e.form() {
            0 => BacklashForm::Play,
            1 => BacklashForm::Lagging {
                omega: 2.0 * PI * e.get("follower_hz"),
            },
            _ => BacklashForm::Smooth,
        },
        width_m: e.get("width_m"),
    }
}

/// The friction of `stick_slip`'s form, as accelerations: the breakaway displacement times the
/// rod's stiffness per mass `ω0²` (constants `c`).
fn friction(c: &PlantConstants, e: &Effect) -> Friction {
    let w2 = c.omega0_rad_per_s * c.omega0_rad_per_s;
    let s = w2 * e.get("breakaway_m");
    Friction {
        form: match e.form() {
            0 => FrictionForm::Coulomb,
            1 => FrictionForm::Stribeck {
                speed_m_per_s: e.get("stribeck_speed_m_per_s"),
            },
            _ => FrictionForm::Dahl {
                presliding_m: e.get("presliding_m"),
            },
        },
        static_accel: s,
        kinetic_accel: s * e.get("kinetic_ratio"),
    }
}

/// The relaxation terms of `creep`'s form: time constants a decade apart from the first.
fn creep(e: &Effect) -> Creep {
    let tau0 = e.get("time_constant_s");
    let (first, terms) = match e.form() {
        0 => (tau0, 3),
        1 => (10.0 * tau0, 1),
        _ => (tau0, CREEP_TERMS),
    };
    let mut taus_s = [0.0; CREEP_TERMS];
    for (k, t) in taus_s.iter_mut().take(terms).enumerate() {
        *t = first * 10f64.powi(k as i32);
    }
    Creep {
        ratio: e.get("ratio"),
        taus_s,
        terms,
    }
}

/// Load masses of each `mechanical_load` form.
fn form_modes(form: usize) -> usize {
    match form {
        0 => 2,
        1 => 1,
        _ => 3,
    }
}

/// `(1/c1_k, τ_k)` of the distributed eddy paths of `e`: the DC conductance share split among
/// the modes of the rod's cross-section (cylinder, laminated slab, spread of skin depths).
fn eddy_paths(c: &PlantConstants, e: &Effect) -> Vec<(f64, f64)> {
    let share = e.get("share");
    let f1 = e.get("first_corner_hz");
    let n = (e.get("paths").round() as usize).clamp(3, BESSEL_J0_ZEROS.len());
    // (corner relative to the first, relative conductance share) of mode k.
    let modes: Vec<(f64, f64)> = (0..n)
        .map(|k| match e.form() {
            0 => {
                let q = BESSEL_J0_ZEROS[k] / BESSEL_J0_ZEROS[0];
                (q * q, 1.0 / (q * q))
            }
            1 => {
                let q = (2 * k + 1) as f64;
                (q * q, 1.0 / (q * q))
            }
            _ => (4f64.powi(k as i32), 1.0),
        })
        .collect();
    let norm: f64 = modes.iter().map(|m| m.1).sum();
    // Σ 1/c1_k = (1/c1) share / (1 - share): conductances add (module docs).
    let total_inv = share / (1.0 - share) / c.c1_per_m_s;
    modes
        .iter()
        .map(|&(corner, weight)| (total_inv * weight / norm, 1.0 / (2.0 * PI * f1 * corner)))
        .collect()
}
