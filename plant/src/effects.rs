//! The effects the bench plant can switch on, each in three or more physical forms (key `form`,
//! [`EffectSpec::forms`]) chosen to differ from the diagnosis' candidate equations
//! (`maglab_diagnose::candidates`) and from each other, so that a diagnosis tested on this plant
//! is tested on equations it does not share, and its rules can be chosen on some forms and
//! scored on the others (`crate::suite`'s form sets).
//!
//! | name | forms | the diagnosis candidate it should be named as |
//! |---|---|---|
//! | `eddy_frequency_dependence` | a Foster ladder of `paths` (≥ 3) extra eddy paths with the time constants of a cylinder (Bessel zeros), of a laminated slab (odd squares) or of a log-spaced spread of skin depths | one extra path |
//! | `amplifier_bandwidth` | second-order current loop with a slew-rate limit; first order with a slew limit; a PI current loop driving the coil's L/R against the rod's back-EMF under a voltage limit; the same loop with its zero off the coil's L/R and the current read through a sense filter | a current loop tuned on the coil, with a filter pole (its low-pass form at `τ_L = 0`) |
//! | `sensor_dynamics` | an LVDT's second-order demodulator, a capacitive probe's first-order filter, a laser's moving average; each with a conversion delay, in continuous time | low-pass and delay on the sampled output |
//! | `reversible_magnetization` | `χ₀ H_r tanh(H / H_r)`, Langevin, Fröhlich–Kennelly | constant susceptibility |
//! | `thermal_drift` | two-node network (coil, rod); coil and a rod of three shells; two nodes with the current capped by the amplifier's compliance voltage over the heated coil's resistance. Copper resistance rises with temperature, λ_s falls and the rod expands with the rod temperature | one time constant |
//! | `delta_e_effect` | stiffness `(1 + d)/(1 + d (1 − m²)²)`, `1 + d |m|³` or `1 + d tanh²(H/H_s)`, each `+ s ε` (dynamic strain `ε`) | stiffness polynomial in `m²` |
//! | `mechanical_load` | one, two or three load masses in a chain | one load mode; in the second stage also a second mass on it |
//!
//! Not in the diagnosis library (a diagnosis must call them `unexplained`): `backlash` (play in
//! the linkage to the sensor: ideal, with a lagging follower, smooth), `stick_slip` (friction at
//! the rod end: Coulomb with stiction, Stribeck, Dahl), `creep` (viscoelastic creep of the rod
//! strain: three time constants a decade apart, one, or a logarithmic law over five decades),
//! `sensor_nonlinearity` (the sensor's gain changes along its range: an odd S-curve, an even
//! bow, a cyclic error).
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
    /// The physical forms of the effect, `(name, equation)`, selected by the key `form` (its
    /// index here; 0 is the default). Every form reads the same keys in the same sense, so a
    /// calibration of the magnitude works for each.
    pub forms: &'static [(&'static str, &'static str)],
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
            ("form", 0.0, 0.0, 2.0, "0 cylinder, 1 laminated slab, 2 skin-effect spread"),
        ],
        magnitude: ("share", true),
        forms: &[
            ("cylinder", "Foster ladder with a cylinder's radial modes: corners f1 (j_k/j_1)^2, shares 1/j_k^2 (j_k the zeros of J0)"),
            ("laminated", "a laminated rod's slab modes: corners f1 (2k-1)^2, shares 1/(2k-1)^2"),
            ("skin", "a spread of skin depths: corners f1 4^k (log-spaced), equal shares"),
        ],
    },
    EffectSpec {
        name: "amplifier_bandwidth",
        in_library: true,
        keys: &[
            ("natural_hz", 700.0, 150.0, 1e6, "natural frequency of the current loop, Hz"),
            ("damping_ratio", 0.7, 0.2, 3.0, "damping ratio of the current loop"),
            ("slew_a_per_s", 5000.0, 1.0, 1e9, "slew-rate limit of the coil current, A/s"),
            ("coil_time_constant_s", 5e-4, 1e-5, 0.1, "coil L/R, s (forms 2 and 3)"),
            ("voltage_limit_a", 100.0, 1.0, 1e4, "amplifier voltage limit / coil resistance, A (forms 2 and 3; the rod's eddy currents reflect into the coil as tau_L c1/c0 times its resistance)"),
            ("zero_to_coil_ratio", 1.0, 0.25, 4.0, "the PI zero's time constant over the coil's L/R (form 3: tuned on an L/R the coil on the rod does not have)"),
            ("sense_to_crossover", 10.0, 2.0, 100.0, "corner of the current-sense filter over the crossover (form 3)"),
            ("form", 0.0, 0.0, 3.0, "0 second order with slew limit, 1 first order, 2 PI current loop against the coil, 3 mistuned PI loop reading the current through a sense filter"),
        ],
        magnitude: ("natural_hz", false),
        forms: &[
            ("second_order", "second-order current loop (natural_hz, damping_ratio) with a slew-rate limit"),
            ("first_order", "first-order current loop, corner natural_hz, with a slew-rate limit"),
            ("pi_loop", "PI current loop (crossover natural_hz, zero on the coil's L/R) driving the coil against the rod's back-EMF, voltage limit with anti-windup"),
            ("sensed_pi_loop", "PI current loop (crossover natural_hz) with its zero at zero_to_coil_ratio times the coil's L/R, fed back through a first-order current-sense filter at sense_to_crossover times the crossover, driving the coil against the rod's back-EMF, voltage limit with anti-windup"),
        ],
    },
    EffectSpec {
        name: "sensor_dynamics",
        in_library: true,
        keys: &[
            ("natural_hz", 1500.0, 200.0, 1e6, "natural frequency of the sensor's low-pass, Hz"),
            ("damping_ratio", 0.7, 0.2, 3.0, "damping ratio of the sensor's low-pass"),
            ("delay_s", 5e-5, 0.0, 0.01, "conversion delay, s"),
            ("form", 0.0, 0.0, 2.0, "0 LVDT demodulator (second order), 1 capacitive probe (first order), 2 laser (moving average)"),
        ],
        magnitude: ("natural_hz", false),
        forms: &[
            ("lvdt", "second-order demodulator low-pass (natural_hz, damping_ratio) plus the conversion delay"),
            ("capacitive", "first-order low-pass, corner natural_hz, plus the conversion delay"),
            ("laser", "moving average over 0.443 / natural_hz (its -3 dB at natural_hz) plus the conversion delay"),
        ],
    },
    EffectSpec {
        name: "reversible_magnetization",
        in_library: true,
        keys: &[
            ("susceptibility", 2.0, 0.0, 6.0, "initial reversible susceptibility chi_0"),
            ("saturation_field_a_per_m", 15e3, 100.0, 1e7, "field H_r of tanh(H / H_r), A/m"),
            ("form", 0.0, 0.0, 2.0, "0 tanh, 1 Langevin, 2 Frohlich-Kennelly"),
        ],
        magnitude: ("susceptibility", true),
        forms: &[
            ("tanh", "chi_0 H_r tanh(H / H_r)"),
            ("langevin", "3 chi_0 H_r L(H / H_r), L(x) = coth x - 1/x"),
            ("frohlich_kennelly", "chi_0 H / (1 + |H| / H_r)"),
        ],
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
            ("compliance_a", 1.0, 0.1, 100.0, "compliance voltage / cold coil resistance, A (form 2)"),
            ("form", 0.0, 0.0, 2.0, "0 lumped coil and rod, 1 distributed rod, 2 resistance rising under a voltage limit"),
        ],
        magnitude: ("coil_rise_k_per_a2", true),
        forms: &[
            ("lumped", "two nodes: coil (rise I^2 R(T)) and rod behind it"),
            ("distributed", "coil node and the rod as three shells in series (rod_time_constant_s shared among them); the strain sees the rod's mean temperature"),
            ("voltage_limited", "two nodes, and the amplifier's compliance voltage caps the current at compliance_a / R(T): the delivered current falls as the coil heats"),
        ],
    },
    EffectSpec {
        name: "delta_e_effect",
        in_library: true,
        keys: &[
            ("magnetization_stiffening", 1.0, -0.9, 2.0, "stiffness change at saturation d: (1 + d) / (1 + d (1 - m^2)^2)"),
            ("stress_stiffening", 0.3, -0.9, 5.0, "stiffness change per unit dynamic strain (relative to the stroke)"),
            ("field_scale_a_per_m", 10e3, 100.0, 1e6, "field H_s of the field form, A/m (form 2)"),
            ("form", 0.0, 0.0, 2.0, "0 (1 + d)/(1 + d (1 - m^2)^2), 1 1 + d |m|^3, 2 1 + d tanh^2(H / H_s)"),
        ],
        magnitude: ("magnetization_stiffening", true),
        forms: &[
            ("quartic", "stiffness (1 + d) / (1 + d (1 - m^2)^2) + s eps"),
            ("cubic", "stiffness 1 + d |m|^3 + s eps"),
            ("field", "stiffness 1 + d tanh^2(H / H_s) + s eps, H_s = field_scale_a_per_m"),
        ],
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
            ("form", 0.0, 0.0, 2.0, "0 two masses in a chain, 1 one mass, 2 three masses in a chain"),
        ],
        // The sensor sits on the load: how close its coupling resonance comes to the band sets
        // the size of the effect (a light load with a low resonance moves a lot).
        magnitude: ("coupling_hz", false),
        forms: &[
            ("two_modes", "two load masses in a chain, the sensor on the first"),
            ("one_mode", "one load mass on the rod, the sensor on it"),
            ("three_modes", "three load masses in a chain (the third as the second relative to its predecessor, coupling x1.7), the sensor on the first"),
        ],
    },
    EffectSpec {
        name: "backlash",
        in_library: false,
        keys: &[
            ("width_m", 2e-6, 0.0, 1e-5, "play in the linkage to the sensor, m"),
            ("follower_hz", 2000.0, 1.0, 1e6, "corner of the follower lag, Hz (form 1)"),
            ("form", 0.0, 0.0, 2.0, "0 play, 1 play with a lagging follower, 2 smooth play"),
        ],
        magnitude: ("width_m", true),
        forms: &[
            ("play", "play operator of width width_m"),
            ("lagging", "play whose follower reaches its position with a first-order lag at follower_hz"),
            ("smooth", "the follower starts to move before the play's edge: dz = dy q^4, q the distance from the far edge over the half width"),
        ],
    },
    EffectSpec {
        name: "stick_slip",
        in_library: false,
        keys: &[
            ("breakaway_m", 0.8e-6, 0.0, 5e-6, "static friction force / rod stiffness, m"),
            ("kinetic_ratio", 0.7, 0.0, 1.0, "kinetic / static friction"),
            ("stribeck_speed_m_per_s", 2e-3, 1e-6, 1.0, "Stribeck speed, m/s (form 1)"),
            ("presliding_m", 0.2e-6, 1e-9, 1e-5, "pre-sliding displacement F_s / sigma, m (form 2)"),
            ("form", 0.0, 0.0, 2.0, "0 Coulomb with stiction, 1 Stribeck, 2 Dahl"),
        ],
        magnitude: ("breakaway_m", true),
        forms: &[
            ("coulomb", "static friction, then kinetic_ratio of it while sliding"),
            ("stribeck", "friction falling from static to kinetic with speed: exp(-(v / stribeck_speed_m_per_s)^2)"),
            ("dahl", "Dahl's pre-sliding friction, no stiction: dF/dy = sigma (1 - F/F_c sgn y'), F_c the kinetic level, sigma = F_s / presliding_m"),
        ],
    },
    EffectSpec {
        name: "creep",
        in_library: false,
        keys: &[
            ("ratio", 0.05, 0.0, 1.0, "creep strain / elastic strain after a long time"),
            ("time_constant_s", 0.02, 1e-4, 100.0, "fastest of three creep time constants (x1, x10, x100), s"),
            ("form", 0.0, 0.0, 2.0, "0 three Prony terms, 1 one time constant, 2 logarithmic (five decades)"),
        ],
        magnitude: ("ratio", true),
        forms: &[
            ("prony3", "three relaxation terms, time constants x1, x10, x100, equal shares"),
            ("single", "one relaxation term at 10 x time_constant_s"),
            ("logarithmic", "five relaxation terms a decade apart with equal shares: creep ~ log t over that span"),
        ],
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
            ("form", 0.0, 0.0, 2.0, "0 odd S-curve, 1 even bow, 2 cyclic error"),
        ],
        magnitude: ("gain_change", true),
        forms: &[
            ("odd_cubic", "y + g/3 r ((y - null)/r)^3 (an LVDT's S-curve)"),
            ("even_bow", "y + g/2 r ((y - null)/r)^2 (a capacitive gap's bow)"),
            ("cyclic", "y + g r/(2 pi) sin(2 pi (y - null)/r) (an interferometer's or encoder's cyclic error)"),
        ],
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
        if key == "form" && value.fract() != 0.0 {
            return Err(format!(
                "effect `{}`: parameter `form` = {value}: must be a whole number (the index of \
                 one of: {})",
                self.spec.name,
                self.spec
                    .forms
                    .iter()
                    .map(|f| f.0)
                    .collect::<Vec<_>>()
                    .join(", ")
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

    /// The index of the effect's physical form ([`EffectSpec::forms`]).
    pub fn form(&self) -> usize {
        self.get("form") as usize
    }

    /// The name of the effect's physical form.
    pub fn form_name(&self) -> &'static str {
        self.spec.forms[self.form()].0
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
        let err = Effect::parse("creep:form=1.5").unwrap_err();
        assert!(
            err.contains("whole number") && err.contains("logarithmic"),
            "{err}"
        );
        assert_eq!(
            Effect::parse("creep:form=2").unwrap().form_name(),
            "logarithmic"
        );
    }

    #[test]
    fn defaults_lie_in_their_bounds() {
        for spec in EFFECTS {
            for &(key, v, lo, hi, _) in spec.keys {
                assert!(v >= lo && v <= hi, "{}.{key}", spec.name);
            }
            assert!(spec.keys.iter().any(|k| k.0 == spec.magnitude.0));
            let form = spec
                .keys
                .iter()
                .find(|k| k.0 == "form")
                .expect("a form key");
            assert_eq!(form.3 as usize + 1, spec.forms.len(), "{}", spec.name);
            assert!(spec.forms.len() >= 3, "{}: at least three forms", spec.name);
        }
    }
}
