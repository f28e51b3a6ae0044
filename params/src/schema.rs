//! Schema of the parameter file and its validation.

use serde::{Deserialize, Serialize};
use std::fmt;
use std::path::Path;

/// Number of input levels of the Preisach grid the core is built for (paper, Section 5: "the
/// discretization level ... was 25").
pub const PREISACH_LEVELS: usize = 25;

/// Number of cells of a grid with `levels` input levels: `levels (levels + 1) / 2`.
pub const fn cell_count(levels: usize) -> usize {
    levels * (levels + 1) / 2
}

/// Version of the schema this crate reads and writes.
pub const SCHEMA_VERSION: u32 = 1;

/// Largest reversible susceptibility a parameter file may give (soft ferrites reach ~10⁴; a
/// value far beyond is a unit error, and it would overflow the core's f32 sums).
pub const MAX_REVERSIBLE_SUSCEPTIBILITY: f64 = 1e7;

/// The whole parameter file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ActuatorParams {
    /// Must equal [`SCHEMA_VERSION`].
    pub schema_version: u32,
    /// Physical constants of the actuator (paper, Sections 3-4).
    pub actuator: Actuator,
    /// The Preisach grid and its cell masses.
    pub preisach: Preisach,
    /// Control-loop settings.
    pub control: Control,
    /// The coil's electrical constants and the amplifier driving it: they bound the current slew
    /// rate the controller may command.
    pub amplifier: Amplifier,
    /// The displacement sensor the control interrupt reads every tick.
    pub sensor: Sensor,
    /// Desired-trajectory generator (Van der Pol oscillator, paper Section 5).
    pub trajectory: Trajectory,
    /// Where these numbers come from. Free-form for tools; `source` is required.
    pub provenance: Provenance,
    /// What the bench's datasheets give, with tolerances: priors of the host tools' fits
    /// (optional; the firmware bakes none of it).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub datasheet: Option<crate::Datasheet>,
    /// The coil's thermal constants and the temperature rise the measurement programme may cause
    /// (optional; without it the programme runs without pauses).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub coil_thermal: Option<CoilThermal>,
    /// The amplifier's current-monitor output on the measurement image's second ADC channel
    /// (optional; without it the firmware's record has no coil current).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub current_monitor: Option<CurrentMonitorScale>,
}

/// Physical constants of the actuator.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Actuator {
    /// N_m: number of turns of the coil.
    pub coil_turns: f64,
    /// A_m: cross-sectional area of the rod, m².
    pub rod_area_m2: f64,
    /// l_m: length of the rod, m.
    pub rod_length_m: f64,
    /// c0: coil factor, H = c0 I in the static limit, 1/m.
    pub coil_factor_per_m: f64,
    /// M_s: saturation magnetization, A/m.
    pub saturation_magnetization_a_per_m: f64,
    /// λ_s: saturation magnetostriction (dimensionless).
    pub saturation_magnetostriction: f64,
    /// f0: first resonance of the rod, Hz.
    pub resonance_hz: f64,
    /// R_eddy: eddy-current resistance, Ω.
    pub eddy_resistance_ohm: f64,
    /// ξ: damping ratio of the magnetoelastic dynamics (5).
    pub damping_ratio: f64,
}

/// The Preisach grid: `levels` intervals of `[h_min, h_max]` (equal, or between the given grid
/// lines) and one mass per cell, spread uniformly over the cell.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Preisach {
    /// L, the number of input levels. The core is built for [`PREISACH_LEVELS`].
    pub levels: usize,
    /// Lower end of the input (field) range, A/m.
    pub h_min_a_per_m: f64,
    /// Upper end of the input (field) range, A/m.
    pub h_max_a_per_m: f64,
    /// The `L + 1` grid lines, A/m, strictly increasing, the first `h_min_a_per_m` and the last
    /// `h_max_a_per_m`: narrower intervals where the loops need resolution. Absent: `L` equal
    /// intervals.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub grid_lines_a_per_m: Option<Vec<f64>>,
    /// The reversible (anhysteretic) part's susceptibility `χ_k = dR/dH` on each of the `L`
    /// grid intervals (dimensionless, `>= 0`): `M = Γ[H] + R(H)` with
    /// `R(H) = Σ_k χ_k (clamp(H, line_k, line_k+1) − middle_k)`, monotone, piecewise linear,
    /// flat beyond the grid. Absent: no reversible part (the paper's `M = Γ[H]`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reversible_susceptibility: Option<Vec<f64>>,
    /// `[H_lo, H_hi]`, A/m: the field range the coil drives this rod through (what the
    /// identification data reached), inside the grid. Present when the rod's Preisach plane is
    /// wider than that: the grid's intervals outside the reach then hold the one-way bands
    /// (docs/model.md, "Rods the coil cannot saturate") and the start-up conditioning sweeps
    /// the reach instead of saturating. Absent: the coil saturates the rod on the grid.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reach_a_per_m: Option<Vec<f64>>,
    /// `M_off`, A/m: the constant magnetization of the part of the plane the coil never
    /// switches, added to the output (`M = Γ[H] + R(H) + M_off`). 0 (absent) for a rod the coil
    /// saturates.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub offset_a_per_m: f64,
    /// Cell masses in A/m, `L (L + 1) / 2` of them, in alpha-major order: the cell whose switch-down
    /// threshold β lies in interval `i` and switch-up threshold α in interval `j` (`i <= j`) has
    /// index `j (j + 1) / 2 + i`. The output is `M = Σ w·(±1)`, so `Σ w` is the saturation output.
    pub weights_a_per_m: Vec<f64>,
}

