//! The effects the bench plant can switch on, in physical forms chosen to differ from the
//! diagnosis' candidate equations (`maglab_diagnose::candidates`), so that a diagnosis tested on
//! this plant is tested on equations it does not share.
//!
//! | name | plant form | the diagnosis candidate it should be named as |
//! |---|---|---|
//! | `eddy_frequency_dependence` | the rod's radial eddy-current diffusion as a Foster ladder of `paths` (≥ 3) extra eddy paths with the time constants of a cylinder (Bessel zeros `j_k`: corners `f_1 (j_k/j_1)²`, conductance shares `∝ 1/j_k²`) | one extra path |
//! | `amplifier_bandwidth` | second-order current loop with a slew-rate limit | low-pass on the current |
//! | `sensor_dynamics` | second-order sensor low-pass plus a conversion delay, in continuous time | low-pass and delay on the sampled output |
//! | `reversible_magnetization` | saturating anhysteretic term `χ₀ H_r tanh(H / H_r)` | constant susceptibility |
//! | `thermal_drift` | two-node thermal network (coil, rod), copper resistance rising with temperature, λ_s falling and the rod expanding with the rod temperature | one time constant |
//! | `delta_e_effect` | stiffness `(1 + d)/(1 + d (1 − m²)²) + s ε` (magnetization and dynamic stress `ε`) | stiffness polynomial in `m²` |
//! | `mechanical_load` | two load masses in a chain (two modes) | one load mode; in the second stage also a second mass on it — the chain's form, met only in its parameterization (each mass relative to the one before), integrator and the rest of the plant |
//!
//! Not in the diagnosis library (a diagnosis must call them `unexplained`): `backlash` (play in
//! the linkage to the sensor), `stick_slip` (static and kinetic friction at the rod end),
//! `creep` (slow viscoelastic creep of the rod strain, three time constants a decade apart),
//! `sensor_nonlinearity` (the sensor's gain changes along its range, odd about its null as an
//! LVDT's S-curve).
//!
//! Each effect has one *magnitude* parameter ([`EffectSpec::magnitude`]) that sets its size
//! (used to calibrate a test case to a given gap) and shape parameters. The bounds of every
//! parameter are a plausible physical range for a bench actuator of this size (a current loop
//! above 150 Hz, a load up to 1.5 times the rod's moving mass, play up to 10 µm, …), so a
//! calibration never reaches a target gap with an absurd plant.

use std::fmt;

