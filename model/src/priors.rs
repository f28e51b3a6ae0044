//! Datasheet priors (`datasheet` in the parameter file, `actuator_params::Datasheet`): each
//! given value bounds the candidate parameter it fixes to the datasheet's band — a uniform prior
//! on `value ± plus_minus`, the fit's search range for that parameter. Without a datasheet every
//! range is the library's ([`crate::candidates::effect_parameters`]).
//!
//! | datasheet field | candidate parameter | band |
//! |---|---|---|
//! | `sensor_bandwidth_hz` | `sensor_dynamics.natural_hz` | the −3 dB band's hull over the candidate's damping range (below) |
//! | `sensor_delay_s` | `sensor_dynamics.delay_s` | `value ± plus_minus`, cut at 0 |
//! | `amplifier_bandwidth_hz` | `amplifier_bandwidth.natural_hz` | as the sensor's bandwidth |
//! | `load_mass_kg` | `mechanical_load.mass_ratio` | `m / m_eff`, `m_eff` a third of the rod's mass (below) |
//! | `coil_resistance_ohm`, `coil_inductance_h` | none | the amplifier's `coil_time_constant_s` ([`crate::model::CurrentLoop`]) is `L/R` without the rod's magnetization (`L = μ0 N A c0`; the model adds the rod's `M` itself), a datasheet's inductance is measured with the rod inside |
//!
//! **A −3 dB bandwidth as a natural frequency.** The library's sensor and amplifier (its current
//! loop at `coil_time_constant_s = 0`; a coil's EMF term moves the loop's −3 dB, which a
//! datasheet's bandwidth does not bound) are
//! second-order low-passes `ωn² / (s² + 2ζωn s + ωn²)`, whose −3 dB frequency is `ωn g(ζ)` with
//! `g(ζ)² = 1 − 2ζ² + √((1 − 2ζ²)² + 1)` (from `|H(jω)|² = 1/2`); `g` falls from 1.454 at
//! ζ = 0.3 through 1 at ζ = 1/√2 to 0.172 at ζ = 3 (a first-order sensor is fitted as an
//! overdamped pair, ζ large). Since ζ is fitted too, the band on `ωn` is the set of natural
//! frequencies some ζ of the range maps into the datasheet's band: `[B_lo / g(ζ_lo),
//! B_hi / g(ζ_hi)]` — exact at its ends, wider than the datasheet's band by up to `g(ζ_lo) /
//! g(ζ_hi)` = 8.5× inside (the box the fit's coordinates allow is the hull of the curved set).
//!
//! **Load mass.** The model's load is a mass on a spring and a damper driven by the rod's end
//! (`crate::model`), its `mass_ratio` the load's mass over the rod's: below its own
//! longitudinal mode the rod acts as a spring, whose kinetic energy is that of a third of its
//! mass moving with its end (Rayleigh), so `m_eff = ρ A_m l_m / 3` with the density of
//! Terfenol-D, [`TERFENOL_DENSITY_KG_M3`].

use crate::candidates::{Edge, ParamSpec};
use crate::effects::EffectName;
use actuator_params::{Datasheet, Toleranced};

/// Density of Terfenol-D, kg/m³ (manufacturers' datasheets: 9,200–9,250).
pub const TERFENOL_DENSITY_KG_M3: f64 = 9250.0;

/// A band narrower than this fraction of its value is widened to it: the fit's coordinate needs
/// a range to move in (a zero-width band leaves its Jacobian column zero).
const MIN_RELATIVE_WIDTH: f64 = 1e-6;

/// Each datasheet field (in [`Datasheet::fields`]'s order) and the candidate parameter it bounds
/// (`None`: none; module docs).
const TARGETS: [(&str, Option<(EffectName, &str)>); 6] = [
    (
        "sensor_bandwidth_hz",
        Some((EffectName::SensorDynamics, "natural_hz")),
    ),
    (
        "sensor_delay_s",
        Some((EffectName::SensorDynamics, "delay_s")),
    ),
    (
        "amplifier_bandwidth_hz",
        Some((EffectName::AmplifierBandwidth, "natural_hz")),
    ),
    ("coil_resistance_ohm", None),
    ("coil_inductance_h", None),
    (
        "load_mass_kg",
        Some((EffectName::MechanicalLoad, "mass_ratio")),
    ),
];

