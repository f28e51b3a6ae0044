//! Displacement → magnetization through the static model (6): `y = l_m λ_s M² / M_s²`, so
//!
//! `|M| = M_s √(y / (l_m λ_s))`.
//!
//! Samples with `y < 0` (sensor noise around zero displacement) are clipped to `y = 0` and
//! **counted** in [`Conversion::clipped_negative`]; samples above the full stroke `l_m λ_s` are
//! counted in [`Conversion::above_stroke`] (kept: `|M|` slightly above `M_s`).
//!
//! The sign of `M` is not observable from `y` (magnetostriction is even in `M`). Two conventions:
//!
//! * [`Branch::Positive`] — `M >= 0` throughout. Valid when a DC bias keeps the magnetization
//!   non-negative: by order preservation (Theorem 1.4) an input `H(t) >= H_d` applied from the
//!   state demagnetized at `H_d` (with `M = 0` there) gives `M(t) >= 0`; e.g. a current `I >= 0`
//!   from the demagnetized state at `I = 0`. Such data cannot excite cells with `β` below the bias:
//!   the fit reports them unexcited.
//! * [`Branch::Monotone`] — for bipolar excitation (e.g. `maglab excite`, which sweeps the whole
//!   grid). Piecewise monotonicity (Theorem 1.3, `μ >= 0`): while the input rises, `M` rises, so
//!   `M` can only change sign from − to + on a rising run (and + to − on a falling run), at the
//!   zero of `M`, which is the minimum of `y` on that run. The rule: on each monotone run of the
//!   input, if the sign entering the run can flip in the run's direction and the run's minimum of
//!   `y` is below `zero_band_m`, the sign flips after that minimum. A wrong decision (the run
//!   turned back with `|M|` inside the zero band) is confined to that run's tail and bounded by
//!   `|M| <= M_s √(zero_band / (l_m λ_s))`; the next run re-decides from its own minimum.

/// Sign convention for `M`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Branch {
    /// `M >= 0` (DC-biased excitation).
    Positive,
    /// Sign from input monotonicity (bipolar excitation).
    Monotone,
}

impl Branch {
    /// CLI names.
    pub const NAMES: [(&'static str, Branch); 2] = [
        ("positive", Branch::Positive),
        ("monotone", Branch::Monotone),
    ];

    /// Parses a CLI name.
    pub fn parse(text: &str) -> Result<Self, String> {
        Self::NAMES
            .iter()
            .find(|(n, _)| *n == text)
            .map(|(_, b)| *b)
            .ok_or_else(|| format!("unknown branch `{text}`; expected positive or monotone"))
    }

    /// The CLI name.
    pub fn name(self) -> &'static str {
        match self {
            Branch::Positive => "positive",
            Branch::Monotone => "monotone",
        }
    }
}

/// The static-model constants the conversion needs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StaticModel {
    /// l_m, m.
    pub rod_length_m: f64,
    /// λ_s.
    pub saturation_magnetostriction: f64,
    /// M_s, A/m.
    pub saturation_magnetization_a_per_m: f64,
}

impl StaticModel {
    /// Full stroke `l_m λ_s`, m.
    pub fn stroke_m(&self) -> f64 {
        self.rod_length_m * self.saturation_magnetostriction
    }

    /// Displacement of the static model (6) for magnetization `m`.
    pub fn displacement_m(&self, m_a_per_m: f64) -> f64 {
        let r = m_a_per_m / self.saturation_magnetization_a_per_m;
        self.stroke_m() * r * r
    }
}

/// The converted magnetization and what was clipped.
#[derive(Debug, Clone, PartialEq)]
pub struct Conversion {
    /// M, A/m.
    pub m_a_per_m: Vec<f64>,
    /// Samples with `y < 0`, clipped to `M = 0`.
    pub clipped_negative: usize,
    /// Samples with `y > l_m λ_s`.
    pub above_stroke: usize,
    /// Sign changes assigned by the monotone rule.
    pub sign_changes: usize,
}

/// Converts a displacement sequence to magnetization. `input` (same length; current or field) is
/// used by [`Branch::Monotone`], which also needs the sign of `M` at the start (`initial_sign`:
/// -1 from negative saturation, +1 from positive saturation, 0 when demagnetized).
pub fn magnetization(
    model: &StaticModel,
    displacement_m: &[f64],
    input: &[f64],
    branch: Branch,
    initial_sign: i8,
    zero_band_m: f64,
) -> Conversion {
    let stroke = model.stroke_m();
    let ms = model.saturation_magnetization_a_per_m;
    let mut clipped_negative = 0;
    let mut above_stroke = 0;
    let magnitude: Vec<f64> = displacement_m
        .iter()
        .map(|&y| {
            if y < 0.0 {
                clipped_negative += 1;
            }
            if y > stroke {
                above_stroke += 1;
            }
            ms * (y.max(0.0) / stroke).sqrt()
        })
        .collect();
    let mut sign_changes = 0;
    let m_a_per_m = match branch {
        Branch::Positive => magnitude,
        Branch::Monotone => {
            let n = magnitude.len();
            let mut sign = vec![1.0; n];
            // Monotone runs of the input: [start, end] inclusive, direction.
            let mut current: f64 = match initial_sign {
                s if s < 0 => -1.0,
                s if s > 0 => 1.0,
                // Demagnetized (M = 0): the first run's direction decides, via the zero rule.
                _ => 0.0,
            };
            let mut start = 0;
            while start + 1 < n {
                let mut dir = 0.0;
                let mut end = start;
                while end + 1 < n {
                    let d = input[end + 1] - input[end];
                    if d != 0.0 {
                        if dir == 0.0 {
                            dir = d.signum();
                        } else if d.signum() != dir {
                            break;
                        }
                    }
                    end += 1;
                }
                if current == 0.0 {
                    current = -dir;
                }
                // A rising run can only take M from − to +, a falling one from + to −.
                let can_flip = dir != 0.0 && current == -dir;
                let (kmin, ymin) = (start..=end)
                    .map(|k| (k, displacement_m[k]))
                    .fold((start, f64::INFINITY), |a, b| if b.1 < a.1 { b } else { a });
                for (k, s) in sign.iter_mut().enumerate().take(end + 1).skip(start) {
                    *s = if can_flip && ymin <= zero_band_m && k > kmin {
                        dir
                    } else {
                        current
                    };
                }
                if can_flip && ymin <= zero_band_m && kmin < end {
                    current = dir;
                    sign_changes += 1;
                }
                start = end;
            }
            if n == 1 {
                sign[0] = if current == 0.0 { 1.0 } else { current };
            }
            magnitude.iter().zip(&sign).map(|(m, s)| m * s).collect()
        }
    };
    Conversion {
        m_a_per_m,
        clipped_negative,
        above_stroke,
        sign_changes,
    }
}