/// Control-loop settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Control {
    /// Rate of the control interrupt and of the model step, Hz.
    pub sample_rate_hz: f64,
    /// The coil current command is limited to `±current_limit_a`, A.
    pub current_limit_a: f64,
    /// Largest change of the current command per second, A/s.
    pub current_slew_limit_a_per_s: f64,
    /// Displacement feedback around the inverse (absent: [`Feedback::default`], the
    /// repetitive structure with the gains of `docs/params.md`).
    #[serde(default)]
    pub feedback: Feedback,
}

/// The feedback structure around the inverse (`docs/control.md`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FeedbackStructure {
    /// Feedforward only: the inverse alone, the sensor only watched for faults.
    Off,
    /// PI on the displacement error, acting on the desired displacement.
    Integral,
    /// Harmonic learning over the trajectory's cycle (repetitive control), plus the PI terms
    /// when their gains are not zero.
    Repetitive,
}

/// Displacement-feedback settings (the law: `magctl::inverse::feedback`; `docs/control.md`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Feedback {
    /// `off`, `integral` or `repetitive`.
    pub structure: FeedbackStructure,
    /// γ: the fraction of the error the table corrects per trajectory cycle, in [0, 2].
    pub learning_gain: f64,
    /// N: the harmonics of the trajectory's fundamental the learning corrects, 1..=16 (those
    /// above are never excited by it: keep `N·f_trajectory` below any unmodelled resonance).
    pub learning_harmonics: u32,
    /// λ: the leak of the learned coefficients per cycle (forgets what is no longer measured),
    /// in [0, 1).
    pub learning_leak_per_cycle: f64,
    /// K_p of the PI, m of correction per m of error, in [0, 1).
    pub proportional_gain: f64,
    /// K_i of the PI, 1/s, in [0, sample_rate_hz / 2].
    pub integral_gain_per_s: f64,
    /// Bound on the correction (each table entry and the integrator), m, > 0.
    pub correction_limit_m: f64,
    /// A sample bit-identical for this many ticks in a row, while the desired displacement moved
    /// more than a tenth of the trajectory's band, is a stuck sensor (the loop falls back to
    /// feedforward), >= 2.
    pub stuck_sensor_ticks: u32,
}

impl Default for Feedback {
    fn default() -> Self {
        Feedback {
            structure: FeedbackStructure::Repetitive,
            learning_gain: 0.3,
            learning_harmonics: 6,
            learning_leak_per_cycle: 0.002,
            proportional_gain: 0.0,
            integral_gain_per_s: 0.0,
            correction_limit_m: 25e-6,
            stuck_sensor_ticks: 200,
        }
    }
}

/// The coil and its current amplifier. A transconductance amplifier can force the coil current
/// to change only as fast as its output voltage allows: `L di/dt = V − R i` (back-EMF of the rod
/// neglected), so at the current limit `I_max` the fastest guaranteed slew is
/// `(V_compliance − R_coil I_max) / L_coil`. A command that slews faster is not followed (the
/// amplifier saturates and the coil current lags the model), so `control.current_slew_limit_a_per_s`
/// must not exceed it ([`Amplifier::max_slew_a_per_s`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Amplifier {
    /// Highest voltage the amplifier can put across the coil (its supply minus its dropout), V.
    pub compliance_voltage_v: f64,
    /// DC resistance of the coil (hot, at the highest expected temperature), Ω.
    pub coil_resistance_ohm: f64,
    /// Inductance of the coil with the rod inside, H.
    pub coil_inductance_h: f64,
}

impl Amplifier {
    /// Fastest current slew the amplifier guarantees at `current_limit_a`, A/s:
    /// `(V_compliance − R_coil I_max) / L_coil` (negative when it cannot even hold `I_max`).
    pub fn max_slew_a_per_s(&self, current_limit_a: f64) -> f64 {
        (self.compliance_voltage_v - self.coil_resistance_ohm * current_limit_a)
            / self.coil_inductance_h
    }
}

