//! Typed actuator parameters, and the values baked in at build time.
//!
//! `build.rs` reads `params/actuator.json` (or the file named by `ACTUATOR_PARAMS`), validates it
//! and generates [`BAKED_PARAMETERS`]; this module only defines the types (same field names and
//! units as the JSON schema in `docs/params.md`, in f32) and derived quantities.

use crate::preisach::CELL_COUNT;

/// Permeability of vacuum μ0, H/m.
pub const VACUUM_PERMEABILITY_H_PER_M: f32 = 1.256_637_1e-6;

/// Physical constants of the actuator (paper Sections 3-4).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Actuator {
    /// N_m: number of turns of the coil.
    pub coil_turns: f32,
    /// A_m: cross-sectional area of the rod, m².
    pub rod_area_m2: f32,
    /// l_m: length of the rod, m.
    pub rod_length_m: f32,
    /// c0: coil factor (H = c0 I in the static limit), 1/m.
    pub coil_factor_per_m: f32,
    /// M_s: saturation magnetization, A/m.
    pub saturation_magnetization_a_per_m: f32,
    /// λ_s: saturation magnetostriction.
    pub saturation_magnetostriction: f32,
    /// f0: first resonance, Hz.
    pub resonance_hz: f32,
    /// R_eddy: eddy-current resistance, Ω.
    pub eddy_resistance_ohm: f32,
    /// ξ: damping ratio of (5).
    pub damping_ratio: f32,
}

impl Actuator {
    /// `c1 = R_eddy / (μ0 N_m A_m)`, the coefficient of equation (4), `H' + M' = c1 (I - H / c0)`.
    /// Unit 1/(m·s): it turns a current (A) into a rate of field (A/(m·s)).
    pub fn eddy_coefficient_per_m_s(&self) -> f32 {
        self.eddy_resistance_ohm
            / (VACUUM_PERMEABILITY_H_PER_M * self.coil_turns * self.rod_area_m2)
    }

    /// Full stroke `l_m λ_s`, reached at `|M| = M_s` (equation (6)), m.
    pub fn stroke_m(&self) -> f32 {
        self.rod_length_m * self.saturation_magnetostriction
    }
}

/// The Preisach grid of the parameter file: input range and cell masses (alpha-major order, see
/// [`crate::preisach`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PreisachGrid {
    /// Lower end of the field range, A/m.
    pub h_min_a_per_m: f32,
    /// Upper end of the field range, A/m.
    pub h_max_a_per_m: f32,
    /// The grid lines (`LEVELS + 1`, from `h_min` to `h_max`), A/m; `None`: equal intervals.
    pub lines_a_per_m: Option<[f32; crate::preisach::LEVELS + 1]>,
    /// The reversible part's susceptibility per grid interval; `None`: no reversible part.
    pub reversible_susceptibility: Option<[f32; crate::preisach::LEVELS]>,
    /// Cell masses, A/m.
    pub weights_a_per_m: [f32; CELL_COUNT],
}

impl PreisachGrid {
    /// The Preisach measure (operator coefficients) of this grid: on its lines, or on equal
    /// intervals (a `const fn`: the baked measure is computed at compile time).
    pub const fn measure(&self) -> crate::preisach::PreisachMeasure {
        let hysteretic = match &self.lines_a_per_m {
            Some(lines) => {
                crate::preisach::PreisachMeasure::with_lines(&self.weights_a_per_m, lines)
            }
            None => crate::preisach::PreisachMeasure::new(
                &self.weights_a_per_m,
                self.h_min_a_per_m,
                self.h_max_a_per_m,
            ),
        };
        match &self.reversible_susceptibility {
            Some(chi) => hysteretic.with_reversible(chi),
            None => hysteretic,
        }
    }
}

/// Control-loop settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Control {
    /// Control interrupt rate, Hz.
    pub sample_rate_hz: f32,
    /// Current command limit (±), A.
    pub current_limit_a: f32,
    /// Current command slew limit, A/s.
    pub current_slew_limit_a_per_s: f32,
    /// Displacement feedback around the inverse (`inverse::feedback`).
    pub feedback: Feedback,
}

/// The feedback structure (parameter file: `control.feedback.structure`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FeedbackStructure {
    /// Feedforward only (the inverse alone).
    Off,
    /// PI on the displacement error, acting on `ȳ`.
    Integral,
    /// Harmonic learning over the trajectory's cycle (repetitive control) plus the PI terms.
    Repetitive,
}

