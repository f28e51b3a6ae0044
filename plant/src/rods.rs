//! Rods: the bench plant's Preisach measure drawn from a family of densities, on a plane wider
//! than the coil reaches, on the plant's own grid (never the model's).
//!
//! A real Terfenol-D rod needs well over 100 kA/m to saturate while a bench coil reaches a few
//! tens: the plane is `[-W, W]` with `W = plane_factor · c0 · I_max`. The density is given in the
//! coercive and interaction coordinates `h_c = (α − β)/2 >= 0`, `h_u = (α + β)/2`:
//!
//! | family | `ρ(h_c, h_u)` (unnormalized), `L(h_u) = 1 / (1 + (h_u/s_u)²)` |
//! |---|---|
//! | [`Family::Gaussian`] | `exp(−(h_c − c)²/2s_c²) · exp(−h_u²/2σ_u²)`, `σ_u = W / 3.5` (the classic factorized form; the rod saturates near `±W`) |
//! | [`Family::LogNormal`] | `(1/h_c) exp(−(ln h_c − ln c)²/2σ²) · L(h_u)`, `σ = s_c / c` (log-normal coercivity, Lorentzian interaction) |
//! | [`Family::Bimodal`] | two coercive populations, `c` and `3c`, weights 1 and ½, `· L(h_u)` |
//! | [`Family::Skewed`] | a skew-normal `h_c` (shape 4: a tail toward hard hysterons) whose interaction spread grows with it, `L(h_u / (0.6 + 0.4 h_c/c))`: not factorized |
//!
//! The Lorentzian's scale is `s_u = W / 8`: most of the mass lies near the middle and its heavy
//! tails reach out to the plane's edge, as on a rod whose saturation field is several times
//! what the coil drives. `c`, `s_c` are the coercivity, in kA/m like a soft prestressed rod. Every
//! density is even in `h_u`: the measure is symmetric under `(β, α) → (−α, −β)` (an unbiased
//! rod: demagnetized, it has `M = 0`, and its major loop is odd). The total mass is `M_s`.
//!
//! **The plant's grid.** Edges every [`FINE_CELL_OF_REACH`] of the reach inside
//! `±1.05 c0 I_max` (the field the coil drives: the loops need the resolution there) and
//! [`OUTER_INTERVALS`] intervals growing geometrically from there to `±W`; a cell's mass is its
//! density integrated by a [`QUADRATURE`]² midpoint rule (sub-squares cut by the diagonal
//! counted half). Other widths than the model's 25 equal intervals, by construction.

use crate::preisach::PreisachGrid;
use actuator_params::ActuatorParams;

/// Fine interval width inside the reach, fraction of `c0 I_max`.
pub const FINE_CELL_OF_REACH: f64 = 1.0 / 40.0;
/// Intervals from the end of the fine part to the plane's edge, on each side.
pub const OUTER_INTERVALS: usize = 6;
/// Midpoints per cell side of the mass integral.
pub const QUADRATURE: usize = 8;
/// The Lorentzian interaction scale is the plane's half width over this.
pub const INTERACTION_SCALE_DIVISOR: f64 = 8.0;
/// The Gaussian interaction spread is the plane's half width over this (0.2 % of the peak
/// density left at the edge).
pub const INTERACTION_SPREAD_DIVISOR: f64 = 3.5;

/// A family of Preisach densities (module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Family {
    /// Factorized Gaussian.
    Gaussian,
    /// Log-normal coercivity, Gaussian interaction.
    LogNormal,
    /// Two coercive populations.
    Bimodal,
    /// Interaction skewed and correlated with coercivity.
    Skewed,
}

impl Family {
    /// Every family with its interface name.
    pub const NAMES: [(&'static str, Family); 4] = [
        ("gaussian", Family::Gaussian),
        ("lognormal", Family::LogNormal),
        ("bimodal", Family::Bimodal),
        ("skewed", Family::Skewed),
    ];

    /// The interface name.
    pub fn name(self) -> &'static str {
        Self::NAMES
            .iter()
            .find(|(_, f)| *f == self)
            .map_or("?", |(n, _)| n)
    }
}