/// The coil's lumped thermal model, `τ ΔT' = R_th R_coil I² − ΔT` (the heat `I² R_coil`, with the
/// hot resistance of [`Amplifier::coil_resistance_ohm`], through the winding's thermal resistance
/// to ambient), and the rise the firmware's measurement programme keeps under (it pauses at 0 A
/// where the Preisach memory allows, `magctl::programme`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CoilThermal {
    /// Thermal resistance from the winding to ambient, K/W.
    pub thermal_resistance_k_per_w: f64,
    /// Thermal time constant of the winding, s.
    pub time_constant_s: f64,
    /// Largest temperature rise of the winding the measurement programme may cause, K.
    pub max_rise_k: f64,
}

/// The current amplifier's current-monitor output, wired to the measurement image's second ADC
/// channel and converted on the displacement's trigger (NUCLEO: ADC2 channel 1, PA1, simultaneous
/// with the sensor's ADC1 channel 0): `coil_current_a = offset_a + gain_a_per_count · count`,
/// counts of the sensor's `adc_bits`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CurrentMonitorScale {
    /// Coil current per count, A (negative for a monitor wired the other way round).
    pub gain_a_per_count: f64,
    /// Coil current at count 0, A.
    pub offset_a: f64,
}

/// The displacement sensor: an ADC count per control tick, scaled to metres. A reading outside
/// `[valid_min_m, valid_max_m]` (a sensor at its rail, a broken cable, the rod beyond its stroke)
/// or a count above the ADC's range is a sensor fault: the controller ramps the coil to 0 A and
/// flags it (`docs/safety.md`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Sensor {
    /// Resolution of the ADC, bits (counts `0 ..= 2^bits − 1`).
    pub adc_bits: u32,
    /// Displacement per count, m (negative for a sensor mounted the other way round).
    pub gain_m_per_count: f64,
    /// Displacement at count 0, m.
    pub offset_m: f64,
    /// Lowest valid reading, m.
    pub valid_min_m: f64,
    /// Highest valid reading, m.
    pub valid_max_m: f64,
    /// Delay from the displacement to the sample the interrupt reads (conversion, anti-alias
    /// filter group delay), s.
    pub sample_delay_s: f64,
}

/// Desired-trajectory generator: a Van der Pol oscillator `x'' - μ (1 - x²) x' + x = 0` in scaled
/// time, mapped into a displacement band.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Trajectory {
    /// μ of the oscillator (dimensionless, ≥ 0).
    pub van_der_pol_mu: f64,
    /// Angular frequency scale: the oscillator runs in time `ω t`, with `ω = 2π frequency_scale_hz`.
    pub frequency_scale_hz: f64,
    /// Lower edge of the displacement band the oscillator's limit cycle is mapped to, m.
    pub displacement_min_m: f64,
    /// Upper edge of the displacement band, m.
    pub displacement_max_m: f64,
}

/// Provenance of the parameters.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Provenance {
    /// What produced this file (e.g. "analytic default", "maglab identify").
    pub source: String,
    /// Free-form details (dataset, date, residuals, density formula...).
    #[serde(default, flatten)]
    pub details: serde_json::Map<String, serde_json::Value>,
}

impl Provenance {
    /// Key of the list of fields identified from data (`maglab identify` writes it).
    pub const IDENTIFIED: &'static str = "identified";
    /// Key of the identification's quality warnings (`maglab identify` writes it).
    pub const WARNINGS: &'static str = "warnings";
    /// The fields of the dynamic constants `R_eddy`, `ξ`, `f0`, in that order: what the
    /// identification fits from sines and the diagnosis refits.
    pub const DYNAMIC_FIELDS: [&'static str; 3] = [
        "actuator.eddy_resistance_ohm",
        "actuator.damping_ratio",
        "actuator.resonance_hz",
    ];

    /// The fields listed under [`Self::IDENTIFIED`] (empty when there is none).
    pub fn identified_fields(&self) -> Vec<&str> {
        self.string_list(Self::IDENTIFIED)
    }

    /// The warnings listed under [`Self::WARNINGS`] (empty when there is none).
    pub fn warnings(&self) -> Vec<&str> {
        self.string_list(Self::WARNINGS)
    }

    fn string_list(&self, key: &str) -> Vec<&str> {
        self.details
            .get(key)
            .and_then(serde_json::Value::as_array)
            .map(|a| a.iter().filter_map(serde_json::Value::as_str).collect())
            .unwrap_or_default()
    }
}

/// An invalid parameter file: which field, and why.
#[derive(Debug, Clone, PartialEq)]
pub struct ParamsError {
    /// The file (or other source name) that was read.
    pub source_name: String,
    /// Dotted path of the offending field, e.g. `preisach.weights_a_per_m[17]`; empty when the
    /// document itself is unreadable.
    pub field: String,
    /// What is wrong with it.
    pub reason: String,
}

