//! What the bench's datasheets say, each value with its tolerance: optional, read by the host
//! tools only (the firmware bakes none of it). `maglab identify` and `maglab diagnose` use these
//! as priors on the effects they fit (`maglab_model::priors`: a value must lie in
//! `value ± plus_minus`), and say which they used.

use crate::ParamsError;
use serde::{Deserialize, Serialize};

/// A datasheet value and its tolerance, in the field's unit: the true value lies in
/// `value ± plus_minus`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Toleranced {
    /// The value.
    pub value: f64,
    /// Half the width of the band the true value lies in (≥ 0, same unit).
    pub plus_minus: f64,
}

impl Toleranced {
    /// The band `[value − plus_minus, value + plus_minus]`.
    pub fn band(&self) -> (f64, f64) {
        (self.value - self.plus_minus, self.value + self.plus_minus)
    }

    /// The band cut at 0 from below (a delay's: "50 µs ± 80 µs" is at most 130 µs).
    pub fn band_from_zero(&self) -> (f64, f64) {
        let (lo, hi) = self.band();
        (lo.max(0.0), hi)
    }
}

/// The datasheet section of a parameter file. Every field is optional.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Datasheet {
    /// The displacement sensor's −3 dB bandwidth, Hz.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sensor_bandwidth_hz: Option<Toleranced>,
    /// The sensor's delay from displacement to reading (conversion, group delay), s.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sensor_delay_s: Option<Toleranced>,
    /// The current amplifier's −3 dB small-signal bandwidth with this coil, Hz.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub amplifier_bandwidth_hz: Option<Toleranced>,
    /// The coil's DC resistance, Ω.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub coil_resistance_ohm: Option<Toleranced>,
    /// The coil's inductance with the rod inside, H.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub coil_inductance_h: Option<Toleranced>,
    /// The mass the rod drives (fixture, payload, the sensor's target), kg.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub load_mass_kg: Option<Toleranced>,
}

impl Datasheet {
    /// Every field with its name in the file (`datasheet.<name>`), given or not.
    pub fn fields(&self) -> [(&'static str, Option<Toleranced>); 6] {
        [
            ("sensor_bandwidth_hz", self.sensor_bandwidth_hz),
            ("sensor_delay_s", self.sensor_delay_s),
            ("amplifier_bandwidth_hz", self.amplifier_bandwidth_hz),
            ("coil_resistance_ohm", self.coil_resistance_ohm),
            ("coil_inductance_h", self.coil_inductance_h),
            ("load_mass_kg", self.load_mass_kg),
        ]
    }

    /// Each given value finite with a finite tolerance `0 <= plus_minus`; the band above 0 for
    /// every quantity but the delay, whose value must be >= 0 and whose band the priors cut at 0
    /// (`Toleranced::band_from_zero`).
    pub fn check(&self, err: &dyn Fn(&str, String) -> ParamsError) -> Result<(), ParamsError> {
        for (name, given) in self.fields() {
            let Some(t) = given else { continue };
            let field = format!("datasheet.{name}");
            if !(t.value.is_finite() && t.plus_minus.is_finite()) {
                return Err(err(
                    &field,
                    format!(
                        "value and plus_minus must be finite, got {} +/- {}",
                        t.value, t.plus_minus
                    ),
                ));
            }
            if t.plus_minus < 0.0 {
                return Err(err(
                    &format!("{field}.plus_minus"),
                    format!("must be >= 0, got {}", t.plus_minus),
                ));
            }
            let (lo, _) = t.band();
            let delay = name == "sensor_delay_s";
            if (delay && t.value < 0.0) || (!delay && lo <= 0.0) {
                return Err(err(
                    &field,
                    if delay {
                        format!("the delay must be >= 0, got {}", t.value)
                    } else {
                        format!(
                            "the band {} +/- {} must lie above 0 (plus_minus < value)",
                            t.value, t.plus_minus
                        )
                    },
                ));
            }
        }
        Ok(())
    }
}
