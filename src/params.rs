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
    /// `[H_lo, H_hi]`, the field range the coil drives the rod through, A/m; `None`: the coil
    /// saturates the rod on the grid (`inverse::conditioning`).
    pub reach_a_per_m: Option<[f32; 2]>,
    /// `M_off`, the magnetization of the part of the plane the coil never switches, A/m.
    pub offset_a_per_m: f32,
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
        let measure = match &self.reversible_susceptibility {
            Some(chi) => hysteretic.with_reversible(chi),
            None => hysteretic,
        };
        measure.with_offset(self.offset_a_per_m)
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

/// The coil's lumped thermal model and the rise the measurement programme keeps under (the
/// parameter file's `coil_thermal` section; `crate::coil_heat`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CoilThermal {
    /// Winding to ambient, K/W.
    pub thermal_resistance_k_per_w: f32,
    /// Thermal time constant of the winding, s.
    pub time_constant_s: f32,
    /// Largest rise the measurement programme may cause, K.
    pub max_rise_k: f32,
}

/// The current-monitor channel's scaling (the parameter file's `current_monitor` section):
/// `coil_current_a = offset_a + gain_a_per_count · count`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CurrentMonitorScale {
    /// Coil current per count, A.
    pub gain_a_per_count: f32,
    /// Coil current at count 0, A.
    pub offset_a: f32,
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
    /// The coil's thermal budget for the measurement programme (`None`: no pauses).
    pub coil_thermal: Option<CoilThermal>,
    /// The current-monitor channel (`None`: the record has no coil current).
    pub current_monitor: Option<CurrentMonitorScale>,
}

include!(concat!(env!("OUT_DIR"), "/baked_params.rs"));

/// The Preisach measure of the baked parameters, its tables computed at compile time.
pub static BAKED_MEASURE: crate::preisach::PreisachMeasure = BAKED_PARAMETERS.preisach.measure();

impl ActuatorParameters {
    /// Every number zero, the feedback off, no grid lines, no reversible part: the value the
    /// baked constants are built from, one field at a time (`actuator_params::codegen`), and the
    /// run-time conversion too (`from_file`). Not a usable actuator.
    pub const ZERO: ActuatorParameters = ActuatorParameters {
        actuator: Actuator {
            coil_turns: 0.0,
            rod_area_m2: 0.0,
            rod_length_m: 0.0,
            coil_factor_per_m: 0.0,
            saturation_magnetization_a_per_m: 0.0,
            saturation_magnetostriction: 0.0,
            resonance_hz: 0.0,
            eddy_resistance_ohm: 0.0,
            damping_ratio: 0.0,
        },
        preisach: PreisachGrid {
            h_min_a_per_m: 0.0,
            h_max_a_per_m: 0.0,
            lines_a_per_m: None,
            reversible_susceptibility: None,
            reach_a_per_m: None,
            offset_a_per_m: 0.0,
            weights_a_per_m: [0.0; CELL_COUNT],
        },
        control: Control {
            sample_rate_hz: 0.0,
            current_limit_a: 0.0,
            current_slew_limit_a_per_s: 0.0,
            feedback: Feedback {
                structure: FeedbackStructure::Off,
                learning_gain: 0.0,
                learning_harmonics: 0,
                learning_leak_per_cycle: 0.0,
                proportional_gain: 0.0,
                integral_gain_per_s: 0.0,
                correction_limit_m: 0.0,
                stuck_sensor_ticks: 0,
            },
        },
        amplifier: Amplifier {
            compliance_voltage_v: 0.0,
            coil_resistance_ohm: 0.0,
            coil_inductance_h: 0.0,
        },
        sensor: Sensor {
            adc_bits: 0,
            gain_m_per_count: 0.0,
            offset_m: 0.0,
            valid_min_m: 0.0,
            valid_max_m: 0.0,
            sample_delay_s: 0.0,
        },
        trajectory: Trajectory {
            van_der_pol_mu: 0.0,
            frequency_scale_hz: 0.0,
            displacement_min_m: 0.0,
            displacement_max_m: 0.0,
        },
        coil_thermal: None,
        current_monitor: None,
    };
}

#[cfg(feature = "host")]
mod file_mapping {
    //! Run-time conversion between a parameter file and the core's types (host tools), derived
    //! from the one list of core fields (`actuator_params::core_fields!`): narrowing is the same
    //! f64 → f32 `build.rs` applies when it bakes a file; widening is exact.

    use super::{ActuatorParameters, FeedbackStructure};
    use actuator_params::{ActuatorParams, ParamsError};
    use std::format;
    use std::string::{String, ToString};
    use std::vec::Vec;

    /// A file value narrowed to the core's type (`field` names it in an error).
    trait Narrow<T> {
        fn narrow(&self, source_name: &str, field: &str) -> Result<T, ParamsError>;
    }

    /// A core value widened to the file's type.
    trait Widen<T> {
        fn widen(&self) -> T;
    }

    impl Narrow<f32> for f64 {
        fn narrow(&self, _: &str, _: &str) -> Result<f32, ParamsError> {
            Ok(*self as f32)
        }
    }

    impl Widen<f64> for f32 {
        fn widen(&self) -> f64 {
            *self as f64
        }
    }

    impl Narrow<u32> for u32 {
        fn narrow(&self, _: &str, _: &str) -> Result<u32, ParamsError> {
            Ok(*self)
        }
    }