impl fmt::Display for ParamsError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.field.is_empty() {
            write!(f, "{}: {}", self.source_name, self.reason)
        } else {
            write!(
                f,
                "{}: field `{}`: {}",
                self.source_name, self.field, self.reason
            )
        }
    }
}

impl std::error::Error for ParamsError {}

impl ActuatorParams {
    /// Reads and validates a parameter file.
    pub fn load(path: &Path) -> Result<Self, ParamsError> {
        let name = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|e| ParamsError {
            source_name: name.clone(),
            field: String::new(),
            reason: format!("cannot read the file: {e}"),
        })?;
        Self::parse(&text, &name)
    }

    /// Parses and validates a parameter document; `source_name` is used in error messages.
    pub fn parse(text: &str, source_name: &str) -> Result<Self, ParamsError> {
        let de = &mut serde_json::Deserializer::from_str(text);
        let params: Self = serde_path_to_error::deserialize(de).map_err(|e| {
            let path = e.path().to_string();
            let inner = e.into_inner();
            let message = inner.to_string();
            // serde reports a missing field at its parent's path: name the field itself.
            let (field, reason) = match message.strip_prefix("missing field `") {
                Some(rest) => {
                    let name = rest.split('`').next().unwrap_or(rest);
                    let field = if path == "." || path.is_empty() {
                        name.to_string()
                    } else {
                        format!("{path}.{name}")
                    };
                    (field, "missing field".to_string())
                }
                None => {
                    let field = if path == "." { String::new() } else { path };
                    // serde_json's wording for the two ways a JSON file can hold a non-finite
                    // number: an overflowing literal (`1e999`) and a bare `NaN`/`Infinity`.
                    let reason = if message.starts_with("number out of range") {
                        format!("must be a finite number ({message})")
                    } else if message.starts_with("expected value") {
                        format!("not a JSON value; numbers must be finite, NaN and Infinity are not JSON ({message})")
                    } else {
                        message
                    };
                    (field, reason)
                }
            };
            ParamsError {
                source_name: source_name.to_string(),
                field,
                reason,
            }
        })?;
        params.validate(source_name)?;
        Ok(params)
    }

    /// Serializes to pretty JSON (the format `build.rs` reads back).
    pub fn to_json_pretty(&self) -> String {
        let mut text = serde_json::to_string_pretty(self).unwrap_or_default();
        text.push('\n');
        text
    }

    /// What a firmware image needs beyond [`ActuatorParams::validate`] (`build.rs` and
    /// `maglab params check` run both): the rod at rest, unmagnetized at 0 A, sits at 0 m, and a
    /// reading there (with its noise and the count it rounds to) must never be a sensor fault, or
    /// the firmware stops at its first sample when it starts without conditioning. The host
    /// tools, which never judge a reading against the valid range, accept a file without it (a
    /// file written for an older default, `valid_min_m` 0.5 µm, still identifies and diagnoses).
    pub fn validate_for_firmware(&self, source_name: &str) -> Result<(), ParamsError> {
        let err = |field: &str, reason: String| ParamsError {
            source_name: source_name.to_string(),
            field: field.to_string(),
            reason,
        };
        let sn = &self.sensor;
        if sn.valid_min_m > -sn.gain_m_per_count.abs() || sn.valid_max_m <= 0.0 {
            return Err(err(
                "sensor.valid_min_m",
                format!(
                    "the rest position 0 m (the rod unmagnetized at 0 A) must lie inside the valid \
                     range [{}, {}] m with at least one ADC count ({:.3e} m) below it to spare",
                    sn.valid_min_m, sn.valid_max_m, sn.gain_m_per_count.abs()
                ),
            ));
        }
        Ok(())
    }

    /// Checks every constraint the core relies on (errors name `source_name`, the field and the
    /// reason).
    pub fn validate(&self, source_name: &str) -> Result<(), ParamsError> {
        let err = |field: &str, reason: String| ParamsError {
            source_name: source_name.to_string(),
            field: field.to_string(),
            reason,
        };
        self.check_scalars(&err)?;
        self.check_band_and_amplifier(&err)?;
        self.check_sensor(&err)?;
        self.check_feedback(&err)?;
        self.check_grid(&err)?;
        self.check_reversible(&err)?;
        self.check_masses(&err)?;
        self.check_reach(&err)?;
        if let Some(d) = &self.datasheet {
            d.check(&err)?;
        }
        if let Some(t) = &self.coil_thermal {
            for (name, value) in [
                (
                    "coil_thermal.thermal_resistance_k_per_w",
                    t.thermal_resistance_k_per_w,
                ),
                ("coil_thermal.time_constant_s", t.time_constant_s),
                ("coil_thermal.max_rise_k", t.max_rise_k),
            ] {
                if !(value.is_finite() && value > 0.0) {
                    return Err(err(name, format!("must be finite and > 0, got {value}")));
                }
            }
        }
        if let Some(m) = &self.current_monitor {
            if !(m.gain_a_per_count.is_finite() && m.gain_a_per_count != 0.0) {
                return Err(err(
                    "current_monitor.gain_a_per_count",
                    format!("must be finite and non-zero, got {}", m.gain_a_per_count),
                ));
            }
            if !m.offset_a.is_finite() {
                return Err(err(
                    "current_monitor.offset_a",
                    format!("must be finite, got {}", m.offset_a),
                ));
            }
        }
        Ok(())
    }

    /// Checks the schema version; every scalar positive, non-negative or finite as it must be.
    fn check_scalars(&self, err: &dyn Fn(&str, String) -> ParamsError) -> Result<(), ParamsError> {
        if self.schema_version != SCHEMA_VERSION {
            return Err(err(
                "schema_version",
                format!(
                    "this build reads version {SCHEMA_VERSION}, the file says {}",
                    self.schema_version
                ),
            ));
        }
        let a = &self.actuator;
        let positive = [
            ("actuator.coil_turns", a.coil_turns),
            ("actuator.rod_area_m2", a.rod_area_m2),
            ("actuator.rod_length_m", a.rod_length_m),
            ("actuator.coil_factor_per_m", a.coil_factor_per_m),
            (
                "actuator.saturation_magnetization_a_per_m",
                a.saturation_magnetization_a_per_m,
            ),
            (
                "actuator.saturation_magnetostriction",
                a.saturation_magnetostriction,
            ),
            ("actuator.resonance_hz", a.resonance_hz),
            ("actuator.damping_ratio", a.damping_ratio),
            ("control.sample_rate_hz", self.control.sample_rate_hz),
            ("control.current_limit_a", self.control.current_limit_a),
            (
                "control.current_slew_limit_a_per_s",
                self.control.current_slew_limit_a_per_s,
            ),
            (
                "trajectory.frequency_scale_hz",
                self.trajectory.frequency_scale_hz,
            ),
            (
                "amplifier.compliance_voltage_v",
                self.amplifier.compliance_voltage_v,
            ),
            (
                "amplifier.coil_resistance_ohm",
                self.amplifier.coil_resistance_ohm,
            ),
            (
                "amplifier.coil_inductance_h",
                self.amplifier.coil_inductance_h,
            ),
        ];
        for (field, value) in positive {
            check_finite(field, value).map_err(|r| err(field, r))?;
            if value <= 0.0 {
                return Err(err(field, format!("must be > 0, got {value}")));
            }
        }
        let non_negative = [
            ("actuator.eddy_resistance_ohm", a.eddy_resistance_ohm),
            ("trajectory.van_der_pol_mu", self.trajectory.van_der_pol_mu),
        ];
        for (field, value) in non_negative {
            check_finite(field, value).map_err(|r| err(field, r))?;
            if value < 0.0 {
                return Err(err(field, format!("must be >= 0, got {value}")));
            }
        }
        let finite = [
            (
                "trajectory.displacement_min_m",
                self.trajectory.displacement_min_m,
            ),
            (
                "trajectory.displacement_max_m",
                self.trajectory.displacement_max_m,
            ),
        ];
        for (field, value) in finite {
            check_finite(field, value).map_err(|r| err(field, r))?;
        }
        Ok(())
    }

    /// Checks the trajectory band within the stroke; the amplifier can hold and slew the current limit.
    fn check_band_and_amplifier(
        &self,
        err: &dyn Fn(&str, String) -> ParamsError,
    ) -> Result<(), ParamsError> {
        let a = &self.actuator;
        let t = &self.trajectory;
        if t.displacement_min_m >= t.displacement_max_m {
            return Err(err(
                "trajectory.displacement_min_m",
                format!(
                    "must be < trajectory.displacement_max_m ({} >= {})",
                    t.displacement_min_m, t.displacement_max_m
                ),
            ));
        }
        let stroke_m = a.rod_length_m * a.saturation_magnetostriction;
        if t.displacement_min_m < 0.0 || t.displacement_max_m > stroke_m {
            return Err(err(
                "trajectory.displacement_max_m",
                format!(
                    "the band [{}, {}] m must lie inside the actuator's stroke [0, {stroke_m:.4e}] m (l_m λ_s)",
                    t.displacement_min_m, t.displacement_max_m
                ),
            ));
        }
        let amp = &self.amplifier;
        let limit_a = self.control.current_limit_a;
        let holding_v = amp.coil_resistance_ohm * limit_a;
        if amp.compliance_voltage_v <= holding_v {
            return Err(err(
                "amplifier.compliance_voltage_v",
                format!(
                    "{} V cannot drive control.current_limit_a = {limit_a} A through the coil's {} ohm \
                     (needs more than R I_max = {holding_v} V)",
                    amp.compliance_voltage_v, amp.coil_resistance_ohm
                ),
            ));
        }
        let max_slew = amp.max_slew_a_per_s(limit_a);
        if self.control.current_slew_limit_a_per_s > max_slew {
            return Err(err(
                "control.current_slew_limit_a_per_s",
                format!(
                    "{} A/s is faster than the amplifier can drive the coil at the current limit: \
                     (V_compliance - R_coil I_max) / L_coil = ({} - {} x {limit_a}) / {} = {max_slew:.1} A/s",
                    self.control.current_slew_limit_a_per_s,
                    amp.compliance_voltage_v,
                    amp.coil_resistance_ohm,
                    amp.coil_inductance_h
                ),
            ));
        }
        Ok(())
    }

    /// Checks the sensor's range, its valid band inside it and the trajectory band inside that, its delay.
    fn check_sensor(&self, err: &dyn Fn(&str, String) -> ParamsError) -> Result<(), ParamsError> {
        let t = &self.trajectory;
        let sn = &self.sensor;
        if !(8..=24).contains(&sn.adc_bits) {
            return Err(err(
                "sensor.adc_bits",
                format!("must be 8 ..= 24, got {}", sn.adc_bits),
            ));
        }
        for (field, value) in [
            ("sensor.gain_m_per_count", sn.gain_m_per_count),
            ("sensor.offset_m", sn.offset_m),
            ("sensor.valid_min_m", sn.valid_min_m),
            ("sensor.valid_max_m", sn.valid_max_m),
            ("sensor.sample_delay_s", sn.sample_delay_s),
        ] {
            check_finite(field, value).map_err(|r| err(field, r))?;
        }
        if sn.gain_m_per_count == 0.0 {
            return Err(err(
                "sensor.gain_m_per_count",
                "must not be 0 (the reading would not depend on the count)".into(),
            ));
        }
        if sn.valid_min_m >= sn.valid_max_m {
            return Err(err(
                "sensor.valid_min_m",
                format!(
                    "must be < sensor.valid_max_m ({} >= {})",
                    sn.valid_min_m, sn.valid_max_m
                ),
            ));
        }
        let full_count = ((1u64 << sn.adc_bits) - 1) as f64;
        let (r0, r1) = (sn.offset_m, sn.offset_m + sn.gain_m_per_count * full_count);
        let (reach_lo, reach_hi) = (r0.min(r1), r0.max(r1));
        if sn.valid_min_m < reach_lo || sn.valid_max_m > reach_hi {
            return Err(err(
                "sensor.valid_max_m",
                format!(
                    "the valid range [{}, {}] m must lie inside what the ADC can read, [{reach_lo:.4e}, {reach_hi:.4e}] m (offset + gain x 0 ..= {full_count})",
                    sn.valid_min_m, sn.valid_max_m
                ),
            ));
        }
        if t.displacement_min_m < sn.valid_min_m || t.displacement_max_m > sn.valid_max_m {
            return Err(err(
                "sensor.valid_min_m",
                format!(
                    "the trajectory band [{}, {}] m must lie inside the sensor's valid range [{}, {}] m",
                    t.displacement_min_m, t.displacement_max_m, sn.valid_min_m, sn.valid_max_m
                ),
            ));
        }
        let period_s = 1.0 / self.control.sample_rate_hz;
        if sn.sample_delay_s < 0.0 || sn.sample_delay_s > 10.0 * period_s {
            return Err(err(
                "sensor.sample_delay_s",
                format!(
                    "must be >= 0 and at most 10 control periods ({:.3e} s), got {}",
                    10.0 * period_s,
                    sn.sample_delay_s
                ),
            ));
        }
        Ok(())
    }

    /// Checks the feedback gains, and the resonance below the Nyquist rate.
    fn check_feedback(&self, err: &dyn Fn(&str, String) -> ParamsError) -> Result<(), ParamsError> {
        let a = &self.actuator;
        let fb = &self.control.feedback;
        let rate = self.control.sample_rate_hz;
        let in_range = |field: &str, v: f64, lo: f64, hi: f64, closed_hi: bool| {
            let ok = v.is_finite() && v >= lo && (v < hi || (closed_hi && v == hi));
            if ok {
                Ok(())
            } else {
                Err(err(
                    field,
                    format!(
                        "must be in [{lo}, {hi}{} got {v}",
                        if closed_hi { "]," } else { ")," }
                    ),
                ))
            }
        };
        in_range(
            "control.feedback.learning_gain",
            fb.learning_gain,
            0.0,
            2.0,
            true,
        )?;
        in_range(
            "control.feedback.learning_leak_per_cycle",
            fb.learning_leak_per_cycle,
            0.0,
            1.0,
            false,
        )?;
        in_range(
            "control.feedback.proportional_gain",
            fb.proportional_gain,
            0.0,
            1.0,
            false,
        )?;
        in_range(
            "control.feedback.integral_gain_per_s",
            fb.integral_gain_per_s,
            0.0,
            rate / 2.0,
            true,
        )?;
        if !(fb.correction_limit_m.is_finite() && fb.correction_limit_m > 0.0) {
            return Err(err(
                "control.feedback.correction_limit_m",
                format!("must be > 0 m, got {}", fb.correction_limit_m),
            ));
        }
        if !(1..=16).contains(&fb.learning_harmonics) {
            return Err(err(
                "control.feedback.learning_harmonics",
                format!("must be in 1..=16, got {}", fb.learning_harmonics),
            ));
        }
        if fb.stuck_sensor_ticks < 2 {
            return Err(err(
                "control.feedback.stuck_sensor_ticks",
                format!("must be >= 2, got {}", fb.stuck_sensor_ticks),
            ));
        }
        let nyquist = self.control.sample_rate_hz / 2.0;
        if a.resonance_hz >= nyquist {
            return Err(err(
                "actuator.resonance_hz",
                format!(
                    "{} Hz is not below the control Nyquist frequency {nyquist} Hz",
                    a.resonance_hz
                ),
            ));
        }

        Ok(())
    }

    /// Checks the Preisach grid: its range and lines.
    fn check_grid(&self, err: &dyn Fn(&str, String) -> ParamsError) -> Result<(), ParamsError> {
        let p = &self.preisach;
        for (field, value) in [
            ("preisach.h_min_a_per_m", p.h_min_a_per_m),
            ("preisach.h_max_a_per_m", p.h_max_a_per_m),
        ] {
            check_finite(field, value).map_err(|r| err(field, r))?;
        }
        if p.h_min_a_per_m >= p.h_max_a_per_m {
            return Err(err(
                "preisach.h_min_a_per_m",
                format!(
                    "must be < preisach.h_max_a_per_m ({} >= {})",
                    p.h_min_a_per_m, p.h_max_a_per_m
                ),
            ));
        }
        if let Some(lines) = &p.grid_lines_a_per_m {
            let field = "preisach.grid_lines_a_per_m";
            if lines.len() != p.levels + 1 {
                return Err(err(
                    field,
                    format!(
                        "{} levels need {} grid lines, the file has {}",
                        p.levels,
                        p.levels + 1,
                        lines.len()
                    ),
                ));
            }
            for (k, &h) in lines.iter().enumerate() {
                let f = format!("{field}[{k}]");
                check_finite(&f, h).map_err(|r| err(&f, r))?;
                if k > 0 && h <= lines[k - 1] {
                    return Err(err(
                        &f,
                        format!(
                            "grid lines must increase strictly: {h} after {}",
                            lines[k - 1]
                        ),
                    ));
                }
                if k > 0 && (h as f32) <= (lines[k - 1] as f32) {
                    return Err(err(
                        &f,
                        format!(
                            "{h} and {} are the same in f32 (the core's precision): the interval is empty",
                            lines[k - 1]
                        ),
                    ));
                }
            }
            if lines.first() != Some(&p.h_min_a_per_m) || lines.last() != Some(&p.h_max_a_per_m) {
                return Err(err(
                    field,
                    format!(
                        "the first and last lines must be preisach.h_min_a_per_m and h_max_a_per_m                          ({} and {}), got {} and {}",
                        p.h_min_a_per_m,
                        p.h_max_a_per_m,
                        lines.first().copied().unwrap_or(f64::NAN),
                        lines.last().copied().unwrap_or(f64::NAN)
                    ),
                ));
            }
        }
        Ok(())
    }

    /// Checks the reversible part's susceptibilities.
    fn check_reversible(
        &self,
        err: &dyn Fn(&str, String) -> ParamsError,
    ) -> Result<(), ParamsError> {
        let p = &self.preisach;
        if let Some(chi) = &p.reversible_susceptibility {
            let field = "preisach.reversible_susceptibility";
            if chi.len() != p.levels {
                return Err(err(
                    field,
                    format!(
                        "{} levels need {} susceptibilities (one per interval), the file has {}",
                        p.levels,
                        p.levels,
                        chi.len()
                    ),
                ));
            }
            for (k, &c) in chi.iter().enumerate() {
                let f = format!("{field}[{k}]");
                check_finite(&f, c).map_err(|r| err(&f, r))?;
                if c < 0.0 {
                    return Err(err(
                        &f,
                        format!(
                            "must be >= 0 (the reversible part must rise with the field for the \
                             inverse to exist), got {c}"
                        ),
                    ));
                }
                if c > MAX_REVERSIBLE_SUSCEPTIBILITY {
                    return Err(err(
                        &f,
                        format!(
                            "{c} is beyond {MAX_REVERSIBLE_SUSCEPTIBILITY:e} (dM/dH of the \
                             reversible part; is the unit right?)"
                        ),
                    ));
                }
            }
        }
        Ok(())
    }

    /// Checks the level count and the cell masses.
    fn check_masses(&self, err: &dyn Fn(&str, String) -> ParamsError) -> Result<(), ParamsError> {
        let p = &self.preisach;
        let implied_levels = levels_for_cells(p.weights_a_per_m.len());
        if p.levels != PREISACH_LEVELS {
            let implied = match implied_levels {
                Some(l) => format!("; its {} weights imply {l}", p.weights_a_per_m.len()),
                None => String::new(),
            };
            return Err(err(
                "preisach.levels",
                format!(
                    "the core is built for {PREISACH_LEVELS} levels, the file says {}{implied}",
                    p.levels
                ),
            ));
        }
        if p.weights_a_per_m.len() != cell_count(p.levels) {
            let implied = match implied_levels {
                Some(l) => format!(" (that is the count for {l} levels)"),
                None => " (no level count gives that many cells)".to_string(),
            };
            return Err(err(
                "preisach.weights_a_per_m",
                format!(
                    "{} levels need {} weights, the file has {}{implied}",
                    p.levels,
                    cell_count(p.levels),
                    p.weights_a_per_m.len()
                ),
            ));
        }
        for (k, &w) in p.weights_a_per_m.iter().enumerate() {
            let field = format!("preisach.weights_a_per_m[{k}]");
            check_finite(&field, w).map_err(|r| err(&field, r))?;
            if w < 0.0 {
                return Err(err(&field, format!("a cell mass must be >= 0, got {w}")));
            }
        }
        let total: f64 = p.weights_a_per_m.iter().sum();
        if total <= 0.0 {
            return Err(err(
                "preisach.weights_a_per_m",
                "all weights are zero: the operator has no output".into(),
            ));
        }
        if total > f32::MAX as f64 {
            return Err(err(
                "preisach.weights_a_per_m",
                format!("the weights sum to {total:e}, beyond f32 (the core's saturation output)"),
            ));
        }
        Ok(())
    }

    /// Checks the reach (inside the grid, increasing) and the offset (finite, at most `M_s`).
    fn check_reach(&self, err: &dyn Fn(&str, String) -> ParamsError) -> Result<(), ParamsError> {
        let p = &self.preisach;
        let field = "preisach.offset_a_per_m";
        check_finite(field, p.offset_a_per_m).map_err(|r| err(field, r))?;
        let ms = self.actuator.saturation_magnetization_a_per_m;
        if p.offset_a_per_m.abs() > ms {
            return Err(err(
                field,
                format!(
                    "|{}| exceeds M_s = {ms} (a magnetization of part of the rod cannot)",
                    p.offset_a_per_m
                ),
            ));
        }
        let Some(reach) = &p.reach_a_per_m else {
            return Ok(());
        };
        let field = "preisach.reach_a_per_m";
        let [lo, hi] = reach[..] else {
            return Err(err(
                field,
                format!(
                    "must be [H_lo, H_hi], two fields; the file has {}",
                    reach.len()
                ),
            ));
        };
        for (k, h) in [lo, hi].into_iter().enumerate() {
            let f = format!("{field}[{k}]");
            check_finite(&f, h).map_err(|r| err(&f, r))?;
        }
        if lo >= hi {
            return Err(err(field, format!("H_lo must be < H_hi, got [{lo}, {hi}]")));
        }
        if lo < p.h_min_a_per_m || hi > p.h_max_a_per_m {
            return Err(err(
                field,
                format!(
                    "[{lo}, {hi}] must lie inside the grid [{}, {}]",
                    p.h_min_a_per_m, p.h_max_a_per_m
                ),
            ));
        }
        Ok(())
    }

    /// The saturation output of the Preisach operator, `Σ w` (A/m).
    pub fn preisach_total_a_per_m(&self) -> f64 {
        self.preisach.weights_a_per_m.iter().sum()
    }
}

fn is_zero(value: &f64) -> bool {
    *value == 0.0
}

/// Finite, and finite once baked: the core stores every parameter as f32, so a value beyond
/// `f32::MAX` would become an infinite constant.
fn check_finite(_field: &str, value: f64) -> Result<(), String> {
    if !value.is_finite() {
        Err(format!("must be a finite number, got {value}"))
    } else if value.abs() > f32::MAX as f64 {
        Err(format!(
            "must be representable in f32 (|x| <= {:e}), got {value:e}",
            f32::MAX
        ))
    } else {
        Ok(())
    }
}

/// The level count `L` with `L (L + 1) / 2 == cells`, if any.
pub fn levels_for_cells(cells: usize) -> Option<usize> {
    (1..=1000).find(|&l| cell_count(l) == cells)
}

/// Index of cell `(i, j)` (β in interval `i`, α in interval `j`, `i <= j`) in the weight vector.
pub const fn cell_index(i: usize, j: usize) -> usize {
    j * (j + 1) / 2 + i
}