/// The static description of an effect.
#[derive(Debug, PartialEq)]
pub struct EffectSpec {
    /// Interface name (`name:key=value,...`).
    pub name: &'static str,
    /// In the diagnosis' candidate library (a correct diagnosis names it).
    pub in_library: bool,
    /// `(key, default, lower bound, upper bound, meaning)`.
    pub keys: &'static [(&'static str, f64, f64, f64, &'static str)],
    /// The key that sets the effect's size, and whether a larger value makes a larger effect.
    pub magnitude: (&'static str, bool),
}

/// Every effect of the plant.
pub static EFFECTS: &[EffectSpec] = &[
    EffectSpec {
        name: "eddy_frequency_dependence",
        in_library: true,
        keys: &[
            ("share", 0.35, 0.0, 0.8, "fraction of the DC eddy conductance carried by the distributed paths"),
            ("first_corner_hz", 200.0, 1.0, 1e5, "corner of the slowest distributed path, Hz"),
            ("paths", 4.0, 3.0, 8.0, "number of distributed paths (>= 3)"),
        ],
        magnitude: ("share", true),
    },
    EffectSpec {
        name: "amplifier_bandwidth",
        in_library: true,
        keys: &[
            ("natural_hz", 700.0, 150.0, 1e6, "natural frequency of the current loop, Hz"),
            ("damping_ratio", 0.7, 0.2, 3.0, "damping ratio of the current loop"),
            ("slew_a_per_s", 5000.0, 1.0, 1e9, "slew-rate limit of the coil current, A/s"),
        ],
        magnitude: ("natural_hz", false),
    },
    EffectSpec {
        name: "sensor_dynamics",
        in_library: true,
        keys: &[
            ("natural_hz", 1500.0, 200.0, 1e6, "natural frequency of the sensor's low-pass, Hz"),
            ("damping_ratio", 0.7, 0.2, 3.0, "damping ratio of the sensor's low-pass"),
            ("delay_s", 5e-5, 0.0, 0.01, "conversion delay, s"),
        ],
        magnitude: ("natural_hz", false),
    },
    EffectSpec {
        name: "reversible_magnetization",
        in_library: true,
        keys: &[
            ("susceptibility", 2.0, 0.0, 6.0, "initial reversible susceptibility chi_0"),
            ("saturation_field_a_per_m", 15e3, 100.0, 1e7, "field H_r of tanh(H / H_r), A/m"),
        ],
        magnitude: ("susceptibility", true),
    },
    EffectSpec {
        name: "thermal_drift",
        in_library: true,
        keys: &[
            ("coil_rise_k_per_a2", 30.0, 0.0, 200.0, "steady coil temperature rise per A^2 (cold coil), K/A^2"),
            ("coil_time_constant_s", 0.4, 1e-3, 1e4, "coil thermal time constant, s"),
            ("rod_time_constant_s", 2.0, 1e-3, 1e4, "rod time constant behind the coil, s"),
            ("copper_tempco_per_k", 0.0039, 0.0, 0.01, "coil resistance rise per K (heating ~ I^2 R(T))"),
            ("magnetostriction_loss_per_k", 3e-3, 0.0, 0.02, "relative loss of lambda_s per K of the rod"),
            ("expansion_m_per_k", 6e-7, -1e-5, 1e-5, "thermal expansion of the rod, m per K"),
        ],
        magnitude: ("coil_rise_k_per_a2", true),
    },
    EffectSpec {
        name: "delta_e_effect",
        in_library: true,
        keys: &[
            ("magnetization_stiffening", 1.0, -0.9, 2.0, "stiffness change at saturation d: (1 + d) / (1 + d (1 - m^2)^2)"),
            ("stress_stiffening", 0.3, -0.9, 5.0, "stiffness change per unit dynamic strain (relative to the stroke)"),
        ],
        magnitude: ("magnetization_stiffening", true),
    },
    EffectSpec {
        name: "mechanical_load",
        in_library: true,
        keys: &[
            ("mass_ratio", 0.5, 0.0, 1.5, "first load mass / rod effective mass"),
            ("coupling_hz", 900.0, 450.0, 1e6, "first coupling frequency sqrt(k2/m2)/2pi, Hz"),
            ("damping_ratio", 0.12, 0.001, 5.0, "damping ratio of the first coupling"),
            ("second_mass_ratio", 0.6, 0.0, 1.0, "second load mass / first load mass"),
            ("second_coupling_hz", 1800.0, 1.0, 1e6, "second coupling frequency, Hz"),
            ("second_damping_ratio", 0.08, 0.001, 5.0, "damping ratio of the second coupling"),
        ],
        // The sensor sits on the load: how close its coupling resonance comes to the band sets
        // the size of the effect (a light load with a low resonance moves a lot).
        magnitude: ("coupling_hz", false),
    },
    EffectSpec {
        name: "backlash",
        in_library: false,
        keys: &[("width_m", 2e-6, 0.0, 1e-5, "play in the linkage to the sensor, m")],
        magnitude: ("width_m", true),
    },
    EffectSpec {
        name: "stick_slip",
        in_library: false,
        keys: &[
            ("breakaway_m", 0.8e-6, 0.0, 5e-6, "static friction force / rod stiffness, m"),
            ("kinetic_ratio", 0.7, 0.0, 1.0, "kinetic / static friction"),
        ],
        magnitude: ("breakaway_m", true),
    },
    EffectSpec {
        name: "creep",
        in_library: false,
        keys: &[
            ("ratio", 0.05, 0.0, 1.0, "creep strain / elastic strain after a long time"),
            ("time_constant_s", 0.02, 1e-4, 100.0, "fastest of three creep time constants (x1, x10, x100), s"),
        ],
        magnitude: ("ratio", true),
    },
    EffectSpec {
        name: "sensor_nonlinearity",
        in_library: false,
        keys: &[
            (
                "gain_change",
                0.1,
                -0.5,
                0.5,
                "relative gain change at the ends of the linear range: y_meas = y + g/3 r ((y - null)/r)^3",
            ),
            ("null_m", 25e-6, -1e-3, 1e-3, "displacement at the sensor's null, m"),
            ("range_m", 20e-6, 1e-7, 1e-3, "half-width r of the sensor's linear range, m"),
        ],
        magnitude: ("gain_change", true),
    },
];

/// One effect switched on, with all its parameters.
#[derive(Debug, Clone, PartialEq)]
pub struct Effect {
    /// The effect's spec.
    pub spec: &'static EffectSpec,
    /// Values in the order of `spec.keys`.
    pub values: Vec<f64>,
}

impl Effect {
    /// The spec of `name`.
    pub fn spec(name: &str) -> Result<&'static EffectSpec, String> {
        EFFECTS.iter().find(|s| s.name == name).ok_or_else(|| {
            format!(
                "unknown effect `{name}`: expected one of {}",
                EFFECTS
                    .iter()
                    .map(|s| s.name)
                    .collect::<Vec<_>>()
                    .join(", ")
            )
        })
    }

