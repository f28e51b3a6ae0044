//! The unmodelled effects: their names (part of the command-line and JSON interface), the rig's
//! physical parameters for each, and the `name:key=value,...` syntax of `maglab rig --effect`.
//!
//! Seven effects are in the diagnosis library ([`EffectName::LIBRARY`]); `backlash` is one the
//! diagnosis deliberately does not know, so that a dataset made with it tests the `unexplained`
//! verdict. Every parameter has a default magnitude that makes a visible gap (a few % of the
//! stroke) with the paper's constants; the defaults are listed by `maglab rig --help` and
//! [`EffectName::keys`].

use host_tests::reference::rig::{EddyPath, MechanicalLoad, PlantEffects, ThermalDrift};
use std::fmt;

/// The name of an effect.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum EffectName {
    /// R_eddy varies with frequency (a ladder of eddy-current paths).
    EddyFrequencyDependence,
    /// The coil current lags the command (first-order driver bandwidth).
    AmplifierBandwidth,
    /// The displacement sensor's low-pass and delay.
    SensorDynamics,
    /// `M = Γ[H] + χ_r H`.
    ReversibleMagnetization,
    /// The output scale drifts as the coil heats with I².
    ThermalDrift,
    /// Stiffness (resonance) depends on magnetization.
    DeltaEEffect,
    /// An extra mass / second mode.
    MechanicalLoad,
    /// Play in the output linkage (not in the diagnosis library).
    Backlash,
}

impl EffectName {
    /// Every effect the rig can switch on.
    pub const ALL: [EffectName; 8] = [
        EffectName::EddyFrequencyDependence,
        EffectName::AmplifierBandwidth,
        EffectName::SensorDynamics,
        EffectName::ReversibleMagnetization,
        EffectName::ThermalDrift,
        EffectName::DeltaEEffect,
        EffectName::MechanicalLoad,
        EffectName::Backlash,
    ];

    /// The effects the diagnosis tries as candidates.
    pub const LIBRARY: [EffectName; 7] = [
        EffectName::EddyFrequencyDependence,
        EffectName::AmplifierBandwidth,
        EffectName::SensorDynamics,
        EffectName::ReversibleMagnetization,
        EffectName::ThermalDrift,
        EffectName::DeltaEEffect,
        EffectName::MechanicalLoad,
    ];

    /// The interface name.
    pub fn name(self) -> &'static str {
        match self {
            EffectName::EddyFrequencyDependence => "eddy_frequency_dependence",
            EffectName::AmplifierBandwidth => "amplifier_bandwidth",
            EffectName::SensorDynamics => "sensor_dynamics",
            EffectName::ReversibleMagnetization => "reversible_magnetization",
            EffectName::ThermalDrift => "thermal_drift",
            EffectName::DeltaEEffect => "delta_e_effect",
            EffectName::MechanicalLoad => "mechanical_load",
            EffectName::Backlash => "backlash",
        }
    }

    /// Parses an interface name.
    pub fn parse(text: &str) -> Result<Self, String> {
        EffectName::ALL
            .into_iter()
            .find(|e| e.name() == text)
            .ok_or_else(|| {
                format!(
                    "unknown effect `{text}`: expected one of {}",
                    EffectName::ALL.map(|e| e.name()).join(", ")
                )
            })
    }

    /// The rig parameters of this effect: `(key, default, meaning)`. Keys marked optional by a
    /// default of `0` switch a part off (`path2_ohm = 0`: no second path; `delay_s = 0`; …).
    pub fn keys(self) -> &'static [(&'static str, f64, &'static str)] {
        match self {
            EffectName::EddyFrequencyDependence => &[
                ("path_ohm", 50.0, "resistance of the extra eddy path, ohm"),
                ("corner_hz", 150.0, "corner frequency of the extra path, Hz"),
                ("path2_ohm", 0.0, "second extra path, ohm (0 = none)"),
                ("corner2_hz", 600.0, "corner of the second path, Hz"),
            ],
            EffectName::AmplifierBandwidth => &[(
                "corner_hz",
                300.0,
                "first-order corner of the coil current, Hz",
            )],
            EffectName::SensorDynamics => &[
                ("corner_hz", 400.0, "sensor low-pass corner, Hz (0 = none)"),
                ("delay_s", 1.0e-4, "sensor delay, s"),
            ],
            EffectName::ReversibleMagnetization => {
                &[("susceptibility", 3.0, "reversible susceptibility chi_r")]
            }
            EffectName::ThermalDrift => &[
                ("time_constant_s", 0.3, "thermal time constant, s"),
                (
                    "rise_k_per_a2",
                    60.0,
                    "steady temperature rise per A^2, K/A^2",
                ),
                (
                    "scale_per_k",
                    2.0e-3,
                    "relative loss of magnetostriction per K, 1/K",
                ),
            ],
            EffectName::DeltaEEffect => &[(
                "stiffness_change",
                1.5,
                "relative stiffness change at saturation: w^2 = w0^2 (1 + d (M/Ms)^2)",
            )],
            EffectName::MechanicalLoad => &[
                ("mass_ratio", 0.6, "load mass / rod effective mass"),
                (
                    "coupling_hz",
                    700.0,
                    "load spring frequency sqrt(k2/m2)/2pi, Hz",
                ),
                ("damping_ratio", 0.15, "damping ratio of the load coupling"),
            ],
            EffectName::Backlash => &[("width_m", 3.0e-6, "play in the output linkage, m")],
        }
    }
}