/// Displacement-feedback settings (see `inverse::feedback` for the law and its units).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Feedback {
    /// Structure.
    pub structure: FeedbackStructure,
    /// γ: fraction of the error corrected per cycle.
    pub learning_gain: f32,
    /// N: harmonics of the trajectory's fundamental the learning corrects.
    pub learning_harmonics: u32,
    /// λ: leak of the learned coefficients per cycle.
    pub learning_leak_per_cycle: f32,
    /// K_p (m per m of error).
    pub proportional_gain: f32,
    /// K_i, 1/s.
    pub integral_gain_per_s: f32,
    /// Bound on the correction (table entries and integrator), m.
    pub correction_limit_m: f32,
    /// Ticks with a bit-identical sample after which the sensor counts as stuck.
    pub stuck_sensor_ticks: u32,
}

/// The coil and its amplifier (what bounds the current slew; see the parameter file's
/// `amplifier` section).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Amplifier {
    /// Highest voltage the amplifier can put across the coil, V.
    pub compliance_voltage_v: f32,
    /// Coil resistance, Ω.
    pub coil_resistance_ohm: f32,
    /// Coil inductance, H.
    pub coil_inductance_h: f32,
}

/// The displacement sensor (see the parameter file's `sensor` section).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sensor {
    /// ADC resolution, bits.
    pub adc_bits: u32,
    /// Displacement per count, m.
    pub gain_m_per_count: f32,
    /// Displacement at count 0, m.
    pub offset_m: f32,
    /// Lowest valid reading, m.
    pub valid_min_m: f32,
    /// Highest valid reading, m.
    pub valid_max_m: f32,
    /// Delay of the sample behind the displacement, s.
    pub sample_delay_s: f32,
}

/// Van der Pol desired-trajectory settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Trajectory {
    /// μ of the oscillator.
    pub van_der_pol_mu: f32,
    /// Time scale: the oscillator runs in `2π frequency_scale_hz · t`, Hz.
    pub frequency_scale_hz: f32,
    /// Lower edge of the displacement band, m.
    pub displacement_min_m: f32,
    /// Upper edge of the displacement band, m.
    pub displacement_max_m: f32,
}

/// All parameters of one actuator and its control loop.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ActuatorParameters {
    /// Physical constants.
    pub actuator: Actuator,
    /// Preisach grid and masses.
    pub preisach: PreisachGrid,
    /// Control settings.
    pub control: Control,
    /// Coil and amplifier.
    pub amplifier: Amplifier,
    /// Displacement sensor.
    pub sensor: Sensor,
    /// Desired-trajectory settings.
    pub trajectory: Trajectory,
}

include!(concat!(env!("OUT_DIR"), "/baked_params.rs"));

/// The Preisach measure of the baked parameters, its tables computed at compile time.
pub static BAKED_MEASURE: crate::preisach::PreisachMeasure = BAKED_PARAMETERS.preisach.measure();

#[cfg(feature = "host")]
mod from_file {
    //! Run-time conversion of a parameter file (host tools), the same f64 → f32 narrowing
    //! `build.rs` applies when it bakes a file.

    use super::{
        Actuator, ActuatorParameters, Amplifier, Control, Feedback, FeedbackStructure,
        PreisachGrid, Sensor, Trajectory,
    };
    use crate::preisach::CELL_COUNT;
    use actuator_params::{ActuatorParams, ParamsError};
    use std::format;
    use std::string::ToString;

    impl Actuator {
        /// The actuator constants of a parameter file, in f32.
        pub fn from_file(a: &actuator_params::Actuator) -> Self {
            Actuator {
                coil_turns: a.coil_turns as f32,
                rod_area_m2: a.rod_area_m2 as f32,
                rod_length_m: a.rod_length_m as f32,
                coil_factor_per_m: a.coil_factor_per_m as f32,
                saturation_magnetization_a_per_m: a.saturation_magnetization_a_per_m as f32,
                saturation_magnetostriction: a.saturation_magnetostriction as f32,
                resonance_hz: a.resonance_hz as f32,
                eddy_resistance_ohm: a.eddy_resistance_ohm as f32,
                damping_ratio: a.damping_ratio as f32,
            }
        }
    }

    impl Feedback {
        /// The feedback settings of a parameter file, in f32.
        pub fn from_file(f: &actuator_params::Feedback) -> Self {
            Feedback {
                structure: match f.structure {
                    actuator_params::FeedbackStructure::Off => FeedbackStructure::Off,
                    actuator_params::FeedbackStructure::Integral => FeedbackStructure::Integral,
                    actuator_params::FeedbackStructure::Repetitive => FeedbackStructure::Repetitive,
                },
                learning_gain: f.learning_gain as f32,
                learning_harmonics: f.learning_harmonics,
                learning_leak_per_cycle: f.learning_leak_per_cycle as f32,
                proportional_gain: f.proportional_gain as f32,
                integral_gain_per_s: f.integral_gain_per_s as f32,
                correction_limit_m: f.correction_limit_m as f32,
                stuck_sensor_ticks: f.stuck_sensor_ticks,
            }
        }
    }