/// Every datasheet value of a parameter file and what it bounds, with the library's parameter
/// ranges (what `maglab identify` and `maglab diagnose` report).
pub fn uses_of(params: &actuator_params::ActuatorParams) -> Vec<PriorUse> {
    let nominal = crate::model::Nominal::from_params(params);
    nominal
        .priors
        .uses(&|e| crate::candidates::library_parameters(e, &nominal))
}

/// The datasheet's priors and what they act on.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Priors {
    /// The datasheet section (all `None` without one).
    pub datasheet: Datasheet,
    /// The rod's effective moving mass `ρ A_m l_m / 3`, kg (module docs).
    pub rod_effective_mass_kg: f64,
}

/// One datasheet value and what the fits did with it.
#[derive(Debug, Clone, PartialEq)]
pub struct PriorUse {
    /// `datasheet.<field>`.
    pub field: String,
    /// The datasheet's value and tolerance.
    pub given: Toleranced,
    /// The candidate parameter it bounds and the band, or why it bounds none.
    pub acts_on: Result<(String, (f64, f64)), String>,
}

impl Priors {
    /// From a parameter file (no priors without its `datasheet` section).
    pub fn from_params(p: &actuator_params::ActuatorParams) -> Self {
        let a = &p.actuator;
        Priors {
            datasheet: p.datasheet.unwrap_or_default(),
            rod_effective_mass_kg: TERFENOL_DENSITY_KG_M3 * a.rod_area_m2 * a.rod_length_m / 3.0,
        }
    }

    /// Whether any value is given.
    pub fn any(&self) -> bool {
        self.datasheet.fields().iter().any(|(_, t)| t.is_some())
    }

    /// The datasheet value that bounds `effect`'s parameter `name`, if any.
    fn source(&self, effect: EffectName, name: &str) -> Option<Toleranced> {
        self.datasheet
            .fields()
            .iter()
            .zip(TARGETS)
            .find(|(_, (_, target))| *target == Some((effect, name)))
            .and_then(|((_, given), _)| *given)
    }

    /// The band the datasheet puts on parameter `k` of `specs` (an effect's parameters, the
    /// library's ranges), if it gives one.
    fn band(&self, effect: EffectName, specs: &[ParamSpec], k: usize) -> Option<(f64, f64)> {
        let given = self.source(effect, specs[k].name)?;
        let (lo, hi) = match specs[k].name {
            "natural_hz" => {
                let damping = specs.iter().find(|s| s.name == "damping_ratio")?;
                let (lo, hi) = given.band();
                (
                    lo / minus_3db_ratio(damping.lo),
                    hi / minus_3db_ratio(damping.hi),
                )
            }
            "delay_s" => given.band_from_zero(),
            "mass_ratio" => {
                let (lo, hi) = given.band();
                (
                    lo / self.rod_effective_mass_kg,
                    hi / self.rod_effective_mass_kg,
                )
            }
            _ => return None,
        };
        let min_width = MIN_RELATIVE_WIDTH * hi.abs().max(f64::MIN_POSITIVE);
        Some((lo, hi.max(lo + min_width)))
    }

    /// `effect`'s parameters (the library's ranges) with the datasheet's bands in place of the
    /// ranges it bounds. A fit at either end of such a band is pinned ([`Edge::Both`]): the data
    /// ask for a value the datasheet rules out.
    pub fn narrow(&self, effect: EffectName, specs: &mut [ParamSpec]) {
        let bands: Vec<Option<(f64, f64)>> = (0..specs.len())
            .map(|k| self.band(effect, specs, k))
            .collect();
        for (spec, band) in specs.iter_mut().zip(bands) {
            if let Some((lo, hi)) = band {
                spec.lo = lo;
                spec.hi = hi;
                // A log-scaled parameter needs a positive range; a delay's band may start at 0.
                spec.log = spec.log && lo > 0.0;
                spec.edge = Edge::Both;
            }
        }
    }

    /// The instruments whose datasheet bandwidth is given: `maglab identify` models them while
    /// it fits `R_eddy`, `ξ`, `f0`, so that their lags are not absorbed into the rod's constants.
    /// The amplifier only when the coil current is not measured (measured, it is the model's
    /// input and the amplifier is outside the chain).
    pub fn instruments(&self, coil_current_measured: bool) -> Vec<EffectName> {
        let d = &self.datasheet;
        let mut out = Vec::new();
        if d.amplifier_bandwidth_hz.is_some() && !coil_current_measured {
            out.push(EffectName::AmplifierBandwidth);
        }
        if d.sensor_bandwidth_hz.is_some() {
            out.push(EffectName::SensorDynamics);
        }
        out
    }