impl fmt::Display for EffectName {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// One effect switched on in the rig, with its parameters (all keys present, defaults filled).
#[derive(Debug, Clone, PartialEq)]
pub struct RigEffect {
    /// Which effect.
    pub name: EffectName,
    /// `(key, value)` in the order of [`EffectName::keys`].
    pub values: Vec<(&'static str, f64)>,
}

impl RigEffect {
    /// The effect with its default parameters.
    pub fn default_for(name: EffectName) -> Self {
        RigEffect {
            name,
            values: name.keys().iter().map(|&(k, v, _)| (k, v)).collect(),
        }
    }

    /// The value of `key` (a key of [`EffectName::keys`]).
    pub fn get(&self, key: &str) -> f64 {
        self.values
            .iter()
            .find(|(k, _)| *k == key)
            .map(|&(_, v)| v)
            .unwrap_or_else(|| panic!("{} has no parameter {key}", self.name))
    }

    /// Returns the effect with `key` set to `value`.
    pub fn with(mut self, key: &str, value: f64) -> Result<Self, String> {
        let name = self.name;
        let slot = self
            .values
            .iter_mut()
            .find(|(k, _)| *k == key)
            .ok_or_else(|| unknown_key(name, key))?;
        slot.1 = value;
        self.check()?;
        Ok(self)
    }

    /// Parses `name` or `name:key=value,key=value` (missing keys take their defaults).
    pub fn parse(text: &str) -> Result<Self, String> {
        let (name, rest) = match text.split_once(':') {
            Some((n, r)) => (n.trim(), Some(r)),
            None => (text.trim(), None),
        };
        let mut effect = RigEffect::default_for(EffectName::parse(name)?);
        if let Some(rest) = rest {
            for item in rest.split(',').filter(|s| !s.trim().is_empty()) {
                let (key, value) = item
                    .split_once('=')
                    .ok_or_else(|| format!("effect `{name}`: `{item}` is not `key=value`"))?;
                let key = key.trim();
                let value: f64 = value.trim().parse().map_err(|_| {
                    format!(
                        "effect `{name}`: parameter `{key}`: `{}` is not a number",
                        value.trim()
                    )
                })?;
                effect = effect.with(key, value)?;
            }
        }
        effect.check()?;
        Ok(effect)
    }

    /// Checks the physical ranges, naming the parameter.
    fn check(&self) -> Result<(), String> {
        let bad = |key: &str, why: &str| {
            Err(format!(
                "effect `{}`: parameter `{key}` = {}: {why}",
                self.name,
                self.get(key)
            ))
        };
        for &(key, value) in &self.values {
            if !value.is_finite() {
                return bad(key, "must be finite");
            }
        }
        let positive: &[&str] = match self.name {
            EffectName::EddyFrequencyDependence => &["path_ohm", "corner_hz", "corner2_hz"],
            EffectName::AmplifierBandwidth => &["corner_hz"],
            EffectName::SensorDynamics => &[],
            EffectName::ReversibleMagnetization => &[],
            EffectName::ThermalDrift => &["time_constant_s"],
            EffectName::DeltaEEffect => &[],
            EffectName::MechanicalLoad => &["mass_ratio", "coupling_hz", "damping_ratio"],
            EffectName::Backlash => &["width_m"],
        };
        for key in positive {
            if self.get(key) <= 0.0 {
                return bad(key, "must be > 0");
            }
        }
        let non_negative: &[&str] = match self.name {
            EffectName::EddyFrequencyDependence => &["path2_ohm"],
            EffectName::SensorDynamics => &["corner_hz", "delay_s"],
            EffectName::ReversibleMagnetization => &["susceptibility"],
            EffectName::ThermalDrift => &["rise_k_per_a2"],
            _ => &[],
        };
        for key in non_negative {
            if self.get(key) < 0.0 {
                return bad(key, "must be >= 0");
            }
        }
        if self.name == EffectName::DeltaEEffect && self.get("stiffness_change") <= -1.0 {
            return bad(
                "stiffness_change",
                "must be > -1 (the stiffness must stay positive)",
            );
        }
        if self.name == EffectName::ThermalDrift
            && self.get("scale_per_k") * self.get("rise_k_per_a2") * 4.0 >= 1.0
        {
            return bad(
                "scale_per_k",
                "with rise_k_per_a2 it would reverse the output at 2 A (scale·rise·4 >= 1)",
            );
        }
        Ok(())
    }

