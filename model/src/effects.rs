//! The names of the unmodelled effects the diagnosis knows (part of the command-line and JSON
//! interface: `diagnosis.json`'s `verdict`). The bench plant (`maglab-plant`) uses the same names
//! for its own, differently written, forms of these effects and for effects outside this library.

use std::fmt;

/// An effect of the diagnosis' candidate library.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum EffectName {
    /// R_eddy varies with frequency.
    EddyFrequencyDependence,
    /// The coil current lags the command.
    AmplifierBandwidth,
    /// The displacement sensor's dynamics and delay.
    SensorDynamics,
    /// A reversible (anhysteretic) part of the magnetization.
    ReversibleMagnetization,
    /// The output drifts as the coil heats with I².
    ThermalDrift,
    /// Stiffness (resonance) depends on magnetization.
    DeltaEEffect,
    /// An extra mass / second mode.
    MechanicalLoad,
}

impl EffectName {
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
        }
    }

    /// Parses an interface name.
    pub fn parse(text: &str) -> Result<Self, String> {
        EffectName::LIBRARY
            .into_iter()
            .find(|e| e.name() == text)
            .ok_or_else(|| {
                format!(
                    "unknown effect `{text}`: expected one of {}",
                    EffectName::LIBRARY.map(|e| e.name()).join(", ")
                )
            })
    }
}

impl fmt::Display for EffectName {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}
