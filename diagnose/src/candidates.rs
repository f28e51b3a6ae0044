//! The candidate effects of the diagnosis: for each effect of the library, its free parameters
//! (name, unit, search range, log or linear scale, a starting grid) and the model augmentation a
//! parameter vector stands for.
//!
//! Parameters are fitted in a normalized coordinate `z ∈ [0, 1]` per parameter (log scale for
//! positive scale quantities such as corners and time constants), so one simplex step size fits
//! all; the optimizer's excursions outside `[0, 1]` are clamped.

use crate::effects::EffectName;
use crate::model::{Augmentation, EddyLadder, Load, Nominal};

/// One free parameter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ParamSpec {
    /// Name in the JSON report.
    pub name: &'static str,
    /// Lower end of the search range.
    pub lo: f64,
    /// Upper end.
    pub hi: f64,
    /// Log scale (`lo > 0`).
    pub log: bool,
}

impl ParamSpec {
    /// Value at normalized coordinate `z` (clamped to `[0, 1]`).
    pub fn value(&self, z: f64) -> f64 {
        let z = z.clamp(0.0, 1.0);
        if self.log {
            (self.lo.ln() + z * (self.hi.ln() - self.lo.ln())).exp()
        } else {
            self.lo + z * (self.hi - self.lo)
        }
    }

    /// Normalized coordinate of `v`.
    pub fn coordinate(&self, v: f64) -> f64 {
        if self.log {
            (v.ln() - self.lo.ln()) / (self.hi.ln() - self.lo.ln())
        } else {
            (v - self.lo) / (self.hi - self.lo)
        }
    }
}

/// The free parameters of a candidate, given the nominal constants (ranges scale with them).
pub fn parameters(effect: EffectName, nominal: &Nominal) -> Vec<ParamSpec> {
    let r = nominal.eddy_resistance_ohm;
    let f0 = nominal.resonance_hz;
    match effect {
        EffectName::EddyFrequencyDependence => vec![
            ParamSpec {
                name: "dc_ohm",
                lo: r / 10.0,
                hi: r * 10.0,
                log: true,
            },
            ParamSpec {
                name: "hf_to_dc_ratio",
                lo: 1.0,
                hi: 30.0,
                log: true,
            },
            ParamSpec {
                name: "corner_hz",
                lo: 5.0,
                hi: 5000.0,
                log: true,
            },
        ],
        EffectName::AmplifierBandwidth => vec![ParamSpec {
            name: "corner_hz",
            lo: 10.0,
            hi: 50_000.0,
            log: true,
        }],
        EffectName::SensorDynamics => vec![
            ParamSpec {
                name: "corner_hz",
                lo: 10.0,
                hi: 50_000.0,
                log: true,
            },
            ParamSpec {
                name: "delay_s",
                lo: 0.0,
                hi: 2.0e-3,
                log: false,
            },
        ],
        EffectName::ReversibleMagnetization => vec![ParamSpec {
            name: "susceptibility",
            lo: 0.0,
            hi: 40.0,
            log: false,
        }],
        EffectName::ThermalDrift => vec![
            ParamSpec {
                name: "time_constant_s",
                lo: 1e-3,
                hi: 100.0,
                log: true,
            },
            ParamSpec {
                name: "scale_loss_per_a2",
                lo: -0.5,
                hi: 0.5,
                log: false,
            },
        ],
        EffectName::DeltaEEffect => vec![ParamSpec {
            name: "stiffness_change",
            lo: -0.9,
            hi: 10.0,
            log: false,
        }],
        EffectName::MechanicalLoad => vec![
            ParamSpec {
                name: "mass_ratio",
                lo: 0.01,
                hi: 10.0,
                log: true,
            },
            ParamSpec {
                name: "coupling_hz",
                lo: 0.3 * f0,
                hi: 20.0 * f0,
                log: true,
            },
            ParamSpec {
                name: "damping_ratio",
                lo: 0.01,
                hi: 3.0,
                log: true,
            },
        ],
        EffectName::Backlash => Vec::new(),
    }
}

/// The normalized starting points of the coarse search (each is refined by Nelder-Mead; the best
/// refined one wins). They cover the range of the most influential parameter.
pub fn starts(effect: EffectName, nominal: &Nominal) -> Vec<Vec<f64>> {
    let specs = parameters(effect, nominal);
    let line = |k: usize| -> Vec<f64> { (0..k).map(|i| (i as f64 + 0.5) / k as f64).collect() };
    match effect {
        EffectName::EddyFrequencyDependence => {
            let dc = specs[0].coordinate(nominal.eddy_resistance_ohm);
            let mut out = Vec::new();
            for corner in [0.35, 0.55, 0.75] {
                out.push(vec![dc, 0.4, corner]);
                out.push(vec![dc - 0.15, 0.4, corner]);
            }
            out
        }
        EffectName::AmplifierBandwidth => line(6).into_iter().map(|z| vec![z]).collect(),
        EffectName::SensorDynamics => {
            let mut out: Vec<Vec<f64>> = line(4).into_iter().map(|z| vec![z, 0.0]).collect();
            out.push(vec![1.0, 0.05]);
            out.push(vec![1.0, 0.2]);
            out
        }
        EffectName::ReversibleMagnetization => [0.5, 2.0, 6.0, 15.0]
            .iter()
            .map(|&c| vec![specs[0].coordinate(c)])
            .collect(),
        EffectName::ThermalDrift => {
            let mut out = Vec::new();
            for tau in [0.2, 0.45, 0.7] {
                for g in [0.45, 0.55] {
                    out.push(vec![tau, g]);
                }
            }
            out
        }
        EffectName::DeltaEEffect => [-0.5, 0.5, 2.0, 6.0]
            .iter()
            .map(|&c| vec![specs[0].coordinate(c)])
            .collect(),
        EffectName::MechanicalLoad => {
            let mut out = Vec::new();
            for ratio in [0.3, 0.6] {
                for coupling in [0.25, 0.5, 0.75] {
                    out.push(vec![ratio, coupling, 0.5]);
                }
            }
            out
        }
        EffectName::Backlash => Vec::new(),
    }
}

/// The augmentation a candidate's parameter values (physical units, in [`parameters`] order)
/// stand for.
pub fn augmentation(effect: EffectName, values: &[f64]) -> Augmentation {
    let mut a = Augmentation::default();
    match effect {
        EffectName::EddyFrequencyDependence => {
            a.eddy = Some(EddyLadder {
                dc_ohm: values[0],
                hf_ohm: values[0] * values[1],
                corner_hz: values[2],
            })
        }
        EffectName::AmplifierBandwidth => a.amplifier_corner_hz = Some(values[0]),
        EffectName::SensorDynamics => {
            a.sensor_corner_hz = Some(values[0]);
            a.sensor_delay_s = Some(values[1]);
        }
        EffectName::ReversibleMagnetization => a.susceptibility = Some(values[0]),
        EffectName::ThermalDrift => a.thermal = Some((values[0], values[1])),
        EffectName::DeltaEEffect => a.delta_e = Some(values[0]),
        EffectName::MechanicalLoad => {
            a.load = Some(Load {
                mass_ratio: values[0],
                coupling_hz: values[1],
                damping_ratio: values[2],
            })
        }
        EffectName::Backlash => {}
    }
    a
}