    /// Where a fit of `effect` with the datasheet's bands starts (physical units, `specs` its
    /// parameters as [`Priors::narrow`] left them): a natural frequency at the datasheet's
    /// bandwidth (ζ = 1/√2 maps one onto the other), a delay at the datasheet's value, a load at
    /// its mass ratio, a damping ratio at 1/√2; a parameter without a datasheet value at the
    /// middle of its range (geometric for a log-scaled one), a delay at 0, the amplifier's coil
    /// time constant at 0 (an ideal current source until the data ask for the coil's EMF).
    pub fn start(&self, effect: EffectName, specs: &[ParamSpec]) -> Vec<f64> {
        specs
            .iter()
            .map(|s| {
                let given = self.source(effect, s.name).map(|t| match s.name {
                    "mass_ratio" => t.value / self.rod_effective_mass_kg,
                    _ => t.value,
                });
                let v = match (given, s.name) {
                    (Some(v), _) => v,
                    (None, "damping_ratio") => std::f64::consts::FRAC_1_SQRT_2,
                    (None, "delay_s" | "coil_time_constant_s") => s.lo,
                    (None, _) if s.log => (s.lo * s.hi).sqrt(),
                    (None, _) => 0.5 * (s.lo + s.hi),
                };
                v.clamp(s.lo, s.hi)
            })
            .collect()
    }

    /// Every given value and what it bounds (the reports list them), with `specs_of` the
    /// library's parameters of an effect.
    pub fn uses(&self, specs_of: &dyn Fn(EffectName) -> Vec<ParamSpec>) -> Vec<PriorUse> {
        self.datasheet
            .fields()
            .iter()
            .zip(TARGETS)
            .filter_map(|((field, given), (_, target))| {
                let given = (*given)?;
                let acts_on = match target {
                    Some((effect, name)) => {
                        let specs = specs_of(effect);
                        let k = specs.iter().position(|s| s.name == name);
                        match k.and_then(|k| self.band(effect, &specs, k)) {
                            Some(band) => Ok((format!("{}.{name}", effect.name()), band)),
                            None => Err(format!("{}.{name} has no band", effect.name())),
                        }
                    }
                    None => Err(
                        "no candidate parameter is it: the amplifier's coil_time_constant_s is \
                         L/R without the rod's magnetization (L = mu0 N A c0, the model adds \
                         the rod's M itself), while a datasheet's inductance is measured with the \
                         rod inside"
                            .into(),
                    ),
                };
                Some(PriorUse {
                    field: format!("datasheet.{field}"),
                    given,
                    acts_on,
                })
            })
            .collect()
    }
}

/// `f_−3dB / f_n` of `ωn² / (s² + 2ζωn s + ωn²)`: `√(1 − 2ζ² + √((1 − 2ζ²)² + 1))`.
pub fn minus_3db_ratio(damping_ratio: f64) -> f64 {
    let a = 1.0 - 2.0 * damping_ratio * damping_ratio;
    (a + (a * a + 1.0).sqrt()).sqrt()
}

impl PriorUse {
    /// One line for a report.
    pub fn describe(&self) -> String {
        match &self.acts_on {
            Ok((param, (lo, hi))) => format!(
                "{} = {} +/- {}: {param} in [{lo:.4e}, {hi:.4e}]",
                self.field, self.given.value, self.given.plus_minus
            ),
            Err(why) => format!(
                "{} = {} +/- {}: not used ({why})",
                self.field, self.given.value, self.given.plus_minus
            ),
        }
    }

    /// As JSON for `provenance` and `diagnosis.json`.
    pub fn to_json(&self) -> serde_json::Value {
        match &self.acts_on {
            Ok((param, (lo, hi))) => serde_json::json!({
                "field": self.field,
                "value": self.given.value,
                "plus_minus": self.given.plus_minus,
                "bounds": param,
                "band": [lo, hi],
            }),
            Err(why) => serde_json::json!({
                "field": self.field,
                "value": self.given.value,
                "plus_minus": self.given.plus_minus,
                "not_used": why,
            }),
        }
    }
}