/// A rod: a family, how much wider its plane is than the coil reaches, and its coercivity.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rod {
    /// The density's family.
    pub family: Family,
    /// `W / (c0 I_max)`, at least 1.
    pub plane_factor: f64,
    /// Typical coercive field `c`, A/m.
    pub coercivity_a_per_m: f64,
    /// Its spread (`s_c`, or `σ·c` for the log-normal), A/m.
    pub coercivity_spread_a_per_m: f64,
}

impl Rod {
    /// A rod of `family`, `plane_factor` times wider than the coil reaches, with the default
    /// coercivity of a soft rod (2.5 kA/m, spread 1.5 kA/m).
    pub fn new(family: Family, plane_factor: f64) -> Self {
        Rod {
            family,
            plane_factor,
            coercivity_a_per_m: 2.5e3,
            coercivity_spread_a_per_m: 1.5e3,
        }
    }

    /// Parses `FAMILY:FACTOR[:COERCIVITY_KA_PER_M[:SPREAD_KA_PER_M]]`, e.g. `lognormal:4` or
    /// `gaussian:2:4:2`.
    pub fn parse(text: &str) -> Result<Self, String> {
        let parts: Vec<&str> = text.split(':').collect();
        let family = Family::NAMES
            .iter()
            .find(|(n, _)| *n == parts[0])
            .map(|(_, f)| *f)
            .ok_or_else(|| {
                format!(
                    "rod `{text}`: unknown family `{}`; expected one of {}",
                    parts[0],
                    Family::NAMES.map(|(n, _)| n).join(", ")
                )
            })?;
        let number = |k: usize, what: &str| -> Result<Option<f64>, String> {
            parts
                .get(k)
                .map(|s| {
                    s.parse::<f64>()
                        .map_err(|_| format!("rod `{text}`: {what} `{s}` is not a number"))
                })
                .transpose()
        };
        let factor = number(1, "plane factor")?
            .ok_or_else(|| format!("rod `{text}`: expected FAMILY:FACTOR, e.g. gaussian:4"))?;
        let mut rod = Rod::new(family, factor);
        if let Some(c) = number(2, "coercivity (kA/m)")? {
            rod.coercivity_a_per_m = 1e3 * c;
        }
        if let Some(s) = number(3, "coercivity spread (kA/m)")? {
            rod.coercivity_spread_a_per_m = 1e3 * s;
        }
        if parts.len() > 4 {
            return Err(format!(
                "rod `{text}`: at most FAMILY:FACTOR:COERCIVITY:SPREAD"
            ));
        }
        rod.check()?;
        Ok(rod)
    }