    impl PreisachGrid {
        /// The Preisach grid of a parameter file, in f32. Fails (naming the field) when the file
        /// does not carry exactly [`CELL_COUNT`] weights.
        pub fn from_file(
            p: &actuator_params::Preisach,
            source_name: &str,
        ) -> Result<Self, ParamsError> {
            if p.weights_a_per_m.len() != CELL_COUNT {
                return Err(ParamsError {
                    source_name: source_name.to_string(),
                    field: "preisach.weights_a_per_m".into(),
                    reason: format!(
                        "the core needs {CELL_COUNT} weights, the file has {}",
                        p.weights_a_per_m.len()
                    ),
                });
            }
            let mut weights_a_per_m = [0.0f32; CELL_COUNT];
            for (dst, &src) in weights_a_per_m.iter_mut().zip(&p.weights_a_per_m) {
                *dst = src as f32;
            }
            let lines_a_per_m = match &p.grid_lines_a_per_m {
                None => None,
                Some(given) => {
                    let levels = crate::preisach::LEVELS;
                    if given.len() != levels + 1 {
                        return Err(ParamsError {
                            source_name: source_name.to_string(),
                            field: "preisach.grid_lines_a_per_m".into(),
                            reason: format!(
                                "the core needs {} grid lines, the file has {}",
                                levels + 1,
                                given.len()
                            ),
                        });
                    }
                    let mut lines = [0.0f32; crate::preisach::LEVELS + 1];
                    for (dst, &src) in lines.iter_mut().zip(given) {
                        *dst = src as f32;
                    }
                    Some(lines)
                }
            };
            let reversible_susceptibility = match &p.reversible_susceptibility {
                None => None,
                Some(given) => {
                    let levels = crate::preisach::LEVELS;
                    if given.len() != levels {
                        return Err(ParamsError {
                            source_name: source_name.to_string(),
                            field: "preisach.reversible_susceptibility".into(),
                            reason: format!(
                                "the core needs {levels} susceptibilities, the file has {}",
                                given.len()
                            ),
                        });
                    }
                    let mut chi = [0.0f32; crate::preisach::LEVELS];
                    for (dst, &src) in chi.iter_mut().zip(given) {
                        *dst = src as f32;
                    }
                    Some(chi)
                }
            };
            Ok(PreisachGrid {
                h_min_a_per_m: p.h_min_a_per_m as f32,
                h_max_a_per_m: p.h_max_a_per_m as f32,
                lines_a_per_m,
                reversible_susceptibility,
                weights_a_per_m,
            })
        }
    }

    impl ActuatorParameters {
        /// All parameters of a (validated) parameter file in the core's f32 types.
        pub fn from_file(file: &ActuatorParams, source_name: &str) -> Result<Self, ParamsError> {
            let c = &file.control;
            let t = &file.trajectory;
            Ok(ActuatorParameters {
                actuator: Actuator::from_file(&file.actuator),
                preisach: PreisachGrid::from_file(&file.preisach, source_name)?,
                control: Control {
                    sample_rate_hz: c.sample_rate_hz as f32,
                    current_limit_a: c.current_limit_a as f32,
                    current_slew_limit_a_per_s: c.current_slew_limit_a_per_s as f32,
                    feedback: Feedback::from_file(&c.feedback),
                },
                amplifier: Amplifier {
                    compliance_voltage_v: file.amplifier.compliance_voltage_v as f32,
                    coil_resistance_ohm: file.amplifier.coil_resistance_ohm as f32,
                    coil_inductance_h: file.amplifier.coil_inductance_h as f32,
                },
                sensor: Sensor {
                    adc_bits: file.sensor.adc_bits,
                    gain_m_per_count: file.sensor.gain_m_per_count as f32,
                    offset_m: file.sensor.offset_m as f32,
                    valid_min_m: file.sensor.valid_min_m as f32,
                    valid_max_m: file.sensor.valid_max_m as f32,
                    sample_delay_s: file.sensor.sample_delay_s as f32,
                },
                trajectory: Trajectory {
                    van_der_pol_mu: t.van_der_pol_mu as f32,
                    frequency_scale_hz: t.frequency_scale_hz as f32,
                    displacement_min_m: t.displacement_min_m as f32,
                    displacement_max_m: t.displacement_max_m as f32,
                },
            })
        }
    }
}