    /// A one-line description, `name(key=value, ...)`.
    pub fn describe(&self) -> String {
        let parts: Vec<String> = self
            .values
            .iter()
            .map(|(k, v)| format!("{k}={v}"))
            .collect();
        format!("{}({})", self.name, parts.join(", "))
    }
}

fn unknown_key(name: EffectName, key: &str) -> String {
    format!(
        "effect `{name}`: unknown parameter `{key}`: expected one of {}",
        name.keys()
            .iter()
            .map(|k| k.0)
            .collect::<Vec<_>>()
            .join(", ")
    )
}

/// The sensor-side effects of a rig configuration (applied to the sampled displacement).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct SensorEffects {
    /// Backlash width, m.
    pub backlash_m: Option<f64>,
    /// Sensor low-pass corner, Hz.
    pub low_pass_hz: Option<f64>,
    /// Sensor delay, s.
    pub delay_s: Option<f64>,
}

/// Splits a set of effects into the plant part and the sensor part. Each effect may appear once.
pub fn split_effects(effects: &[RigEffect]) -> Result<(PlantEffects, SensorEffects), String> {
    let mut plant = PlantEffects::default();
    let mut sensor = SensorEffects::default();
    let mut seen = Vec::new();
    for e in effects {
        if seen.contains(&e.name) {
            return Err(format!("effect `{}` is given twice", e.name));
        }
        seen.push(e.name);
        match e.name {
            EffectName::EddyFrequencyDependence => {
                plant.eddy_paths.push(EddyPath {
                    resistance_ohm: e.get("path_ohm"),
                    corner_hz: e.get("corner_hz"),
                });
                if e.get("path2_ohm") > 0.0 {
                    plant.eddy_paths.push(EddyPath {
                        resistance_ohm: e.get("path2_ohm"),
                        corner_hz: e.get("corner2_hz"),
                    });
                }
            }
            EffectName::AmplifierBandwidth => plant.amplifier_corner_hz = Some(e.get("corner_hz")),
            EffectName::SensorDynamics => {
                if e.get("corner_hz") > 0.0 {
                    sensor.low_pass_hz = Some(e.get("corner_hz"));
                }
                if e.get("delay_s") > 0.0 {
                    sensor.delay_s = Some(e.get("delay_s"));
                }
            }
            EffectName::ReversibleMagnetization => {
                plant.reversible_susceptibility = Some(e.get("susceptibility"))
            }
            EffectName::ThermalDrift => {
                plant.thermal = Some(ThermalDrift {
                    time_constant_s: e.get("time_constant_s"),
                    rise_k_per_a2: e.get("rise_k_per_a2"),
                    scale_per_k: e.get("scale_per_k"),
                })
            }
            EffectName::DeltaEEffect => plant.delta_e = Some(e.get("stiffness_change")),
            EffectName::MechanicalLoad => {
                plant.load = Some(MechanicalLoad {
                    mass_ratio: e.get("mass_ratio"),
                    coupling_hz: e.get("coupling_hz"),
                    coupling_damping_ratio: e.get("damping_ratio"),
                })
            }
            EffectName::Backlash => sensor.backlash_m = Some(e.get("width_m")),
        }
    }
    Ok((plant, sensor))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parse_fills_defaults_and_names_errors() {
        let e = RigEffect::parse("amplifier_bandwidth:corner_hz=250").unwrap();
        assert_eq!(e.get("corner_hz"), 250.0);
        let e = RigEffect::parse("thermal_drift").unwrap();
        assert_eq!(e.get("time_constant_s"), 0.3);
        let err = RigEffect::parse("amplifier_bandwidth:corner=3").unwrap_err();
        assert!(err.contains("unknown parameter `corner`"), "{err}");
        let err = RigEffect::parse("amplifier_bandwidth:corner_hz=-3").unwrap_err();
        assert!(err.contains("`corner_hz` = -3: must be > 0"), "{err}");
        let err = RigEffect::parse("skin").unwrap_err();
        assert!(err.contains("unknown effect `skin`"), "{err}");
        let err = RigEffect::parse("backlash:width_m=abc").unwrap_err();
        assert!(err.contains("`abc` is not a number"), "{err}");
        let twice = [
            RigEffect::default_for(EffectName::Backlash),
            RigEffect::default_for(EffectName::Backlash),
        ];
        assert!(split_effects(&twice).unwrap_err().contains("twice"));
    }
}