    /// `name` with its default parameters.
    pub fn default_for(name: &str) -> Result<Self, String> {
        let spec = Self::spec(name)?;
        Ok(Effect {
            spec,
            values: spec.keys.iter().map(|k| k.1).collect(),
        })
    }

    /// The interface name.
    pub fn name(&self) -> &'static str {
        self.spec.name
    }

    /// The value of `key`.
    pub fn get(&self, key: &str) -> f64 {
        self.spec
            .keys
            .iter()
            .position(|k| k.0 == key)
            .map(|i| self.values[i])
            .unwrap_or_else(|| panic!("{} has no parameter {key}", self.spec.name))
    }

    /// Sets `key` (checked against its bounds).
    pub fn with(mut self, key: &str, value: f64) -> Result<Self, String> {
        let Some(i) = self.spec.keys.iter().position(|k| k.0 == key) else {
            return Err(format!(
                "effect `{}`: unknown parameter `{key}`: expected one of {}",
                self.spec.name,
                self.spec
                    .keys
                    .iter()
                    .map(|k| k.0)
                    .collect::<Vec<_>>()
                    .join(", ")
            ));
        };
        let (_, _, lo, hi, _) = self.spec.keys[i];
        if !(value.is_finite() && value >= lo && value <= hi) {
            return Err(format!(
                "effect `{}`: parameter `{key}` = {value}: must be in [{lo}, {hi}]",
                self.spec.name
            ));
        }
        self.values[i] = value;
        Ok(self)
    }

    /// Parses `name` or `name:key=value,key=value` (missing keys take their defaults).
    pub fn parse(text: &str) -> Result<Self, String> {
        let (name, rest) = match text.split_once(':') {
            Some((n, r)) => (n.trim(), Some(r)),
            None => (text.trim(), None),
        };
        let mut effect = Self::default_for(name)?;
        for item in rest.into_iter().flat_map(|r| r.split(',')) {
            if item.trim().is_empty() {
                continue;
            }
            let (key, value) = item
                .split_once('=')
                .ok_or_else(|| format!("effect `{name}`: `{item}` is not `key=value`"))?;
            let value: f64 = value.trim().parse().map_err(|_| {
                format!(
                    "effect `{name}`: parameter `{}`: `{}` is not a number",
                    key.trim(),
                    value.trim()
                )
            })?;
            effect = effect.with(key.trim(), value)?;
        }
        Ok(effect)
    }

    /// The magnitude parameter's value.
    pub fn magnitude(&self) -> f64 {
        self.get(self.spec.magnitude.0)
    }
}

impl fmt::Display for Effect {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let parts: Vec<String> = self
            .spec
            .keys
            .iter()
            .zip(&self.values)
            .map(|(k, v)| format!("{}={v}", k.0))
            .collect();
        write!(f, "{}({})", self.spec.name, parts.join(", "))
    }
}

/// Checks that no effect appears twice.
pub fn check_unique(effects: &[Effect]) -> Result<(), String> {
    for (k, e) in effects.iter().enumerate() {
        if effects[..k].iter().any(|o| o.name() == e.name()) {
            return Err(format!("effect `{}` is given twice", e.name()));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parse_fills_defaults_and_names_errors() {
        let e = Effect::parse("amplifier_bandwidth:natural_hz=250").unwrap();
        assert_eq!(e.get("natural_hz"), 250.0);
        assert_eq!(e.get("damping_ratio"), 0.7);
        let err = Effect::parse("amplifier_bandwidth:corner=3").unwrap_err();
        assert!(err.contains("unknown parameter `corner`"), "{err}");
        let err = Effect::parse("amplifier_bandwidth:natural_hz=-3").unwrap_err();
        assert!(err.contains("`natural_hz` = -3: must be in"), "{err}");
        let err = Effect::parse("skin").unwrap_err();
        assert!(err.contains("unknown effect `skin`"), "{err}");
        let err = Effect::parse("backlash:width_m=abc").unwrap_err();
        assert!(err.contains("`abc` is not a number"), "{err}");
        let twice = [
            Effect::default_for("backlash").unwrap(),
            Effect::default_for("backlash").unwrap(),
        ];
        assert!(check_unique(&twice).unwrap_err().contains("twice"));
    }

    #[test]
    fn defaults_lie_in_their_bounds() {
        for spec in EFFECTS {
            for &(key, v, lo, hi, _) in spec.keys {
                assert!(v >= lo && v <= hi, "{}.{key}", spec.name);
            }
            assert!(spec.keys.iter().any(|k| k.0 == spec.magnitude.0));
        }
    }
}