    /// The rod's parameters make sense.
    pub fn check(&self) -> Result<(), String> {
        if !(self.plane_factor.is_finite() && (1.0..=20.0).contains(&self.plane_factor)) {
            return Err(format!(
                "plane factor must be 1 ..= 20 (the plane's half width over c0 I_max), got {}",
                self.plane_factor
            ));
        }
        for (what, v) in [
            ("coercivity", self.coercivity_a_per_m),
            ("coercivity spread", self.coercivity_spread_a_per_m),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(format!("{what} must be > 0 A/m, got {v}"));
            }
        }
        Ok(())
    }

    /// `family:factor`, for tables.
    pub fn label(&self) -> String {
        format!("{}:{}", self.family.name(), self.plane_factor)
    }

    /// The plane's half width `W` for the coil and limit of `params`, A/m.
    pub fn half_width_a_per_m(&self, params: &ActuatorParams) -> f64 {
        self.plane_factor * reach_a_per_m(params)
    }

    /// The unnormalized density at `(β, α)`, `α >= β`, on a plane of half width `w`.
    pub fn density(&self, beta: f64, alpha: f64, w: f64) -> f64 {
        let hc = 0.5 * (alpha - beta);
        let hu = 0.5 * (alpha + beta);
        let su = w / INTERACTION_SCALE_DIVISOR;
        let (c, sc) = (self.coercivity_a_per_m, self.coercivity_spread_a_per_m);
        let gauss = |x: f64, s: f64| (-0.5 * (x / s) * (x / s)).exp();
        let lorentz = |x: f64, s: f64| 1.0 / (1.0 + (x / s) * (x / s));
        match self.family {
            Family::Gaussian => gauss(hc - c, sc) * gauss(hu, w / INTERACTION_SPREAD_DIVISOR),
            Family::LogNormal => {
                if hc <= 0.0 {
                    return 0.0;
                }
                gauss((hc / c).ln(), sc / c) / hc * lorentz(hu, su)
            }
            Family::Bimodal => {
                (gauss(hc - c, sc) + 0.5 * gauss(hc - 3.0 * c, sc)) * lorentz(hu, su)
            }
            Family::Skewed => {
                // Skew-normal in h_c (shape 4); the interaction scale grows with h_c.
                let z = (hc - c) / sc;
                let skew = 0.5 * (1.0 + libm::erf(4.0 * z / std::f64::consts::SQRT_2));
                let scale = su * (0.6 + 0.4 * hc.max(0.0) / c);
                gauss(hc - c, sc) * skew * lorentz(hu, scale) / scale
            }
        }
    }

    /// The plant's grid edges for `params` (module docs), A/m.
    pub fn edges_a_per_m(&self, params: &ActuatorParams) -> Vec<f64> {
        let reach = reach_a_per_m(params);
        let w = self.half_width_a_per_m(params);
        let fine_end = (1.05 * reach).min(w);
        let fine = (2.0 * fine_end / (FINE_CELL_OF_REACH * reach))
            .ceil()
            .max(2.0) as usize;
        let mut edges: Vec<f64> = (0..=fine)
            .map(|k| -fine_end + 2.0 * fine_end * k as f64 / fine as f64)
            .collect();
        if w > fine_end * (1.0 + 1e-9) {
            // Geometric growth from the last fine width to the edge: the widths
            // δ r, δ r², … sum to W − fine_end.
            let first = 2.0 * fine_end / fine as f64;
            let ratio = growth_ratio(first, w - fine_end, OUTER_INTERVALS);
            let mut outer = Vec::with_capacity(OUTER_INTERVALS);
            let mut at = fine_end;
            let mut width = first;
            for k in 0..OUTER_INTERVALS {
                width *= ratio;
                at = if k + 1 == OUTER_INTERVALS {
                    w
                } else {
                    at + width
                };
                outer.push(at);
            }
            let mut out: Vec<f64> = outer.iter().rev().map(|h| -h).collect();
            out.extend(edges);
            out.extend(outer);
            edges = out;
        }
        edges
    }

    /// The rod's measure on the plant's grid for `params` (total mass `M_s`).
    pub fn grid(&self, params: &ActuatorParams) -> Result<PreisachGrid, String> {
        self.check()?;
        let edges = self.edges_a_per_m(params);
        let w = self.half_width_a_per_m(params);
        let l = edges.len() - 1;
        let q = QUADRATURE;
        let mut masses = vec![0.0; l * (l + 1) / 2];
        for j in 0..l {
            for i in 0..=j {
                let (b0, b1) = (edges[i], edges[i + 1]);
                let (a0, a1) = (edges[j], edges[j + 1]);
                let (db, da) = ((b1 - b0) / q as f64, (a1 - a0) / q as f64);
                let mut sum = 0.0;
                for a in 0..q {
                    for b in 0..q {
                        let factor = match (i < j, a.cmp(&b)) {
                            (true, _) | (false, std::cmp::Ordering::Greater) => 1.0,
                            (false, std::cmp::Ordering::Equal) => 0.5,
                            (false, std::cmp::Ordering::Less) => 0.0,
                        };
                        if factor == 0.0 {
                            continue;
                        }
                        let beta = b0 + (b as f64 + 0.5) * db;
                        let alpha = a0 + (a as f64 + 0.5) * da;
                        sum += factor * self.density(beta, alpha.max(beta), w) * db * da;
                    }
                }
                masses[j * (j + 1) / 2 + i] = sum;
            }
        }
        let total: f64 = masses.iter().sum();
        if !(total.is_finite() && total > 0.0) {
            return Err(format!(
                "rod {}: the density integrates to {total}",
                self.label()
            ));
        }
        let ms = params.actuator.saturation_magnetization_a_per_m;
        for m in &mut masses {
            *m *= ms / total;
        }
        PreisachGrid::new(edges, &masses)
    }
}