    impl Widen<u32> for u32 {
        fn widen(&self) -> u32 {
            *self
        }
    }

    impl Narrow<FeedbackStructure> for actuator_params::FeedbackStructure {
        fn narrow(&self, _: &str, _: &str) -> Result<FeedbackStructure, ParamsError> {
            Ok(match self {
                actuator_params::FeedbackStructure::Off => FeedbackStructure::Off,
                actuator_params::FeedbackStructure::Integral => FeedbackStructure::Integral,
                actuator_params::FeedbackStructure::Repetitive => FeedbackStructure::Repetitive,
            })
        }
    }

    impl Widen<actuator_params::FeedbackStructure> for FeedbackStructure {
        fn widen(&self) -> actuator_params::FeedbackStructure {
            match self {
                FeedbackStructure::Off => actuator_params::FeedbackStructure::Off,
                FeedbackStructure::Integral => actuator_params::FeedbackStructure::Integral,
                FeedbackStructure::Repetitive => actuator_params::FeedbackStructure::Repetitive,
            }
        }
    }

    /// The core's fixed-length arrays: the file must carry exactly as many values.
    impl<const N: usize> Narrow<[f32; N]> for Vec<f64> {
        fn narrow(&self, source_name: &str, field: &str) -> Result<[f32; N], ParamsError> {
            if self.len() != N {
                return Err(ParamsError {
                    source_name: source_name.to_string(),
                    field: field.to_string(),
                    reason: format!("the core needs {N} values, the file has {}", self.len()),
                });
            }
            let mut out = [0.0f32; N];
            for (dst, &src) in out.iter_mut().zip(self) {
                *dst = src as f32;
            }
            Ok(out)
        }
    }

    impl<const N: usize> Widen<Vec<f64>> for [f32; N] {
        fn widen(&self) -> Vec<f64> {
            self.iter().map(|&v| v as f64).collect()
        }
    }

    impl<const N: usize> Narrow<Option<[f32; N]>> for Option<Vec<f64>> {
        fn narrow(&self, source_name: &str, field: &str) -> Result<Option<[f32; N]>, ParamsError> {
            self.as_ref()
                .map(|v| v.narrow(source_name, field))
                .transpose()
        }
    }

    impl<const N: usize> Widen<Option<Vec<f64>>> for Option<[f32; N]> {
        fn widen(&self) -> Option<Vec<f64>> {
            self.as_ref().map(Widen::widen)
        }
    }

    /// An optional section of f64 members in the file and f32 members in the core, member by
    /// member (the same narrowing as a scalar field).
    macro_rules! optional_section {
        ($section:ident { $($member:ident),+ }) => {
            impl Narrow<Option<super::$section>> for Option<actuator_params::$section> {
                fn narrow(&self, _: &str, _: &str) -> Result<Option<super::$section>, ParamsError> {
                    Ok(self.map(|s| super::$section { $($member: s.$member as f32),+ }))
                }
            }

            impl Widen<Option<actuator_params::$section>> for Option<super::$section> {
                fn widen(&self) -> Option<actuator_params::$section> {
                    self.map(|s| actuator_params::$section { $($member: s.$member as f64),+ })
                }
            }
        };
    }
    optional_section!(CoilThermal {
        thermal_resistance_k_per_w,
        time_constant_s,
        max_rise_k
    });
    optional_section!(CurrentMonitorScale {
        gain_a_per_count,
        offset_a
    });

    macro_rules! narrow_all {
        ($($($file:ident).+ => $($core:ident).+;)*) => {
            /// All parameters of a (validated) parameter file in the core's f32 types (errors
            /// name `source_name` and the field).
            pub fn from_file(
                file: &ActuatorParams,
                source_name: &str,
            ) -> Result<ActuatorParameters, ParamsError> {
                let mut core = ActuatorParameters::ZERO;
                $(
                    core.$($core).+ = Narrow::narrow(
                        &file.$($file).+,
                        source_name,
                        &actuator_params::field_path!($($file).+),
                    )?;
                )*
                Ok(core)
            }
        };
    }
    actuator_params::core_fields!(narrow_all);

    macro_rules! widen_all {
        ($($($file:ident).+ => $($core:ident).+;)*) => {
            /// `core` as a parameter file: every core field widened exactly to f64 into `base`
            /// (which gives the fields the core does not carry).
            pub fn to_file(core: &ActuatorParameters, mut base: ActuatorParams) -> ActuatorParams {
                $( base.$($file).+ = Widen::widen(&core.$($core).+); )*
                base
            }
        };
    }
    actuator_params::core_fields!(widen_all);

    impl ActuatorParameters {
        /// All parameters of a (validated) parameter file in the core's f32 types, the same
        /// narrowing `build.rs` applies when it bakes a file.
        pub fn from_file(file: &ActuatorParams, source_name: &str) -> Result<Self, ParamsError> {
            from_file(file, source_name)
        }

        /// These parameters as a parameter file: every field widened exactly to f64, the rest
        /// (provenance, schema version, the grid's level count) from `base`.
        pub fn to_file(&self, base: ActuatorParams) -> ActuatorParams {
            to_file(self, base)
        }
    }

    #[allow(dead_code)]
    fn _uses(_: String) {}
}