/// The field the coil reaches at the current limit, `c0 I_max`, A/m.
pub fn reach_a_per_m(params: &ActuatorParams) -> f64 {
    params.actuator.coil_factor_per_m * params.control.current_limit_a
}

/// The ratio `r` with `δ (r + r² + … + r^n) = span` (bisection; 1 when that already fits).
fn growth_ratio(delta: f64, span: f64, n: usize) -> f64 {
    let sum = |r: f64| (1..=n).map(|k| r.powi(k as i32)).sum::<f64>() * delta;
    if sum(1.0) >= span {
        return span / (n as f64 * delta);
    }
    let (mut lo, mut hi) = (1.0, 2.0);
    while sum(hi) < span {
        hi *= 2.0;
    }
    for _ in 0..100 {
        let mid = 0.5 * (lo + hi);
        if sum(mid) < span {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_family_gives_a_measure_of_total_m_s_on_a_plane_of_the_asked_width() {
        let params = actuator_params::paper_defaults();
        for (_, family) in Family::NAMES {
            for factor in [1.0, 4.0] {
                let rod = Rod::new(family, factor);
                let g = rod.grid(&params).unwrap();
                let w = factor * 15_400.0 * 2.0;
                assert!((g.h_min() + w).abs() < 1e-6 * w && (g.h_max() - w).abs() < 1e-6 * w);
                let ms = params.actuator.saturation_magnetization_a_per_m;
                assert!((g.total_mass() - ms).abs() < 1e-9 * ms);
                assert!(g.levels() >= 80 && g.levels() <= 100, "{}", g.levels());
            }
        }
    }

    #[test]
    fn a_wide_rod_is_far_from_saturation_at_the_coil_limit() {
        use crate::preisach::PreisachMemory;
        let params = actuator_params::paper_defaults();
        let reach = reach_a_per_m(&params);
        for (_, family) in Family::NAMES {
            let g = Rod::new(family, 4.0).grid(&params).unwrap();
            let mut m = PreisachMemory::ac_demagnetized(&g, 0.0, 0.95, 1.0);
            m.move_to(&g, reach);
            let fraction = m.output_a_per_m(&g) / g.total_mass();
            assert!(fraction < 0.8, "{}: {fraction}", family.name());
            let narrow = Rod::new(family, 1.0).grid(&params).unwrap();
            let mut m = PreisachMemory::negative_saturation(&narrow);
            m.move_to(&narrow, reach);
            assert!(m.output_a_per_m(&narrow) / narrow.total_mass() > 0.99);
        }
    }

    #[test]
    fn bad_rod_texts_name_the_part() {
        assert!(Rod::parse("gaussian:4").is_ok());
        assert!(Rod::parse("lognormal:2:3:1").is_ok());
        assert!(Rod::parse("cubic:4")
            .unwrap_err()
            .contains("unknown family `cubic`"));
        assert!(Rod::parse("gaussian")
            .unwrap_err()
            .contains("FAMILY:FACTOR"));
        assert!(Rod::parse("gaussian:x")
            .unwrap_err()
            .contains("`x` is not a number"));
        assert!(Rod::parse("gaussian:0.5").unwrap_err().contains("1 ..= 20"));
    }
}
